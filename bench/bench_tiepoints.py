"""Tie points from images: reading a DMC-size frame (7680 x 13824 px) in bounded memory,
and the matching of a rendered block.  Prints figures.

    .venv/bin/python bench/bench_tiepoints.py [--big] [--strips 2 --per-strip 4]
        [--memory 16,32,64,128]

``--big`` writes a 7680 x 13824 RGB frame as JPEG and as tiled, compressed TIFF (zlib)
in a temporary folder (about 1 min) and reads each in a fresh process (peak RSS:
VmHWM of /proc/self/status, which exec resets, unlike ru_maxrss), at the default level
(longer side 3000 px): JPEG decoded at 1/4 by pillow's draft, TIFF tile by tile reduced
band by band ("level"), and for comparison the TIFF decoded whole ("whole").  The block: 640 x 480 px images of a seeded
terrain (photogrammetry.simulate.render), priors 0.2 deg off; time per stage and the
tracks' agreement with the truth (ground spread of each track with the true EO).

``--memory N,...``: peak RSS of ``match_images`` (fresh process, VmHWM) against the number
of images, with every image's features held in memory (``cache_images = N``: what
tiepoints did before the feature cache) and with the default LRU of 4 images (features
on disk, :mod:`photogrammetry.imagery.feature_cache`).  The images are 1000 x 750 px nadir crops
of one multi-scale noise texture, strips of 16 with 60 % forward and side overlap
(pairs: the neighbours along and across the strips), priors exact with sigma 0.1 deg,
--max-features 4000 (about 2650 found per image).  Measured (2 shared cores, load 4):

    images pairs tracks |      all held (before) | LRU of 4 (feature cache)
        16    15  13910 |      215 MiB    25.3 s  |      205 MiB    44.5 s
        32    46  23335 |      227 MiB   128.0 s  |      206 MiB    64.4 s
        64   108  40093 |      251 MiB   146.1 s  |      213 MiB   102.6 s
       128   232  74280 |      305 MiB   262.8 s  |      214 MiB   355.0 s

+0.8 MiB per image before, +0.08 after (matches and tracks); the times follow the
other processes' load (a reload from the cache costs 10 ms).
"""
import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

READ = """
import json, sys, time
import photogrammetry.imagery.images as im
if sys.argv[3] == 'whole':
    im.BANDED_PIXELS = 10**12
t = time.perf_counter()
lv = im.read_grey(sys.argv[1], int(sys.argv[2]))
dt = time.perf_counter() - t
hwm = [ln for ln in open("/proc/self/status") if ln.startswith("VmHWM")][0].split()[1]
print(json.dumps({"s": dt, "shape": list(lv.pixels.shape), "rss_mb": int(hwm) / 1024}))
"""


