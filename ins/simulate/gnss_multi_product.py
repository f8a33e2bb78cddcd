"""Multi-constellation raw observations of a simulated flight: the files of ``[gnss_raw]``
with ``systems`` other than GPS alone or ``signals`` beyond L1.

:func:`write_gnss_multi` simulates (:func:`ins.simulate.gnss_multi.simulate_multi`) and
writes the files of :mod:`ins.simulate.gnss_raw_product` in their multi-GNSS form:

``rover.obs`` (and ``base.obs``)
    RINEX 3.04 ``M (MIXED)``: per system the ``C L D S`` codes of its signals
    (:mod:`ins.simulate.gnss_signals`), ``GLONASS SLOT / FRQ #``, time system GPS.
``rover.nav``
    RINEX 3.04 mixed navigation: the GPS records of ``nav_file`` within 2 h of the flight
    (rewritten as RINEX 3) and the generated Galileo, BeiDou and GLONASS ephemerides
    (:func:`ins.simulate.kepler_orbit.galileo_constellation`,
    :func:`~ins.simulate.kepler_orbit.beidou_constellation`,
    :func:`ins.simulate.glonass_orbit.glonass_constellation`), with the Klobuchar
    coefficients (``nav_file``'s, or RTKLIB's defaults without one) and the leap seconds.
``receiver_clock.txt``
    As for GPS alone.
``gnss_raw_truth.csv``
    One row per satellite, epoch and signal: ``time_rx_s,sat,signal,frequency_hz,
    time_gps_s,range_m,sat_clock_m,iono_m,tropo_m,multipath_code_m,multipath_phase_m,
    ambiguity_cycles,elevation_deg,azimuth_deg,x_sat_m,y_sat_m,z_sat_m,lli,
    antenna_elevation_deg`` (``sat`` the RINEX id ``Xnn``, ``signal`` the name of
    :data:`~ins.simulate.gnss_signals.SIGNALS`; ``sat_clock_m`` and ``iono_m`` of that
    signal), with ``C = range + c clock_bias - sat_clock + iono + tropo + multipath_code +
    noise`` and ``L = (range + c clock_bias - sat_clock - iono + tropo + multipath_phase
    + noise) frequency / c + ambiguity``.
"""
import io
from dataclasses import replace

import numpy as np

from ins.common.errors import InputError
from ins.common.fileio import atomic_open
from ins.io.rinex_nav import SECONDS_PER_WEEK, read_gps_nav
from ins.simulate.glonass_orbit import GlonassOrbits, glonass_constellation, leap_seconds
from ins.simulate.gnss_multi import MultiOrbits, simulate_multi
from ins.simulate.gnss_raw_product import (BASE_FILE, FILES, _receiver, _static, _write_clock,
                                           epochs)
from ins.simulate.gnss_signals import obs_types, signal_table
from ins.simulate.gps_orbit import MAX_AGE_S, BroadcastOrbits
from ins.simulate.kepler_orbit import KeplerOrbits, beidou_constellation, galileo_constellation
from ins.simulate.rinex_mixed import write_mixed_nav, write_mixed_obs

__all__ = ["KLOBUCHAR_DEFAULT", "build_orbits", "check_multi", "write_gnss_multi",
           "TRUTH_HEADER"]

#: RTKLIB's default Klobuchar coefficients (alpha, beta), used without a navigation file.
KLOBUCHAR_DEFAULT = ((0.1118e-07, -0.7451e-08, -0.5961e-07, 0.1192e-06),
                     (0.1167e+06, -0.2294e+06, -0.1311e+06, 0.1049e+07))
#: Largest ``|t - toe|`` of a usable Galileo and BeiDou ephemeris (RTKLIB's), s.
MAX_AGE = {"E": 14400.0, "C": 21600.0}
TRUTH_HEADER = ("time_rx_s,sat,signal,frequency_hz,time_gps_s,range_m,sat_clock_m,iono_m,"
                "tropo_m,multipath_code_m,multipath_phase_m,ambiguity_cycles,elevation_deg,"
                "azimuth_deg,x_sat_m,y_sat_m,z_sat_m,lli,antenna_elevation_deg\n")


