"""GLONASS broadcast orbits: PZ-90 state vectors integrated with the ICD's equations.

GLONASS ICD (edition 5.1, 2008), appendix A.3.1.2: the immediate information gives at
``tb`` the satellite's position ``(x, y, z)``, velocity and the luni-solar acceleration
``(x'', y'', z'')`` (constant over the interval) in the rotating PZ-90 frame; the position
at ``t`` is the numerical integration (Runge-Kutta 4) of::

    r = |x|,  mu~ = mu / r^2,  x~ = x / r, ...,  rho = a_e / r
    dv_x/dt = -mu~ x~ - 3/2 J2 mu~ x~ rho^2 (1 - 5 z~^2) + w^2 x + 2 w v_y + x''
    dv_y/dt = -mu~ y~ - 3/2 J2 mu~ y~ rho^2 (1 - 5 z~^2) + w^2 y - 2 w v_x + y''
    dv_z/dt = -mu~ z~ - 3/2 J2 mu~ z~ rho^2 (3 - 5 z~^2)              + z''

(the gravity of the Earth with its J2 term, the centrifugal and Coriolis accelerations of
the rotating frame) with ``mu = 398600.4418e9 m^3/s^2``, ``a_e = 6378136 m``,
``J2 = 1082625.75e-9``, ``w = 7.292115e-5 rad/s``.  The step here is
:data:`STEP_S` (RTKLIB's ``glorbit`` takes 60 s: both are far below the model's own
error; a time is integrated from the nearest of the ephemeris' states cached every
``STEP_S``).  The clock (ICD 3.3.3, ``t_b`` the reference)::

    dt_s = -tau_n + gamma_n (t - t_b)        (satellite time minus GLONASS time, s)

Time: GLONASS time is ``UTC(SU) + 3 h``, so ``GPST = GLONASST - 3 h + leap`` with
``leap = GPS - UTC`` of the date (:func:`leap_seconds`: the IERS table, not a constant).
RINEX 3 writes the ephemeris epoch ``t_b`` in UTC; inside the simulator every time is GPS.
The PZ-90.11 frame is taken as WGS84 (they agree to a few centimetres).

:func:`glonass_constellation` makes a plausible constellation: 24 satellites in 3 planes
(i = 64.8 deg, a = 25510 km, 8 slots per plane, the planes' arguments of latitude shifted
by 15 deg) with the frequency channels of the real slots, and an ephemeris every 30 min
(``t_b`` at 15 and 45 min past the hour, UTC).  Each ephemeris' state is the previous one
integrated to the midpoint between the two ``t_b`` (with the previous message's
luni-solar acceleration), then on to its ``t_b`` with its own: the two messages agree at
the midpoint, where the nearest-``t_b`` rule changes from one to the other, so the truth
is continuous there (to the 12 digits of RINEX).
"""
import datetime as _dt
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.io.rinex_nav import SECONDS_PER_WEEK
from ins.io.rtklib import LEAP_SECONDS
from ins.simulate.kepler_orbit import rinex_round

__all__ = ["MU_GLO", "AE_GLO", "J2_GLO", "OMEGA_GLO", "STEP_S", "MAX_AGE_S", "FREQ_CHANNELS",
           "GlonassEphemeris", "GlonassOrbits", "derivatives", "integrate",
           "glonass_constellation", "leap_seconds", "gps_to_utc", "glonass_frequencies"]

MU_GLO = 398600.4418e9
AE_GLO = 6378136.0
J2_GLO = 1082625.75e-9
OMEGA_GLO = 7.292115e-5
#: Runge-Kutta step of the simulator's integration, s.
STEP_S = 10.0
#: Largest ``|t - t_b|`` of a usable ephemeris (RTKLIB's MAXDTOE_GLO), s.
MAX_AGE_S = 1800.0
#: Frequency channel ``k`` of slots 1-24 (antipodal slots share a channel).
FREQ_CHANNELS = (1, -4, 5, 6, 1, -4, 5, 6, -2, -7, 0, -1, -2, -7, 0, -1, 4, -3, 3, 2, 4, -3,
                 3, 2)
_GPS_EPOCH = _dt.datetime(1980, 1, 6)


