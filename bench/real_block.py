"""The real DJI block of issue 14 item 4: from the images and the drone's metadata alone
(EO from the XMP gimbal angles and RTK positions, tie points from the images), refine,
and compare the gimbal angles and the refined ones with the OpenSfM bundle adjustment.
Prints figures.

    .venv/bin/python bench/real_block.py [--real ../shared/real] [--camera odm|dji]
        [--max-features 8000]

The bundle's world frame differs from the RTK positions' by a rotation about the
vertical (fitted here: Helmert, SVD); the comparisons are in the RTK datum (the bundle
rotated by it), and also raw.  Camera ``odm``: the reconstruction's calibrated "brown"
camera; ``dji``: the drone's DewarpData (its factory calibration).
"""
import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from photogrammetry.adjustment.batch import refine
from photogrammetry.cli.main import main
from photogrammetry.imagery.tiepoints import read_tiepoints
from photogrammetry.orientation.camera import read_camera, write_camera
from photogrammetry.orientation.drone import camera_from_dji, gimbal_angles, read_drone_shot
from photogrammetry.orientation.exposure import read_eo_csv
from photogrammetry.orientation.mapping import EnuFrame
from photogrammetry.orientation.rotation import matrix_to_angles
from photogrammetry.sfm.opensfm import read_reconstruction

SYSTEM = "omega-phi-kappa"


def helmert(A, B):
    ca, cb = A.mean(0), B.mean(0)
    U, S, Vt = np.linalg.svd((A - ca).T @ (B - cb))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    s = np.trace(np.diag(S) @ D) / np.sum((A - ca) ** 2)
    return s, R, cb - s * R @ ca


def wrap_deg(a):
    return np.rad2deg((a + np.pi) % (2 * np.pi) - np.pi)


def table(title, ids, rows):
    print(f"\n{title}")
    print(f"{'image':15s} {'omega':>8s} {'phi':>8s} {'kappa':>8s}")
    for i, r in zip(ids, rows):
        print(f"{i:15s} " + " ".join(f"{v:8.3f}" for v in r))


def main_(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--real", default=str(Path(__file__).resolve().parents[2] / "shared"
                                          / "real"))
    ap.add_argument("--camera", choices=["odm", "dji"], default="odm")
    ap.add_argument("--max-features", default="8000")
    a = ap.parse_args(argv)
    real = Path(a.real) / "odm_drone_block"
    bundle = read_reconstruction(real / "opensfm" / "reconstruction.json", SYSTEM)
    lat, lon, h = bundle.reference_lla_deg
    images = sorted(str(p) for p in (real / "images").glob("*.tif"))
    with tempfile.TemporaryDirectory() as d:
        eo_csv, cam, tp_csv = f"{d}/eo.csv", f"{d}/cam.toml", f"{d}/tp.csv"
        main(["eo", "--from-exif", *images, "--origin", f"{lat},{lon},{h}", "--system",
              SYSTEM, "-o", eo_csv, "-q"])
        write_camera(cam, next(iter(bundle.cameras.values()))[0] if a.camera == "odm"
                     else camera_from_dji(images[0])[0])
        t0 = time.perf_counter()
        main(["tiepoints", *images, "--eo", eo_csv, "--camera", cam, "--dem",
              str(real / "dsm.tif"), "--max-features", a.max_features, "-o", tp_csv])
        t_tp = time.perf_counter() - t0
        camera, _ = read_camera(cam)
        prior = read_eo_csv(eo_csv)
        tp = read_tiepoints(tp_csv, camera)
    order = [bundle.eo.image_id.index(i) for i in prior.image_id]
    s, R, t = helmert(bundle.eo.position[order], prior.position)
    resid = s * bundle.eo.position[order] @ R.T + t - prior.position
    rv = Rotation.from_matrix(R).as_rotvec(degrees=True)
    print(f"\ntie points: {t_tp:.1f} s; camera {a.camera}; sigma_px (file) "
          f"{tp.sigma_mm / camera.pixel_size_mm:.3f}")
    print(f"bundle -> RTK Helmert: rotation {rv.round(3)} deg, scale {s:.6f}, residuals "
          f"max {np.abs(resid).max() * 100:.1f} cm")
    raw = bundle.eo.angles[order]
    rtk = matrix_to_angles(R @ bundle.eo.matrices()[order], SYSTEM)
    ids = prior.image_id
    table("gimbal - bundle (raw), deg", ids, wrap_deg(prior.angles - raw))
    table("gimbal - bundle (RTK datum), deg", ids, wrap_deg(prior.angles - rtk))
    table("gimbal sigma (stated), deg", ids, np.rad2deg(prior.angle_sigma))
    enu = EnuFrame.from_degrees(lat, lon, h)
    C_mn = enu.C_mn(enu.to_lla(prior.position))
    xmp = np.array([read_drone_shot(p).gimbal_rpy_deg for p in images])
    print("\nthe drone's own terms (XMP roll, pitch, yaw) and the bundle's (RTK datum), deg")
    print(f"{'image':15s} {'roll':>8s} {'pitch':>8s} {'yaw':>8s} | {'roll':>8s} {'pitch':>8s} "
          f"{'yaw':>8s} | gimbal - bundle")
    b_rpy = np.rad2deg(gimbal_angles(R @ bundle.eo.matrices()[order], C_mn))
    for k, i in enumerate(ids):
        d = (xmp[k] - b_rpy[k] + 180) % 360 - 180
        print(f"{i:15s} " + " ".join(f"{v:8.3f}" for v in xmp[k]) + " | "
              + " ".join(f"{v:8.3f}" for v in b_rpy[k]) + " | "
              + " ".join(f"{v:6.3f}" for v in d))
    for method, datum in (("known-base", "none"), ("known-base", "ins"),
                          ("base-free", "ins"), ("relative", "ins")):
        t0 = time.perf_counter()
        res = refine(prior, tp, camera=camera, method=method, datum=datum)
        dt = time.perf_counter() - t0
        st = res.settings
        print(f"\n== refine {method} / datum {datum}: {dt:.2f} s, {st['n_pairs']} pairs, "
              f"sigma0 {res.block.sigma0 * st['sigma_mm'] / camera.pixel_size_mm:.3f} px, "
              f"{int(res.block.rejected.sum())} rejected, redundancy {res.block.redundancy}")
        err = wrap_deg(res.eo.angles - rtk)
        sig = np.rad2deg(res.eo.angle_sigma)
        table("refined - bundle (RTK datum), deg", ids, err)
        table("refined sigma, deg", ids, sig)
        table("(refined - bundle) / sigma", ids, err / sig)
        table("refined - bundle (raw), deg", ids, wrap_deg(res.eo.angles - raw))


if __name__ == "__main__":
    main_()
