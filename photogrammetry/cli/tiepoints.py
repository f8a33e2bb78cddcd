"""``photogrammetry tiepoints``: tie points from images guided by their prior EO."""
import argparse
import os

import numpy as np

from ins.cli.util import Progress, positive_int
from ins.common.errors import InputError
from ins.common.fileio import check_output_file

EPILOG = """\
frames and units:
  EO.csv is the prior exterior orientation (docs/interfaces.md: positions X_m Y_m Z_m in
  the mapping frame, angles deg in the named system, R = C_mc takes a camera ray
  (x, y, -f) into the mapping frame; optional sigma columns).  Each image's file name
  without extension (or with it) is its EO image_id.  CAM.toml is the full-frame camera
  (the images must have its width_px x height_px); distortion is removed before any
  geometry.  The ground lies between Z = H - R and H + R (mapping-frame heights, m:
  --ground-height-m H --relief-m R), or spans the heights of a DEM GeoTIFF (--dem;
  for an ENU frame Z = h - origin_h_m, for a projected frame the DEM's own heights).

method:
  SIFT keypoints (RootSIFT) on a level of at most --max-side-px, in 3 x 3 tiles; pairs
  whose prior footprints on the ground overlap by --min-overlap of the frame; for each
  keypoint of image i, the candidates of image j lie within a band around the segment
  of its epipolar line between the ground heights, of half-width
    n_sigma * sqrt(2 (f + r^2/f)^2 s_ang^2 + 2 (f s_pos / D)^2) + 3 level px
  (s_ang, s_pos: RMS prior angle (rad) and position (m) sigmas of the EO file, else
  --angle-sigma-deg, --position-sigma-m; r the half diagonal, D the distance to the
  ground); ratio test and mutual nearest neighbour; essential matrix by MAGSAC
  (--ransac-px level px); pairs with fewer than --min-inliers matches dropped; tracks
  through all pairs (a track seen twice in one image is dropped).

memory:
  each image's keypoints (px) and descriptors go to a file (--cache DIR, else a
  temporary folder) as it is detected; matching a pair loads its two images through a
  set of --cache-images images in memory, so the features' memory does not grow with
  the block (about 1.1 MB per held image at 4000 keypoints).

output:
  TIEPOINTS.csv: image_id,point_id,x_mm,y_mm (observed photo coordinates, mm, x right,
  y up from the principal point), header sigma_px = the matches' scatter about their
  epipolar geometry (1.4826 x median Sampson distance, full-frame px), which refine
  takes as the weight.  A summary per pair on stdout (unless -q).

example:
  photogrammetry tiepoints images/*.jpg --eo eo.csv --camera camera.toml \\
      --ground-height-m 0 --relief-m 30 -o tiepoints.csv
"""


