"""Raw GPS observations of a simulated flight: the files of ``[gnss_raw]``.

:func:`write_gnss_raw` simulates the antenna's raw L1 observations
(:func:`ins.simulate.gnss_raw.simulate_raw`) from the broadcast orbits of the plan's
navigation file and writes, beside the IMU and the truth of the flight folder:

``rover.obs``
    RINEX 3.04 observations ``C1C L1C D1C S1C`` (m, cycles, Hz, dB-Hz), epochs in the
    receiver's clock time; LLI bit 0 at the first epoch of every arc after the first
    epoch and at each cycle slip; the signal-strength digit from C/N0 (``C/N0 / 6``,
    1-9).
``rover.nav``
    The navigation file's header and its GPS records within 2 h of the flight (verbatim).
``receiver_clock.txt``
    ``time_rx_s time_gps_s clock_bias_s clock_drift_s_per_s``: the receiver clock's truth
    (time_gps = time_rx - bias).
``gnss_raw_truth.csv``
    One row per observation: ``time_rx_s,prn,time_gps_s,range_m,sat_clock_m,iono_m,
    tropo_m,multipath_code_m,multipath_phase_m,ambiguity_cycles,elevation_deg,
    azimuth_deg,x_sat_m,y_sat_m,z_sat_m,lli,antenna_elevation_deg`` (the last: above the
    aircraft's x-y plane, whose body hides what is below ``[gnss_raw] antenna_mask_deg``)
    with ``range_m`` the geometric range with
    light time and Sagnac, the satellite at transmit time in the ECEF frame at reception,
    so that ``C1C = range + c clock_bias - sat_clock + iono + tropo + multipath_code +
    noise`` and ``L1C = (range + c clock_bias - sat_clock - iono + tropo +
    multipath_phase + noise) / lambda_L1 + ambiguity``.

``base.obs``
    (with ``base_lla_deg``) A static base station's observations of the same epochs:
    the same model, orbits, ionosphere and troposphere models, its own receiver clock,
    noise, multipath and ambiguities, no slips or masks; its header's ``APPROX POSITION
    XYZ`` is its true antenna position (ECEF, m), also in the manifest's ``[gnss_raw]``
    ``base_ecef_m``.  For differential and RTK processing.

The antenna is that of ``gnss.txt`` (the plan's lever arms and the mount).  The random
numbers come from ``product_rng(seed, "gnss_raw")``: the raw product leaves the other
products' bytes unchanged.
"""
import io
import warnings
from dataclasses import replace

import numpy as np

from ins.common.errors import InputError, QualityWarning
from ins.common.fileio import atomic_open
from ins.io.rinex_nav import read_gps_nav, span_text
from ins.io.rinex_obs import write_rinex3_obs
from ins.nav.earth import lla_to_ecef
from ins.nav.rotation import quat_to_dcm
from ins.simulate.gnss import antenna_state
from ins.simulate.gnss_raw import L1_WAVELENGTH, simulate_raw
from ins.simulate.gps_orbit import C_LIGHT, MAX_AGE_S, BroadcastOrbits

__all__ = ["FILES", "BASE_FILE", "write_gnss_raw", "load_orbits", "epochs", "check_span"]

#: Manifest ``[files]`` key -> file name.
FILES = {"gnss_raw_obs": "rover.obs", "gnss_raw_nav": "rover.nav",
         "receiver_clock": "receiver_clock.txt", "gnss_raw_truth": "gnss_raw_truth.csv"}
#: The static base station's observations (with ``[gnss_raw] base_lla_deg``).
BASE_FILE = "base.obs"
TRUTH_HEADER = ("time_rx_s,prn,time_gps_s,range_m,sat_clock_m,iono_m,tropo_m,"
                "multipath_code_m,multipath_phase_m,ambiguity_cycles,elevation_deg,"
                "azimuth_deg,x_sat_m,y_sat_m,z_sat_m,lli,antenna_elevation_deg\n")
#: Margin kept inside the flight at both ends for the receiver clock and the Doppler's
#: central difference, s.
EDGE_S = 0.1


def load_orbits(settings, source=None):
    """BroadcastOrbits of ``settings.nav_file`` (InputError naming the plan ``source`` and
    the key when it is absent)."""
    if not settings.nav_file:
        raise InputError("[gnss_raw] nav_file: the raw observations need a RINEX GPS "
                         "navigation file (a path, or ins simulate --gnss-raw NAV_FILE)",
                         path=source)
    return BroadcastOrbits(read_gps_nav(settings.nav_file))


