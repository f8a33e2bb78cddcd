"""Galileo and BeiDou broadcast orbits (Keplerian, like GPS) and plausible constellations.

The simulator's own implementation of the user algorithms (independent of RTKLIB, which
``tests/test_gnss_multi.py`` compares at the millimetre level):

- Galileo OS SIS ICD 5.1.1 (Table 58-60): the algorithm of IS-GPS-200 Table 20-IV with
  ``mu = 3.986004418e14 m^3/s^2``, ``w_e = 7.2921151467e-5 rad/s``; Galileo System Time
  is aligned with GPS time (the week of RINEX 3 is the GPS week);
- BeiDou ICD B1I 3.0 (5.2.4.12, Table 5-11): the same with CGCS2000's
  ``mu = 3.986004418e14``, ``w_e = 7.292115e-5``, in BeiDou time ``BDT = GPST - 14 s``
  (BDT week 0 began at GPS week 1356), for MEO and IGSO satellites.  The GEO satellites
  (PRN 1-5 and 59-63) have the ICD's own rotation: with ``Omega = omega0 +
  omega_dot t_k - w_e toe`` (no Earth rotation over ``t_k``) and ``(x_g, y_g, z_g) =
  Rz(-Omega) Rx(-i) (r cos u, r sin u, 0)`` in a frame tilted by 5 deg::

      r_e = R_Z(w_e t_k) R_X(-5 deg) (x_g, y_g, z_g),
      R_X(phi) = [[1, 0, 0], [0, cos phi, sin phi], [0, -sin phi, cos phi]],
      R_Z(phi) = [[cos phi, sin phi, 0], [-sin phi, cos phi, 0], [0, 0, 1]].

Everything else (Kepler's equation, harmonic corrections, the clock polynomial with the
relativistic term ``F e sqrt_a sin E``, ``F = -2 sqrt(mu) / c^2``) is that of
:mod:`ins.simulate.gps_orbit`.  The group delays (Galileo BGD, BeiDou TGD) of the
generated constellations are zero, so the broadcast clock is that of every signal.

:func:`galileo_constellation` and :func:`beidou_constellation` make plausible
constellations (Walker 24/3/1 MEOs, BeiDou's 3 IGSOs over 118 deg E and optionally its
GEOs) whose ephemerides, one every ``step_s``, describe one and the same orbit and clock
(the elements of each are those of the first propagated to its ``toe``), so that the
truth is continuous whichever ephemeris a receiver selects.  Every value is rounded to
the 12 digits of RINEX's ``D19.12`` so that the written file holds the simulator's orbit.
"""
from dataclasses import dataclass, replace

import numpy as np

from ins.common.errors import InputError
from ins.io.rinex_nav import SECONDS_PER_WEEK
from ins.simulate.gps_orbit import C_LIGHT, eccentric_anomaly

__all__ = ["KeplerEphemeris", "KeplerOrbits", "SYSTEM_CONSTANTS", "BDT_MINUS_GPST_S",
           "BDT_WEEK0_GPS", "kepler_state", "galileo_constellation", "beidou_constellation",
           "is_beidou_geo", "rinex_round", "to_system_time"]

#: (mu m^3/s^2, w_e rad/s) of each system's ICD.
SYSTEM_CONSTANTS = {"E": (3.986004418e14, 7.2921151467e-5), "C": (3.986004418e14, 7.292115e-5)}
#: BDT - GPST, s.
BDT_MINUS_GPST_S = -14.0
#: GPS week of BDT week 0 (2006-01-01 00:00:00 UTC).
BDT_WEEK0_GPS = 1356
_SIN5, _COS5 = np.sin(np.deg2rad(-5.0)), np.cos(np.deg2rad(-5.0))


def rinex_round(value):
    """``value`` as RINEX's ``D19.12`` holds it (12 digits after the point)."""
    return float(f"{float(value):.12E}")