def build_orbits(settings, week, t_first, t_last, source=None):
    """The orbits of the settings' systems over a span, and the records to write.

    Parameters
    ----------
    settings : ins.simulate.gnss_raw.RawSettings
    week : int
        GPS week.
    t_first, t_last : float
        GPS s of week.
    source : str, optional
        The plan (named in errors).

    Returns
    -------
    orbits : MultiOrbits
    records : dict
        ``gps``, ``kepler``, ``glonass`` ephemerides, ``alpha``, ``beta``, ``leap``.
    """
    s = settings
    table = signal_table(s.systems, s.signals)
    by, rec = {}, {"gps": [], "kepler": [], "glonass": []}
    alpha, beta = KLOBUCHAR_DEFAULT
    if "G" in s.systems and not s.nav_file:
        raise InputError("[gnss_raw] nav_file: GPS observations need a RINEX GPS "
                         "navigation file", path=source)
    if s.nav_file:
        nav = read_gps_nav(s.nav_file)
        if nav.ion_alpha is not None and nav.ion_beta is not None:
            alpha, beta = nav.ion_alpha, nav.ion_beta
        if "G" in s.systems:
            by["G"] = BroadcastOrbits(nav)
            by["G"].check_time(week, t_first, t_last, what="the flight ([flight] gps_week, "
                                                          "start_time_s)")
            lo = week * SECONDS_PER_WEEK + t_first - MAX_AGE_S
            hi = week * SECONDS_PER_WEEK + t_last + MAX_AGE_S
            rec["gps"] = [e for e in nav.ephemerides
                          if lo <= e.week * SECONDS_PER_WEEK + e.toe <= hi]
    if "E" in s.systems:
        ephs = galileo_constellation(week, t_first, t_last)
        by["E"], rec["kepler"] = KeplerOrbits(ephs, MAX_AGE["E"]), rec["kepler"] + ephs
    if "C" in s.systems:
        try:
            ephs = beidou_constellation(week, t_first, t_last, geo=s.beidou_geo)
        except InputError as exc:
            raise InputError(f"[gnss_raw] systems: {exc}", path=source) from None
        by["C"], rec["kepler"] = KeplerOrbits(ephs, MAX_AGE["C"]), rec["kepler"] + ephs
    if "R" in s.systems:
        rec["glonass"] = glonass_constellation(week, t_first, t_last)
        by["R"] = GlonassOrbits(rec["glonass"])
    rec.update(alpha=tuple(alpha), beta=tuple(beta), leap=leap_seconds(week, t_first))
    return MultiOrbits(by, table, alpha=tuple(alpha), beta=tuple(beta)), rec


def check_multi(settings, source, week, t_first, t_last):
    """InputError unless the orbits can be built for the flight (before the work)."""
    build_orbits(settings, week, t_first, t_last, source)


def _channels(orbits):
    r = orbits.by_system.get("R")
    return {} if r is None else {p: r.channel(p) for p in r.prns}


def _write_truth(path, obs):
    rows = []
    for q in range(obs.code.shape[2]):
        ok = np.isfinite(obs.code[:, :, q])
        i, j = np.nonzero(ok)
        if not len(i):
            continue
        sig = [obs.signals[obs.sats[jj][0]][q] for jj in j]
        num = np.column_stack([
            obs.frequency_hz[j, q], obs.time_gps[i], obs.rho[i, j], obs.sat_clock_m[i, j, q],
            obs.iono_m[i, j, q], obs.tropo_m[i, j], obs.mp_code_m[i, j, q],
            obs.mp_phase_m[i, j, q], obs.ambiguity[i, j, q], np.rad2deg(obs.elevation[i, j]),
            np.rad2deg(obs.azimuth[i, j]), *obs.r_sat_e[i, j].T, obs.lli[i, j, q],
            np.rad2deg(obs.elevation_antenna[i, j])])
        buf = io.StringIO()
        np.savetxt(buf, num, delimiter=",",
                   fmt=["%.1f", "%.12f", "%.4f", "%.4f", "%.4f", "%.4f", "%.4f", "%.5f", "%d",
                        "%.6f", "%.6f", "%.4f", "%.4f", "%.4f", "%d", "%.6f"])
        for ii, jj, sg, line in zip(i, j, sig, buf.getvalue().splitlines()):
            rows.append((obs.time_rx[ii], jj, q, f"{obs.time_rx[ii]:.3f},{obs.sats[jj]},{sg},"
                                                 f"{line}\n"))
    rows.sort(key=lambda r: r[:3])
    with atomic_open(path, "w") as f:
        f.write(TRUTH_HEADER)
        f.write("".join(r[3] for r in rows))


