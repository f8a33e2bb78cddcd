"""The simulated twin of an Android GnssLogger log: a phone carried along a ground
journey (:mod:`ins.simulate.ground`) logs its raw GPS, its inertial sensors and its own
fixes as Google's GnssLogger app writes them (``gnss_log.txt``), with the truth of every
clock and measurement beside it.

What the phone does, and how the log's fields are made (Google's "Raw GNSS
measurements" white paper, 2017; ``android.location.GnssMeasurement`` / ``GnssClock``):

- **GNSS chip clock.**  ``TimeNanos`` is the chip's hardware clock, ticking an epoch
  every ``1 / rate_hz`` s from an arbitrary start; the phone set ``FullBiasNanos``
  (integer) and ``BiasNanos`` (its sub-nanosecond part) at its first fix and keeps them,
  so its estimate of GPS time, ``t_rx = TimeNanos - (FullBiasNanos + BiasNanos)``, is
  the simulator's receiver clock (:mod:`ins.simulate.gnss_raw`: ``t_rx = t_gps +
  clock_bias``, a bias of about a microsecond drifting ``DriftNanosPerSecond``).
- **Raw measurements** (GPS L1 C/A, the satellites of the navigation file), the white
  paper's formula inverted: ``ReceivedSvTimeNanos`` (integer ns of the GPS week) and
  ``TimeOffsetNanos`` (its sub-ns rest, < 0.5 ns: a measurement time 0.5 ns from the
  epoch moves no satellite by a micrometre) such that ``(t_rx + TimeOffsetNanos -
  ReceivedSvTimeNanos) c`` is the simulated pseudorange; ``PseudorangeRateMetersPerSecond
  = -Doppler lambda`` (uncorrected: the chip clock's drift in it, as Android asks);
  ``AccumulatedDeltaRangeMeters = phase lambda`` with state VALID, CYCLE_SLIP at the
  simulator's loss-of-lock epochs; ``State`` 16431 (code lock, bit and subframe sync,
  TOW decoded and known); ``ReceivedSvTimeUncertaintyNanos`` the code's sigma;
  ``ChipsetElapsedRealtimeNanos`` the boot clock at the epoch's true GPS time, with
  ``elapsed_jitter_ns`` of noise.
- **Boot clock** (``elapsedRealtimeNanos``): ``elapsed = boot_offset + (t_gps - t0)
  (1 + boot_rate_ppm 1e-6)`` ns: an offset from GPS time that drifts ``boot_rate_ppm``.
  The system clock (``utcTimeMillis``) is UTC off by ``system_clock_error_s`` (NTP).
- **Inertial sensors** (``UncalGyro`` rad/s, ``UncalAccel`` m/s^2, the phone's axes x
  right, y top, z out of the screen: the journey's body FRD is (y, x, -z) of the phone):
  each sensor samples on its own crystal (``*_rate_hz`` times ``1 + *_clock_ppm 1e-6``),
  a sample being the mean rate over the interval since the previous one (the
  simulator's increments of :func:`ins.simulate.imu_synth.synthesize_imu` with the
  errors of :class:`ins.simulate.sensor_errors.ImuErrorModel`, divided by the
  interval), stamped with the boot clock at its end plus ``stamp_jitter_s`` of white
  jitter.
- **Fixes** (``Fix``, provider ``GPS``, 1 Hz on UTC whole seconds): the truth plus a
  first-order Gauss-Markov error per axis (``fix_sigma_h_m`` north and east,
  ``fix_sigma_v_m`` up, correlation time ``fix_time_s``): a phone's fused location,
  metres off and slowly wandering; ``AccuracyMeters`` the 68 % radius of that error.

Files of :func:`write_android_journey` (``folder``): ``gnss_log.txt``, ``rover.nav``
(the navigation file's records of the span, for ``ins process --nav``), ``truth.nav``
(the journey at 10 Hz), ``android_truth.csv`` (one row per Raw measurement: ``time_gps_s,
svid,pseudorange_m,range_m,clock_bias_m,sat_clock_m,iono_m,tropo_m,multipath_m,
elevation_deg``, with ``pseudorange_m`` what the fields encode and ``pseudorange = range +
clock_bias - sat_clock + iono + tropo + multipath + noise``) and ``android_truth.toml``
(the clocks: GPS week, leap seconds, the boot clock's offset and rate, the chip clock's
fields, the sensors' rates, the fix error).
"""
from dataclasses import asdict, dataclass, replace

