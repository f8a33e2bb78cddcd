"""GNSS antenna of the simulator: varying lever arm of the stabilized mount, antenna
position and velocity against independent computations, noise, outages, file."""
from pathlib import Path

import numpy as np
import pymap3d
import pytest
from scipy.spatial.transform import Rotation

from ins.io.gnss import read_gnss, write_gnss
from ins.nav.earth import ned_offset
from ins.nav.rotation import euler_to_dcm
from ins.simulate.gnss import antenna_state, gnss_times, lever_arm_b, simulate_gnss

PLAN = Path(__file__).parent / "data" / "flights" / "short.toml"
L_BP = np.array([0.1, -0.05, -0.2])
L_AP = np.array([0.4, 0.2, -1.5])


@pytest.fixture(scope="module")
def truth():
    from ins.simulate.plan_read import load_plan
    from ins.simulate.truth import build_truth
    return build_truth(load_plan(PLAN))


def _mount_motion(t):
    rpy = np.column_stack([0.05 * np.sin(t), 0.03 * np.cos(1.3 * t), 0.4 * np.sin(0.2 * t)])
    rate = np.column_stack([0.05 * np.cos(t), -0.039 * np.sin(1.3 * t), 0.08 * np.cos(0.2 * t)])
    return rpy, rate


def test_lever_arm_geometry_and_rate():
    t = np.linspace(0.0, 10.0, 41)
    rpy, rate = _mount_motion(t)
    l_b, dl_b = lever_arm_b(rpy, rate, L_BP, L_AP)
    # l_b = l_bp + C_pa l_ap with C_ap = Rz Ry Rx (ins.nav.rotation.euler_to_dcm)
    assert np.allclose(l_b, L_BP + np.einsum("nji,j->ni", euler_to_dcm(rpy), L_AP), atol=1e-14)
    # mount at zero: the fixed arm l_bp + l_ap
    l0, dl0 = lever_arm_b(np.zeros((1, 3)), np.zeros((1, 3)), L_BP, L_AP)
    assert np.allclose(l0[0], L_BP + L_AP) and np.all(dl0 == 0)
    h = 1e-5
    lp, _ = lever_arm_b(_mount_motion(t + h)[0], rate, L_BP, L_AP)
    lm, _ = lever_arm_b(_mount_motion(t - h)[0], rate, L_BP, L_AP)
    assert np.abs(dl_b).max() > 0.05
    assert np.allclose((lp - lm) / (2 * h), dl_b, atol=1e-9)


def _independent_antenna_ecef(s, l_bp=L_BP, l_ap=L_AP):
    """Antenna ECEF position (m) written without ins: the mount's C_ap = Rz Ry Rx from
    scipy's ZYX Euler angles, C_nb from scipy's quaternion, and pymap3d's NED -> ECEF."""
    C_ap = Rotation.from_euler("ZYX", s.mount_rpy[:, ::-1])
    l_b = l_bp + C_ap.inv().apply(l_ap)
    arm_n = Rotation.from_quat(s.q_nb).apply(l_b)
    lat, lon, h = s.lla.T
    return np.column_stack(pymap3d.ned2ecef(arm_n[:, 0], arm_n[:, 1], arm_n[:, 2],
                                            lat, lon, h, deg=False)), arm_n


def test_antenna_position_is_exact(truth):
    t = np.linspace(truth.t_start, truth.t_end, 25)
    s = truth.evaluate(t)
    lla_ant, _ = antenna_state(s, L_BP, L_AP)
    r_ref, arm_n = _independent_antenna_ecef(s)
    r_ant = np.column_stack(pymap3d.geodetic2ecef(lla_ant[:, 0], lla_ant[:, 1], lla_ant[:, 2],
                                                  deg=False))
    assert np.abs(r_ant - r_ref).max() < 1e-6
    n, e, d = pymap3d.geodetic2ned(lla_ant[:, 0], lla_ant[:, 1], lla_ant[:, 2],
                                   s.lla[:, 0], s.lla[:, 1], s.lla[:, 2], deg=False)
    assert np.allclose(np.column_stack([n, e, d]), arm_n, atol=1e-6)
    assert np.abs(np.rad2deg(s.mount_rpy)).max() > 0.5      # the mount really moves
    # and the arm really turns with it: against the fixed arm, centimetres
    fixed = Rotation.from_quat(s.q_nb).apply(L_BP + L_AP)
    assert np.abs(arm_n - fixed).max() > 0.01


def test_antenna_velocity_against_finite_difference(truth):
    """The lever-arm part of v_ant against the finite difference of the exact antenna
    position minus that of the IMU (which cancels the truth's own velocity).  The
    first-order formula neglects ~|v| |l| / R = 1e-5 m/s."""
    h = 0.02
    t = np.linspace(truth.t_start + 1.0, truth.t_end - 1.0, 60)
    s = truth.evaluate(t)
    _, v_ant = antenna_state(s, L_BP, L_AP)
    sp, sm = truth.evaluate(t + h), truth.evaluate(t - h)
    ant_p, _ = antenna_state(sp, L_BP, L_AP)
    ant_m, _ = antenna_state(sm, L_BP, L_AP)
    fd_ant = ned_offset(s.lla, ant_p) - ned_offset(s.lla, ant_m)
    fd_imu = ned_offset(s.lla, sp.lla) - ned_offset(s.lla, sm.lla)
    fd_arm = (fd_ant - fd_imu) / (2 * h)
    arm_v = v_ant - s.v_n
    assert np.abs(arm_v).max() > 0.02                       # turns and mount motion
    assert np.abs(fd_arm - arm_v).max() < 1e-4


