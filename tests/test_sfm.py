"""SfM imports and exports: the OpenSfM "brown" and COLMAP OPENCV cameras against their
projection formulas written out here, hand-written reconstruction.json / tracks.csv /
COLMAP text models, the exports read back by pycolmap and by the layouts' definitions,
and the real ODM reconstruction."""
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from photogrammetry.cli.main import main
from photogrammetry.imagery.tiepoints import read_tiepoints
from photogrammetry.orientation.camera import read_camera
from photogrammetry.orientation.exposure import ExposureOrientation, read_eo_csv
from photogrammetry.orientation.mapping import EnuFrame, ProjectedFrame
from photogrammetry.orientation.rotation import angles_to_matrix
from photogrammetry.sfm.colmap import camera_from_colmap, camera_to_colmap
from photogrammetry.sfm.opensfm import camera_from_opensfm, camera_to_opensfm, read_reconstruction

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "real" / "odm_drone_block"

BROWN = {"projection_type": "brown", "width": 1368, "height": 912,
         "focal_x": 0.6664614123723713, "focal_y": 0.6664614123723713,
         "c_x": -0.0015460447606643697, "c_y": 0.004751874732641298,
         "k1": -0.2640629100413887, "k2": 0.10188934223670705, "p1": 0.0007345906274317972,
         "p2": 0.0002595206713083041, "k3": -0.02581956399353581}


def _brown_pixels(c, X_cv):
    """OpenSfM's brown projection of CV-camera points, to pixel centres (u, v)."""
    xn, yn = X_cv[:, 0] / X_cv[:, 2], X_cv[:, 1] / X_cv[:, 2]
    r2 = xn ** 2 + yn ** 2
    rad = 1 + c["k1"] * r2 + c["k2"] * r2 ** 2 + c["k3"] * r2 ** 3
    xd = xn * rad + 2 * c["p1"] * xn * yn + c["p2"] * (r2 + 2 * xn ** 2)
    yd = yn * rad + c["p1"] * (r2 + 2 * yn ** 2) + 2 * c["p2"] * xn * yn
    s = max(c["width"], c["height"])
    un, vn = c["focal_x"] * xd + c["c_x"], c["focal_y"] * yd + c["c_y"]
    return np.column_stack([un * s - 0.5 + c["width"] / 2, vn * s - 0.5 + c["height"] / 2])


def _points_cv(n=200, seed=3):
    rng = np.random.default_rng(seed)
    xn = rng.uniform(-0.45, 0.45, n)
    yn = rng.uniform(-0.3, 0.3, n)
    z = rng.uniform(5, 50, n)
    return np.column_stack([xn * z, yn * z, z])


def _our_pixels(cam, X_cv):
    """Our chain: CV camera -> photogrammetric ray (x, y, -f) -> ideal -> distort -> px."""
    X_c = X_cv * [1, -1, -1]
    xy = -cam.focal_length_mm * X_c[:, :2] / X_c[:, 2:3]
    return cam.photo_to_pixel(cam.distort(xy))


@pytest.mark.parametrize("pixel_size", [0.01, 0.00241])
def test_brown_camera_projects_as_opensfm(pixel_size):
    """Both ways: the same pixels from the same points, and our undistorted ray of the
    pixel is the point's direction."""
    cam = camera_from_opensfm(BROWN, pixel_size)
    X = _points_cv()
    uv = _brown_pixels(BROWN, X)
    np.testing.assert_allclose(_our_pixels(cam, X), uv, atol=1e-9)
    rays = cam.rays(cam.undistort(cam.pixel_to_photo(uv))) * [1, -1, -1]
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    np.testing.assert_allclose(rays, X / np.linalg.norm(X, axis=1, keepdims=True), atol=1e-9)
    back = camera_to_opensfm(cam)
    for k in ("focal_x", "c_x", "c_y", "k1", "k2", "k3", "p1", "p2"):
        assert back[k] == pytest.approx(BROWN[k], rel=1e-12, abs=1e-15)


