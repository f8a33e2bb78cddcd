"""Ground journeys of low-cost GNSS/INS users, with their truth in closed form: a consumer
car parked before it drives, and a handheld walk.

A journey is a speed profile ``u(t)`` (smooth steps between rest and motion), a heading
``psi(t)`` (smooth turns), a road grade ``theta(t)`` and, for a walk, the vertical bounce
of the steps ``b(t)`` (down, m, proportional to the speed).  The carrier's velocity lies
along its forward axis, ``v_n = u (cos th cos psi, cos th sin psi, -sin th) + (0, 0, db)``,
its axes are ``C_nv = Rz(psi) Ry(th)`` and the IMU is mounted at ``C_vb`` (a roof box, a
phone held sideways), so ``C_nb = C_nv C_vb``.  The position integrates ``D^-1 v_n``
(scipy ``solve_ivp``, DOP853); the IMU sees ``w_ib_b = C_bn (w_ie + w_en) + C_bv w_nv_v``
and ``f_b = C_bn (a_n + (2 w_ie + w_en) x v_n - g_n)`` with the analytic ``a_n``
(:func:`ins.simulate.imu_synth.synthesize_imu` integrates them).  Only the Earth model is
shared with the filter.

:func:`rtk_fixes` makes what a u-blox RTK receiver logs: antenna positions at 4 Hz with
centimetre sigmas, velocities stamped late by a fixed latency, and outages.
"""
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from ins.io.gnss_log import GnssLog
from ins.nav import earth

__all__ = ["Journey", "GroundTruth", "CONSUMER_CAR", "WALK", "SCENARIOS", "rtk_fixes",
           "write_journey"]


@dataclass(frozen=True)
class Journey:
    """A ground journey (all times in s after its start).

    Attributes
    ----------
    duration_s : float
    speed_steps : tuple of (centre_s, duration_s, change_mps)
        Smooth steps of the speed (raised cosine of the acceleration); the speed is 0
        before the first.
    turns : tuple of (centre_s, duration_s, change_deg)
        Smooth heading changes (clockwise positive, seen from above).
    heading0_deg : float
        Heading at the start, deg from north.
    grade_deg, grade_period_s : float
        Road grade, a sine of this amplitude and period (s) scaled by the speed's
        fraction of full pace (the carrier does not tilt at rest).
    bounce_m, bounce_hz : float
        Vertical bounce of the steps at full speed (amplitude m, frequency Hz).
    mounting_rpy_deg : tuple of 3 float
        The IMU's roll, pitch, yaw in the carrier's axes (``C_vb = Rz Ry Rx``).
    lla0_deg : tuple of 3 float
        Start latitude, longitude (deg), ellipsoidal height (m).
    t0 : float
        GPS second of week of the start.
    outages : tuple of (start_s, duration_s)
        Spans without GNSS records (s after the start).
    """

    duration_s: float
    speed_steps: tuple
    turns: tuple = ()
    heading0_deg: float = 30.0
    grade_deg: float = 0.0
    grade_period_s: float = 60.0
    bounce_m: float = 0.0
    bounce_hz: float = 1.8
    mounting_rpy_deg: tuple = (0.0, 0.0, 0.0)
    lla0_deg: tuple = (30.5, 114.3, 20.0)
    t0: float = 300000.0
    outages: tuple = field(default=())

    def max_speed(self):
        """The speed at full pace (sum of the positive steps), m/s."""
        return float(sum(c for _, _, c in self.speed_steps if c > 0)) or 1.0


