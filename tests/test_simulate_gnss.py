"""GNSS antenna of the simulator: varying lever arm of the stabilized mount, antenna
position and velocity against independent computations, noise, outages, file."""
from pathlib import Path

import numpy as np
import pymap3d
import pytest

from ins.earth import ned_offset
from ins.gnss import read_gnss, write_gnss
from ins.rotation import euler_to_dcm, quat_to_dcm
from ins.simulate.gnss import antenna_state, gnss_times, lever_arm_b, simulate_gnss

PLAN = Path(__file__).parent / "data" / "flights" / "short.toml"
L_BP = np.array([0.1, -0.05, -0.2])
L_AP = np.array([0.4, 0.2, -1.5])


@pytest.fixture(scope="module")
def truth():
    from ins.simulate.plan import load_plan
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
    # l_b = l_bp + C_pa l_ap with C_ap = Rz Ry Rx (ins.rotation.euler_to_dcm)
    assert np.allclose(l_b, L_BP + np.einsum("nji,j->ni", euler_to_dcm(rpy), L_AP), atol=1e-14)
    # mount at zero: the fixed arm l_bp + l_ap
    l0, dl0 = lever_arm_b(np.zeros((1, 3)), np.zeros((1, 3)), L_BP, L_AP)
    assert np.allclose(l0[0], L_BP + L_AP) and np.all(dl0 == 0)
    h = 1e-5
    lp, _ = lever_arm_b(_mount_motion(t + h)[0], rate, L_BP, L_AP)
    lm, _ = lever_arm_b(_mount_motion(t - h)[0], rate, L_BP, L_AP)
    assert np.abs(dl_b).max() > 0.05
    assert np.allclose((lp - lm) / (2 * h), dl_b, atol=1e-9)


def test_antenna_position_is_exact(truth):
    t = np.linspace(truth.t_start, truth.t_end, 25)
    s = truth.evaluate(t)
    lla_ant, _ = antenna_state(s, L_BP, L_AP)
    l_b, _ = lever_arm_b(s.mount_rpy, s.mount_rate, L_BP, L_AP)
    arm_n = np.einsum("nij,nj->ni", quat_to_dcm(s.q_nb), l_b)
    n, e, d = pymap3d.geodetic2ned(lla_ant[:, 0], lla_ant[:, 1], lla_ant[:, 2],
                                   s.lla[:, 0], s.lla[:, 1], s.lla[:, 2], deg=False)
    assert np.allclose(np.column_stack([n, e, d]), arm_n, atol=1e-6)
    assert np.abs(np.rad2deg(s.mount_rpy)).max() > 0.5      # the mount really moves


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


def test_velocity_matches_processing_lever_arm(truth):
    """Same numbers as the post-processor's ins.lever_arm.antenna_velocity."""
    lever_arm = pytest.importorskip("ins.lever_arm")
    from ins.earth import earth_rate_n, transport_rate_n
    t = np.linspace(truth.t_start, truth.t_end, 7)
    s = truth.evaluate(t)
    _, v_ant = antenna_state(s, L_BP, L_AP)
    l_b, dl_b = lever_arm_b(s.mount_rpy, s.mount_rate, L_BP, L_AP)
    C_nb = quat_to_dcm(s.q_nb)
    w_in = earth_rate_n(s.lla[:, 0]) + transport_rate_n(s.lla[:, 0], s.lla[:, 2], s.v_n)
    for k in range(len(t)):
        v = lever_arm.antenna_velocity(s.v_n[k], C_nb[k], s.w_ib_b[k], w_in[k], l_b[k], dl_b[k])
        assert np.allclose(v, v_ant[k], atol=1e-12)


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
    assert np.allclose((log.vel_n - v_true).std(axis=0), 0.01, rtol=0.1)
    assert np.array_equal(log.std_ned, np.tile(sigma, (len(time), 1)))
    path = tmp_path / "gnss.txt"
    write_gnss(path, log)
    back = read_gnss(path)
    assert np.allclose(back.time, log.time, atol=1e-9)
    assert np.abs(ned_offset(log.lla, back.lla)).max() < 1e-4
    assert np.allclose(back.vel_n, log.vel_n, atol=1e-6)
