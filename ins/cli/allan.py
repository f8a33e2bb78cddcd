"""``ins allan IMU_FILE``: Allan deviation of a static IMU log, IEEE 952 noise terms per
axis with intervals, the classic reading where the model does not describe the curve
(:func:`ins.estimation.tools.allan.classic_reading`); a moving log is refused
(:func:`ins.estimation.alignment.static_check.static_check`)."""
import argparse
import os
import warnings

import numpy as np

from ins.common.errors import InputError, InputWarning, QualityError

#: Largest reduced chi-square of a trusted fit: with the estimator's own covariance in
#: the weights a curve that the model explains gives about 1 (0.5 .. 2 on simulated
#: logs); above 10 the curve departs from the model by about 3 times its noise.
CHI2_POOR = 10.0

EPILOG = """\
frames and units:
  The IMU file holds increments (dtheta rad, dvel m/s) over (t[k-1], t[k]] in the body
  frame forward-right-down (KF-GINS text/binary or CSV, as for `ins mechanize`).  The
  Allan deviation is that of the rates (overlapping estimator).  The IEEE 952 model
    sigma^2(tau) = 3 Q^2/tau^2 + N^2/tau + (2 ln2/pi) B^2 + K^2 tau/3 + R^2 tau^2/2
  is fitted to the whole curve (non-negative least squares at octave taus, weighted by
  the covariance of the estimates) and printed per axis with its 95 % interval:
  quantization Q, random walk N (ARW deg/sqrt(h), VRW m/s/sqrt(h)), bias instability
  B (deg/h, mGal = 1e-5 m/s^2; the flat floor is 0.664 B), rate random walk K
  (deg/h/sqrt(h), mGal/sqrt(h)) and rate ramp R (deg/h^2, mGal/h).  chi2 is the
  reduced chi-square of the fit: well above 1, the curve has what the model lacks
  (a filter's ripple, a sinusoid), and the intervals are widened by its root.
  Above 10 on an axis the model does not describe the curve, and the classic reading
  of that axis follows the table, with 95 % intervals from the degrees of freedom of
  the overlapping Allan variance (NIST SP 1065): N from the line of slope -1/2 laid on
  the curve where the curve has that slope (within 0.1, over at least 0.3 decade
  before the minimum; the lowest such stretch), read at tau = 1 s, its interval
  widened by the curve's departure from that slope there; B = the curve's
  minimum / 0.664 (high where the other noises add to the floor) and its tau; beside
  them the model's reduced chi-square.  Exit 0; exit 3 when an axis has no such stretch
  (--accept-poor: 0).

the log must be static (motion would be reported as noise); it is refused when
  - its mean specific force is not normal gravity (9.780..9.832 m/s^2) within 0.3 m/s^2,
  - gravity's direction in the body (mean specific force over windows) turns faster or
    farther than an accelerometer bias drifts with temperature: between two adjacent
    windows of S = 1, 2, 4, ... s by more than 15 mg/h x S (0.014 deg/min) plus 7 sigma
    of its noise at that scale (at least 0.1 deg), or by more than 20 mg (1.15 deg) over
    the log; the specific force's magnitude likewise (at least 1.7 mg); a slow drift of
    the level over hours (tenths of a degree) is the sensor's, not motion,
  - the gyros integrate a rotation (rate less its 5 min running median) between two
    adjacent windows of up to 75 s above 7 sigma of their own noise (at least 0.1 deg),
  - in 1 s windows the mean rate or specific force departs from its running median
    (5 min) by more than 7 sigma of a window mean and more than 0.01 deg/s or
    0.05 m/s^2: a turn about the vertical, a bump;
  a constant rate is not motion (a MEMS gyro bias of several deg/s is accepted); the
  message gives the time spans that move.  --start/--end (s, the log's time) cut the
  static part; --allow-motion computes anyway, with a warning.

example:
  ins allan static_imu.txt --plot allan.png
  ins allan flight_imu.txt --start 200000 --end 200055
"""


