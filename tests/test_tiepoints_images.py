"""``photogrammetry tiepoints``: tie points found in rendered images of a seeded terrain
(known truth: every pixel's ray of the true EO hits the ground point it shows), then
refined back to the true angles; the image reader's levels and pixel mapping; tracks;
bad inputs."""
import os

import cv2
import numpy as np
import pytest

from photogrammetry.adjustment.batch import refine
from photogrammetry.cli.main import main
from photogrammetry.imagery.images import read_grey
from photogrammetry.imagery.matching import PairMatches, PriorView, build_tracks, guided_matches
from photogrammetry.imagery.tiepoints import read_tiepoints, write_tiepoints
from photogrammetry.orientation.camera import FrameCamera, read_camera, write_camera
from photogrammetry.orientation.exposure import ExposureOrientation, read_eo_csv, write_eo_csv
from photogrammetry.orientation.rotation import angles_to_matrix
from photogrammetry.simulate.render import make_texture, ray_ground, render_view
from photogrammetry.simulate.terrain import make_terrain

SYSTEM = "phi-omega-kappa"
FRAME = "enu; origin_lat_deg = 30.0; origin_lon_deg = 114.0; origin_h_m = 0.0"
GSD_M = 300.0 * 0.01 / 5.0          # flying height x pixel / f


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    """Two strips of three 480 x 360 px images (60 % / 35 % overlap), flown in opposite
    directions over 15 m of relief; prior angles 0.2 deg off (sigma 0.3 deg) except the
    first image's."""
    d = tmp_path_factory.mktemp("tiepoints")
    rng = np.random.default_rng(7)
    cam = FrameCamera(5.0, 0.01, 480, 360, (239.5, 179.5), (1e-3, 0.0, 0.0), (0.0, 0.0))
    terrain = make_terrain(15.0, 200.0, rng)
    texture = make_texture(rng, (-300, 650), (-300, 450), 0.25)
    ids, X, ang = [], [], []
    for s, y in enumerate((0.0, 140.0)):
        for k in range(3):
            ids.append(f"S{s + 1}_{k + 1}")
            X.append((k * 115.0, y, 300.0))
            ang.append(np.deg2rad(rng.normal(0, 1.0, 3)) + [0, 0, np.pi * s])
    X, ang = np.array(X), np.array(ang)
    paths = []
    for k, iid in enumerate(ids):
        img = render_view(cam, X[k], angles_to_matrix(ang[k], SYSTEM), terrain, texture)
        paths.append(str(d / f"{iid}.png"))
        cv2.imwrite(paths[-1], img)
    prior = ang + np.deg2rad(rng.normal(0, 0.2, ang.shape))
    prior[0] = ang[0]
    n = len(ids)
    eo = ExposureOrientation(ids, np.arange(n, dtype=float), X, prior, SYSTEM, FRAME,
                             np.full((n, 3), 0.05), np.full((n, 3), np.deg2rad(0.3)))
    write_eo_csv(d / "prior.csv", eo)
    write_camera(d / "cam.toml", cam)
    tp = str(d / "tp.csv")
    code = main(["tiepoints", *paths, "--eo", str(d / "prior.csv"), "--camera",
                 str(d / "cam.toml"), "--ground-height-m", "0", "--relief-m", "15",
                 "-o", tp, "-q"])
    assert code == 0
    return dict(dir=d, cam=cam, terrain=terrain, ids=ids, X=X, angles=ang, paths=paths,
                eo=str(d / "prior.csv"), camera=str(d / "cam.toml"), tp=tp)


def test_tracks_are_one_ground_point(block):
    """Every observation's ray of the TRUE orientation meets the terrain at the ground
    point of its track (within a pixel's footprint for 95 %; the rest are few)."""
    cam = block["cam"]
    tp = read_tiepoints(block["tp"], cam)
    index = {iid: k for k, iid in enumerate(block["ids"])}
    ground = {}
    for iid, pid, xy in zip(tp.image_id, tp.point_id, tp.xy_mm):
        k = index[iid]
        ray = cam.rays(cam.undistort(xy[None])) @ angles_to_matrix(block["angles"][k],
                                                                  SYSTEM).T
        ground.setdefault(pid, []).append(ray_ground(block["X"][k], ray, block["terrain"])[0])
    spread = np.array([np.max(np.linalg.norm(np.array(g) - np.mean(g, axis=0), axis=1))
                       for g in ground.values()])
    assert len(spread) > 1000
    assert np.percentile(spread, 95) < GSD_M
    assert np.mean(spread > 3 * GSD_M) < 0.01
    assert tp.sigma_mm is not None and 0 < tp.sigma_mm < 0.5 * cam.pixel_size_mm
    counts = {iid: tp.image_id.count(iid) for iid in block["ids"]}
    assert min(counts.values()) > 300            # every image tied, cross-strip too
    assert max(len(g) for g in ground.values()) >= 4


