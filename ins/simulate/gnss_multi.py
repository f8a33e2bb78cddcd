"""Raw observations of several constellations and frequencies, with known truth.

The model of :mod:`ins.simulate.gnss_raw` for every satellite ``s`` of the chosen systems
and every simulated signal ``f`` of its system (:mod:`ins.simulate.gnss_signals`), with
``lambda_f = c / f`` (GLONASS: ``f`` of the satellite's channel ``k``)::

    I_f  = (f_L1 / f)^2 I_L1                     (Klobuchar L1 delay x iono_scale)
    P_f  = rho + c (dt_r - dt_s,f) + I_f + T + m_P,f + e_P,f                  (m)
    L_f  = (rho + c (dt_r - dt_s,f) - I_f + T + m_L,f + e_L,f) / lambda_f + N_f  (cycles)
    D_f  = -(d/dt [rho - c dt_s,f - I_f + T] + c d(dt_r)/dt) / lambda_f + e_D,f  (Hz)

One receiver clock (in GPS time) for all systems: the system times are taken exactly
``GST = GPST``, ``BDT = GPST - 14 s``, ``GLONASST = UTC + 3 h = GPST - leap + 3 h``
(no inter-system bias), and each system's broadcast clock is relative to its own time.
The geometry (light time, Sagnac, elevation, masks, the vehicle's body, arcs) is per
satellite and shared by its signals; ambiguities, multipath and white noise are drawn per
signal (the standard deviations of the settings times the signal's factor of
``signal_noise``, 1 by default); a slip of ``[gnss_raw] slips`` (a GPS PRN,
or 0: every satellite) jumps every signal of the satellite by its cycles and sets their
LLI.  The Doppler's derivative is the central difference of :mod:`ins.simulate.gnss_raw`.
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.simulate.gnss_raw import (DOPPLER_STEP_S, _apply_masks, _arc_starts, _gauss_markov,
                                   antenna_elevation, az_el, clock_process, klobuchar,
                                   light_time, saastamoinen)
from ins.simulate.gnss_signals import F_L1, SIGNALS, clock_offset, frequency_hz
from ins.simulate.gps_orbit import C_LIGHT

__all__ = ["MultiOrbits", "MultiObservations", "simulate_multi"]

_PI = np.pi


class MultiOrbits:
    """The orbits of several systems behind one interface.

    Parameters
    ----------
    by_system : dict
        ``"G"``: :class:`ins.simulate.gps_orbit.BroadcastOrbits`, ``"E"``/``"C"``:
        :class:`ins.simulate.kepler_orbit.KeplerOrbits`, ``"R"``:
        :class:`ins.simulate.glonass_orbit.GlonassOrbits`.
    signals : dict
        system -> indices of the signals (:func:`ins.simulate.gnss_signals.signal_table`).
    alpha, beta : sequence of 4 float or None
        Klobuchar coefficients.
    """

    def __init__(self, by_system, signals, alpha=None, beta=None):
        missing = [s for s in signals if s not in by_system]
        if missing:
            raise InputError(f"no orbits for the systems {missing}")
        self.by_system = dict(by_system)
        self.signals = dict(signals)
        self.alpha, self.beta = alpha, beta

    @property
    def sats(self):
        """Satellite ids ``Xnn`` of the simulated systems (system order of ``signals``)."""
        return [f"{s}{p:02d}" for s in self.signals for p in self.by_system[s].prns]

    def channel(self, sat):
        """GLONASS frequency channel of ``Rnn`` (0 for the other systems)."""
        return self.by_system["R"].channel(int(sat[1:])) if sat[0] == "R" else 0

    def state(self, sat, week, t):
        """``(r_e, v_e, dt, ddt)`` of satellite ``sat`` at GPS times (see the orbits)."""
        return self.by_system[sat[0]].state(int(sat[1:]), week, t)

    def tgd(self, sat, week, t):
        """GPS ``tgd`` of the ephemeris used at each time (0 for other systems), s."""
        t = np.atleast_1d(np.asarray(t, float))
        out = np.zeros(len(t))
        if sat[0] == "G":
            ephs, idx = self.by_system["G"].select(int(sat[1:]), week, t)
            ok = idx >= 0
            out[ok] = [ephs[k].tgd for k in idx[ok]]
        return out


@dataclass(frozen=True)
class MultiObservations:
    """Simulated observations and truth: ``(n epochs, m satellites)`` geometry and
    ``(n, m, k)`` per signal slot (slot ``j``: the ``j``-th simulated signal of the
    satellite's system; NaN where the system has fewer signals or the satellite is not
    observed).

    Attributes
    ----------
    week : int
    time_rx, time_gps : ndarray (n,)
        Receiver clock epochs and true GPS time of reception, GPS s of week.
    sats : tuple of str
        ``Xnn`` ids.
    signals : dict
        system -> tuple of signal names in slot order.
    frequency_hz : ndarray (m, k)
    code, phase, doppler, snr : ndarray (n, m, k)
        m, cycles, Hz, dB-Hz.
    lli : ndarray of int (n, m, k)
    observed : ndarray of bool (n, m)
    rho, tropo_m, elevation, azimuth, elevation_antenna : ndarray (n, m)
        Geometric range with light time and Sagnac (m), troposphere (m), rad.
    sat_clock_m, iono_m, mp_code_m, mp_phase_m, ambiguity : ndarray (n, m, k)
        ``c dt_s,f``, ``I_f`` (group delay), multipath (m), integer ambiguity (cycles).
    r_sat_e : ndarray (n, m, 3)
    clock_bias_s, clock_drift : ndarray (n,)
    r_rx_e : ndarray (n, 3)
    slips : tuple of (float, str, int)
    """

    week: int
    time_rx: np.ndarray
    time_gps: np.ndarray
    sats: tuple
    signals: dict
    frequency_hz: np.ndarray
    code: np.ndarray
    phase: np.ndarray
    doppler: np.ndarray
    snr: np.ndarray
    lli: np.ndarray
    observed: np.ndarray
    rho: np.ndarray
    tropo_m: np.ndarray
    elevation: np.ndarray
    azimuth: np.ndarray
    elevation_antenna: np.ndarray
    sat_clock_m: np.ndarray
    iono_m: np.ndarray
    mp_code_m: np.ndarray
    mp_phase_m: np.ndarray
    ambiguity: np.ndarray
    r_sat_e: np.ndarray
    clock_bias_s: np.ndarray
    clock_drift: np.ndarray
    r_rx_e: np.ndarray
    slips: tuple = ()


def _geometry(orbits, sats, week, t, lla, r_rx, C_na, ends, s, iono_l1):
    """Range, satellite, clocks, delays and the central-difference rates per satellite."""
    n, m = len(t), len(sats)
    rho, dts, trop, el, az, el_a, i1 = (np.full((n, m), np.nan) for _ in range(7))
    rate, irate = np.full((n, m), np.nan), np.full((n, m), np.nan)
    r_sat = np.full((n, m, 3), np.nan)
    h = DOPPLER_STEP_S
    for j, sat in enumerate(sats):
        def state(tt, sat=sat):
            r, _, c, _ = orbits.state(sat, week, tt)
            return r, c
        rho_j, rs_j, dts_j = light_time(state, t, r_rx)
        if np.all(np.isnan(rho_j)):
            continue
        az_j, el_j = az_el(lla, r_rx, rs_j)
        rho[:, j], dts[:, j], r_sat[:, j], az[:, j], el[:, j] = rho_j, dts_j, rs_j, az_j, el_j
        i1[:, j] = iono_l1(lla, az_j, el_j, t)
        trop[:, j] = s.tropo_scale * saastamoinen(lla[:, 0], lla[:, 2], el_j, s.humidity_fraction)
        if C_na is not None:
            el_a[:, j] = antenna_elevation(lla, C_na, r_rx, rs_j)
        up = np.flatnonzero(el_j >= s.elevation_mask_rad)
        geo, ion = [], []
        for tt, ll, rr in ends:
            tt, ll, rr = tt[up], ll[up], rr[up]
            rho_k, rs_k, dts_k = light_time(state, tt, rr)
            a_k, e_k = az_el(ll, rr, rs_k)
            tr_k = s.tropo_scale * saastamoinen(ll[:, 0], ll[:, 2], e_k, s.humidity_fraction)
            geo.append(rho_k - C_LIGHT * dts_k + tr_k)
            ion.append(iono_l1(ll, a_k, e_k, tt))
        rate[up, j] = (geo[0] - geo[1]) / (2.0 * h)
        irate[up, j] = (ion[0] - ion[1]) / (2.0 * h)
    return rho, dts, trop, el, az, el_a, i1, rate, irate, r_sat


def simulate_multi(orbits, week, time_rx, receiver, settings, rng, t_start=None):
    """Simulate raw multi-constellation, multi-frequency observations (module docstring).

    Parameters
    ----------
    orbits : MultiOrbits
    week : int
        GPS week of the times.
    time_rx : ndarray (n,)
        Receiver clock epochs, GPS s of week, evenly spaced.
    receiver : callable
        As :func:`ins.simulate.gnss_raw.simulate_raw`'s.
    settings : ins.simulate.gnss_raw.RawSettings
    rng : numpy.random.Generator
    t_start : float, optional
        Origin of the slips' and masks' times (default ``time_rx[0]``), s.

    Returns
    -------
    MultiObservations
    """
    s = settings
    time_rx = np.asarray(time_rx, dtype=float)
    n = len(time_rx)
    dt = float(np.median(np.diff(time_rx))) if n > 1 else 1.0
    t0 = time_rx[0] if t_start is None else float(t_start)
    bias, drift = clock_process(n, dt, s.clock_bias_s, s.clock_drift, s.clock_bias_noise,
                                s.clock_drift_noise, rng)
    t = time_rx - bias
    h = DOPPLER_STEP_S
    lla, r_rx, *attitude = receiver(t)
    ends = [(t + h, *receiver(t + h)[:2]), (t - h, *receiver(t - h)[:2])]
    C_na = attitude[0] if attitude else None
    alpha, beta = orbits.alpha, orbits.beta

    def iono_l1(ll, a, e, tt):
        if alpha is None or beta is None:
            return np.zeros(len(tt))
        return s.iono_scale * klobuchar(ll[:, 0], ll[:, 1], a, e, tt, alpha, beta)

    sats = orbits.sats
    m = len(sats)
    k = max(len(v) for v in orbits.signals.values())
    rho, dts, trop, el, az, el_a, i1, rate, irate, r_sat = _geometry(
        orbits, sats, week, t, lla, r_rx, C_na, ends, s, iono_l1)
    visible = np.isfinite(rho) & (el >= s.elevation_mask_rad)
    if C_na is not None:
        visible &= el_a >= s.antenna_mask_rad
    observed = _apply_masks(el, visible, time_rx - t0, s.masks)
    sin_el = np.sin(np.where(observed, el, _PI / 2))
    freq = np.full((m, k), np.nan)
    shape = (n, m, k)
    sat_clk = np.full(shape, np.nan)
    for j, sat in enumerate(sats):
        idx = orbits.signals[sat[0]]
        tgd = orbits.tgd(sat, week, t - rho[:, j] / C_LIGHT)
        for q, i in enumerate(idx):
            freq[j, q] = frequency_hz(sat[0], i, orbits.channel(sat))
            sat_clk[:, j, q] = C_LIGHT * (dts[:, j] + clock_offset(sat[0], i, tgd))
    has = np.isfinite(freq)[None, :, :] & observed[:, :, None]
    starts = _arc_starts(observed)
    amb = np.zeros(shape)
    lli = np.zeros(shape, dtype=int)
    for j in range(m):
        arc_id = np.cumsum(starts[:, j])
        for q in range(k):
            draws = rng.integers(-s.ambiguity_max, s.ambiguity_max + 1, size=arc_id[-1] + 1)
            amb[:, j, q] = draws[arc_id]
    lli[starts] = 1
    lli[0] = 0
    applied = _slips(s, time_rx, t0, dt, sats, observed, amb, lli)
    mp_code, mp_phase = np.empty(shape), np.empty(shape)
    for j in range(m):
        for q in range(k):
            mp_code[:, j, q] = _gauss_markov(n, dt, s.multipath_time_s, rng)
            mp_phase[:, j, q] = _gauss_markov(n, dt, s.multipath_time_s, rng)
    factors = dict(s.signal_noise)
    fac = np.ones((m, k))
    for j, sat in enumerate(sats):
        for q, i in enumerate(orbits.signals[sat[0]]):
            fac[j, q] = factors.get(SIGNALS[sat[0]][i][0], 1.0)
    se = sin_el[:, :, None] / fac[None, :, :]
    mp_code *= s.multipath_code_m / se
    mp_phase *= s.multipath_phase_m / se
    e_code = rng.standard_normal(shape) * s.sigma_code_m / se
    e_phase = rng.standard_normal(shape) * s.sigma_phase_m / se
    e_dop = rng.standard_normal(shape) * s.sigma_doppler_hz / se
    scale = (F_L1 / freq[None, :, :]) ** 2
    iono = i1[:, :, None] * scale
    lam = C_LIGHT / freq[None, :, :]
    base = rho[:, :, None] + C_LIGHT * bias[:, None, None] - sat_clk + trop[:, :, None]
    code = base + iono + mp_code + e_code
    phase = (base - iono + mp_phase + e_phase) / lam + amb
    # the signal's clock offset (GPS tgd) is constant: the rate is that of the L1 clock
    doppler = -(rate[:, :, None] - irate[:, :, None] * scale
                + C_LIGHT * drift[:, None, None]) / lam + e_dop
    snr = np.broadcast_to((s.cn0_horizon_dbhz + (s.cn0_zenith_dbhz - s.cn0_horizon_dbhz)
                           * sin_el)[:, :, None], shape).copy()
    for a in (code, phase, doppler, snr, mp_code, mp_phase, amb, iono, sat_clk):
        a[~has] = np.nan
    lli[~has] = 0
    return MultiObservations(
        week, time_rx, t, tuple(sats),
        {sy: tuple(SIGNALS[sy][i][0] for i in ix) for sy, ix in orbits.signals.items()},
        freq, code, phase, doppler, snr, lli, observed, rho, trop, el, az, el_a, sat_clk,
        iono, mp_code, mp_phase, amb, r_sat, bias, drift, r_rx, tuple(applied))


def _slips(s, time_rx, t0, dt, sats, observed, amb, lli):
    applied = []
    n = len(time_rx)
    for t_slip, prn, cycles in s.slips:
        i = int(np.argmin(np.abs(time_rx - (t0 + t_slip))))
        if abs(time_rx[i] - (t0 + t_slip)) > dt:
            raise InputError(f"[gnss_raw] slips: {t_slip:g} s is outside the observations "
                             f"({time_rx[0] - t0:g} to {time_rx[-1] - t0:g} s after the start)")
        cols = [j for j, sat in enumerate(sats) if prn == 0 or sat == f"G{int(prn):02d}"]
        for j in cols:
            if i == 0 or not (observed[i, j] and observed[i - 1, j]):
                continue
            end = i + int(np.argmax(~observed[i:, j])) if not observed[i:, j].all() else n
            amb[i:end, j] += cycles
            lli[i, j] = 1
            applied.append((float(time_rx[i]), sats[j], int(cycles)))
    return applied
