"""A simulated car for the land-vehicle tests (non-holonomic constraint, IMU mounting,
dual-antenna heading): an analytic drive whose velocity lies along the vehicle's forward
axis at every instant, with an IMU mounted at a known rotation ``C_vb``.

The truth is written from its definition, not from the toolkit's mechanization: speed
``u(t)``, heading ``psi(t)`` (smooth raised-cosine turns) and road pitch ``theta(t)``
are closed-form; ``v_n = u (cos th cos psi, cos th sin psi, -sin th)``; ``C_nv = Rz(psi)
Ry(theta)``; ``C_nb = C_nv C_vb``; the position integrates ``D^-1 v_n`` (scipy
``solve_ivp``, DOP853, tight tolerances).  The IMU sees ``w_ib_b = C_bn (w_ie + w_en) +
C_bv w_nv_v`` and ``f_b = C_bn (a_n + (2 w_ie + w_en) x v_n - g_n)`` with the analytic
``a_n``; :func:`ins.simulate.imu_synth.synthesize_imu` integrates them (duck-typed
``rates``).  Only the Earth model (WGS84 radii, normal gravity, Earth rate) is shared
with the filter.
"""

import numpy as np
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from ins.nav import earth
from ins.simulate.ground import GroundTruth

T0 = 300000.0
DURATION_S = 240.0
LLA0 = (np.deg2rad(30.5), np.deg2rad(114.3), 20.0)
PSI0 = np.deg2rad(30.0)
#: (centre s after the start, duration s, heading change deg) of the turns
TURNS = ((40.0, 10.0, 90.0), (100.0, 8.0, -90.0), (150.0, 15.0, 180.0), (205.0, 6.0, -45.0))
SPEED_MPS, SPEED_AMP_MPS, SPEED_PERIOD_S = 15.0, 3.0, 40.0
GRADE_AMP_DEG, GRADE_PERIOD_S = 2.0, 50.0


class CarTruth(GroundTruth):
    """The drive of the module notes with the IMU mounted at ``mounting_rpy_deg`` (the
    IMU's roll, pitch, yaw in the vehicle axes: ``C_vb = Rz(y) Ry(p) Rx(r)``, built here
    with scipy's intrinsic "ZYX" Euler angles).  Its own profiles; the IMU's rates and the
    truth at given epochs as for any ground journey (:class:`ins.simulate.ground.GroundTruth`)."""

    def __init__(self, mounting_rpy_deg=(0.0, 0.0, 0.0), duration_s=DURATION_S):
        self.t_start, self.t_end = T0, T0 + duration_s
        self.C_vb = Rotation.from_euler("ZYX", np.asarray(mounting_rpy_deg)[::-1],
                                        degrees=True).as_matrix()
        self.sol = solve_ivp(lambda t, y: earth.lla_rate(y[0], y[2], self._kin(t)[0]),
                             (self.t_start, self.t_end), np.array(LLA0), method="DOP853",
                             rtol=1e-12, atol=1e-13, dense_output=True)

    # speed, heading, grade and their rates (closed form)
    def _profiles(self, t):
        s = np.asarray(t, dtype=float) - self.t_start
        w = 2 * np.pi / SPEED_PERIOD_S
        u = SPEED_MPS + SPEED_AMP_MPS * np.sin(w * s)
        du = SPEED_AMP_MPS * w * np.cos(w * s)
        psi, dpsi = np.full_like(s, PSI0), np.zeros_like(s)
        for c, d, a in TURNS:
            x = np.clip(s - c + d / 2, 0.0, d)
            a = np.deg2rad(a)
            psi = psi + a * (x / d - np.sin(2 * np.pi * x / d) / (2 * np.pi))
            inside = (s > c - d / 2) & (s < c + d / 2)
            dpsi = dpsi + np.where(inside, a / d * (1 - np.cos(2 * np.pi * x / d)), 0.0)
        wg = 2 * np.pi / GRADE_PERIOD_S
        th = np.deg2rad(GRADE_AMP_DEG) * np.sin(wg * s)
        dth = np.deg2rad(GRADE_AMP_DEG) * wg * np.cos(wg * s)
        return u, du, psi, dpsi, th, dth

    def _kin(self, t):
        """``v_n``, ``a_n`` (n, 3) and ``C_nv`` (n, 3, 3), ``w_nv_v`` (n, 3)."""
        u, du, psi, dpsi, th, dth = (np.atleast_1d(x) for x in self._profiles(t))
        cp, sp, ct, st = np.cos(psi), np.sin(psi), np.cos(th), np.sin(th)
        d = np.column_stack([ct * cp, ct * sp, -st])
        dd = np.column_stack([-st * dth * cp - ct * sp * dpsi, -st * dth * sp + ct * cp * dpsi,
                              -ct * dth])
        v_n = u[:, None] * d
        a_n = du[:, None] * d + u[:, None] * dd
        C_nv = Rotation.from_euler("ZYX", np.column_stack([psi, th, np.zeros_like(th)])
                                   ).as_matrix()
        # C_nv = Rz(psi) Ry(th): body rates of the Euler angles (roll 0)
        w_nv_v = np.column_stack([-dpsi * st, dth, dpsi * ct])
        return v_n.squeeze() if np.ndim(t) == 0 else v_n, a_n, C_nv, w_nv_v