import numpy as np

from ins.common.errors import InputError
from ins.common.fileio import atomic_open

__all__ = ["PhoneSettings", "PHONE_RAW", "RAW_COLUMNS", "FIX_COLUMNS", "ACCEL_COLUMNS",
           "GYRO_COLUMNS", "write_android_journey", "elapsed_ns", "STATE_GPS_TRACKED",
           "ANDROID_WALK", "ANDROID_CAR"]

C_LIGHT = 299792458.0
WEEK_NS = 604800 * 10 ** 9
GPS_EPOCH_UNIX_MS = 315964800000
L1_HZ = 1575.42e6
#: State of a GPS satellite tracked with its time of week: CODE_LOCK | BIT_SYNC |
#: SUBFRAME_SYNC | TOW_DECODED | SYMBOL_SYNC | TOW_KNOWN.
STATE_GPS_TRACKED = 1 | 2 | 4 | 8 | 32 | 16384
_ADR_VALID, _ADR_SLIP = 1, 4

RAW_COLUMNS = (
    "utcTimeMillis,TimeNanos,LeapSecond,TimeUncertaintyNanos,FullBiasNanos,BiasNanos,"
    "BiasUncertaintyNanos,DriftNanosPerSecond,DriftUncertaintyNanosPerSecond,"
    "HardwareClockDiscontinuityCount,Svid,TimeOffsetNanos,State,ReceivedSvTimeNanos,"
    "ReceivedSvTimeUncertaintyNanos,Cn0DbHz,PseudorangeRateMetersPerSecond,"
    "PseudorangeRateUncertaintyMetersPerSecond,AccumulatedDeltaRangeState,"
    "AccumulatedDeltaRangeMeters,AccumulatedDeltaRangeUncertaintyMeters,CarrierFrequencyHz,"
    "CarrierCycles,CarrierPhase,CarrierPhaseUncertainty,MultipathIndicator,SnrInDb,"
    "ConstellationType,AgcDb,BasebandCn0DbHz,FullInterSignalBiasNanos,"
    "FullInterSignalBiasUncertaintyNanos,SatelliteInterSignalBiasNanos,"
    "SatelliteInterSignalBiasUncertaintyNanos,CodeType,ChipsetElapsedRealtimeNanos"
).split(",")
FIX_COLUMNS = ("Provider,LatitudeDegrees,LongitudeDegrees,AltitudeMeters,SpeedMps,"
               "AccuracyMeters,BearingDegrees,UnixTimeMillis,SpeedAccuracyMps,"
               "BearingAccuracyDegrees,elapsedRealtimeNanos,VerticalAccuracyMeters").split(",")
ACCEL_COLUMNS = ("utcTimeMillis,elapsedRealtimeNanos,UncalAccelXMps2,UncalAccelYMps2,"
                 "UncalAccelZMps2,BiasXMps2,BiasYMps2,BiasZMps2").split(",")
GYRO_COLUMNS = ("utcTimeMillis,elapsedRealtimeNanos,UncalGyroXRadPerSec,"
                "UncalGyroYRadPerSec,UncalGyroZRadPerSec,DriftXRadPerSec,DriftYRadPerSec,"
                "DriftZRadPerSec").split(",")
#: 68 % radius of a circular 2-D normal distribution, in sigmas.
R68_PER_SIGMA = 1.515


