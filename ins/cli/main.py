"""Command-line interface: ``ins mechanize``, ``ins compare``, the commands of the
modules listed in ``COMMAND_MODULES`` and those registered by other packages in the
entry-point group ``ins.commands`` (:data:`COMMAND_GROUP`).

Each command module has ``add_parser(sub)`` that registers one sub-command and sets
``func``.  The entry-point group is how a package ABOVE ``ins`` adds a command to the
``ins`` tool without ``ins`` importing it: ``ins simulate`` needs the camera (exposures,
tie points) and is therefore provided by ``photogrammetry.cli.simulate``, declared in
``pyproject.toml``::

    [project.entry-points."ins.commands"]
    simulate = "photogrammetry.cli.simulate:add_parser"

(the name is the sub-command, the value the module's ``add_parser``).  The group is read
with :mod:`importlib.metadata` from the installed distributions, so a change of it takes
effect after ``pip install -e .`` (``make test`` and ``make demo`` reinstall when
pyproject.toml changes).  ``ins`` itself never imports ``photogrammetry``
(``tests/test_layering.py``).

Units on the command line are degrees and metres; inside, SI.  Errors in the input give
one line on stderr and exit code 2, and no output file.
"""
import argparse
import errno
import importlib
import os
import re
import signal
import sys
import threading
import time as wallclock
import warnings

from ins import __version__
from ins.cli.util import (
    EXIT_BAD_INPUT,
    Parser,
    Progress,
    check_initial,
    nonnegative_int,
    positive_int,
    triplet,
)
from ins.common import interrupts, native_build
from ins.common.errors import InputError, InputWarning, QualityError

EXIT_QUALITY = 3
EXIT_INTERRUPTED = 130
#: SIGTERM (batch schedulers, ``timeout``, ``kill``): 128 + 15, as the shell reports a
#: process killed by it, but after the same clean-up as Ctrl-C and with one line.
EXIT_TERMINATED = 143


def _stop_code():
    """Exit code of a run stopped by a signal: 143 for SIGTERM, 130 for Ctrl-C."""
    return EXIT_TERMINATED if interrupts.stop_signal() == signal.SIGTERM else EXIT_INTERRUPTED


def _stopped():
    """The word of the one line: ``terminated (SIGTERM)`` or ``interrupted`` (Ctrl-C)."""
    return ("terminated (SIGTERM)" if interrupts.stop_signal() == signal.SIGTERM
            else "interrupted")


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
  ins mechanize imu.txt --init-lla -33.9,151.2,50 --init-vel -60,0,0 ...  (south or
      west: negative values as typed; --init-lla=-33.9,151.2,50 works too)

exit codes: 0 success, 2 bad input or an unwritable output (one line naming the file),
  130 Ctrl-C, 143 SIGTERM (no output written).
