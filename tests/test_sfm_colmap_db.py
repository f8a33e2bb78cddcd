"""sfm-export --format colmap-db: pose priors in a COLMAP database built by pycolmap here,
read back with plain sqlite3 through the pose_priors layout of COLMAP's schema
(position, position_covariance, gravity: float64 blobs; coordinate_system 0 = WGS84,
1 = CARTESIAN; corr_data_id = images.image_id).  The WGS84 truth: ECEF by the ENU axes
written out here and pyproj's geocentric <-> geodetic transformation."""
import hashlib
import sqlite3

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from photogrammetry.cli.main import main
from photogrammetry.orientation.camera import FrameCamera, write_camera
from photogrammetry.orientation.exposure import ExposureOrientation, read_eo_csv, write_eo_csv
from photogrammetry.orientation.mapping import EnuFrame

pycolmap = pytest.importorskip("pycolmap")
if not hasattr(pycolmap, "PosePriorCoordinateSystem"):
    pytest.skip("pycolmap without pose priors (4.x needed)", allow_module_level=True)

LAT0, LON0, H0 = 30.5, 114.3, 20.0
CAM = FrameCamera(8.0, 0.004, 1000, 750, (499.5, 374.5), (0.0, 0.0, 0.0), (0.0, 0.0))


def _database(path, names, prior_on=None):
    """A COLMAP database as feature extraction leaves it: a camera, a rig, images and
    frames; optionally an old (CARTESIAN) prior on one image."""
    db = pycolmap.Database.open(str(path))
    cid = db.write_camera(pycolmap.Camera(model="SIMPLE_PINHOLE", width=1000, height=750,
                                          params=[2000.0, 500.0, 375.0]))
    sensor = pycolmap.sensor_t(type=pycolmap.SensorType.CAMERA, id=cid)
    rig = pycolmap.Rig()
    rig.add_ref_sensor(sensor)
    rid = db.write_rig(rig)
    for name in names:
        iid = db.write_image(pycolmap.Image(name=name, camera_id=cid))
        fr = pycolmap.Frame()
        fr.rig_id = rid
        fr.add_data_id(pycolmap.data_t(sensor, iid))
        db.write_frame(fr)
        if name == prior_on:
            db.write_pose_prior(pycolmap.PosePrior(
                corr_data_id=db.read_image(iid).data_id, position=np.array([9.0, 9, 9]),
                coordinate_system=pycolmap.PosePriorCoordinateSystem.CARTESIAN))
    db.close()


def _eo(ids, sigmas=True):
    rng = np.random.default_rng(7)
    n = len(ids)
    X = np.column_stack([rng.uniform(-3000, 3000, n), rng.uniform(-3000, 3000, n),
                         rng.uniform(500, 900, n)])
    ang = np.deg2rad(np.column_stack([rng.normal(0, 3, n), rng.normal(0, 3, n),
                                      rng.uniform(-180, 180, n)]))
    frame = EnuFrame.from_degrees(LAT0, LON0, H0).header()
    ps = np.column_stack([np.full(n, 0.05), np.full(n, 0.08), np.full(n, 0.12)])
    return ExposureOrientation(list(ids), np.arange(n, dtype=float), X, ang,
                               "omega-phi-kappa", frame, ps if sigmas else None,
                               np.full((n, 3), 1e-4) if sigmas else None)


def _priors(path):
    """name -> (system, position, covariance, gravity) read with sqlite3 only."""
    con = sqlite3.connect(str(path))
    rows = con.execute("SELECT i.name, p.coordinate_system, p.position, "
                       "p.position_covariance, p.gravity, p.corr_sensor_id, i.camera_id "
                       "FROM pose_priors p JOIN images i ON p.corr_data_id = i.image_id"
                       ).fetchall()
    con.close()
    out = {}
    for name, system, pos, cov, grav, sensor, cam in rows:
        assert sensor == cam
        out[name] = (system, np.frombuffer(pos, np.float64),
                     np.frombuffer(cov, np.float64).reshape(3, 3, order="F"),
                     np.frombuffer(grav, np.float64) if grav is not None else None)
    return out


