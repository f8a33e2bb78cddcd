"""``ins allan IMU_FILE``: Allan deviation of a static IMU log, noise terms per axis (a
moving log is refused: :func:`ins.estimation.allan.static_check`)."""
import argparse
import os
import warnings

import numpy as np

from ins.common.errors import InputError, InputWarning

EPILOG = """\
frames and units:
  The IMU file holds increments (dtheta rad, dvel m/s) over (t[k-1], t[k]] in the body
  frame forward-right-down (KF-GINS text/binary or CSV, as for `ins mechanize`).  The
  Allan deviation is that of the rates (overlapping estimator).  The table gives per
  axis the angle random walk (deg/sqrt(h)) and gyro bias instability (deg/h), the
  velocity random walk (m/s/sqrt(h)) and accelerometer bias instability (mGal =
  1e-5 m/s^2); random walk = sigma(1 s) of the slope -1/2, bias instability = flat
  minimum / 0.664.

the log must be static (motion would be reported as noise); it is refused when
  - its mean specific force is not normal gravity (9.780..9.832 m/s^2) within 0.3 m/s^2,
  - its mean angular rate exceeds 0.1 deg/s (Earth rate 15 deg/h plus a gyro bias), or
  - in 1 s windows the mean rate or specific force departs from the log's median by
    more than 7 sigma of a window mean (white noise estimated from the log's
    sample-to-sample differences) and more than 0.01 deg/s or 0.05 m/s^2;
  the message gives the time spans that move.  --start/--end (s, the log's time) cut
  the static part; --allow-motion computes anyway, with a warning.

example:
  ins allan static_imu.txt --plot allan.png
  ins allan flight_imu.txt --start 200000 --end 200055
"""


def add_parser(sub):
    p = sub.add_parser("allan", help="Allan deviation and noise densities of an IMU log",
                       description="Overlapping Allan deviation of the gyro and accelerometer "
                                   "axes of a static IMU log, with the random walks and bias "
                                   "instabilities read from it.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("imu_file", metavar="IMU_FILE")
    p.add_argument("--format", choices=["kfgins", "kfgins-bin", "csv"], default=None,
                   help="IMU file format (default: from the extension)")
    p.add_argument("--axes", choices=["FRD", "FLU", "RFU", "FUR"], default="FRD")
    p.add_argument("--start", type=float, metavar="T",
                   help="first epoch used, s (the log's time; default: the first)")
    p.add_argument("--end", type=float, metavar="T",
                   help="last epoch used, s (default: the last)")
    p.add_argument("--allow-motion", action="store_true",
                   help="compute even when the log moves (a warning instead of an error)")
    p.add_argument("--plot", metavar="PNG", help="write the log-log plot of the deviations")
    p.set_defaults(func=_cmd_allan)


def _span_text(spans, limit=3):
    text = ", ".join(f"{a:.2f} .. {b:.2f} s" for a, b in spans[:limit])
    if len(spans) > limit:
        text += f" and {len(spans) - limit} more span(s)"
    return text


def _cmd_allan(args):
    from ins.estimation.allan import allan_deviation, noise_densities, static_check
    from ins.io import imu_files

    if args.plot:
        from ins.common.fileio import check_output_file
        check_output_file(args.plot)      # an unwritable plot: now, not after the work
    log = imu_files.read_imu(args.imu_file, format=args.format, axes=args.axes)
    if args.start is not None or args.end is not None:
        t0, t1 = float(log.time[0]), float(log.time[-1])
        if args.start is not None and args.end is not None and args.start >= args.end:
            raise InputError(f"--start {args.start} s is not before --end {args.end} s")
        log = log.slice_time(args.start, args.end)
        if len(log) == 0:
            raise InputError(f"{args.imu_file}: no epoch in --start/--end (the log covers "
                             f"{t0:.3f} .. {t1:.3f} s)")
    if len(log) < 100:
        raise InputError(f"{args.imu_file}: {len(log)} epochs are too few for an Allan "
                         f"deviation (expected >= 100)")
    check = static_check(log.time, log.dtheta_b, log.dvel_b)
    if not check.static:
        where = f"; moving: {_span_text(check.spans)}" if check.spans else ""
        text = (f"{args.imu_file} is not a static log: {'; '.join(check.reasons)}{where}")
        if not args.allow_motion:
            raise InputError(text + " (cut the static part with --start/--end, or "
                             "--allow-motion)")
        warnings.warn(text + " (--allow-motion: the deviations include the motion)",
                      InputWarning)
    dt = log.nominal_dt
    tau, ag = allan_deviation(log.dtheta_b, dt)
    _, aa = allan_deviation(log.dvel_b, dt)
    try:
        arw, gbi = noise_densities(tau, ag)
        vrw, abi = noise_densities(tau, aa)
    except ValueError as exc:
        raise InputError(f"{args.imu_file}: {exc}") from None
    print(f"{args.imu_file}: {len(log)} epochs, dt {dt:.6g} s, {len(log) * dt:.1f} s")
    print(f"{'axis':<6}{'ARW deg/sqrt(h)':>17}{'gyro BI deg/h':>15}"
          f"{'VRW m/s/sqrt(h)':>17}{'accel BI mGal':>15}")
    for i, name in enumerate("xyz"):
        print(f"{name:<6}{np.degrees(arw[i]) * 60:>17.5g}{np.degrees(gbi[i]) * 3600:>15.5g}"
              f"{vrw[i] * 60:>17.5g}{abi[i] / 1e-5:>15.5g}")
    if args.plot:
        plot_allan(args.plot, tau, ag, aa,
                   f"{os.path.basename(args.imu_file)}: {len(log) * dt:.0f} s static, "
                   f"{1 / dt:.0f} Hz")
        print(f"wrote {args.plot}")
    return 0


def plot_allan(path, tau_s, adev_gyro_rad_s, adev_accel_mps2, what=""):
    """Log-log plot of the Allan deviations (gyro deg/h, accel mGal) against tau (s)."""
    from ins.common.plotstyle import legend_right, pyplot, save_png
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.6))
    for i, name in enumerate("xyz"):
        a1.loglog(tau_s, np.degrees(adev_gyro_rad_s[:, i]) * 3600, label=f"gyro {name}")
        a2.loglog(tau_s, adev_accel_mps2[:, i] / 1e-5, label=f"accel {name}")
    a1.set(xlabel="averaging time tau, s", ylabel="Allan deviation, deg/h",
           title="gyroscopes")
    a2.set(xlabel="averaging time tau, s", ylabel="Allan deviation, mGal",
           title="accelerometers")
    for a in (a1, a2):
        a.grid(True, which="both", alpha=0.3)
        a.xaxis.set_major_formatter(lambda v, _: f"{v:g}")
        a.yaxis.set_major_formatter(lambda v, _: f"{v:g}")
        legend_right(a)
    fig.suptitle("Allan deviation" + (f" of {what}" if what else "")
                 + " (slope -1/2: random walk, flat floor: bias instability)")
    fig.tight_layout()
    return save_png(fig, path, dpi=100)
