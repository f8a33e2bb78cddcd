"""GPS satellite position, velocity and clock from the broadcast ephemeris (IS-GPS-200).

The simulator's own implementation (independent of RTKLIB, which the tight-coupling
filter uses; ``tests/test_gnss_raw.py`` compares the two at the millimetre level).
Formulas of IS-GPS-200 Table 20-IV (user algorithm for ephemeris determination) and
20.3.3.3.3.1 (satellite clock correction), with the WGS84 constants of the ICD::

    A = sqrt_a^2;  n = sqrt(mu / A^3) + delta_n;  t_k = t - toe  (week crossover)
    M = m0 + n t_k;  M = E - e sin E  (Kepler, Newton);  nu = atan2(sqrt(1-e^2) sin E, cos E - e)
    Phi = nu + omega;  du, dr, di = (cus, crs, cis) sin 2 Phi + (cuc, crc, cic) cos 2 Phi
    u = Phi + du;  r = A (1 - e cos E) + dr;  i = i0 + di + idot t_k
    Omega = omega0 + (omega_dot - w_ie) t_k - w_ie toe
    r_e = Rz(-Omega) Rx(-i) (r cos u, r sin u, 0)                      (ECEF, m)

The velocity ``v_e`` (ECEF, m/s: the time derivative of ``r_e`` in the rotating frame)
is the analytic derivative of the same expressions.  Clock (s; the satellite's time
minus GPS time)::

    dt_sv = af0 + af1 (t - toc) + af2 (t - toc)^2 + F e sqrt_a sin E,  F = -2 sqrt(mu) / c^2
    dt_L1 = dt_sv - tgd                          (L1 C/A user, 20.3.3.3.3.2)

Times are GPS seconds of week of the week ``week`` passed to the functions; the
ephemeris' own week is accounted for, so a flight near a week boundary works.

Ephemeris selection (:meth:`BroadcastOrbits.select`): of the healthy ephemerides of the
satellite, the one whose ``toe`` is nearest to ``t`` and within :data:`MAX_AGE_S` (the
rule of RTKLIB's ``seleph``, so that the filter uses the same orbit as the simulator).
"""
import numpy as np

from ins.common.errors import InputError
from ins.io.rinex_nav import SECONDS_PER_WEEK

__all__ = ["MU_GPS", "OMEGA_E_GPS", "C_LIGHT", "F_REL", "MAX_AGE_S", "BroadcastOrbits",
           "eph_state"]

#: Earth's gravitational constant of the GPS ICD, m^3/s^2.
MU_GPS = 3.986005e14
#: Earth rotation rate of the GPS ICD, rad/s.
OMEGA_E_GPS = 7.2921151467e-5
#: Speed of light, m/s.
C_LIGHT = 299792458.0
#: Relativistic clock constant ``-2 sqrt(mu) / c^2``, s/sqrt(m).
F_REL = -2.0 * np.sqrt(MU_GPS) / C_LIGHT ** 2
#: Largest ``|t - toe|`` of a usable ephemeris, s.
MAX_AGE_S = 7200.0


def eccentric_anomaly(M, e):
    """Eccentric anomaly E (rad) of Kepler's equation ``M = E - e sin E`` by Newton's
    iteration (to 1e-14 rad), for mean anomalies ``M`` (rad, array) and eccentricity
    ``e``."""
    E = M.copy()
    for _ in range(30):
        dE = (E - e * np.sin(E) - M) / (1.0 - e * np.cos(E))
        E = E - dE
        if np.all(np.abs(dE) < 1e-14):
            break
    return E


