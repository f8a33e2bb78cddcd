"""The real DJI block (../shared/real/odm_drone_block, skipped when absent): EO from the
drone's metadata, tie points from the images, refinement with the RTK bases, and the
angles against the OpenSfM bundle adjustment.

The bundle's frame is the RTK positions' up to a rotation of 0.89 deg about the vertical
(its centres fit the RTK centres by a Helmert transformation to 1-2 cm, but its yaw is
ODM's georeferencing): the angles are compared in the RTK datum, the bundle rotated by
that Helmert rotation (fitted here by SVD, Umeyama/Kabsch).  The camera is the block's
calibrated one (the reconstruction's "brown" camera through the import); the
interior orientation is not what the drone's metadata is about."""
from pathlib import Path

import numpy as np
import pytest

from photogrammetry.adjustment.batch import refine
from photogrammetry.cli.main import main
from photogrammetry.imagery.tiepoints import read_tiepoints
from photogrammetry.orientation.camera import read_camera, write_camera
from photogrammetry.orientation.exposure import read_eo_csv
from photogrammetry.orientation.rotation import matrix_to_angles
from photogrammetry.sfm.opensfm import read_reconstruction

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "real" / "odm_drone_block"
SYSTEM = "omega-phi-kappa"

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not REAL.is_dir(), reason="../shared/real is absent")]


def helmert(A, B):
    """Scale s, rotation R, translation t with B ~ s R A + t (least squares, SVD)."""
    ca, cb = A.mean(0), B.mean(0)
    U, S, Vt = np.linalg.svd((A - ca).T @ (B - cb))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    s = np.trace(np.diag(S) @ D) / np.sum((A - ca) ** 2)
    return s, R, cb - s * R @ ca


def _wrap_deg(a):
    return np.rad2deg((a + np.pi) % (2 * np.pi) - np.pi)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("real")
    bundle = read_reconstruction(REAL / "opensfm" / "reconstruction.json", SYSTEM)
    lat, lon, h = bundle.reference_lla_deg
    images = sorted(str(p) for p in (REAL / "images").glob("*.tif"))
    eo_csv, cam_toml, tp_csv = str(d / "eo.csv"), str(d / "cam.toml"), str(d / "tp.csv")
    assert main(["eo", "--from-exif", *images, "--origin", f"{lat},{lon},{h}",
                 "--system", SYSTEM, "-o", eo_csv, "-q"]) == 0
    write_camera(cam_toml, next(iter(bundle.cameras.values()))[0])
    assert main(["tiepoints", *images, "--eo", eo_csv, "--camera", cam_toml, "--dem",
                 str(REAL / "dsm.tif"), "--max-features", "8000", "-o", tp_csv, "-q"]) == 0
    camera, _ = read_camera(cam_toml)
    prior = read_eo_csv(eo_csv)
    tp = read_tiepoints(tp_csv, camera)
    res = refine(prior, tp, camera=camera, method="known-base", datum="none")
    order = [bundle.eo.image_id.index(i) for i in prior.image_id]
    s, R, t = helmert(bundle.eo.position[order], prior.position)
    ref = matrix_to_angles(R @ bundle.eo.matrices()[order], SYSTEM)
    return dict(bundle=bundle, order=order, prior=prior, tp=tp, res=res, helmert=(s, R, t),
                ref=ref)


def test_tie_points(run):
    tp = run["tp"]
    assert len(tp) > 1000 and len(set(tp.point_id)) > 500
    assert run["res"].settings["n_pairs"] == 5              # 0018-0140 face away
    assert 0.2 < tp.sigma_mm / 0.01 < 1.0                    # px


def test_bundle_is_the_rtk_frame_rotated(run):
    s, R, t = run["helmert"]
    A = run["bundle"].eo.position[run["order"]]
    resid = s * A @ R.T + t - run["prior"].position
    assert np.abs(resid).max() < 0.03 and abs(s - 1) < 1e-3
    from scipy.spatial.transform import Rotation
    rv = Rotation.from_matrix(R).as_rotvec(degrees=True)
    assert 0.8 < rv[2] < 1.0 and np.abs(rv[:2]).max() < 0.05


def test_refined_agree_with_the_bundle_within_their_sigmas(run):
    res, ref, prior = run["res"], run["ref"], run["prior"]
    err = _wrap_deg(res.eo.angles - ref)
    sig = np.rad2deg(res.eo.angle_sigma)
    assert np.all(np.abs(err) < 3 * sig), (err, sig)
    gimbal = _wrap_deg(prior.angles - ref)
    assert np.all(np.abs(gimbal) < 1.5)                      # the drone's own errors
    assert np.sqrt(np.mean(err ** 2)) < 0.2 * np.sqrt(np.mean(gimbal ** 2))
    sigma0_px = res.block.sigma0 * res.settings["sigma_mm"] / 0.01
    assert 0.2 < sigma0_px < 1.0
