"""Error-state model: units of Q, Gauss-Markov steady state, discretization against
scipy's expm, and F against the mechanization itself (a perturbed state propagated by
the compiled mechanization kernel, compared with Phi dx)."""
import numpy as np
import pytest
from scipy.linalg import expm

from ins.estimation.core import _filter_kernels
from ins.estimation.core.error_model import (
    N_STATES,
    STATE_NAMES,
    ImuNoise,
    discretize,
    interval_matrix,
    noise_matrix,
    system_matrix,
)
from ins.nav import earth
from ins.nav.mechanization import NavState
from ins.nav.rotation import dcm_to_rotvec, quat_to_dcm


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


def test_constant_sensor_states_with_instability():
    """With a bias instability the sensor states are random constants plus a random walk
    of ``2 sigma_inst^2 / T`` (hand values): after an hour from the prior, a bias
    variance is prior^2 + 2 sigma_inst^2 (T = 1 h), a scale factor's is its prior^2."""
    noise = ImuNoise(gyro_bias_std_dph=1.2, accel_bias_std_mgal=1000.0,
                     gyro_scale_std_ppm=150.0, accel_scale_std_ppm=300.0, corr_time_h=1.0,
                     gyro_bias_instability_dph=0.5, accel_bias_instability_mgal=100.0)
    assert noise.constant_sensors and noise.decay_time_s == np.inf
    assert not ImuNoise().constant_sensors and ImuNoise().decay_time_s == 4.0 * 3600
    q = noise.q_continuous()
    dph, mgal = np.pi / 180 / 3600, 1e-5
    np.testing.assert_allclose(q[6:9], 2 * (0.5 * dph) ** 2 / 3600)
    np.testing.assert_allclose(q[9:12], 2 * (100 * mgal) ** 2 / 3600)
    np.testing.assert_array_equal(q[12:18], 0.0)
    # one of the two given: the other instability is zero
    only = ImuNoise(gyro_bias_instability_dph=0.5)
    np.testing.assert_array_equal(only.q_continuous()[9:18], 0.0)
    A = interval_matrix(0.5, 100.0, np.zeros(3), [0, 0, -9.8],
                        (np.zeros((3, 3)),) * 3, 1.0, noise.decay_time_s)
    Phi, Qd = discretize(A, noise_matrix(noise), 1.0)
    np.testing.assert_array_equal(np.diag(Phi)[9:21], 1.0)
    P = np.zeros((21, 21))
    idx = np.arange(9, 21)
    P[idx, idx] = noise.sensor_std ** 2
    for _ in range(3600):
        P = Phi @ P @ Phi.T + Qd
    d = np.diag(P)
    np.testing.assert_allclose(d[9:12], (1.2 * dph) ** 2 + 2 * (0.5 * dph) ** 2, rtol=1e-9)
    np.testing.assert_allclose(d[12:15], (1000 * mgal) ** 2 + 2 * (100 * mgal) ** 2,
                               rtol=1e-9)
    np.testing.assert_allclose(d[15:18], (150e-6) ** 2, rtol=1e-12)
    np.testing.assert_allclose(d[18:21], (300e-6) ** 2, rtol=1e-12)


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


# --- F against the nonlinear NED mechanization equations, built here independently ----
# (WGS84 and the normal gravity of conventions.md written out; scipy for rotations)
A_WGS, F_WGS, W_IE = 6378137.0, 1 / 298.257223563, 7.292115e-5
E2_WGS = F_WGS * (2 - F_WGS)
GRAV = (9.7803267715, 0.0052790414, 0.0000232718, -0.0000030876910891, 0.0000000043977311,
        0.0000000000007211)


def _M(lat):
    return A_WGS * (1 - E2_WGS) / (1 - E2_WGS * np.sin(lat) ** 2) ** 1.5


def _N(lat):
    return A_WGS / np.sqrt(1 - E2_WGS * np.sin(lat) ** 2)


def _g(lat, h):
    a1, a2, a3, a4, a5, a6 = GRAV
    s2 = np.sin(lat) ** 2
    return a1 * (1 + a2 * s2 + a3 * s2 * s2) + (a4 + a5 * s2) * h + a6 * h * h