@dataclass(frozen=True)
class PhoneSettings:
    """The phone of the twin (SI units; module notes).

    Attributes
    ----------
    grade : str
        IMU error preset of :data:`ins.simulate.sensor_errors.PRESETS`.
    noise_factor : float
        Factor on the preset's white noise (ARW, VRW): a phone's vibrating hand or mount
        scatters more than the datasheet's bench.
    gyro_rate_hz, accel_rate_hz : float
        Nominal sample rates, Hz.
    gyro_clock_ppm, accel_clock_ppm : float
        The sensors' own crystals' rate errors (1e-6).
    stamp_jitter_s : float
        White jitter of the sensor stamps, s (sigma).
    boot_offset_ns : int
        ``elapsedRealtimeNanos`` at the journey's start, ns.
    boot_rate_ppm : float
        The boot clock's rate error against GPS time (1e-6).
    elapsed_jitter_ns : float
        Noise of ``ChipsetElapsedRealtimeNanos``, ns (sigma).
    system_clock_error_s : float
        The system clock (``utcTimeMillis``) minus UTC, s.
    time_nanos0 : int
        The chip's ``TimeNanos`` at the first epoch, ns.
    bias_nanos : float
        ``BiasNanos`` (the sub-ns part of the phone's clock estimate), ns in [0, 1).
    hardware_discontinuity : int
        ``HardwareClockDiscontinuityCount`` (constant: no restart).
    fix_sigma_h_m, fix_sigma_v_m, fix_time_s : float
        The fixes' Gauss-Markov error: sigma north/east, up (m), correlation time (s).
    lever_b_m : tuple of 3 float
        The GNSS antenna from the IMU, body FRD, m.
    """

    grade: str = "consumer"
    noise_factor: float = 1.5
    gyro_rate_hz: float = 200.0
    accel_rate_hz: float = 200.0
    gyro_clock_ppm: float = 40.0
    accel_clock_ppm: float = -25.0
    stamp_jitter_s: float = 2e-4
    boot_offset_ns: int = 11_523_456_789_012
    boot_rate_ppm: float = 3.7
    elapsed_jitter_ns: float = 300.0
    system_clock_error_s: float = 0.037
    time_nanos0: int = 987_654_321_000
    bias_nanos: float = 0.625
    hardware_discontinuity: int = 2
    fix_sigma_h_m: float = 3.0
    fix_sigma_v_m: float = 5.0
    fix_time_s: float = 30.0
    lever_b_m: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        checks = (("bias_nanos", 0.0 <= self.bias_nanos < 1.0, "ns in [0, 1)"),
                  ("gyro_rate_hz", 0 < self.gyro_rate_hz <= 1000, "Hz in (0, 1000]"),
                  ("accel_rate_hz", 0 < self.accel_rate_hz <= 1000, "Hz in (0, 1000]"),
                  ("stamp_jitter_s", 0 <= self.stamp_jitter_s < 0.01, "s in [0, 0.01)"),
                  ("noise_factor", self.noise_factor > 0, "a factor > 0"),
                  ("fix_time_s", self.fix_time_s > 0, "s > 0"),
                  ("time_nanos0", self.time_nanos0 >= 0, "ns >= 0"),
                  ("boot_offset_ns", self.boot_offset_ns >= 0, "ns >= 0"))
        for name, ok, want in checks:
            if not ok:
                raise ValueError(f"PhoneSettings {name}: expected {want}, got "
                                 f"{getattr(self, name)!r}")


def _phone_raw():
    from ins.simulate.gnss_raw import RawSettings
    return RawSettings(rate_hz=1.0, elevation_mask_rad=np.deg2rad(10.0), sigma_code_m=2.0,
                       sigma_phase_m=0.003, sigma_doppler_hz=0.2, multipath_code_m=2.0,
                       multipath_phase_m=0.005, multipath_time_s=15.0, clock_bias_s=1.2e-6,
                       clock_drift=8e-8, clock_bias_noise=3e-10, clock_drift_noise=6e-10,
                       cn0_zenith_dbhz=45.0, cn0_horizon_dbhz=25.0)


#: The phone's raw GPS (:class:`ins.simulate.gnss_raw.RawSettings` without ``nav_file``):
#: 1 Hz, 10 deg mask, 2 m code noise and 2 m multipath (15 s) at zenith, 0.2 Hz Doppler,
#: C/N0 25-45 dB-Hz, a chip clock 1.2 us off drifting 80 ns/s.
PHONE_RAW = _phone_raw()


def _walk():
    from ins.simulate.ground import WALK
    return replace(WALK, lla0_deg=(35.1605, 139.6150, 72.0), t0=524400.0)


def _car():
    from ins.simulate.ground import CONSUMER_CAR
    return replace(CONSUMER_CAR, lla0_deg=(35.1605, 139.6150, 72.0), t0=524400.0)


#: The consumer car of :mod:`ins.simulate.ground` (parked 40 s, then 4 min of town
#: driving; the phone in a cradle 1, -2, 3 deg off the car's axes) at the same place and
#: time as :data:`ANDROID_WALK`.
ANDROID_CAR = _car()
#: The handheld walk of :mod:`ins.simulate.ground` moved beside the station of the
#: 2005 day 092 navigation file of ``../shared/real/rtklib_static_pair`` (Japan, GPS
#: week 1316, 524400 s: 7 satellites above 15 deg, GDOP 2.8).
ANDROID_WALK = _walk()
ANDROID_WEEK = 1316