def glonass_frequencies(k):
    """G1 and G2 carrier frequencies of channel ``k``, Hz (ICD 3.3.1.4):
    ``f_G1 = 1602 MHz + k 0.5625 MHz``, ``f_G2 = 1246 MHz + k 0.4375 MHz``.
    """
    k = np.asarray(k, dtype=float)
    return 1602.0e6 + k * 0.5625e6, 1246.0e6 + k * 0.4375e6


def leap_seconds(gps_week, t_gps):
    """GPS - UTC at a GPS time, s (the table of :data:`ins.io.rtklib.LEAP_SECONDS`).

    The table is by UTC date; near a leap second the GPS date is within 18 s of the UTC
    date, which is checked with the result.
    """
    gps = _GPS_EPOCH + _dt.timedelta(seconds=float(gps_week * SECONDS_PER_WEEK + t_gps))
    leap = 0
    for y, m, d, n in LEAP_SECONDS:
        if gps - _dt.timedelta(seconds=n) >= _dt.datetime(y, m, d):
            leap = n
    return leap


def gps_to_utc(gps_week, t_gps):
    """The UTC ``datetime`` of a GPS time (whole-second leap from :func:`leap_seconds`)."""
    sec = float(gps_week * SECONDS_PER_WEEK + t_gps - leap_seconds(gps_week, t_gps))
    return _GPS_EPOCH + _dt.timedelta(seconds=sec)


@dataclass(frozen=True)
class GlonassEphemeris:
    """One GLONASS immediate-information set (SI units, PZ-90 frame).

    Attributes
    ----------
    slot : int
        Orbital slot (the RINEX ``Rnn`` number).
    k : int
        Frequency channel, -7..6.
    week, tb : int, float
        ``t_b`` as GPS week and s of week (GPS time; the ICD's ``t_b`` is GLONASS time,
        ``UTC(SU) + 3 h``).
    pos, vel, acc : tuple of 3 float
        PZ-90 position (m), velocity (m/s) and luni-solar acceleration (m/s^2) at ``t_b``.
    tau_n : float
        Clock offset, GLONASS time minus satellite time at ``t_b``, s.
    gamma_n : float
        Relative frequency offset, s/s.
    health : int
    """

    slot: int
    k: int
    week: int
    tb: float
    pos: tuple
    vel: tuple
    acc: tuple
    tau_n: float
    gamma_n: float
    health: int = 0

    @property
    def tb_utc(self):
        """``t_b`` in UTC (``datetime``; the RINEX epoch)."""
        return gps_to_utc(self.week, self.tb)

    @property
    def tb_glonass_tod(self):
        """``t_b`` as the ICD gives it: seconds of the day of GLONASS time
        (UTC(SU) + 3 h)."""
        u = self.tb_utc + _dt.timedelta(hours=3)
        return u.hour * 3600.0 + u.minute * 60.0 + u.second + u.microsecond * 1e-6


def derivatives(state, acc):
    """Time derivative of PZ-90 states ``(n, 6)`` (m, m/s) with luni-solar ``acc`` (n, 3)
    m/s^2: the equations of the module docstring."""
    x, y, z, vx, vy, vz = state.T
    r2 = x * x + y * y + z * z
    r = np.sqrt(r2)
    mu_t = MU_GLO / r2
    rho2 = AE_GLO ** 2 / r2
    zt2 = z * z / r2
    w2 = OMEGA_GLO ** 2
    c = 1.5 * J2_GLO * mu_t * rho2
    ax = -mu_t * x / r - c * x / r * (1.0 - 5.0 * zt2) + w2 * x + 2.0 * OMEGA_GLO * vy
    ay = -mu_t * y / r - c * y / r * (1.0 - 5.0 * zt2) + w2 * y - 2.0 * OMEGA_GLO * vx
    az = -mu_t * z / r - c * z / r * (3.0 - 5.0 * zt2)
    return np.column_stack([vx, vy, vz, ax + acc[:, 0], ay + acc[:, 1], az + acc[:, 2]])


