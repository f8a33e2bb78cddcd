"""Truth trajectory of a survey flight, smooth and evaluable at any time.

From the :class:`~ins.simulate.path.FlightPath` (track ``psi``, ground speed ``V``,
climb ``v_climb``, airborne weight ``s``) and the turbulence:

* velocity ``v_n = (V cos psi, V sin psi, v_climb - d(s heave)/dt)`` (NED, m/s) and its
  derivative ``a_n`` analytically;
* height ``h = h0 - int v_climb + s heave`` analytically; latitude and longitude from
  ``d(lat, lon)/dt = D^-1 v_n`` (:func:`ins.earth.lla_rate`) integrated by DOP853
  (rtol 1e-12) piece by piece between the breakpoints of the profiles, forward and
  backward from the start of strip 0, which is the block origin, with dense output;
* aircraft attitude ``a`` (ZYX Euler): roll ``atan(V psi_dot / g) + s roll_turb``
  (coordinated turn), pitch = flight-path angle of the climb ``+ s pitch_turb``, yaw
  ``= psi + s (crab(psi) + yaw_turb)``, crab from the wind triangle at ground speed V;
* the stabilized mount (when enabled): the command ``C_ap* = C_na^T Rz(psi)`` keeps the
  platform level and along the flight line; the platform follows it with the servo lag
  as a dead time (``m(t) = sat(m*(t - tau))``, exact and smooth; a first-order servo of
  time constant tau has the same delay for slow motion) and a smooth saturation at the
  limits (identity up to 80 % of the limit, then a tanh knee: C2).  The IMU body is the
  platform: ``C_nb = C_na C_ap``;
* ``w_ib_b = w_nb_b + C_bn (w_ie_n + w_en_n)`` with ``w_nb_b`` from the Euler-angle
  rates, and ``f_b = C_bn (a_n - g_n + (2 w_ie_n + w_en_n) x v_n)`` (normal gravity of
  :mod:`ins.earth`), all analytic.
"""
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from .. import earth
from ..rotation import dcm_to_euler, dcm_to_quat, euler_to_dcm, quat_to_dcm
from .path import build_path
from .plan import G_TURN

__all__ = ["FlightTruth", "TruthSample", "Strip", "build_truth", "euler_rates_to_body",
           "body_to_euler_rates"]

_KNEE = 0.8


@dataclass(frozen=True)
class Strip:
    """A photo line: index, start and end (GPS s of week), azimuth of flight (rad)."""
    index: int
    t_start: float
    t_end: float
    azimuth_rad: float


@dataclass(frozen=True)
class TruthSample:
    """True state at ``n`` epochs (leading dimension n).

    ``time`` (n,) GPS s; ``lla`` (n, 3) lat, lon rad, h m of the IMU; ``v_n``, ``a_n``
    (n, 3) NED m/s, m/s^2; ``q_nb`` (n, 4) IMU body (= platform) attitude, scalar last;
    ``w_ib_b`` (n, 3) rad/s; ``f_b`` (n, 3) specific force m/s^2; ``q_na`` (n, 4)
    aircraft attitude; ``mount_rpy`` (n, 3) rad, platform relative to aircraft,
    ``C_ap = Rz(yaw) Ry(pitch) Rx(roll)``; ``mount_rate`` (n, 3) rad/s, its derivative.
    """
    time: np.ndarray
    lla: np.ndarray
    v_n: np.ndarray
    a_n: np.ndarray
    q_nb: np.ndarray
    w_ib_b: np.ndarray
    f_b: np.ndarray
    q_na: np.ndarray
    mount_rpy: np.ndarray
    mount_rate: np.ndarray


def euler_rates_to_body(rpy, rpy_dot):
    """Body angular rate (rad/s) of ``C = Rz(yaw) Ry(pitch) Rx(roll)`` from Euler rates."""
    r, p = rpy[..., 0], rpy[..., 1]
    dr, dp, dy = rpy_dot[..., 0], rpy_dot[..., 1], rpy_dot[..., 2]
    return np.stack([dr - dy * np.sin(p),
                     dp * np.cos(r) + dy * np.sin(r) * np.cos(p),
                     -dp * np.sin(r) + dy * np.cos(r) * np.cos(p)], axis=-1)


