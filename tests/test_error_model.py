"""Error-state model: units of Q, Gauss-Markov steady state, discretization against
scipy's expm, and F against the mechanization itself (a perturbed state propagated by
the numba kernel, compared with Phi dx)."""
import numpy as np
import pytest
from scipy.linalg import expm

from ins import _filter_kernels, earth
from ins.error_model import (N_STATES, STATE_NAMES, ImuNoise, discretize, interval_matrix,
                             noise_matrix, system_matrix)
from ins.mechanization import NavState
from ins.rotation import dcm_to_rotvec, quat_to_dcm


def test_layout_names():
    assert len(STATE_NAMES) == N_STATES == 21
    assert STATE_NAMES[6] == "att_N" and STATE_NAMES[20] == "accel_scale_z"


def test_noise_units():
    n = ImuNoise(arw_deg_sqrth=1.0, vrw_mps_sqrth=1.0, gyro_bias_std_dph=1.0,
                 accel_bias_std_mgal=1.0, gyro_scale_std_ppm=1.0, accel_scale_std_ppm=1.0,
                 corr_time_h=1.0)
    q = n.q_continuous()
    assert q[0] == pytest.approx((np.pi / 180 / 60) ** 2)           # rad^2/s
    assert q[3] == pytest.approx((1 / 60) ** 2)                     # (m/s)^2/s
    assert q[6] == pytest.approx(2 * (np.pi / 180 / 3600) ** 2 / 3600)
    assert q[9] == pytest.approx(2 * 1e-10 / 3600)
    assert q[15] == pytest.approx(2 * 1e-12 / 3600)
    with pytest.raises(ValueError):
        ImuNoise(corr_time_h=0.0)
    with pytest.raises(ValueError):
        ImuNoise(arw_deg_sqrth=-1.0)


def test_gauss_markov_steady_state():
    """P = sigma^2 on the sensor states is stationary under Phi P Phi^T + Q_d."""
    noise = ImuNoise(corr_time_h=0.5)
    GQG = noise_matrix(noise)
    A = interval_matrix(0.5, 100.0, np.zeros(3), [0, 0, -9.8],
                        (np.zeros((3, 3)),) * 3, 1.0, noise.corr_time_s)
    Phi, Qd = discretize(A, GQG, 1.0)
    P = np.zeros((21, 21))
    idx = np.arange(9, 21)
    P[idx, idx] = noise.sensor_std ** 2
    for _ in range(3600):
        P = Phi @ P @ Phi.T + Qd
    np.testing.assert_allclose(np.diag(P)[9:], noise.sensor_std ** 2, rtol=1e-6)


def test_discretization_against_expm():
    C_nb = quat_to_dcm(NavState.from_degrees(30, 114, 1000, [0, 0, 0], [2, 3, 45]).q_nb)
    F = system_matrix(0.53, 1000.0, np.array([60.0, 5.0, -1.0]), np.array([0.3, 0.5, -9.8]),
                      C_nb, np.array([0.1, 0.2, -9.8]), np.array([0.01, 0.02, 0.05]), 3600.0)
    for dt in (0.1, 1.0):
        Phi, _ = discretize(F * dt, np.zeros((21, 21)), dt)
        E = expm(F * dt)
        # fourth-order remainder: (|F| dt)^4 / 24
        bound = np.linalg.norm(F * dt, 2) ** 4 / 24 * 1.01 + 1e-15
        assert np.abs(Phi - E).max() <= bound


def _state_error(est, ref):
    """Error of ``est`` against ``ref`` (kernel layout): NED m, m/s, phi rad."""
    dr = earth.ned_offset(ref[:3], est[:3])
    dv = est[3:6] - ref[3:6]
    C = quat_to_dcm(est[6:10]) @ quat_to_dcm(ref[6:10]).T   # = I - [phi x]
    return np.concatenate([dr, dv, -dcm_to_rotvec(C)])


@pytest.mark.parametrize("block, size", [
    (slice(0, 3), 1.0), (slice(3, 6), 0.05), (slice(6, 9), 2e-4), (slice(9, 12), 2e-6),
    (slice(12, 15), 2e-3), (slice(15, 18), 2e-4), (slice(18, 21), 2e-4)])
def test_transition_matches_the_mechanization(block, size):
    """Propagate a true and a perturbed state through 1 s of IMU rows; the difference of
    the results must be Phi dx to first order (each block perturbed in turn)."""
    rng = np.random.default_rng(hash(block.start) % 1000)
    dt, n = 0.005, 201
    time = np.arange(n) * dt
    w_b = np.array([0.02, -0.03, 0.05])                   # rad/s: the body turns
    f_b = np.array([0.5, 0.3, -9.7])
    dtheta = np.tile(w_b * dt, (n, 1))
    dvel = np.tile(f_b * dt, (n, 1))
    true0 = NavState.from_degrees(30.44, 114.47, 1000.0, [60.0, 5.0, -1.0], [3, 2, 40])
    dx = np.zeros(21)
    dx[block] = rng.choice([-1.0, 1.0], 3) * size * (0.5 + rng.random(3))
    # estimate = truth + navigation error; sensor estimates = -error (truth is 0)
    est = true0.as_vector().copy()
    _filter_kernels.correct_state(est, -dx[:9])
    s_true = true0.as_vector().copy()
    out = np.empty((n - 1, 10))
    acc = np.zeros((10, 3))
    _filter_kernels.propagate_rows(time, dtheta, dvel, 1, n, s_true, np.zeros(12), out, acc)
    acc_true = acc.copy()
    x0 = _state_error(est, true0.as_vector())
    _filter_kernels.propagate_rows(time, dtheta, dvel, 1, n, est, -dx[9:21], out,
                                   np.zeros((10, 3)))
    x1 = _state_error(est, s_true)
    T = time[-1]
    mid = 0.5 * (true0.as_vector() + s_true)
    A = interval_matrix(mid[0], mid[2], mid[3:6], acc_true[9] / T,
                        (acc_true[0:3], acc_true[3:6], acc_true[6:9]), T, 3600.0)
    Phi, _ = discretize(A, np.zeros((21, 21)), T)
    x0_full = np.concatenate([x0, dx[9:21]])
    predicted = (Phi @ x0_full)[:9]
    change = x1 - x0
    scale = np.abs(predicted - x0).max()
    assert scale > 0
    # first-order agreement: residual a small fraction of the change it predicts
    np.testing.assert_allclose(x1, predicted, atol=0.02 * scale + 1e-9)
    assert np.abs(change).max() > 0
