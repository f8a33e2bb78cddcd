"""Android GnssLogger logs (ins.io.gnsslogger, ``ins import-android``): a log the test
writes from a simulation whose truth is known (pseudoranges, phases, Dopplers of GPS,
Galileo, BeiDou and GLONASS satellites; the phone's hardware clock with a bias and a
drift; sensors on the boot clock; fixes) comes out as RINEX 3 with the pseudoranges to
the millimetre, the IMU on GPS time to the microsecond in FRD, the fixes as a .pos."""
import numpy as np
import pytest

from ins.common.errors import InputError

C = 299792458.0
WEEK, TOW0 = 2300, 302400.0
GPS_EPOCH_UNIX_MS = 315964800000
LEAP = 18
RAW_COLS = ("utcTimeMillis,TimeNanos,LeapSecond,TimeUncertaintyNanos,FullBiasNanos,"
            "BiasNanos,BiasUncertaintyNanos,DriftNanosPerSecond,DriftUncertaintyNanosPerSecond,"
            "HardwareClockDiscontinuityCount,Svid,TimeOffsetNanos,State,ReceivedSvTimeNanos,"
            "ReceivedSvTimeUncertaintyNanos,Cn0DbHz,PseudorangeRateMetersPerSecond,"
            "PseudorangeRateUncertaintyMetersPerSecond,AccumulatedDeltaRangeState,"
            "AccumulatedDeltaRangeMeters,AccumulatedDeltaRangeUncertaintyMeters,"
            "CarrierFrequencyHz,CarrierCycles,CarrierPhase,CarrierPhaseUncertainty,"
            "MultipathIndicator,SnrInDb,ConstellationType,AgcDb,BasebandCn0DbHz,"
            "FullInterSignalBiasNanos,FullInterSignalBiasUncertaintyNanos,"
            "SatelliteInterSignalBiasNanos,SatelliteInterSignalBiasUncertaintyNanos,CodeType,"
            "ChipsetElapsedRealtimeNanos").split(",")
#: (constellation type, svid, carrier Hz, RINEX system, code, State bits)
SIGNALS = [(1, 5, 1575.42e6, "G", "1C", 1 | 8), (1, 5, 1176.45e6, "G", "5Q", 1 | 8),
           (1, 13, 1575.42e6, "G", "1C", 1 | 8 | 16384), (6, 11, 1575.42e6, "E", "1C", 1 | 8),
           (5, 30, 1561.098e6, "C", "2I", 1 | 8), (3, 9, 1602e6 + 2 * 0.5625e6, "R", "1C",
                                                   1 | 128),
           (1, 22, 1575.42e6, "G", "1C", 1)]          # the last: TOW unknown, left out
BOOT_OFFSET_NS, BOOT_RATE = 123_456_789_000, 1.0 + 3e-6   # elapsed = off + rate * gps


def _simulate(n=6):
    """Per epoch: (gps_ns int, {signal index: (pr m, phase cycles, doppler Hz, cn0)})."""
    rng = np.random.default_rng(4)
    r0 = rng.uniform(2.0e7, 2.6e7, len(SIGNALS))
    rd = rng.uniform(-600, 600, len(SIGNALS))
    out = []
    for k in range(n):
        gps_ns = (WEEK * 604800 + int(TOW0) + k) * 10 ** 9 + 250_000_000
        sig = {}
        for i, (_, _, f, *_rest) in enumerate(SIGNALS):
            lam = C / f
            r = r0[i] + rd[i] * k
            sig[i] = (r, r / lam + 1000.0 * i, -rd[i] / lam, 30.0 + i)
        out.append((gps_ns, sig))
    return out


