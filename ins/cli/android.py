"""``ins import-android LOG.txt -o DIR``: an Android GnssLogger log into the toolkit's
files: the raw GNSS as RINEX 3.04, the IMU as a CSV of rates on GPS time, the phone's
own fixes as an RTKLIB .pos (:mod:`ins.io.gnsslogger`)."""
import argparse
import os

import numpy as np

from ins.common.errors import InputError

EPILOG = """\
input: a GnssLogger text log (Google's GnssLogger app, 'gnss_log_*.txt': '# Raw,...'
  header comments, then Raw, Fix, UncalAccel, UncalGyro, Accel, Gyro records; other
  records are skipped).  Columns by their header's names (those of GnssLogger 1.4,
  2016, too: Fix Latitude, Longitude, Altitude, Accuracy, (UTC)TimeInMs); a record cut
  short or with a field that is no number is left out and counted in the summary.
  Leap seconds: the log's LeapSecond column, else the table at its first epoch.

outputs (in -o DIR, new or empty; --force replaces it):
  gnss.obs   RINEX 3.04 of the Raw records, every system and signal (GPS, GLONASS,
             Galileo, BeiDou, QZSS; 1C/2I/5Q ...): pseudorange m = (receive time -
             ReceivedSvTimeNanos) c, the receive time TimeNanos + TimeOffsetNanos -
             (FullBiasNanos + BiasNanos) of each epoch in the system's time scale, kept
             when State says the code is locked and the satellite time known (TOW /
             GLONASS time of day) and ReceivedSvTimeUncertaintyNanos <= 500; carrier
             phase cycles = AccumulatedDeltaRangeMeters / wavelength when its state is
             VALID (RESET/CYCLE_SLIP, or a change of HardwareClockDiscontinuityCount,
             set the loss-of-lock flag); Doppler Hz = -PseudorangeRateMetersPerSecond
             / wavelength; C/N0 dB-Hz.  Epochs in GPS time (the phone's estimate).
             'ins gnss gnss.obs --nav BRDC' solves it.
  imu.csv    time_s (GPS s of week), gyro_x/y/z_radps, accel_x/y/z_mps2 in the body
             frame FRD: forward = the phone's y (top edge), right = its x, down = -z
             (out of the screen), i.e. the phone flat, screen up, top forward; mount it
             otherwise with [vehicle] mounting_rpy_deg.  UncalGyro/UncalAccel (biases
             left in: the filter estimates them) when the log has them, else Gyro/Accel;
             the accelerometer interpolated linearly to the gyro's stamps.  Time: the
             sensors' elapsedRealtimeNanos mapped to GPS time by the least-squares line
             through the Raw epochs' ChipsetElapsedRealtimeNanos and their GPS times
             (else through the GPS fixes' elapsedRealtimeNanos and UTC time; else,
             logs before Android 10, through the sensor records' own utcTimeMillis:
             the phone's system clock, off GPS time by an unknown NTP error of tens
             of ms, which the summary says: 'ins time-offset' estimates it).  'ins
             process --imu imu.csv' reads it (rates into increments over the real
             intervals).
  fix.pos    the phone's fixes (provider gps; fused/network when there is no gps fix)
             as an RTKLIB .pos: latitude, longitude deg, height m above the WGS84
             ellipsoid (Android's altitude), GPS time (UnixTimeMillis + leap seconds),
             sigmas N = E = AccuracyMeters / 1.515 (a 68 % horizontal radius), U =
             VerticalAccuracyMeters: a reference trajectory, or --gnss of ins process.

example:
  ins import-android gnss_log_2024_05_01.txt -o drive
  ins gnss drive/gnss.obs --nav BRDC00IGS_R_20241220000_01D_MN.rnx --mode single -o p.pos
"""

#: 68 % radius of a circular 2-D normal distribution in units of its sigma.
R68_PER_SIGMA = 1.515


def add_parser(sub):
    p = sub.add_parser(
        "import-android", help="Android GnssLogger log into RINEX, IMU CSV and fix.pos",
        description="Convert an Android GnssLogger log: raw GNSS measurements to RINEX "
                    "3.04, the inertial sensors to the toolkit's IMU CSV on GPS time, the "
                    "phone's fixes to an RTKLIB .pos.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("log", metavar="LOG.txt", help="GnssLogger text log")
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="output folder (new or empty)")
    p.add_argument("--force", action="store_true", help="replace a non-empty DIR whole")
    p.add_argument("-q", "--quiet", action="store_true", help="no summary")
    p.set_defaults(func=run)


def run(args):
    from ins.common.fileio import output_folder
    from ins.io.gnsslogger import raw_observations, read_gnsslogger
    log = read_gnsslogger(args.log)
    raw = raw_observations(log)
    summary = []
    with output_folder(args.output, force=args.force) as stage:
        from ins.io.rinex_obs_multi import write_rinex3_multi
        note = f"ins import-android {os.path.basename(args.log)}"[:60]
        n = write_rinex3_multi(os.path.join(stage, "gnss.obs"), raw.week, raw.time_s,
                               raw.epochs, leap_seconds=raw.leap_s, comments=[note],
                               glonass_fcn=raw.glonass_fcn)
        sigs = sorted({f"{s}{c}" for ep in raw.epochs for s, _, c in ep})
        summary.append(f"gnss.obs: {n} epochs, signals {' '.join(sigs)}; {raw.dropped} "
                       f"measurements left out (time unknown, no code lock, unknown signal, "
                       f"ReceivedSvTimeUncertaintyNanos > 500)")
        imu_line = write_imu(log, raw, os.path.join(stage, "imu.csv"))
        if imu_line:
            summary.append(imu_line)
        fix_line = write_fixes(log, raw, os.path.join(stage, "fix.pos"))
        if fix_line:
            summary.append(fix_line)
    if log.skipped:
        no, why = log.skipped[0]
        summary.append(f"{len(log.skipped)} malformed record(s) left out, the first: line "
                       f"{no}: {why}")
    if not args.quiet:
        print(f"{args.log}: GPS week {raw.week}, leap seconds {raw.leap_s}")
        for line in summary:
            print("  " + line)
    return 0


