"""``ins import-android`` on real GnssLogger logs (tests/data/android, README.md there):

- a Pixel 4 log of the Google Smartphone Decimeter Challenge 2021 (one epoch, GPS L1/L5,
  GLONASS, Galileo E1/E5a): the pseudoranges against Google's own published ones (the
  challenge's derived file, ``rawPrM``), the inertial records on GPS time through their
  ``utcTimeMillis`` (the log has no other tie), a corrupt record left out;
- Google's 2016 demo log (GnssLogger 1.4, GPS L1, a hardware clock discontinuity at
  every epoch from the 10th): its Fix columns of that app version, 17 leap seconds,
  the pseudoranges and epochs against the white paper's formula evaluated here in
  exact integer nanoseconds, and RTKLIB's single-point solution of the RINEX against
  the phone's own fixes (which are no truth: the phone's fused estimate).

The test skips when the data or RTKLIB's binding (the optional extra ``gnss``) is
missing."""
import csv
import datetime as dt
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parent / "data" / "android"
PIXEL4 = DATA / "pixel4_gsdc2021_excerpt.txt"
DERIVED = DATA / "pixel4_gsdc2021_derived_head.csv"
GOOGLE16 = DATA / "google_demo_2016_06_30_21_26_07_head.txt"
NAV16 = DATA / "hour1820_2000.16n"
C = 299792458
GPS_EPOCH = dt.datetime(1980, 1, 6)


def _need(*paths):
    for p in paths:
        if not p.exists():
            pytest.skip(f"real test data missing: {p.name}")


def _import(log, out, capsys):
    from ins.cli.main import main
    assert main(["import-android", str(log), "-o", str(out)]) == 0
    return capsys.readouterr().out


def _records(path, kind):
    """The log's records of one kind as dicts, by its header (read here, not by ins)."""
    head, rows = None, []
    for line in path.read_text().splitlines():
        if line.startswith(f"# {kind},"):
            head = [c.strip() for c in line[2:].split(",")[1:]]
        elif line.startswith(f"{kind},") and head:
            rows.append(dict(zip(head, line.split(",")[1:])))
    return rows


