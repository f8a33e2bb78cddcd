"""The measurement protocol (ins.estimation.core.measurements): H of every measurement against central
finite differences of its predicted value under the filter's own feedback rule, the
Cholesky update against the textbook (inverse) form, the S-not-positive-definite error,
and the innovation file read back by hand."""
import numpy as np
import pytest

from ins.common.errors import QualityError
from ins.estimation.core.error_model import OPTIONAL_GROUPS, StateLayout
from ins.estimation.core.measurements import (
    DualAntennaHeading,
    GnssPosition,
    GnssVelocity,
    NavPoint,
    NonHolonomic,
    ZeroVelocity,
    corrected,
    kalman_update,
    write_innovations,
)
from ins.estimation.tools.vehicle import mounting_dcm
from ins.nav.rotation import euler_to_quat

FULL = StateLayout(tuple(OPTIONAL_GROUPS))


def _point(layout=FULL):
    rng = np.random.default_rng(3)
    state = np.concatenate([[np.deg2rad(30.5), np.deg2rad(114.3), 520.0],
                            [40.0, -35.0, 1.5],
                            euler_to_quat(np.deg2rad([8.0, -3.0, 137.0]))])
    sensors = np.zeros(layout.n - 9)
    sensors[:12] = np.concatenate([[2e-6, -1e-6, 3e-6], [0.01, -0.02, 0.005],
                                   [1e-4, -2e-4, 1.5e-4], [3e-4, -1e-4, 2e-4]])
    sensors[12:] = rng.normal(0.0, 5e-4, layout.n - 21)
    if layout.time_offset is not None:
        sensors[layout.time_offset.start - 9] = 0.004
    return NavPoint(100.0, state, sensors, layout, w_meas_b=np.array([0.05, -0.12, 0.2]),
                    l_b=np.array([0.55, 0.15, -1.2]), dl_b=np.array([0.01, -0.02, 0.005]),
                    a_n=np.array([1.2, -0.8, 0.3]))


def _measurements():
    p = _point()
    lla = p.state[:3] + np.array([1e-7, -2e-7, 0.3])
    return [GnssPosition(100.003, lla, [[4e-4, 1e-4, 0], [1e-4, 4e-4, 0], [0, 0, 1.6e-3]]),
            GnssVelocity(100.0, [40.1, -35.2, 1.4], np.full(3, 1e-4)),
            DualAntennaHeading(100.0, np.deg2rad(137.2), np.deg2rad(0.05), [0.3, 1.0, 0.1]),
            ZeroVelocity(100.0, 0.01), NonHolonomic(100.0, [0.1, 0.05]),
            NonHolonomic(100.0, 0.1, mounting_dcm([1.0, 3.9, -1.5]))]   # IMU askew


# step per state: small against the quantity, large against rounding
def _steps(layout):
    h = np.empty(layout.n)
    h[layout.pos], h[layout.vel], h[layout.att] = 1e-3, 1e-4, 1e-6
    h[layout.gyro_bias], h[layout.accel_bias] = 1e-6, 1e-4
    h[layout.gyro_scale], h[layout.accel_scale] = 1e-5, 1e-5
    for g in layout.groups:
        h[getattr(layout, g)] = 1e-3 if g in ("lever_arm", "time_offset") else 1e-5
    return h


@pytest.mark.parametrize("meas", _measurements(), ids=lambda m: m.name)
def test_jacobian_matches_finite_differences(meas):
    p = _point()
    H = meas.jacobian(p)
    h = _steps(p.layout)
    num = np.empty_like(H)
    for k in range(p.layout.n):
        e = np.zeros(p.layout.n)
        e[k] = h[k]
        plus = meas.predict(corrected(p, e))
        minus = meas.predict(corrected(p, -e))
        # residual(pred(p), pred(truth)) ~ H dx with truth = p corrected by dx
        num[:, k] = meas.residual(minus, plus) / (2 * h[k])
    scale = np.max(np.abs(H), axis=1, keepdims=True)
    np.testing.assert_allclose(H, num, atol=float(np.max(2e-5 * scale)) + 1e-12, rtol=2e-4)
    assert np.any(H[:, p.layout.sensors] != 0) or meas.name in (
        "heading", "zero_velocity", "nonholonomic")


def test_jacobian_of_kfgins_layout_is_the_first_21_columns():
    p_full, p21 = _point(), _point(StateLayout(()))
    p21.sensors = p_full.sensors[:12].copy()
    p_full.sensors[12:] = 0.0
    for meas in _measurements():
        np.testing.assert_allclose(meas.jacobian(p21), meas.jacobian(p_full)[:, :21],
                                   rtol=1e-12, atol=1e-15)


def test_time_offset_and_lever_columns_by_hand():
    p = _point()
    m = _measurements()[0]
    H = m.jacobian(p)
    np.testing.assert_allclose(H[:, p.layout.lever_arm], -p.C_nb, atol=1e-15)
    # an antenna moving at v: a later epoch is further along v
    assert H[:, p.layout.time_offset][:, 0] @ p.state[3:6] < -0.9 * (p.state[3:6] @ p.state[3:6])


