"""``photogrammetry refine``: coplanarity adjustment of the INS exposure angles."""
import argparse
import os
import warnings

import numpy as np

from ins.cli.util import Progress, nonnegative_int, positive_int
from ins.common import interrupts
from ins.common.errors import InputError, QualityWarning
from ins.common.fileio import check_output_file

EPILOG = """\
frames and units:
  EO.csv is the INS exterior orientation (docs/interfaces.md): positions X_m Y_m Z_m in
  the mapping frame (ENU at the block origin, or a projection), angles in deg in the
  named system (R = C_mc takes a camera ray (x, y, -f) into the mapping frame; active
  elementary rotations):
    phi-omega-kappa  R = Ry(-phi) Rx(omega) Rz(kappa), the textbooks' sign:
                     a3 = R[0,2] = -sin(phi) cos(omega), phi = atan2(-a3, c3)
    omega-phi-kappa  R = Rx(omega) Ry(phi) Rz(kappa)
  TIEPOINTS.csv: image_id,point_id,x_mm,y_mm (observed photo coordinates, mm, origin at
  the principal point) or image_id,point_id,u_px,v_px.  CAM.toml gives f, pixel size
  and distortion (removed before the adjustment): [camera] focal_length_mm,
  pixel_size_mm, width_px, height_px, principal_point_px required; radial_k and
  tangential_p optional (zeros); [mounting] optional (nadir axes, zero lever arm and
  boresight); unknown sections or keys are errors (docs/interfaces.md).

methods:
  known-base  det[b, R1 u1, R2 u2] = 0 with the base b from the EO positions (GNSS);
              their sigmas (EO file or --position-sigma-m, m) are propagated into the
              angles' covariance
  relative    the same with each pair's base direction adjusted (5-parameter RO)
  base-free   the base eliminated (pencil of epipolar planes; no base needed)
datum:
  first  the first image keeps its INS angles (the paper); ins  every image's INS angles
  are weighted observations (EO sigmas or --prior-sigma-deg); none  only known-base.

output:
  REFINED.csv: EO CSV with the refined angles and their sigmas (deg; the photo sigma
  scaled by max(sigma0, 1); position sigmas as given, 0 if none).  REPORT.md with
  REPORT_residuals.png and REPORT_corrections.png: sigma0, redundancy, per-image sigmas
  and correlations, INS-minus-adjusted mean, RMS, INS noise, boresight (rx, ry, rz as in
  the camera file).

boresight sigma (known-base, datum none):
  the estimate holds the INS attitude error common to the exposures (a body-fixed error
  cannot be told from a boresight), so its sigma is stated twice: the adjustment's alone,
  and the total sqrt(adjustment^2 + INS^2) with the INS attitude sigma (roll, pitch, yaw of
  the smoothed trajectory's sigma file, at the exposures, in the camera frame, taken as
  fully correlated over the block: an upper bound).  The sigma file: --ins-std, else the
  EO file's '# trajectory sigma =' line (photogrammetry eo --sigma).  Without one the
  report says the sigma is the adjustment's alone and understates the error.  REFINED.csv
  carries both in its comments (boresight_sigma_adjustment_deg, boresight_sigma_total_deg).

outliers:
  every pair starts robustly (minimal samples of 5 points, 3 with known-base, solved
  exactly from the prior and scored by MSAC at |misclosure| < 5 sigma), is iterated on
  the inliers, then data snooping (Baarda, w > 3.29) runs on the converged pair; after
  the block has converged, snooping on the block's misclosures (per pair the largest
  |g|/sigma_g above 4.0) and the block again.  The result and the rejected points do
  not depend on the prior within a few tenths of a degree.

trust (exit 3 unless --accept-poor):
  - sigma0 (1 = the stated photo sigma) of a pair's screening (redundancy r >= 5) or
    of the block above max(2, sqrt(chi2_q(r) / r)) (q = 0.999 for the block,
    1 - 0.001/P for each of its P pairs);
  - an image whose refined angle differs from its prior by more than
    5 sqrt(2 s_prior^2 + s_adj^2) (s_prior: the EO or --prior-sigma-deg sigma, s_adj:
    the adjusted sigma; with known-base and --datum none after removing the common
    camera-frame rotation, the boresight);
  - a pair whose screening (redundancy >= 5) moved an image beyond 5 deg and 5 of its
    sigmas from its prior (left out);
  - a block left with redundancy < 5 after its outlier tests rejected tie points, or
    with no condition at all (every pair left out: the images keep their priors).
  Any flag: exit 3 and nothing written; with --accept-poor the outputs are written,
  the flags stated in the CSV comments and the report.

  A flight folder (ins simulate) may replace EO.csv TIEPOINTS.csv: its tiepoints.csv and
  camera.toml are used, the EO from --eo or FOLDER/eo.csv.  Several folders run as Dask
  tasks (--workers N local processes, or --scheduler tcp://host:8786); each gets
  refined.csv and report.md unless -o/--report name a single output.

report (--report F):
  F.md (any name but .html/.htm): Markdown with F_residuals.png and F_corrections.png
  beside it.  F.html or F.htm: the same text as one self-contained HTML page (CSS
  inline, both plots embedded as PNG data URIs, no script, nothing fetched: it opens
  offline and can be mailed alone), written atomically; nothing beside it.  The same
  option as 'ins process --report F.html'.

tiles (one large block, --tile-images N):
  the images are cut into tiles of at most N core images (recursive bisection of the EO
  positions x, y), each with a halo of the images within --tile-halo-hops pair-hops
  (default 3: every core image keeps its pairs, its partners theirs, and one ring
  more); each tile is adjusted on its own as a Dask task (--workers/--scheduler; a
  worker gets only its tile's data) and every image takes its refined angles and
  sigmas from the tile where it is core.  Needs a datum in every tile: --method
  known-base --datum none (GNSS bases) or --datum ins; --datum first is refused.  Lost:
  the correlation across tile borders (the covariance is per image) and the pull of
  pairs beyond the halo.  The INS assessment is combined from the tiles' core images
  (boresight and INS noise by inverse variance); each tile's flags are carried.
  Progress in tiles and images.

example:
  photogrammetry refine eo.csv tiepoints.csv --camera camera.toml --method base-free \\
      --datum first -o refined.csv --report report.md
  photogrammetry refine eo.csv tiepoints.csv --camera camera.toml --method known-base \\
      --datum none -o refined.csv --report report.html
"""