def _enu_axes(lat_deg, lon_deg):
    """ECEF from ENU: the columns east, north, up."""
    p, l = np.deg2rad(lat_deg), np.deg2rad(lon_deg)
    return np.array([[-np.sin(l), -np.sin(p) * np.cos(l), np.cos(p) * np.cos(l)],
                     [np.cos(l), -np.sin(p) * np.sin(l), np.cos(p) * np.sin(l)],
                     [0.0, np.cos(p), np.sin(p)]])


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_wgs84_priors_read_back_with_sqlite(tmp_path, capsys):
    from pyproj import Transformer
    _database(tmp_path / "in.db", ["a.jpg", "b.jpg", "c.jpg", "z.jpg"], prior_on="b.jpg")
    before = _sha(tmp_path / "in.db")
    write_eo_csv(tmp_path / "eo.csv", _eo(["a", "b", "c"]))
    eo = read_eo_csv(tmp_path / "eo.csv")
    assert main(["sfm-export", str(tmp_path / "eo.csv"), "--format", "colmap-db",
                 "--database", str(tmp_path / "in.db"), "-o", str(tmp_path / "out.db")]) == 0
    text = capsys.readouterr().out
    assert "3 pose priors (WGS84)" in text and "1 replaced" in text and "z.jpg" in text
    assert _sha(tmp_path / "in.db") == before                 # the input untouched
    got = _priors(tmp_path / "out.db")
    assert sorted(got) == ["a.jpg", "b.jpg", "c.jpg"]
    to_ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    to_geo = Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=True)
    X0 = np.array(to_ecef.transform(LON0, LAT0, H0))
    R0 = _enu_axes(LAT0, LON0)
    for k, iid in enumerate(eo.image_id):
        system, pos, cov, grav = got[iid + ".jpg"]
        assert system == 0
        lon, lat, h = to_geo.transform(*(X0 + R0 @ eo.position[k]))
        np.testing.assert_allclose(pos[:2], [lat, lon], rtol=0, atol=1e-10)   # 1e-5 m
        assert pos[2] == pytest.approx(h, abs=1e-4)
        Ri = _enu_axes(lat, lon)
        M = Ri.T @ R0                                 # mapping (ENU at origin) -> local
        np.testing.assert_allclose(cov, M @ np.diag(eo.position_sigma[k] ** 2) @ M.T,
                                   atol=1e-12)
        # meridian convergence over 3 km: off-diagonal terms of the order 1e-5 m^2
        assert np.abs(cov - np.diag(np.diag(cov))).max() > 1e-7
        C_mc = Rotation.from_euler("XYZ", eo.angles[k]).as_matrix()
        down_m = R0.T @ -Ri[:, 2]
        np.testing.assert_allclose(grav, np.diag([1.0, -1, -1]) @ C_mc.T @ down_m,
                                   atol=1e-12)


def test_cartesian_priors_and_missing_images(tmp_path, capsys):
    _database(tmp_path / "in.db", ["img/a.png", "b.png"])
    write_eo_csv(tmp_path / "eo.csv", _eo(["a", "b", "d"]))
    eo = read_eo_csv(tmp_path / "eo.csv")              # the file's rounding
    write_camera(tmp_path / "cam.toml", CAM)
    args = ["sfm-export", str(tmp_path / "eo.csv"), "--format", "colmap-db", "--database",
            str(tmp_path / "in.db"), "-o", str(tmp_path / "out.db"),
            "--prior-coordinates", "cartesian"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "1 of 3 EO images are not in the database: d" in err
    assert not (tmp_path / "out.db").exists()
    assert main(args + ["--add-missing", "--camera", str(tmp_path / "cam.toml"),
                        "--image-suffix", ".tif"]) == 0
    assert "added 1 images to the database: d.tif" in capsys.readouterr().out
    got = _priors(tmp_path / "out.db")
    assert sorted(got) == ["b.png", "d.tif", "img/a.png"]
    for name, k in (("img/a.png", 0), ("b.png", 1), ("d.tif", 2)):
        system, pos, cov, grav = got[name]
        assert system == 1
        np.testing.assert_array_equal(pos, eo.position[k])
        np.testing.assert_allclose(cov, np.diag(eo.position_sigma[k] ** 2), rtol=1e-15)
    con = sqlite3.connect(str(tmp_path / "out.db"))
    model, w, h = con.execute("SELECT c.model, c.width, c.height FROM cameras c JOIN images i "
                              "ON i.camera_id = c.camera_id WHERE i.name = 'd.tif'").fetchone()
    nframes = con.execute("SELECT COUNT(*) FROM frame_data").fetchone()[0]
    con.close()
    assert (model, w, h) == (4, 1000, 750) and nframes == 3      # 4 = OPENCV
    # updating in place: the database named as the output; an existing other one refused
    assert main(["sfm-export", str(tmp_path / "eo.csv"), "--format", "colmap-db",
                 "--database", str(tmp_path / "out.db"), "-o", str(tmp_path / "out.db"),
                 "-q"]) == 0
    assert len(_priors(tmp_path / "out.db")) == 3
    assert main(args) == 2
    assert "exists" in capsys.readouterr().err


def test_new_database_without_sigmas(tmp_path):
    """No --database: a new one holding the EO's images; no sigmas -> NaN covariance
    (COLMAP's own prior_position_std then)."""
    eo = _eo(["a", "b"], sigmas=False)
    write_eo_csv(tmp_path / "eo.csv", eo)
    assert main(["sfm-export", str(tmp_path / "eo.csv"), "--format", "colmap-db", "-o",
                 str(tmp_path / "new.db")]) == 2                    # needs the camera
    write_camera(tmp_path / "cam.toml", CAM)
    assert main(["sfm-export", str(tmp_path / "eo.csv"), "--format", "colmap-db", "-o",
                 str(tmp_path / "new.db"), "--camera", str(tmp_path / "cam.toml"),
                 "-q"]) == 0
    got = _priors(tmp_path / "new.db")
    assert sorted(got) == ["a.jpg", "b.jpg"]
    assert all(np.isnan(v[2]).all() and v[0] == 0 for v in got.values())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cam.toml", "eo.csv", "new.db"]


def test_missing_pycolmap_names_the_extra(tmp_path, monkeypatch, capsys):
    import sys
    write_eo_csv(tmp_path / "eo.csv", _eo(["a"]))
    write_camera(tmp_path / "cam.toml", CAM)
    monkeypatch.setitem(sys.modules, "pycolmap", None)
    assert main(["sfm-export", str(tmp_path / "eo.csv"), "--format", "colmap-db", "-o",
                 str(tmp_path / "new.db"), "--camera", str(tmp_path / "cam.toml")]) == 2
    assert "pip install 'insphoto[colmap]'" in capsys.readouterr().err
    assert not (tmp_path / "new.db").exists()
