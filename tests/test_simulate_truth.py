"""Truth trajectory: its rates are the derivatives of its states, the block geometry,
the coordinated turn, the static segment and the stabilized mount."""
from pathlib import Path

import numpy as np
import pytest
import tomllib
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from ins.nav.earth import earth_rate_n, gravity_n, lla_rate, ned_offset, radii, transport_rate_n
from ins.nav.rotation import quat_to_dcm, quat_to_euler
from ins.simulate.plan_read import parse_plan
from ins.simulate.truth import KNEE, build_truth

DEMO = Path(__file__).resolve().parents[1] / "data" / "flights" / "demo.toml"


def short_plan(**changes):
    """A ~3 min flight: 10 s straight and level, 2 strips of 1 km, a 25 deg bank turn in
    which the mount saturates (level limit 5 deg), turbulence and wind."""
    with open(DEMO, "rb") as f:
        d = tomllib.load(f)
    d["block"].update(strip_length_m=1000.0, n_strips=2)
    d["flight"].update(start="air", stationary_s=10.0, run_in_m=200.0, bank_deg=25.0)
    d["mount"]["level_limit_deg"] = 5.0
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
    assert np.abs(_fd(truth, t, "mount_rpy", 2e-3) - s.mount_rate).max() < 1e-8
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


def _strip_ned(truth):
    plan = truth.plan
    o = np.array([plan.block.origin_lat, plan.block.origin_lon, plan.flying_height_m])
    t = [x for st in truth.strips for x in (st.t_start, st.t_end)]
    return ned_offset(o, truth.evaluate(t).lla)[:, :2].reshape(-1, 2, 2)


def _three_strips():
    """3 strips at azimuth 30 deg, 2.5 km apart: 90-straight-90 turns (diameter 2 km)."""
    with open(DEMO, "rb") as f:
        d = tomllib.load(f)
    del d["block"]["side_overlap_percent"]
    d["block"].update(strip_length_m=1000.0, n_strips=3, strip_spacing_m=2500.0,
                      strip_azimuth_deg=30.0)
    d["flight"].update(stationary_s=0.0, bank_deg=20.0)
    return build_truth(parse_plan(d))


@pytest.mark.parametrize("case", ["bulb turn", "90-straight-90"])
def test_strip_geometry(truth, case):
    """Each strip starts at its planned point in the local level frame at the origin
    (within 2 cm; the turns are designed on a flat Earth, then corrected on the
    geodetic path), for bulb turns (spacing < turn diameter) and 90-straight-90 turns."""
    if case != "bulb turn":
        truth = _three_strips()
    plan = truth.plan
    ned = _strip_ned(truth)
    az = plan.block.strip_azimuth
    right = np.array([-np.sin(az), np.cos(az)])
    along = np.array([np.cos(az), np.sin(az)])
    L = plan.block.strip_length
    for i, st in enumerate(truth.strips):
        planned = i * plan.strip_spacing_m * right + (i % 2) * L * along
        assert np.hypot(*(ned[i, 0] - planned)) < 0.02             # m
        # the strip is a line of constant azimuth of the planned length
        assert (ned[i, 1] - ned[i, 0]) @ (along if i % 2 == 0 else -along) == pytest.approx(
            L, abs=0.05)
        v = truth.evaluate(np.linspace(st.t_start, st.t_end, 20)).v_n
        assert np.allclose(np.arctan2(v[:, 1], v[:, 0]) % (2 * np.pi), st.azimuth_rad,
                           atol=1e-12)
    assert ned[0, 0] == pytest.approx([0.0, 0.0], abs=1e-6)        # origin


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
    # C_nb = C_na C_ap, C_ap = Rz(yaw) Ry(pitch) Rx(roll) (scipy's ZYX, independent of ins)
    C_ap = Rotation.from_euler("ZYX", s.mount_rpy[:, ::-1]).as_matrix()
    C = Rotation.from_quat(s.q_na).as_matrix() @ C_ap
    assert np.abs(C - Rotation.from_quat(s.q_nb).as_matrix()).max() < 1e-12