def big_frames(d):
    import cv2
    import tifffile
    rng = np.random.default_rng(0)
    small = rng.integers(0, 255, (13824 // 16, 7680 // 16, 3), dtype=np.uint8)
    img = cv2.resize(small, (7680, 13824), interpolation=cv2.INTER_CUBIC)
    cv2.imwrite(str(d / "big.jpg"), img, [cv2.IMWRITE_JPEG_QUALITY, 90])
    tifffile.imwrite(d / "big.tif", img, tile=(512, 512), compression="zlib")
    print(f"frame 7680 x 13824 x 3 = {img.nbytes / 2**20:.0f} MiB in memory when decoded")
    del img
    for name, mode in (("big.jpg", "level"), ("big.tif", "level"), ("big.tif", "whole")):
        out = subprocess.run([sys.executable, "-c", READ, str(d / name), "3000", mode],
                             capture_output=True, text=True, check=True).stdout
        r = json.loads(out)
        print(f"read_grey {name:8s} {mode:7s}: {r['s']:6.2f} s, level {r['shape']}, "
              f"peak RSS {r['rss_mb']:.0f} MiB")


def block(strips, per_strip):
    import cv2

    from photogrammetry.adjustment.batch import refine
    from photogrammetry.imagery.tiepoints import TiePoints
    from photogrammetry.imagery.tiepoints_images import match_images
    from photogrammetry.orientation.camera import FrameCamera
    from photogrammetry.orientation.exposure import ExposureOrientation
    from photogrammetry.orientation.rotation import angles_to_matrix
    from photogrammetry.simulate.render import make_texture, ray_ground, render_view
    from photogrammetry.simulate.terrain import make_terrain
    rng = np.random.default_rng(5)
    cam = FrameCamera(5.0, 0.01, 640, 480, (319.5, 239.5), (1e-3, 0, 0), (0, 0))
    terrain = make_terrain(15.0, 200.0, rng)
    ids, X, ang = [], [], []
    for s in range(strips):
        for k in range(per_strip):
            ids.append(f"S{s + 1}_{k + 1}")
            X.append((k * 154.0, s * 180.0, 300.0))
            ang.append(np.deg2rad(rng.normal(0, 1.0, 3)) + [0, 0, np.pi * (s % 2)])
    X, ang = np.array(X), np.array(ang)
    tex = make_texture(rng, (-300, X[:, 0].max() + 300), (-300, X[:, 1].max() + 300), 0.3)
    n = len(ids)
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        paths = []
        for k, iid in enumerate(ids):
            paths.append(f"{d}/{iid}.png")
            cv2.imwrite(paths[-1], render_view(cam, X[k], angles_to_matrix(
                ang[k], "phi-omega-kappa"), terrain, tex))
        t_render = time.perf_counter() - t
        prior = ang + np.deg2rad(rng.normal(0, 0.2, ang.shape))
        prior[0] = ang[0]
        eo = ExposureOrientation(ids, np.arange(n, dtype=float), X, prior, "phi-omega-kappa",
                                 "enu; origin_lat_deg = 30; origin_lon_deg = 114; "
                                 "origin_h_m = 0", np.full((n, 3), 0.05),
                                 np.full((n, 3), np.deg2rad(0.3)))
        t = time.perf_counter()
        res = match_images(paths, eo, cam, (-15.0, 15.0))
        t_match = time.perf_counter() - t
    ground = {}
    for iid, pid, xy in zip(res.image_id, res.point_id, res.xy_mm):
        k = ids.index(iid)
        ray = cam.rays(cam.undistort(xy[None])) @ angles_to_matrix(ang[k],
                                                                   "phi-omega-kappa").T
        ground.setdefault(pid, []).append(ray_ground(X[k], ray, terrain)[0])
    spread = np.array([np.max(np.linalg.norm(np.array(g) - np.mean(g, 0), axis=1))
                       for g in ground.values()])
    gsd = 300 * 0.01 / 5.0
    print(f"\nblock {strips} x {per_strip} images 640 x 480: render {t_render:.1f} s, "
          f"tie points {t_match:.1f} s ({sum(p['kept'] for p in res.pairs)} pairs, "
          f"{res.n_tracks} tracks, {len(res.image_id)} observations, sigma "
          f"{res.sigma_px:.3f} px)")
    print(f"track lengths {dict(enumerate(np.bincount(res.track_lengths)))}")
    print(f"ground spread of the tracks (true EO): median {np.median(spread) / gsd:.2f} "
          f"GSD, 95 % {np.percentile(spread, 95) / gsd:.2f} GSD, above 3 GSD "
          f"{100 * np.mean(spread > 3 * gsd):.2f} %")
    tp = TiePoints("bench", tuple(res.image_id), tuple(res.point_id), res.xy_mm,
                   np.arange(len(res.image_id)), res.sigma_px * cam.pixel_size_mm)
    t = time.perf_counter()
    r = refine(eo, tp, camera=cam, datum="first")
    err = np.rad2deg(np.abs((r.eo.angles - ang + np.pi) % (2 * np.pi) - np.pi))[1:] * 3600
    print(f"refine {time.perf_counter() - t:.1f} s: |error| max {err.max():.1f} arcsec "
          f"(priors {np.rad2deg(np.abs(prior - ang)).max() * 3600:.0f} arcsec), max "
          f"|error|/sigma {(err / (np.rad2deg(r.eo.angle_sigma[1:]) * 3600)).max():.2f}")


MATCH = """
import json, sys, time
from photogrammetry.orientation.camera import read_camera
from photogrammetry.orientation.exposure import read_eo_csv
from photogrammetry.imagery.tiepoints_images import MatchSettings, match_images
d, lru = sys.argv[1], int(sys.argv[2])
eo = read_eo_csv(d + "/eo.csv")
cam, _ = read_camera(d + "/cam.toml")
paths = [d + "/" + i + ".png" for i in eo.image_id]
t = time.perf_counter()
r = match_images(paths, eo, cam, (-1.0, 1.0), MatchSettings(min_overlap=0.5),
                 cache_images=lru)
dt = time.perf_counter() - t
hwm = [ln for ln in open("/proc/self/status") if ln.startswith("VmHWM")][0].split()[1]
print(json.dumps({"s": dt, "rss_mb": int(hwm) / 1024, "pairs": len(r.pairs),
                  "tracks": r.n_tracks, "features": sum(r.n_features)}))
"""


def crop_block(d, n, per_strip=16):
    """n nadir 1000 x 750 crops of one texture (module docstring) with their EO."""
    import cv2

    from photogrammetry.orientation.camera import FrameCamera, write_camera
    from photogrammetry.orientation.exposure import ExposureOrientation, write_eo_csv
    w, h, step_u, step_v, gsd = 1000, 750, 400, 300, 0.5
    strips = -(-n // per_strip)
    W, H = step_u * (min(n, per_strip) - 1) + w, step_v * (strips - 1) + h
    rng = np.random.default_rng(3)
    tex = np.zeros((H, W), np.float32)
    for s, a in ((3, 1.0), (12, 1.5), (48, 2.0)):
        small = rng.normal(0, a, (H // s + 2, W // s + 2)).astype(np.float32)
        tex += cv2.resize(small, (W, H), interpolation=cv2.INTER_CUBIC)
    tex = np.clip(128 + 30 * tex, 0, 255).astype(np.uint8)
    cam = FrameCamera(10.0, 0.01, w, h, ((w - 1) / 2, (h - 1) / 2), (0, 0, 0), (0, 0))
    ids, X = [], []
    for k in range(n):
        c0, r0 = step_u * (k % per_strip), step_v * (k // per_strip)
        ids.append(f"C{k:04d}")
        cv2.imwrite(str(d / f"{ids[-1]}.png"), tex[r0:r0 + h, c0:c0 + w])
        X.append(((c0 + (w - 1) / 2) * gsd, -(r0 + (h - 1) / 2) * gsd, 500.0))
    eo = ExposureOrientation(ids, np.arange(n, dtype=float), np.array(X), np.zeros((n, 3)),
                             "omega-phi-kappa", "enu; origin_lat_deg = 30; origin_lon_deg "
                             "= 114; origin_h_m = 0", np.full((n, 3), 0.1),
                             np.full((n, 3), np.deg2rad(0.1)))
    write_eo_csv(d / "eo.csv", eo)
    write_camera(d / "cam.toml", cam)


def memory(sizes):
    print("\npeak RSS of match_images against the images (1000 x 750 px, --max-features 4000 "
          "; fresh process)")
    print(f"{'images':>6} {'pairs':>5} {'tracks':>6} | {'all held (before)':>22} | "
          f"{'LRU of 4 (feature cache)':>24}")
    for n in sizes:
        with tempfile.TemporaryDirectory() as d:
            crop_block(Path(d), n)
            row = []
            for lru in (n, 4):
                out = subprocess.run([sys.executable, "-c", MATCH, d, str(lru)],
                                     capture_output=True, text=True, check=True).stdout
                row.append(json.loads(out))
        a, b = row
        print(f"{n:6d} {a['pairs']:5d} {a['tracks']:6d} | {a['rss_mb']:8.0f} MiB {a['s']:7.1f} s"
              f"  | {b['rss_mb']:8.0f} MiB {b['s']:7.1f} s", flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--big", action="store_true")
    ap.add_argument("--strips", type=int, default=2)
    ap.add_argument("--per-strip", type=int, default=4)
    ap.add_argument("--memory", metavar="N,N,...", help="peak RSS against images")
    a = ap.parse_args()
    if a.memory:
        memory([int(v) for v in a.memory.split(",")])
        sys.exit(0)
    if a.big:
        with tempfile.TemporaryDirectory() as d:
            big_frames(Path(d))
    block(a.strips, a.per_strip)