def test_colmap_opencv_camera_projects_as_colmap():
    """COLMAP OPENCV (pixel centre of the top-left pixel at 0.5, 0.5) written out here."""
    fx, cx, cy, k1, k2, p1, p2 = 900.0, 330.2, 241.7, -0.12, 0.03, 0.0011, -0.0007
    X = _points_cv()
    xn, yn = X[:, 0] / X[:, 2], X[:, 1] / X[:, 2]
    r2 = xn ** 2 + yn ** 2
    rad = 1 + k1 * r2 + k2 * r2 ** 2
    xd = xn * rad + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn ** 2)
    yd = yn * rad + p1 * (r2 + 2 * yn ** 2) + 2 * p2 * xn * yn
    uv_colmap = np.column_stack([fx * xd + cx, fx * yd + cy])
    cam = camera_from_colmap("OPENCV", 640, 480, [fx, fx, cx, cy, k1, k2, p1, p2])
    np.testing.assert_allclose(_our_pixels(cam, X), uv_colmap - 0.5, atol=1e-9)
    model, params = camera_to_colmap(cam)
    assert model == "OPENCV"
    np.testing.assert_allclose(params, [fx, fx, cx, cy, k1, k2, p1, p2], rtol=1e-12)


def _write_project(d, shots_pose, points, cam=BROWN):
    """reconstruction.json and tracks.csv (v2) of points seen by shots, projected by
    OpenSfM's formulas above."""
    shots, lines = {}, ["OPENSFM_TRACKS_VERSION_v2"]
    s = max(cam["width"], cam["height"])
    for name, (R_cw, C) in shots_pose.items():
        t = -R_cw @ C
        shots[name] = {"rotation": Rotation.from_matrix(R_cw).as_rotvec().tolist(),
                       "translation": t.tolist(), "camera": "cam1"}
        uv = _brown_pixels(cam, points @ R_cw.T + t)
        xn = (uv[:, 0] + 0.5 - cam["width"] / 2) / s
        yn = (uv[:, 1] + 0.5 - cam["height"] / 2) / s
        for k in range(len(points)):
            lines.append(f"{name}\t{k}\t{k + 100}\t{float(xn[k])!r}\t{float(yn[k])!r}"
                         "\t0.01\t10\t20\t30\t0\t0")
    doc = [{"cameras": {"cam1": cam}, "shots": shots,
            "reference_lla": {"latitude": 30.0, "longitude": 114.0, "altitude": 20.0},
            "points": {str(k): {"coordinates": p.tolist()} for k, p in enumerate(points)}}]
    (d / "reconstruction.json").write_text(json.dumps(doc))
    (d / "tracks.csv").write_text("\n".join(lines) + "\n")


