"""Mount-angle interpolation against analytic truth: an angle crossing +-180 deg is
interpolated the short way (issue 12 red flag), and the lever arm built on it stays
smooth there."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ins.estimation.core.lever_arm import LeverArm
from ins.io.mount import MountLog, read_mount

YAW_RATE_DPS = 4.0


def _true_rpy_deg(t):
    """A mount that rolls and pitches a little and yaws steadily through 180 deg at
    t = 2.49 s (half-way between two log epochs) (the log stores angles in (-180, 180], as a mount controller writes them)."""
    roll = 0.5 * np.sin(0.7 * t)
    pitch = -0.3 + 0.2 * np.cos(0.4 * t)
    yaw = 170.04 + YAW_RATE_DPS * t                      # 170 .. 190 deg over 5 s
    return np.column_stack([roll, pitch, (yaw + 180.0) % 360.0 - 180.0]), yaw


@pytest.fixture
def log():
    t = np.arange(0.0, 5.0 + 1e-9, 0.02)                  # 50 Hz
    rpy_deg, _ = _true_rpy_deg(t)
    assert rpy_deg[:, 2].max() > 179.0 and rpy_deg[:, 2].min() < -179.0   # the wrap is in
    return MountLog(t, np.deg2rad(rpy_deg))


def test_yaw_crossing_180_is_interpolated_the_short_way(log):
    t = np.linspace(0.01, 4.99, 997)                      # between the log's epochs
    rpy, valid = log.angles(t)
    assert valid.all()
    _, yaw_true = _true_rpy_deg(t)
    # distance on the circle to the true yaw (linear in t, so linear interpolation is exact)
    err = np.angle(np.exp(1j * (rpy[:, 2] - np.deg2rad(yaw_true))))
    assert np.abs(err).max() < 1e-12
    assert np.all((rpy[:, 2] > -np.pi) & (rpy[:, 2] <= np.pi))
    # the interval that holds the wrap: half-way between 179.96 and -179.96 deg is 180
    k = int(np.flatnonzero(np.abs(np.diff(log.rpy[:, 2])) > np.pi)[0])
    assert np.rad2deg(log.rpy[k, 2]) == pytest.approx(179.96)
    mid = 0.5 * (log.time[k] + log.time[k + 1])
    assert abs(abs(np.rad2deg(log.angles(mid)[0][0, 2])) - 180.0) < 1e-9


def test_C_ap_against_scipy_at_the_crossing(log):
    """C_ap = Rz(yaw) Ry(pitch) Rx(roll) of the interpolated angles against scipy's
    ZYX matrix of the true ones; the naive (unwrapped) interpolation is ~180 deg off."""
    t = np.linspace(2.4, 2.6, 41)
    C_ap, valid = log.C_ap(t)
    rpy_deg, yaw = _true_rpy_deg(t)
    ref = Rotation.from_euler("ZYX", np.column_stack([yaw, rpy_deg[:, 1], rpy_deg[:, 0]]),
                              degrees=True)
    # roll and pitch are smooth: linear interpolation over 20 ms errs by < dt^2/8 |a''|
    err = np.linalg.norm((Rotation.from_matrix(C_ap) * ref.inv()).as_rotvec(), axis=1)
    assert valid.all() and np.rad2deg(err).max() < 1e-4


def test_lever_arm_rate_is_smooth_across_the_crossing(log):
    """dl_b/dt (central difference of C_ap in ins.estimation.core.lever_arm) against the analytic rate of
    l_b = l_bp + C_pa l_ap: a wrong-way interpolation made it ~ 2 pi |l_ap| / 0.02 s."""
    l_bp, l_ap = np.array([0.1, 0.0, -0.2]), np.array([0.4, 0.2, -1.5])
    arm = LeverArm(l_bp, l_ap, mount=log)
    t = np.linspace(2.3, 2.7, 81)
    l_b, dl_b, valid = arm.at(t)
    h = 1e-6
    exact = []
    for s in (t + h, t - h):
        rpy_deg, yaw = _true_rpy_deg(s)
        R = Rotation.from_euler("ZYX", np.column_stack([yaw, rpy_deg[:, 1], rpy_deg[:, 0]]),
                                degrees=True)
        exact.append(l_bp + R.inv().apply(l_ap))
    rate_true = (exact[0] - exact[1]) / (2 * h)
    assert valid.all()
    # |l_ap horizontal| * yaw rate = 0.03 m/s; the interpolation's piecewise-linear angles bend the
    # central difference by at most ~|l_ap| |roll''| dt  -> 1e-4 m/s
    assert np.abs(rate_true).max() > 0.02
    assert np.abs(dl_b - rate_true).max() < 1e-3
    assert np.abs(l_b - 0.5 * (exact[0] + exact[1])).max() < 1e-4


def test_read_mount_then_interpolate_across_the_wrap(tmp_path):
    p = tmp_path / "mount.txt"
    p.write_text("# time_s roll_deg pitch_deg yaw_deg\n"
                 "0.0 0.0 0.0 178.0\n"
                 "1.0 0.0 0.0 -178.0\n"
                 "2.0 1.0 -1.0 -176.0\n")
    log = read_mount(p)
    rpy, valid = log.angles([0.25, 0.5, 0.75, 1.5])
    assert valid.all()
    np.testing.assert_allclose(np.rad2deg(rpy[:, 2]), [179.0, 180.0, -179.0, -177.0],
                               atol=1e-9)
    np.testing.assert_allclose(np.rad2deg(rpy[3, :2]), [0.5, -0.5], atol=1e-12)