#: A consumer car: parked for 40 s, then 4 minutes of town driving with a stop at a
#: light, turns, a 2 deg grade and the IMU in a roof box turned 3 deg from the car's
#: axes; 15 s outages while it moves.
CONSUMER_CAR = Journey(
    duration_s=280.0,
    speed_steps=((45.0, 8.0, 10.0), (75.0, 6.0, 5.0), (140.0, 8.0, -15.0),
                 (165.0, 8.0, 12.0)),
    turns=((60.0, 8.0, 90.0), (100.0, 10.0, -90.0), (190.0, 12.0, 135.0),
           (240.0, 6.0, -45.0)),
    heading0_deg=30.0, grade_deg=2.0, grade_period_s=70.0,
    mounting_rpy_deg=(1.0, -2.0, 3.0),
    outages=((85.0, 15.0), (115.0, 15.0), (200.0, 15.0), (250.0, 15.0)))

#: A handheld walk: 1.5 m/s from a standstill, the phone held 60 deg to the right of the
#: walking direction and pitched down, steps bouncing 3 cm at 1.8 Hz, two stops and
#: turns at the corners; 15 s outages while walking.
WALK = Journey(
    duration_s=240.0,
    speed_steps=((6.0, 3.0, 1.5), (90.0, 2.0, -1.5), (100.0, 2.0, 1.5),
                 (180.0, 2.0, -1.5), (190.0, 2.0, 1.2)),
    turns=((40.0, 4.0, 90.0), (70.0, 3.0, -90.0), (130.0, 4.0, 180.0), (160.0, 3.0, 90.0),
           (215.0, 3.0, -60.0)),
    heading0_deg=300.0, grade_deg=0.5, grade_period_s=80.0,
    bounce_m=0.03, bounce_hz=1.8, mounting_rpy_deg=(5.0, -20.0, 60.0),
    lla0_deg=(-33.9, 151.2, 40.0),
    outages=((45.0, 15.0), (110.0, 15.0), (200.0, 15.0)))


def _smooth_steps(s, steps):
    """Sum of smooth steps at times ``s``: value, first and second derivatives."""
    y, dy, ddy = np.zeros_like(s), np.zeros_like(s), np.zeros_like(s)
    for c, d, a in steps:
        x = np.clip(s - c + d / 2, 0.0, d)
        inside = (s > c - d / 2) & (s < c + d / 2)
        y = y + a * (x / d - np.sin(2 * np.pi * x / d) / (2 * np.pi))
        dy = dy + np.where(inside, a / d * (1 - np.cos(2 * np.pi * x / d)), 0.0)
        ddy = ddy + np.where(inside, a / d * (2 * np.pi / d) * np.sin(2 * np.pi * x / d), 0.0)
    return y, dy, ddy


@dataclass
class Sample:
    """The truth at some epochs: time (s), lla (rad, rad, m), v_n (m/s), q_nb."""
    time: np.ndarray
    lla: np.ndarray
    v_n: np.ndarray
    q_nb: np.ndarray