def test_opensfm_import_collinear(tmp_path):
    """Nadir shot: R_cw = diag(1, -1, -1) is C_mc = I; every imported observation's ray
    through the imported EO passes through its world point."""
    rng = np.random.default_rng(5)
    pts = np.column_stack([rng.uniform(-40, 40, 30), rng.uniform(-30, 30, 30),
                           rng.uniform(-3, 3, 30)])
    R2 = np.diag([1.0, -1, -1]) @ Rotation.from_euler("xyz", [2, -3, 30], degrees=True
                                                         ).as_matrix().T
    _write_project(tmp_path, {"a.jpg": (np.diag([1.0, -1, -1]), np.array([0, 0, 100.0])),
                              "b.jpg": (R2, np.array([20.0, 5, 102]))}, pts)
    P = read_reconstruction(tmp_path / "reconstruction.json", "phi-omega-kappa")
    assert P.eo.image_id == ("a", "b")
    np.testing.assert_allclose(P.eo.matrices()[0], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(P.eo.position[1], [20, 5, 102], atol=1e-9)
    assert P.eo.frame == EnuFrame.from_degrees(30.0, 114.0, 20.0).header()
    out = tmp_path / "imp"
    assert main(["sfm-import", str(tmp_path / "reconstruction.json"), "-o", str(out),
                 "-q"]) == 0
    cam, _ = read_camera(out / "camera.toml")
    eo = read_eo_csv(out / "eo.csv")
    tp = read_tiepoints(out / "tiepoints.csv")
    assert len(tp) == 60
    C = eo.matrices()
    for iid, pid, xy in zip(tp.image_id, tp.point_id, tp.xy_mm):
        k = eo.image_id.index(iid)
        ray = C[k] @ cam.rays(cam.undistort(xy[None]))[0]
        d = pts[int(pid)] - eo.position[k]
        angle = np.arctan2(np.linalg.norm(np.cross(ray, d)), ray @ d)
        assert np.degrees(angle) * 3600 < 0.05      # arcsec (the file's 1e-7 mm: 0.002")


def test_exports_read_back(tmp_path):
    """OpenSfM export -> our reader; COLMAP text -> pycolmap (its centre and rotation);
    orthority CSV by its layout (with the .prj of the EPSG frame)."""
    pycolmap = pytest.importorskip("pycolmap")
    cam = camera_from_opensfm(BROWN)
    ang = np.deg2rad([[1.0, -2.0, 30.0], [-3.0, 1.5, 175.0]])
    frame = EnuFrame.from_degrees(30.0, 114.0, 20.0)
    eo = ExposureOrientation(["a", "b"], [0.0, 1.0], [[0, 0, 100.0], [30.0, -4, 99]], ang,
                             "omega-phi-kappa", frame.header())
    from photogrammetry.orientation.camera import write_camera
    from photogrammetry.orientation.exposure import write_eo_csv
    write_eo_csv(tmp_path / "eo.csv", eo)
    write_camera(tmp_path / "cam.toml", cam)
    assert main(["sfm-export", str(tmp_path / "eo.csv"), "--camera", str(tmp_path / "cam.toml"),
                 "--format", "opensfm", "-o", str(tmp_path / "rec.json")]) == 0
    P = read_reconstruction(tmp_path / "rec.json")
    np.testing.assert_allclose(P.eo.matrices(), eo.matrices(), atol=1e-12)
    np.testing.assert_allclose(P.eo.position, eo.position, atol=1e-9)
    assert main(["sfm-export", str(tmp_path / "eo.csv"), "--camera", str(tmp_path / "cam.toml"),
                 "--format", "colmap", "-o", str(tmp_path / "colmap")]) == 0
    rec = pycolmap.Reconstruction(str(tmp_path / "colmap"))
    for im in rec.images.values():
        k = eo.image_id.index(im.name)
        np.testing.assert_allclose(im.projection_center(), eo.position[k], atol=1e-9)
        cfw = im.cam_from_world() if callable(im.cam_from_world) else im.cam_from_world
        # the CV camera's z (viewing direction) is minus our z_c, in the world frame
        np.testing.assert_allclose(cfw.rotation.matrix()[2], -eo.matrices()[k][:, 2],
                                   atol=1e-12)
    c = rec.cameras[1]
    X = _points_cv(20)
    uv = np.array([c.img_from_cam(x) for x in X])
    np.testing.assert_allclose(uv - 0.5, _our_pixels(cam, X), atol=1e-6)
    utm = ProjectedFrame("EPSG:32650")
    eo_utm = ExposureOrientation(["a"], [0.0], [[500000.0, 3300000.0, 120.0]], ang[:1],
                                 "omega-phi-kappa", utm.header())
    write_eo_csv(tmp_path / "u.csv", eo_utm)
    assert main(["sfm-export", str(tmp_path / "u.csv"), "--format", "orthority", "-o",
                 str(tmp_path / "opk.csv")]) == 0
    rows = (tmp_path / "opk.csv").read_text().splitlines()
    assert rows[0].split() == ["filename", "x", "y", "z", "omega", "phi", "kappa"]
    f = rows[1].split()
    assert f[0] == '"a"'
    np.testing.assert_allclose([float(v) for v in f[1:]], [500000, 3300000, 120, 1, -2, 30])
    assert "32650" in (tmp_path / "opk.prj").read_text()


def test_bad_inputs(tmp_path, capsys):
    (tmp_path / "r.json").write_text('[{"cameras": {"c": {"projection_type": "fisheye", '
                                     '"width": 10, "height": 10}}, "shots": {"a": {}}}]')
    assert main(["sfm-import", str(tmp_path / "r.json"), "-o", str(tmp_path / "o")]) == 2
    assert "fisheye" in capsys.readouterr().err
    assert main(["sfm-import", str(tmp_path / "none.json"), "-o", str(tmp_path / "o")]) == 2
    bad = dict(BROWN, focal_y=0.7)
    with pytest.raises(Exception, match="square pixels"):
        camera_from_opensfm(bad)


@pytest.mark.skipif(not REAL.is_dir(), reason="../shared/real is absent")
def test_real_reconstruction_and_the_orthority_csv():
    """The ODM reconstruction read in its ENU frame.  odm_xyz_opk.csv holds the same
    angles with the topocentric ENU axes taken as UTM grid axes (the grid convergence,
    -0.856 deg there, left out): checked to 0.002 deg."""
    P = read_reconstruction(REAL / "opensfm" / "reconstruction.json")
    cam, _ = P.cameras[next(iter(P.cameras))]
    assert (cam.width_px, cam.height_px) == (1368, 912)
    rows = [ln.replace("'", "").split() for ln in (REAL / "odm_xyz_opk.csv").read_text()
            .splitlines()[1:] if ln.strip()]
    ref = {r[0]: np.deg2rad([float(v) for v in r[4:7]]) for r in rows}
    for k, iid in enumerate(P.eo.image_id):
        R = angles_to_matrix(ref[iid], "omega-phi-kappa")
        err = Rotation.from_matrix(R.T @ P.eo.matrices()[k]).magnitude()
        assert np.rad2deg(err) < 0.002


def _colmap_model(d, poses, points, params):
    """A COLMAP text model (the layout of COLMAP's docs) with observations projected by
    the OPENCV formula written out here (pixel centre of the top-left pixel: 0.5, 0.5)."""
    fx, fy, cx, cy, k1, k2, p1, p2 = params
    d.mkdir()
    (d / "cameras.txt").write_text("# CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
                                   "1 OPENCV 640 480 " + " ".join(map(repr, params)) + "\n")
    img_lines, tracks = [], {k: [] for k in range(len(points))}
    for n, (name, (R_cw, C)) in enumerate(poses.items(), 1):
        t = -R_cw @ C
        x, y, z, w = Rotation.from_matrix(R_cw).as_quat()
        q = " ".join(repr(float(v)) for v in (w, x, y, z, *t))
        img_lines.append(f"{n} {q} 1 {name}")
        X = points @ R_cw.T + t
        xn, yn = X[:, 0] / X[:, 2], X[:, 1] / X[:, 2]
        r2 = xn ** 2 + yn ** 2
        rad = 1 + k1 * r2 + k2 * r2 ** 2
        xd = xn * rad + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn ** 2)
        yd = yn * rad + p1 * (r2 + 2 * yn ** 2) + 2 * p2 * xn * yn
        u, v = fx * xd + cx, fy * yd + cy
        img_lines.append(" ".join(f"{float(u[k])!r} {float(v[k])!r} {k + 1}"
                                  for k in range(len(points))))
        for k in range(len(points)):
            tracks[k].append(f"{n} {k}")
    (d / "images.txt").write_text("\n".join(img_lines) + "\n")
    (d / "points3D.txt").write_text("".join(
        f"{k + 1} " + " ".join(repr(float(v)) for v in points[k]) + " 0 0 0 0.1 "
        + " ".join(tracks[k]) + "\n" for k in range(len(points))))


