"""``ins time-offset --imu F --gnss F``: the IMU-GNSS clock offset estimated from the
data (:mod:`ins.estimation.tools.time_offset`), with its sigma; ``-o`` writes the GNSS log shifted onto
the IMU's time scale."""
import argparse

import numpy as np

from ins.cli.util import number
from ins.common.errors import InputError

EPILOG = """\
method:
  The GNSS velocity change over a window (--window, s) centred on each fix, less
  gravity, against the specific force integrated over the same window, resolved in the
  IMU's first body frame by the gyros alone; that frame's rotation into NED is fitted
  per knot interval (--knots s: tilt from gravity, heading from the turns and speed
  changes), so the IMU may sit in any attitude and the vehicle may bank, crab or turn.
  Slowly varying terms (accelerometer bias, tilt drift) are fitted as piecewise-linear
  functions on the same knots.  The residual sum of squares over trial offsets (step
  --step s within +-max) has its minimum refined by a parabola (sub-sample); sigma from
  its curvature, inflated by the residuals' correlation.  A constant accelerometer
  bias (body frame: it turns with the IMU) is fitted at the offset found without it
  and the offset searched again (at walking pace a 10 mg bias is as large as the
  signal).  Fixes slower than --min-speed (m/s, default 0.5: a walk at 1-2 m/s with
  turns and stops works) are not used.  The information is in the accelerations and
  turns: a straight constant-speed log is refused.

sign:
  offset = IMU clock - GNSS clock (s): a fix stamped t was taken at IMU time
  t + offset.  Paste it as it is into the process config: the position's offset into
  [gnss] time_shift_s (--gnss-time-shift-s), the velocity's into [gnss]
  velocity_time_shift_s (--gnss-velocity-time-shift-s) when the two differ by more
  than their sigmas ([imu] time_shift_s would take -offset).  The same sign as the
  filter's time_offset state in states.txt ([states] time_offset = true).
  -o writes the GNSS log with the offset added to every stamp.

--source:
  velocity  the GNSS velocity columns (13-column file)
  position  the differences of consecutive positions (at their mid times)
  both      (default) both, reported one beside the other: a receiver's positions and
            its Doppler velocities may carry different delays (the comma2k19 u-blox:
            docs/real-data.md); -o then uses the velocity estimate when the file has
            velocities.

frames and units:
  IMU increments in the body frame (any mounting: its attitude is fitted; --axes and
  --rates read the file as ins process does);
  GNSS KF-GINS text (time, lat, lon deg, h m, sigmas; optionally vn ve vd m/s, NED) or
  RTKLIB .pos (positions: use --source position).

exit codes: 0 success, 2 bad input (files, too few fixes at speed, no accelerations,
  a minimum at the edge of the searched range), 130 Ctrl-C, 143 SIGTERM.

example:
  ins time-offset --imu imu.txt --gnss gnss.txt
  ins time-offset --imu imu.txt --gnss gnss.txt --source velocity -o gnss_on_imu_time.txt
"""


def add_parser(sub):
    p = sub.add_parser("time-offset", help="IMU-GNSS clock offset estimated from the data",
                       description="Estimate the offset between the IMU's and the GNSS's "
                                   "time stamps (s) from the accelerations both see, with "
                                   "its 1-sigma.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--imu", required=True, metavar="F", help="IMU log (KF-GINS text/binary "
                   "or CSV)")
    p.add_argument("--gnss", required=True, metavar="F",
                   help="GNSS log (KF-GINS text or RTKLIB .pos, sniffed as ins process does)")
    p.add_argument("--format", choices=["kfgins", "kfgins-bin", "csv"], default=None,
                   help="IMU file format (default: from the extension)")
    p.add_argument("--rates", action="store_true",
                   help="the IMU columns hold rad/s and m/s^2 instead of increments")
    p.add_argument("--axes", choices=["FRD", "FLU", "RFU", "FUR"], default="FRD")
    p.add_argument("--source", choices=["both", "velocity", "position"], default="both")
    p.add_argument("--max", type=number(0, lo_open=True, unit="s"), default=1.0, metavar="S",
                   help="largest offset searched, s (default 1)")
    p.add_argument("--step", type=number(0, lo_open=True, unit="s"), default=0.005, metavar="S",
                   help="step of the trial offsets, s (default 0.005)")
    p.add_argument("--window", type=number(0, lo_open=True, unit="s"), default=0.5, metavar="S",
                   help="window of the velocity changes, s (default 0.5)")
    p.add_argument("--knots", type=number(0, lo_open=True, unit="s"), default=10.0, metavar="S",
                   help="knot spacing of the slowly varying terms, s (default 10)")
    p.add_argument("--min-speed", type=number(0, unit="m/s"), default=0.5, metavar="MPS",
                   help="fixes slower than this are not used, m/s (default 0.5)")
    p.add_argument("-o", "--output", metavar="GNSS_OUT",
                   help="write the GNSS log shifted onto the IMU's time scale (KF-GINS "
                        "text; an RTKLIB covariance is not carried over)")
    p.set_defaults(func=_cmd_time_offset)


