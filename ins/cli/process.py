"""``ins process``: GNSS/INS post-processing (forward filter + RTS smoother)."""
import argparse
import os
import sys
import tempfile
import time as wallclock

import numpy as np

from ins.cli.process_summary import summary
from ins.cli.util import nonnegative_int, number
from ins.common.errors import InputError, QualityError
from ins.common.limits import MAX_TIME_SHIFT_S

EPILOG = """\
inputs:
  FLIGHT_DIR        a flight folder of 'ins simulate' (manifest.toml names the files,
                    lever arms, IMU errors, stationary segment); --config overrides keys
  --imu/--gnss      KF-GINS text files as they are: IMU 'time dtheta_xyz[rad]
                    dvel_xyz[m/s]' (FRD, increment over (t[k-1], t[k]] stamped at its end);
                    GNSS 'time lat lon[deg] h[m] std_n std_e std_d[m]' of the ANTENNA,
                    optionally 'vn ve vd std_vn std_ve std_vd [m/s]'; or an RTKLIB .pos
                    solution of the antenna (detected from its header: lat/lon/height,
                    d'", x/y/z-ecef or e/n/u-baseline; GPST/UTC/JST, week/tow or date;
                    the full covariance from sdn..sdun; UTC -> GPS with leap seconds);
                    or a u-blox receiver's own solution: UBX NAV-PVT (its ellipsoidal
                    height; hAcc, vAcc, sAcc as sigmas) or NMEA GGA + RMC (+ GST sigmas),
                    the altitude above mean sea level plus the GGA geoid separation, or
                    plus N of --gnss-geoid (EGM96 default) when the GGA has none
  --rover/--base/--nav (repeatable)/--sp3/--clk/--atx/--dcb  raw GNSS instead of
                    --gnss (or the config's [files] rover, base, nav, sp3, clk, atx,
                    dcb): RINEX, or a receiver log in any format RTKLIB decodes (rtcm2,
                    rtcm3, oem4 NovAtel, ubx, sbf, hemisphere, skytraq, javad, nvs,
                    binex, rt17, unicore, swift), detected from the content or named by
                    --rover-format/--base-format ([rtklib] rover_format, base_format),
                    converted to RINEX on the way; [rtklib] mode = "ppp-kinematic": PPP
                    with the precise orbits and clocks, no base;
                    RTKLIB runs first with the config's [rtklib] settings (ins gnss
                    --help; optional extra: pip install 'insphoto[gnss]'), writes
                    OUT_DIR/gnss.pos (and, in kinematic mode, fwd_bwd_separation.txt
                    and .png), its covariances are screened and the filter takes it
                    as an RTKLIB .pos; the summary names the source (mode, direction,
                    fix/float/single counts, records repaired or dropped by the screen)
  --gnss-quality    RTKLIB only: Q values kept, e.g. fix,float (names fix, float, sbas,
                    dgps, single, ppp or numbers 1..6; default all)
  --gnss-quality-scale  RTKLIB only: sigma factors per Q, e.g. float=3,single=10
  --gnss-geoid      RTKLIB only: the geoid model (EGM96, EGM2008) of a .pos written with
                    geodetic heights (height=WGS84/geodetic in its header): converted to
                    ellipsoidal h = H + N (default EGM96, RTKLIB's own model, with a
                    warning; needs a geoid grid: pip install 'insphoto[geoid]')
  --imu-time-shift-s / --gnss-time-shift-s  added to that log's stamps at read time (s):
                    the offset of its clock against the common time base (GPS seconds of
                    week), e.g. a GNSS stamped at reception 0.2 s late: -0.2; the offset
                    that 'ins time-offset' prints goes into --gnss-time-shift-s as it is
  --gnss-velocity-time-shift-s  added to the stamps of the GNSS velocities instead (s),
                    when they are stamped differently from the positions (a u-blox: its
                    Doppler velocities ~0.1 s apart); default: --gnss-time-shift-s.  'ins
                    time-offset' prints both (from the positions / from the velocities).
                    The filter's time_offset state, when enabled, is one state for both,
                    on top of these shifts
  --mount           mount log 'time roll pitch yaw [deg]' (C_ap = Rz(yaw) Ry(pitch) Rx(roll))
  --config F.toml   initial state and sigma, IMU noise (deg/sqrt(h), m/s/sqrt(h), deg/h,
                    mGal, ppm, h), lever arm (m, body FRD), alignment; see
                    data/configs/kfgins_like.toml

frames and units:
  n = north-east-down, b = forward-right-down; lever arm from the IMU to the antenna in
  b (m); with a mount l_b(t) = l_bp + C_pa(t) l_ap.

start position:
  checked against the first GNSS fix at or after the start (within 10 s): the start
  state is moved to the fix time along its velocity and carried to the antenna through
  the lever arm.  Farther than 5 sigma (fix, start position and velocity sigmas) + 300 m
  is refused (exit 2, naming the config key and the distance: a start of another
  flight, a wrong time_s, another time scale); beyond 5 sigma only, the start position
  sigma is widened with a warning.  Without [initial] lat_deg, lon_deg, h_m the start
  position is taken from that fix, less the lever arm (as the static and in-air
  alignments do).

trust (checked before anything is written):
  GNSS measurements rejected by the innovation test: more than 5 % is a warning; more
  than 50 %, none accepted, or the written solution farther than 10 fix sigmas from
  every fix for 30 s or more (10 s or more up to the last fix: the solution ends
  drifted) stops with exit 3, naming the counts and the likely cause
  (start state, IMU noise settings, lever arm, time base).  --accept-poor writes the
  outputs anyway (exit 0, the warning printed).  A negative variance or a covariance
  that is not positive definite stops with exit 3, naming the time and the state.

exit codes:
  0 success; 2 bad input (files, config, options, start far from the GNSS fixes, an
  output folder that is not empty without --force); 3 untrustworthy solution (nothing
  written without --accept-poor); 130 interrupted (Ctrl-C), 143 SIGTERM (nothing written).
  A batch (several inputs) exits with its worst run's code (see 'many logs' below).

outputs (in -o OUT_DIR, a new or empty folder; --force replaces an existing one whole,
built aside and swapped in: never a mix of two runs):
  solution.nav      smoothed trajectory, KF-GINS .nav: week t lat lon[deg] h[m]
                    vN vE vD[m/s] roll pitch yaw[deg] (--format nav, the default)
  sbet_solution.out with --format sbet: the smoothed trajectory as an Applanix SBET
                    (17 little-endian doubles: GPS s of week, lat lon[rad], h[m],
                    velocity x north y west z up[m/s], roll pitch heading[rad], wander
                    angle 0, body accelerations and rates 0), and smrmsg_solution.out
                    (its accuracy at the filter nodes: N E D[m], vN vE vD[m/s], roll
                    pitch heading[arcmin]); --format nav,sbet writes both
  forward.nav       with --forward: the forward-filter trajectory (same layout; a
                    diagnostic, not written by default: solution.nav is the product;
                    sbet_forward.out with --format sbet)
  solution_std.txt  smoothed sigma at the filter nodes: N E D [m], vN vE vD [m/s],
                    roll pitch yaw [deg]
  imu_errors.txt    smoothed gyro bias [deg/h], accel bias [mGal], scale factors [ppm]
  solution_orthometric.txt  with --height orthometric[:MODEL]: the smoothed
                    trajectory's heights above the geoid MODEL (EGM2008, the default, or
                    EGM96; a grid installed locally: pip install 'insphoto[geoid]'):
                    week t lat lon[deg] h_ellipsoidal N H[m], H = h - N, the model named
                    in the header; solution.nav and the SBET keep ellipsoidal heights (their
                    formats define them so)
  *.png             plots (errors against the truth when there is one, sigma, biases)
  --report F.html   one self-contained HTML page (the QC view; opens offline: CSS inline,
                    figures embedded, no script, nothing fetched): the trust verdict and
                    its reasons, the summary table with the processing time, the GNSS
                    source and its quality flags over time, recoveries and
                    re-anchorings, RTKLIB's forward/backward separation (raw GNSS), the
                    smoothed IMU errors against their stated sigmas, the identified IMU
                    noise, the errors against a truth and every PNG above.  F inside
                    OUT_DIR is built with the folder; elsewhere it is written atomically
                    once the folder is in place (same name as photogrammetry refine
                    --report F.html)

example:
  ins process --imu imu.txt --gnss gnss.txt --config data/configs/kfgins_like.toml -o out
  ins process flight_dir -o out
"""