def test_colmap_import_collinear(tmp_path):
    """Hand-written COLMAP model -> sfm-import: the imported rays of every observation
    pass through its 3-D point; a nadir CV pose diag(1, -1, -1) is C_mc = I."""
    pytest.importorskip("pycolmap")
    rng = np.random.default_rng(8)
    pts = np.column_stack([rng.uniform(-30, 30, 25), rng.uniform(-20, 20, 25),
                           rng.uniform(-2, 2, 25)])
    R2 = np.diag([1.0, -1, -1]) @ Rotation.from_euler("xyz", [-2, 3, -20], degrees=True
                                                         ).as_matrix().T
    params = [700.0, 700.0, 321.3, 238.9, -0.08, 0.01, 0.0005, -0.0003]
    _colmap_model(tmp_path / "m", {"a.png": (np.diag([1.0, -1, -1]), np.array([0, 0, 80.0])),
                                   "b.png": (R2, np.array([15.0, 2, 81]))}, pts, params)
    out = tmp_path / "imp"
    assert main(["sfm-import", str(tmp_path / "m"), "-o", str(out), "-q",
                 "--system", "phi-omega-kappa"]) == 0
    cam, _ = read_camera(out / "camera.toml")
    eo = read_eo_csv(out / "eo.csv")
    tp = read_tiepoints(out / "tiepoints.csv")
    assert eo.image_id == ("a", "b") and len(tp) == 50
    np.testing.assert_allclose(eo.matrices()[0], np.eye(3), atol=1e-12)
    C = eo.matrices()
    for iid, pid, xy in zip(tp.image_id, tp.point_id, tp.xy_mm):
        k = eo.image_id.index(iid)
        ray = C[k] @ cam.rays(cam.undistort(xy[None]))[0]
        d = pts[int(pid) - 1] - eo.position[k]
        angle = np.arctan2(np.linalg.norm(np.cross(ray, d)), ray @ d)
        assert np.degrees(angle) * 3600 < 0.05