class GroundTruth:
    """The motion of a :class:`Journey` (``rates`` for the IMU synthesis, ``evaluate``
    for the truth)."""

    def __init__(self, journey):
        self.j = journey
        self.t_start, self.t_end = journey.t0, journey.t0 + journey.duration_s
        self.C_vb = Rotation.from_euler("ZYX", np.asarray(journey.mounting_rpy_deg)[::-1],
                                        degrees=True).as_matrix()
        lla0 = np.array([np.deg2rad(journey.lla0_deg[0]), np.deg2rad(journey.lla0_deg[1]),
                         journey.lla0_deg[2]])
        self.sol = solve_ivp(lambda t, y: earth.lla_rate(y[0], y[2], self._kin(t)[0][0]),
                             (self.t_start, self.t_end), lla0, method="DOP853",
                             rtol=1e-12, atol=1e-13, dense_output=True, max_step=0.05)

    def _kin(self, t):
        """``v_n``, ``a_n`` (n, 3), ``C_nv`` (n, 3, 3), ``w_nv_v`` (n, 3)."""
        j = self.j
        s = np.atleast_1d(np.asarray(t, dtype=float)) - self.t_start
        u, du, ddu = _smooth_steps(s, j.speed_steps)
        turns = [(c, d, np.deg2rad(a)) for c, d, a in j.turns]
        psi, dpsi, _ = _smooth_steps(s, turns)
        psi = psi + np.deg2rad(j.heading0_deg)
        wg, U = 2 * np.pi / j.grade_period_s, j.max_speed()
        r, dr = u / U, du / U                  # the grade changes only while moving
        th = np.deg2rad(j.grade_deg) * np.sin(wg * s) * r
        dth = np.deg2rad(j.grade_deg) * (wg * np.cos(wg * s) * r + np.sin(wg * s) * dr)
        cp, sp, ct, st = np.cos(psi), np.sin(psi), np.cos(th), np.sin(th)
        d = np.column_stack([ct * cp, ct * sp, -st])
        dd = np.column_stack([-st * dth * cp - ct * sp * dpsi, -st * dth * sp + ct * cp * dpsi,
                              -ct * dth])
        v_n = u[:, None] * d
        a_n = du[:, None] * d + u[:, None] * dd
        if j.bounce_m:                              # b = A (u / U) sin(w s), down
            A, U, w = j.bounce_m, j.max_speed(), 2 * np.pi * j.bounce_hz
            sn, cs = np.sin(w * s), np.cos(w * s)
            v_n[:, 2] += A / U * (du * sn + u * w * cs)
            a_n[:, 2] += A / U * (ddu * sn + 2 * du * w * cs - u * w * w * sn)
        C_nv = Rotation.from_euler("ZYX", np.column_stack([psi, th, np.zeros_like(th)])
                                   ).as_matrix()
        w_nv_v = np.column_stack([-dpsi * st, dth, dpsi * ct])
        return v_n, a_n, C_nv, w_nv_v

    def lla(self, t):
        return self.sol.sol(np.atleast_1d(np.asarray(t, float))).T

    def rates(self, time):
        """``w_ib_b`` (rad/s), ``f_b`` (m/s^2), shape (n, 3)."""
        time = np.atleast_1d(np.asarray(time, dtype=float))
        lla = self.lla(time)
        v_n, a_n, C_nv, w_nv_v = self._kin(time)
        C_bn = np.einsum("ji,njk->nik", self.C_vb, np.transpose(C_nv, (0, 2, 1)))
        w_ie = earth.earth_rate_n(lla[:, 0])
        w_en = earth.transport_rate_n(lla[:, 0], lla[:, 2], v_n)
        g_n = earth.gravity_n(lla[:, 0], lla[:, 2])
        w_ib_b = np.einsum("nij,nj->ni", C_bn, w_ie + w_en) + w_nv_v @ self.C_vb
        f_b = np.einsum("nij,nj->ni", C_bn, a_n + np.cross(2 * w_ie + w_en, v_n) - g_n)
        return w_ib_b, f_b

    def evaluate(self, time):
        """The truth at ``time`` (s): :class:`Sample`."""
        time = np.atleast_1d(np.asarray(time, dtype=float))
        v_n, _, C_nv, _ = self._kin(time)
        C_nb = C_nv @ self.C_vb
        return Sample(time, self.lla(time), v_n, Rotation.from_matrix(C_nb).as_quat())


