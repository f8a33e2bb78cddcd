"""The flight plan's ``[gnss_raw]`` section: raw GNSS observations of the flight.

Present, it makes the simulator write ``rover.obs`` (RINEX 3.04), ``rover.nav`` (the
navigation file's records of the flight's span), ``receiver_clock.txt`` and
``gnss_raw_truth.csv`` (:mod:`ins.simulate.gnss_raw_product`).  Keys (units in the names;
defaults of :class:`ins.simulate.gnss_raw.RawSettings`)::

    [gnss_raw]
    nav_file = "../shared/real/rtklib_static_pair/07590920.05n"   # relative to the plan
    rate_hz = 1.0
    elevation_mask_deg = 10.0
    antenna_mask_deg = 0.0        # hidden by the aircraft: below its x-y plane (FRD)
    sigma_code_m = 0.3            # white noise at zenith, / sin(el)
    sigma_phase_m = 0.002
    sigma_doppler_hz = 0.05
    multipath_code_m = 0.3        # Gauss-Markov, / sin(el)
    multipath_phase_m = 0.003
    multipath_time_s = 60.0
    clock_bias_ms = 0.1           # receiver clock at the first epoch
    clock_drift_ppb = 10.0        # 1e-9 s/s
    clock_bias_noise_ns_sqrts = 0.3
    clock_drift_noise_ppb_sqrts = 0.6
    iono_scale = 1.0              # x Klobuchar (0: none)
    tropo_scale = 1.0             # x Saastamoinen
    humidity_percent = 70.0
    cn0_zenith_dbhz = 50.0
    cn0_horizon_dbhz = 35.0
    ambiguity_max_cycles = 1000
    slips = [[120.0, 7, 3]]       # [time_s after the start, PRN (0: all), cycles]
    masks = [[200.0, 30.0, 3]]    # [start_s after the start, duration_s, satellites kept]
    base_lla_deg = [35.17, 139.60, 60.0]   # optional static base station -> base.obs
    systems = ["G", "R", "E", "C"]   # GPS (nav_file), GLONASS, Galileo, BeiDou (generated)
    signals = ["L1", "L2", "L5", "G1", "G2", "E1", "E5a", "B1I", "B2a", "B3I"]
                                  # default: the first of each system
    beidou_geo = true             # BeiDou's 5 GEO satellites (PRN 1-5)
    signal_noise = { L2 = 2.0 }   # x the noise and multipath above, per signal (default 1)

With ``systems`` other than ``["G"]`` or ``signals`` beyond ``L1``, the observations are
those of :mod:`ins.simulate.gnss_multi` (RINEX 3.04 mixed ``rover.obs`` and ``rover.nav``);
``nav_file`` is then needed only with GPS (without it the Klobuchar coefficients are
RTKLIB's defaults).

The flight's time (``[flight] gps_week``, ``start_time_s``) must lie within the
ephemerides of the navigation file (e.g. week 1316, 518400-525600 s for the 2005 day 092
files of ``rtklib_static_pair``); this is checked before the simulation starts.
"""
import os

import numpy as np

from ins.common.errors import InputError
from ins.simulate.gnss_raw import RawSettings
from ins.simulate.gnss_signals import SIGNALS, signal_table

__all__ = ["GNSS_RAW_KEYS", "parse_gnss_raw"]

GNSS_RAW_KEYS = ("nav_file", "rate_hz", "elevation_mask_deg", "antenna_mask_deg",
                 "sigma_code_m", "sigma_phase_m",
                 "sigma_doppler_hz", "multipath_code_m", "multipath_phase_m",
                 "multipath_time_s", "clock_bias_ms", "clock_drift_ppb",
                 "clock_bias_noise_ns_sqrts", "clock_drift_noise_ppb_sqrts", "iono_scale",
                 "tropo_scale", "humidity_percent", "cn0_zenith_dbhz", "cn0_horizon_dbhz",
                 "ambiguity_max_cycles", "slips", "masks", "base_lla_deg", "systems",
                 "signals", "beidou_geo", "signal_noise")


def _rows(sec, key, width, what, check):
    raw = sec.raw(key, [])
    ok = isinstance(raw, list) and all(
        isinstance(r, list) and len(r) == width
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in r)
        and check(r) for r in raw)
    if not ok:
        raise sec.error(key, f"expected {what}, got {raw!r}")
    return raw