def _write_log(path, truth, with_elapsed=True, discontinuity_at=None):
    lines = ["# Version: v3.0.6.0 Platform: 13 Manufacturer: test Model: sim",
             "# Raw," + ",".join(RAW_COLS),
             "# Fix,Provider,LatitudeDegrees,LongitudeDegrees,AltitudeMeters,SpeedMps,"
             "AccuracyMeters,BearingDegrees,UnixTimeMillis,SpeedAccuracyMps,"
             "BearingAccuracyDegrees,elapsedRealtimeNanos,VerticalAccuracyMeters,"
             "MockLocation,NumberOfUsedSignals,VerticalSpeedAccuracyMps,SolutionType",
             "# UncalAccel,utcTimeMillis,elapsedRealtimeNanos,UncalAccelXMps2,UncalAccelYMps2,"
             "UncalAccelZMps2,BiasXMps2,BiasYMps2,BiasZMps2",
             "# UncalGyro,utcTimeMillis,elapsedRealtimeNanos,UncalGyroXRadPerSec,"
             "UncalGyroYRadPerSec,UncalGyroZRadPerSec,DriftXRadPerSec,DriftYRadPerSec,"
             "DriftZRadPerSec", "#", "# Status,UnixTimeMillis,SignalCount", ""]
    hw0 = 5_000_000_000_000                 # the GNSS chip's clock at the first epoch, ns
    for k, (gps_ns, sig) in enumerate(truth):
        bias = 0.25 + 0.7 * k               # ns: the clock's sub-ns bias, drifting
        time_nanos = hw0 + k * 10 ** 9
        full_bias = time_nanos - gps_ns - 1  # FullBias + Bias = TimeNanos - GPS + bias
        # -> TimeNanos - (FullBias + Bias) = gps_ns + 1 - bias
        t_rx_true = gps_ns + 1 - bias       # the phone's GPS time estimate of the epoch, ns
        elapsed = BOOT_OFFSET_NS + int(round(BOOT_RATE * (t_rx_true - truth[0][0])))
        for i, (ctype, svid, f, sysl, code, state) in enumerate(SIGNALS):
            pr, cp, dop, cn0 = sig[i]
            if sysl == "R":
                period, shift = 86400 * 10 ** 9, 3 * 3600 * 10 ** 9 - LEAP * 10 ** 9
            else:
                period, shift = 604800 * 10 ** 9, (-14 * 10 ** 9 if sysl == "C" else 0)
            t_sys = (gps_ns + 1 + shift) % period            # integer part of t_rx
            # transmit time tx = t_sys - d (ns), d = pr / c + bias; ReceivedSvTimeNanos
            # the integer ns below it, as phones log; TimeOffsetNanos the rest:
            # t_rx + TimeOffsetNanos - rx_sv = pr / c  with  t_rx = t_sys - bias
            d = pr / C * 1e9 + bias
            rx_sv = t_sys - int(np.ceil(d))
            offset = float(d - np.ceil(d))
            lam = C / f
            row = dict.fromkeys(RAW_COLS, "")
            row.update(utcTimeMillis=str((gps_ns // 10 ** 6) + GPS_EPOCH_UNIX_MS - LEAP * 1000),
                       TimeNanos=str(time_nanos), LeapSecond=str(LEAP),
                       FullBiasNanos=str(full_bias), BiasNanos=repr(float(bias)),
                       HardwareClockDiscontinuityCount=str(
                           int(discontinuity_at is not None and k >= discontinuity_at)),
                       Svid=str(svid),
                       TimeOffsetNanos=repr(offset), State=str(state),
                       ReceivedSvTimeNanos=str(rx_sv), Cn0DbHz=repr(float(cn0)),
                       PseudorangeRateMetersPerSecond=repr(float(-dop * lam)),
                       AccumulatedDeltaRangeState="1" if k != 3 or i != 0 else "5",
                       AccumulatedDeltaRangeMeters=repr(float(cp * lam)),
                       CarrierFrequencyHz=repr(float(f)),
                       ConstellationType=str(ctype), CodeType=code[1],
                       ChipsetElapsedRealtimeNanos=str(elapsed) if with_elapsed else "")
            lines.append("Raw," + ",".join(row[c] for c in RAW_COLS))
        unix_ms = gps_ns // 10 ** 6 + GPS_EPOCH_UNIX_MS - LEAP * 1000
        lines.append(f"Fix,GPS,35.{k:02d}1,139.5,70.{k},0.1,3.03,0,{unix_ms},0.1,1,"
                     f"{elapsed},4.0,0,20,0.5,")
    # sensors: 50 Hz over the span, constant rates in the phone's axes
    t0 = truth[0][0]
    for j in range(0, 250):
        g = t0 + j * 20_000_000
        e = BOOT_OFFSET_NS + int(round(BOOT_RATE * (g + 1 - 0.25 - t0)))   # same line
        lines.append(f"UncalGyro,0,{e},0.01,0.02,0.03,0,0,0")
        lines.append(f"UncalAccel,0,{e + 3_000_000},0.1,0.2,9.8,0,0,0")
    path.write_text("\n".join(lines) + "\n")


def test_import_android_reconstructs_the_simulation(tmp_path, capsys):
    from ubx_frames import read_rinex3_obs

    from ins.cli.main import main
    from ins.io.imu_files import read_csv
    from ins.io.rtklib import read_pos
    truth = _simulate()
    log = tmp_path / "gnss_log.txt"
    _write_log(log, truth)
    src = log.read_bytes()
    out = tmp_path / "out"
    assert main(["import-android", str(log), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "gnss.obs: 6 epochs" in text and "6 measurements left out" in text
    assert log.read_bytes() == src
    conv = read_rinex3_obs(out / "gnss.obs")
    assert len(conv) == len(truth)
    worst = {"C": 0.0, "L": 0.0, "D": 0.0}
    for k, ((gps_ns, sig), (ymdhms, rows)) in enumerate(zip(truth, conv)):
        sow = ymdhms[3] * 3600 + ymdhms[4] * 60 + ymdhms[5]        # s of the day
        bias = 0.25 + 0.7 * k
        want = ((gps_ns % (86400 * 10 ** 9)) + 1 - bias) * 1e-9
        assert abs(sow - want) < 1e-7                     # the RINEX epoch, 0.1 us
        for i, (_, svid, f, sysl, code, state) in enumerate(SIGNALS):
            sat = f"{sysl}{svid:02d}"
            if not state & 8 and not state & 128:
                assert sat not in rows
                continue
            pr, cp, dop, cn0 = sig[i]
            worst["C"] = max(worst["C"], abs(rows[sat]["C" + code] - pr))
            worst["L"] = max(worst["L"], abs(rows[sat]["L" + code] - cp))
            worst["D"] = max(worst["D"], abs(rows[sat]["D" + code] - dop))
            assert abs(rows[sat]["S" + code] - cn0) < 1e-3
    assert worst["C"] < 6e-4 and worst["L"] < 6e-4 and worst["D"] < 6e-4, worst
    print("worst |RINEX - truth|:", worst)
    body = (out / "gnss.obs").read_text()
    assert "G    8 C1C L1C D1C S1C C5Q L5Q D5Q S5Q" in body and "R    4 C1C" in body
    # the slip (ADR state 5 = valid + cycle slip) at epoch 3 of G05 L1: LLI 1 after L1C
    ep3 = body.split("> ")[4].splitlines()
    g05 = next(line for line in ep3 if line.startswith("G05"))
    assert g05[3 + 16 + 14] == "1"
    rtk = pytest.importorskip("pyrtklib5", reason="RTKLIB reads the RINEX too")
    from ins.gnss.rtklib_engine import count_epochs
    assert count_epochs(out / "gnss.obs", rtk) == 6
    imu = read_csv(out / "imu.csv")
    dt = np.diff(imu.time)
    assert np.allclose(dt, 0.02, atol=1e-6)
    # the first gyro sample precedes the accelerometer's (3 ms later): left out
    assert abs(imu.time[0] - (TOW0 + 0.27 + 1e-9 - 0.25e-9)) < 2e-6    # GPS time, 1 us
    w = imu.dtheta_b[1:] / dt[:, None]
    f = imu.dvel_b[1:] / dt[:, None]
    assert np.allclose(w, [0.02, 0.01, -0.03], atol=1e-9)        # FRD = (y, x, -z)
    assert np.allclose(f, [0.2, 0.1, -9.8], atol=1e-9)
    fixes = read_pos(out / "fix.pos")
    assert len(fixes) == 6
    assert np.allclose(fixes.time - TOW0, np.arange(6) + 0.25, atol=1e-3)
    assert np.allclose(np.degrees(fixes.lla[:, 0]), [35.001, 35.011, 35.021, 35.031,
                                                      35.041, 35.051])
    assert np.allclose(fixes.sigma_ned_m[:, 0], 3.03 / 1.515, atol=1e-3)


def test_sensor_time_falls_back_to_the_fixes(tmp_path):
    from ins.io.gnsslogger import raw_observations, read_gnsslogger, sensor_to_gps
    log = tmp_path / "log.txt"
    _write_log(log, _simulate(), with_elapsed=False)
    g = read_gnsslogger(log)
    raw = raw_observations(g)
    assert raw.elapsed_ns is None
    to_gps, (src, rms) = sensor_to_gps(raw, g)
    assert src.startswith("Fix") and rms < 1e-3
    e = BOOT_OFFSET_NS + int(round(BOOT_RATE * 2.0e9))
    assert abs(to_gps(np.array([e]))[0] - (TOW0 + 0.25 + 2.0)) < 2e-3   # ms UTC stamps


def test_gnsslogger_errors(tmp_path):
    from ins.io.gnsslogger import raw_observations, read_gnsslogger
    bad = tmp_path / "a.txt"
    bad.write_text("Raw,1,2,3\n")
    with pytest.raises(InputError, match=r"a\.txt.*line 1: a Raw record before its"):
        read_gnsslogger(bad)
    bad.write_text("# Raw,utcTimeMillis,TimeNanos\nRaw,1,2,3\n")
    with pytest.raises(InputError, match=r"line 2: Raw record with 3 fields, its header "
                                         r"names 2"):
        read_gnsslogger(bad)
    bad.write_text("# Raw,utcTimeMillis,BiasNanos\nRaw,1,x\n")
    with pytest.raises(InputError, match=r"line 2: Raw BiasNanos: expected a number"):
        read_gnsslogger(bad)
    bad.write_text("hello\n")
    with pytest.raises(InputError, match=r"no Raw, Fix.*GnssLogger"):
        read_gnsslogger(bad)
    bad.write_text("# Raw,utcTimeMillis,TimeNanos\nRaw,1,2\n")
    with pytest.raises(InputError, match=r"Raw records have no FullBiasNanos"):
        raw_observations(read_gnsslogger(bad))


def test_clock_discontinuity_breaks_the_phases(tmp_path):
    """HardwareClockDiscontinuityCount 0 -> 1 at epoch 4: every phase of epoch 4 has
    its loss-of-lock flag (the ADR state says nothing), none of the others but the
    logged slip (G05 L1, epoch 3)."""
    from ins.io.gnsslogger import raw_observations, read_gnsslogger
    log = tmp_path / "log.txt"
    _write_log(log, _simulate(), discontinuity_at=4)
    raw = raw_observations(read_gnsslogger(log))
    for k, ep in enumerate(raw.epochs):
        for key, (_, phase, _, _, lli) in ep.items():
            assert np.isfinite(phase)
            want = k == 4 or (k == 3 and key == ("G", 5, "1C"))
            assert lli == int(want), (k, key)


def test_cut_and_corrupt_records_are_left_out(tmp_path):
    """A last line cut short (the app stopped while writing) and a field that is no
    number lose those records only, listed with their lines; a weak signal's
    ReceivedSvTimeUncertaintyNanos above 500 ns drops that measurement."""
    from ins.io.gnsslogger import raw_observations, read_gnsslogger
    log = tmp_path / "log.txt"
    _write_log(log, _simulate())
    lines = log.read_text().splitlines()
    first_raw = next(i for i, line in enumerate(lines) if line.startswith("Raw,"))
    f = lines[first_raw].split(",")
    f[1 + RAW_COLS.index("ReceivedSvTimeUncertaintyNanos")] = "667"
    lines[first_raw] = ",".join(f)
    fix = next(i for i, line in enumerate(lines) if line.startswith("Fix,"))
    lines[fix] = lines[fix].replace(",139.5,", ",139.5x,")
    lines.append(lines[first_raw + 1][:40])
    log.write_text("\n".join(lines) + "\n")
    g = read_gnsslogger(log)
    assert [no for no, _ in g.skipped] == [fix + 1, len(lines)]
    assert "Fix LongitudeDegrees: expected a number, got '139.5x'" in g.skipped[0][1]
    assert "fields, its header names" in g.skipped[1][1]
    assert len(g.lines["Fix"]) == 5
    raw = raw_observations(g)
    assert ("G", 5, "1C") not in raw.epochs[0] and ("G", 5, "5Q") in raw.epochs[0]