def elapsed_ns(t_gps, t0, phone):
    """The boot clock (``elapsedRealtimeNanos``, int64 ns) at GPS times ``t_gps`` (s of
    the week), the journey starting at ``t0``."""
    dt = np.asarray(t_gps, float) - t0
    return phone.boot_offset_ns + np.round(dt * 1e9 * (1 + phone.boot_rate_ppm * 1e-6)
                                           ).astype(np.int64)


def _unix_ms(t_gps, week, leap_s, error_s=0.0):
    """Unix ms (UTC, plus a system clock error) of GPS times (s of ``week``)."""
    return (GPS_EPOCH_UNIX_MS + week * 604800000
            + np.round((np.asarray(t_gps, float) - leap_s + error_s) * 1e3)).astype(np.int64)


def _gauss_markov(n, dt, tau, sigma, rng):
    phi = np.exp(-dt / tau)
    x = np.empty(n)
    x[0] = rng.standard_normal() * sigma
    w = rng.standard_normal(n) * sigma * np.sqrt(1 - phi * phi)
    for k in range(1, n):
        x[k] = phi * x[k - 1] + w[k]
    return x


def _epochs(t_start, t_end, raw, phone, week):
    """The chip's epochs: ``TimeNanos`` (int), ``FullBiasNanos`` and the phone's GPS time
    estimate ``t_rx`` (s of week), evenly spaced inside the journey."""
    from ins.simulate.gnss_raw_product import EDGE_S
    step = int(round(1e9 / raw.rate_hz))
    first_ns = int(np.ceil((t_start + EDGE_S) * 1e9)) + 123_457     # off the whole ms
    n = int(((t_end - EDGE_S) * 1e9 - first_ns) // step) + 1
    tow_int = first_ns + step * np.arange(n, dtype=np.int64)        # integer ns of week
    full_bias = phone.time_nanos0 - (week * WEEK_NS + first_ns)
    time_nanos = tow_int + week * WEEK_NS + full_bias
    t_rx = tow_int * 1e-9 - phone.bias_nanos * 1e-9
    return time_nanos, full_bias, tow_int, t_rx


def _raw_lines(obs, time_nanos, full_bias, tow_int, phone, raw, week, leap_s, t0, rng):
    lam = C_LIGHT / L1_HZ
    b = phone.bias_nanos
    el_ns = elapsed_ns(obs.time_gps, t0, phone) + np.round(
        rng.standard_normal(len(obs.time_gps)) * phone.elapsed_jitter_ns).astype(np.int64)
    utc = _unix_ms(obs.time_gps, week, leap_s, phone.system_clock_error_s)
    sig = np.hypot(raw.sigma_code_m, raw.multipath_code_m)
    lines, truth = [], []
    idx = {c: i for i, c in enumerate(RAW_COLUMNS)}
    for k in range(len(obs.time_rx)):
        for j in np.flatnonzero(obs.observed[k]):
            code_ns = obs.code[k, j] / C_LIGHT * 1e9
            # t_rx = tow_int - b; (t_rx + off - sv) = code_ns with sv integer
            r = int(np.round(code_ns + b))
            sv = (int(tow_int[k]) - r) % WEEK_NS          # the week's rollover
            off = code_ns + b - r
            sin_el = np.sin(obs.elevation[k, j])
            st = _ADR_VALID | (_ADR_SLIP if obs.lli[k, j] else 0)
            row = [""] * len(RAW_COLUMNS)
            for name, v in (
                    ("utcTimeMillis", str(utc[k])), ("TimeNanos", str(time_nanos[k])),
                    ("LeapSecond", str(leap_s)), ("TimeUncertaintyNanos", "0.0"),
                    ("FullBiasNanos", str(full_bias)), ("BiasNanos", repr(b)),
                    ("BiasUncertaintyNanos", "10.0"),
                    ("DriftNanosPerSecond", f"{obs.clock_drift[k] * 1e9:.6f}"),
                    ("DriftUncertaintyNanosPerSecond", "1.0"),
                    ("HardwareClockDiscontinuityCount", str(phone.hardware_discontinuity)),
                    ("Svid", str(int(obs.prns[j]))), ("TimeOffsetNanos", f"{off:.9f}"),
                    ("State", str(STATE_GPS_TRACKED)), ("ReceivedSvTimeNanos", str(sv)),
                    ("ReceivedSvTimeUncertaintyNanos", f"{sig / sin_el / C_LIGHT * 1e9:.1f}"),
                    ("Cn0DbHz", f"{obs.snr[k, j]:.2f}"),
                    ("PseudorangeRateMetersPerSecond", f"{-obs.doppler[k, j] * lam:.6f}"),
                    ("PseudorangeRateUncertaintyMetersPerSecond",
                     f"{raw.sigma_doppler_hz * lam / sin_el:.4f}"),
                    ("AccumulatedDeltaRangeState", str(st)),
                    ("AccumulatedDeltaRangeMeters", f"{obs.phase[k, j] * lam:.6f}"),
                    ("AccumulatedDeltaRangeUncertaintyMeters", f"{raw.sigma_phase_m:.4f}"),
                    ("CarrierFrequencyHz", repr(L1_HZ)), ("MultipathIndicator", "0"),
                    ("ConstellationType", "1"), ("CodeType", "C"),
                    ("ChipsetElapsedRealtimeNanos", str(el_ns[k]))):
                row[idx[name]] = v
            lines.append("Raw," + ",".join(row))
            truth.append((obs.time_gps[k], obs.prns[j], obs.code[k, j], obs.rho[k, j],
                          C_LIGHT * obs.clock_bias_s[k], obs.sat_clock_m[k, j],
                          obs.iono_m[k, j], obs.tropo_m[k, j], obs.mp_code_m[k, j],
                          np.rad2deg(obs.elevation[k, j])))
    return lines, np.array(truth), el_ns


def _sensor_lines(truth, phone, model, seed, week, leap_s):
    """UncalGyro and UncalAccel lines (time-ordered together) and the truth of the
    stamps: per sensor ``(true end times s, stamps ns)``."""
    from ins.simulate.imu_synth import synthesize_imu
    from ins.simulate.sensor_errors import apply_errors
    out, stamps = [], {}
    for kind, rate, ppm, cols, shift in (
            ("UncalGyro", phone.gyro_rate_hz, phone.gyro_clock_ppm, GYRO_COLUMNS, 0.0),
            ("UncalAccel", phone.accel_rate_hz, phone.accel_clock_ppm, ACCEL_COLUMNS, 1.3e-3)):
        r = rate * (1 + ppm * 1e-6)
        imu = synthesize_imu(truth, r, t_start=truth.t_start + shift)
        imu = apply_errors(imu, model, seed=seed + (0 if kind == "UncalGyro" else 1))
        dt = np.diff(imu.time)
        inc = (imu.dtheta_b if kind == "UncalGyro" else imu.dvel_b)[1:] / dt[:, None]
        t_end = imu.time[1:]
        rng = np.random.default_rng(seed + 7 + len(kind))
        e = elapsed_ns(t_end, truth.t_start, phone) + np.round(
            rng.standard_normal(len(t_end)) * phone.stamp_jitter_s * 1e9).astype(np.int64)
        utc = _unix_ms(t_end, week, leap_s, phone.system_clock_error_s)
        phone_xyz = np.column_stack([inc[:, 1], inc[:, 0], -inc[:, 2]])
        for u, s, v in zip(utc, e, phone_xyz):
            out.append((int(s), f"{kind},{u},{s},{v[0]:.9g},{v[1]:.9g},{v[2]:.9g},0,0,0"))
        stamps[kind] = (t_end, e)
    out.sort(key=lambda x: x[0])
    return [s for _, s in out], stamps


def _fix_lines(truth, phone, week, leap_s, rng):
    from ins.nav import earth
    t_utc0 = np.ceil(truth.t_start - leap_s + 1.0)
    t = np.arange(t_utc0, truth.t_end - leap_s - 0.5, 1.0) + leap_s      # GPS s, UTC whole
    s = truth.evaluate(t)
    err = np.column_stack([_gauss_markov(len(t), 1.0, phone.fix_time_s, sg, rng)
                           for sg in (phone.fix_sigma_h_m, phone.fix_sigma_h_m,
                                      -phone.fix_sigma_v_m)])         # N, E, D
    lla = earth.offset_lla(s.lla, err)
    speed = np.hypot(s.v_n[:, 0], s.v_n[:, 1])
    bearing = np.rad2deg(np.arctan2(s.v_n[:, 1], s.v_n[:, 0])) % 360
    unix = _unix_ms(t, week, leap_s)
    el = elapsed_ns(t, truth.t_start, phone)
    acc = R68_PER_SIGMA * phone.fix_sigma_h_m
    lines = [f"Fix,GPS,{np.rad2deg(a):.9f},{np.rad2deg(o):.9f},{h:.3f},{v:.3f},{acc:.2f},"
             f"{br:.2f},{u},0.5,10.0,{e},{phone.fix_sigma_v_m:.2f}"
             for (a, o, h), v, br, u, e in zip(lla, speed, bearing, unix, el)]
    return lines, t, lla, el


def write_android_journey(folder, nav_file, journey=None, week=ANDROID_WEEK, seed=0,
                          phone=PhoneSettings(), raw=PHONE_RAW):
    """Write the GnssLogger twin of a phone carried along ``journey`` (module notes).

    Parameters
    ----------
    folder : str or os.PathLike
        Output folder (created; existing files of the same names are replaced, each
        written atomically).
    nav_file : str or os.PathLike
        RINEX GPS navigation file covering the journey (GPS week ``week``).
    journey : ins.simulate.ground.Journey, optional
        Default :data:`ANDROID_WALK`.
    week : int
        GPS week of the journey's times.
    seed : int
        Seed of every random draw.
    phone : PhoneSettings
    raw : ins.simulate.gnss_raw.RawSettings
        The raw GPS (its ``nav_file`` is replaced by ``nav_file``).

    Returns
    -------
    dict
        The truth of ``android_truth.toml`` (clocks and settings).
    """
    from pathlib import Path

    import tomli_w

    from ins.io.gnsslogger import leap_seconds_at_gps_ns
    from ins.io.navfiles import write_nav
    from ins.io.rinex_nav import span_text
    from ins.nav.earth import lla_to_ecef
    from ins.nav.trajectory import Trajectory
    from ins.simulate.ground import GroundTruth
    from ins.simulate.gnss_raw import simulate_raw
    from ins.simulate.gnss_raw_product import load_orbits
    from ins.simulate.sensor_errors import ImuErrorModel
    journey = ANDROID_WALK if journey is None else journey
    raw = replace(raw, nav_file=str(nav_file))
    orbits = load_orbits(raw)
    if not orbits.covers(week, journey.t0, journey.t0 + journey.duration_s):
        raise InputError(f"the broadcast ephemerides do not cover the journey (GPS week "
                         f"{week}, {journey.t0:.0f}-{journey.t0 + journey.duration_s:.0f} s "
                         f"of week): give a Journey whose t0 (GPS s of week) and a week "
                         f"inside the file's span", path=str(nav_file))
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    truth = GroundTruth(journey)
    rng = np.random.default_rng(seed)
    time_nanos, full_bias, tow_int, t_rx = _epochs(truth.t_start, truth.t_end, raw, phone,
                                                   week)
    leap_s = leap_seconds_at_gps_ns(week * WEEK_NS + int(tow_int[0]))
    lever = np.asarray(phone.lever_b_m, float)

    def receiver(t):
        from scipy.spatial.transform import Rotation

        from ins.nav import earth
        s = truth.evaluate(np.clip(t, truth.t_start, truth.t_end))
        lla = earth.offset_lla(s.lla, Rotation.from_quat(s.q_nb).as_matrix() @ lever)
        return lla, lla_to_ecef(lla[:, 0], lla[:, 1], lla[:, 2])
    obs = simulate_raw(orbits, week, t_rx, receiver, raw, rng, t_start=truth.t_start)
    raw_lines, raw_truth, chip_el = _raw_lines(obs, time_nanos, full_bias, tow_int, phone,
                                               raw, week, leap_s, truth.t_start, rng)
    model = ImuErrorModel.preset(phone.grade)
    model = replace(model, arw=model.arw * phone.noise_factor,
                    vrw=model.vrw * phone.noise_factor)
    sensor_lines, stamps = _sensor_lines(truth, phone, model, seed, week, leap_s)
    fix_lines, fix_t, _, _ = _fix_lines(truth, phone, week, leap_s, rng)
    header = ["# Version: v3.0.6.0 Platform: 13 Manufacturer: insphoto Model: simulated "
              "twin (ins.simulate.gnsslogger_writer)",
              "# Raw," + ",".join(RAW_COLUMNS), "# Fix," + ",".join(FIX_COLUMNS),
              "# UncalAccel," + ",".join(ACCEL_COLUMNS),
              "# UncalGyro," + ",".join(GYRO_COLUMNS), "#"]
    # the records in time order as the app writes them: by the boot clock
    timed = [(int(e), line) for line, e in zip(raw_lines, np.repeat(
        chip_el, obs.observed.sum(axis=1)))]
    timed += [(int(e), line) for e, line in zip(
        elapsed_ns(fix_t, truth.t_start, phone), fix_lines)]
    body = sorted(timed, key=lambda x: x[0])
    merged, i = [], 0
    for s in sensor_lines:                       # sensors already sorted by stamp
        e = int(s.split(",", 3)[2])
        while i < len(body) and body[i][0] <= e:
            merged.append(body[i][1])
            i += 1
        merged.append(s)
    merged += [b for _, b in body[i:]]
    with atomic_open(folder / "gnss_log.txt", "w") as f:
        f.write("\n".join(header + merged) + "\n")
    with atomic_open(folder / "rover.nav", "w") as f:
        f.write(span_text(nav_file, week, truth.t_start, truth.t_end))
    t = np.arange(truth.t_start, truth.t_end, 0.1)
    s = truth.evaluate(t)
    write_nav(folder / "truth.nav", Trajectory(t, s.lla, s.v_n, s.q_nb))
    with atomic_open(folder / "android_truth.csv", "w") as f:
        f.write("time_gps_s,svid,pseudorange_m,range_m,clock_bias_m,sat_clock_m,iono_m,"
                "tropo_m,multipath_m,elevation_deg\n")
        for row in raw_truth:
            f.write(f"{row[0]:.12f},{int(row[1])}," + ",".join(f"{v:.6f}" for v in row[2:])
                    + "\n")
    facts = {
        "gps_week": week, "leap_seconds": leap_s, "journey_start_gps_s": truth.t_start,
        "journey_end_gps_s": truth.t_end,
        "boot_clock": {"elapsed_at_start_ns": phone.boot_offset_ns,
                       "rate_ppm": phone.boot_rate_ppm,
                       "chipset_jitter_ns": phone.elapsed_jitter_ns,
                       "note": "elapsedRealtimeNanos = elapsed_at_start_ns + (t_gps - "
                               "journey_start_gps_s) 1e9 (1 + rate_ppm 1e-6)"},
        "chip_clock": {"time_nanos0": int(time_nanos[0]), "full_bias_nanos": int(full_bias),
                       "bias_nanos": phone.bias_nanos,
                       "clock_bias_s_first": float(obs.clock_bias_s[0]),
                       "clock_bias_s_last": float(obs.clock_bias_s[-1]),
                       "clock_bias_abs_max_s": float(np.max(np.abs(obs.clock_bias_s))),
                       "note": "t_rx = TimeNanos - FullBiasNanos - BiasNanos = t_gps + "
                               "clock_bias"},
        "sensors": {"grade": phone.grade, "noise_factor": phone.noise_factor,
                    "gyro_rate_hz": phone.gyro_rate_hz, "accel_rate_hz": phone.accel_rate_hz,
                    "gyro_clock_ppm": phone.gyro_clock_ppm,
                    "accel_clock_ppm": phone.accel_clock_ppm,
                    "stamp_jitter_s": phone.stamp_jitter_s,
                    "n_gyro": int(len(stamps["UncalGyro"][0])),
                    "n_accel": int(len(stamps["UncalAccel"][0]))},
        "gnss": {"n_epochs": int(len(obs.time_rx)), "n_measurements": int(obs.observed.sum()),
                 "satellites": sorted(int(p) for p in obs.prns[obs.observed.any(axis=0)])},
        "fixes": {"sigma_h_m": phone.fix_sigma_h_m, "sigma_v_m": phone.fix_sigma_v_m,
                  "time_s": phone.fix_time_s, "n": int(len(fix_t))},
        "raw": {k: v for k, v in asdict(raw).items()
                if isinstance(v, (int, float, str)) and not isinstance(v, bool)},
        "system_clock_error_s": phone.system_clock_error_s,
        "lever_b_m": list(map(float, phone.lever_b_m)),
    }
    with atomic_open(folder / "android_truth.toml", "wb") as f:
        tomli_w.dump(facts, f)
    return facts
