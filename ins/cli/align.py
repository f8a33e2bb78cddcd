"""``ins align IMU_FILE --lla LAT,LON,H``: static alignment of an IMU at rest without
GNSS (coarse levelling and gyrocompassing, fine zero-velocity Kalman filter;
:mod:`ins.estimation.alignment.fine`)."""
import argparse
import os

import numpy as np

from ins.cli.util import triplet
from ins.common.errors import InputError, QualityError

EPILOG = """\
frames and units:
  n = north-east-down (NED), b = the IMU body frame forward-right-down (FRD; --axes maps
  other mountings); C_nb = Rz(yaw) Ry(pitch) Rx(roll) takes b into n; roll, pitch,
  heading (yaw) in deg, heading in [0, 360) from north towards east.  The IMU file holds
  increments (dtheta rad, dvel m/s) over (t[k-1], t[k]] stamped at the end, as for
  `ins mechanize`.  --lla: latitude, longitude (deg, south and west negative, as typed:
  --lla -33.9,151.2,50) and ellipsoidal height (m).  --start/--end: the log's time, s.

what the data support:
  roll and pitch come from the mean specific force, their sigma is the horizontal
  accelerometer bias over g (a bias and a tilt are one at rest: 1000 mGal ~ 210 arcsec).
  The heading comes from the Earth rate's horizontal component, W_ie cos(lat) (13 deg/h
  at 30 deg), and its sigma is
      hypot(sigma_bE, ARW / sqrt(T)) / (W_ie cos lat)
  with sigma_bE the gyro bias sigma on east (not observable at rest: it is one with the
  heading) and T the window's length.  Give the gyro's figures (--gyro-bias-std-dph: the
  turn-on bias and instability over the window; --arw-deg-sqrth); without them they are
  estimated from the log (ARW from the scatter of the increments; the bias sigma from its
  north and down components, which ARE observable: a two-sample estimate, say so).  When
  that sigma exceeds --max-heading-std-deg (default 10) the gyro cannot resolve the
  Earth rate (consumer MEMS; near the poles): the heading is reported unknown and the
  command exits 3 after printing roll and pitch, unless --level-only.

output (-o FILE.toml, written atomically; the heading known):
  [initial] lat_deg, lon_deg, h_m, time_s (the window's first epoch), vel_ned_mps = 0,
  rpy_deg, att_std_deg and [alignment] method = "given": a config for
  `ins process --config FILE.toml` (or its rpy_deg for `ins mechanize --init-att`).

example:
  ins align static.txt --lla 30.44,114.47,25 --gyro-bias-std-dph 1 --arw-deg-sqrth 0.12 \\
      --end 600 -o initial.toml
  ins align phone.csv --lla -33.9,151.2,50 --level-only

exit codes: 0 success; 2 bad input (the file, a missing or bad option, a log that moves);
  3 heading unknown (the gyro cannot see the Earth rate) without --level-only.
"""