def body_to_euler_rates(rpy, w):
    """Euler rates (rad/s) from the body angular rate; the inverse of
    :func:`euler_rates_to_body` (singular at pitch +-90 deg)."""
    r, p = rpy[..., 0], rpy[..., 1]
    a = w[..., 1] * np.sin(r) + w[..., 2] * np.cos(r)
    return np.stack([w[..., 0] + a * np.tan(p),
                     w[..., 1] * np.cos(r) - w[..., 2] * np.sin(r),
                     a / np.cos(p)], axis=-1)


def _soft_limit(x, dx, limit):
    """C2 saturation: x below ``0.8 limit``, then a tanh knee toward the limit."""
    k = _KNEE * limit
    span = limit - k
    over = np.abs(x) > k
    u = np.where(over, (np.abs(x) - k) / span, 0.0)
    y = np.where(over, np.sign(x) * (k + span * np.tanh(u)), x)
    dy = np.where(over, dx / np.cosh(u) ** 2, dx)
    return y, dy


def _sines(t, amps, freqs, phases, order):
    """Sum of sinusoids A sin(2 pi f t + phase) and its derivatives up to ``order``."""
    out = [np.zeros_like(t) for _ in range(order + 1)]
    for a, f, ph in zip(amps, freqs, phases):
        w = 2 * np.pi * f
        arg = w * t + ph
        s, c = np.sin(arg), np.cos(arg)
        terms = (a * s, a * w * c, -a * w * w * s)
        for i in range(order + 1):
            out[i] += terms[i]
    return out


