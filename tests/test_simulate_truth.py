"""Truth trajectory: its rates are the derivatives of its states, the block geometry,
the coordinated turn, the static segment and the stabilized mount."""
import copy
import tomllib
from pathlib import Path

import numpy as np
import pytest

from ins.earth import earth_rate_n, gravity_n, lla_rate, ned_offset, radii, transport_rate_n
from ins.rotation import quat_to_dcm, quat_to_euler
from ins.simulate.plan import parse_plan
from ins.simulate.truth import build_truth

DEMO = Path(__file__).resolve().parents[1] / "data" / "flights" / "demo.toml"


def short_plan(**changes):
    """A ~4 min flight: 10 s static in the air, 2 strips of 1 km, a 15 deg bank turn,
    turbulence, wind and the mount (level limit 20 deg)."""
    with open(DEMO, "rb") as f:
        d = tomllib.load(f)
    d["block"].update(strip_length_m=1000.0, n_strips=2)
    d["flight"].update(start="air", stationary_s=10.0, run_in_m=300.0, bank_deg=15.0)
    d["mount"]["level_limit_deg"] = 20.0
    for key, value in changes.items():
        section, name = key.split("__")
        d[section][name] = value
    return parse_plan(d)


@pytest.fixture(scope="module")
def truth():
    return build_truth(short_plan())


def _fd(truth, t, attr, h):
    """4th-order central difference of a TruthSample attribute."""
    v = [getattr(truth.evaluate(t + k * h), attr) for k in (-2, -1, 1, 2)]
    return (v[0] - 8 * v[1] + 8 * v[2] - v[3]) / (12 * h)


def test_rates_are_derivatives(truth):
    t = np.linspace(truth.t_start + 1, truth.t_end - 1, 400)
    s = truth.evaluate(t)
    assert np.abs(_fd(truth, t, "v_n", 1e-2) - s.a_n).max() < 1e-6
    assert np.abs(_fd(truth, t, "mount_rpy", 1e-2) - s.mount_rate).max() < 1e-7
    rm, rn = radii(s.lla[:, 0])
    d = (_fd(truth, t, "lla", 0.1) - lla_rate(s.lla[:, 0], s.lla[:, 2], s.v_n))
    # (dense output of the ODE: a few um of interpolation error)
    assert np.abs(d[:, 0] * rm).max() < 1e-4 and np.abs(d[:, 1] * rn).max() < 1e-4
    dh = _fd(truth, t, "lla", 0.01)[:, 2] + s.v_n[:, 2]          # analytic height
    assert np.abs(dh).max() < 1e-6
    # w_nb_b from the derivative of C_nb: C_bn dC_nb/dt = [w_nb_b x]
    h = 1e-3
    C = [quat_to_dcm(truth.evaluate(t + k * h).q_nb) for k in (-2, -1, 1, 2)]
    dC = (C[0] - 8 * C[1] + 8 * C[2] - C[3]) / (12 * h)
    C_nb = quat_to_dcm(s.q_nb)
    W = np.einsum("nji,njk->nik", C_nb, dC)
    w_nb_b = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], -1)
    w_in_n = earth_rate_n(s.lla[:, 0]) + transport_rate_n(s.lla[:, 0], s.lla[:, 2], s.v_n)
    w_ib_b = w_nb_b + np.einsum("nji,nj->ni", C_nb, w_in_n)
    assert np.abs(w_ib_b - s.w_ib_b).max() < 1e-8
    assert np.abs(s.w_ib_b).max() > 0.02            # the test saw real rotation


def test_strip_geometry(truth):
    plan = truth.plan
    o = np.array([plan.block.origin_lat, plan.block.origin_lon, plan.flying_height_m])
    s0, s1 = truth.strips
    a = truth.evaluate([s0.t_start, s0.t_end, s1.t_start, s1.t_end])
    assert np.abs(a.lla[0, :2] - o[:2]).max() < 1e-12          # strip 0 starts at the origin
    ned = ned_offset(o, a.lla)
    az = plan.block.strip_azimuth                               # strip 1 to the right
    right = np.array([-np.sin(az), np.cos(az)])
    along = np.array([np.cos(az), np.sin(az)])
    assert ned[1, :2] @ along == pytest.approx(plan.block.strip_length, abs=0.5)
    assert ned[2, :2] @ right == pytest.approx(plan.strip_spacing_m, abs=2.0)
    assert ned[2, :2] @ along == pytest.approx(plan.block.strip_length, abs=3.0)
    assert ned[3, :2] @ along == pytest.approx(0.0, abs=3.0)
    # on the strips the ground track has the strip azimuth
    for st in truth.strips:
        v = truth.evaluate(np.linspace(st.t_start, st.t_end, 20)).v_n
        assert np.allclose(np.arctan2(v[:, 1], v[:, 0]) % (2 * np.pi), st.azimuth_rad,
                           atol=1e-12)


