"""Raw GPS L1 observations of a moving receiver from real broadcast orbits, with known truth.

For each epoch (receiver clock time ``t_rx``, GPS s of week) and each GPS satellite of the
navigation file above the elevation mask, with ``lambda = c / 1575.42 MHz``::

    t         = t_rx - dt_r                   true GPS time of reception (dt_r: receiver clock)
    rho       = |Rz(w_ie tau) r_s(t - tau) - r_r(t)|,  tau = rho / c     (light time, Sagnac)
    P  = rho + c (dt_r - dt_s) + I + T + m_P + e_P                        (C1C, m)
    L  = (rho + c (dt_r - dt_s) - I + T + m_L + e_L) / lambda + N         (L1C, cycles)
    D  = -(d/dt [rho - c dt_s - I + T] + c d(dt_r)/dt) / lambda + e_D      (D1C, Hz)

- ``r_r``: the antenna in ECEF (m), ``r_s``, ``dt_s``: the satellite's ECEF position (the
  WGS84 frame at transmit time, rotated by ``w_ie tau`` into the frame at reception) and
  L1 C/A clock (``dt_sv - tgd``, s) of :mod:`ins.simulate.gps_orbit` at the transmit time;
- ``dt_r``: receiver clock bias (s), integrating a drift (s/s) with random walks on both
  (the two-state clock model); the epoch is stamped in receiver time, so the receiver
  sits at its true position at ``t``;
- ``I``: Klobuchar L1 group delay (IS-GPS-200 20.3.3.5.2.5) from the navigation header's
  alpha/beta, times ``iono_scale``; ``T``: Saastamoinen troposphere (standard atmosphere,
  relative humidity ``humidity_fraction``) times ``tropo_scale``;
- ``m_P``, ``m_L``: multipath-like errors, per satellite a first-order Gauss-Markov process
  of time constant ``multipath_time_s`` and standard deviation
  ``multipath_*_m / sin(el)``; ``e_P``, ``e_L``, ``e_D``: white noise of standard deviation
  ``sigma_* / sin(el)``; the Doppler carries no multipath;
- ``N``: an integer ambiguity per arc (new at each acquisition), changed by the chosen
  cycle slips; the loss-of-lock indicator (LLI bit 0) is set at the first epoch of every
  arc after the file's first epoch and at each slip;
- masked satellites: in the spans of the mask schedule only the ``n`` highest satellites
  above the elevation mask are observed (all of them if fewer are in view);
- the vehicle: with its attitude, satellites below ``antenna_mask_rad`` above its x-y plane
  are hidden (an aircraft banking 25 deg loses the low satellites on the outside of the
  turn); a satellite coming back starts a new arc;
- ``S1C``: C/N0 = ``cn0_horizon + (cn0_zenith - cn0_horizon) sin(el)``, dB-Hz.

The derivative in ``D`` is a central difference over +-:data:`DOPPLER_STEP_S` of the
error-free model (light time included) at receiver positions evaluated at those times;
the receiver clock contributes its drift.  Frames: ECEF WGS84 (m, m/s); angles rad
inside; times GPS s of week of ``week``.
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.nav.earth import dcm_en
from ins.simulate.gps_orbit import C_LIGHT, OMEGA_E_GPS

__all__ = ["L1_HZ", "L1_WAVELENGTH", "DOPPLER_STEP_S", "RawSettings", "RawObservations",
           "light_time", "az_el", "antenna_elevation", "klobuchar", "saastamoinen", "clock_process",
           "simulate_raw", "dops"]

#: GPS L1 carrier frequency, Hz.
L1_HZ = 1575.42e6
#: GPS L1 wavelength, m.
L1_WAVELENGTH = C_LIGHT / L1_HZ
#: Half step of the central difference of the Doppler, s.
DOPPLER_STEP_S = 0.05
_PI = np.pi


@dataclass(frozen=True)
class RawSettings:
    """Settings of the raw observations (SI inside; the plan's ``[gnss_raw]`` keys).

    Attributes
    ----------
    nav_file : str
        RINEX 2/3 GPS navigation file (broadcast orbits, Klobuchar coefficients).
    rate_hz : float
        Observation rate, Hz.
    elevation_mask_rad : float
        rad.
    sigma_code_m, sigma_phase_m : float
        White noise at zenith, m (divided by sin(el)).
    sigma_doppler_hz : float
        White Doppler noise at zenith, Hz.
    multipath_code_m, multipath_phase_m : float
        Multipath-like error at zenith, m (standard deviation, divided by sin(el)).
    multipath_time_s : float
        Its correlation time, s.
    clock_bias_s, clock_drift : float
        Receiver clock bias (s) and drift (s/s) at the first epoch.
    clock_bias_noise, clock_drift_noise : float
        Random-walk densities of bias (s/sqrt(s)) and drift (1/sqrt(s)).
    iono_scale, tropo_scale : float
        Factors on the Klobuchar and Saastamoinen delays injected (1: the models exactly).
    humidity_fraction : float
        Relative humidity of the troposphere model, 0-1.
    antenna_mask_rad : float
        Satellites below this elevation in the vehicle's frame (the antenna's horizon,
        tilted with the attitude of the aircraft) are hidden by the vehicle, rad.
    cn0_zenith_dbhz, cn0_horizon_dbhz : float
        C/N0 at zenith and at the horizon, dB-Hz.
    ambiguity_max : int
        Ambiguities are drawn uniformly from [-ambiguity_max, ambiguity_max], cycles.
    slips : tuple of (float, int, int)
        ``(time_s after the flight start, prn (0: every satellite), cycles)``.
    masks : tuple of (float, float, int)
        ``(start_s after the flight start, duration_s, n_satellites)``.
    base_lla : tuple of 3 float or None
        A static base station (lat, lon rad, ellipsoidal h m) observed as well (the
        flight folder's ``base.obs``), or None.
    systems : tuple of str
        Constellations of ``G R E C`` (GPS, GLONASS, Galileo, BeiDou).  Anything but GPS
        alone, or more signals than L1, makes the observations those of
        :mod:`ins.simulate.gnss_multi` (GPS from ``nav_file``, the others generated:
        :mod:`ins.simulate.kepler_orbit`, :mod:`ins.simulate.glonass_orbit`).
    signals : tuple of str
        Signals of :data:`ins.simulate.gnss_signals.SIGNALS` (``L1 L2 L5 E1 E5a G1 G2 B1I
        B2a B3I``); empty: the first of each system.
    beidou_geo : bool
        Include BeiDou's five GEO satellites.
    signal_noise : tuple of (str, float)
        ``(signal name, factor)``: the signal's white noise and multipath (code, phase,
        Doppler) are those above times the factor (default 1 for every signal).
    """

    nav_file: str = ""
    rate_hz: float = 1.0
    elevation_mask_rad: float = np.deg2rad(10.0)
    sigma_code_m: float = 0.3
    sigma_phase_m: float = 0.002
    sigma_doppler_hz: float = 0.05
    multipath_code_m: float = 0.3
    multipath_phase_m: float = 0.003
    multipath_time_s: float = 60.0
    clock_bias_s: float = 1e-4
    clock_drift: float = 1e-8
    clock_bias_noise: float = 3e-10
    clock_drift_noise: float = 6e-10
    iono_scale: float = 1.0
    tropo_scale: float = 1.0
    humidity_fraction: float = 0.7
    cn0_zenith_dbhz: float = 50.0
    cn0_horizon_dbhz: float = 35.0
    antenna_mask_rad: float = 0.0
    ambiguity_max: int = 1000
    slips: tuple = ()
    masks: tuple = ()
    base_lla: tuple | None = None
    systems: tuple = ("G",)
    signals: tuple = ()
    beidou_geo: bool = True
    signal_noise: tuple = ()

    @property
    def multi(self):
        """Whether the settings ask for more than GPS L1 (:mod:`ins.simulate.gnss_multi`)."""
        return tuple(self.systems) != ("G",) or any(x != "L1" for x in self.signals)


@dataclass(frozen=True)
class RawObservations:
    """Simulated observations and their truth; arrays (n epochs, m satellites), NaN where
    a satellite is not observed.

    Attributes
    ----------
    week : int
    time_rx : ndarray (n,)
        Epochs in receiver clock time (the RINEX epochs), GPS s of week.
    time_gps : ndarray (n,)
        True GPS time of reception, s.
    prns : ndarray (m,)
    code, phase, doppler, snr : ndarray (n, m)
        m, cycles, Hz, dB-Hz.
    lli : ndarray of int (n, m)
    observed : ndarray of bool (n, m)
    rho, sat_clock_m, iono_m, tropo_m, mp_code_m, mp_phase_m : ndarray (n, m)
        Geometric range with Sagnac, ``c dt_s``, ionosphere (group delay), troposphere,
        multipath of code and phase; m.
    ambiguity : ndarray (n, m)
        Integer ambiguity, cycles.
    elevation, azimuth : ndarray (n, m)
        rad, at the receiver.
    elevation_antenna : ndarray (n, m)
        Elevation above the vehicle's horizontal plane (its x-y plane, FRD), rad; NaN
        without the vehicle's attitude.
    r_sat_e : ndarray (n, m, 3)
        Satellite at transmit time in the ECEF frame at reception, m.
    clock_bias_s, clock_drift : ndarray (n,)
        Receiver clock, s and s/s.
    r_rx_e : ndarray (n, 3)
        Antenna, ECEF, m.
    slips : tuple of (float, int, int)
        The slips made: ``(time_rx, prn, cycles)`` (a slip of a satellite not tracked
        across its epoch is not made).
    """

    week: int
    time_rx: np.ndarray
    time_gps: np.ndarray
    prns: np.ndarray
    code: np.ndarray
    phase: np.ndarray
    doppler: np.ndarray
    snr: np.ndarray
    lli: np.ndarray
    observed: np.ndarray
    rho: np.ndarray
    sat_clock_m: np.ndarray
    iono_m: np.ndarray
    tropo_m: np.ndarray
    mp_code_m: np.ndarray
    mp_phase_m: np.ndarray
    ambiguity: np.ndarray
    elevation: np.ndarray
    azimuth: np.ndarray
    elevation_antenna: np.ndarray
    r_sat_e: np.ndarray
    clock_bias_s: np.ndarray
    clock_drift: np.ndarray
    r_rx_e: np.ndarray
    slips: tuple = ()


def light_time(sat_state, t, r_rx_e, iterations=4):
    """Geometric range with the light time and the Earth's rotation during it (Sagnac).

    Parameters
    ----------
    sat_state : callable
        ``sat_state(t_tx) -> (r_e (n, 3) m, dt_s (n,) s)``: the satellite in the ECEF
        frame at GPS times ``t_tx`` and its clock.
    t : ndarray (n,)
        GPS time of reception, s.
    r_rx_e : ndarray (n, 3)
        Receiver, ECEF at ``t``, m.

    Returns
    -------
    rho : ndarray (n,)
        ``|Rz(w_ie tau) r_s(t - tau) - r_rx_e|``, m, with ``tau = rho / c``.
    r_sat : ndarray (n, 3)
        ``Rz(w_ie tau) r_s(t - tau)``: the satellite in the ECEF frame at reception, m.
    dt_s : ndarray (n,)
        Satellite clock at transmit time, s.

    The fixed-point iteration ``tau <- rho(tau) / c`` contracts by ``|d rho/dt| / c``
    (< 3e-6): from 75 ms, four iterations leave < 1e-9 m.
    """
    tau = np.full(len(t), 0.075)
    for _ in range(iterations):
        r_s, dt_s = sat_state(t - tau)
        th = OMEGA_E_GPS * tau
        c, s = np.cos(th), np.sin(th)
        r_sat = np.column_stack([c * r_s[:, 0] + s * r_s[:, 1],
                                 -s * r_s[:, 0] + c * r_s[:, 1], r_s[:, 2]])
        rho = np.linalg.norm(r_sat - r_rx_e, axis=1)
        tau = rho / C_LIGHT
    return rho, r_sat, dt_s


def antenna_elevation(lla, C_na, r_rx_e, r_sat_e):
    """Elevation of satellites above the vehicle's x-y plane (FRD: up is -z), rad.

    ``lla`` (n, 3) rad, rad, m; ``C_na`` (n, 3, 3) vehicle (FRD) to NED; ``r_rx_e``,
    ``r_sat_e`` (n, 3) ECEF m.
    """
    los = r_sat_e - r_rx_e
    los_n = np.einsum("nji,nj->ni", dcm_en(lla[:, 0], lla[:, 1]), los)
    los_a = np.einsum("nji,nj->ni", C_na, los_n)
    return np.arcsin(-los_a[:, 2] / np.linalg.norm(los_a, axis=1))


def az_el(lla, r_rx_e, r_sat_e):
    """Azimuth (clockwise from north) and elevation of satellites, rad.

    ``lla`` (n, 3) rad, rad, m; ``r_rx_e``, ``r_sat_e`` (n, 3) ECEF m.
    """
    los = r_sat_e - r_rx_e
    los_n = np.einsum("nji,nj->ni", dcm_en(lla[:, 0], lla[:, 1]), los)
    dist = np.linalg.norm(los_n, axis=1)
    return np.arctan2(los_n[:, 1], los_n[:, 0]) % (2 * _PI), np.arcsin(-los_n[:, 2] / dist)


def klobuchar(lat, lon, az, el, t_gps, alpha, beta):
    """Klobuchar L1 ionospheric group delay (IS-GPS-200 20.3.3.5.2.5), m.

    Parameters
    ----------
    lat, lon : array_like
        Receiver geodetic latitude and longitude, rad.
    az, el : array_like
        Satellite azimuth and elevation, rad.
    t_gps : array_like
        GPS time, s of week (only the time of day matters).
    alpha, beta : sequence of 4 float
        Broadcast coefficients (s, s/semicircle, ...).
    """
    E = np.asarray(el) / _PI                                   # semicircles
    psi = 0.0137 / (E + 0.11) - 0.022
    phi_i = np.clip(np.asarray(lat) / _PI + psi * np.cos(az), -0.416, 0.416)
    lam_i = np.asarray(lon) / _PI + psi * np.sin(az) / np.cos(phi_i * _PI)
    phi_m = phi_i + 0.064 * np.cos((lam_i - 1.617) * _PI)
    t = np.mod(4.32e4 * lam_i + np.asarray(t_gps), 86400.0)
    F = 1.0 + 16.0 * (0.53 - E) ** 3
    amp = np.maximum(sum(a * phi_m ** k for k, a in enumerate(alpha)), 0.0)
    per = np.maximum(sum(b * phi_m ** k for k, b in enumerate(beta)), 72000.0)
    x = 2.0 * _PI * (t - 50400.0) / per
    delay = np.where(np.abs(x) < 1.57, F * (5e-9 + amp * (1.0 - x ** 2 / 2.0 + x ** 4 / 24.0)),
                     F * 5e-9)
    return C_LIGHT * delay


def saastamoinen(lat, h, el, humidity_fraction=0.7):
    """Saastamoinen slant troposphere delay, m (hydrostatic + wet, 1/cos(z) mapping).

    Standard atmosphere at the receiver's height ``h`` (m; clipped to [0, 10 km])::

        P = 1013.25 (1 - 2.2557e-5 h)^5.2568 hPa,  T = 15 - 6.5e-3 h + 273.16 K
        e = 6.108 humidity_fraction exp((17.15 T - 4684) / (T - 38.45)) hPa
        T_d = 0.0022768 P / (1 - 0.00266 cos 2 lat - 0.00028 h_km) / cos z
        T_w = 0.002277 (1255 / T + 0.05) e / cos z

    (Saastamoinen 1972, the form of RTKLIB's ``tropmodel``), ``z = pi/2 - el``.
    """
    hgt = np.clip(np.asarray(h, dtype=float), 0.0, 1e4)
    P = 1013.25 * (1.0 - 2.2557e-5 * hgt) ** 5.2568
    T = 15.0 - 6.5e-3 * hgt + 273.16
    e = 6.108 * humidity_fraction * np.exp((17.15 * T - 4684.0) / (T - 38.45))
    cos_z = np.cos(_PI / 2.0 - np.asarray(el))
    dry = 0.0022768 * P / (1.0 - 0.00266 * np.cos(2.0 * np.asarray(lat)) - 0.00028 * hgt / 1e3)
    wet = 0.002277 * (1255.0 / T + 0.05) * e
    return (dry + wet) / cos_z


def clock_process(n, dt, bias0, drift0, bias_noise, drift_noise, rng):
    """Two-state receiver clock at ``n`` epochs ``dt`` s apart: bias (s), drift (s/s).

    ``b[k+1] = b[k] + d[k] dt + w_b``, ``d[k+1] = d[k] + w_d`` with
    ``std(w_b) = bias_noise sqrt(dt)``, ``std(w_d) = drift_noise sqrt(dt)``.
    """
    w_d = rng.standard_normal(n) * drift_noise * np.sqrt(dt)
    w_b = rng.standard_normal(n) * bias_noise * np.sqrt(dt)
    drift = drift0 + np.concatenate([[0.0], np.cumsum(w_d[:-1])])
    bias = bias0 + np.concatenate([[0.0], np.cumsum(drift[:-1] * dt + w_b[:-1])])
    return bias, drift


def _gauss_markov(n, dt, tau, rng):
    """Unit-variance first-order Gauss-Markov sequence (stationary start)."""
    from scipy.signal import lfilter
    phi = np.exp(-dt / tau)
    w = rng.standard_normal(n) * np.sqrt(1.0 - phi ** 2)
    w[0] = rng.standard_normal()                  # x[0] ~ N(0, 1), x[k] = phi x[k-1] + w[k]
    return lfilter([1.0], [1.0, -phi], w)


def _arc_starts(observed):
    prev = np.vstack([np.zeros((1, observed.shape[1]), bool), observed[:-1]])
    return observed & ~prev


def _apply_masks(el, visible, time_rel, masks):
    """Keep only the ``n`` highest visible satellites in the mask spans."""
    out = visible.copy()
    for start, duration, n in masks:
        rows = np.flatnonzero((time_rel >= start) & (time_rel < start + duration))
        for i in rows:
            cols = np.flatnonzero(visible[i])
            if len(cols) > n:
                keep = cols[np.argsort(-el[i, cols])[:n]]
                out[i] = False
                out[i, keep] = True
    return out


def simulate_raw(orbits, week, time_rx, receiver, settings, rng, t_start=None, alpha=None,
                 beta=None):
    """Simulate raw L1 observations (module docstring).

    Parameters
    ----------
    orbits : ins.simulate.gps_orbit.BroadcastOrbits
    week : int
        GPS week of the times.
    time_rx : ndarray (n,)
        Epochs in receiver clock time, GPS s of week, evenly spaced.
    receiver : callable
        ``receiver(t) -> (lla (n, 3) rad rad m, r_e (n, 3) m[, C_na (n, 3, 3)])``: the
        antenna at true GPS times ``t`` and, optionally, the attitude of the vehicle that
        carries it (``C_na``: aircraft FRD to NED), whose body hides the satellites below
        ``antenna_mask_rad`` in its own frame (the antenna's horizon tilts with the bank).
    settings : RawSettings
    rng : numpy.random.Generator
    t_start : float, optional
        Origin of the times of the slips and masks (default ``time_rx[0]``), s.
    alpha, beta : sequence of 4 float, optional
        Klobuchar coefficients (default: the navigation file's; none: no ionosphere).

    Returns
    -------
    RawObservations
    """
    s = settings
    time_rx = np.asarray(time_rx, dtype=float)
    n = len(time_rx)
    dt = float(np.median(np.diff(time_rx))) if n > 1 else 1.0
    t0 = time_rx[0] if t_start is None else float(t_start)
    alpha = orbits.nav.ion_alpha if alpha is None else alpha
    beta = orbits.nav.ion_beta if beta is None else beta
    bias, drift = clock_process(n, dt, s.clock_bias_s, s.clock_drift, s.clock_bias_noise,
                                s.clock_drift_noise, rng)
    t = time_rx - bias
    h = DOPPLER_STEP_S
    lla, r_rx, *attitude = receiver(t)
    lla_p, r_p = receiver(t + h)[:2]
    lla_m, r_m = receiver(t - h)[:2]
    C_na = attitude[0] if attitude else None
    prns = np.array(orbits.prns, dtype=int)
    m = len(prns)
    shape = (n, m)
    rho, dts, iono, trop, el, az, el_a = (np.full(shape, np.nan) for _ in range(7))
    rate = np.full(shape, np.nan)
    r_sat = np.full((n, m, 3), np.nan)

    def delays(lla_, az_, el_, t_):
        i_ = 0.0 if alpha is None or beta is None else \
            s.iono_scale * klobuchar(lla_[:, 0], lla_[:, 1], az_, el_, t_, alpha, beta)
        return i_, s.tropo_scale * saastamoinen(lla_[:, 0], lla_[:, 2], el_,
                                                s.humidity_fraction)

    for j, prn in enumerate(prns):
        def state(tt, prn=prn):
            r, _, c, _ = orbits.state(prn, week, tt)
            return r, c
        rho_j, rs_j, dts_j = light_time(state, t, r_rx)
        if np.all(np.isnan(rho_j)):
            continue
        az_j, el_j = az_el(lla, r_rx, rs_j)
        io_j, tr_j = delays(lla, az_j, el_j, t)
        rho[:, j], dts[:, j], r_sat[:, j] = rho_j, C_LIGHT * dts_j, rs_j
        az[:, j], el[:, j], iono[:, j], trop[:, j] = az_j, el_j, io_j, tr_j
        if C_na is not None:
            el_a[:, j] = antenna_elevation(lla, C_na, r_rx, rs_j)
        up = np.flatnonzero(el_j >= s.elevation_mask_rad)     # the Doppler where it is used
        ends = []
        for tt, ll, rr in ((t + h, lla_p, r_p), (t - h, lla_m, r_m)):
            tt, ll, rr = tt[up], ll[up], rr[up]
            rho_k, rs_k, dts_k = light_time(state, tt, rr)
            a_k, e_k = az_el(ll, rr, rs_k)
            io_k, tr_k = delays(ll, a_k, e_k, tt)
            ends.append(rho_k - C_LIGHT * dts_k - io_k + tr_k)
        rate[up, j] = (ends[0] - ends[1]) / (2.0 * h)
    visible = np.isfinite(rho) & (el >= s.elevation_mask_rad)
    if C_na is not None:
        visible &= el_a >= s.antenna_mask_rad
    observed = _apply_masks(el, visible, time_rx - t0, s.masks)
    sin_el = np.sin(np.where(observed, el, _PI / 2))
    # ambiguities per arc, slips
    starts = _arc_starts(observed)
    amb = np.zeros(shape)
    lli = np.zeros(shape, dtype=int)
    for j in range(m):
        arc_id = np.cumsum(starts[:, j])              # 0 before the first arc
        draws = rng.integers(-s.ambiguity_max, s.ambiguity_max + 1, size=arc_id[-1] + 1)
        amb[:, j] = draws[arc_id]
    lli[starts] = 1
    lli[0] = 0
    applied = []
    for t_slip, prn, cycles in s.slips:
        k = int(np.argmin(np.abs(time_rx - (t0 + t_slip))))
        if abs(time_rx[k] - (t0 + t_slip)) > dt:
            raise InputError(f"[gnss_raw] slips: {t_slip:g} s is outside the observations "
                             f"({time_rx[0] - t0:g} to {time_rx[-1] - t0:g} s after the start)")
        cols = range(m) if prn == 0 else np.flatnonzero(prns == prn)
        for j in cols:
            if k == 0 or not (observed[k, j] and observed[k - 1, j]):
                continue                  # not tracked across the epoch: no slip to make
            arc_end = k + int(np.argmax(~observed[k:, j])) if not observed[k:, j].all() else n
            amb[k:arc_end, j] += cycles
            lli[k, j] = 1
            applied.append((float(time_rx[k]), int(prns[j]), int(cycles)))
    # multipath and noise
    mp_code = np.empty(shape)
    mp_phase = np.empty(shape)
    for j in range(m):
        mp_code[:, j] = _gauss_markov(n, dt, s.multipath_time_s, rng)
        mp_phase[:, j] = _gauss_markov(n, dt, s.multipath_time_s, rng)
    mp_code *= s.multipath_code_m / sin_el
    mp_phase *= s.multipath_phase_m / sin_el
    e_code = rng.standard_normal(shape) * s.sigma_code_m / sin_el
    e_phase = rng.standard_normal(shape) * s.sigma_phase_m / sin_el
    e_dop = rng.standard_normal(shape) * s.sigma_doppler_hz / sin_el
    clk = C_LIGHT * bias[:, None]
    code = rho + clk - dts + iono + trop + mp_code + e_code
    phase = (rho + clk - dts - iono + trop + mp_phase + e_phase) / L1_WAVELENGTH + amb
    doppler = -(rate + C_LIGHT * drift[:, None]) / L1_WAVELENGTH + e_dop
    snr = s.cn0_horizon_dbhz + (s.cn0_zenith_dbhz - s.cn0_horizon_dbhz) * sin_el
    hide = ~observed
    for a in (code, phase, doppler, snr, mp_code, mp_phase, amb):
        a[hide] = np.nan
    lli[hide] = 0
    return RawObservations(week, time_rx, t, prns, code, phase, doppler, snr, lli, observed,
                           rho, dts, iono, trop, mp_code, mp_phase, amb, el, az, el_a, r_sat,
                           bias, drift, r_rx, tuple(applied))


def dops(az, el):
    """Dilution of precision of the satellites at one epoch (NED geometry + clock).

    Parameters
    ----------
    az, el : array_like (k,)
        rad.

    Returns
    -------
    dict
        ``gdop, pdop, hdop, vdop, tdop`` (NaN with fewer than 4 satellites).
    """
    az, el = np.asarray(az, float), np.asarray(el, float)
    if len(az) < 4:
        return dict.fromkeys(("gdop", "pdop", "hdop", "vdop", "tdop"), np.nan)
    H = np.column_stack([-np.cos(el) * np.cos(az), -np.cos(el) * np.sin(az), np.sin(el),
                         np.ones_like(az)])
    Q = np.linalg.inv(H.T @ H)
    d = np.diag(Q)
    return {"gdop": float(np.sqrt(d.sum())), "pdop": float(np.sqrt(d[:3].sum())),
            "hdop": float(np.sqrt(d[:2].sum())), "vdop": float(np.sqrt(d[2])),
            "tdop": float(np.sqrt(d[3]))}