def _exact_antenna_velocity(truth, t, h=0.005):
    """Antenna velocity NED at the antenna (m/s), independent of ins: central difference
    of the independently built ECEF antenna position, rotated by pymap3d (fourth order:
    the truth is smooth, so the difference error is ~h^4 |r^(5)| / 30, far below 1e-6)."""
    r = [_independent_antenna_ecef(truth.evaluate(t + k * h))[0] for k in (-2, -1, 1, 2)]
    v_e = (r[0] - 8 * r[1] + 8 * r[2] - r[3]) / (12 * h)
    lat, lon, _ = pymap3d.ecef2geodetic(*_independent_antenna_ecef(truth.evaluate(t))[0].T,
                                        deg=False)
    return np.column_stack(pymap3d.ecef2nedv(v_e[:, 0], v_e[:, 1], v_e[:, 2], lat, lon,
                                             deg=False))


def test_antenna_velocity_of_simulator_and_processor_against_exact(truth):
    """The simulator's antenna velocity (antenna_state) and the post-processor's
    (ins.estimation.core.lever_arm.LeverArm on the mount log + antenna_velocity) against the exact one.

    Both use the first-order form, which neglects w_en x (C_nb l_b) and the turn of n
    between IMU and antenna, ~|v| |l_b| / R = 1.5e-5 m/s; a wrong sign of its
    w_in x (C_nb l_b) term would be off by 2 |w_ie| |l_b| ~ 2e-4 m/s."""
    from ins.estimation.core.lever_arm import LeverArm, antenna_velocity
    from ins.io.mount import MountLog
    from ins.nav.earth import earth_rate_n, transport_rate_n
    t = np.linspace(truth.t_start + 1.0, truth.t_end - 1.0, 40)
    v_exact = _exact_antenna_velocity(truth, t)
    s = truth.evaluate(t)
    arm_v = v_exact - s.v_n
    assert np.abs(arm_v).max() > 0.02                       # turns and mount motion
    _, v_sim = antenna_state(s, L_BP, L_AP)
    assert np.abs(v_sim - v_exact).max() < 3e-5
    # the post-processor on a dense mount log of the same flight (its own interpolation
    # and central difference of C_ap; 1 kHz keeps their error below 1e-6 m/s)
    tm = np.arange(truth.t_start, truth.t_end, 0.001)
    mount = MountLog(tm, truth.evaluate(tm).mount_rpy)
    l_b, dl_b, valid = LeverArm(L_BP, L_AP, mount=mount).at(t)
    assert valid.all()
    C_nb = Rotation.from_quat(s.q_nb).as_matrix()
    w_in = earth_rate_n(s.lla[:, 0]) + transport_rate_n(s.lla[:, 0], s.lla[:, 2], s.v_n)
    v_proc = antenna_velocity(s.v_n, C_nb, s.w_ib_b, w_in, l_b, dl_b)
    assert np.abs(v_proc - v_exact).max() < 3e-5


def test_gnss_times_and_outages():
    t = gnss_times(100.2, 110.0, 2.0, outages=[(2.0, 1.5)])
    expect = [x / 2 for x in range(201, 221) if not 102.2 <= x / 2 < 103.7]
    assert np.array_equal(t, expect)


def test_noise_statistics_and_file_round_trip(truth, tmp_path):
    time = gnss_times(truth.t_start, truth.t_end, 20.0)
    sigma = np.array([0.02, 0.03, 0.05])
    rng = np.random.default_rng(5)
    log = simulate_gnss(truth, time, L_BP, L_AP, sigma, rng, velocity=True, sigma_vel_mps=0.01)
    lla_true, v_true = antenna_state(truth.evaluate(time), L_BP, L_AP)
    err = ned_offset(lla_true, log.lla)
    assert len(time) > 1000
    assert np.allclose(err.std(axis=0), sigma, rtol=0.1)
    assert np.all(np.abs(err.mean(axis=0)) < 4 * sigma / np.sqrt(len(time)))
    assert np.allclose((log.v_n - v_true).std(axis=0), 0.01, rtol=0.1)
    assert np.array_equal(log.sigma_ned_m, np.tile(sigma, (len(time), 1)))
    path = tmp_path / "gnss.txt"
    write_gnss(path, log)
    back = read_gnss(path)
    assert np.allclose(back.time, log.time, atol=1e-9)
    assert np.abs(ned_offset(log.lla, back.lla)).max() < 1e-4
    assert np.allclose(back.v_n, log.v_n, atol=1e-6)
