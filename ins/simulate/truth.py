"""Truth trajectory of a survey flight, smooth and evaluable at any time.

From the :class:`~ins.simulate.path.FlightPath` (track ``psi``, ground speed ``V``,
climb ``v_climb``, airborne weight ``s``) and the turbulence:

* velocity ``v_n = (V cos psi, V sin psi, v_climb - d(s heave)/dt)`` (NED, m/s) and its
  derivative ``a_n`` analytically;
* height ``h = h0 - int v_climb + s heave`` analytically; latitude and longitude from
  ``d(lat, lon)/dt = D^-1 v_n`` (:func:`ins.nav.earth.lla_rate`) integrated by DOP853
  (rtol 1e-12) piece by piece between the breakpoints of the profiles, forward and
  backward from the start of strip 0, which is the block origin, with dense output;
* strip placement: the turns are designed in the plane (:mod:`~ins.simulate.path`); the
  lateral offset and the run-in of every turn are then corrected on the integrated
  geodetic path (a fixed-point iteration, :data:`GEOMETRY_TOL`) so that each strip starts
  at its planned point: ``i * spacing`` to the right of the origin (and ``strip_length``
  along the azimuth for the odd, returning strips) in the local level frame at the block
  origin (ENU/NED at the origin, the mapping frame).  The strips are lines of constant
  azimuth (rhumb lines); over a strip of length L they leave the tangent-plane straight
  line by about ``L^2 tan(lat) |sin az| / (2 R)`` (0.3 m for 2.5 km at 30 deg);
* aircraft attitude ``a`` (ZYX Euler): roll ``atan(V psi_dot / g) + s roll_turb``
  (coordinated turn), pitch = flight-path angle of the climb ``+ s pitch_turb``, yaw
  ``= psi + d``, ``d = s (crab(psi, V) + yaw_turb)``, crab from the wind triangle;
* the stabilized mount (when enabled): the command ``C_ap* = C_na^T Rz(psi) = Rx(-roll)
  Ry(-pitch) Rz(-d)`` keeps the platform level and along the flight line.  The servos
  follow the aircraft's angles with a first-order lag of time constant ``tau``
  (``servo_lag_s``): the turbulence, a sum of sinusoids, through its exact steady-state
  response (gain ``1/sqrt(1 + (w tau)^2)``, phase ``-atan(w tau)``; the transient is
  dropped: the turbulence has always been there, or fades in with the slow airborne
  weight); the slow parts (bank of the turns, climb pitch, crab, airborne weight)
  through a dead time ``tau``, ``x(t - tau)``, which is the lag's response up to
  ``O((w tau)^2)`` for motions of bandwidth ``w`` (0.5 % for the 5-s roll-in at
  tau = 0.1 s) and keeps the truth analytic and C2 (an exact convolution of the
  arctan bank would need a numerical filter state).  The ZYX angles of the lagged
  command are soft-limited (identity up to :data:`KNEE` of the limit, then a tanh knee:
  C2): in the turns, whose bank exceeds the level limit, the mount saturates smoothly
  and the platform banks with the aircraft; on the strips the plan validation keeps it
  inside the knee.  The IMU body is the platform: ``C_nb = C_na C_ap``;
* ``w_ib_b = w_nb_b + C_bn (w_ie_n + w_en_n)`` with ``w_nb_b`` from the Euler-angle
  rates, and ``f_b = C_bn (a_n - g_n + (2 w_ie_n + w_en_n) x v_n)`` (normal gravity of
  :mod:`ins.nav.earth`), all analytic, evaluated per sample by a compiled kernel
  (:func:`ins.simulate._kernels.platform_state`).
"""
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import PPoly

from ins.nav import earth
from ins.nav.rotation import dcm_to_quat
from ins.simulate import _kernels
from ins.simulate.path import build_path
from ins.simulate.plan_model import G_TURN, MOUNT_KNEE

__all__ = ["FlightTruth", "TruthSample", "Strip", "build_truth", "euler_rates_to_body",
           "body_to_euler_rates", "GEOMETRY_TOL", "KNEE"]

#: The mount's soft limit is the identity up to this fraction of the limit.
KNEE = MOUNT_KNEE
#: Strip starts are placed on the geodetic path to this horizontal tolerance, m.
GEOMETRY_TOL = 0.005
_GEOMETRY_ITER = 8


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
    rpy, d = np.asarray(rpy, float), np.asarray(rpy_dot, float)
    return np.stack(_kernels.euler_rates_to_body(rpy[..., 0], rpy[..., 1], d[..., 0],
                                                 d[..., 1], d[..., 2]), axis=-1)