class FlightTruth:
    """The truth of a flight plan; :meth:`evaluate` at any time in [t_start, t_end].

    Attributes
    ----------
    plan : FlightPlan
    t_start, t_end : float
        GPS seconds of week.
    strips : list of Strip
    stationary : list of (t0, t1)
        Stationary segments, GPS s (on the ground: static; in the air: straight level
        flight).
    path : ins.simulate.path.FlightPath
    """

    def __init__(self, plan):
        self.plan = plan
        self.path = p = build_path(plan)
        self.t0 = t0 = plan.flight.start_time
        self.t_start, self.t_end = t0, t0 + p.duration
        self.strips = [Strip(i, float(t0 + a), float(t0 + b), float(az))
                       for i, (a, b, az) in enumerate(p.strips)]
        self.stationary = [(float(t0 + a), float(t0 + b)) for a, b in p.stationary]
        self._psi = p.psi_dot.antiderivative()
        self._psi_ddot = p.psi_dot.derivative()
        self._climb = p.v_down.antiderivative()
        self._v_down_dot = p.v_down.derivative()
        self._speed_dot = p.speed.derivative()
        self._air_d = p.air.derivative()
        self._air_dd = p.air.derivative(2)
        tb = plan.turbulence
        rng = np.random.default_rng(tb.seed)
        self._turb = {name: (getattr(tb, f"{name}_amp"), getattr(tb, f"{name}_freq"),
                             rng.uniform(0, 2 * np.pi, len(getattr(tb, f"{name}_amp"))))
                      for name in ("roll", "pitch", "yaw", "heave")}
        self._wind = plan.wind.w_n
        b = plan.block
        self._solve_lat_lon([b.origin_lat, b.origin_lon])

    def _solve_lat_lon(self, lat_lon0):
        """Integrate (lat, lon) piece by piece between the profile breakpoints, forward
        and backward from the start of strip 0 (= the block origin)."""
        p = self.path
        opts = dict(method="DOP853", rtol=1e-12, atol=1e-14, dense_output=True)
        edges = np.asarray(p.psi_dot.x, dtype=float)
        pieces = []
        for direction in (1, -1):
            y = np.array(lat_lon0, dtype=float)
            ends = edges[edges > p.t_strip0] if direction > 0 else edges[edges < p.t_strip0][::-1]
            ta = p.t_strip0
            for tb in ends:
                sol = solve_ivp(self._rhs, (ta, tb), y, **opts)
                y = sol.y[:, -1]
                pieces.append((min(ta, tb), sol.sol))
                ta = tb
        pieces.sort(key=lambda x: x[0])
        self._piece_start = np.array([x[0] for x in pieces])
        self._piece_sol = [x[1] for x in pieces]

    # ---- profiles (t relative to the flight start, s)
    def _horizontal(self, t):
        p = self.path
        psi = p.psi0 + self._psi(t)
        return psi, p.psi_dot(t), self._psi_ddot(t), p.speed(t), self._speed_dot(t)

    def _vertical(self, t):
        """h (m), v_down (m/s), a_down (m/s^2) with the heave weighted by ``air``."""
        p = self.path
        s, ds, dds = p.air(t), self._air_d(t), self._air_dd(t)
        hv, dhv, ddhv = _sines(t, *self._turb["heave"], 2)
        h = p.h0 - self._climb(t) + s * hv
        vd = p.v_down(t) - (ds * hv + s * dhv)
        ad = self._v_down_dot(t) - (dds * hv + 2 * ds * dhv + s * ddhv)
        return h, vd, ad

    def _rhs(self, t, y):
        psi, _, _, V, _ = self._horizontal(t)
        h = self._vertical(t)[0]
        rm, rn = earth.radii(y[0])
        return [V * np.cos(psi) / (rm + h), V * np.sin(psi) / ((rn + h) * np.cos(y[0]))]

    def _lat_lon(self, t):
        out = np.empty((len(t), 2))
        idx = np.clip(np.searchsorted(self._piece_start, t, side="right") - 1, 0,
                      len(self._piece_sol) - 1)
        for i in np.unique(idx):
            sel = idx == i
            out[sel] = self._piece_sol[i](t[sel]).T
        return out

    def _crab(self, psi, V):
        """Crab angle (rad) and d crab / d psi from the wind triangle."""
        wn, we = self._wind
        c, s = np.cos(psi), np.sin(psi)
        A = V - (wn * c + we * s)              # air velocity along track
        B = wn * s - we * c                    # air velocity to the right of track
        dA, dB = -(-wn * s + we * c), wn * c + we * s
        den = A * A + B * B
        if wn == 0.0 and we == 0.0:
            return np.zeros_like(psi), np.zeros_like(psi)
        return np.arctan2(B, A), (A * dB - B * dA) / np.where(den > 0, den, 1.0)

    def _aircraft(self, t, psi, psi_dot, psi_ddot, V, V_dot):
        """Aircraft Euler angles (n, 3) and their rates (rad, rad/s)."""
        p = self.path
        s, ds = p.air(t), self._air_d(t)
        roll_t, droll_t = _sines(t, *self._turb["roll"], 1)
        pitch_t, dpitch_t = _sines(t, *self._turb["pitch"], 1)
        yaw_t, dyaw_t = _sines(t, *self._turb["yaw"], 1)
        x = V * psi_dot / G_TURN
        dx = (V_dot * psi_dot + V * psi_ddot) / G_TURN
        roll = np.arctan(x) + s * roll_t
        droll = dx / (1 + x * x) + ds * roll_t + s * droll_t
        up, dup = -p.v_down(t), -self._v_down_dot(t)
        den = V * V + up * up
        safe = np.where(den > 0, den, 1.0)
        pitch = np.arctan2(up, V) + s * pitch_t
        dpitch = np.where(den > 0, (V * dup - up * V_dot) / safe, 0.0) + ds * pitch_t + s * dpitch_t
        crab, dcrab = self._crab(psi, V)
        yaw = psi + s * (crab + yaw_t)
        dyaw = psi_dot + ds * (crab + yaw_t) + s * (dcrab * psi_dot + dyaw_t)
        return np.stack([roll, pitch, yaw], -1), np.stack([droll, dpitch, dyaw], -1)

    def _mount_command(self, t):
        """Mount angles that level the platform along the track, and their rates."""
        psi, psi_dot, psi_ddot, V, V_dot = self._horizontal(t)
        rpy_a, drpy_a = self._aircraft(t, psi, psi_dot, psi_ddot, V, V_dot)
        C_na = euler_to_dcm(rpy_a)
        C_np = euler_to_dcm(np.stack([0 * psi, 0 * psi, psi], -1))
        C_ap = np.einsum("nji,njk->nik", C_na, C_np)
        cmd = dcm_to_euler(C_ap)
        w_na_a = euler_rates_to_body(rpy_a, drpy_a)
        w_np_p = np.stack([0 * psi, 0 * psi, psi_dot], -1)
        w_ap_p = w_np_p - np.einsum("nji,nj->ni", C_ap, w_na_a)
        return cmd, body_to_euler_rates(cmd, w_ap_p)

    def _mount(self, t):
        m = self.plan.mount
        if not m.enabled:
            z = np.zeros((len(t), 3))
            return z, z.copy()
        cmd, dcmd = self._mount_command(t - m.servo_lag)
        limits = (m.level_limit, m.level_limit, m.azimuth_limit)
        out = [_soft_limit(cmd[:, i], dcmd[:, i], limits[i]) for i in range(3)]
        return (np.stack([o[0] for o in out], -1), np.stack([o[1] for o in out], -1))

    def evaluate(self, time):
        """True state at ``time`` (GPS s, scalar or array within [t_start, t_end]).

        Returns
        -------
        TruthSample
        """
        t_abs = np.atleast_1d(np.asarray(time, dtype=float))
        if np.any(t_abs < self.t_start - 1e-9) or np.any(t_abs > self.t_end + 1e-9):
            raise ValueError(f"time outside the flight [{self.t_start}, {self.t_end}] s")
        t = t_abs - self.t0
        psi, psi_dot, psi_ddot, V, V_dot = self._horizontal(t)
        h, vd, ad = self._vertical(t)
        lla = np.column_stack([self._lat_lon(t), h])
        c, s = np.cos(psi), np.sin(psi)
        v_n = np.column_stack([V * c, V * s, vd])
        a_n = np.column_stack([V_dot * c - V * psi_dot * s, V_dot * s + V * psi_dot * c, ad])
        rpy_a, drpy_a = self._aircraft(t, psi, psi_dot, psi_ddot, V, V_dot)
        mount, dmount = self._mount(t)
        C_na, C_ap = euler_to_dcm(rpy_a), euler_to_dcm(mount)
        C_nb = C_na @ C_ap
        w_na_a = euler_rates_to_body(rpy_a, drpy_a)
        w_nb_b = np.einsum("nji,nj->ni", C_ap, w_na_a) + euler_rates_to_body(mount, dmount)
        w_ie_n = earth.earth_rate_n(lla[:, 0])
        w_en_n = earth.transport_rate_n(lla[:, 0], h, v_n)
        w_ib_b = w_nb_b + np.einsum("nji,nj->ni", C_nb, w_ie_n + w_en_n)
        f_n = a_n - earth.gravity_n(lla[:, 0], h) + np.cross(2 * w_ie_n + w_en_n, v_n)
        f_b = np.einsum("nji,nj->ni", C_nb, f_n)
        return TruthSample(time=t_abs, lla=lla, v_n=v_n, a_n=a_n, q_nb=dcm_to_quat(C_nb),
                           w_ib_b=w_ib_b, f_b=f_b, q_na=dcm_to_quat(C_na), mount_rpy=mount,
                           mount_rate=dmount)

    def C_nb(self, time):
        """``C_nb`` (n, 3, 3) at ``time`` (GPS s)."""
        return quat_to_dcm(self.evaluate(time).q_nb)


def build_truth(plan):
    """The :class:`FlightTruth` of a :class:`~ins.simulate.plan.FlightPlan`."""
    return FlightTruth(plan)