"""


def _add_mechanize(sub):
    p = sub.add_parser(
        "mechanize", help="strapdown mechanization of an IMU log (no aiding)",
        description="Integrate gyro and accelerometer increments into position, velocity "
                    "and attitude in the local-level NED frame (normal gravity, Earth rate, "
                    "transport rate; two-sample coning and sculling).",
        epilog=MECHANIZE_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("imu_file", metavar="IMU_FILE", help="IMU log (KF-GINS text/binary or CSV)")
    p.add_argument("--init-lla", required=True, type=triplet, metavar="LAT,LON,H",
                   help="initial latitude, longitude (deg) and ellipsoidal height (m)")
    p.add_argument("--init-vel", required=True, type=triplet, metavar="VN,VE,VD",
                   help="initial velocity north, east, down (m/s)")
    p.add_argument("--init-att", required=True, type=triplet, metavar="ROLL,PITCH,YAW",
                   help="initial roll, pitch, yaw (deg)")
    p.add_argument("--format", choices=["kfgins", "kfgins-bin", "csv"], default=None,
                   help="IMU file format (default: from the extension: .bin binary, "
                        ".csv CSV, else KF-GINS text)")
    p.add_argument("--rates", action="store_true",
                   help="the KF-GINS columns hold rates (rad/s, m/s^2), not increments; "
                        "increment[k] = rate[k] * (t[k] - t[k-1])")
    p.add_argument("--axes", choices=["FRD", "FLU", "RFU", "FUR"], default="FRD",
                   help="axes of the IMU's x, y, z (mapped into FRD; default FRD)")
    p.add_argument("--gyro-bias-dph", type=triplet, metavar="X,Y,Z",
                   help="gyro bias to remove, deg/h")
    p.add_argument("--accel-bias-mgal", type=triplet, metavar="X,Y,Z",
                   help="accelerometer bias to remove, mGal (1 mGal = 1e-5 m/s^2)")
    p.add_argument("--gyro-scale-ppm", type=triplet, metavar="X,Y,Z",
                   help="gyro scale-factor error to remove, ppm")
    p.add_argument("--accel-scale-ppm", type=triplet, metavar="X,Y,Z",
                   help="accelerometer scale-factor error to remove, ppm")
    p.add_argument("--start", type=float, metavar="T", help="start time, s (default: first epoch)")
    p.add_argument("--end", type=float, metavar="T", help="end time, s (default: last epoch)")
    p.add_argument("--every", type=positive_int, default=1, metavar="N",
                   help="write every N-th epoch (default 1)")
    p.add_argument("--week", type=nonnegative_int, default=0, help="GPS week written in column 1 (default 0)")
    p.add_argument("--strict", action="store_true",
                   help="refuse logs with gaps longer than 1.5 nominal intervals "
                        "(default: integrate across them with a warning)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.add_argument("-o", "--output", required=True, metavar="OUT.nav", help="output .nav file")
    p.set_defaults(func=_cmd_mechanize)


def _cmd_mechanize(args):
    import numpy as np

    from ins.io.imu_blocks import iter_imu, prefetch
    from ins.io.navfiles import write_nav
    from ins.nav import imu as imu_mod
    from ins.nav.mechanization import NavState, iter_mechanize_blocks

    t_start = wallclock.perf_counter()
    check_initial(args.init_lla, "--init-lla", args.init_vel, "--init-vel")
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
    progress = Progress("mechanize", not args.quiet and total > 100_000)
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
            if getattr(exc, "time_s", None) is not None:
                from ins.io.imu_blocks import with_location
                raise with_location(exc, args.imu_file, args.format) from None
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
        "compare", help="errors of a trajectory (.nav or SBET) against a reference (truth)",
        description="Compare two trajectories (KF-GINS .nav or Applanix SBET, detected by "
                    "the extension .out/.sbet or the content) on their common epochs (times "
                    "equal within 1 us): position error north/east/down in m (in the "
                    "reference's n frame), velocity error in m/s, attitude error as the "
                    "rotation C_nb_est C_nb_ref^T (tilt about north and east, heading) in "
                    "arcsec.")
    p.add_argument("result", metavar="RESULT", help="trajectory: .nav or SBET")
    p.add_argument("reference", metavar="TRUTH", help="reference trajectory: .nav or SBET")
    p.set_defaults(func=_cmd_compare)


def _cmd_compare(args):
    from ins.io.navfiles import read_trajectory
    from ins.nav.accuracy import compare

    try:
        errors = compare(read_trajectory(args.result), read_trajectory(args.reference))
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
    "ins.cli.align",
    "ins.cli.android",
    "ins.cli.allan",
    "ins.cli.bag",
    "ins.cli.export",
    "ins.cli.georeference",
    "ins.cli.gnss",
    "ins.cli.process_batch",        # ins process (one log: ins.cli.process; many)
    "ins.cli.simulate_phone",
    "ins.cli.strip_check",
    "ins.cli.time_offset",
    "ins.cli.vehicle",
]
#: Entry-point group of the sub-commands that other packages add to ``ins`` (name: the
#: sub-command; value: ``module:add_parser``).
COMMAND_GROUP = "ins.commands"


def command_entry_points():
    """The entry points of :data:`COMMAND_GROUP` of the installed distributions, one per
    name (the first found), in the order found."""
    from importlib.metadata import entry_points
    found = {}
    for ep in entry_points(group=COMMAND_GROUP):
        found.setdefault(ep.name, ep)
    return list(found.values())


def build_parser():
    parser = Parser(prog="ins", description="Strapdown INS and GNSS/INS post-processing. "
                     "Frames: n = north-east-down, b = forward-right-down; units on the "
                     "command line: deg, m, s.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    sub.required = True
    _add_mechanize(sub)
    _add_compare(sub)
    for name in COMMAND_MODULES:
        importlib.import_module(name).add_parser(sub)
    for ep in command_entry_points():
        ep.load()(sub)
    return parser


def main(argv=None):
    """``ins`` on the command line (``argv=None``: ``sys.argv``); returns the exit code."""
    return run_main(build_parser, argv, "ins")


def run_main(build, argv, prog):
    """Parse ``argv`` with ``build()`` and run the command (:func:`run_command`).

    Shared by ``ins`` and ``photogrammetry``.  Stdout and stderr are guarded against a
    reader that goes away (``| head``): further output is dropped, the command finishes
    its files, the exit code is the command's own.  Ctrl-C exits 130, SIGTERM 143 (see
    :func:`run_command`); run as a program (``argv=None``) SIGINT and SIGTERM are
    ignored once the command has returned, so that a signal during the interpreter's
    shutdown cannot turn a finished run into a killed one.
    """
    streams = sys.stdout, sys.stderr
    guards = _PipeGuard(sys.stdout), _PipeGuard(sys.stderr)
    sys.stdout, sys.stderr = guards
    interrupts.reset()
    restore = interrupts.install()
    args = None
    try:
        try:
            args = build().parse_args(argv)
        except SystemExit:
            raise
        except BaseException as exc:
            if not interrupts.caused_by_interrupt(exc):
                raise
            _say(f"{prog}: {_stopped()}; no output written")
            return _stop_code()
        return run_command(args, prog)
    except KeyboardInterrupt:       # between the command's end and here
        if args is not None and hasattr(args, "command"):
            return _interrupted(args, prog)
        _say(f"{prog}: {_stopped()}; no output written")
        return _stop_code()
    finally:
        interrupts.close()          # from here on the handler ignores SIGINT and SIGTERM
        for guard in guards:        # a pipe's buffered rest: EPIPE here, not at exit
            guard.flush()
        sys.stdout, sys.stderr = streams
        if argv is None and threading.current_thread() is threading.main_thread():
            for signum in interrupts.SIGNALS:
                signal.signal(signum, signal.SIG_IGN)
            if interrupts.interrupted():
                _exit_now(_stop_code())
        else:
            restore()


def _exit_now(code):
    """Leave at once after an interrupt (run as a program only): the interpreter's own
    exit would wait for worker threads still finishing a block, and turns the exit status
    into "killed by SIGINT" when a KeyboardInterrupt escaped inside an extension's call
    back into Python; everything was cleaned up on the way here."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