def test_refine_returns_the_true_angles(block):
    """Tie points from the images -> refine: the angles come back within 3 sigma of the
    truth (the priors were 0.2 deg = 720 arcsec off)."""
    cam, _ = read_camera(block["camera"])
    eo = read_eo_csv(block["eo"])
    res = refine(eo, read_tiepoints(block["tp"], cam), camera=cam, datum="first")
    err = res.eo.angles - block["angles"]
    err = (err + np.pi) % (2 * np.pi) - np.pi
    sig = res.eo.angle_sigma
    assert np.all(np.abs(err[1:]) < 3 * sig[1:]), (np.rad2deg(err) * 3600,
                                                    np.rad2deg(sig) * 3600)
    assert np.abs(err[1:]).max() < 0.15 * np.deg2rad(0.2)         # priors 720" off
    assert 0.5 < res.block.sigma0 < 2.0


def test_read_grey_levels_map_to_full_frame(tmp_path):
    """A bright square at a known place: its centroid on a reduced level (JPEG draft,
    TIFF, PNG) maps back to the full-frame centre within a fraction of a level pixel."""
    import tifffile
    img = np.full((600, 800), 30, np.uint8)
    img[300:340, 500:540] = 220                # centre (519.5, 319.5)
    cv2.imwrite(str(tmp_path / "a.png"), img)
    cv2.imwrite(str(tmp_path / "a.jpg"), img, [cv2.IMWRITE_JPEG_QUALITY, 100])
    tifffile.imwrite(tmp_path / "a.tif", np.dstack([img] * 3), tile=(128, 128))
    for name in ("a.png", "a.jpg", "a.tif"):
        lv = read_grey(tmp_path / name, max_side_px=200)
        assert (lv.width_px, lv.height_px) == (800, 600) and max(lv.pixels.shape) == 200
        w = np.clip(lv.pixels.astype(float) - 30, 0, None)
        vv, uu = np.mgrid[:w.shape[0], :w.shape[1]]
        c = np.array([(uu * w).sum(), (vv * w).sum()]) / w.sum()
        np.testing.assert_allclose(lv.to_full(c), [519.5, 319.5], atol=0.5 * lv.scale[0])


@pytest.mark.parametrize("layout", ["strips", "tiles", "tiles16"])
def test_read_grey_segment_by_segment(tmp_path, monkeypatch, layout):
    """A frame above BANDED_PIXELS is decoded tile by tile (strip by strip) and reduced
    band by band: the same level as the whole frame in memory (16 bit too)."""
    import tifffile

    import photogrammetry.imagery.images as imagery
    rng = np.random.default_rng(1)
    img = cv2.GaussianBlur(rng.integers(0, 255, (3000, 700)).astype(np.uint8), (0, 0), 3)
    kw = dict(rowsperstrip=64) if layout == "strips" else dict(tile=(256, 128))
    if layout == "tiles16":
        img = img.astype(np.uint16) * 200
    tifffile.imwrite(tmp_path / "big.tif", np.dstack([img] * 3), compression="zlib", **kw)
    ref = read_grey(tmp_path / "big.tif", 600).pixels
    monkeypatch.setattr(imagery, "BANDED_PIXELS", 1000)
    banded = read_grey(tmp_path / "big.tif", 600).pixels
    assert banded.shape == ref.shape == (600, 140)
    assert np.abs(banded.astype(int) - ref).max() <= 2


def test_build_tracks_by_hand():
    """Matches 0-1, 1-2 join three images; a chain that returns to an image twice is
    dropped."""
    m = [PairMatches(0, 1, np.array([0, 1]), np.array([5, 6]), 0, 0, np.zeros(0)),
         PairMatches(1, 2, np.array([5, 6]), np.array([9, 3]), 0, 0, np.zeros(0)),
         PairMatches(0, 2, np.array([2]), np.array([3]), 0, 0, np.zeros(0))]
    tracks, conflicts = build_tracks([3, 7, 10], m)
    assert conflicts == 1                       # 1(0)-6(1)-3(2)-2(0): image 0 twice
    assert [t.tolist() for t in tracks] == [[[0, 0], [1, 5], [2, 9]]]


