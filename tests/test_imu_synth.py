"""Error-free increments: the mechanization reproduces the truth; pyins agrees."""
import numpy as np
import pytest
from test_simulate_truth import short_plan

from ins.nav.accuracy import compare
from ins.nav.mechanization import NavState, mechanize
from ins.nav.trajectory import Trajectory
from ins.simulate.imu_synth import synthesize_imu
from ins.simulate.truth import build_truth


@pytest.fixture(scope="module")
def flight():
    truth = build_truth(short_plan())
    return truth, synthesize_imu(truth, 200.0)


def test_round_trip_through_the_mechanization(flight):
    truth, log = flight
    assert log.time[0] == truth.t_start and np.allclose(np.diff(log.time), 0.005)
    s0 = truth.evaluate(log.time[0])
    nav = mechanize(log, NavState(s0.lla[0], s0.v_n[0], s0.q_nb[0]))
    s = truth.evaluate(log.time)
    e = compare(nav, Trajectory(time=s.time, lla=s.lla, v_n=s.v_n, q_nb=s.q_nb)).summary()
    assert e["horizontal_m"]["max"] < 0.01                 # target: 1 cm (measured ~1 mm)
    assert abs(e["down_m"]["max"]) < 0.01
    for k in ("tilt_n_arcsec", "tilt_e_arcsec", "heading_arcsec"):
        assert abs(e[k]["max"]) < 1.0                      # target: 1 arcsec (measured 1e-6)
    # the flight turned and shook: a test of something
    assert np.ptp(np.cumsum(log.dtheta_b[:, 2])) > np.pi


def test_increments_are_integrals_of_the_rates(flight):
    truth, log = flight
    k = np.arange(1, len(log), 997)
    fine = np.linspace(0, 1, 201)
    for kk in k[:5]:
        t = log.time[kk - 1] + fine * (log.time[kk] - log.time[kk - 1])
        s = truth.evaluate(t)
        from scipy.integrate import simpson
        assert np.allclose(simpson(s.w_ib_b, x=t, axis=0), log.dtheta_b[kk], rtol=0, atol=1e-14)
        assert np.allclose(simpson(s.f_b, x=t, axis=0), log.dvel_b[kk], rtol=0, atol=1e-12)


def test_agrees_with_pyins(flight):
    pytest.importorskip("pyins")
    from pyins import sim

    from ins.nav.rotation import quat_to_euler
    truth, log = flight
    i0, n = 200 * 100, 200 * 60                    # one minute inside the turn
    t = log.time[i0:i0 + n]
    s = truth.evaluate(t)
    rph = np.degrees(quat_to_euler(s.q_nb))
    rph[:, 2] = np.degrees(np.unwrap(np.radians(rph[:, 2])))
    lla = np.column_stack([np.degrees(s.lla[:, :2]), s.lla[:, 2]])
    _, imu = sim.generate_imu(t - t[0], lla, rph, s.v_n, sensor_type="increment")
    g = imu[["gyro_x", "gyro_y", "gyro_z"]].to_numpy()[1:]
    a = imu[["accel_x", "accel_y", "accel_z"]].to_numpy()[1:]
    assert np.abs(log.dtheta_b[i0 + 1:i0 + n]).max() > 1e-4        # it turns
    # measured 5e-12 rad: pyins fits splines to the sampled attitude
    assert np.abs(g - log.dtheta_b[i0 + 1:i0 + n]).max() < 1e-10
    # measured 7e-8 m/s (1.4e-5 m/s^2): pyins has its own gravity model (Somigliana with
    # a linear height term), ours is the normal gravity of the INS paper
    assert np.abs(a - log.dvel_b[i0 + 1:i0 + n]).max() < 2e-7