def epochs(t_start, t_end, rate_hz):
    """Receiver-clock epochs: whole multiples of ``1 / rate_hz`` inside the flight, s."""
    k0 = int(np.ceil((t_start + EDGE_S) * rate_hz - 1e-9))
    k1 = int(np.floor((t_end - EDGE_S) * rate_hz + 1e-9))
    return np.arange(k0, k1 + 1) / rate_hz


def check_span(orbits, week, t_start, t_end):
    """InputError unless the broadcast orbits cover the flight (naming the plan keys)."""
    orbits.check_time(week, t_start, t_end, what="the flight ([flight] gps_week, "
                                                  "start_time_s)")


def _warn_few_satellites(obs, time_rel_s, settings, orbits):
    """A warning when, outside the plan's masks, most epochs see fewer than 4 satellites:
    a navigation file holds the ephemerides of the satellites its station saw, and a
    flight far from that station (or at another time) sees few of them."""
    n = obs.observed.sum(axis=1)
    free = np.ones(len(n), bool)
    for start, length, _ in settings.masks:
        free &= ~((time_rel_s >= start) & (time_rel_s < start + length))
    few = np.count_nonzero(n[free] < 4)
    if free.any() and few > 0.5 * np.count_nonzero(free):
        t_mid = float(np.median(obs.time_gps))
        valid = sum(np.all(np.isfinite(orbits.state(p, obs.week, [t_mid])[0]))
                    for p in orbits.prns)
        warnings.warn(f"{settings.nav_file}: only {int(np.median(n[free]))} satellites in view "
                      f"(median; fewer than 4 at {few} of {np.count_nonzero(free)} unmasked "
                      f"epochs): at the flight's time {valid} of the file's "
                      f"{len(orbits.prns)} satellites have an ephemeris (within "
                      f"{MAX_AGE_S / 3600:g} h), those its station saw shortly before; fly "
                      f"near that station or give a navigation file of the flight's place and "
                      f"time (no GNSS solution is possible from these observations)",
                      QualityWarning, stacklevel=2)


def _receiver(truth, l_bp, l_ap):
    def receiver(t):
        t = np.clip(t, truth.t_start, truth.t_end)
        sample = truth.evaluate(t)
        lla, _ = antenna_state(sample, l_bp, l_ap)
        return (lla, lla_to_ecef(lla[:, 0], lla[:, 1], lla[:, 2]),
                quat_to_dcm(np.atleast_2d(sample.q_na)))
    return receiver


def _ssi(snr):
    return np.where(np.isfinite(snr), np.clip(np.floor(np.nan_to_num(snr) / 6.0), 1, 9),
                    0).astype(int)


def _write_truth(path, obs):
    i, j = np.nonzero(obs.observed)
    cols = [obs.time_rx[i], obs.prns[j], obs.time_gps[i], obs.rho[i, j], obs.sat_clock_m[i, j],
            obs.iono_m[i, j], obs.tropo_m[i, j], obs.mp_code_m[i, j], obs.mp_phase_m[i, j],
            obs.ambiguity[i, j], np.rad2deg(obs.elevation[i, j]),
            np.rad2deg(obs.azimuth[i, j]), *obs.r_sat_e[i, j].T, obs.lli[i, j],
            np.rad2deg(obs.elevation_antenna[i, j])]
    fmt = ["%.3f", "%d", "%.12f", "%.4f", "%.4f", "%.4f", "%.4f", "%.4f", "%.5f", "%d",
           "%.6f", "%.6f", "%.4f", "%.4f", "%.4f", "%d", "%.6f"]
    buf = io.StringIO()
    np.savetxt(buf, np.column_stack(cols), fmt=fmt, delimiter=",")
    with atomic_open(path, "w") as f:
        f.write(TRUTH_HEADER)
        f.write(buf.getvalue())


def _write_clock(path, obs):
    buf = io.StringIO()
    np.savetxt(buf, np.column_stack([obs.time_rx, obs.time_gps, obs.clock_bias_s,
                                     obs.clock_drift]),
               fmt=["%.3f", "%.12f", "%.15e", "%.15e"])
    with atomic_open(path, "w") as f:
        f.write("# time_rx_s time_gps_s clock_bias_s clock_drift_s_per_s  "
                "(receiver clock: time_gps = time_rx - clock_bias)\n")
        f.write(buf.getvalue())