def test_band_excludes_matches_off_the_epipolar_line():
    """Two nadir views 100 m apart along x: a keypoint's twin with the same descriptor is
    taken on its epipolar line, refused 20 px off it."""
    f = 5.0
    vi = PriorView(np.array([0.0, 0, 300]), np.eye(3), 0.0, 0.0)
    vj = PriorView(np.array([100.0, 0, 300]), np.eye(3), 0.0, 0.0)
    G = np.array([[50.0, 20.0, 0.0]])
    xi = -f * (G[:, :2] - vi.X0_m[:2]) / (G[:, 2:] - 300.0)
    xj = -f * (G[:, :2] - vj.X0_m[:2]) / (G[:, 2:] - 300.0)
    d = np.eye(4, dtype=np.float32)[:2]
    on = np.vstack([xj, xj + [0.0, 0.2]])          # twin on the line / 20 px across it
    ii, jj, _ = guided_matches(d[:1], d[[0, 1]], xi, on, vi, vj, f, (-10, 10), 0.03)
    assert ii.tolist() == [0] and jj.tolist() == [0]
    ii, jj, _ = guided_matches(d[:1], d[[1, 0]], xi, on, vi, vj, f, (-10, 10), 0.03)
    assert ii.tolist() == []


def test_write_read_tiepoints_round_trip(tmp_path):
    p = tmp_path / "t.csv"
    xy = np.array([[1.25, -2.5], [0.1234567, 3.0]])
    write_tiepoints(p, ["a", "b"], ["1", "1"], xy, sigma_px=0.4, pixel_size_mm=0.01)
    tp = read_tiepoints(p)
    assert tp.image_id == ("a", "b") and tp.point_id == ("1", "1")
    np.testing.assert_allclose(tp.xy_mm, xy, atol=1e-7)
    assert tp.sigma_mm == pytest.approx(0.004)


def _args(block, paths, out):
    return ["tiepoints", *paths, "--eo", block["eo"], "--camera", block["camera"],
            "--ground-height-m", "0", "-o", out, "-q"]


def test_bad_inputs(block, tmp_path, capsys):
    out = str(tmp_path / "t.csv")
    # an image of the EO that does not exist
    missing = str(block["dir"] / "S1_1.jpg")
    assert main(_args(block, [missing, block["paths"][1]], out)) == 2
    assert "S1_1.jpg" in capsys.readouterr().err
    # an image whose name is no EO id
    other = str(tmp_path / "X9.png")
    cv2.imwrite(other, np.zeros((360, 480), np.uint8))
    assert main(_args(block, [other, block["paths"][1]], out)) == 2
    err = capsys.readouterr().err
    assert "X9" in err and "not in" in err
    # an image of another size than the camera's
    small = str(tmp_path / "S1_2.png")
    cv2.imwrite(small, np.zeros((100, 100), np.uint8))
    assert main(_args(block, [block["paths"][0], small], out)) == 2
    assert "100 x 100" in capsys.readouterr().err
    # one id twice
    assert main(_args(block, [block["paths"][0], block["paths"][0]], out)) == 2
    assert "twice" in capsys.readouterr().err
    # output over an input
    assert main(_args(block, block["paths"][:2], block["eo"])) == 2
    assert not os.path.exists(out)


def test_pairs_ignore_points_folded_back_by_the_distortion():
    """Strong barrel distortion (OpenSfM k1 = -0.26, the DJI camera's) folds points at
    2 x the frame's radius back onto it: two nadir views 200 m apart at 100 m, which
    share no ground, are no pair; 60 m apart they are."""
    from photogrammetry.imagery.matching import select_pairs
    from photogrammetry.sfm.opensfm import camera_from_opensfm
    cam = camera_from_opensfm({"projection_type": "brown", "width": 1368, "height": 912,
                               "focal_x": 0.666, "focal_y": 0.666, "c_x": 0.0, "c_y": 0.0,
                               "k1": -0.264, "k2": 0.102, "k3": -0.0258, "p1": 0.0,
                               "p2": 0.0})
    xy = cam.pixel_to_photo(np.array([[1367.0, 455.5]]))
    u = cam.undistort(xy)[0] * 2.0
    assert cam.inside(cam.photo_to_pixel(cam.distort(u[None])))[0]     # the fold exists
    far = [PriorView(np.array([0.0, 0, 100]), np.eye(3), 0.01, 0.1),
           PriorView(np.array([200.0, 0, 100]), np.eye(3), 0.01, 0.1)]
    assert select_pairs(far, cam, 0.0) == []
    near = [far[0], PriorView(np.array([60.0, 0, 100]), np.eye(3), 0.01, 0.1)]
    assert [p[:2] for p in select_pairs(near, cam, 0.0)] == [(0, 1)]


