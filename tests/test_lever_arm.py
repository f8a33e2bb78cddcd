"""Lever arm: l_b(t) and its rate against scipy, antenna position against pymap3d,
Jacobians against numerical perturbation, mount fallback, and the lever-arm paper's
comparison (varying arm against constant arm) on a simulated flight with mount motion."""
import numpy as np
import pymap3d
import pytest
from scipy.spatial.transform import Rotation

from ins.common.errors import InputError
from ins.estimation.core.lever_arm import (
    LeverArm,
    antenna_lla,
    antenna_velocity,
    position_jacobian,
    velocity_jacobian,
)
from ins.io.mount import MountLog, read_mount
from ins.nav import earth
from ins.nav.rotation import rotvec_to_dcm, skew

L_BP = np.array([0.1, 0.05, -0.1])
L_AP = np.array([0.5, 0.2, -1.5])


def mount_log(rate_dps=(0.3, -0.2, 2.0), t_end=10.0):
    t = np.arange(0.0, t_end + 1e-9, 0.02)
    rpy_deg = np.outer(t, rate_dps) + np.array([1.0, -2.0, 5.0])
    return MountLog(t, np.deg2rad(rpy_deg)), np.asarray(rate_dps)


def test_varying_arm_and_rate_against_scipy():
    log, rate = mount_log()
    arm = LeverArm(L_BP, L_AP, log)
    t = np.array([1.234, 5.5, 9.0])
    l_b, dl_b, valid = arm.at(t)
    assert valid.all()
    rpy_deg = np.outer(t, rate) + np.array([1.0, -2.0, 5.0])
    C_ap = Rotation.from_euler("ZYX", rpy_deg[:, ::-1], degrees=True).as_matrix()
    expect = L_BP + np.einsum("mji,j->mi", C_ap, L_AP)          # C_pa = C_ap^T
    np.testing.assert_allclose(l_b, expect, atol=1e-12)
    h = 1e-4
    C_p = Rotation.from_euler("ZYX", (rpy_deg + rate * h)[:, ::-1], degrees=True).as_matrix()
    C_m = Rotation.from_euler("ZYX", (rpy_deg - rate * h)[:, ::-1], degrees=True).as_matrix()
    d_expect = np.einsum("mji,j->mi", C_p - C_m, L_AP) / (2 * h)
    np.testing.assert_allclose(dl_b, d_expect, atol=1e-7)


def test_missing_mount_data_falls_back_to_static_arm():
    log, _ = mount_log(t_end=5.0)
    arm = LeverArm(L_BP, L_AP, log)
    l_b, dl_b, valid = arm.at([-1.0, 2.0, 7.0])
    assert list(valid) == [False, True, False]
    np.testing.assert_array_equal(l_b[0], L_BP + L_AP)
    np.testing.assert_array_equal(dl_b[2], 0.0)


def test_fixed_arm_when_no_mount():
    l_b, dl_b, valid = LeverArm([0.8, 0.2, -1.5]).at([0.0, 1.0])
    np.testing.assert_array_equal(l_b, [[0.8, 0.2, -1.5]] * 2)
    assert valid.all() and not dl_b.any()


def test_antenna_position_against_pymap3d():
    lla = np.array([np.deg2rad(30.44), np.deg2rad(114.47), 1000.0])
    C_nb = Rotation.from_euler("ZYX", [40.0, 3.0, -10.0], degrees=True).as_matrix()
    l_b = np.array([0.8, 0.2, -1.5])
    ant = antenna_lla(lla, C_nb, l_b)
    d = C_nb @ l_b
    lat, lon, h = pymap3d.ned2geodetic(d[0], d[1], d[2], np.rad2deg(lla[0]),
                                       np.rad2deg(lla[1]), lla[2])
    offset = earth.ned_offset(np.array([np.deg2rad(lat), np.deg2rad(lon), h]), ant)
    assert np.linalg.norm(offset) < 1e-6


def _perturb(C_nb, phi):
    """C_nb_est = (I - [phi x]) C_nb, exactly: Rot(-phi) C_nb."""
    return rotvec_to_dcm(-phi) @ C_nb


