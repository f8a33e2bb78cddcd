"""Sensor errors: each term does what its definition says; reproducible by seed; a
bias-only static run drifts as the analytic Schuler error model predicts."""
import numpy as np
import pytest

from ins.nav.earth import earth_rate_n, gravity_n, radii
from ins.nav.imu import ImuLog
from ins.nav.mechanization import NavState, mechanize
from ins.simulate.sensor_errors import PRESETS, ImuErrorModel, apply_errors


def static_log(lat, h, rate_hz, duration_s):
    """Exact increments of an IMU at rest, axes = NED (x north, y east, z down)."""
    n = int(duration_s * rate_hz) + 1
    dt = 1.0 / rate_hz
    w = earth_rate_n(lat) * dt
    f = -gravity_n(lat, h) * dt
    return ImuLog(np.arange(n) * dt, np.tile(w, (n, 1)), np.tile(f, (n, 1)))


def test_units_round_trip_and_presets():
    for grade, values in PRESETS.items():
        m = ImuErrorModel.preset(grade)
        back = m.to_units()
        for k, v in values.items():
            assert np.allclose(back[k], v, rtol=1e-12), (grade, k)
    m = ImuErrorModel.from_units(gyro_bias_dph=3600.0, accel_bias_mgal=[1e5, 0, 0],
                                 arw_deg_sqrth=60.0)
    assert np.allclose(m.gyro_bias, np.radians(1.0))         # 3600 deg/h = 1 deg/s
    assert np.allclose(m.accel_bias, [1.0, 0, 0])            # 1e5 mGal = 1 m/s^2
    assert np.allclose(m.arw, np.radians(1.0))               # 60 deg/sqrt(h) = 1 deg/sqrt(s)
    with pytest.raises(ValueError, match="unknown IMU error key"):
        ImuErrorModel.from_units(gyro_drift=1.0)


def test_seed_reproducible_and_chunk_independent():
    log = static_log(0.5, 100.0, 100.0, 60.0)
    m = ImuErrorModel.preset("mems")
    a = apply_errors(log, m, seed=7)
    b = apply_errors(log, m, seed=7, chunk_rows=1000)
    c = apply_errors(log, m, seed=8)
    assert np.array_equal(a.dtheta_b, b.dtheta_b) and np.array_equal(a.dvel_b, b.dvel_b)
    assert not np.array_equal(a.dtheta_b, c.dtheta_b)
    assert not np.shares_memory(a.dtheta_b, log.dtheta_b)


def test_deterministic_terms():
    rng = np.random.default_rng(0)
    n = 1000
    log = ImuLog(np.arange(n) * 0.01, rng.normal(0, 1e-3, (n, 3)), rng.normal(0, 0.1, (n, 3)))
    m = ImuErrorModel(gyro_bias=[1e-4, 2e-4, 3e-4], gyro_scale=[1e-3, 0, 0],
                      gyro_misalignment=[0, 0, 2e-3], accel_bias=[0.01, 0, 0])
    y = apply_errors(log, m, seed=0)
    M = np.array([[1.001, 2e-3, 0], [2e-3, 1, 0], [0, 0, 1]])
    assert np.allclose(y.dtheta_b, log.dtheta_b @ M.T + np.array([1e-4, 2e-4, 3e-4]) * 0.01,
                       atol=1e-15)
    assert np.allclose(y.dvel_b - log.dvel_b, [0.01 * 0.01, 0, 0], atol=1e-15)


def test_quantization_carries_the_residue():
    rng = np.random.default_rng(1)
    n = 5000
    x = rng.uniform(0, 3e-6, (n, 3))
    log = ImuLog(np.arange(n) * 0.005, x, x)
    q = 1e-6
    y = apply_errors(log, ImuErrorModel(gyro_quantization=q, accel_quantization=q), seed=0)
    r = y.dtheta_b / q
    assert np.allclose(r, np.round(r), atol=1e-9)            # multiples of q
    err = np.cumsum(y.dtheta_b - x, axis=0)                  # the running sum stays within q/2
    assert np.abs(err).max() <= 0.5 * q + 1e-15


def test_gauss_markov_statistics():
    n = 200_000
    dt = 1.0
    log = ImuLog(np.arange(n) * dt, np.zeros((n, 3)), np.zeros((n, 3)))
    sigma, T = 1e-5, 50.0
    y = apply_errors(log, ImuErrorModel(gyro_bias_instability=sigma, corr_time=T), seed=3)
    g = y.dtheta_b[:, 0] / dt
    assert np.std(g) == pytest.approx(sigma, rel=0.05)
    lag = int(T / dt)
    rho = np.corrcoef(g[:-lag], g[lag:])[0, 1]
    assert rho == pytest.approx(np.exp(-1.0), abs=0.05)     # e^{-tau/T} at tau = T


@pytest.mark.parametrize("which", ["accel", "gyro"])
def test_bias_only_static_drift_follows_schuler(which):
    """Static at the equator, axes north-east-down, over one Schuler period.

    Error model (psi-angle, Earth rate neglected): dv_N' = g phi_E + b_N,
    phi_E' = -dv_N / R - eps_E, hence
    dN(t) = b_N / ws^2 (1 - cos ws t) - R eps_E (t - sin(ws t) / ws), ws^2 = g / R.
    """
    lat, h, rate = 0.0, 0.0, 20.0
    g = float(gravity_n(lat, h)[2])
    R = float(radii(lat)[0]) + h
    ws = np.sqrt(g / R)
    T = 2 * np.pi / ws
    log = static_log(lat, h, rate, T)
    if which == "accel":
        model = ImuErrorModel.from_units(accel_bias_mgal=[50.0, 0, 0])   # b_N = 5e-4 m/s^2
    else:
        model = ImuErrorModel.from_units(gyro_bias_dph=[0, 0.01, 0])     # eps_E
    y = apply_errors(log, model, seed=0)
    nav = mechanize(y, NavState(np.array([lat, 0.0, h]), np.zeros(3), np.array([0, 0, 0, 1.0])))
    t = nav.time - nav.time[0]
    dN = (nav.lla[:, 0] - lat) * R
    b, eps = model.accel_bias[0], model.gyro_bias[1]
    pred = b / ws ** 2 * (1 - np.cos(ws * t)) - R * eps * (t - np.sin(ws * t) / ws)
    scale = np.abs(pred).max()
    assert scale > 1.0                                        # metres of drift, not noise
    assert np.abs(dN - pred).max() < 0.03 * scale
    if which == "accel":                                      # amplitude 2 b/g R at t = T/2
        assert np.abs(dN).max() == pytest.approx(2 * b / g * R, rel=0.03)
