"""Command-line interface: ``ins mechanize``, ``ins compare`` and the commands of the
modules listed in ``COMMAND_MODULES`` (each has ``add_parser(sub)`` that registers one
sub-command and sets ``func``).

Units on the command line are degrees and metres; inside, SI.  Errors in the input give
one line on stderr and exit code 2, and no output file.
"""
import argparse
import importlib
import os
import sys
import time as wallclock
import warnings

import numpy as np

from . import __version__
from .errors import InputError, InputWarning

EXIT_BAD_INPUT = 2


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.print_usage(sys.stderr)
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message}\n")


def _triplet(text, name="value"):
    parts = text.replace(" ", "").split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers, got {text!r}")
    try:
        values = np.array([float(p) for p in parts])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected three numbers, got {text!r}") from None
    if not np.all(np.isfinite(values)):
        raise argparse.ArgumentTypeError(f"expected finite numbers, got {text!r}")
    return values


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


MECHANIZE_EPILOG = """\
frames and units:
  The IMU file holds increments over (t[k-1], t[k]] stamped at the END of the interval:
  dtheta in rad, dvel in m/s, in the body frame forward-right-down (FRD; use --axes for
  other mountings), or rates in rad/s and m/s^2 with --rates (KF-GINS layouts) or as the
  CSV header states.  The initial state is at the first IMU epoch >= --start: latitude,
  longitude in deg, ellipsoidal height in m; velocity north, east, down in m/s; roll,
  pitch, yaw (ZYX Euler, C_nb = Rz(yaw) Ry(pitch) Rx(roll)) in deg.

output (KF-GINS .nav, one epoch a line):
  week t[s] lat[deg] lon[deg] h[m] vN vE vD[m/s] roll pitch yaw[deg], yaw in [0, 360).

example:
  ins mechanize imu.txt --init-lla 30.44,114.47,1000 --init-vel 60,0,0 \\
      --init-att 0,2.3,0.09 -o out.nav
"""