def test_position_jacobian_numerically():
    rng = np.random.default_rng(1)
    C_nb = Rotation.from_euler("ZYX", [70.0, 2.0, 5.0], degrees=True).as_matrix()
    l_b = np.array([0.6, 0.25, -1.6])
    H = position_jacobian(C_nb, l_b)
    for _ in range(3):
        dx = np.zeros(21)
        dx[0:3] = rng.normal(0, 0.1, 3)
        dx[6:9] = rng.normal(0, 1e-4, 3)
        r_est = dx[0:3] + _perturb(C_nb, dx[6:9]) @ l_b
        np.testing.assert_allclose(r_est - C_nb @ l_b, H @ dx, atol=1e-7)   # phi^2 |l|


def test_velocity_jacobian_numerically():
    rng = np.random.default_rng(2)
    C_nb = Rotation.from_euler("ZYX", [-120.0, 4.0, 12.0], degrees=True).as_matrix()
    l_b = np.array([0.6, 0.25, -1.6])
    dl_b = np.array([0.01, -0.02, 0.005])
    w_ib_b = np.array([0.05, -0.02, 0.1])
    w_in_n = np.array([5e-5, 1e-5, -4e-5])
    v = np.array([60.0, 3.0, -1.0])
    H = velocity_jacobian(C_nb, w_ib_b, w_in_n, l_b, dl_b)
    v0 = antenna_velocity(v, C_nb, w_ib_b, w_in_n, l_b, dl_b)
    for _ in range(3):
        dx = np.zeros(21)
        dx[3:6] = rng.normal(0, 0.01, 3)
        dx[6:9] = rng.normal(0, 1e-4, 3)
        dx[9:12] = rng.normal(0, 1e-5, 3)            # gyro bias error: truth - estimate
        dx[15:18] = rng.normal(0, 1e-4, 3)           # gyro scale error
        w_est = w_ib_b + dx[9:12] + dx[15:18] * w_ib_b
        v1 = antenna_velocity(v + dx[3:6], _perturb(C_nb, dx[6:9]), w_est, w_in_n, l_b, dl_b)
        np.testing.assert_allclose(v1 - v0, H @ dx, atol=2e-8)     # second order


def test_read_mount_errors(tmp_path):
    p = tmp_path / "mount.txt"
    p.write_text("# time_s roll_deg pitch_deg yaw_deg\n0 0 0 0\n1 0 0 0\n1 0 0 0\n")
    with pytest.raises(InputError, match=r"mount.txt:4: time not increasing"):
        read_mount(p)
    p.write_text("0 0 0 0\n1 0 0 200\n")
    with pytest.raises(InputError, match=r"mount.txt:2: .*180 deg"):
        read_mount(p)
    p.write_text("0 0 0\n")
    with pytest.raises(InputError, match="mount.txt:1"):
        read_mount(p)


def test_varying_arm_beats_constant_arm_on_a_flight_with_mount_motion():
    """The lever-arm paper's comparison (Tables 1 and 2): with the mount moving, the
    constant arm l_bp + l_ap leaves centimetre position errors that the varying arm
    removes; the attitude stays comparable."""
    from test_filter import given_config, short_flight

    from ins.estimation.pipeline.process import process
    folder = short_flight()
    rms = {}
    for varying in (True, False):
        res = process(given_config(folder, varying=varying))
        e = res.errors_smoothed
        sel = e.time > e.time[0] + 60.0
        rms[varying] = (np.sqrt(np.mean(e.pos_n[sel] ** 2, axis=0)),
                        np.sqrt(np.mean(e.att_n[sel] ** 2, axis=0)))
    pos_v, att_v = rms[True]
    pos_c, att_c = rms[False]
    assert np.all(pos_v[:2] < 0.01)                  # mm-level with the varying arm
    assert np.all(pos_c[:2] > 3 * pos_v[:2])         # constant arm: several times worse
    assert np.all(att_v < 2.0 * att_c)               # attitude: comparable, not worse


# --- antenna velocity against the time derivative of the antenna position along an
# analytic trajectory (pymap3d for geodetic -> ECEF, independent Earth model) ----------
_A, _F = 6378137.0, 1 / 298.257223563
_E2 = _F * (2 - _F)
_W = 7.292115e-5
OMEGA = 2 * np.pi / 7.0                      # s^-1: the wiggles of the trajectory