@dataclass(frozen=True)
class KeplerEphemeris:
    """One Galileo or BeiDou broadcast ephemeris (SI units, ICD names).

    Attributes
    ----------
    system : str
        ``"E"`` or ``"C"``.
    prn : int
    week : int
        Week of ``toe`` and ``toc`` in the system's time (GPS week for Galileo, BDT week
        for BeiDou).
    toe, toc : float
        Reference times of the orbit and clock, s of ``week`` in the system's time.
    af0, af1, af2 : float
        s, s/s, s/s^2.
    sqrt_a : float
        sqrt(m).
    e, m0, omega, omega0, i0, delta_n, omega_dot, idot : float
        -, rad, rad/s.
    cuc, cus, crc, crs, cic, cis : float
        rad (``crc``, ``crs``: m).
    iode : int
    """

    system: str
    prn: int
    week: int
    toe: float
    toc: float
    af0: float
    af1: float
    af2: float
    sqrt_a: float
    e: float
    m0: float
    omega: float
    omega0: float
    i0: float
    delta_n: float = 0.0
    omega_dot: float = 0.0
    idot: float = 0.0
    cuc: float = 0.0
    cus: float = 0.0
    crc: float = 0.0
    crs: float = 0.0
    cic: float = 0.0
    cis: float = 0.0
    iode: int = 0
    tgd: float = 0.0
    health: int = 0


def is_beidou_geo(prn):
    """Whether a BeiDou PRN is a GEO satellite (1-5, 59-63)."""
    return prn <= 5 or prn >= 59


def to_system_time(system, gps_week, t_gps):
    """GPS (week, s) -> (week, s of that week) of the system's time (``E``: GPS time,
    ``C``: BDT); the seconds may leave [0, 604800) like the input's."""
    if system == "C":
        return gps_week - BDT_WEEK0_GPS, np.asarray(t_gps, float) + BDT_MINUS_GPST_S
    return gps_week, np.asarray(t_gps, float)


def _position_clock(eph, t):
    """ECEF position (m) and clock (s) at system times ``t`` (s of ``eph.week``)."""
    mu, we = SYSTEM_CONSTANTS[eph.system]
    A = eph.sqrt_a ** 2
    n = np.sqrt(mu / A ** 3) + eph.delta_n
    tk = t - eph.toe
    E = eccentric_anomaly(eph.m0 + n * tk, eph.e)
    sE, cE = np.sin(E), np.cos(E)
    nu = np.arctan2(np.sqrt(1.0 - eph.e ** 2) * sE, cE - eph.e)
    phi = nu + eph.omega
    s2, c2 = np.sin(2.0 * phi), np.cos(2.0 * phi)
    u = phi + eph.cus * s2 + eph.cuc * c2
    r = A * (1.0 - eph.e * cE) + eph.crs * s2 + eph.crc * c2
    i = eph.i0 + eph.cis * s2 + eph.cic * c2 + eph.idot * tk
    xp, yp = r * np.cos(u), r * np.sin(u)
    geo = eph.system == "C" and is_beidou_geo(eph.prn)
    Om = eph.omega0 + (eph.omega_dot if geo else eph.omega_dot - we) * tk - we * eph.toe
    sO, cO, ci = np.sin(Om), np.cos(Om), np.cos(i)
    x = xp * cO - yp * ci * sO
    y = xp * sO + yp * ci * cO
    z = yp * np.sin(i)
    if geo:
        so, co = np.sin(we * tk), np.cos(we * tk)
        yg, zg = y * _COS5 + z * _SIN5, -y * _SIN5 + z * _COS5      # R_X(-5 deg)
        x, y, z = x * co + yg * so, -x * so + yg * co, zg            # R_Z(w_e t_k)
    dtc = t - eph.toc
    dt = (eph.af0 + eph.af1 * dtc + eph.af2 * dtc ** 2
          - 2.0 * np.sqrt(mu) / C_LIGHT ** 2 * eph.e * eph.sqrt_a * sE)
    return np.column_stack([x, y, z]), dt