def _add_mechanize(sub):
    p = sub.add_parser(
        "mechanize", help="strapdown mechanization of an IMU log (no aiding)",
        description="Integrate gyro and accelerometer increments into position, velocity "
                    "and attitude in the local-level NED frame (normal gravity, Earth rate, "
                    "transport rate; two-sample coning and sculling).",
        epilog=MECHANIZE_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("imu_file", metavar="IMU_FILE", help="IMU log (KF-GINS text/binary or CSV)")
    p.add_argument("--init-lla", required=True, type=_triplet, metavar="LAT,LON,H",
                   help="initial latitude, longitude (deg) and ellipsoidal height (m)")
    p.add_argument("--init-vel", required=True, type=_triplet, metavar="VN,VE,VD",
                   help="initial velocity north, east, down (m/s)")
    p.add_argument("--init-att", required=True, type=_triplet, metavar="ROLL,PITCH,YAW",
                   help="initial roll, pitch, yaw (deg)")
    p.add_argument("--format", choices=["kfgins", "kfgins-bin", "csv"], default=None,
                   help="IMU file format (default: from the extension: .bin binary, "
                        ".csv CSV, else KF-GINS text)")
    p.add_argument("--rates", action="store_true",
                   help="the KF-GINS columns hold rates (rad/s, m/s^2), not increments; "
                        "increment[k] = rate[k] * (t[k] - t[k-1])")
    p.add_argument("--axes", choices=["FRD", "FLU", "RFU", "FUR"], default="FRD",
                   help="axes of the IMU's x, y, z (mapped into FRD; default FRD)")
    p.add_argument("--gyro-bias-dph", type=_triplet, metavar="X,Y,Z",
                   help="gyro bias to remove, deg/h")
    p.add_argument("--accel-bias-mgal", type=_triplet, metavar="X,Y,Z",
                   help="accelerometer bias to remove, mGal (1 mGal = 1e-5 m/s^2)")
    p.add_argument("--gyro-scale-ppm", type=_triplet, metavar="X,Y,Z",
                   help="gyro scale-factor error to remove, ppm")
    p.add_argument("--accel-scale-ppm", type=_triplet, metavar="X,Y,Z",
                   help="accelerometer scale-factor error to remove, ppm")
    p.add_argument("--start", type=float, metavar="T", help="start time, s (default: first epoch)")
    p.add_argument("--end", type=float, metavar="T", help="end time, s (default: last epoch)")
    p.add_argument("--every", type=_positive_int, default=1, metavar="N",
                   help="write every N-th epoch (default 1)")
    p.add_argument("--week", type=int, default=0, help="GPS week written in column 1 (default 0)")
    p.add_argument("--strict", action="store_true",
                   help="refuse logs with gaps longer than 1.5 nominal intervals "
                        "(default: integrate across them with a warning)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.add_argument("-o", "--output", required=True, metavar="OUT.nav", help="output .nav file")
    p.set_defaults(func=_cmd_mechanize)


class _Progress:
    """A one-line progress bar on stderr (only on a terminal)."""

    def __init__(self, label, enabled):
        self.label = label
        self.enabled = enabled and sys.stderr.isatty()
        self.last = 0.0

    def note(self, text):
        """A transient status line (erased by the bar)."""
        if self.enabled:
            sys.stderr.write(f"\r{text}")
            sys.stderr.flush()

    def __call__(self, done, total):
        if not self.enabled:
            return
        now = wallclock.monotonic()
        if now - self.last < 0.1 and done < total:
            return
        self.last = now
        frac = done / max(total, 1)
        bar = "#" * int(30 * frac)
        sys.stderr.write(f"\r{self.label} [{bar:<30}] {100 * frac:5.1f}% {done}/{total} epochs"
                         "      ")
        if done >= total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def _cmd_mechanize(args):
    from . import imu as imu_mod
    from .imu_blocks import iter_imu, prefetch
    from .mechanization import NavState, iter_mechanize_blocks
    from .trajectory import write_nav

    t_start = wallclock.perf_counter()
    if abs(args.init_lla[0]) > 90:
        raise InputError(f"--init-lla: latitude {args.init_lla[0]} deg is outside +-90 deg")
    if os.path.abspath(args.output) == os.path.abspath(args.imu_file):
        raise InputError(f"--output {args.output} would overwrite the input file")
    size = os.path.getsize(args.imu_file) if os.path.isfile(args.imu_file) else 0
    errors = {name: value * unit for name, value, unit in (
        ("gyro_bias", args.gyro_bias_dph, imu_mod.DPH),
        ("accel_bias", args.accel_bias_mgal, imu_mod.MGAL),
        ("gyro_scale", args.gyro_scale_ppm, imu_mod.PPM),
        ("accel_scale", args.accel_scale_ppm, imu_mod.PPM)) if value is not None}
    initial = NavState.from_degrees(*args.init_lla, args.init_vel, args.init_att)
    # the log is read block by block in a thread beside the integration: memory is a few
    # blocks whatever its length; the epoch count of a text log is estimated from its size
    binary = args.format == "kfgins-bin" or (args.format is None and os.path.splitext(
        args.imu_file)[1].lower() in (".bin", ".imu"))
    total = size // 56 if binary else size // 95
    progress = _Progress("mechanize", not args.quiet and total > 100_000)
    seen = {"n": 0, "t0": None, "t1": None, "dt": None}
    last = []

    def blocks():
        for log in prefetch(iter_imu(args.imu_file, format=args.format, rates=args.rates,
                                     axes=args.axes)):
            if seen["t0"] is None:
                seen["t0"] = log.time[0]
                seen["dt"] = log.nominal_dt if len(log) > 1 else None
            seen["n"] += len(log)
            seen["t1"] = log.time[-1]
            yield log

    def pieces():
        for piece in iter_mechanize_blocks(blocks(), initial, start=args.start, end=args.end,
                                           every=args.every, strict=args.strict,
                                           errors=errors, progress=progress, total=total):
            last[:] = [piece]
            yield piece

    with warnings.catch_warnings(record=True) as caught:     # name the file in them
        warnings.simplefilter("always", InputWarning)
        try:
            n = write_nav(args.output, pieces(), week=args.week)
        except InputError as exc:
            if exc.path is None:
                raise InputError(exc.reason, path=args.imu_file, line=exc.line) from None
            raise
    for w in caught:
        warnings.warn(f"{w.message} (in {args.imu_file})", w.category)
    progress(seen["n"], seen["n"])
    t_end = wallclock.perf_counter()
    if not args.quiet:
        end = last[0]
        rpy = end.rpy(degrees=True)[-1]
        lat, lon, h = end.lla[-1]
        dt = "" if seen["dt"] is None else f" (nominal dt {seen['dt']:.6g} s)"
        print(f"{args.imu_file}: {seen['n']} IMU epochs read, {seen['t0']:.3f} .. "
              f"{seen['t1']:.3f} s{dt}")
        print(f"wrote {n} epochs to {args.output} in {t_end - t_start:.2f} s")
        print(f"final epoch t={end.time[-1]:.3f} s: lat {np.rad2deg(lat):.9f} deg, "
              f"lon {np.rad2deg(lon):.9f} deg, h {h:.3f} m, "
              f"v_NED {end.v_n[-1, 0]:.3f} {end.v_n[-1, 1]:.3f} {end.v_n[-1, 2]:.3f} m/s, "
              f"roll {rpy[0]:.4f} pitch {rpy[1]:.4f} yaw {np.mod(rpy[2], 360):.4f} deg")
    return 0


def _add_compare(sub):
    p = sub.add_parser(
        "compare", help="errors of a .nav result against a reference .nav (truth)",
        description="Compare two KF-GINS .nav files on their common epochs (times equal "
                    "within 1 us): position error north/east/down in m (in the reference's "
                    "n frame), velocity error in m/s, attitude error as the rotation "
                    "C_nb_est C_nb_ref^T (tilt about north and east, heading) in arcsec.")
    p.add_argument("result", metavar="RESULT.nav")
    p.add_argument("reference", metavar="TRUTH.nav")
    p.set_defaults(func=_cmd_compare)


def _cmd_compare(args):
    from .accuracy import compare
    from .trajectory import read_nav

    try:
        errors = compare(read_nav(args.result), read_nav(args.reference))
    except InputError:
        raise
    except ValueError as exc:          # no common epoch
        raise InputError(f"{args.result} vs {args.reference}: {exc}") from None
    s = errors.summary()
    print(f"{s['n_epochs']} common epochs, {s['t_from']:.3f} .. {s['t_to']:.3f} s "
          f"({s['t_to'] - s['t_from']:.1f} s)")
    print(f"{'error':<18}{'final':>12}{'RMS':>12}{'max':>12}")
    rows = [("horizontal mm", "horizontal_m", 1e3), ("north mm", "north_m", 1e3),
            ("east mm", "east_m", 1e3), ("down mm", "down_m", 1e3),
            ("velocity mm/s", "vel_3d_mps", 1e3), ("tilt N arcsec", "tilt_n_arcsec", 1.0),
            ("tilt E arcsec", "tilt_e_arcsec", 1.0), ("heading arcsec", "heading_arcsec", 1.0)]
    for label, key, scale in rows:
        v = s[key]
        print(f"{label:<18}" + "".join(f"{scale * v[k]:>12.4g}" for k in ("final", "rms", "max")))
    return 0


# Sub-commands that live in modules of their own (one line each).
COMMAND_MODULES = [
    "ins.cli_simulate",
    "ins.cli_allan",
    "ins.cli_process",
]


def build_parser():
    parser = _Parser(prog="ins", description="Strapdown INS and GNSS/INS post-processing. "
                     "Frames: n = north-east-down, b = forward-right-down; units on the "
                     "command line: deg, m, s.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    _add_mechanize(sub)
    _add_compare(sub)
    for name in COMMAND_MODULES:
        importlib.import_module(name).add_parser(sub)
    return parser


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_command(args, "ins")


def run_command(args, prog):
    """Run ``args.func(args)``: bad input -> one line on stderr and exit code 2."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", InputWarning)
        try:
            code = args.func(args)
        except InputError as exc:
            _flush_warnings(caught)
            print(f"{prog} {args.command}: error: {exc}", file=sys.stderr)
            return EXIT_BAD_INPUT
        except (FileNotFoundError, IsADirectoryError, PermissionError) as exc:
            print(f"{prog} {args.command}: error: {exc.filename}: {exc.strerror}", file=sys.stderr)
            return EXIT_BAD_INPUT
        except KeyboardInterrupt:
            print(f"{prog} {args.command}: interrupted; no output written", file=sys.stderr)
            return 130
    _flush_warnings(caught)
    return code


def _flush_warnings(caught):
    for w in caught:
        print(f"warning: {w.message}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