def add_parser(sub):
    p = sub.add_parser(
        "process", help="GNSS/INS post-processing: forward Kalman filter + RTS smoother",
        description=(
            "GNSS/INS post-processing: error-state Kalman filter with closed-loop\n"
            "feedback (fixed or mount-varying lever arm), then a backward\n"
            "Rauch-Tung-Striebel pass.  Loosely coupled on a GNSS solution (a ready\n"
            "one, or RTKLIB's of raw --rover/--base/--nav run first), or tightly coupled\n"
            "(--coupling tight: the pseudoranges and Doppler of every system of [rtklib]\n"
            "systems, receiver clock and inter-system bias states; with --base, double\n"
            "differences and the carrier phase with its ambiguities fixed by LAMBDA (RTK);\n"
            "one to three satellites still count).  State layout from the config's [states]:\n"
            "'survey' (default: the 21 KF-GINS states plus gyro and accelerometer axis\n"
            "misalignment; lever-arm and IMU-GNSS time-offset groups on request) or\n"
            "'kfgins' (the 21 states: position, velocity, attitude, gyro/accel bias and\n"
            "scale factor)."),
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("flight_dir", nargs="*", metavar="FLIGHT_DIR",
                   help="flight folder with manifest.toml; two or more (flight folders "
                        "or per-log configs F.toml): a batch into OUT_DIR/NAME (see "
                        "'many logs' below)")
    p.add_argument("--imu", metavar="F", help="IMU log (KF-GINS text/binary or CSV)")
    p.add_argument("--gnss", metavar="F",
                   help="GNSS log of the antenna (KF-GINS text or RTKLIB .pos, detected)")
    p.add_argument("--rover", metavar="F",
                   help="raw GNSS: the rover's observations (RINEX or a receiver log), run "
                        "through RTKLIB first instead of --gnss")
    p.add_argument("--base", metavar="F", help="raw GNSS: base station observations")
    p.add_argument("--nav", action="append", metavar="F",
                   help="raw GNSS: broadcast navigation, RINEX (repeatable)")
    p.add_argument("--sp3", action="append", metavar="F",
                   help="raw GNSS: precise orbits (repeatable)")
    p.add_argument("--clk", action="append", metavar="F",
                   help="raw GNSS: precise clocks, RINEX CLK (repeatable)")
    from ins.gnss.receiver_formats import RAW_FORMATS
    raw_names = ("rinex",) + RAW_FORMATS
    p.add_argument("--rover-format", type=str.lower, choices=raw_names, metavar="NAME",
                   help="raw GNSS: the receiver format of --rover (default: detected from "
                        "the content; [rtklib] rover_format): " + ", ".join(raw_names))
    p.add_argument("--base-format", type=str.lower, choices=raw_names, metavar="NAME",
                   help="raw GNSS: the receiver format of --base (default: detected; "
                        "[rtklib] base_format)")
    p.add_argument("--atx", metavar="F", help="raw GNSS: antenna phase centres (ANTEX)")
    p.add_argument("--dcb", metavar="F", help="raw GNSS: code biases (CODE .DCB)")
    p.add_argument("--gnss-format", choices=["kfgins", "rtklib", "ubx", "nmea"],
                   help="GNSS file format (default: detected from the extension and "
                        "content): KF-GINS text, RTKLIB .pos, a u-blox receiver's own "
                        "solution (UBX NAV-PVT; NMEA GGA + RMC + GST)")
    p.add_argument("--gnss-quality", metavar="Q,...",
                   help="RTKLIB: solution qualities kept, e.g. fix,float (default all)")
    p.add_argument("--gnss-quality-scale", metavar="Q=F,...",
                   help="RTKLIB: sigma factor per quality, e.g. float=3,single=10")
    p.add_argument("--gnss-geoid", metavar="MODEL", type=str.upper,
                   choices=["EGM96", "EGM2008"],
                   help="RTKLIB: geoid model of geodetic heights, converted to ellipsoidal "
                        "(EGM96 default, EGM2008)")
    p.add_argument("--imu-time-shift-s", type=number(-MAX_TIME_SHIFT_S, MAX_TIME_SHIFT_S, unit="s"), metavar="S",
                   help="added to the IMU stamps at read time, s (overrides [imu] "
                        "time_shift_s)")
    p.add_argument("--gnss-time-shift-s", type=number(-MAX_TIME_SHIFT_S, MAX_TIME_SHIFT_S, unit="s"), metavar="S",
                   help="added to the GNSS stamps at read time, s (overrides [gnss] "
                        "time_shift_s)")
    p.add_argument("--gnss-velocity-time-shift-s", type=float, metavar="S",
                   help="added to the stamps of the GNSS velocities instead, s (overrides "
                        "[gnss] velocity_time_shift_s; default: the GNSS time shift)")
    p.add_argument("--format", default="nav", metavar="nav|sbet|nav,sbet",
                   help="trajectory output format(s): nav (solution.nav, default), sbet "
                        "(sbet_solution.out + smrmsg_solution.out), or both")
    p.add_argument("--height", default="ellipsoidal",
                   metavar="ellipsoidal|orthometric[:MODEL]",
                   help="also write the orthometric heights H = h - N (m) of the geoid "
                        "MODEL EGM2008 (default) or EGM96 to solution_orthometric.txt")
    p.add_argument("--preset", metavar="NAME",
                   help="defaults for the keys the config does not give: tactical, mems, "
                        "land (ins/estimation/pipeline/presets.py: IMU noise in deg/sqrt(h), m/s/sqrt(h), "
                        "deg/h, mGal, ppm, h)")
    p.add_argument("--mount", metavar="F", help="mount-angle log (varying lever arm)")
    p.add_argument("--coupling", choices=["loose", "tight"],
                   help="loose: the GNSS solution's positions (default); tight: the GPS "
                        "L1 pseudoranges (m) and Doppler range rates (m/s) of --rover "
                        "(RINEX) with --nav through RTKLIB, receiver clock bias/drift "
                        "states; with --base: their double differences against the base "
                        "(no clock states); RTKLIB's solution still gives the start and "
                        "the checks; with FLIGHT_DIR its simulated raw GPS (rover.obs, "
                        "rover.nav)")
    p.add_argument("--config", metavar="F.toml", help="processing config (TOML)")
    p.add_argument("--truth", metavar="F.nav",
                   help="truth .nav: errors and error plots (on the shared epochs; a "
                        "truth at other epochs is interpolated to the solution's)")
    p.add_argument("--no-smooth", action="store_true", help="forward filter only")
    p.add_argument("--forward", action="store_true",
                   help="also write forward.nav (the forward filter's trajectory)")
    p.add_argument("--no-plots", action="store_true", help="do not write PNG plots")
    p.add_argument("--week", type=nonnegative_int, default=0, help="GPS week in the .nav (default 0)")
    p.add_argument("--accept-poor", action="store_true",
                   help="write the outputs even when the solution is not to be trusted "
                        "(exit 0 with the warning; default: exit 3, nothing written)")
    p.add_argument("--report", metavar="F.html",
                   help="also write the run's QC report as one self-contained HTML file "
                        "(in OUT_DIR or elsewhere; see 'outputs' below)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress or summary")
    p.add_argument("-o", "--output", required=True, metavar="OUT_DIR",
                   help="output folder (new or empty; see --force)")
    p.add_argument("--force", action="store_true",
                   help="replace a non-empty OUT_DIR whole (the new run is built aside "
                        "and swapped in; nothing of the old run is kept)")
    p.set_defaults(func=_cmd_process)
    return p            # ins.cli.process_batch adds the batch's options and help


def _config(args):
    from ins.estimation.pipeline.config import config_from_manifest, load_config
    if args.flight_dir:
        if args.imu or args.gnss or args.rover:
            raise InputError("give either FLIGHT_DIR or --imu/--gnss (--rover), not both")
        if not os.path.isdir(args.flight_dir):
            raise InputError(f"FLIGHT_DIR {args.flight_dir}: not a folder")
        cfg = config_from_manifest(args.flight_dir, overrides=args.config)
        extra = [f"--{k}" for k in ("base", "nav", "sp3", "clk", "atx", "dcb")
                 if getattr(args, k, None)]
        if extra and not (extra == ["--base"] and getattr(args, "coupling", None) == "tight"):
            raise InputError(f"{', '.join(extra)} with FLIGHT_DIR: only --base, with "
                             f"--coupling tight (double differences and RTK against that "
                             f"base; the flight's own raw files give the rover and the "
                             f"navigation)")
    else:
        if not args.config:
            raise InputError("--config F.toml is required without FLIGHT_DIR")
        if not os.path.isfile(args.config):
            raise InputError(f"--config {args.config}: no such file")
        cfg = _from_args(args, load_config, args.config)
    if args.mount:
        cfg.mount = args.mount
    if args.truth:
        cfg.truth = args.truth
    if args.no_smooth:
        cfg.smooth = False
    cfg.gnss_raw_plot = not args.no_plots
    if getattr(args, "coupling", None):
        cfg.coupling = args.coupling
    if args.flight_dir and cfg.coupling == "tight" and cfg.gnss_raw is None:
        _flight_raw_gnss(cfg, args.flight_dir, getattr(args, "base", None))
    _input_options(cfg, args)
    if args.preset:
        from ins.common.textfiles import read_toml
        from ins.estimation.pipeline.presets import apply_preset
        given = read_toml(args.config, "a processing config (TOML)") if args.config else {}
        cfg = apply_preset(cfg, args.preset, given)
    return cfg


def _flight_raw_gnss(cfg, flight_dir, base=None):
    """Tight coupling on a simulated flight folder: its raw GNSS (``rover.obs`` and
    ``rover.nav`` of ``[gnss_raw]``, :mod:`ins.simulate.gnss_raw_product`; the systems
    it simulated) with RTKLIB's single-point solution of them as the GNSS log (start,
    delays, checks), not the folder's ready fixes; with ``base`` (``--base``, e.g. the
    folder's ``base.obs``) double differences and RTK against it."""
    from ins.common.textfiles import read_toml
    from ins.estimation.pipeline.gnss_source import RawGnss
    from ins.gnss.rtklib_options import RtklibOptions
    manifest = read_toml(os.path.join(flight_dir, "manifest.toml"), "a flight manifest")
    files = manifest.get("files", {})
    letters = manifest.get("gnss_raw", {}).get("systems", ["G"])
    names = {"G": "gps", "R": "glonass", "E": "galileo", "C": "beidou", "J": "qzss"}
    if not (files.get("gnss_raw_obs") and files.get("gnss_raw_nav")):
        raise InputError(f"--coupling tight: the flight folder {flight_dir} has no raw GPS "
                         "observations (simulate it with a [gnss_raw] table in the plan or "
                         "'ins simulate --gnss-raw NAV_FILE')")
    cfg.gnss_raw = RawGnss(rover=os.path.join(flight_dir, files["gnss_raw_obs"]),
                           nav=(os.path.join(flight_dir, files["gnss_raw_nav"]),), base=base,
                           options=RtklibOptions(mode="single", systems=tuple(
                               names[s] for s in letters if s in names) or ("gps",),
                                                 frequencies=1,
                                                 elevation_mask_deg=cfg.elevation_mask_deg))
    cfg.gnss = None


def _input_options(cfg, args):
    """The GNSS format, quality policy and time shifts of the command line into ``cfg``."""
    from ins.io.gnss_quality import parse_quality, parse_quality_scale
    for key, path in (("imu", cfg.imu), ("gnss", cfg.gnss)):
        if path and (os.path.isdir(path) or os.path.splitext(str(path))[1].lower()
                     in (".bag", ".db3", ".mcap")):
            raise InputError(f"--{key} {path}: a ROS bag; convert it first with 'ins "
                             f"import-bag {path} -o DIR' (imu.txt, gnss.pos)")
    if args.gnss_format:
        cfg.gnss_format = args.gnss_format
    formats = {k: getattr(args, k) for k in ("rover_format", "base_format")
               if getattr(args, k, None)}
    if formats:
        if cfg.gnss_raw is None:
            raise InputError("--rover-format / --base-format go with raw GNSS (--rover, or "
                             "[files] rover)")
        from dataclasses import replace
        cfg.gnss_raw = replace(cfg.gnss_raw, options=replace(cfg.gnss_raw.options,
                                                             **formats))
    if args.gnss_geoid:
        cfg.gnss_geoid = args.gnss_geoid
    if args.gnss_quality:
        cfg.gnss_quality = parse_quality(args.gnss_quality, "--gnss-quality")
    if args.gnss_quality_scale:
        cfg.gnss_quality_scale = parse_quality_scale(args.gnss_quality_scale,
                                                     "--gnss-quality-scale")
    for name in ("imu_time_shift_s", "gnss_time_shift_s", "gnss_velocity_time_shift_s"):
        value = getattr(args, name)
        if value is not None:
            if not np.isfinite(value):
                raise InputError(f"--{name.replace('_', '-')}: expected a finite number of "
                                 f"seconds, got {value!r}")
            setattr(cfg, name, float(value))


def output_formats(text):
    """The trajectory formats of ``--format`` (``"nav"``, ``"sbet"``, ``"nav,sbet"``)."""
    from ins.estimation.pipeline.outputs import OUTPUT_FORMATS
    formats = tuple(dict.fromkeys(f.strip().lower() for f in text.split(",") if f.strip()))
    bad = [f for f in formats if f not in OUTPUT_FORMATS]
    if bad or not formats:
        raise InputError(f"--format {text!r}: expected nav, sbet or nav,sbet")
    return formats


def _from_args(args, load_config, path):
    from ins.common.textfiles import read_toml
    has_files = "files" in read_toml(path, "a processing config (TOML)")
    if args.gnss and args.rover:
        raise InputError("give either --gnss (a GNSS solution) or --rover (raw "
                         "observations through RTKLIB), not both")
    if not has_files and not (args.imu and (args.gnss or args.rover)):
        raise InputError("--imu and --gnss (or --rover, --base, --nav) are required (the "
                         "config has no [files])")
    raw = {"rover": args.rover, "base": args.base, "nav": args.nav, "sp3": args.sp3,
           "clk": args.clk, "atx": args.atx, "dcb": args.dcb}
    if not args.rover and any(raw.values()):
        raise InputError("--base, --nav, --sp3, --clk, --atx, --dcb go with --rover (raw "
                         "GNSS)")
    return load_config(path, files={"imu": args.imu, "gnss": args.gnss, **raw})


def report_target(report, out_dir):
    """Where ``--report`` goes: ``(name in OUT_DIR, None)`` or ``(None, path outside
    it)``, or ``(None, None)`` without one.  An .html/.htm file; not in a subfolder of
    OUT_DIR (the folder is built whole); its directory must exist (checked now)."""
    from ins.common.fileio import check_output_file
    if not report:
        return None, None
    if os.path.splitext(report)[1].lower() not in (".html", ".htm"):
        raise InputError(f"--report {report}: expected an .html file (one self-contained "
                         "HTML page)")
    path, out = os.path.abspath(report), os.path.abspath(out_dir)
    if os.path.dirname(path) == out:
        return os.path.basename(path), None
    if path.startswith(out + os.sep):
        raise InputError(f"--report {report}: inside a subfolder of OUT_DIR {out_dir}; "
                         "give a name in OUT_DIR itself or a path outside it")
    check_output_file(report)
    return None, report


def _cmd_process(args):
    import contextlib

    from ins.common.fileio import atomic_open, output_folder
    inputs = args.flight_dir or []              # one (several: ins.cli.process_batch)
    args.flight_dir = inputs[0] if inputs else None
    t0 = wallclock.perf_counter()
    formats, height = _products(args)
    report_inside, report_outside = report_target(args.report, args.output)
    cfg = _config(args)
    with contextlib.ExitStack() as outside:
        # a report outside OUT_DIR: a temporary file beside it, renamed after the
        # folder's swap (this stack unwinds last); removed on any failure
        report_file = (outside.enter_context(atomic_open(report_outside, "wb"))
                       if report_outside else None)
        # the run is built in a hidden sibling of OUT_DIR and swapped in whole at the
        # end; on any failure (QualityError, Ctrl-C) that sibling is removed: nothing is
        # written
        with output_folder(args.output, force=args.force) as stage:
            result, paths, t_proc, t_write = run_into(
                args, cfg, formats, height, stage, t0, report_inside, report_outside,
                report_file)
    if not args.quiet:
        summary(result, cfg, paths, t_proc, t_write)
    return 0


def _products(args):
    """The trajectory formats and the height system of the run (checked first: a
    missing geoid grid stops before the work)."""
    from ins.io.geoid import parse_height
    return output_formats(args.format), parse_height(args.height)


def run_into(args, cfg, formats, height, stage, t0, report_inside=None, report_outside=None,
             report_file=None, progress=None):
    """One run of ``args`` (its ``flight_dir`` one folder or None) and ``cfg``
    (:func:`_config`), built in the folder ``stage`` that becomes ``args.output``; the
    report inside it, or into the open ``report_file`` (``report_outside`` its path).
    Returns ``(result, paths, processing_s, writing_s)``, ``paths`` as they will be once
    ``stage`` is in place."""
    from ins.cli.util import Progress
    from ins.estimation.pipeline.outputs import write_outputs
    from ins.estimation.pipeline.process import process
    if progress is None:
        progress = Progress("process", not args.quiet)
    progress.note(f"reading {cfg.imu} ...")
    # the forward trajectory and the node matrices are spilled to temporary files
    # inside the staged folder (memory bounded whatever the length of the log),
    # removed before the swap
    with tempfile.TemporaryDirectory(dir=stage, prefix=".work-") as work:
        try:
            result = process(cfg, progress=progress, workdir=work,
                             accept_poor=args.accept_poor, gnss_dir=stage)
        except QualityError as exc:
            raise QualityError(f"{exc} Nothing written (--accept-poor writes the "
                               f"outputs anyway).") from None
        t1 = wallclock.perf_counter()
        names = write_outputs(result, stage, week=args.week, forward=args.forward,
                              formats=formats, height=height)
        if not args.no_plots:
            from ins.estimation.pipeline.plots import write_plots
            names += write_plots(result, stage, flight_dir=args.flight_dir)
        t2 = wallclock.perf_counter()
        if result.gnss_source is not None:
            from ins.estimation.pipeline.gnss_source import SEPARATION_PNG, SEPARATION_TXT
            names += [os.path.join(stage, n)
                      for n in ("gnss.pos", SEPARATION_TXT, SEPARATION_PNG)
                      if os.path.isfile(os.path.join(stage, n))]
        paths = [os.path.join(args.output, os.path.basename(p)) for p in names]
        if args.report:
            paths.append(os.path.join(args.output, report_inside) if report_inside
                         else report_outside)
            page = _report(args, cfg, result, stage, paths,
                           {"processing_s": t1 - t0, "writing_s": t2 - t1})
            if report_inside:
                page.write(os.path.join(stage, report_inside))
            else:
                report_file.write(page.html().encode("utf-8"))
    return result, paths, t1 - t0, t2 - t1


def _report(args, cfg, result, stage, paths, times):
    """The HTML report of the run (:mod:`ins.estimation.pipeline.report`): every PNG in
    the staged folder embedded."""
    from ins.estimation.pipeline.plots import injected_biases
    from ins.estimation.pipeline.report import process_report
    raw = cfg.gnss_raw
    inputs = [("flight folder", args.flight_dir), ("config", args.config),
              ("IMU", cfg.imu), ("GNSS", cfg.gnss),
              ("rover (raw GNSS)", getattr(raw, "rover", None)),
              ("base (raw GNSS)", getattr(raw, "base", None)),
              ("mount", cfg.mount), ("truth", cfg.truth)]
    pngs = sorted(os.path.join(stage, n) for n in os.listdir(stage) if n.endswith(".png"))
    return process_report(result, cfg, plots=pngs, files=paths, times=times,
                          inputs=[(r, str(p)) for r, p in inputs if p],
                          injected=injected_biases(args.flight_dir) if args.flight_dir
                          else None)