def kepler_state(eph, t, h=0.01):
    """Position, velocity and clock of one ephemeris' satellite.

    Parameters
    ----------
    eph : KeplerEphemeris
    t : array_like, shape (n,)
        The system's time (Galileo: GPS time; BeiDou: BDT), s of week ``eph.week``.
    h : float
        Half step of the central difference that gives the velocity and clock rate, s.

    Returns
    -------
    r_e : ndarray (n, 3)
        ECEF (the system's terrestrial frame, taken as WGS84), m.
    v_e : ndarray (n, 3)
        Velocity relative to the rotating frame, m/s.
    dt : ndarray (n,)
        Clock offset (satellite time minus system time) with the relativistic term, s.
    ddt : ndarray (n,)
        Its rate, s/s.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    r, dt = _position_clock(eph, t)
    rp, dp = _position_clock(eph, t + h)
    rm, dm = _position_clock(eph, t - h)
    return r, (rp - rm) / (2.0 * h), dt, (dp - dm) / (2.0 * h)


class KeplerOrbits:
    """The ephemerides of one Keplerian system, evaluable at GPS times.

    Parameters
    ----------
    ephemerides : sequence of KeplerEphemeris
        Of one system.
    max_age_s : float
        Largest ``|t - toe|`` of a usable ephemeris, s.
    """

    def __init__(self, ephemerides, max_age_s=7200.0):
        self.ephemerides = list(ephemerides)
        systems = {e.system for e in self.ephemerides}
        if len(systems) > 1:
            raise InputError(f"KeplerOrbits: ephemerides of several systems {sorted(systems)}")
        self.system = systems.pop() if systems else "E"
        self.max_age_s = float(max_age_s)
        self._by_prn = {}
        for e in self.ephemerides:
            if e.health == 0:
                self._by_prn.setdefault(e.prn, []).append(e)

    @property
    def prns(self):
        """PRNs with at least one healthy ephemeris (sorted)."""
        return sorted(self._by_prn)

    def state(self, prn, week, t):
        """Satellite ``prn`` at GPS times ``t`` (s of GPS week ``week``): the ephemeris of
        nearest ``toe`` within ``max_age_s``.

        Returns
        -------
        r_e, v_e : ndarray (n, 3)
            m, m/s (NaN where no ephemeris is valid).
        dt, ddt : ndarray (n,)
            Clock (s, relative to the system's time, which is GPS time for Galileo and
            GPS time - 14 s for BeiDou: an offset of the time scale, not of the clock) and
            rate (s/s).
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        ephs = self._by_prn.get(prn, [])
        r, v = np.full((len(t), 3), np.nan), np.full((len(t), 3), np.nan)
        dt, ddt = np.full(len(t), np.nan), np.full(len(t), np.nan)
        if not ephs:
            return r, v, dt, ddt
        sys_week, ts = to_system_time(self.system, week, t)
        toe = np.array([(e.week - sys_week) * SECONDS_PER_WEEK + e.toe for e in ephs])
        age = np.abs(ts[:, None] - toe[None, :])
        k = np.argmin(age, axis=1)
        k[age[np.arange(len(t)), k] > self.max_age_s] = -1
        for j in np.unique(k[k >= 0]):
            m = k == j
            e = ephs[j]
            r[m], v[m], dt[m], ddt[m] = kepler_state(
                e, ts[m] + (sys_week - e.week) * SECONDS_PER_WEEK)
        return r, v, dt, ddt