def _x(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def _rates(lat, lon, h, v, C, f_b, w_b):
    """Time derivatives of the nonlinear mechanization in n (NED):
    lat' = vN/(M+h), lon' = vE/((N+h) cos lat), h' = -vD,
    v' = C f - (2 w_ie + w_en) x v + g,  C' = C [w_ib x] - [w_in x] C."""
    vn, ve, vd = v
    lat_d = vn / (_M(lat) + h)
    lon_d = ve / ((_N(lat) + h) * np.cos(lat))
    h_d = -vd
    w_ie = W_IE * np.array([np.cos(lat), 0.0, -np.sin(lat)])
    w_en = np.array([lon_d * np.cos(lat), -lat_d, -lon_d * np.sin(lat)])
    v_d = C @ f_b - np.cross(2 * w_ie + w_en, v) + np.array([0.0, 0.0, _g(lat, h)])
    C_d = C @ _x(w_b) - _x(w_ie + w_en) @ C
    return lat_d, lon_d, h_d, v_d, C_d


def _error_rate(x, truth, f_b, w_b, tau):
    """d/dt of the 21-state error (estimate minus truth; phi with C_est = exp(-[phi x])
    C_true; sensor errors truth minus estimate, the truth's sensors being zero) at the
    error ``x``, from the nonlinear equations of the estimate and the truth."""
    from scipy.spatial.transform import Rotation
    lat, lon, h, v, C = truth
    Mh, Nh = _M(lat) + h, _N(lat) + h
    lat_e = lat + x[0] / Mh
    lon_e = lon + x[1] / (Nh * np.cos(lat))
    h_e = h - x[2]
    v_e = v + x[3:6]
    C_e = Rotation.from_rotvec(-x[6:9]).as_matrix() @ C
    # measured = truth (zero sensor errors); estimate compensates with b = -db, s = -ds
    w_e = (w_b + x[9:12]) / (1 - x[15:18])
    f_e = (f_b + x[12:15]) / (1 - x[18:21])
    rt = _rates(lat, lon, h, v, C, f_b, w_b)
    re = _rates(lat_e, lon_e, h_e, v_e, C_e, f_e, w_e)
    # product rule on dr_N = dlat (M + h), dr_E = dlon (N + h) cos lat (truth's lat, h)
    k = 1e-6
    dM = (_M(lat + k) - _M(lat - k)) / (2 * k)
    dN = (_N(lat + k) - _N(lat - k)) / (2 * k)
    lat_d, h_d = rt[0], rt[2]
    e = np.zeros(21)
    e[0] = (re[0] - rt[0]) * Mh + (lat_e - lat) * (dM * lat_d + h_d)
    e[1] = ((re[1] - rt[1]) * Nh * np.cos(lat)
            + (lon_e - lon) * ((dN * lat_d + h_d) * np.cos(lat) - Nh * np.sin(lat) * lat_d))
    e[2] = -(re[2] - rt[2])
    e[3:6] = re[3] - rt[3]
    X = re[4] @ C.T + C_e @ rt[4].T            # d/dt (C_est C_true^T) = -[phi' x] + O(2)
    A = 0.5 * (X - X.T)
    e[6:9] = -np.array([A[2, 1], A[0, 2], A[1, 0]])
    e[9:21] = -x[9:21] / tau
    return e


STEP = np.array([100.0] * 3 + [0.1] * 3 + [1e-5] * 3 + [1e-6] * 3 + [1e-3] * 3 + [1e-5] * 6)


def numerical_F(truth, f_b, w_b, tau):
    F = np.zeros((21, 21))
    for j in range(21):
        d = np.zeros(21)
        d[j] = STEP[j]
        F[:, j] = (_error_rate(d, truth, f_b, w_b, tau) - _error_rate(-d, truth, f_b, w_b, tau)) \
            / (2 * STEP[j])
    return F


@pytest.mark.parametrize("lat_deg, v, rpy_deg", [
    (30.5, [60.0, 25.0, -3.0], [3.0, -2.0, 40.0]),
    (-47.0, [-35.0, 70.0, 2.0], [-10.0, 5.0, -120.0]),
    (68.0, [5.0, -250.0, 0.5], [25.0, 2.0, 190.0])])
def test_F_against_the_numerical_jacobian_of_the_mechanization(lat_deg, v, rpy_deg):
    """Every block of F (system_matrix) against the central-difference Jacobian of the
    nonlinear NED equations of this test.  Known approximations of the Shin/KF-GINS F,
    all below the tolerances: the gravity gradient 2 g / (sqrt(M N) + h) (the normal
    gravity's is 0.6 % larger: 2e-8 s^-2), no d g / d lat (7e-9 s^-2) and M, N taken
    constant in the velocity rows (terms e^2 v^2 / R^2 < 1e-12).  The Coriolis term
    2 w_ie sin(lat) of the velocity block is 1e-4 s^-1: its sign (and that of any other
    entry above 1e-7) is decided."""
    from scipy.spatial.transform import Rotation
    lat, h = np.deg2rad(lat_deg), 1500.0
    C = Rotation.from_euler("ZYX", rpy_deg[::-1], degrees=True).as_matrix()
    f_b = np.array([0.4, -0.3, -9.9])
    w_b = np.array([0.01, -0.02, 0.03])
    v = np.array(v)
    tau = 3600.0
    truth = (lat, 1.9, h, v, C)
    Fn = numerical_F(truth, f_b, w_b, tau)
    F = system_matrix(lat, h, v, C @ f_b, C, f_b, w_b, tau)
    blocks = {"pos": slice(0, 3), "vel": slice(3, 6), "att": slice(6, 9),
              "sensors": slice(9, 21)}
    # absolute tolerance per (row, column) block: about 10 x the largest difference seen
    # over the three cases (rounding of the numerical Jacobian, the e^2 v / R^2 terms
    # of the F approximations), except (vel, pos): the gravity approximations above
    tol = {("pos", "pos"): 2e-12, ("pos", "vel"): 2e-12, ("vel", "pos"): 3e-8,
           ("vel", "vel"): 1e-13, ("vel", "att"): 2e-9, ("vel", "sensors"): 1e-8,
           ("att", "pos"): 4e-13, ("att", "vel"): 1e-15, ("att", "att"): 3e-12,
           ("att", "sensors"): 3e-11}
    for rname, rows in blocks.items():
        for cname, cols in blocks.items():
            diff = np.abs(F[rows, cols] - Fn[rows, cols])
            assert diff.max() <= tol.get((rname, cname), 1e-14), \
                (rname, cname, diff.max(), F[rows, cols], Fn[rows, cols])
    # entries whose sign is decided: the attitude rows' W sin(lat) / R (6e-12 and more)
    assert np.abs(Fn[6, 0]) > 10 * tol[("att", "pos")]
    # the Coriolis entries are far above the tolerance (they decide their sign)
    assert abs(Fn[3, 4]) > 1e3 * tol[("vel", "vel")]


def _van_loan(F, GQG, dt):
    """Exact Phi and Q_d = int_0^dt Phi(s) GQG Phi(s)^T ds (Van Loan, scipy's expm)."""
    n = len(F)
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -F
    M[:n, n:] = GQG
    M[n:, n:] = F.T
    B = expm(M * dt)
    Phi = B[n:, n:].T
    return Phi, Phi @ B[:n, n:]


def test_process_noise_against_van_loan():
    """Q_d of discretize (trapezoid) against the exact integral (Van Loan): the single
    step agrees on the directly driven states (attitude, sensors: 1e-3; velocity: 4 %), and
    a covariance propagated over 10 min of 1 s steps agrees everywhere within 1 % (the
    trapezoid rule is second order: its 1-step error on the integrated terms, e.g.
    q dt^3 / 2 instead of q dt^3 / 3 in position, does not accumulate)."""
    C_nb = quat_to_dcm(NavState.from_degrees(30, 114, 1000, [0, 0, 0], [2, 3, 45]).q_nb)
    f_b = np.array([0.3, -0.2, -9.8])
    F = system_matrix(0.53, 1000.0, np.array([60.0, 5.0, -1.0]), C_nb @ f_b, C_nb, f_b,
                      np.array([0.001, 0.002, 0.005]), 3600.0)
    noise = ImuNoise(arw_deg_sqrth=0.12, vrw_mps_sqrth=0.05, gyro_bias_std_dph=1.0,
                     accel_bias_std_mgal=300.0, gyro_scale_std_ppm=300, accel_scale_std_ppm=300,
                     corr_time_h=1.0)
    GQG = noise_matrix(noise)
    dt = 1.0
    Phi, Qd = discretize(F * dt, GQG, dt)
    Phi_x, Qd_x = _van_loan(F, GQG, dt)
    d = np.arange(6, 21)
    np.testing.assert_allclose(np.diag(Qd)[d], np.diag(Qd_x)[d], rtol=1e-3)
    # velocity: the ARW carried through [f x] adds f^2 q_arw dt^3 / 6 (2.8 % here)
    np.testing.assert_allclose(np.diag(Qd)[3:6], np.diag(Qd_x)[3:6], rtol=0.04)
    P = P_x = np.zeros((21, 21))
    for _ in range(600):
        P = Phi @ P @ Phi.T + Qd
        P_x = Phi_x @ P_x @ Phi_x.T + Qd_x
    np.testing.assert_allclose(np.diag(P), np.diag(P_x), rtol=0.01)


def test_named_layouts_match_the_documented_indices():
    """The named slices against the documented layout (literal indices, written out
    here independently) and against what the mechanization and the sensor states hold."""
    from ins.estimation.core.error_model import NAV, SENSORS, STATE
    names = {"pos": "pos_", "vel": "vel_", "att": "att_", "gyro_bias": "gyro_bias_",
             "accel_bias": "accel_bias_", "gyro_scale": "gyro_scale_",
             "accel_scale": "accel_scale_"}
    covered = []
    for field, prefix in names.items():
        sl = getattr(STATE, field)
        assert sl.stop - sl.start == 3
        assert all(n.startswith(prefix) for n in STATE_NAMES[sl])
        covered += list(range(N_STATES))[sl]
    assert sorted(covered) == list(range(21))
    assert (STATE.att.start, STATE.gyro_bias.start, STATE.accel_scale.stop) == (6, 9, 21)
    assert list(range(21))[STATE.nav] == list(range(9))
    assert list(range(21))[STATE.sensors] == list(range(9, 21))
    for field in ("gyro_bias", "accel_bias", "gyro_scale", "accel_scale"):
        s, full = getattr(SENSORS, field), getattr(STATE, field)
        assert (s.start + 9, s.stop + 9) == (full.start, full.stop)
    nav = NavState.from_degrees(30, 114, 1000, [1, 2, 3], [2, 3, 45])
    v = nav.as_vector()
    np.testing.assert_array_equal(v[NAV.vel], [1, 2, 3])
    np.testing.assert_array_equal(v[NAV.q_nb], nav.q_nb)
    np.testing.assert_allclose(v[NAV.lla], [np.radians(30), np.radians(114), 1000])


@pytest.mark.parametrize("group", ["gyro_misalignment", "accel_misalignment"])
def test_misalignment_columns_match_the_mechanization(group):
    """The non-orthogonality columns of the survey layout: a true IMU without
    non-orthogonality mechanized with an estimate ``-dx`` of it (the kernel removes
    ``N(m) dtheta``) departs from the truth by ``Phi dx`` to first order."""
    from ins.estimation.core.error_model import StateLayout
    L = StateLayout(("gyro_misalignment", "accel_misalignment"))
    dt, n = 0.005, 201
    time = np.arange(n) * dt
    w_b = np.array([0.02, -0.03, 0.08])                   # rad/s: the body turns
    f_b = np.array([0.8, 2.5, -9.5])
    dtheta = np.tile(w_b * dt, (n, 1))
    dvel = np.tile(f_b * dt, (n, 1))
    true0 = NavState.from_degrees(30.44, 114.47, 1000.0, [60.0, 5.0, -1.0], [3, 2, 40])
    dx = np.zeros(L.n)
    dx[getattr(L, group)] = np.array([1.0, -0.7, 0.8]) * 5e-4          # ~100 arcsec
    s_true = true0.as_vector().copy()
    out = np.empty((n - 1, 10))
    acc = np.zeros((16, 3))
    _filter_kernels.propagate_rows_mis(time, dtheta, dvel, 1, n, s_true, np.zeros(12),
                                       np.zeros(6), out, acc)
    est = true0.as_vector().copy()
    mis = -dx[21:27]
    _filter_kernels.propagate_rows_mis(time, dtheta, dvel, 1, n, est, np.zeros(12), mis, out,
                                       np.zeros((16, 3)))
    x1 = _state_error(est, s_true)
    T = time[-1]
    mid = 0.5 * (true0.as_vector() + s_true)
    A = interval_matrix(mid[0], mid[2], mid[3:6], acc[9] / T,
                        (acc[0:3], acc[3:6], acc[6:9], acc[10:13], acc[13:16]), T, 3600.0, L)
    Phi, _ = discretize(A, np.zeros((L.n, L.n)), T)
    predicted = (Phi @ dx)[:9]
    scale = np.abs(predicted).max()
    assert scale > 0
    np.testing.assert_allclose(x1, predicted, atol=0.02 * scale + 1e-9)
    # the 21-state kernel with no estimate gives the truth back exactly
    s21 = true0.as_vector().copy()
    _filter_kernels.propagate_rows(time, dtheta, dvel, 1, n, s21, np.zeros(12), out,
                                   np.zeros((10, 3)))
    np.testing.assert_array_equal(s21, s_true)