def integrate(state0, acc, dt, step_s=STEP_S):
    """Runge-Kutta 4 from ``state0`` over ``dt`` seconds (either sign), each element in
    ``ceil(max |dt| / step_s)`` equal steps.

    Parameters
    ----------
    state0 : array_like, shape (6,) or (n, 6)
        PZ-90 position (m) and velocity (m/s) at the start: one for every ``dt``, or one
        per element.
    acc : array_like, shape (3,) or (n, 3)
        Luni-solar acceleration, m/s^2 (constant).
    dt : array_like, shape (n,)
        s.

    Returns
    -------
    ndarray (n, 6)
        PZ-90 position (m) and velocity (m/s).
    """
    s = np.asarray(state0, dtype=float)
    a = np.asarray(acc, dtype=float)
    if s.ndim == 1:
        dt = np.atleast_1d(np.asarray(dt, dtype=float))
        s, a = np.tile(s, (len(dt), 1)), np.tile(a, (len(dt), 1))
    else:
        dt = np.broadcast_to(np.asarray(dt, dtype=float), (len(s),))
        a = np.broadcast_to(a, s[:, :3].shape)
    steps = max(1, int(np.ceil(np.max(np.abs(dt)) / step_s))) if dt.size else 1
    h = (dt / steps)[:, None]
    for _ in range(steps):
        k1 = derivatives(s, a)
        k2 = derivatives(s + 0.5 * h * k1, a)
        k3 = derivatives(s + 0.5 * h * k2, a)
        k4 = derivatives(s + h * k3, a)
        s = s + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return s