def _propagate(eph, toe_cont):
    """The same orbit and clock with reference time ``toe_cont`` (continuous s of the
    system's time since its week 0), every value rounded to D19.12."""
    mu, _ = SYSTEM_CONSTANTS[eph.system]
    d = toe_cont - (eph.week * SECONDS_PER_WEEK + eph.toe)
    n = np.sqrt(mu / eph.sqrt_a ** 6) + eph.delta_n
    week = int(toe_cont // SECONDS_PER_WEEK)
    toe = toe_cont - week * SECONDS_PER_WEEK
    wrap = lambda a: float(np.mod(a + np.pi, 2 * np.pi) - np.pi)           # noqa: E731
    e = replace(eph, week=week, toe=toe, toc=toe,
                m0=wrap(eph.m0 + n * d), omega0=wrap(eph.omega0 + eph.omega_dot * d),
                i0=eph.i0 + eph.idot * d, af0=eph.af0 + eph.af1 * d + eph.af2 * d * d,
                af1=eph.af1 + 2.0 * eph.af2 * d, iode=int((toe_cont // 3600) % 256))
    return _rounded(e)


def _rounded(e):
    names = ("af0", "af1", "af2", "sqrt_a", "e", "m0", "omega", "omega0", "i0", "delta_n",
             "omega_dot", "idot", "cuc", "cus", "crc", "crs", "cic", "cis", "tgd")
    return replace(e, **{k: rinex_round(getattr(e, k)) for k in names})


def _series(first, t_first, t_last, step_s, margin_s):
    """Ephemerides of ``first``'s orbit every ``step_s`` covering the span (continuous
    system seconds) with ``margin_s`` on both sides."""
    return [_propagate(first, tc) for tc in _grid(t_first, t_last, step_s, margin_s)]


def _grid(t_first, t_last, step_s, margin_s):
    k0 = int(np.floor((t_first - margin_s) / step_s))
    k1 = int(np.ceil((t_last + margin_s) / step_s))
    return [k * step_s for k in range(k0, k1 + 1)]


def _walker(system, prns, planes, phasing, sqrt_a, inc, omega_dot, rng, t_ref, raan0=0.0):
    """Elements of a Walker constellation (``len(prns)`` satellites in ``planes``) with
    reference time ``t_ref`` (continuous system s)."""
    per = len(prns) // planes
    out = []
    for s, prn in enumerate(prns):
        p, q = divmod(s, per)
        raan = raan0 + 2 * np.pi * p / planes
        u = 2 * np.pi * q / per + 2 * np.pi * phasing * p / len(prns)
        out.append(_elements(system, prn, sqrt_a, inc, raan, u, omega_dot, rng, t_ref))
    return out


def _elements(system, prn, sqrt_a, inc, raan, u, omega_dot, rng, t_ref):
    """A near-circular orbit with plausible harmonic terms and clock; ``raan``: the
    ascending node's longitude (ECEF) at ``t_ref`` (continuous system s), ``u``: the
    argument of latitude then."""
    _, we = SYSTEM_CONSTANTS[system]
    week = int(t_ref // SECONDS_PER_WEEK)
    toe = float(t_ref - week * SECONDS_PER_WEEK)
    omega = rng.uniform(-np.pi, np.pi)
    wrap = lambda a: float(np.mod(a + np.pi, 2 * np.pi) - np.pi)           # noqa: E731
    return KeplerEphemeris(
        system=system, prn=int(prn), week=week, toe=toe, toc=toe,
        af0=rng.uniform(-5e-4, 5e-4), af1=rng.uniform(-5e-12, 5e-12), af2=0.0,
        sqrt_a=sqrt_a, e=rng.uniform(1e-4, 5e-3), m0=wrap(u - omega), omega=omega,
        omega0=wrap(raan + we * toe), i0=inc + rng.uniform(-0.01, 0.01),
        delta_n=rng.uniform(2e-9, 5e-9), omega_dot=omega_dot,
        idot=rng.uniform(-5e-10, 5e-10),
        cuc=rng.uniform(-5e-6, 5e-6), cus=rng.uniform(-5e-6, 5e-6),
        crc=rng.uniform(100.0, 300.0), crs=rng.uniform(-100.0, 100.0),
        cic=rng.uniform(-1e-7, 1e-7), cis=rng.uniform(-1e-7, 1e-7))


def galileo_constellation(gps_week, t_first, t_last, step_s=600.0, seed=2016):
    """A Walker 24/3/1 Galileo constellation (PRN 1-24, a = 29600 km, i = 56 deg).

    Parameters
    ----------
    gps_week : int
    t_first, t_last : float
        The span to cover, GPS s of week ``gps_week`` (ephemerides from 1 h before to 1 h
        after).
    step_s : float
        Spacing of the ephemerides' ``toe`` (Galileo: 600 s), s.
    seed : int
        Seed of the plausible clocks and harmonic terms.

    Returns
    -------
    list of KeplerEphemeris
    """
    rng = np.random.default_rng(seed)
    t0 = gps_week * SECONDS_PER_WEEK
    t_ref = _grid(t0 + t_first, t0 + t_first, 3600.0, 0.0)[0]
    base = _walker("E", range(1, 25), 3, 1, np.sqrt(29600.0e3), np.deg2rad(56.0), -5.6e-9,
                   rng, t_ref)
    return [e for b in base
            for e in _series(b, t0 + t_first, t0 + t_last, step_s, 3600.0)]


def beidou_constellation(gps_week, t_first, t_last, step_s=3600.0, seed=2020, geo=True):
    """A BeiDou-like constellation: 24 MEO (PRN 19-30, 32-37, 41-46, Walker 24/3/1,
    a = 27906 km, i = 55 deg), 3 IGSO (PRN 38-40, a = 42164 km, i = 55 deg, ground track
    crossing the equator at 118 deg E) and, with ``geo``, 5 GEO (PRN 1-5 at 58.75, 80,
    110.5, 140, 160 deg E, inclination 1 deg), in BDT.

    Parameters and result as :func:`galileo_constellation`.

    Raises
    ------
    InputError
        A span before BDT week 0 (2006-01-01): no BeiDou time, no BeiDou week to write.
    """
    sys_week, _ = to_system_time("C", gps_week, 0.0)
    t0 = sys_week * SECONDS_PER_WEEK + BDT_MINUS_GPST_S
    if t0 + t_first < 0:
        raise InputError(f"BeiDou: GPS week {gps_week} is before BDT week 0 "
                         f"(GPS week {BDT_WEEK0_GPS}, 2006-01-01): no BeiDou observations")
    rng = np.random.default_rng(seed)
    mu, we = SYSTEM_CONSTANTS["C"]
    t_ref = _grid(t0 + t_first, t0 + t_first, 3600.0, 0.0)[0]
    meo = list(range(19, 31)) + list(range(32, 38)) + list(range(41, 47))
    base = _walker("C", meo, 3, 1, np.sqrt(27906.1e3), np.deg2rad(55.0), -7.0e-9, rng, t_ref)
    a_geo = (mu / we ** 2) ** (1.0 / 3.0)          # the synchronous radius
    for s, prn in enumerate((38, 39, 40)):
        raan = np.deg2rad(118.0) + 2 * np.pi * s / 3
        e = _elements("C", prn, np.sqrt(a_geo), np.deg2rad(55.0), raan, -2 * np.pi * s / 3,
                      -8.0e-10, rng, t_ref)
        base.append(replace(e, delta_n=0.0))
    out = [e for b in base for e in _series(b, t0 + t_first, t0 + t_last, step_s, 3600.0)]
    if geo:
        for prn, lon in zip(range(1, 6), (58.75, 80.0, 110.5, 140.0, 160.0)):
            clock = _elements("C", prn, 1.0, 0.0, 0.0, 0.0, 0.0, rng, t_ref)
            out += [_geo_elements(clock, np.deg2rad(lon), a_geo, tc, t_ref)
                    for tc in _grid(t0 + t_first, t0 + t_last, step_s, 3600.0)]
    return out


def _geo_elements(clock, lon, a, toe_cont, t_ref):
    """The GEO ephemeris of reference time ``toe_cont`` (continuous BDT s) of a circular
    synchronous orbit (inclination 1 deg, ascending node over ``lon`` at ``t_ref``):
    position and inertial velocity in the frame that coincides with ECEF at ``toe``,
    rotated by ``R_X(-5 deg)^T`` into the frame of the broadcast elements, whose
    Keplerian elements these are (``e = 0``, no harmonic terms: successive ephemerides
    describe the same orbit)."""
    _, we = SYSTEM_CONSTANTS["C"]
    inc = np.deg2rad(1.0)
    u = we * (toe_cont - t_ref)
    R = np.array([[np.cos(lon), -np.sin(lon), 0.0], [np.sin(lon), np.cos(lon), 0.0],
                  [0.0, 0.0, 1.0]]) @ np.array([[1.0, 0.0, 0.0],
                                                [0.0, np.cos(inc), -np.sin(inc)],
                                                [0.0, np.sin(inc), np.cos(inc)]])
    r_i = R @ (a * np.array([np.cos(u), np.sin(u), 0.0]))
    v_i = R @ (a * we * np.array([-np.sin(u), np.cos(u), 0.0]))
    th = -we * (toe_cont - t_ref)                       # inertial -> ECEF at toe
    rz = np.array([[np.cos(th), -np.sin(th), 0.0], [np.sin(th), np.cos(th), 0.0],
                   [0.0, 0.0, 1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, _COS5, _SIN5], [0.0, -_SIN5, _COS5]])
    rg, vg = rx.T @ rz @ r_i, rx.T @ rz @ v_i
    hv = np.cross(rg, vg)
    i = np.arccos(hv[2] / np.linalg.norm(hv))
    raan = np.arctan2(hv[0], -hv[1])
    node = np.array([np.cos(raan), np.sin(raan), 0.0])
    ug = np.arctan2(np.dot(np.cross(node, rg), hv) / np.linalg.norm(hv), np.dot(node, rg))
    week = int(toe_cont // SECONDS_PER_WEEK)
    toe = float(toe_cont - week * SECONDS_PER_WEEK)
    d = toe_cont - t_ref
    wrap = lambda x: float(np.mod(x + np.pi, 2 * np.pi) - np.pi)           # noqa: E731
    e = KeplerEphemeris(system="C", prn=clock.prn, week=week, toe=toe, toc=toe,
                        af0=clock.af0 + clock.af1 * d, af1=clock.af1, af2=0.0,
                        sqrt_a=np.sqrt(a), e=0.0, m0=wrap(ug), omega=0.0,
                        omega0=wrap(raan + we * toe), i0=float(i),
                        iode=int((toe_cont // 3600) % 256))
    return _rounded(e)