def add_parser(sub):
    p = sub.add_parser(
        "refine", help="coplanarity adjustment of the INS exposure angles",
        description="Refine the angles of aerial images by least squares on the coplanarity "
                    "of corresponding rays of every overlapping pair, and assess the INS "
                    "(noise, boresight misalignment).",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("inputs", nargs="+", metavar="EO.csv TIEPOINTS.csv | FOLDER")
    p.add_argument("--camera", metavar="CAM.toml", help="camera file (default: FOLDER/camera.toml)")
    p.add_argument("--eo", metavar="EO.csv", help="INS EO for folder inputs")
    p.add_argument("--system", choices=["phi-omega-kappa", "omega-phi-kappa"],
                   help="angle system of the work and the output (default: the EO file's)")
    p.add_argument("--datum", choices=["first", "ins", "none"], default="first")
    p.add_argument("--method", choices=["known-base", "relative", "base-free"],
                   default="base-free")
    p.add_argument("--sigma-px", type=float, metavar="PX",
                   help="photo-coordinate sigma, px (default: the tie-point file's header, "
                        "else 0.5)")
    p.add_argument("--prior-sigma-deg", type=float, metavar="DEG",
                   help="INS angle sigma for --datum ins (default: EO sigmas, else 0.2865 deg)")
    p.add_argument("--position-sigma-m", type=float, metavar="M",
                   help="sigma of each EO position, m per coordinate (known-base: the base "
                        "errors are propagated into the angle covariance and the INS "
                        "assessment; default: the EO sigmas, else exact bases)")
    p.add_argument("--ins-std", metavar="STD.txt",
                   help="the trajectory's sigmas (solution_std.txt of ins process: roll, pitch, "
                        "yaw deg) for the boresight's total sigma (default: the EO file's "
                        "'# trajectory sigma =' line, if any)")
    p.add_argument("--no-snooping", action="store_true", help="no outlier rejection")
    p.add_argument("--accept-poor", action="store_true",
                   help="write the outputs even when a pair's or the block's sigma0 or an "
                        "image's angle change is implausible (flagged in the CSV comments "
                        "and the report; default: exit 3, nothing written)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--workers", type=int, metavar="N",
                   help="local Dask workers (several folders, or the tiles of --tile-images)")
    g.add_argument("--scheduler", metavar="ADDRESS", help="dask.distributed scheduler address")
    p.add_argument("--tile-images", type=positive_int, metavar="N",
                   help="refine one large block in tiles of at most N core images (Dask "
                        "tasks; datum none or ins; see 'tiles' below)")
    p.add_argument("--tile-halo-hops", type=nonnegative_int, metavar="HOPS", default=None,
                   help="pair-hops of each tile's halo (default 3)")
    p.add_argument("-o", "--output", metavar="REFINED.csv")
    p.add_argument("--report", metavar="REPORT.md|REPORT.html",
                   help="the report: Markdown with its two PNG plots beside it "
                        "(REPORT_residuals.png, REPORT_corrections.png), or, for a name "
                        "ending in .html/.htm, one self-contained HTML page with the "
                        "plots embedded (opens offline; as ins process --report)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=run)


def _task(args, eo_path, tp_path, cam_path):
    from photogrammetry.imagery.tiepoints import read_tiepoints
    from photogrammetry.orientation.camera import read_camera
    from photogrammetry.orientation.exposure import read_eo_csv
    if cam_path is None:
        raise InputError("--camera CAM.toml is required (photo scale and distortion)")
    camera, mounting = read_camera(cam_path)
    eo = read_eo_csv(eo_path)
    tp = read_tiepoints(tp_path, camera)
    tp.check_images(eo.image_id, eo_path)
    if args.sigma_px is not None and not 0 < args.sigma_px <= 1e3:
        raise InputError(f"--sigma-px must be > 0 px and <= 1000 px, got {args.sigma_px:g}")
    sigma_mm = None if args.sigma_px is None else args.sigma_px * camera.pixel_size_mm
    if args.position_sigma_m is not None and not 0 <= args.position_sigma_m <= 1e4:
        raise InputError(f"--position-sigma-m must be >= 0 m and <= 10000 m, got "
                         f"{args.position_sigma_m:g}")
    if args.prior_sigma_deg is not None and not 0 < args.prior_sigma_deg <= 30:
        raise InputError(f"--prior-sigma-deg must be an angle sigma > 0 deg and <= 30 deg, "
                         f"got {args.prior_sigma_deg:g}")
    prior = None if args.prior_sigma_deg is None else np.deg2rad(args.prior_sigma_deg)
    return {"boresight_inputs": _ins_std(args, eo_path, eo, mounting.axes),
            "eo": eo, "tiepoints": tp, "camera": camera, "system": args.system,
            "method": args.method, "datum": args.datum, "sigma_mm": sigma_mm,
            "prior_sigma_rad": prior, "position_sigma_m": args.position_sigma_m,
            "snooping": not args.no_snooping, "accept_poor": True}


def _ins_std(args, eo_path, eo, axes):
    """The INS attitude sigma common to the exposures, in the camera frame, for the
    boresight's total sigma: ``(sigma rad (3,), path, None)`` or ``(None, None, why
    not)``.  The file: --ins-std, else the EO file's ``# trajectory sigma =`` line (as
    written, else relative to the EO file's folder)."""
    from photogrammetry.orientation.boresight_sigma import ins_common_sigma
    from photogrammetry.orientation.exposure import read_eo_header, read_solution_std
    path = args.ins_std
    if args.datum != "none":        # the datum takes the INS attitude: no boresight estimate
        return None, None, (f"the boresight is not estimated with --datum {args.datum} "
                            "(the adjusted attitudes are tied to the INS's)")
    if not path:
        named = read_eo_header(eo_path).get("trajectory sigma")
        if not named:
            return None, None, ("no INS sigma file was given (--ins-std, or a "
                                f"'# trajectory sigma =' line in {eo_path})")
        path = next((p for p in (named, os.path.join(os.path.dirname(eo_path), named))
                     if os.path.isfile(p)), None)
        if path is None:
            return None, None, f"the INS sigma file {named} named in {eo_path} was not found"
    t, std = read_solution_std(path)
    return ins_common_sigma(t, std, eo.time, axes, names=list(eo.image_id), path=path), \
        path, None


def _boresight_sigma(res, inputs):
    """:class:`BoresightSigma` of a result, and the reason when it has no INS part."""
    from photogrammetry.orientation.boresight_sigma import BoresightSigma
    ins, path, why_not = inputs
    return BoresightSigma(res.assessment.boresight_sigma, ins, path), why_not


def _boresight_comments(res, bs, why_not):
    """Comment lines (``key = value``) of the refined CSV: the boresight and its sigmas."""
    from photogrammetry.adjustment.report import boresight_lines
    return boresight_lines(res.assessment, bs, why_not, csv=True)


def _jobs(args):
    """(task kwargs, output csv, report) per block."""
    ins = args.inputs
    if all(os.path.isdir(d) for d in ins):
        if len(ins) > 1 and (args.output or args.report or args.eo):
            raise InputError("-o/--report/--eo name one output: give one folder, or none of "
                             "them (each folder gets refined.csv and report.md)")
        jobs = []
        for d in ins:
            eo = args.eo or os.path.join(d, "eo.csv")
            if not os.path.isfile(eo):
                raise InputError(f"{d}: no INS EO (eo.csv); run photogrammetry eo or pass --eo")
            cam = args.camera or os.path.join(d, "camera.toml")
            jobs.append((_task(args, eo, os.path.join(d, "tiepoints.csv"), cam),
                         args.output or os.path.join(d, "refined.csv"),
                         args.report or (None if args.output else os.path.join(d, "report.md"))))
        return jobs
    if len(ins) != 2:
        raise InputError("expected EO.csv TIEPOINTS.csv, or flight folders")
    if not args.output:
        raise InputError("-o REFINED.csv is required")
    for path in ins:
        if os.path.abspath(path) == os.path.abspath(args.output):
            raise InputError(f"--output {args.output} would overwrite an input file")
    return [(_task(args, ins[0], ins[1], args.camera), args.output, args.report)]


def _tiled(args, task, bar):
    """One block refined in tiles (photogrammetry.adjustment.tiling)."""
    from photogrammetry.adjustment.tiling import DEFAULT_HALO_HOPS, check_tiled_datum, refine_tiled
    check_tiled_datum(task["method"], task["datum"])
    hops = DEFAULT_HALO_HOPS if args.tile_halo_hops is None else args.tile_halo_hops
    return refine_tiled(**task, tile_images=args.tile_images, halo_hops=hops,
                        workers=args.workers, scheduler=args.scheduler,
                        progress=lambda done, total, images, n: bar.note(
                            f"refine: {done}/{total} tiles ({images}/{n} images)   "))


def run(args):
    from photogrammetry.adjustment.batch import check_quality, refine, refine_many
    from photogrammetry.adjustment.report import HTML_SUFFIXES, write_html_report, write_report
    from photogrammetry.orientation.exposure import write_eo_csv
    jobs = _jobs(args)
    # the INS attitude sigma common to each block's exposures (not an argument of refine)
    bore_inputs = [task.pop("boresight_inputs") for task, _, _ in jobs]
    for _, out, rep in jobs:               # an unwritable output: now, not after the work
        for path in (out, rep):
            if path:
                check_output_file(path)
    bar = Progress("refine", not args.quiet)
    if args.tile_images is None and args.tile_halo_hops is not None:
        raise InputError("--tile-halo-hops needs --tile-images N")
    if args.tile_images is not None:
        results = [_tiled(args, task, bar) for task, _, _ in jobs]
    elif len(jobs) == 1 and args.scheduler is None:
        n = len(jobs[0][0]["eo"])
        results = [refine(**jobs[0][0], progress=lambda k, kmax: bar.note(
            f"refine: {n} images, block iteration {k} (at most {kmax})   "),
            assess_progress=lambda k, kmax: bar.note(
                f"refine: {n} images, INS assessment round {k} (at most {kmax})   "))]
    else:
        sizes = [len(j[0]["eo"]) for j in jobs]
        results = refine_many([j[0] for j in jobs], workers=args.workers,
                              scheduler=args.scheduler, progress=lambda done, total: bar.note(
                                  f"refine: {done}/{total} blocks ({sum(sizes)} images)   "))
    bar.note("\r" + " " * 70 + "\r")
    if not args.accept_poor:
        for (_, out, _), res in zip(jobs, results):
            check_quality(res.block.quality, where=f"{out}: " if len(jobs) > 1 else "")
    # the outputs of every block (CSV, report, its plots) are written as one set: a
    # Ctrl-C meanwhile takes effect once the set is complete (ins.common.interrupts)
    with interrupts.deferred():
        for (task, out, rep), res, b_in in zip(jobs, results, bore_inputs):
            blk = res.block
            bs, why_not = _boresight_sigma(res, b_in)
            q = blk.quality
            flags = (() if q is None or not q.poor else
                     ("QUALITY POOR (written with --accept-poor): " + r for r in q.reasons))
            s = res.settings
            tiled = (() if "n_tiles" not in s else
                     (f"tiled: {s['n_tiles']} tiles of <= {s['tile_images']} core images, "
                      f"halo {s['halo_hops']} pair-hops; sigma0 pooled over the tiles; "
                      "sigmas per tile (no covariance across tiles)",))
            write_eo_csv(out, res.eo, comments=(
                f"refined by photogrammetry refine: method = {s['method']}; "
                f"datum = {s['datum']}; sigma0 = {blk.sigma0:.4f}",) + tiled
                + tuple(_boresight_comments(res, bs, why_not)) + tuple(flags))
            if q is not None and q.poor:
                warnings.warn(f"{out}: refinement flagged as poor (written with "
                              f"--accept-poor): {q.reasons[0]}", QualityWarning)
            if rep and rep.lower().endswith(HTML_SUFFIXES):
                write_html_report(rep, res, boresight_sigma=bs, boresight_note=why_not)
            elif rep:
                write_report(rep, res, boresight_sigma=bs, boresight_note=why_not)
            if not args.quiet:
                s = res.settings
                s0 = blk.sigma0 * s['sigma_mm'] / s['pixel_size_mm']
                print(f"{out}: {s['n_images']} images, {s['n_pairs']} pairs, sigma0 "
                      + (f"{s0:.3f} px" if np.isfinite(s0) else "not estimable")
                      + ", redundancy "
                      f"{blk.redundancy}, {int(blk.rejected.sum())} points rejected"
                      + (f"; {s['n_tiles']} tiles" if tiled else "")
                      + (f"; report {rep}" if rep else ""))
    return 0