class _PipeGuard:
    """A text stream whose reader may go away: on EPIPE (``| head``) the descriptor is
    pointed at /dev/null (the usual recipe, so that the interpreter's last flush does
    not fail either) and further writes are dropped silently."""

    def __init__(self, stream):
        self._stream = stream
        self.broken = False

    def _broken(self):
        self.broken = True
        try:
            fd = self._stream.fileno()
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, fd)
            os.close(null)
        except (OSError, ValueError, AttributeError):   # not a real file (pytest capture)
            pass

    def write(self, text):
        if self.broken:
            return len(text)
        try:
            return self._stream.write(text)
        except BrokenPipeError:
            self._broken()
            return len(text)

    def writelines(self, lines):
        for line in lines:
            self.write(line)

    def flush(self):
        if self.broken:
            return
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._broken()

    def __getattr__(self, name):
        return getattr(self._stream, name)


def _say(text):
    try:
        print(text, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


_HIDDEN = re.compile(r"^\.(?P<name>.+)\.[A-Za-z0-9_]{8}\.(?:part|old)$")


def user_path(path):
    """The user's spelling of a path that may pass through a hidden temporary of
    :mod:`ins.common.fileio` (``.out.nav.k2j3x9a1.part`` -> ``out.nav``; ``.res.abcd1234.part/
    solution.nav`` -> ``res/solution.nav``)."""
    if path is None:
        return None
    path = os.fsdecode(path) if isinstance(path, bytes) else str(path)
    parts = path.split(os.sep)
    for i, part in enumerate(parts):
        m = _HIDDEN.match(part)
        if m:
            parts[i] = m.group("name")
    return os.sep.join(parts)


def _outputs(args):
    """The output paths named on the command line (for messages without a file name)."""
    found = []
    for name in ("output", "plot", "report"):
        value = getattr(args, name, None)
        if value:
            found.append(str(value))
    return found


def _os_error_message(exc, args):
    """One line for an OSError: the user's path and the reason, never a temporary."""
    reason = exc.strerror or errno.errorcode.get(exc.errno, "") or str(exc)
    names = [user_path(n) for n in (exc.filename, exc.filename2) if n is not None]
    # a rename names the temporary first and the user's path second: keep one, the
    # user's path (the two are the same once the temporary is mapped)
    names = list(dict.fromkeys(names))
    if len(names) == 2 and exc.filename2 is not None:
        names = [user_path(exc.filename2)]
    if names:
        return f"{names[0]}: {reason}"
    outputs = _outputs(args)
    if outputs:
        return f"{reason} (while writing {', '.join(outputs)})"
    return reason


def run_command(args, prog):
    """Run ``args.func(args)`` and map what goes wrong to an exit code and ONE line.

    ======================================================  ====  =======================
    outcome                                                  exit  stderr
    ======================================================  ====  =======================
    success                                                  code  warnings only
    :class:`~ins.common.errors.InputError` (bad input)              2     ``PROG CMD: error: ...``
    OSError on a path (missing, a file in the path, no       2     the user's path (never
    space, read-only, permission, not empty without --force)       a hidden temporary)
    :class:`~ins.common.errors.QualityError` (untrustworthy result) 3     ``PROG CMD: error: ...``
    Ctrl-C (also when it surfaced wrapped in another         130   ``PROG CMD: interrupted;
    exception, e.g. from extension code)                            no output written``
    SIGTERM (the same clean-up as Ctrl-C)                    143   ``PROG CMD: terminated
                                                                   (SIGTERM); no output
                                                                   written``
    ======================================================  ====  =======================

    An interrupt is held back while an output is renamed into place
    (:mod:`ins.common.interrupts`): it either takes effect before (no output) or after the
    output is complete, which the message then says.  After an interrupt, tracebacks
    of background threads and unraisable exceptions (finalizers of half-built objects)
    are silenced.
    """
    stale = native_build.stale_kernels()
    if stale:
        _say(f"{prog}: warning: compiled kernels older than their sources ({', '.join(stale)}): "
             f"the run uses the old ones; rebuild with `make` or `pip install -e .`")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", InputWarning)
        try:
            code = args.func(args)
        except SystemExit:
            raise
        except BaseException as exc:
            return _failure(exc, args, prog, caught)
    if interrupts.interrupted():           # held back until after the last output
        return _interrupted(args, prog)
    _flush_warnings(caught)
    return code


def _failure(exc, args, prog, caught):
    if interrupts.caused_by_interrupt(exc):
        return _interrupted(args, prog)
    where = f"{prog} {args.command}"
    if isinstance(exc, InputError):
        _flush_warnings(caught)
        _say(f"{where}: error: {exc}")
        return EXIT_BAD_INPUT
    if isinstance(exc, QualityError):
        _flush_warnings(caught)
        _say(f"{where}: error: {exc}")
        return EXIT_QUALITY
    if isinstance(exc, OSError):
        _flush_warnings(caught)
        _say(f"{where}: error: {_os_error_message(exc, args)}")
        return EXIT_BAD_INPUT
    raise exc                              # a bug: the traceback is the report


def _interrupted(args, prog):
    written = interrupts.written_outputs()
    if written:
        _say(f"{prog} {args.command}: {_stopped()} after the output was complete: "
             + ", ".join(user_path(p) for p in written))
    else:
        _say(f"{prog} {args.command}: {_stopped()}; no output written")
    return _stop_code()


def _flush_warnings(caught):
    for w in caught:
        _say(f"warning: {w.message}")


if __name__ == "__main__":
    sys.exit(main())
