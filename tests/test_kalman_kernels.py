"""The compiled covariance kernels of the run against their references: filterpy's
``predict`` and ``update`` (the outside oracle), ``discretize`` of the error model (numpy;
``interval_matrix`` shares the compiled ``fill_interval``, whose navigation block is checked
element by element against the hand-written formulas), the RTS algebra with scipy's Cholesky solve, and
scipy's chi-square quantile; and the one-point fast paths of the nav functions against
their stacked forms."""
import numpy as np
import pytest

from ins.common.errors import QualityError
from ins.estimation.core import _kalman_kernels as kk
from ins.estimation.core.error_model import (
    LAYOUTS,
    OPTIONAL_GROUPS,
    ImuNoise,
    StateLayout,
    discretize,
    interval_matrix,
    navigation_matrix,
    noise_matrix,
)
from ins.estimation.core.measurements import chi2_upper_quantile, kalman_update
from ins.nav import earth, rotation

LAYOUT_CASES = [StateLayout(LAYOUTS["kfgins"]), StateLayout(LAYOUTS["survey"]),
                StateLayout(tuple(OPTIONAL_GROUPS))]


def _node(rng, layout):
    """A realistic node: state, integrals (as propagate_rows_mis accumulates them over
    1 s at 200 Hz), noise and a positive definite covariance."""
    lat, h = np.deg2rad(30.44), 1000.0
    v_n = np.array([60.0, -3.0, 0.4])
    acc = np.zeros((16, 3))
    C = rotation.euler_to_dcm(np.deg2rad([2.0, 3.0, 40.0]))
    w_b, f_b = np.deg2rad([0.5, -0.3, 3.0]), np.array([0.3, -0.2, -9.79])
    acc[0:3] = C
    acc[3:6] = C * w_b[None, :]
    acc[6:9] = C * f_b[None, :]
    acc[9] = C @ f_b
    N = lambda v: np.array([[0, v[2], v[1]], [v[2], 0, v[0]], [v[1], v[0], 0]])  # noqa: E731
    acc[10:13] = C @ N(w_b)
    acc[13:16] = C @ N(f_b)
    noise = ImuNoise(0.003, 0.03, 0.5, 50.0, 1.0, 1.0, 4.0)
    M = rng.normal(size=(layout.n, layout.n))
    P = M @ M.T * 1e-4 + np.diag(rng.uniform(1e-6, 1e-2, layout.n))
    return lat, h, v_n, acc, noise, P


@pytest.mark.parametrize("layout", LAYOUT_CASES, ids=lambda L: f"n{L.n}")
def test_node_predict_matches_python_model_and_filterpy(layout):
    from filterpy.kalman import predict as fp_predict
    rng = np.random.default_rng(layout.n)
    lat, h, v_n, acc, noise, P = _node(rng, layout)
    dt, tau = 1.0, noise.decay_time_s
    A_ref = interval_matrix(lat, h, v_n, acc[9] / dt,
                            (acc[0:3], acc[3:6], acc[6:9], acc[10:13], acc[13:16]), dt, tau,
                            layout)
    gm = -1 if layout.gyro_misalignment is None else layout.gyro_misalignment.start
    am = -1 if layout.accel_misalignment is None else layout.accel_misalignment.start
    ck = -1 if layout.clock is None else layout.clock.start
    A = kk.interval(lat, h, v_n, acc, dt, float(tau), layout.n, gm, am, ck)
    np.testing.assert_allclose(A, A_ref, rtol=1e-14, atol=0)
    GQG = noise_matrix(noise, layout, clock_psd=(0.1, 0.01))
    Phi_ref, Qd_ref = discretize(A_ref, GQG, dt)
    _, P_ref = fp_predict(np.zeros(layout.n), P, Phi_ref, Qd_ref)
    Phi, Qd, Pp = kk.node_predict(lat, h, v_n, acc, dt, float(tau), gm, am, ck, GQG, P)
    np.testing.assert_allclose(Phi, Phi_ref, rtol=1e-13, atol=1e-18)
    np.testing.assert_allclose(Qd, Qd_ref, rtol=1e-12, atol=1e-25)
    scale = np.sqrt(np.outer(np.diag(P_ref), np.diag(P_ref)))
    assert np.max(np.abs(Pp - P_ref) / scale) < 1e-13