def rtk_fixes(truth, rate_hz=4.0, sigma_ned_m=(0.01, 0.01, 0.02), sigma_vel_mps=0.03,
              velocity_latency_s=0.125, lever_b_m=(0.0, 0.0, 0.0), seed=0):
    """Antenna fixes of an RTK receiver along ``truth`` (a :class:`GroundTruth`).

    Positions at ``rate_hz`` with Gaussian noise of ``sigma_ned_m``; velocities with
    ``sigma_vel_mps`` that are ``velocity_latency_s`` late (the record stamped t holds the
    velocity of t - latency, as u-blox receivers log them); no record in the journey's
    outages.  The antenna sits at ``lever_b_m`` (IMU body FRD, m).

    Returns
    -------
    ins.io.gnss_log.GnssLog
    """
    j = truth.j
    t = truth.t_start + np.arange(1.0, j.duration_s - 0.5, 1.0 / rate_hz)
    rel = t - truth.t_start
    keep = np.ones(len(t), bool)
    for a, n in j.outages:
        keep &= ~((rel >= a) & (rel < a + n))
    t = t[keep]
    s = truth.evaluate(t)
    C_nb = Rotation.from_quat(s.q_nb).as_matrix()
    l_n = C_nb @ np.asarray(lever_b_m, float)
    rng = np.random.default_rng(seed)
    sig = np.asarray(sigma_ned_m, float)
    lla = earth.offset_lla(s.lla, l_n + rng.standard_normal((len(t), 3)) * sig)
    tl = t - velocity_latency_s
    h = 1e-3                            # the antenna's velocity: the IMU's + d(C_nb l_b)/dt
    C_p, C_m = (Rotation.from_quat(truth.evaluate(tl + e).q_nb).as_matrix() for e in (h, -h))
    v = (truth.evaluate(tl).v_n + (C_p - C_m) @ np.asarray(lever_b_m, float) / (2 * h)
         + rng.standard_normal((len(t), 3)) * sigma_vel_mps)
    return GnssLog(t, lla, np.tile(sig, (len(t), 1)), v, np.full((len(t), 3), sigma_vel_mps))


#: The scenarios of ``bench/bench_low_cost.py`` and the tests: journey, IMU rate (Hz),
#: the antenna's lever arm in the IMU body (m), the simulator's IMU grade.
SCENARIOS = {
    "consumer-car": (CONSUMER_CAR, 100.0, (-0.3, 0.2, -0.4), "consumer"),
    "walk": (WALK, 167.0, (0.0, 0.0, -0.15), "consumer"),
}


def write_journey(name, folder, seed=0, velocity_latency_s=0.125):
    """Write scenario ``name`` of :data:`SCENARIOS` into ``folder`` as a user has it:
    ``imu.txt`` (KF-GINS text), ``gnss.txt`` (positions and velocities, KF-GINS text),
    ``truth.nav`` and ``config.toml`` with only the facts of the hardware (files, the
    antenna's lever arm, the receiver's velocity latency as ``[gnss]
    velocity_time_shift_s``, and for the car the IMU's mounting in the vehicle).

    Returns ``(truth, journey, config_path)``.
    """
    from pathlib import Path

    from ins.io.gnss import write_gnss
    from ins.io.imu_files import write_kfgins_text
    from ins.io.navfiles import write_nav
    from ins.nav.trajectory import Trajectory
    from ins.simulate.imu_synth import synthesize_imu
    from ins.simulate.sensor_errors import ImuErrorModel, apply_errors
    journey, rate_hz, lever_b, grade = SCENARIOS[name]
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    truth = GroundTruth(journey)
    imu = apply_errors(synthesize_imu(truth, rate_hz), ImuErrorModel.preset(grade),
                       seed=seed)
    write_kfgins_text(folder / "imu.txt", imu)
    write_gnss(folder / "gnss.txt", rtk_fixes(truth, lever_b_m=lever_b, seed=seed + 100,
                                              velocity_latency_s=velocity_latency_s))
    t = np.arange(truth.t_start, truth.t_end, 0.1)
    s = truth.evaluate(t)
    write_nav(folder / "truth.nav", Trajectory(t, s.lla, s.v_n, s.q_nb))
    facts = ('[files]\nimu = "imu.txt"\ngnss = "gnss.txt"\n'
             f"[gnss]\nlever_arm_b_m = {list(lever_b)}\n"
             f"velocity_time_shift_s = {-float(velocity_latency_s)!r}\n")
    if name == "consumer-car":
        facts += f"[vehicle]\nmounting_rpy_deg = {list(journey.mounting_rpy_deg)}\n"
    (folder / "config.toml").write_text(facts)
    return truth, journey, folder / "config.toml"