def body_to_euler_rates(rpy, w):
    """Euler rates (rad/s) from the body angular rate; the inverse of
    :func:`euler_rates_to_body` (singular at pitch +-90 deg)."""
    rpy, w = np.asarray(rpy, float), np.asarray(w, float)
    return np.stack(_kernels.body_to_euler_rates(rpy[..., 0], rpy[..., 1], w[..., 0],
                                                 w[..., 1], w[..., 2]), axis=-1)


class _Sines:
    """A sum of sinusoids ``sum A sin(w t + phase)`` and its first-order-lag response."""

    def __init__(self, amps, freqs, phases, tau):
        self.a = np.asarray(amps, float)
        self.w = 2 * np.pi * np.asarray(freqs, float)
        self.ph = np.asarray(phases, float)
        gain = 1.0 / np.sqrt(1.0 + (self.w * tau) ** 2)
        lag = np.arctan(self.w * tau)
        self.cos_l, self.sin_l = gain * np.cos(lag), gain * np.sin(lag)

    def __call__(self, t):
        """(n, 5): value, first and second derivative, lag response and its derivative
        (``A g sin(w t + phase - atan(w tau))``, ``g = 1 / sqrt(1 + (w tau)^2)``)."""
        out = np.empty((len(t), 5))
        _kernels.sum_of_sines(t, self.a, self.w, self.ph, self.cos_l, self.sin_l, out)
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
    strip_start_error_m : ndarray, shape (n_strips, 2)
        Planned minus flown start of each strip, north and east at the origin, m.
    """

    def __init__(self, plan):
        self.plan = plan
        self.t0 = t0 = plan.flight.start_time
        tb = plan.turbulence
        m = plan.mount
        self._tau = m.servo_lag if m.enabled else 0.0
        rng = np.random.default_rng(tb.seed)
        self._turb = {name: _Sines(getattr(tb, f"{name}_amp"), getattr(tb, f"{name}_freq"),
                                   rng.uniform(0, 2 * np.pi, len(getattr(tb, f"{name}_amp"))),
                                   self._tau)
                      for name in ("roll", "pitch", "yaw", "heave")}
        self._wind = plan.wind.w_n
        self._limits = np.array([m.level_limit, m.level_limit, m.azimuth_limit])
        self._place_strips()
        p = self.path
        self.t_start, self.t_end = t0, t0 + p.duration
        self.strips = [Strip(i, float(t0 + a), float(t0 + b), float(az))
                       for i, (a, b, az) in enumerate(p.strips)]
        self.stationary = [(float(t0 + a), float(t0 + b)) for a, b in p.stationary]

    # ---- construction
    def _set_path(self, path):
        """Adopt a path; all profiles and their derivatives as the columns of one PPoly
        (the profiles share their breakpoints: one interval search per evaluation)."""
        self.path = p = path
        cols = [p.psi_dot.antiderivative(), p.psi_dot, p.psi_dot.derivative(), p.speed,
                p.speed.derivative(), p.v_down.antiderivative(), p.v_down,
                p.v_down.derivative(), p.air, p.air.derivative(), p.air.derivative(2)]
        k = max(c.c.shape[0] for c in cols)
        c = np.zeros((k, len(p.psi_dot.x) - 1, len(cols)))
        for j, pp in enumerate(cols):
            c[k - pp.c.shape[0]:, :, j] = pp.c
        self._pp = PPoly(c, p.psi_dot.x)

    def _place_strips(self):
        """Build the path and correct each turn until the strips start at their planned
        points on the geodetic path (see the module docstring)."""
        plan = self.plan
        b = plan.block
        n = b.n_strips
        az = b.strip_azimuth
        along = np.array([np.cos(az), np.sin(az)])
        right = np.array([-np.sin(az), np.cos(az)])
        i = np.arange(n)
        planned = (i * plan.strip_spacing_m)[:, None] * right \
            + ((i % 2) * b.strip_length)[:, None] * along
        direction = np.where(i % 2 == 0, 1.0, -1.0)[:, None] * along
        origin = np.array([b.origin_lat, b.origin_lon, plan.flying_height_m])
        corr = np.zeros((max(n - 1, 0), 2))
        for _ in range(_GEOMETRY_ITER):
            self._set_path(build_path(plan, corr))
            self._solve_lat_lon(origin[:2])
            t = np.array([a for a, _, _ in self.path.strips])
            lla = np.column_stack([self._lat_lon(t), np.full(n, origin[2])])
            err = planned - earth.ned_offset(origin, lla)[:, :2]
            self.strip_start_error_m = err
            if n < 2 or np.abs(err).max() < GEOMETRY_TOL:
                break
            d = np.diff(err, axis=0)
            corr[:, 0] += d @ right
            corr[:, 1] += np.sum(d * direction[1:], axis=1)

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
    def _profiles(self, t):
        """(n, 9): psi, psi_dot, psi_ddot (rad, /s, /s^2), V, V_dot (m/s, m/s^2), up,
        up_dot (climb up-speed, m/s, m/s^2), s, s_dot (airborne weight); and (n, 2): the
        climb (m, upward) and s_ddot."""
        v = self._pp(t)
        prof = v[:, [0, 1, 2, 3, 4, 6, 7, 8, 9]]
        prof[:, 0] += self.path.psi0
        prof[:, 5:7] *= -1.0
        return prof, v[:, [5, 10]]

    def _vertical(self, t, prof=None):
        """h (m), v_down (m/s), a_down (m/s^2) with the heave weighted by ``air``."""
        prof, extra = prof or self._profiles(t)
        up, up_dot, s, ds = prof[:, 5], prof[:, 6], prof[:, 7], prof[:, 8]
        climb, dds = extra[:, 0], extra[:, 1]
        hv = self._turb["heave"](t)
        h = self.path.h0 - climb + s * hv[:, 0]
        vd = -up - (ds * hv[:, 0] + s * hv[:, 1])
        ad = -up_dot - (dds * hv[:, 0] + 2 * ds * hv[:, 1] + s * hv[:, 2])
        return h, vd, ad

    def _rhs(self, t, y):
        t = np.array([t])
        prof = self._profiles(t)
        psi, V = prof[0][0, 0], prof[0][0, 3]
        h = self._vertical(t, prof)[0][0]
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

    def _state(self, t_abs):
        """Everything at ``t_abs`` (GPS s): lla, v_n, a_n and the kernel's outputs."""
        t_abs = np.atleast_1d(np.asarray(t_abs, dtype=float))
        if np.any(t_abs < self.t_start - 1e-9) or np.any(t_abs > self.t_end + 1e-9):
            raise ValueError(f"time outside the flight [{self.t_start}, {self.t_end}] s")
        t = t_abs - self.t0
        prof_all = self._profiles(t)
        prof = prof_all[0]
        psi, psi_dot, V, V_dot = prof[:, 0], prof[:, 1], prof[:, 3], prof[:, 4]
        h, vd, ad = self._vertical(t, prof_all)
        lla = np.column_stack([self._lat_lon(t), h])
        c, s = np.cos(psi), np.sin(psi)
        v_n = np.column_stack([V * c, V * s, vd])
        a_n = np.column_stack([V_dot * c - V * psi_dot * s, V_dot * s + V * psi_dot * c, ad])
        turb = np.empty((len(t), 6))
        turb_lag = np.empty((len(t), 6))
        for j, name in enumerate(("roll", "pitch", "yaw")):
            v = self._turb[name](t)
            turb[:, 2 * j:2 * j + 2] = v[:, :2]
            turb_lag[:, 2 * j:2 * j + 2] = v[:, 3:]
        enabled = self.plan.mount.enabled
        # the servos: slow parts delayed by tau, turbulence through the exact lag response
        prof_lag = self._profiles(t - self._tau)[0] if enabled and self._tau > 0 else prof
        n = len(t)
        out = dict(C_na=np.empty((n, 3, 3)), C_nb=np.empty((n, 3, 3)),
                   mount=np.empty((n, 3)), mount_rate=np.empty((n, 3)),
                   w_ib_b=np.empty((n, 3)), f_b=np.empty((n, 3)))
        _kernels.platform_state(prof, prof_lag, turb, turb_lag, *self._wind, G_TURN,
                                lla[:, 0].copy(), h, v_n, a_n, self._limits, KNEE, enabled,
                                **out)
        return t_abs, lla, v_n, a_n, out

    def rates(self, time):
        """``w_ib_b`` (rad/s) and ``f_b`` (m/s^2), shape (n, 3), at ``time`` (GPS s)."""
        out = self._state(time)[-1]
        return out["w_ib_b"], out["f_b"]

    def evaluate(self, time):
        """True state at ``time`` (GPS s, scalar or array within [t_start, t_end]).

        Returns
        -------
        TruthSample
        """
        t_abs, lla, v_n, a_n, out = self._state(time)
        return TruthSample(time=t_abs, lla=lla, v_n=v_n, a_n=a_n,
                           q_nb=dcm_to_quat(out["C_nb"]), w_ib_b=out["w_ib_b"],
                           f_b=out["f_b"], q_na=dcm_to_quat(out["C_na"]),
                           mount_rpy=out["mount"], mount_rate=out["mount_rate"])

    def C_nb(self, time):
        """``C_nb`` (n, 3, 3) at ``time`` (GPS s)."""
        return self._state(time)[-1]["C_nb"]


def build_truth(plan):
    """The :class:`FlightTruth` of a :class:`~ins.simulate.plan_model.FlightPlan`."""
    return FlightTruth(plan)