def add_parser(sub):
    p = sub.add_parser("allan", help="Allan deviation and IEEE 952 noise terms of an IMU log",
                       description="Overlapping Allan deviation of the gyro and accelerometer "
                                   "axes of a static IMU log, with the IEEE 952 noise model "
                                   "fitted to it (quantization, random walk, bias "
                                   "instability, rate random walk, rate ramp).",
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
    p.add_argument("--accept-poor", action="store_true",
                   help=f"exit 0 even when neither the model (reduced chi-square above "
                        f"{CHI2_POOR:g} on an axis) nor the classic reading (no stretch of "
                        f"slope -1/2) describes the curve (default: exit 3)")
    p.set_defaults(func=_cmd_allan)


def _span_text(spans, limit=3):
    text = ", ".join(f"{a:.2f} .. {b:.2f} s" for a, b in spans[:limit])
    if len(spans) > limit:
        text += f" and {len(spans) - limit} more span(s)"
    return text


def _cmd_allan(args):
    from ins.estimation.tools.allan import (
        MIN_RUN_DECADES,
        SLOPE_TOL,
        TERMS,
        allan_deviation,
        fit_noise_model,
    )
    from ins.estimation.alignment.static_check import static_check
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
        fit_g = fit_noise_model(log.dtheta_b, dt)
        fit_a = fit_noise_model(log.dvel_b, dt)
    except ValueError as exc:
        raise InputError(f"{args.imu_file}: {exc}") from None
    print(f"{args.imu_file}: {len(log)} epochs, dt {dt:.6g} s, {len(log) * dt:.1f} s; "
          f"IEEE 952 model, value [95 % interval]")
    for sensor, fit, units in (("gyro", fit_g, GYRO_UNITS), ("accel", fit_a, ACCEL_UNITS)):
        print(f"{sensor:<8}" + "".join(f"{t + ' ' + u[0]:<28}" for t, u in zip(TERMS, units))
              + "chi2")
        for i, name in enumerate("xyz"):
            cells = [f"{_g(fit.value[j, i] / u[1])} [{_g(fit.lo[j, i] / u[1])}, "
                     f"{_g(fit.hi[j, i] / u[1])}]" for j, u in enumerate(units)]
            print(f"{sensor[0] + ' ' + name:<8}" + "".join(f"{c:<28}" for c in cells)
                  + f"{fit.chi2[i]:.3g}")
    poor = {sensor: fit.chi2 > CHI2_POOR for sensor, fit in (("gyro", fit_g), ("accel", fit_a))}
    classic = {}
    if any(p.any() for p in poor.values()):
        from ins.estimation.tools.allan import classic_reading
        try:
            classic = {"gyro": classic_reading(log.dtheta_b, dt) if poor["gyro"].any()
                       else None,
                       "accel": classic_reading(log.dvel_b, dt) if poor["accel"].any()
                       else None}
        except ValueError as exc:
            raise InputError(f"{args.imu_file}: {exc}") from None
        _print_classic(poor, classic, fit_g, fit_a)
    if args.plot:
        plot_allan(args.plot, tau, ag, aa,
                   f"{os.path.basename(args.imu_file)}: {len(log) * dt:.0f} s static, "
                   f"{1 / dt:.0f} Hz", fit_gyro=fit_g, fit_accel=fit_a,
                   classic_gyro=_masked(classic.get("gyro"), poor["gyro"]),
                   classic_accel=_masked(classic.get("accel"), poor["accel"]))
        print(f"wrote {args.plot}")
    unread = [f"{sensor} {'xyz'[i]}" for sensor in ("gyro", "accel") for i in range(3)
              if poor[sensor][i] and not classic[sensor].found[i]]
    if unread and not args.accept_poor:
        chi = ", ".join(f"{sensor} {'xyz'[i]} {fit.chi2[i]:.3g}" for sensor, fit in
                        (("gyro", fit_g), ("accel", fit_a)) for i in range(3)
                        if poor[sensor][i])
        raise QualityError(f"{args.imu_file}: the IEEE 952 model does not describe the "
                           f"Allan deviation (reduced chi-square {chi}, above "
                           f"{CHI2_POOR:g}) and the curve of {', '.join(unread)} has no "
                           f"stretch of slope -1/2 (within {SLOPE_TOL:g}, at least "
                           f"{MIN_RUN_DECADES:g} decade) before its minimum to read the "
                           f"random walk from: the log holds what neither describes "
                           f"(vibration, a filter's ripple, motion) or is too short "
                           f"(--accept-poor: exit 0)")
    return 0


_DEG = np.pi / 180.0
#: Display units of the gyro terms Q, N, B, K, R: (text, SI per unit).
GYRO_UNITS = (("arcsec", _DEG / 3600), ("deg/sqrt(h)", _DEG / 60), ("deg/h", _DEG / 3600),
              ("deg/h/sqrt(h)", _DEG / 3600 / 60), ("deg/h^2", _DEG / 3600 ** 2))
#: ... and of the accelerometer terms.
ACCEL_UNITS = (("mm/s", 1e-3), ("m/s/sqrt(h)", 1 / 60), ("mGal", 1e-5),
               ("mGal/sqrt(h)", 1e-5 / 60), ("mGal/h", 1e-5 / 3600))


def _g(v):
    return f"{v:.3g}"


def _masked(reading, mask):
    """``reading`` with the axes outside ``mask`` (the ones the model describes) unread."""
    if reading is None:
        return None
    import dataclasses
    return dataclasses.replace(reading, found=reading.found & mask)


def _print_classic(poor, classic, fit_g, fit_a):
    axes = [f"{s} {'xyz'[i]}" for s in ("gyro", "accel") for i in range(3) if poor[s][i]]
    print(f"the IEEE 952 model does not describe the curve of {', '.join(axes)} (reduced "
          f"chi-square above {CHI2_POOR:g}): the classic reading, 95 % intervals from the "
          f"degrees of freedom of the overlapping Allan variance (the clusters, NIST SP "
          f"1065); N: the -1/2 slope line laid where the curve has that slope, read at "
          f"tau = 1 s; B: the curve's minimum / 0.664 (it reads high where the other "
          f"noises add to the floor; few clusters at the longest taus)")
    print(f"{'classic':<9}{'N':<38}{'line on at':<12}{'B':<30}{'minimum at':<12}model chi2")
    for sensor, fit, units in (("gyro", fit_g, GYRO_UNITS), ("accel", fit_a, ACCEL_UNITS)):
        r = classic[sensor]
        if r is None:
            continue
        (nu, nk), (bu, bk) = units[1], units[2]
        for i in np.flatnonzero(poor[sensor]):
            if r.found[i]:
                n_cell = (f"{_g(r.n[i] / nk)} [{_g(r.n_lo[i] / nk)}, {_g(r.n_hi[i] / nk)}] "
                          f"{nu}")
                n_tau = f"{_g(r.n_tau[i])} s"
            else:
                n_cell, n_tau = "not readable: no -1/2 stretch", "-"
            b_cell = f"{_g(r.b[i] / bk)} [{_g(r.b_lo[i] / bk)}, {_g(r.b_hi[i] / bk)}] {bu}"
            print(f"{sensor + ' ' + 'xyz'[i]:<9}{n_cell:<38}{n_tau:<12}{b_cell:<30}"
                  f"{_g(r.b_tau[i]) + ' s':<12}{fit.chi2[i]:.3g}")


def plot_allan(path, tau_s, adev_gyro_rad_s, adev_accel_mps2, what="", fit_gyro=None,
               fit_accel=None, classic_gyro=None, classic_accel=None):
    """Log-log plot of the Allan deviations (gyro deg/h, accel mGal) against tau (s),
    with the fitted IEEE 952 models (:class:`ins.estimation.tools.allan.NoiseFit`) dashed and
    the classic readings (:class:`ins.estimation.tools.allan.ClassicReading`, the axes it
    marks ``found``) dotted: the -1/2 line of N and the minimum of B (a circle)."""
    from ins.common.plotstyle import legend_right, pyplot, save_png
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(12, 9))
    per_h = np.degrees(1.0) * 3600
    for i, name in enumerate("xyz"):
        a1.loglog(tau_s, adev_gyro_rad_s[:, i] * per_h, label=f"gyro {name}")
        a2.loglog(tau_s, adev_accel_mps2[:, i] / 1e-5, label=f"accel {name}")
    for ax, fit, k, units, sensor in ((a1, fit_gyro, per_h, GYRO_UNITS, "gyro"),
                                      (a2, fit_accel, 1e5, ACCEL_UNITS, "accel")):
        if fit is None:
            continue
        model = fit.adev(tau_s) * k
        for i, name in enumerate("xyz"):
            n_u, b_u = units[1], units[2]
            ax.loglog(tau_s, model[:, i], "--", color=f"C{i}", lw=1.0,
                      label=f"model {name}: N {_g(fit.value[1, i] / n_u[1])} "
                            f"[{_g(fit.lo[1, i] / n_u[1])}, {_g(fit.hi[1, i] / n_u[1])}] "
                            f"{n_u[0]}, B {_g(fit.value[2, i] / b_u[1])} "
                            f"[{_g(fit.lo[2, i] / b_u[1])}, {_g(fit.hi[2, i] / b_u[1])}] "
                            f"{b_u[0]}")
    for ax, r, k, units in ((a1, classic_gyro, per_h, GYRO_UNITS),
                            (a2, classic_accel, 1e5, ACCEL_UNITS)):
        if r is None:
            continue
        for i in np.flatnonzero(r.found):
            ax.loglog(tau_s, r.n[i] / np.sqrt(tau_s) * k, ":", color=f"C{i}", lw=1.2,
                      label=f"classic {'xyz'[i]}: N {_g(r.n[i] / units[1][1])} "
                            f"[{_g(r.n_lo[i] / units[1][1])}, {_g(r.n_hi[i] / units[1][1])}] "
                            f"{units[1][0]}, B {_g(r.b[i] / units[2][1])} {units[2][0]}")
            ax.plot([r.b_tau[i]], [r.b[i] * 0.664 * k], "o", color=f"C{i}", mfc="none")
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
                 + " and the fitted IEEE 952 model (dashed; 95 % intervals)"
                 + ("; the classic reading where the model does not fit (dotted: the -1/2 "
                    "line, circle: the minimum)" if classic_gyro is not None
                    or classic_accel is not None else ""))
    fig.tight_layout()
    return save_png(fig, path, dpi=100)