def _trajectory(t):
    """IMU lat, lon (rad), h (m), roll, pitch, yaw (rad) and their time derivatives
    (analytic): a 60 m/s track with wiggles, a turning and rocking body."""
    lat = 0.53 + 9e-6 * t + 2e-6 * np.sin(OMEGA * t)
    lon = 1.99 + 3e-6 * t + 1e-6 * np.cos(OMEGA * t)
    h = 1500.0 + 2.0 * t + 3.0 * np.sin(OMEGA * t)
    d_lat = 9e-6 + 2e-6 * OMEGA * np.cos(OMEGA * t)
    d_lon = 3e-6 - 1e-6 * OMEGA * np.sin(OMEGA * t)
    d_h = 2.0 + 3.0 * OMEGA * np.cos(OMEGA * t)
    rpy = np.array([0.1 * np.sin(OMEGA * t), 0.05 + 0.03 * np.cos(OMEGA * t), 0.7 + 0.05 * t])
    d_rpy = np.array([0.1 * OMEGA * np.cos(OMEGA * t), -0.03 * OMEGA * np.sin(OMEGA * t), 0.05])
    return (lat, lon, h), (d_lat, d_lon, d_h), rpy, d_rpy


def _arm(t):
    """Varying arm l_b (m) and its rate (m/s): a mount turning the antenna around."""
    l0 = np.array([0.6, 1.4, -1.2])
    a = np.array([0.05, -0.04, 0.02])
    return l0 + a * np.sin(1.3 * t), a * 1.3 * np.cos(1.3 * t)


def _C_nb(rpy):
    return Rotation.from_euler("ZYX", rpy[::-1]).as_matrix()


def _antenna_ecef(t):
    (lat, lon, h), _, rpy, _ = _trajectory(t)
    arm_n = _C_nb(rpy) @ _arm(t)[0]
    return np.array(pymap3d.ned2ecef(*arm_n, lat, lon, h, deg=False))


def _inputs(t):
    """Everything antenna_velocity needs, from the analytic trajectory (independent of
    ins.nav.earth): v_n from the lat/lon/h rates, w_ib_b from the Euler rates and w_in_n."""
    (lat, lon, h), (d_lat, d_lon, d_h), rpy, d_rpy = _trajectory(t)
    s = np.sin(lat)
    M = _A * (1 - _E2) / (1 - _E2 * s * s) ** 1.5
    N = _A / np.sqrt(1 - _E2 * s * s)
    v_n = np.array([(M + h) * d_lat, (N + h) * np.cos(lat) * d_lon, -d_h])
    r, p, _ = rpy
    dr, dp, dy = d_rpy
    w_nb_b = np.array([dr - dy * np.sin(p),                      # body rate from the
                       dp * np.cos(r) + dy * np.cos(p) * np.sin(r),   # ZYX Euler rates
                       -dp * np.sin(r) + dy * np.cos(p) * np.cos(r)])
    w_ie = _W * np.array([np.cos(lat), 0.0, -np.sin(lat)])
    w_en = np.array([d_lon * np.cos(lat), -d_lat, -d_lon * np.sin(lat)])
    C = _C_nb(rpy)
    w_ib_b = w_nb_b + C.T @ (w_ie + w_en)
    l_b, dl_b = _arm(t)
    return (lat, lon, h), v_n, C, w_ib_b, w_ie, w_en, l_b, dl_b


def _ecef_rate(f, t, k=0.01):
    """Five-point central difference (truncation and rounding ~1e-7 m/s)."""
    return (-f(t + 2 * k) + 8 * f(t + k) - 8 * f(t - k) + f(t - 2 * k)) / (12 * k)