def test_update_matches_the_inverse_form():
    rng = np.random.default_rng(0)
    n, m = 9, 3
    A = rng.normal(size=(n, n))
    P = A @ A.T + np.eye(n)
    H = rng.normal(size=(m, n))
    R = np.diag([0.5, 1.0, 2.0])
    z = rng.normal(size=m)
    dx, P1, nis, sigma = kalman_update(P, H, R, z, np.inf)
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    np.testing.assert_allclose(dx, K @ z, rtol=1e-10)
    np.testing.assert_allclose(P1, (np.eye(n) - K @ H) @ P, rtol=1e-9, atol=1e-12)
    assert nis == pytest.approx(z @ np.linalg.inv(S) @ z, rel=1e-12)
    np.testing.assert_allclose(sigma, np.sqrt(np.diag(S)))
    dx, P2, _, _ = kalman_update(P, H, R, z, nis * 0.99)
    assert dx is None and P2 is P


def test_update_refuses_indefinite_s_naming_measurement_and_time():
    meas = ZeroVelocity(123.25, 0.01)
    P = np.diag([1.0, 1.0, 1.0, -5.0, 1.0, 1.0])
    H = np.zeros((3, 6))
    H[:, 3:6] = np.eye(3)
    with pytest.raises(QualityError, match=r"zero_velocity at t = 123\.250 s.*not positive"):
        kalman_update(P, H, meas.R, np.zeros(3), np.inf, meas)


def test_innovation_file_layout(tmp_path):
    from ins.estimation.core.measurements import UpdateRecord
    recs = [UpdateRecord("gnss_position", ("N", "E", "D"), "m", 10.0,
                         np.array([0.01, -0.02, 0.03]), np.array([0.02, 0.02, 0.06]), 2.5, True),
            UpdateRecord("heading", ("psi",), "deg", 11.0, np.array([np.pi / 180]),
                         np.array([np.pi / 360]), 4.0, False)]
    path = tmp_path / "innovations.txt"
    write_innovations(path, recs)
    lines = [ln.split() for ln in path.read_text().splitlines() if not ln.startswith("#")]
    assert len(lines) == 4
    assert lines[1][:3] == ["10.000", "gnss_position", "E"]
    assert float(lines[1][3]) == pytest.approx(-0.02) and float(lines[1][5]) == -1.0
    assert lines[3][1:3] == ["heading", "psi"] and float(lines[3][3]) == pytest.approx(1.0)
    assert float(lines[3][5]) == 2.0 and lines[3][7] == "0" and lines[3][8] == "deg"


def test_nonholonomic_in_the_vehicle_axes_by_hand():
    """With the mounting, the predicted value is the vehicle-frame velocity
    ``C_vb C_nb^T v_n`` (y, z): zero for a velocity along the vehicle's forward axis,
    whatever the IMU's attitude; identity by default."""
    p = _point()
    C_vb = mounting_dcm([1.0, 3.9, -1.5])
    fwd_n = p.C_nb @ C_vb.T @ np.array([1.0, 0.0, 0.0])
    p.state[3:6] = 17.0 * fwd_n
    np.testing.assert_allclose(NonHolonomic(0.0, 0.1, C_vb).predict(p), 0.0, atol=1e-12)
    assert np.all(np.abs(NonHolonomic(0.0, 0.1).predict(p)) > 0.3)   # askew in b
    np.testing.assert_allclose(NonHolonomic(0.0, 0.1).predict(p),
                               (p.C_nb.T @ p.state[3:6])[1:], atol=1e-12)
    with pytest.raises(ValueError, match="rotation matrix"):
        NonHolonomic(0.0, 0.1, 2 * np.eye(3))


def test_gnss_predictions_carried_by_the_node_acceleration():
    """A record 3 ms after its node with a 4 ms time offset: the predicted velocity is
    v + a dt and the position v dt + a dt^2 / 2 further (dt = 7 ms, by hand in NED);
    node_acceleration of a level IMU at rest is zero (f_b = -g_n)."""
    from ins.estimation.core.measurements import node_acceleration
    from ins.nav import earth
    p = _point()
    dt = 0.003 + 0.004
    a = p.a_n
    v = GnssVelocity(100.003, np.zeros(3), np.ones(3))
    p0 = NavPoint(p.time, p.state, p.sensors, p.layout, p.w_meas_b, p.l_b, p.dl_b)
    np.testing.assert_allclose(v.predict(p) - v.predict(p0), a * dt, atol=1e-12)
    g = GnssPosition(100.003, p.state[:3], np.eye(3))
    moved = earth.ned_offset(g.predict(p0), g.predict(p))
    np.testing.assert_allclose(moved, 0.5 * a * dt ** 2, atol=1e-9)
    rest = np.concatenate([[0.5, 1.0, 10.0], np.zeros(3), [0.0, 0.0, 0.0, 1.0]])
    f_b = -earth.gravity_n(0.5, 10.0)
    np.testing.assert_allclose(node_acceleration(rest, f_b), 0.0, atol=1e-12)