def test_pixel4_pseudoranges_are_googles(tmp_path, capsys):
    """All 28 signals of the epoch against the challenge's rawPrM (Google's computation
    of the same raw log, printed to the mm; its millisSinceGpsEpoch is the raw epoch's
    + 1 s, a known trait of the 2021 derived files: the receivedSvTimeInGpsNanos
    agree)."""
    from ubx_frames import read_rinex3_obs
    _need(PIXEL4, DERIVED)
    text = _import(PIXEL4, tmp_path / "out", capsys)
    # the NLP fix's altitude '-29co.199999': that record alone is left out
    assert "1 malformed record(s) left out, the first: line 85: Fix AltitudeMeters" in text
    (ymdhms, rows), = read_rinex3_obs(tmp_path / "out" / "gnss.obs")
    raw = _records(PIXEL4, "Raw")[0]
    gps_ns = int(raw["TimeNanos"]) - int(raw["FullBiasNanos"])
    t = GPS_EPOCH + dt.timedelta(microseconds=gps_ns // 1000)
    assert ymdhms[:5] == (t.year, t.month, t.day, t.hour, t.minute)
    codes = {"GPS_L1": ("G", "C1C"), "GPS_L5": ("G", "C5Q"), "GLO_G1": ("R", "C1C"),
             "GAL_E1": ("E", "C1C"), "GAL_E5A": ("E", "C5Q")}
    worst, n = 0.0, 0
    for d in csv.DictReader(DERIVED.open()):
        sysl, obs = codes[d["signalType"]]
        ours = rows[f"{sysl}{int(d['svid']):02d}"][obs]
        worst = max(worst, abs(ours - float(d["rawPrM"])))
        n += 1
        rx_ms = round(float(d["receivedSvTimeInGpsNanos"]) * 1e-6)
        assert int(d["millisSinceGpsEpoch"]) - 1000 - rx_ms in range(60, 100)  # 60-100 ms
    assert n == 28 and worst <= 0.0015, worst           # both printed to the mm


def test_pixel4_glonass_channels(tmp_path, capsys):
    """The GLONASS SLOT / FRQ # record from the carrier frequencies: the channels of the
    constellation's published plan (slots 11, 12, 13, 21, 22, 23, 24: 0, -1, -2, 4, -3,
    3, 2), which RTKLIB reads with the file."""
    _need(PIXEL4)
    _import(PIXEL4, tmp_path / "out", capsys)
    head = (tmp_path / "out" / "gnss.obs").read_text().split("END OF HEADER")[0]
    rec = next(line for line in head.splitlines() if line.endswith("GLONASS SLOT / FRQ #"))
    assert rec[:60].split() == ["7", "R11", "0", "R12", "-1", "R13", "-2", "R21", "4",
                                "R22", "-3", "R23", "3", "R24", "2"]
    rtk = pytest.importorskip("pyrtklib5", reason="RTKLIB reads the RINEX too")
    from ins.gnss.rtklib_engine import count_epochs
    assert count_epochs(tmp_path / "out" / "gnss.obs", rtk) == 1


def test_pixel4_sensors_on_the_system_clock(tmp_path, capsys):
    """No ChipsetElapsedRealtimeNanos in the Raw records, no elapsedRealtimeNanos in
    the fixes (app v2.0.4.2): the IMU goes on GPS time through the sensors' own
    utcTimeMillis (+ 18 leap seconds), and the summary says so."""
    from ins.io.imu_files import read_csv
    _need(PIXEL4)
    text = _import(PIXEL4, tmp_path / "out", capsys)
    assert "through the sensors' utcTimeMillis: the phone's system clock" in text
    gyro = _records(PIXEL4, "Gyro")
    acc = _records(PIXEL4, "Accel")
    imu = read_csv(tmp_path / "out" / "imu.csv")
    assert len(imu.time) > 15
    week = 2105                                           # 2020-05-14
    # the gyro records in boot-clock order; utc + leap onto GPS s of week, ms stamps
    g = sorted(gyro, key=lambda r: int(r["elapsedRealtimeNanos"]))
    gps_s = [(int(r["utcTimeMillis"]) - 315964800000 + 18000) * 1e-3 - week * 604800
             for r in g]
    # every sample's time within the ms stamps' quantization (+ line residual) of its own
    times = np.array(gps_s)
    k = [int(np.argmin(abs(times - t))) for t in imu.time]
    assert np.max(abs(imu.time - times[k])) < 2.5e-3
    # rates in FRD = phone (y, x, -z): the second sample's increment over its interval
    w = imu.dtheta_b[1] / (imu.time[1] - imu.time[0])
    j = int(np.argmin(abs(times - imu.time[1])))
    x, y, z = (float(g[j][f"Gyro{a}RadPerSec"]) for a in "XYZ")
    assert np.allclose(w, [y, x, -z], atol=1e-6)
    assert len(acc) > 15


def test_google_2016_fixes_and_leap_seconds(tmp_path, capsys):
    """GnssLogger 1.4 names its Fix columns Latitude, Longitude, Altitude, Accuracy,
    (UTC)TimeInMs and leaves LeapSecond empty: 2016-06-30 is GPS - UTC = 17 s."""
    from ins.io.rtklib import read_pos
    _need(GOOGLE16)
    text = _import(GOOGLE16, tmp_path / "out", capsys)
    assert "leap seconds 17" in text and "gnss.obs: 20 epochs" in text
    fixes = read_pos(tmp_path / "out" / "fix.pos")
    rec = _records(GOOGLE16, "Fix")
    assert len(fixes) == len(rec) == 21
    utc = dt.datetime(1970, 1, 1) + dt.timedelta(milliseconds=int(rec[0]["(UTC)TimeInMs"]))
    assert utc == dt.datetime(2016, 6, 30, 21, 26, 9)
    tow = (utc + dt.timedelta(seconds=17) - GPS_EPOCH).total_seconds() - 1903 * 604800
    assert abs(fixes.time[0] - tow) < 1e-6
    assert np.allclose(np.degrees(fixes.lla[0, :2]), [37.422541, -122.081659], atol=1e-9)
    assert abs(fixes.lla[0, 2] + 33.0) < 1e-6
    assert np.allclose(fixes.sigma_ned_m[0, :2], 3.0 / 1.515, atol=1e-6)


def test_google_2016_pseudoranges_by_the_white_paper(tmp_path, capsys):
    """Every measurement of the 20 epochs, across the clock discontinuities (a new
    FullBiasNanos each epoch, BiasNanos 4.2 us, TimeNanos off the second), against
    Google's formula in exact rational nanoseconds: t_rx = TimeNanos + TimeOffsetNanos
    - (FullBiasNanos + BiasNanos), pseudorange = (t_rx mod week - ReceivedSvTimeNanos)
    c; the RINEX epoch = t_rx without the offset."""
    from ubx_frames import read_rinex3_obs
    _need(GOOGLE16)
    text = _import(GOOGLE16, tmp_path / "out", capsys)
    assert "3 measurements left out" in text        # G03's 667-692 ns uncertainty
    conv = read_rinex3_obs(tmp_path / "out" / "gnss.obs")
    by_epoch = {}
    for r in _records(GOOGLE16, "Raw"):
        by_epoch.setdefault(r["TimeNanos"], []).append(r)
    assert len(conv) == len(by_epoch) == 20
    week_ns = 604800 * 10 ** 9
    worst, n = Fraction(0), 0
    for (ymdhms, rows), recs in zip(conv, by_epoch.values()):
        r0 = recs[0]
        t_rx = (int(r0["TimeNanos"]) - int(r0["FullBiasNanos"])
                - Fraction(r0["BiasNanos"]))
        t = GPS_EPOCH + dt.timedelta(microseconds=float(t_rx / 1000))
        sod = ymdhms[3] * 3600 + ymdhms[4] * 60 + ymdhms[5]
        assert abs(sod - (t.hour * 3600 + t.minute * 60 + t.second + t.microsecond * 1e-6)) \
            < 2e-6
        for r in recs:
            if float(r["ReceivedSvTimeUncertaintyNanos"]) > 500:
                assert f"G{int(r['Svid']):02d}" not in rows
                continue
            t_sv = t_rx + Fraction(r["TimeOffsetNanos"])
            pr = (t_sv % week_ns - int(r["ReceivedSvTimeNanos"])) * C / 10 ** 9
            worst = max(worst, abs(Fraction(rows[f"G{int(r['Svid']):02d}"]["C1C"]) - pr))
            n += 1
    assert n == 141 and worst < Fraction(6, 10000), float(worst)    # F14.3: 0.5 mm


def test_google_2016_single_point_against_the_phone(tmp_path, capsys):
    """RTKLIB's single-point solution of the RINEX (broadcast GPS ephemerides of the day,
    copied with the log) against the phone's fixes at the same instants (interpolated,
    the phone static).  Measured: all 20 epochs, horizontal RMS 10.3 m, mean N +4.0,
    E -1.7 m, U scatter 27 m: the code noise of this 2016 phone (4-8 m epoch to epoch
    against its Doppler), 6 satellites above RTKLIB's 15 deg mask.  A pseudorange or
    time-tag error of the import (a ms is 300 km; a leap second moves the fixes, not
    the RINEX) would be hundreds of m off."""
    pytest.importorskip("pyrtklib5", reason="RTKLIB's binding (extra 'gnss') solves it")
    from ins.cli.main import main
    from ins.io.rtklib import read_pos
    _need(GOOGLE16, NAV16)
    out = tmp_path / "out"
    _import(GOOGLE16, out, capsys)
    assert main(["gnss", str(out / "gnss.obs"), "--nav", str(NAV16), "--mode", "single",
                 "-o", str(tmp_path / "spp.pos")]) == 0
    spp, fix = read_pos(tmp_path / "spp.pos"), read_pos(out / "fix.pos")
    assert len(spp) == 20
    lat = np.interp(spp.time, fix.time, fix.lla[:, 0])
    lon = np.interp(spp.time, fix.time, fix.lla[:, 1])
    dn = (spp.lla[:, 0] - lat) * 6378137.0
    de = (spp.lla[:, 1] - lon) * 6378137.0 * np.cos(lat)
    rms = float(np.sqrt(np.mean(dn ** 2 + de ** 2)))
    print(f"single point - phone fix: horizontal RMS {rms:.2f} m, mean N {dn.mean():.2f} "
          f"E {de.mean():.2f} m")
    assert rms < 15.0 and abs(dn.mean()) < 8.0 and abs(de.mean()) < 5.0


def test_google_2016_single_point_has_the_doppler_velocity(tmp_path, capsys):
    """RTKLIB's single-point solution carries its Doppler velocity (``vn ve vu`` in the
    .pos, :mod:`ins.gnss.rtklib_options`): of the static 2016 phone, measured median
    horizontal speed 0.09 m/s (19 of 20 epochs below 0.3 m/s, one 1.0 m/s), where its
    positions differenced over 1 s (what the start would use without it) scatter by a
    median 5 m/s, 0.6-10.8 m/s: the rest the phone is at could not be seen (the
    alignment's rest threshold is 0.2 m/s).  Fails without the velocity columns."""
    pytest.importorskip("pyrtklib5", reason="RTKLIB's binding (extra 'gnss') solves it")
    from ins.cli.main import main
    from ins.estimation.alignment.motion import REST_SPEED_MPS, gnss_velocities
    from ins.io.gnss_log import GnssLog
    from ins.io.rtklib import read_pos
    _need(GOOGLE16, NAV16)
    out = tmp_path / "out"
    _import(GOOGLE16, out, capsys)
    assert main(["gnss", str(out / "gnss.obs"), "--nav", str(NAV16), "--mode", "single",
                 "-o", str(tmp_path / "spp.pos")]) == 0
    spp = read_pos(tmp_path / "spp.pos")
    assert spp.has_velocity
    speed = np.hypot(spp.v_n[:, 0], spp.v_n[:, 1])
    assert np.median(speed) < REST_SPEED_MPS and np.count_nonzero(speed < 0.3) >= 18
    assert np.all(np.isfinite(spp.v_n)) and np.all(np.asarray(spp.sigma_vel_ned_mps) > 0)
    diff = gnss_velocities(GnssLog(time=spp.time, lla=spp.lla, sigma_ned_m=spp.sigma_ned_m))
    assert np.median(np.hypot(diff[:, 0], diff[:, 1])) > 2.0