def _sensor(log, names):
    for kind, prefix, unit in names:
        if log.has(kind):
            t = log.tables[kind]
            cols = [f"{prefix}{a}{unit}" for a in "XYZ"]
            if all(c in t for c in cols) and "elapsedRealtimeNanos" in t:
                el = t["elapsedRealtimeNanos"]
                keep = np.array([e is not None for e in el])
                return kind, np.array([e for e in el if e is not None], np.int64), \
                    np.column_stack([t[c][keep] for c in cols])
    return None


def write_imu(log, raw, path):
    """The IMU CSV (EPILOG); returns the summary line, or None without sensors."""
    from ins.common.fileio import atomic_open
    from ins.io.gnsslogger import sensor_to_gps
    gyro = _sensor(log, (("UncalGyro", "UncalGyro", "RadPerSec"),
                         ("Gyro", "Gyro", "RadPerSec")))
    acc = _sensor(log, (("UncalAccel", "UncalAccel", "Mps2"), ("Accel", "Accel", "Mps2")))
    if gyro is None or acc is None:
        return None
    to_gps, (src, rms) = sensor_to_gps(raw, log)
    tg = to_gps(gyro[1])
    ta = to_gps(acc[1])
    og, oa = np.argsort(tg, kind="stable"), np.argsort(ta, kind="stable")
    tg, wg = tg[og], gyro[2][og]
    ta, fa = ta[oa], acc[2][oa]
    keep = (tg >= ta[0]) & (tg <= ta[-1]) & np.concatenate([[True], np.diff(tg) > 0])
    tg, wg = tg[keep], wg[keep]
    if len(tg) < 2:
        raise InputError("the gyro and accelerometer records do not overlap in time",
                         path=log.path)
    fg = np.column_stack([np.interp(tg, ta, fa[:, k]) for k in range(3)])
    frd = lambda v: np.column_stack([v[:, 1], v[:, 0], -v[:, 2]])  # noqa: E731
    table = np.column_stack([tg, frd(wg), frd(fg)])
    with atomic_open(path, "w") as f:
        f.write("# ins import-android: phone axes x right, y top, z out of the screen -> "
                "FRD (y, x, -z)\n")
        f.write("time_s,gyro_x_radps,gyro_y_radps,gyro_z_radps,accel_x_mps2,accel_y_mps2,"
                "accel_z_mps2\n")
        for row in table:
            f.write(f"{row[0]:.6f}," + ",".join(f"{v:.9g}" for v in row[1:]) + "\n")
    rate = (len(tg) - 1) / (tg[-1] - tg[0]) if tg[-1] > tg[0] else 0.0
    return (f"imu.csv: {len(tg)} samples of {gyro[0]}/{acc[0]} ({rate:.0f} Hz) on GPS "
            f"time through {src} (line RMS {rms * 1e6:.1f} us)")


def write_fixes(log, raw, path):
    """fix.pos (EPILOG); returns the summary line, or None without fixes."""
    from ins.io.gnss_log import GnssLog
    from ins.io.gnsslogger import unix_ms_to_gps
    from ins.io.rtklib import write_pos
    if not log.has("Fix"):
        return None
    f = log.tables["Fix"]
    prov = np.array([str(p).lower() for p in f.get("Provider", [])], dtype=object)
    ok = np.array([u is not None for u in f["UnixTimeMillis"]]) & \
        np.isfinite(f["LatitudeDegrees"]) & np.isfinite(f["LongitudeDegrees"])
    use = ok & (prov == "gps") if np.any(ok & (prov == "gps")) else ok
    if not np.any(use):
        return None
    unix_ms = np.array([u for u, k in zip(f["UnixTimeMillis"], use) if k], np.int64)
    t = unix_ms_to_gps(unix_ms, raw.week, raw.leap_s)
    lla = np.column_stack([np.radians(f["LatitudeDegrees"][use]),
                           np.radians(f["LongitudeDegrees"][use]),
                           np.nan_to_num(f.get("AltitudeMeters", np.zeros(len(use)))[use])])
    acc = f.get("AccuracyMeters", np.full(len(use), np.nan))[use]
    vacc = f.get("VerticalAccuracyMeters", np.full(len(use), np.nan))[use]
    sh = np.where(np.isfinite(acc), acc / R68_PER_SIGMA, 10.0)
    sv = np.where(np.isfinite(vacc), vacc, 2.0 * sh)
    order = np.argsort(t, kind="stable")
    gl = GnssLog(time=t[order], lla=lla[order],
                 sigma_ned_m=np.column_stack([sh, sh, sv])[order])
    which = "gps" if np.any(prov[use] == "gps") else "all providers"
    write_pos(path, gl, raw.week, comments=[f"ins import-android {os.path.basename(log.path)}"
                                            f": the phone's fixes ({which})"])
    return f"fix.pos: {len(gl)} fixes"