def write_gnss_raw(flight, settings, rng):
    """Simulate and write the raw observations of a flight (module docstring).

    Parameters
    ----------
    flight : ins.simulate.folder.FlightProducts
        The plan, the truth and the folder being built.
    settings : ins.simulate.gnss_raw.RawSettings
    rng : numpy.random.Generator

    Returns
    -------
    dict
        Manifest tables: ``[files]`` and ``[gnss_raw]`` (settings, counts).
    """
    plan, truth, folder = flight.plan, flight.truth, flight.folder
    week = plan.flight.gps_week
    orbits = load_orbits(settings)
    check_span(orbits, week, truth.t_start, truth.t_end)
    time_rx = epochs(truth.t_start, truth.t_end, settings.rate_hz)
    m = plan.mount
    obs = simulate_raw(orbits, week, time_rx, _receiver(truth, m.l_bp, m.l_ap), settings, rng,
                       t_start=truth.t_start)
    flight.progress(0.6)
    _warn_few_satellites(obs, time_rx - truth.t_start, settings, orbits)
    _write_obs(folder / FILES["gnss_raw_obs"], obs, obs.r_rx_e[0], settings, orbits,
               "SIMULATED_ROVER", ("simulated by ins simulate (insphoto): truth in",
                                   "receiver_clock.txt and gnss_raw_truth.csv"))
    files = dict(FILES)
    extra = {}
    if settings.base_lla is not None:
        base = simulate_raw(orbits, week, time_rx, _static(settings.base_lla),
                            replace(settings, slips=(), masks=()),
                            np.random.default_rng(rng.integers(2 ** 63)), t_start=truth.t_start)
        _write_obs(folder / BASE_FILE, base, base.r_rx_e[0], settings, orbits,
                   "SIMULATED_BASE", ("simulated static base station: APPROX POSITION XYZ is",
                                      "its true antenna position (ECEF, m)"))
        files["gnss_raw_base_obs"] = BASE_FILE
        lat, lon, h = settings.base_lla
        extra = {"base_lla_deg": [float(np.rad2deg(lat)), float(np.rad2deg(lon)), float(h)],
                 "base_ecef_m": [float(x) for x in base.r_rx_e[0]],
                 "base_clock_bias_ms": float(base.clock_bias_s[0] * 1e3)}
    with atomic_open(folder / FILES["gnss_raw_nav"], "w") as f:
        f.write(span_text(settings.nav_file, week, truth.t_start, truth.t_end))
    _write_clock(folder / FILES["receiver_clock"], obs)
    _write_truth(folder / FILES["gnss_raw_truth"], obs)
    flight.progress(1.0)
    s = settings
    n_sat = obs.observed.sum(axis=1)
    table = {
        "nav_source": str(s.nav_file), "rate_hz": s.rate_hz,
        "obs_types": ["C1C", "L1C", "D1C", "S1C"],
        "elevation_mask_deg": float(np.rad2deg(s.elevation_mask_rad)),
        "antenna_mask_deg": float(np.rad2deg(s.antenna_mask_rad)),
        "sigma_code_m": s.sigma_code_m, "sigma_phase_m": s.sigma_phase_m,
        "sigma_doppler_hz": s.sigma_doppler_hz, "multipath_code_m": s.multipath_code_m,
        "multipath_phase_m": s.multipath_phase_m, "multipath_time_s": s.multipath_time_s,
        "clock_bias_ms": s.clock_bias_s * 1e3, "clock_drift_ppb": s.clock_drift * 1e9,
        "iono_scale": s.iono_scale, "tropo_scale": s.tropo_scale,
        "wavelength_l1_m": L1_WAVELENGTH, "speed_of_light_mps": C_LIGHT,
        "slips": [[float(a), int(b), int(c)] for a, b, c in s.slips],
        "masks": [[float(a), float(b), int(c)] for a, b, c in s.masks],
        "slips_made": [[t, p, c] for t, p, c in obs.slips],
        "n_epochs": int(len(time_rx)), "min_satellites": int(n_sat.min()),
        "max_satellites": int(n_sat.max()),
        "antenna": "the antenna of gnss.txt (lever arms l_bp, l_ap and the mount)", **extra}
    return {"files": files, "gnss_raw": table}


def _static(lla):
    lla = np.asarray(lla, dtype=float)
    r_e = lla_to_ecef(*lla)

    def receiver(t):
        return np.tile(lla, (len(t), 1)), np.tile(r_e, (len(t), 1))
    return receiver


def _write_obs(path, obs, approx_xyz, settings, orbits, marker, comments):
    values = np.stack([obs.code, obs.phase, obs.doppler, obs.snr], axis=2)
    lli = np.zeros(values.shape, int)
    lli[:, :, 1] = obs.lli
    ssi = np.repeat(_ssi(obs.snr)[:, :, None], 4, axis=2)
    ssi[:, :, 2:] = 0
    write_rinex3_obs(path, obs.week, obs.time_rx, obs.prns, values, lli=lli, ssi=ssi,
                     approx_xyz_m=approx_xyz, interval_s=1.0 / settings.rate_hz,
                     marker=marker, leap_seconds=orbits.nav.leap_seconds, comments=comments)