def test_opensfm_import_without_tracks(tmp_path, capsys):
    """No tracks.csv: camera and EO written (the EO's centres are the shots'), no
    tiepoints.csv, the summary says why; an explicit --tiepoints or --tracks without the
    file fails naming it."""
    rng = np.random.default_rng(2)
    pts = np.column_stack([rng.uniform(-40, 40, 5), rng.uniform(-30, 30, 5), np.zeros(5)])
    _write_project(tmp_path, {"a.jpg": (np.diag([1.0, -1, -1]), np.array([0, 0, 100.0])),
                              "b.jpg": (np.diag([1.0, -1, -1]), np.array([20.0, 5, 102]))},
                   pts)
    (tmp_path / "tracks.csv").unlink()
    rec = str(tmp_path / "reconstruction.json")
    out = tmp_path / "imp"
    assert main(["sfm-import", rec, "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "no tie points written: no tracks.csv beside" in text
    assert sorted(p.name for p in out.iterdir()) == ["camera.toml", "eo.csv"]
    eo = read_eo_csv(out / "eo.csv")
    np.testing.assert_allclose(eo.position, [[0, 0, 100], [20, 5, 102]], atol=1e-9)
    cam, _ = read_camera(out / "camera.toml")
    assert (cam.width_px, cam.height_px) == (BROWN["width"], BROWN["height"])
    assert main(["sfm-import", rec, "-o", str(tmp_path / "o2"), "--tiepoints",
                 str(tmp_path / "tp.csv")]) == 2
    err = capsys.readouterr().err
    assert "tracks.csv" in err and "--tiepoints" in err
    assert not (tmp_path / "o2").exists() and not (tmp_path / "tp.csv").exists()
    assert main(["sfm-import", rec, "-o", str(tmp_path / "o3"), "--tracks",
                 str(tmp_path / "mine.csv")]) == 2
    assert "mine.csv" in capsys.readouterr().err


def test_opensfm_import_tiepoints_elsewhere(tmp_path):
    """--tiepoints OUT: the tie points at OUT (the same as the folder's would be)."""
    rng = np.random.default_rng(4)
    pts = np.column_stack([rng.uniform(-40, 40, 7), rng.uniform(-30, 30, 7), np.zeros(7)])
    _write_project(tmp_path, {"a.jpg": (np.diag([1.0, -1, -1]), np.array([0, 0, 100.0])),
                              "b.jpg": (np.diag([1.0, -1, -1]), np.array([20.0, 5, 102]))},
                   pts)
    rec = str(tmp_path / "reconstruction.json")
    assert main(["sfm-import", rec, "-o", str(tmp_path / "a"), "-q"]) == 0
    assert main(["sfm-import", rec, "-o", str(tmp_path / "b"), "-q", "--tiepoints",
                 str(tmp_path / "tp.csv")]) == 0
    assert not (tmp_path / "b" / "tiepoints.csv").exists()
    t1, t2 = read_tiepoints(tmp_path / "a" / "tiepoints.csv"), read_tiepoints(tmp_path / "tp.csv")
    assert len(t2) == 14 and t1.image_id == t2.image_id
    np.testing.assert_array_equal(t1.xy_mm, t2.xy_mm)


@pytest.mark.parametrize("points", ["missing", "empty"])
def test_colmap_import_without_points(tmp_path, capsys, points):
    """A COLMAP model whose points3D file is missing or empty (the images still refer to
    point ids): camera and EO, no tie point, the reason in the summary; --tiepoints
    refused."""
    pytest.importorskip("pycolmap")
    pts = np.array([[1.0, 2, 0], [-3, 4, 1], [5, -2, 0]])
    params = [700.0, 700.0, 321.3, 238.9, -0.08, 0.01, 0.0005, -0.0003]
    m = tmp_path / "m"
    _colmap_model(m, {"a.png": (np.diag([1.0, -1, -1]), np.array([0, 0, 80.0])),
                      "b.png": (np.diag([1.0, -1, -1]), np.array([15.0, 2, 81]))}, pts, params)
    if points == "missing":
        (m / "points3D.txt").unlink()
    else:
        (m / "points3D.txt").write_text("# 3D point list\n")
    before = sorted(p.name for p in m.iterdir())
    out = tmp_path / "imp"
    assert main(["sfm-import", str(m), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "no tie points written" in text
    assert ("no points3D.txt file" if points == "missing" else "points3D are empty") in text
    assert sorted(p.name for p in out.iterdir()) == ["camera.toml", "eo.csv"]
    assert sorted(p.name for p in m.iterdir()) == before          # the input untouched
    eo = read_eo_csv(out / "eo.csv")
    np.testing.assert_allclose(eo.position, [[0, 0, 80], [15, 2, 81]], atol=1e-9)
    cam, _ = read_camera(out / "camera.toml")
    assert cam.principal_point_px == pytest.approx((320.8, 238.4))
    assert main(["sfm-import", str(m), "-o", str(tmp_path / "o2"), "--tiepoints",
                 str(tmp_path / "tp.csv")]) == 2
    assert "points3D" in capsys.readouterr().err