def eph_state(eph, week, t):
    """Position, velocity, clock and clock rate of one ephemeris' satellite.

    Parameters
    ----------
    eph : ins.io.rinex_nav.GpsEphemeris
    week : int
        GPS week of ``t``.
    t : array_like, shape (n,)
        GPS time (transmit time of the signal), s of week ``week``.

    Returns
    -------
    r_e : ndarray, shape (n, 3)
        ECEF position (WGS84 frame at time ``t``), m.
    v_e : ndarray, shape (n, 3)
        ECEF velocity (relative to the rotating frame), m/s.
    dt_sv : ndarray, shape (n,)
        Satellite clock offset including the relativistic term, without ``tgd``, s.
    ddt_sv : ndarray, shape (n,)
        Its rate, s/s.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float)) + (week - eph.week) * SECONDS_PER_WEEK
    A = eph.sqrt_a ** 2
    n = np.sqrt(MU_GPS / A ** 3) + eph.delta_n
    tk = t - eph.toe
    e = eph.e
    E = eccentric_anomaly(eph.m0 + n * tk, e)
    sE, cE = np.sin(E), np.cos(E)
    one_ecE = 1.0 - e * cE
    q = np.sqrt(1.0 - e * e)
    nu = np.arctan2(q * sE, cE - e)
    phi = nu + eph.omega
    s2, c2 = np.sin(2.0 * phi), np.cos(2.0 * phi)
    u = phi + eph.cus * s2 + eph.cuc * c2
    r = A * one_ecE + eph.crs * s2 + eph.crc * c2
    i = eph.i0 + eph.cis * s2 + eph.cic * c2 + eph.idot * tk
    Om_dot = eph.omega_dot - OMEGA_E_GPS
    Om = eph.omega0 + Om_dot * tk - OMEGA_E_GPS * eph.toe
    su, cu, si, ci, sO, cO = np.sin(u), np.cos(u), np.sin(i), np.cos(i), np.sin(Om), np.cos(Om)
    xp, yp = r * cu, r * su
    x = xp * cO - yp * ci * sO
    y = xp * sO + yp * ci * cO
    z = yp * si
    # derivatives
    E_dot = n / one_ecE
    phi_dot = q * E_dot / one_ecE
    u_dot = phi_dot * (1.0 + 2.0 * (eph.cus * c2 - eph.cuc * s2))
    r_dot = A * e * sE * E_dot + 2.0 * phi_dot * (eph.crs * c2 - eph.crc * s2)
    i_dot = eph.idot + 2.0 * phi_dot * (eph.cis * c2 - eph.cic * s2)
    xp_dot = r_dot * cu - r * u_dot * su
    yp_dot = r_dot * su + r * u_dot * cu
    vx = xp_dot * cO - yp_dot * ci * sO + yp * si * sO * i_dot - Om_dot * y
    vy = xp_dot * sO + yp_dot * ci * cO - yp * si * cO * i_dot + Om_dot * x
    vz = yp_dot * si + yp * ci * i_dot
    dtc = t - eph.toc - (eph.toc_week - eph.week) * SECONDS_PER_WEEK
    dt_sv = eph.af0 + eph.af1 * dtc + eph.af2 * dtc ** 2 + F_REL * e * eph.sqrt_a * sE
    ddt_sv = eph.af1 + 2.0 * eph.af2 * dtc + F_REL * e * eph.sqrt_a * cE * E_dot
    return (np.column_stack([x, y, z]), np.column_stack([vx, vy, vz]), dt_sv, ddt_sv)


class BroadcastOrbits:
    """The satellites of a navigation file, evaluable at any GPS time.

    Parameters
    ----------
    nav : ins.io.rinex_nav.NavData
        From :func:`ins.io.rinex_nav.read_gps_nav`.
    """

    def __init__(self, nav):
        self.nav = nav
        self._by_prn = {}
        for eph in nav.ephemerides:
            if eph.health == 0:
                self._by_prn.setdefault(eph.prn, []).append(eph)

    @property
    def prns(self):
        """PRNs with at least one healthy ephemeris (sorted)."""
        return sorted(self._by_prn)

    def _ages(self, prn, week, t):
        ephs = self._by_prn.get(prn, [])
        toe = np.array([(e.week - week) * SECONDS_PER_WEEK + e.toe for e in ephs])
        return ephs, np.abs(np.atleast_1d(t)[:, None] - toe[None, :])

    def select(self, prn, week, t):
        """Index into the satellite's healthy ephemerides per time (-1: none valid).

        Parameters
        ----------
        prn : int
        week : int
        t : array_like, shape (n,)
            GPS s of week ``week``.

        Returns
        -------
        ephs : list of GpsEphemeris
        index : ndarray of int, shape (n,)
        """
        ephs, age = self._ages(prn, week, np.asarray(t, dtype=float))
        if not ephs:
            return ephs, np.full(np.size(t), -1)
        k = np.argmin(age, axis=1)
        ok = age[np.arange(len(k)), k] <= MAX_AGE_S
        return ephs, np.where(ok, k, -1)

    def covers(self, week, t_first, t_last):
        """Whether at least 4 satellites have a valid ephemeris over the whole span."""
        t = np.linspace(t_first, t_last, 7)
        n_ok = [np.all(self.select(p, week, t)[1] >= 0) for p in self.prns]
        return int(np.sum(n_ok)) >= 4

    def state(self, prn, week, t):
        """Satellite ``prn`` at GPS times ``t`` (s of week ``week``).

        Returns
        -------
        r_e, v_e : ndarray, shape (n, 3)
            ECEF position (m) and velocity (m/s); NaN where no ephemeris is valid.
        dt_L1 : ndarray, shape (n,)
            L1 C/A clock offset ``dt_sv - tgd``, s (NaN where invalid).
        ddt : ndarray, shape (n,)
            Clock rate, s/s.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        ephs, idx = self.select(prn, week, t)
        r = np.full((len(t), 3), np.nan)
        v = np.full((len(t), 3), np.nan)
        dt = np.full(len(t), np.nan)
        ddt = np.full(len(t), np.nan)
        for k in np.unique(idx[idx >= 0]):
            m = idx == k
            rk, vk, dk, ddk = eph_state(ephs[k], week, t[m])
            r[m], v[m], dt[m], ddt[m] = rk, vk, dk - ephs[k].tgd, ddk
        return r, v, dt, ddt

    def check_time(self, week, t_first, t_last, what="the flight"):
        """Raise InputError unless the span is covered (naming the file and the span)."""
        if not self.covers(week, t_first, t_last):
            ephs = self.nav.ephemerides
            lo = min((e.week - week) * SECONDS_PER_WEEK + e.toe for e in ephs) - MAX_AGE_S
            hi = max((e.week - week) * SECONDS_PER_WEEK + e.toe for e in ephs) + MAX_AGE_S
            raise InputError(
                f"{what} (GPS week {week}, {t_first:.0f}-{t_last:.0f} s of week) is not "
                f"covered by the broadcast ephemerides (valid for GPS week {week} s of week "
                f"{lo:.0f} to {hi:.0f}, +-{MAX_AGE_S:.0f} s around their toe): set "
                f"[flight] gps_week and start_time_s (GPS s of week) inside that span",
                path=self.nav.path)