def test_coordinated_turn_and_crab(truth):
    plan = truth.plan
    t = 0.5 * (truth.strips[0].t_end + truth.strips[1].t_start)   # inside the turn manoeuvre
    t = np.linspace(t - 30, t + 30, 200)
    s = truth.evaluate(t)
    roll, pitch, yaw = quat_to_euler(s.q_na).T
    speed = np.hypot(s.v_n[:, 0], s.v_n[:, 1])
    psi_dot = (s.v_n[:, 0] * s.a_n[:, 1] - s.v_n[:, 1] * s.a_n[:, 0]) / speed ** 2
    turb = sum(plan.turbulence.roll_amp)
    assert np.abs(roll - np.arctan(speed * psi_dot / 9.80665)).max() <= turb + 1e-9
    assert np.abs(psi_dot).max() == pytest.approx(plan.flight.turn_rate, rel=1e-6)
    # wind triangle: air velocity = ground velocity - wind, along the aircraft heading
    wn, we = plan.wind.w_n
    air = s.v_n[:, :2] - [wn, we]
    heading = np.arctan2(air[:, 1], air[:, 0])
    dyaw = np.angle(np.exp(1j * (yaw - heading)))
    assert np.abs(dyaw).max() <= sum(plan.turbulence.yaw_amp) + 1e-9


def test_ground_static_segment():
    plan = short_plan(flight__start="ground", flight__stationary_s=30.0,
                      flight__height_agl_m=300.0)
    tr = build_truth(plan)
    t0, t1 = tr.stationary[0]
    s = tr.evaluate(np.linspace(t0, t1, 50))
    assert np.abs(s.v_n).max() == 0 and np.ptp(s.lla, axis=0).max() == 0
    assert np.allclose(np.linalg.norm(s.w_ib_b, axis=1), 7.292115e-5, rtol=1e-12)
    assert np.allclose(np.linalg.norm(s.f_b, axis=1), gravity_n(s.lla[:, 0], s.lla[:, 2])[:, 2],
                       rtol=1e-12)
    assert s.lla[0, 2] == pytest.approx(plan.block.origin_h)
    top = tr.evaluate(tr.strips[0].t_start)
    assert top.lla[0, 2] == pytest.approx(plan.flying_height_m, abs=1.0)   # + heave


def test_mount_levels_the_platform(truth):
    st = truth.strips[0]
    s = truth.evaluate(np.linspace(st.t_start, st.t_end, 500))
    rpy_a = quat_to_euler(s.q_na)
    rpy_b = quat_to_euler(s.q_nb)
    # the aircraft rolls, pitches and crabs; the platform stays level and on the line,
    # up to the motion during the servo lag (turbulence rate x lag)
    lag = truth.plan.mount.servo_lag
    tb = truth.plan.turbulence
    slack = lag * sum(2 * np.pi * f * a for f, a in zip(tb.roll_freq, tb.roll_amp))
    assert np.abs(rpy_a[:, 0]).max() > 3 * slack
    assert np.abs(rpy_b[:, 0]).max() < 1.5 * slack + 1e-6
    track = np.arctan2(s.v_n[:, 1], s.v_n[:, 0])
    crab = np.abs(np.angle(np.exp(1j * (rpy_a[:, 2] - track)))).max()
    assert crab > np.radians(3)
    assert np.abs(np.angle(np.exp(1j * (rpy_b[:, 2] - track)))).max() < 0.05 * crab
    # C_nb = C_na C_ap
    C = quat_to_dcm(s.q_na) @ quat_to_dcm(
        __import__("ins.rotation", fromlist=["euler_to_quat"]).euler_to_quat(s.mount_rpy))
    assert np.abs(C - quat_to_dcm(s.q_nb)).max() < 1e-12


def test_mount_soft_limit():
    plan = short_plan(mount__level_limit_deg=2.0, flight__bank_deg=1.0,
                      turbulence__roll_amp_deg=[0.5, 0.4])
    tr = build_truth(plan)
    m = tr.evaluate(np.linspace(tr.t_start, tr.t_end, 3000)).mount_rpy
    assert np.abs(m[:, :2]).max() < np.radians(2.0)
    assert np.abs(m[:, :2]).max() > np.radians(1.6)     # the knee was reached