class GlonassOrbits:
    """GLONASS ephemerides evaluable at GPS times (the nearest ``t_b`` within
    :data:`MAX_AGE_S`, RTKLIB's rule)."""

    def __init__(self, ephemerides):
        self.ephemerides = list(ephemerides)
        self._by_slot = {}
        for e in self.ephemerides:
            if e.health == 0:
                self._by_slot.setdefault(e.slot, []).append(e)
        self.system = "R"
        self._cache = {}

    def _nodes(self, e):
        """The ephemeris' states every :data:`STEP_S` from ``t_b - MAX_AGE_S`` to
        ``t_b + MAX_AGE_S`` (RK4 steps of ``STEP_S`` out from ``t_b``; cached): a time is
        integrated from its nearest node in one step of at most ``STEP_S / 2``."""
        key = (e.slot, e.week, e.tb)
        nodes = self._cache.get(key)
        if nodes is None:
            n = int(np.ceil(MAX_AGE_S / STEP_S)) + 1
            s = np.tile(np.r_[e.pos, e.vel], (2, 1))
            out = [s]
            for _ in range(n):
                s = integrate(s, e.acc, np.array([STEP_S, -STEP_S]))
                out.append(s)
            out = np.array(out)                          # (n + 1, 2, 6)
            nodes = np.concatenate([out[:0:-1, 1], out[:, 0]])
            self._cache[key] = nodes
        return nodes

    @property
    def prns(self):
        """Slots with at least one healthy ephemeris (sorted)."""
        return sorted(self._by_slot)

    def channel(self, slot):
        """Frequency channel ``k`` of a slot."""
        ephs = self._by_slot.get(slot)
        if not ephs:
            raise InputError(f"GLONASS slot {slot} has no ephemeris")
        return ephs[0].k

    def state(self, slot, week, t):
        """Satellite ``slot`` at GPS times ``t`` (s of GPS week ``week``).

        Returns
        -------
        r_e, v_e : ndarray (n, 3)
            PZ-90 (= WGS84) m, m/s; NaN where no ephemeris is valid.
        dt, ddt : ndarray (n,)
            Clock ``-tau_n + gamma_n (t - t_b)`` (s) and ``gamma_n``.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        r, v = np.full((len(t), 3), np.nan), np.full((len(t), 3), np.nan)
        dt, ddt = np.full(len(t), np.nan), np.full(len(t), np.nan)
        ephs = self._by_slot.get(slot, [])
        if not ephs:
            return r, v, dt, ddt
        tb = np.array([(e.week - week) * SECONDS_PER_WEEK + e.tb for e in ephs])
        age = np.abs(t[:, None] - tb[None, :])
        k = np.argmin(age, axis=1)
        k[age[np.arange(len(t)), k] > MAX_AGE_S] = -1
        for j in np.unique(k[k >= 0]):
            m = k == j
            e = ephs[j]
            d = t[m] - tb[j]
            nodes = self._nodes(e)
            i = np.clip(np.round(d / STEP_S).astype(int), -len(nodes) // 2, len(nodes) // 2)
            s = integrate(nodes[i + len(nodes) // 2], e.acc, d - i * STEP_S)
            r[m], v[m] = s[:, :3], s[:, 3:]
            dt[m] = -e.tau_n + e.gamma_n * d
            ddt[m] = e.gamma_n
        return r, v, dt, ddt


def _luni_solar(t_cont, phase):
    """Slowly varying luni-solar accelerations (plausible size, about 2e-6 m/s^2), one
    row per phase, m/s^2."""
    w = 2 * np.pi / 86400.0
    phase = np.asarray(phase, dtype=float)
    return np.column_stack([2.0e-6 * np.sin(w * t_cont + phase),
                            1.5e-6 * np.cos(w * t_cont + 2 * phase),
                            1.0e-6 * np.sin(0.5 * w * t_cont + 3 * phase)])


def glonass_constellation(gps_week, t_first, t_last, seed=1982):
    """A plausible 24-satellite GLONASS constellation (module docstring).

    Parameters
    ----------
    gps_week : int
    t_first, t_last : float
        The span to cover, GPS s of week ``gps_week`` (ephemerides from 45 min before to
        45 min after).
    seed : int
        Seed of the clocks and the orbits' phase.

    Returns
    -------
    list of GlonassEphemeris
    """
    rng = np.random.default_rng(seed)
    t0 = gps_week * SECONDS_PER_WEEK
    leap = leap_seconds(gps_week, t_first)
    # t_b: 15 and 45 min past the UTC hour, as GPS continuous seconds
    grid = 1800.0 * np.arange(np.floor((t0 + t_first - leap - 900.0 - 2700.0) / 1800.0),
                              np.ceil((t0 + t_last - leap - 900.0 + 2700.0) / 1800.0) + 1)
    tbs = grid + 900.0 + leap
    a, inc = 25510.0e3, np.deg2rad(64.8)
    n = np.sqrt(MU_GLO / a ** 3)
    theta0 = rng.uniform(0, 2 * np.pi)
    states = []
    for slot in range(1, 25):
        p, q = divmod(slot - 1, 8)
        u = 2 * np.pi * q / 8 + np.deg2rad(15.0) * p
        # inertial (the frame that coincides with PZ-90 at the first t_b) -> rotating
        R = _rz(theta0 + 2 * np.pi * p / 3) @ _rx(inc)
        r_i = a * (R @ [np.cos(u), np.sin(u), 0.0])
        v_i = a * n * (R @ [-np.sin(u), np.cos(u), 0.0])
        states.append(np.r_[r_i, v_i - np.cross([0.0, 0.0, OMEGA_GLO], r_i)])
    state = np.array(states)
    tau0 = rng.uniform(-3e-4, 3e-4, 24)
    gamma = np.array([rinex_round(g) for g in rng.uniform(-2e-12, 2e-12, 24)])
    phase = rng.uniform(0, 2 * np.pi, 24)
    out = []
    t_prev = tbs[0]
    for tb in tbs:
        acc = _luni_solar(tb, phase)
        if tb != t_prev:             # the previous message to the midpoint, this one on
            mid = 0.5 * (t_prev + tb)
            state = integrate(state, _luni_solar(t_prev, phase), mid - t_prev)
            state = integrate(state, acc, tb - mid)
        # the file holds km with 12 digits: the truth is what it holds
        state = np.vectorize(rinex_round)(state / 1e3) * 1e3
        acc = np.vectorize(rinex_round)(acc / 1e3) * 1e3
        week = int(tb // SECONDS_PER_WEEK)
        for j in range(24):
            out.append(GlonassEphemeris(
                slot=j + 1, k=FREQ_CHANNELS[j], week=week,
                tb=float(tb - week * SECONDS_PER_WEEK), pos=tuple(state[j, :3]),
                vel=tuple(state[j, 3:]), acc=tuple(acc[j]),
                tau_n=rinex_round(tau0[j] - gamma[j] * (tb - tbs[0])), gamma_n=float(gamma[j])))
        t_prev = tb
    return sorted(out, key=lambda e: (e.slot, e.week, e.tb))


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