def _positive(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (np.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return v


def _nonnegative(text):
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (np.isfinite(v) and v >= 0):
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return v


def add_parser(sub):
    p = sub.add_parser(
        "tiepoints", help="tie points from images guided by their prior EO",
        description="Find tie points in overlapping images: SIFT features, matching "
                    "inside the epipolar bands of the prior exterior orientation, "
                    "essential-matrix verification and multi-image tracks.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("images", nargs="+", metavar="IMAGE", help="JPEG, TIFF/GeoTIFF, PNG")
    p.add_argument("--eo", required=True, metavar="EO.csv", help="prior EO (EO CSV)")
    p.add_argument("--camera", required=True, metavar="CAM.toml", help="camera file")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--dem", metavar="DEM.tif", help="ground heights from a DEM GeoTIFF")
    g.add_argument("--ground-height-m", type=float, metavar="H",
                   help="mean ground height, mapping-frame Z (m)")
    p.add_argument("--relief-m", type=_nonnegative, default=None, metavar="R",
                   help="ground within H +- R (m; default 10 %% of the flying height)")
    p.add_argument("--angle-sigma-deg", type=_positive, default=1.0, metavar="DEG",
                   help="prior angle sigma when the EO has none (default 1 deg)")
    p.add_argument("--position-sigma-m", type=_positive, default=1.0, metavar="M",
                   help="prior position sigma when the EO has none (default 1 m)")
    p.add_argument("--n-sigma", type=_positive, default=3.0, help="band width in sigmas (3)")
    p.add_argument("--ratio", type=_positive, default=0.8, help="ratio test (0.8)")
    p.add_argument("--max-side-px", type=positive_int, default=3000, metavar="PX",
                   help="longer side of the level searched, px (3000)")
    p.add_argument("--max-features", type=positive_int, default=4000, metavar="N",
                   help="keypoints per image (4000)")
    p.add_argument("--min-overlap", type=_positive, default=0.1, metavar="FRACTION",
                   help="smallest footprint overlap of a pair (0.1)")
    p.add_argument("--min-inliers", type=positive_int, default=15, metavar="N",
                   help="fewest verified matches of a pair (15)")
    p.add_argument("--ransac-px", type=_positive, default=1.5, metavar="PX",
                   help="MAGSAC threshold, level px (1.5)")
    p.add_argument("--workers", type=positive_int, metavar="N",
                   help="Dask threads for detection and matching")
    p.add_argument("--cache", metavar="DIR", help="keep each image's keypoints and "
                   "descriptors in DIR (reused next time for unchanged images and "
                   "settings; default: a temporary folder, removed)")
    p.add_argument("--cache-images", type=positive_int, metavar="N",
                   help="images whose features are held in memory at once (default "
                        "2 x workers + 2, at least 4; >= 2)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.add_argument("-o", "--output", required=True, metavar="TIEPOINTS.csv")
    p.set_defaults(func=run)


def run(args):
    from photogrammetry.imagery.tiepoints import write_tiepoints
    from photogrammetry.imagery.tiepoints_images import (
        MatchSettings,
        dem_height_range,
        match_images,
    )
    from photogrammetry.orientation.camera import read_camera
    from photogrammetry.orientation.exposure import read_eo_csv

    check_output_file(args.output)
    out = os.path.abspath(args.output)
    for p in [args.eo, args.camera, args.dem] + list(args.images):
        if p is not None and os.path.abspath(p) == out:
            raise InputError(f"--output {args.output} would overwrite the input file {p}")
    if args.ratio >= 1:
        raise InputError(f"--ratio must be < 1, got {args.ratio}")
    if args.min_overlap > 1:
        raise InputError(f"--min-overlap is a fraction of the frame (0..1], got "
                         f"{args.min_overlap}")
    if args.ground_height_m is not None and not -1e4 <= args.ground_height_m <= 1e5:
        raise InputError(f"--ground-height-m must be a mapping-frame height in -10000 .. "
                         f"100000 m, got {args.ground_height_m:g}")
    camera, _ = read_camera(args.camera)
    eo = read_eo_csv(args.eo)
    if args.dem:
        z_range = dem_height_range(args.dem, eo.frame)
        if args.relief_m:
            z_range = (z_range[0] - args.relief_m, z_range[1] + args.relief_m)
    else:
        relief = args.relief_m
        if relief is None:
            relief = 0.1 * float(np.median(np.abs(eo.position[:, 2] - args.ground_height_m)))
        z_range = (args.ground_height_m - relief, args.ground_height_m + relief)
    settings = MatchSettings(max_side_px=args.max_side_px, max_features=args.max_features,
                             angle_sigma_rad=np.deg2rad(args.angle_sigma_deg),
                             position_sigma_m=args.position_sigma_m, n_sigma=args.n_sigma,
                             ratio=args.ratio, min_overlap=args.min_overlap,
                             min_inliers=args.min_inliers, ransac_px=args.ransac_px)
    progress = Progress("tiepoints", not args.quiet, unit="images+pairs")
    if args.cache_images is not None and args.cache_images < 2:
        raise InputError(f"--cache-images must be >= 2 (a pair), got {args.cache_images}")
    res = match_images(args.images, eo, camera, z_range, settings, workers=args.workers,
                       progress=progress, eo_path=args.eo, cache_dir=args.cache,
                       cache_images=args.cache_images)
    if res.n_tracks == 0:
        raise InputError("no tie points: no pair of images kept --min-inliers verified "
                         "matches (check the EO, the camera and the ground heights)")
    kept = sum(p["kept"] for p in res.pairs)
    write_tiepoints(args.output, res.image_id, res.point_id, res.xy_mm, res.sigma_px,
                    camera.pixel_size_mm, comments=(
                        f"from {len(args.images)} images by photogrammetry tiepoints; prior "
                        f"EO = {args.eo}; camera = {args.camera}",
                        f"{res.n_tracks} tracks, {len(res.image_id)} observations, "
                        f"{kept} of {len(res.pairs)} pairs"))
    if not args.quiet:
        for p in res.pairs:
            print(f"{p['i']} {p['j']}: overlap {p['overlap']:.2f}, {p['candidates']} "
                  f"keypoints with candidates, {p['guided']} guided matches, "
                  f"{p['inliers']} verified" + ("" if p["kept"] else " (dropped)"))
        hist = np.bincount(res.track_lengths)
        lengths = ", ".join(f"{n} of {k} images" for k, n in enumerate(hist) if n)
        print(f"{res.n_tracks} tracks ({lengths}"
              f"; {res.n_conflicting} conflicting dropped), {len(res.image_id)} observations, "
              f"sigma {res.sigma_px:.3f} px")
        print(f"wrote {args.output}")
    return 0