def test_mount_saturates_in_turns_and_follows_on_strips(truth):
    """Bank 25 deg > level limit 5 deg: in the turn the mount runs (smoothly) into its
    limit and the platform banks by the rest; on the strips it stays inside the knee."""
    plan = truth.plan
    lim = plan.mount.level_limit
    s = truth.evaluate(np.linspace(truth.t_start, truth.t_end, 4000))
    assert np.abs(s.mount_rpy[:, :2]).max() <= lim
    assert np.abs(s.mount_rpy[:, 0]).max() > 0.99 * lim            # saturated
    roll_a = quat_to_euler(s.q_na)[:, 0]
    roll_b = quat_to_euler(s.q_nb)[:, 0]
    k = np.argmax(np.abs(roll_a))
    assert abs(roll_a[k]) > plan.flight.bank
    assert abs(roll_b[k]) == pytest.approx(abs(roll_a[k]) - lim, abs=np.radians(0.3))
    for st in truth.strips:
        m = truth.evaluate(np.linspace(st.t_start, st.t_end, 500)).mount_rpy
        assert np.abs(m[:, :2]).max() < KNEE * lim
        assert np.abs(m[:, 2]).max() < KNEE * plan.mount.azimuth_limit


def test_smooth_through_saturation(truth):
    """Angular rate and acceleration continuous where the mount enters its soft limit:
    the largest step of the angular acceleration (finite differences of w_ib_b) between
    neighbouring samples shrinks with the grid step (a jump would not)."""
    lim = KNEE * truth.plan.mount.level_limit
    t = np.linspace(truth.strips[0].t_end, truth.strips[1].t_start, 20000)
    m = truth.evaluate(t).mount_rpy[:, 0]
    k = np.nonzero(np.abs(m) > lim)[0][0]                          # enters the knee
    h = 1e-5
    steps = []
    for dt in (1e-3, 1e-4):
        tt = t[k] + np.arange(-100, 100) * dt
        acc = (truth.evaluate(tt + h).w_ib_b - truth.evaluate(tt - h).w_ib_b) / (2 * h)
        steps.append(np.abs(np.diff(acc, axis=0)).max())
        # and the mount angle is the integral of its rate (no step in the angle)
        assert np.abs(np.diff(truth.evaluate(tt).mount_rpy, axis=0)).max() < 0.2 * dt
    assert np.abs(acc).max() > 5e-3                                 # rad/s^2: it turns in
    assert steps[1] < 0.15 * steps[0]                               # continuous


def test_servo_is_a_first_order_lag():
    """One roll sinusoid, no wind, straight flight: the mount roll is minus the output of
    y' = (x - y) / tau driven by the aircraft roll x (solved numerically here)."""
    tau = 0.3
    plan = short_plan(wind__speed_mps=0.0, mount__servo_lag_s=tau,
                      turbulence__roll_amp_deg=[2.0], turbulence__roll_freq_hz=[0.4],
                      turbulence__pitch_amp_deg=[], turbulence__pitch_freq_hz=[],
                      turbulence__yaw_amp_deg=[], turbulence__yaw_freq_hz=[])
    tr = build_truth(plan)
    st = tr.strips[0]
    t0 = st.t_start - 20 * tau                      # the transient decays as e^-20

    def roll_a(t):
        return quat_to_euler(tr.evaluate(t).q_na)[:, 0]

    sol = solve_ivp(lambda t, y: (roll_a(t) - y) / tau, (t0, st.t_end), roll_a(t0),
                    method="DOP853", rtol=1e-11, atol=1e-13, dense_output=True)
    t = np.linspace(st.t_start, st.t_end, 300)
    s = tr.evaluate(t)
    y = sol.sol(t)[0]
    assert np.abs(s.mount_rpy[:, 0] + y).max() < 1e-8
    # the platform keeps the residual (1 - H) of the turbulence: gain w tau / sqrt(1 + ..)
    w = 2 * np.pi * 0.4
    resid = quat_to_euler(s.q_nb)[:, 0]
    assert np.abs(resid).max() == pytest.approx(np.radians(2.0) * w * tau / np.hypot(1, w * tau),
                                                rel=0.02)