#: The walk: (centre s after the start, duration s, heading change deg) of its turns, and
#: (start s, duration s) of its stops (speed down to 0 over STOP_RAMP_S before each,
#: back up over STOP_RAMP_S after).
WALK_TURNS = ((20.0, 3.0, 90.0), (45.0, 4.0, -90.0), (62.0, 2.5, 120.0), (85.0, 3.0, -60.0),
              (118.0, 5.0, 180.0), (140.0, 3.0, -90.0), (160.0, 2.0, 45.0))
WALK_STOPS = ((32.0, 4.0), (100.0, 6.0), (150.0, 3.0))
WALK_SPEED_MPS, WALK_SPEED_AMP_MPS, WALK_SPEED_PERIOD_S = 1.5, 0.2, 13.0
STOP_RAMP_S = 1.5


def _ramp(x, d):
    """Raised-cosine step from 0 (x <= 0) to 1 (x >= d) and its derivative."""
    y = np.clip(x / d, 0.0, 1.0)
    inside = (x > 0) & (x < d)
    return 0.5 * (1 - np.cos(np.pi * y)), np.where(inside, 0.5 * np.pi / d * np.sin(np.pi * y),
                                                   0.0)


class WalkTruth(CarTruth):
    """A walk on level ground: about 1.5 m/s (+-0.2 m/s over 13 s), turns of 45 to 180
    deg in 2 to 5 s, and stops of 3 to 6 s (WALK_TURNS, WALK_STOPS), the IMU held at
    ``mounting_rpy_deg`` in the walker's forward-right-down axes."""

    def __init__(self, mounting_rpy_deg=(0.0, 0.0, 0.0), duration_s=180.0):
        super().__init__(mounting_rpy_deg, duration_s)

    def _profiles(self, t):
        s = np.asarray(t, dtype=float) - self.t_start
        w = 2 * np.pi / WALK_SPEED_PERIOD_S
        u0 = WALK_SPEED_MPS + WALK_SPEED_AMP_MPS * np.sin(w * s)
        du0 = WALK_SPEED_AMP_MPS * w * np.cos(w * s)
        gate, dgate = np.ones_like(s), np.zeros_like(s)
        for a, d in WALK_STOPS:            # gate = 1 - down(s) + up(s), 0 while stopped
            down, ddown = _ramp(s - (a - STOP_RAMP_S), STOP_RAMP_S)
            up, dup = _ramp(s - (a + d), STOP_RAMP_S)
            gate, dgate = gate - down + up, dgate - ddown + dup
        u, du = u0 * gate, du0 * gate + u0 * dgate
        psi, dpsi = np.full_like(s, PSI0), np.zeros_like(s)
        for c, d, a in WALK_TURNS:
            x = np.clip(s - c + d / 2, 0.0, d)
            a = np.deg2rad(a)
            psi = psi + a * (x / d - np.sin(2 * np.pi * x / d) / (2 * np.pi))
            inside = (s > c - d / 2) & (s < c + d / 2)
            dpsi = dpsi + np.where(inside, a / d * (1 - np.cos(2 * np.pi * x / d)), 0.0)
        zero = np.zeros_like(s)
        return u, du, psi, dpsi, zero, zero