def parse_gnss_raw(sec, source):
    """The ``[gnss_raw]`` table as :class:`~ins.simulate.gnss_raw.RawSettings` (SI).

    Parameters
    ----------
    sec : ins.common.tomlschema.Table
    source : str
        The plan's path: a relative ``nav_file`` is relative to its folder.
    """
    d = RawSettings()
    nav = sec.string("nav_file", "", "path of a RINEX GPS navigation file")
    if nav and not os.path.isabs(nav):
        nav = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(source)), nav))

    def pos(key, default, unit, hi=None):
        return sec.number(key, default, unit, 0.0, hi, lo_open=True)

    def nonneg(key, default, unit, hi=None):
        return sec.number(key, default, unit, 0.0, hi)

    slips = _rows(sec, "slips", 3, "[[time_s >= 0, PRN 0-32, integer cycles != 0], ...]",
                  lambda r: r[0] >= 0 and r[1] == int(r[1]) and 0 <= r[1] <= 32
                  and r[2] == int(r[2]) and r[2] != 0)
    masks = _rows(sec, "masks", 3, "[[start_s >= 0, duration_s > 0, satellites >= 0], ...]",
                  lambda r: r[0] >= 0 and r[1] > 0 and r[2] == int(r[2]) and r[2] >= 0)
    base = sec.numbers("base_lla_deg", (), "[lat deg, lon deg, h m]", length=None)
    if base and (len(base) != 3 or abs(base[0]) > 90 or abs(base[1]) > 360
                 or not -500 <= base[2] <= 9000):
        raise sec.error("base_lla_deg", f"expected [lat deg, lon deg, h m], got {list(base)}",
                        "[lat deg, lon deg, h m]")
    systems = _strings(sec, "systems", ["G"], "a list of systems of G R E C")
    signals = _strings(sec, "signals", [],
                       "a list of signals of L1 L2 L5 G1 G2 E1 E5a B1I B2a B3I")
    try:
        signal_table(systems, signals)
    except InputError as exc:
        key = "systems" if "systems" in str(exc) else "signals"
        raise sec.error(key, str(exc).split(": ", 1)[-1]) from None
    noise = sec.raw("signal_noise", {})
    names = {n for sys in SIGNALS.values() for n, _, _ in sys}
    if not (isinstance(noise, dict) and all(
            k in names and isinstance(v, (int, float)) and not isinstance(v, bool)
            and 0 < v <= 100 for k, v in noise.items())):
        raise sec.error("signal_noise", f"expected a table of signal = factor in (0, 100] "
                                        f"with signals of {sorted(names)}, got {noise!r}")
    zenith = nonneg("cn0_zenith_dbhz", d.cn0_zenith_dbhz, "dB-Hz in [0, 99]", 99.0)
    horizon = nonneg("cn0_horizon_dbhz", d.cn0_horizon_dbhz, "dB-Hz in [0, 99]", 99.0)
    return RawSettings(
        nav_file=nav,
        rate_hz=pos("rate_hz", d.rate_hz, "Hz in (0, 100]", 100.0),
        elevation_mask_rad=np.deg2rad(nonneg("elevation_mask_deg", 10.0, "deg in [0, 60]", 60.0)),
        antenna_mask_rad=np.deg2rad(sec.number("antenna_mask_deg", 0.0, "deg in [-90, 60]",
                                           -90.0, 60.0)),
        sigma_code_m=nonneg("sigma_code_m", d.sigma_code_m, "m >= 0", 100.0),
        sigma_phase_m=nonneg("sigma_phase_m", d.sigma_phase_m, "m >= 0", 0.05),
        sigma_doppler_hz=nonneg("sigma_doppler_hz", d.sigma_doppler_hz, "Hz >= 0", 100.0),
        multipath_code_m=nonneg("multipath_code_m", d.multipath_code_m, "m >= 0", 100.0),
        multipath_phase_m=nonneg("multipath_phase_m", d.multipath_phase_m, "m >= 0", 0.05),
        multipath_time_s=pos("multipath_time_s", d.multipath_time_s, "s > 0"),
        clock_bias_s=sec.number("clock_bias_ms", d.clock_bias_s * 1e3, "ms in [-1, 1]",
                                -1.0, 1.0) * 1e-3,
        clock_drift=sec.number("clock_drift_ppb", d.clock_drift * 1e9, "ppb (1e-9 s/s)",
                               -1e4, 1e4) * 1e-9,
        clock_bias_noise=nonneg("clock_bias_noise_ns_sqrts", d.clock_bias_noise * 1e9,
                                "ns/sqrt(s) >= 0", 1e3) * 1e-9,
        clock_drift_noise=nonneg("clock_drift_noise_ppb_sqrts", d.clock_drift_noise * 1e9,
                                 "ppb/sqrt(s) >= 0", 1e3) * 1e-9,
        iono_scale=nonneg("iono_scale", d.iono_scale, "factor >= 0", 10.0),
        tropo_scale=nonneg("tropo_scale", d.tropo_scale, "factor >= 0", 10.0),
        humidity_fraction=nonneg("humidity_percent", d.humidity_fraction * 100,
                                 "percent in [0, 100]", 100.0) / 100.0,
        cn0_zenith_dbhz=zenith, cn0_horizon_dbhz=horizon,
        ambiguity_max=sec.number("ambiguity_max_cycles", d.ambiguity_max,
                                 "integer cycles in [0, 1e7]", 0, 10_000_000, integer=True),
        slips=tuple((float(a), int(b), int(c)) for a, b, c in slips),
        masks=tuple((float(a), float(b), int(c)) for a, b, c in masks),
        base_lla=(float(np.deg2rad(base[0])), float(np.deg2rad(base[1])), float(base[2]))
        if base else None,
        systems=tuple(systems), signals=tuple(signals),
        beidou_geo=sec.boolean("beidou_geo", d.beidou_geo),
        signal_noise=tuple((str(k), float(v)) for k, v in noise.items()))


def _strings(sec, key, default, what):
    raw = sec.raw(key, default)
    if not (isinstance(raw, list) and all(isinstance(x, str) for x in raw)):
        raise sec.error(key, f"expected {what}, got {raw!r}")
    return list(raw)