def test_dask_workers_give_the_same_file(block, tmp_path):
    out = str(tmp_path / "w.csv")
    assert main(["tiepoints", *block["paths"], "--eo", block["eo"], "--camera",
                 block["camera"], "--ground-height-m", "0", "--relief-m", "15", "-o", out,
                 "-q", "--workers", "2"]) == 0
    with open(out) as a, open(block["tp"]) as b:
        assert a.read() == b.read()


def test_dem_height_range(tmp_path):
    """A hand-written float GeoTIFF with GDAL's nodata tag: the range of its valid
    heights, less origin_h_m for an ENU frame, as is for a projected frame."""
    import tifffile

    from photogrammetry.imagery.tiepoints_images import dem_height_range
    z = np.linspace(80.0, 120.0, 200 * 100).reshape(100, 200).astype(np.float32)
    z[:10] = -9999.0
    tifffile.imwrite(tmp_path / "dem.tif", z, extratags=[(42113, "s", 0, "-9999", True)])
    lo, hi = dem_height_range(tmp_path / "dem.tif", "EPSG:32650; heights = ellipsoidal")
    valid = z[10:]
    assert lo == pytest.approx(np.percentile(valid, 0.5)) and lo > 80
    assert hi == pytest.approx(np.percentile(valid, 99.5)) and hi < 120
    lo2, hi2 = dem_height_range(tmp_path / "dem.tif", "enu; origin_lat_deg = 30.0; "
                                "origin_lon_deg = 114.0; origin_h_m = 20.0")
    assert (lo2, hi2) == pytest.approx((lo - 20.0, hi - 20.0))


def test_feature_cache_kept_and_reused(block, tmp_path):
    """--cache DIR: one file per image, the same tie-point file as without it (and with
    two images in memory at once); a second run reuses the files (not rewritten); a
    changed setting detects again."""
    cache = tmp_path / "feat"
    out = str(tmp_path / "c.csv")
    args = ["tiepoints", *block["paths"], "--eo", block["eo"], "--camera", block["camera"],
            "--ground-height-m", "0", "--relief-m", "15", "-q", "--cache", str(cache),
            "--cache-images", "2"]
    assert main(args + ["-o", out]) == 0
    assert sorted(p.name for p in cache.iterdir()) == sorted(f"{i}.npz" for i in block["ids"])
    with open(out) as a, open(block["tp"]) as b:
        assert a.read() == b.read()
    stamp = {p.name: p.stat().st_mtime_ns for p in cache.iterdir()}
    assert main(args + ["-o", str(tmp_path / "d.csv")]) == 0
    assert {p.name: p.stat().st_mtime_ns for p in cache.iterdir()} == stamp
    with open(tmp_path / "d.csv") as a, open(block["tp"]) as b:
        assert a.read() == b.read()
    assert main(args[:-4] + ["--max-features", "500", "--cache", str(cache), "-o",
                             str(tmp_path / "e.csv")]) == 0
    assert all(p.stat().st_mtime_ns != stamp[p.name] for p in cache.iterdir())
    assert not [n for n in os.listdir(cache) if not n.endswith(".npz") or n.startswith(".")]


def test_feature_store_holds_at_most_its_images(tmp_path):
    """The LRU: at most max_images in memory, the least recently used dropped first;
    the temporary folder removed on close."""
    from photogrammetry.imagery.feature_cache import FeatureStore
    rng = np.random.default_rng(1)
    with FeatureStore(None, 2, ideal=lambda uv: uv * 2.0) as store:
        folder = store.folder
        for k in range(4):
            store.put(k, f"im{k}", "key", rng.normal(size=(5 + k, 2)),
                      rng.random((5 + k, 128)), 2.0)
        assert store.lookup(3, "im3", "key") == (8, 2.0)
        assert store.lookup(3, "im3", "other") is None
        uv0, d0, xy0, s0 = store.get(0)
        np.testing.assert_array_equal(xy0, 2.0 * uv0)
        assert d0.dtype == np.float16 and d0.shape == (5, 128) and s0 == 2.0
        store.get(1)
        store.get(0)                                  # 0 most recent: 1 goes next
        store.get(2)
        assert list(store._lru) == [0, 2] and store.loads == 3
        store.get(0)
        assert store.loads == 3                       # still held
        store.get(3)
        assert list(store._lru) == [0, 3] and len(store._lru) <= 2
    assert not os.path.exists(folder)
