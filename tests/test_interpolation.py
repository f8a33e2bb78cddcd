"""Tests of ins.nav.interpolation on a closed-form 200 Hz trajectory (a climbing, banked
constant-rate turn with roll and pitch oscillations)."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from ins.common.errors import InputError
from ins.nav.earth import ned_offset, radii
from ins.nav.interpolation import interpolate_linear, interpolate_trajectory
from ins.nav.rotation import euler_to_quat, quat_conjugate, quat_multiply, quat_to_rotvec
from ins.nav.trajectory import Trajectory

ARCSEC = np.pi / 180 / 3600


class Turn:
    """Closed form: position (rad, m), NED velocity (m/s) and attitude at any t (s)."""

    lat0, lon0, h0 = np.deg2rad(30.5), np.deg2rad(114.3), 1000.0
    w = np.deg2rad(3.0)            # turn rate, rad/s
    speed = 60.0                   # m/s
    roll_amp, roll_f = np.deg2rad(2.0), 0.5     # turbulence: 0.34 rad/s^2
    pitch_amp, pitch_f = np.deg2rad(0.5), 0.3

    def __init__(self, lon0=None):
        if lon0 is not None:
            self.lon0 = lon0
        self.M, self.N = radii(self.lat0)
        self.R = self.speed / self.w

    def lla(self, t):
        return np.column_stack([
            self.lat0 + self.R / self.M * np.sin(self.w * t),
            self.lon0 + self.R / self.N * (1 - np.cos(self.w * t)),
            self.h0 + 2.0 * t + 3.0 * np.sin(0.7 * t)])

    def v_n(self, t):
        lla = self.lla(t)
        rm, rn = radii(lla[:, 0])
        dlat = self.R / self.M * self.w * np.cos(self.w * t)
        dlon = self.R / self.N * self.w * np.sin(self.w * t)
        dh = 2.0 + 2.1 * np.cos(0.7 * t)
        return np.column_stack([dlat * (rm + lla[:, 2]), dlon * (rn + lla[:, 2]) * np.cos(
            lla[:, 0]), -dh])

    def rpy(self, t):
        return np.column_stack([
            np.deg2rad(10.0) + self.roll_amp * np.sin(2 * np.pi * self.roll_f * t),
            np.deg2rad(2.0) + self.pitch_amp * np.sin(2 * np.pi * self.pitch_f * t),
            self.w * t + 0.1])

    def trajectory(self, t):
        return Trajectory(time=np.asarray(t, float), lla=self.lla(t), v_n=self.v_n(t),
                          q_nb=euler_to_quat(self.rpy(t)))


def attitude_error_arcsec(q, q_ref):
    return np.linalg.norm(quat_to_rotvec(quat_multiply(quat_conjugate(q_ref), q)), axis=1) \
        / ARCSEC


TURN = Turn()
T200 = np.arange(0.0, 20.0 + 1e-9, 0.005)
TRAJ = TURN.trajectory(T200)
rng = np.random.default_rng(11)
T_EV = np.sort(rng.uniform(0.0, 20.0, 500))


def test_position_and_velocity_hermite():
    out = interpolate_trajectory(TRAJ, T_EV)
    err_m = np.linalg.norm(ned_offset(TURN.lla(T_EV), out.lla), axis=1)
    assert err_m.max() < 1e-6                    # sub-micrometre at 200 Hz
    assert np.abs(out.v_n - TURN.v_n(T_EV)).max() < 1e-5
    # linear interpolation would be far worse: the test can tell
    lin = interpolate_linear(T200, TRAJ.lla, T_EV)
    assert np.linalg.norm(ned_offset(TURN.lla(T_EV), lin), axis=1).max() > 100 * err_m.max()


def test_attitude_cubic_and_slerp():
    cubic = attitude_error_arcsec(interpolate_trajectory(TRAJ, T_EV).q_nb,
                                  euler_to_quat(TURN.rpy(T_EV)))
    slerp = attitude_error_arcsec(interpolate_trajectory(TRAJ, T_EV, method="slerp").q_nb,
                                  euler_to_quat(TURN.rpy(T_EV)))
    # slerp's error is the constant-rate defect, ~ dt^2/8 |dw/dt|
    bound = 0.005**2 / 8 * TURN.roll_amp * (2 * np.pi * TURN.roll_f) ** 2 / ARCSEC
    assert 0.2 * bound < slerp.max() < 1.5 * bound
    assert cubic.max() < 1e-3                    # "better than slerp": 4th order
    assert cubic.max() < slerp.max() / 100


def test_exact_at_epochs_and_ends():
    t = T200[[0, 1, 1000, -1]]
    out = interpolate_trajectory(TRAJ, t)
    assert_allclose(out.lla, TRAJ.lla[[0, 1, 1000, -1]], rtol=0, atol=1e-12)
    assert attitude_error_arcsec(out.q_nb, TRAJ.q_nb[[0, 1, 1000, -1]]).max() < 1e-9


def test_error_names_event():
    with pytest.raises(InputError, match="event IMG_0002 at t = 25.0 s is outside"):
        interpolate_trajectory(TRAJ, [1.0, 25.0], names=["IMG_0001", "IMG_0002"],
                               path="flight.nav")
    with pytest.raises(InputError, match="flight.nav: event 1 at"):
        interpolate_trajectory(TRAJ, [-1.0], path="flight.nav")
    with pytest.raises(ValueError, match="cubic"):
        interpolate_trajectory(TRAJ, [1.0], method="linear")


def test_longitude_wrap_and_short_trajectory():
    turn = Turn(lon0=np.pi - 3e-7)               # crosses the 180 deg meridian
    t = np.arange(0.0, 2.0, 0.005)
    traj = turn.trajectory(t)
    traj.lla[:, 1] = np.angle(np.exp(1j * traj.lla[:, 1]))
    assert traj.lla[:, 1].min() < 0 < traj.lla[:, 1].max()
    tq = rng.uniform(0, t[-1], 50)
    out = interpolate_trajectory(traj, tq)
    assert np.linalg.norm(ned_offset(turn.lla(tq), out.lla), axis=1).max() < 1e-6
    two = interpolate_trajectory(TURN.trajectory(T200[:2]), [0.0025])   # 2 epochs
    assert attitude_error_arcsec(two.q_nb, euler_to_quat(TURN.rpy(np.array([0.0025])))) < 0.5


def test_inputs_not_modified():
    lla = TRAJ.lla.copy()
    t = T_EV.copy()
    interpolate_trajectory(TRAJ, t)
    assert np.array_equal(lla, TRAJ.lla) and np.array_equal(t, T_EV)