def write_gnss_multi(flight, settings, rng):
    """Simulate and write the multi-GNSS raw observations of a flight (module docstring).

    Parameters and result as :func:`ins.simulate.gnss_raw_product.write_gnss_raw`.
    """
    plan, truth, folder = flight.plan, flight.truth, flight.folder
    week = plan.flight.gps_week
    orbits, rec = build_orbits(settings, week, truth.t_start, truth.t_end, plan.source)
    time_rx = epochs(truth.t_start, truth.t_end, settings.rate_hz)
    m = plan.mount
    obs = simulate_multi(orbits, week, time_rx, _receiver(truth, m.l_bp, m.l_ap), settings,
                         rng, t_start=truth.t_start)
    flight.progress(0.6)
    ch = _channels(orbits)
    write_mixed_obs(folder / FILES["gnss_raw_obs"], obs, ch, obs.r_rx_e[0],
                    1.0 / settings.rate_hz, "SIMULATED_ROVER", leap_seconds=rec["leap"],
                    comments=("simulated by ins simulate (insphoto): truth in",
                              "receiver_clock.txt and gnss_raw_truth.csv"))
    files, extra = dict(FILES), {}
    if settings.base_lla is not None:
        base = simulate_multi(orbits, week, time_rx, _static(settings.base_lla),
                              replace(settings, slips=(), masks=()),
                              np.random.default_rng(rng.integers(2 ** 63)),
                              t_start=truth.t_start)
        write_mixed_obs(folder / BASE_FILE, base, ch, base.r_rx_e[0], 1.0 / settings.rate_hz,
                        "SIMULATED_BASE", leap_seconds=rec["leap"],
                        comments=("simulated static base station: APPROX POSITION XYZ is",
                                  "its true antenna position (ECEF, m)"))
        files["gnss_raw_base_obs"] = BASE_FILE
        lat, lon, h = settings.base_lla
        extra = {"base_lla_deg": [float(np.rad2deg(lat)), float(np.rad2deg(lon)), float(h)],
                 "base_ecef_m": [float(x) for x in base.r_rx_e[0]],
                 "base_clock_bias_ms": float(base.clock_bias_s[0] * 1e3)}
    write_mixed_nav(folder / FILES["gnss_raw_nav"], gps=rec["gps"], kepler=rec["kepler"],
                    glonass=rec["glonass"], ion_alpha=rec["alpha"], ion_beta=rec["beta"],
                    leap_seconds=rec["leap"],
                    comments=("GPS: the records of the plan's nav_file; Galileo, BeiDou,",
                              "GLONASS: plausible constellations of ins simulate"))
    _write_clock(folder / FILES["receiver_clock"], obs)
    _write_truth(folder / FILES["gnss_raw_truth"], obs)
    flight.progress(1.0)
    s = settings
    n_sat = obs.observed.sum(axis=1)
    table = {
        "nav_source": str(s.nav_file), "rate_hz": s.rate_hz,
        "systems": list(orbits.signals),
        "signals": {sy: list(v) for sy, v in obs.signals.items()},
        "obs_types": {sy: list(obs_types(sy, ix)) for sy, ix in orbits.signals.items()},
        "glonass_channels": {f"R{p:02d}": int(k) for p, k in ch.items()},
        "elevation_mask_deg": float(np.rad2deg(s.elevation_mask_rad)),
        "antenna_mask_deg": float(np.rad2deg(s.antenna_mask_rad)),
        "sigma_code_m": s.sigma_code_m, "sigma_phase_m": s.sigma_phase_m,
        "sigma_doppler_hz": s.sigma_doppler_hz, "multipath_code_m": s.multipath_code_m,
        "multipath_phase_m": s.multipath_phase_m, "multipath_time_s": s.multipath_time_s,
        "clock_bias_ms": s.clock_bias_s * 1e3, "clock_drift_ppb": s.clock_drift * 1e9,
        "iono_scale": s.iono_scale, "tropo_scale": s.tropo_scale,
        "signal_noise": {k: v for k, v in s.signal_noise},
        "klobuchar_alpha": list(rec["alpha"]), "klobuchar_beta": list(rec["beta"]),
        "leap_seconds": int(rec["leap"]),
        "slips": [[float(a), int(b), int(c)] for a, b, c in s.slips],
        "masks": [[float(a), float(b), int(c)] for a, b, c in s.masks],
        "slips_made": [[t, p, c] for t, p, c in obs.slips],
        "n_epochs": int(len(time_rx)), "min_satellites": int(n_sat.min()),
        "max_satellites": int(n_sat.max()),
        "antenna": "the antenna of gnss.txt (lever arms l_bp, l_ap and the mount)", **extra}
    return {"files": files, "gnss_raw": table}