def test_navigation_block_by_hand():
    """Three elements of the navigation block from the formulas of Shin / KF-GINS."""
    lat, h, v = 0.5, 800.0, np.array([50.0, 10.0, -1.0])
    rm, rn = earth.radii(lat)
    F = navigation_matrix(lat, h, v, np.array([0.1, 0.2, -9.8]))
    assert F[1, 2] == pytest.approx(v[1] / (rn + h), rel=1e-15)
    assert F[3, 8] == pytest.approx(0.2, rel=1e-15)           # [f_n x]: row vN, col phi_D
    w_in_d = -earth.OMEGA_IE * np.sin(lat) - v[1] * np.tan(lat) / (rn + h)
    assert F[6, 7] == pytest.approx(w_in_d, rel=1e-14)        # -[w_in x]: (N, E) = w_D


@pytest.mark.parametrize("n,m", [(21, 3), (27, 3), (31, 1), (33, 6), (29, 48)])   # m > n: every
# satellite of four constellations, code and Doppler, in one update
def test_joseph_update_matches_filterpy(n, m):
    from filterpy.kalman import update as fp_update
    rng = np.random.default_rng(100 + n + m)
    M = rng.normal(size=(n, n))
    P = M @ M.T * 1e-3 + np.eye(n) * 1e-4
    H = rng.normal(size=(m, n))
    R = np.diag(rng.uniform(1e-3, 1e-2, m))
    z = rng.normal(size=m) * 0.1
    dx, P_post, nis, sigma = kalman_update(P, H, R, z, 1e9)
    x_ref, P_ref = fp_update(np.zeros(n), P, z, R, H)
    S = H @ P @ H.T + R
    np.testing.assert_allclose(dx, x_ref, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(P_post, P_ref, rtol=1e-9, atol=1e-14)
    assert nis == pytest.approx(z @ np.linalg.solve(S, z), rel=1e-12)
    np.testing.assert_allclose(sigma, np.sqrt(np.diag(S)), rtol=1e-14)
    dx, P_same, nis2, _ = kalman_update(P, H, R, z, 0.5 * nis)   # rejected by the test
    assert dx is None and P_same is P and nis2 == nis


def test_update_refuses_indefinite_innovation_covariance():
    P = np.eye(4)
    H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
    R = np.diag([-3.0, 1.0])                                   # S = diag(-2, 2)
    meas = type("M", (), {"name": "gnss_position", "time": 12.5})()
    with pytest.raises(QualityError, match="gnss_position at t = 12.500 s.*not positive"):
        kalman_update(P, H, R, np.ones(2), 10.0, meas)
    with pytest.raises(QualityError, match="not positive"):
        kalman_update(P, H, np.diag([np.nan, 1.0]), np.ones(2), 10.0)


def test_rts_step_matches_scipy_algebra():
    from scipy.linalg import cho_factor, cho_solve
    rng = np.random.default_rng(7)
    n = 27
    def spd():
        M = rng.normal(size=(n, n))
        return M @ M.T * 1e-3 + np.eye(n) * 1e-3
    P_post, P_prior, Ps = spd(), spd(), spd()
    Phi = np.eye(n) + 0.01 * rng.normal(size=(n, n))
    v = rng.normal(size=n)
    A = cho_solve(cho_factor(P_prior), Phi @ P_post).T
    P_ref = P_post + A @ (Ps - P_prior) @ A.T
    P_ref = 0.5 * (P_ref + P_ref.T)
    ok, xs, Pj = kk.rts_step(P_prior, Phi, P_post, Ps, v)
    assert ok
    np.testing.assert_allclose(xs, A @ v, rtol=1e-10)
    np.testing.assert_allclose(Pj, P_ref, rtol=1e-9, atol=1e-15)
    assert np.array_equal(Pj, Pj.T)
    ok, _, _ = kk.rts_step(-P_prior, Phi, P_post, Ps, v)
    assert not ok


def test_chi2_quantile_matches_scipy():
    from scipy.stats import chi2
    for dof in range(1, 10):
        for q in (0.9, 0.5, 0.05, 1e-3, 1e-5, 1e-9, 1e-14):
            assert chi2_upper_quantile(q, dof) == pytest.approx(chi2.isf(q, dof), rel=1e-12)
    assert chi2_upper_quantile(0.0, 3) == np.inf and chi2_upper_quantile(1.0, 3) == 0.0
    with pytest.raises(ValueError):
        chi2_upper_quantile(0.1, 0)


def test_one_point_fast_paths_equal_stacked_forms():
    rng = np.random.default_rng(11)
    for _ in range(200):
        q = rng.normal(size=4)
        assert np.array_equal(rotation.quat_to_dcm(q), rotation.quat_to_dcm(q[None])[0])
        a = np.array([rng.uniform(-1.5, 1.5), rng.uniform(-3, 3), rng.uniform(-50, 9000)])
        b = a + rng.normal(size=3) * [1e-4, 1e-4, 30.0]
        v = rng.normal(size=3) * 50
        assert np.array_equal(earth.ned_offset(a, b), earth.ned_offset(a[None], b[None])[0])
        one, many = (a[0], a[2], v), (a[:1], a[2:], v[None])
        for f in (earth.lla_rate, earth.transport_rate_n):
            assert np.array_equal(f(*one), f(*many)[0])
        assert np.array_equal(earth.gravity_n(a[0], a[2]), earth.gravity_n(a[:1], a[2:])[0])
        assert np.array_equal(earth.earth_rate_n(a[0]), earth.earth_rate_n(a[:1])[0])
    with pytest.raises(ValueError, match="nonzero norm"):
        rotation.quat_to_dcm(np.zeros(4))
    with pytest.raises(ValueError, match="finite"):
        rotation.quat_to_dcm([np.nan, 0, 0, 1])


def test_diag_std_is_the_numpy_check_and_sqrt():
    """The node store's compiled check: True and ``sqrt(max(diag(P_post), 0))``, bit for
    bit, exactly when numpy's rule (every variance of both at least -rtol times the
    larger magnitude of the two) holds; False for a variance below it or a NaN."""
    from ins.estimation.core.error_model import VARIANCE_RTOL as rtol
    rng = np.random.default_rng(5)
    n = 27
    for trial in range(400):
        a, b = rng.normal(size=(2, n, n))
        P1, P2 = a @ a.T, b @ b.T
        k = rng.integers(n)
        if trial % 4 == 1:        # rounding-size negative: accepted, std 0
            P2[k, k] = -0.5 * rtol * P1[k, k]
        elif trial % 4 == 2:      # beyond rounding (in one or the other): refused
            (P1 if trial % 8 == 2 else P2)[k, k] = -3.0 * rtol * max(P1[k, k], P2[k, k], 1.0)
        elif trial % 4 == 3:
            (P1 if trial % 8 == 3 else P2)[k, k] = np.nan
        d1, d2 = np.diag(P1), np.diag(P2)
        floor = -rtol * np.maximum(np.abs(d1), np.abs(d2))
        expect = bool((d1 >= floor).all() and (d2 >= floor).all())
        std = np.full(n, 7.0)
        assert kk.diag_std(P1, P2, rtol, std) is expect
        if expect:
            assert np.array_equal(std, np.sqrt(np.maximum(d2, 0.0)))
        assert expect == (trial % 4 in (0, 1))
    with pytest.raises(ValueError, match="shape"):
        kk.diag_std(np.eye(3), np.eye(3), rtol, np.empty(2))