@pytest.mark.parametrize("t", [0.0, 1.7, 4.2, 8.9])
def test_antenna_velocity_against_the_derivative_of_the_antenna_position(t):
    """antenna_velocity (v + C_nb (w_ib x l + dl/dt) - w_in x C_nb l, conventions.md)
    against d/dt of the antenna's ECEF position, rotated into the IMU's n frame.

    Differentiating ``r_ant = r_imu + C_en C_nb l_b`` exactly gives the Earth rate
    ``- w_ie x (C_nb l_b)`` in that frame (the transport rate of ``C_en`` cancels that of
    ``C_nb``): the formula's ``w_in`` adds ``- w_en x arm`` (2e-5 m/s here, 60 m/s and a
    2 m arm), which is asserted to 3e-7 m/s; the sign of ``w_in x arm`` (3e-4 m/s here)
    is thus decided.  In the receiver's frame (n at the antenna, the lat/lon/h rates
    of the antenna) the formula agrees within ``(|w_en| + |v| / R) |arm|``."""
    (lat, lon, h), v_n, C, w_ib_b, w_ie, w_en, l_b, dl_b = _inputs(t)
    w_in = w_ie + w_en
    arm_n = C @ l_b
    got = antenna_velocity(v_n, C, w_ib_b, w_in, l_b, dl_b)
    d_ecef = _ecef_rate(_antenna_ecef, t)
    truth_imu_n = np.array(pymap3d.ecef2nedv(*d_ecef, lat, lon, deg=False))
    np.testing.assert_allclose(got, truth_imu_n - np.cross(w_en, arm_n), atol=3e-7)
    assert np.linalg.norm(np.cross(w_in, arm_n)) > 300 * 3e-7           # the term is seen
    # in the receiver's frame: antenna lat/lon/h rates -> NED at the antenna
    def geodetic(tt):
        return np.array(pymap3d.ecef2geodetic(*_antenna_ecef(tt), deg=False))
    lat_a, _, h_a = geodetic(t)
    d_lat, d_lon, d_h = _ecef_rate(geodetic, t)
    s = np.sin(lat_a)
    M = _A * (1 - _E2) / (1 - _E2 * s * s) ** 1.5
    N = _A / np.sqrt(1 - _E2 * s * s)
    truth_ant_n = np.array([(M + h_a) * d_lat, (N + h_a) * np.cos(lat_a) * d_lon, -d_h])
    bound = (np.linalg.norm(w_en) + np.linalg.norm(v_n) / 6.3e6) * np.linalg.norm(l_b)
    assert np.linalg.norm(got - truth_ant_n) < bound + 1e-6, (got - truth_ant_n, bound)


def test_velocity_jacobian_by_central_differences_column_by_column():
    """Every column of the velocity Jacobian against a central difference of
    antenna_velocity (second-order terms cancel: 1e-9 agreement), so that a term as
    small as [w_in x][arm x] phi (1e-4 m/s per rad here) is decided."""
    C_nb = Rotation.from_euler("ZYX", [-120.0, 4.0, 12.0], degrees=True).as_matrix()
    l_b = np.array([0.6, 0.25, -1.6])
    dl_b = np.array([0.01, -0.02, 0.005])
    w_ib_b = np.array([0.05, -0.02, 0.1])
    w_in_n = np.array([6.3e-5, 1e-5, -4e-5])
    v = np.array([60.0, 3.0, -1.0])

    def vel(dx):
        w_est = w_ib_b + dx[9:12] + dx[15:18] * w_ib_b
        return antenna_velocity(v + dx[3:6], _perturb(C_nb, dx[6:9]), w_est, w_in_n, l_b, dl_b)
    H = velocity_jacobian(C_nb, w_ib_b, w_in_n, l_b, dl_b)
    for j in range(21):
        step = np.zeros(21)
        step[j] = 1e-4
        np.testing.assert_allclose((vel(step) - vel(-step)) / 2e-4, H[:, j], atol=1e-9,
                                   err_msg=f"velocity column {j}")
    term = np.abs(skew(w_in_n) @ skew(C_nb @ l_b)).max()
    assert term > 1e4 * 1e-9


def test_one_epoch_antenna_position_equals_the_stacked_form():
    """antenna_lla_one (the filter's path, arm given in n) gives antenna_lla's bits."""
    from ins.estimation.core.lever_arm import antenna_lla, antenna_lla_one
    from ins.nav.rotation import euler_to_dcm
    rng = np.random.default_rng(3)
    for _ in range(200):
        lla = np.array([rng.uniform(-1.4, 1.4), rng.uniform(-3.1, 3.1), rng.uniform(-100, 9000)])
        C = euler_to_dcm(rng.uniform(-3, 3, 3))
        l_b = rng.normal(0.0, 2.0, 3)
        assert np.array_equal(antenna_lla_one(lla, C @ l_b), antenna_lla(lla, C, l_b))