def add_parser(sub):
    p = sub.add_parser("align", help="static alignment of an IMU at rest (no GNSS)",
                       description="Roll, pitch and heading of an IMU at rest with their "
                                   "sigmas: levelling and gyrocompassing, then a Kalman "
                                   "filter with zero-velocity updates over the window.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("imu_file", metavar="IMU_FILE")
    p.add_argument("--lla", required=True, type=triplet, metavar="LAT,LON,H",
                   help="position of the IMU: latitude, longitude (deg), ellipsoidal "
                        "height (m)")
    p.add_argument("--start", type=float, metavar="T", help="window start, s (default: first epoch)")
    p.add_argument("--end", type=float, metavar="T", help="window end, s (default: last epoch)")
    p.add_argument("--format", choices=["kfgins", "kfgins-bin", "csv"], default=None,
                   help="IMU file format (default: from the extension)")
    p.add_argument("--rates", action="store_true",
                   help="the KF-GINS columns hold rates (rad/s, m/s^2), not increments")
    p.add_argument("--axes", choices=["FRD", "FLU", "RFU", "FUR"], default="FRD")
    p.add_argument("--arw-deg-rth", "--arw-deg-sqrth", dest="arw_deg_sqrth", type=float, metavar="X",
                   help="gyro angle random walk, deg/sqrt(h) (default: from the log)")
    p.add_argument("--vrw-mps-sqrth", type=float, metavar="X",
                   help="accelerometer velocity random walk, m/s/sqrt(h) (default: from "
                        "the log)")
    p.add_argument("--gyro-bias-deg-h", "--gyro-bias-std-dph", dest="gyro_bias_std_dph",
                   type=float, metavar="X",
                   help="prior 1-sigma gyro bias per axis over the window, deg/h (default: "
                        "estimated from the log)")
    p.add_argument("--accel-bias-std-mgal", type=float, metavar="X",
                   help="prior 1-sigma accelerometer bias per axis, mGal = 1e-5 m/s^2 "
                        "(default: the vertical misfit |f| - g, at least 25 mGal)")
    p.add_argument("--zupt-sigma-mps", type=float, default=0.001, metavar="X",
                   help="sigma of the zero-velocity measurement, m/s (default 0.001; more "
                        "for a vibrating vehicle)")
    p.add_argument("--max-heading-std-deg", type=float, default=10.0, metavar="X",
                   help="larger heading sigma: heading unknown (default 10 deg)")
    p.add_argument("--level-only", action="store_true",
                   help="roll and pitch only (exit 0 whatever the gyro; no -o)")
    p.add_argument("-o", "--output", metavar="FILE.toml",
                   help="write the initial state for `ins process --config`")
    p.set_defaults(func=_cmd_align)


def _positive(args, name, unit):
    value = getattr(args, name)
    if value is not None and not (np.isfinite(value) and value > 0):
        raise InputError(f"--{name.replace('_', '-')}: expected a number > 0 ({unit}), "
                         f"got {value!r}")
    return value


def _angle_text(rad):
    """A sigma in arcsec below 0.1 deg, else in deg."""
    deg = float(np.rad2deg(rad))
    return f"{deg * 3600:.1f} arcsec" if deg < 0.1 else f"{deg:.2f} deg"


def _cmd_align(args):
    from ins.estimation.alignment.fine import align_at_rest
    from ins.estimation.core.error_model import DEG_SQRTH, DPH, MGAL, MPS_SQRTH
    from ins.io import imu_files

    lat, lon, h = (float(v) for v in args.lla)
    if abs(lat) > 90:
        raise InputError(f"--lla: latitude {lat:g} deg is outside +-90 deg (expected "
                         f"LAT,LON,H in deg, deg, m)")
    for name, unit in (("arw_deg_sqrth", "deg/sqrt(h)"), ("vrw_mps_sqrth", "m/s/sqrt(h)"),
                       ("gyro_bias_std_dph", "deg/h"), ("accel_bias_std_mgal", "mGal"),
                       ("zupt_sigma_mps", "m/s"), ("max_heading_std_deg", "deg")):
        _positive(args, name, unit)
    if args.start is not None and args.end is not None and args.start >= args.end:
        raise InputError(f"--start {args.start} s is not before --end {args.end} s")
    if args.output:
        if args.level_only:
            raise InputError("-o: --level-only gives no heading, and the initial state of "
                             "`ins process` needs one (drop -o or --level-only)")
        if os.path.abspath(args.output) == os.path.abspath(args.imu_file):
            raise InputError(f"--output {args.output} would overwrite the input file")
        from ins.common.fileio import check_output_file
        check_output_file(args.output)
    log = imu_files.read_imu(args.imu_file, format=args.format, rates=args.rates,
                             axes=args.axes)
    scale = lambda v, s: None if v is None else v * s          # noqa: E731
    try:
        al = align_at_rest(
            log, np.array([np.deg2rad(lat), np.deg2rad(lon), h]), args.start, args.end,
            arw=scale(args.arw_deg_sqrth, DEG_SQRTH), vrw=scale(args.vrw_mps_sqrth, MPS_SQRTH),
            gyro_bias_std=scale(args.gyro_bias_std_dph, DPH),
            accel_bias_std=scale(args.accel_bias_std_mgal, MGAL), level_only=args.level_only,
            max_heading_std=np.deg2rad(args.max_heading_std_deg),
            zupt_sigma_mps=args.zupt_sigma_mps)
    except InputError as exc:
        if exc.path is None:
            raise InputError(exc.reason, path=args.imu_file) from None
        raise
    _print(args, al, lat)
    if not al.heading_known and not args.level_only:
        raise QualityError(
            f"{args.imu_file}: heading unknown: {_gyro_error_text(al, lat)} over "
            f"{al.duration_s:.0f} s: the heading sigma would be more than "
            f"{args.max_heading_std_deg:g} deg; roll and pitch are printed above "
            f"(--level-only to accept them alone; the heading must come from elsewhere)")
    if args.output:
        _write_toml(args, al, lat, lon, h)
        print(f"wrote {args.output}")
    return 0


def _gyro_error_text(al, lat):
    """The gyro's east error (bias sigma, ARW over the window) against the Earth rate's
    horizontal component, deg/h."""
    w = _w_h(lat)
    dph = 180.0 / np.pi * 3600.0
    return (f"the gyro error on east (bias sigma {al.heading_std_bias * w * dph:.4g} deg/h, "
            f"ARW over the window {al.heading_std_noise * w * dph:.3g} deg/h) against the "
            f"Earth rate's horizontal component {w * dph:.2f} deg/h at {lat:g} deg")


def _w_h(lat_deg):
    from ins.nav import earth
    return earth.OMEGA_IE * np.cos(np.deg2rad(lat_deg))


def _print(args, al, lat):
    from ins.estimation.core.error_model import DEG_SQRTH, DPH, MGAL, MPS_SQRTH
    nz = al.noise
    src = nz.sources
    print(f"{args.imu_file}: window {al.time:.3f} .. {al.time_end:.3f} s "
          f"({al.duration_s:.1f} s) at latitude {lat:g} deg (Earth rate horizontal "
          f"{np.rad2deg(_w_h(lat)) * 3600:.3f} deg/h)")
    print(f"gyro: ARW {np.max(nz.arw) / DEG_SQRTH:.4g} deg/sqrt(h) ({src['arw']}), "
          f"bias sigma {np.max(nz.gyro_bias_std) / DPH:.4g} deg/h ({src['gyro_bias_std']})")
    print(f"accelerometers: VRW {np.max(nz.vrw) / MPS_SQRTH:.4g} m/s/sqrt(h) ({src['vrw']}), "
          f"bias sigma {np.max(nz.accel_bias_std) / MGAL:.4g} mGal ({src['accel_bias_std']})")
    if src["gyro_bias_std"] == "log":
        print("  (gyro bias sigma from the log: its north and down components at rest, a "
              "two-sample estimate, uncertain by a factor of about 2; give "
              "--gyro-bias-std-dph for a heading sigma to rely on)")
    if src["accel_bias_std"] == "log":
        print("  (accelerometer bias sigma from the log: the vertical misfit |f| - g, one "
              "sample that also holds the gravity anomaly; give --accel-bias-std-mgal for "
              "roll and pitch sigmas to rely on)")
    c = np.rad2deg(al.coarse_rpy)
    print(f"coarse: roll {c[0]:.4f} pitch {c[1]:.4f} heading {np.mod(c[2], 360):.4f} deg")
    what = (f"fine (Kalman filter, {al.n_updates} zero-velocity updates, mean NIS "
            f"{al.nis_mean:.2f} of 3 expected)" if al.method == "fine"
            else "levelling only (no fine filter: heading unknown)")
    print(what + ":")
    rpy = np.rad2deg(al.rpy)
    print(f"  roll    {rpy[0]:10.4f} deg  +- {_angle_text(al.rpy_std[0])}")
    print(f"  pitch   {rpy[1]:10.4f} deg  +- {_angle_text(al.rpy_std[1])}")
    parts = (f"(gyro bias east {_angle_text(al.heading_std_bias)}, ARW over the window "
             f"{_angle_text(al.heading_std_noise)})")
    if al.heading_known:
        print(f"  heading {np.mod(rpy[2], 360):10.4f} deg  +- {_angle_text(al.rpy_std[2])}  "
              f"{parts}")
    else:
        print(f"  heading    unknown       ({_gyro_error_text(al, lat)})")
    if al.method == "fine":
        print("estimated gyro bias x y z: "
              + " ".join(f"{v / DPH:.4g}" for v in al.gyro_bias_b) + " deg/h; accelerometer "
              "bias: " + " ".join(f"{v / MGAL:.4g}" for v in al.accel_bias_b) + " mGal "
              "(the east gyro and horizontal accelerometer components are their priors)")


def _write_toml(args, al, lat, lon, h):
    import tomli_w

    from ins.common.fileio import atomic_open
    rpy = np.rad2deg(al.rpy)
    rpy[2] = float(np.mod(rpy[2], 360.0))
    doc = {"initial": {"lat_deg": lat, "lon_deg": lon, "h_m": h, "time_s": float(al.time),
                       "vel_ned_mps": [0.0, 0.0, 0.0],
                       "rpy_deg": [float(v) for v in rpy],
                       "att_std_deg": [float(v) for v in np.rad2deg(al.rpy_std)]},
           "alignment": {"method": "given"}}
    src = al.noise.sources
    head = (f"# ins align {os.path.basename(args.imu_file)}: static alignment over "
            f"{al.time:.3f} .. {al.time_end:.3f} s (NED, C_nb = Rz(yaw) Ry(pitch) Rx(roll))\n"
            f"# sigmas from: gyro bias {src['gyro_bias_std']}, ARW {src['arw']}, "
            f"accelerometer bias {src['accel_bias_std']}\n")
    with atomic_open(args.output, "w") as f:
        f.write(head + tomli_w.dumps(doc))