def _cmd_time_offset(args):
    from ins.common.fileio import check_output_file
    from ins.estimation.tools.time_offset import estimate_time_offset, shift_gnss
    from ins.io.gnss import read_gnss, write_gnss
    from ins.io.imu_files import read_imu
    if args.output:
        check_output_file(args.output)
    imu = read_imu(args.imu, format=args.format, rates=args.rates, axes=args.axes)
    gnss = read_gnss(args.gnss)
    sources = ["position", "velocity"] if args.source == "both" else [args.source]
    if args.source == "both" and not gnss.has_velocity:
        sources = ["position"]
    results = {}
    for src in sources:
        try:
            results[src] = estimate_time_offset(
                imu, gnss, source=src, max_offset_s=args.max, step_s=args.step,
                window_s=args.window, knot_s=args.knots, min_speed_mps=args.min_speed)
        except InputError as exc:
            raise InputError(f"{args.gnss} ({src}): {exc}") from None
    for src, r in results.items():
        print(f"{src:<8}  offset {r.offset_s:+.4f} s  sigma {r.sigma_s:.4f} s  "
              f"({r.n_fixes} epochs, {r.n_eff:.0f} independent; signal {r.signal_rms_mps:.3f} "
              f"m/s RMS, residual {r.residual_rms_mps:.3f} m/s)")
        if r.accel_bias_b_mps2 is not None:
            print(f"{'':<8}  with an accelerometer bias fitted (IMU axes): "
                  + " ".join(f"{v:+.3f}" for v in r.accel_bias_b_mps2) + " m/s^2")
    print("offset = IMU clock - GNSS clock: a fix stamped t was taken at IMU time t + offset")
    for line in _advice(results):
        print(line)
    if args.output:
        chosen = results.get("velocity", results.get("position"))
        write_gnss(args.output, shift_gnss(gnss, chosen.offset_s))
        print(f"wrote {args.output}: stamps plus {chosen.offset_s:+.4f} s ({chosen.source})")
    return 0


def _advice(results):
    """The options of ``ins process`` to pass, from the estimates by source."""
    pos, vel = results.get("position"), results.get("velocity")
    if pos is not None and vel is not None:
        diff = vel.offset_s - pos.offset_s
        sig = float(np.hypot(pos.sigma_s, vel.sigma_s))
        if abs(diff) > 2.0 * sig:
            return [f"ins process --gnss-time-shift-s {pos.offset_s:.3f} "
                    f"--gnss-velocity-time-shift-s {vel.offset_s:.3f}   (the velocities "
                    f"{diff:+.3f} s from the positions, {abs(diff) / sig:.1f} sigma)"]
        return [f"ins process --gnss-time-shift-s {pos.offset_s:.3f}   (positions and "
                f"velocities agree within {abs(diff) / sig:.1f} sigma: one shift for both; "
                f"or --gnss-velocity-time-shift-s {vel.offset_s:.3f})"]
    r = pos if pos is not None else vel
    name = "--gnss-time-shift-s" if r.source == "position" else "--gnss-velocity-time-shift-s"
    return [f"ins process {name} {r.offset_s:.3f}"]
