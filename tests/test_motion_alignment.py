"""Start anywhere (ins.estimation.alignment.motion) and the recovery from a run of
rejected fixes (ins.estimation.core.filter), on ground journeys whose truth is closed-form
(ins.simulate.ground): a consumer IMU at rest then driving, a walk, a moving start."""
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ins.common.errors import InputError
from ins.estimation.alignment.motion import _match, align_anywhere
from ins.simulate.ground import GroundTruth, Journey, rtk_fixes
from ins.simulate.imu_synth import synthesize_imu
from ins.simulate.sensor_errors import ImuErrorModel, apply_errors

#: A short drive: 12 s parked, then away with two turns (the IMU turned 25 deg in the car).
SHORT_CAR = Journey(duration_s=70.0, speed_steps=((15.0, 6.0, 8.0), (50.0, 4.0, 3.0)),
                    turns=((30.0, 6.0, 90.0), (55.0, 5.0, -60.0)), heading0_deg=200.0,
                    mounting_rpy_deg=(2.0, -3.0, 25.0), grade_deg=1.0)
#: A short walk from a standstill, the phone held 80 deg to the left and pitched down.
SHORT_WALK = Journey(duration_s=50.0, speed_steps=((5.0, 3.0, 1.4),),
                     turns=((25.0, 4.0, 90.0),), heading0_deg=120.0, bounce_m=0.03,
                     mounting_rpy_deg=(3.0, -25.0, -80.0), lla0_deg=(-33.9, 151.2, 40.0))


def _log(journey, rate_hz, grade, seed):
    truth = GroundTruth(journey)
    imu = synthesize_imu(truth, rate_hz)
    if grade is not None:
        imu = apply_errors(imu, ImuErrorModel.preset(grade), seed=seed)
    return truth, imu, rtk_fixes(truth, seed=seed, velocity_latency_s=0.0)


@pytest.fixture(scope="module")
def car():
    return _log(SHORT_CAR, 100.0, "consumer", 3)


@pytest.fixture(scope="module")
def walk():
    return _log(SHORT_WALK, 167.0, "consumer", 4)


def _errors_deg(truth, ms):
    """Tilt error about north and east (the n-frame rotation vector of ``C_est C_true^T``)
    and heading error of the alignment, deg."""
    s = truth.evaluate(ms.alignment.time)
    est = Rotation.from_quat(ms.alignment.state.q_nb)
    ref = Rotation.from_quat(s.q_nb[0])
    e_n = np.rad2deg((est * ref.inv()).as_rotvec())
    head = (est.as_euler("ZYX")[0] - ref.as_euler("ZYX")[0] + np.pi) % (2 * np.pi) - np.pi
    return e_n, np.rad2deg(head)


def test_procrustes_match_recovers_a_known_azimuth_with_drift():
    rng = np.random.default_rng(0)
    t = np.linspace(0.0, 10.0, 41)
    x = np.column_stack([3 * np.sin(0.5 * t), 2 * (1 - np.cos(0.4 * t)), -9.8 * t])
    psi = np.deg2rad(-123.4)
    c, s = np.cos(psi), np.sin(psi)
    y = np.zeros((len(t), 3))
    y[:, :2] = x[:, :2] @ np.array([[c, s], [-s, c]]) + 0.3 + 0.05 * t[:, None]  # offset, drift
    y[:, :2] += rng.normal(0.0, 0.01, (len(t), 2))
    x_L = x.copy()
    x_L[:, 2] = 0.0              # _match adds g t to the vertical of L: any g works here
    est, sigma = _match(t, x_L, t, y, 0.0, 10.0, 9.8)
    assert abs(np.rad2deg(est - psi)) < 5 * np.rad2deg(sigma)
    assert np.rad2deg(sigma) < 0.5


def test_rest_start_level_bias_and_heading_error_free(car):
    truth, _, gnss = car
    imu = synthesize_imu(truth, 100.0)                         # no sensor errors
    ms = align_anywhere(imu, gnss)
    e, head = _errors_deg(truth, ms)
    assert ms.rest_s > 10.0 and "rest" in ms.how
    assert np.all(np.abs(e[:2]) < 1e-3)                       # level: exact at rest
    assert abs(head) < 0.5 and abs(head) < 3 * ms.alignment.att_std_deg[2]
    # the rest's mean rate is the Earth rate in the body (15 deg/h): taken out with the
    # attitude found, the error-free gyro has no bias left (the heading error's share of
    # the horizontal Earth rate: 0.5 deg x 15 deg/h = 0.13 deg/h at most)
    assert np.linalg.norm(ms.gyro_bias_b) < np.deg2rad(0.15 / 3600)


def test_rest_start_consumer_imu_within_its_sigmas(car):
    truth, imu, gnss = car
    ms = align_anywhere(imu, gnss)
    e, head = _errors_deg(truth, ms)
    std = ms.alignment.att_std_deg
    assert np.all(np.abs(e[:2]) < 3 * std[:2])
    assert abs(head) < 3 * std[2] and std[2] < 10.0
    # the gyro biases found at rest: the injected 400/-300/-612 deg/h within the Earth
    # rate and the noise of a 12 s mean (0.4 deg/sqrt(h) -> ~7 deg/h)
    injected = np.deg2rad(np.array([400.0, -300.0, -612.0]) / 3600)
    assert np.all(np.abs(ms.gyro_bias_b - injected) < np.deg2rad(40.0 / 3600))


def test_walk_from_standstill_with_the_phone_held_sideways(walk):
    truth, imu, gnss = walk
    ms = align_anywhere(imu, gnss)
    e, head = _errors_deg(truth, ms)
    std = ms.alignment.att_std_deg
    assert abs(head) < 3 * std[2] and std[2] < 15.0, (head, std)
    assert np.all(np.abs(e[:2]) < 3 * std[:2])


def test_moving_start(car):
    truth, imu, gnss = car
    t0 = truth.t_start + 22.0                                  # at 8 m/s, before the turn
    ms = align_anywhere(imu, gnss, t0)
    e, head = _errors_deg(truth, ms)
    std = ms.alignment.att_std_deg
    assert ms.gyro_bias_b is None and "moving" in ms.how
    assert abs(head) < 3 * std[2], (head, std)
    assert np.all(np.abs(e[:2]) < 3 * std[:2])
    s = truth.evaluate(ms.alignment.time)
    assert np.linalg.norm(ms.alignment.state.v_n - s.v_n[0]) < 0.1


def test_moving_start_levels_from_metre_fixes_without_velocities():
    """A moving start from 1 Hz fixes of 1 m noise and no velocities in the file (the
    PSINS car's emulated GNSS): the level from the drift of the velocity mismatch over
    the matching window is within 0.5 deg with an error-free IMU, and inside 3 of its
    stated sigmas (the GNSS acceleration over the first 3 s left 1.2-3.5 deg stated as
    1.0)."""
    truth = GroundTruth(SHORT_CAR)
    imu = synthesize_imu(truth, 100.0)
    fixes = rtk_fixes(truth, rate_hz=1.0, sigma_ned_m=(1.0, 1.0, 1.0), seed=5)
    gnss = replace(fixes, v_n=None, sigma_vel_ned_mps=None, cov_ned_m2=None)
    for dt0 in (13.0, 22.0, 32.0):
        ms = align_anywhere(imu, gnss, truth.t_start + dt0)
        e, _ = _errors_deg(truth, ms)
        std = ms.alignment.att_std_deg
        assert "moving" in ms.how
        assert np.all(np.abs(e[:2]) < 0.5), (dt0, e)
        assert np.all(np.abs(e[:2]) < 3 * std[:2]), (dt0, e, std)


def test_a_log_that_never_moves_starts_from_the_gyrocompass():
    """No motion to match (it used to be refused): level exact from the error-free rest,
    the gyrocompass heading exact too (the Earth rate is all the gyro sees), stated with
    the filter's broad prior (at least 30 deg) and the at-rest bound (about 0 here);
    the gyro biases nil."""
    from ins.estimation.alignment.motion import STATIC_HEADING_PRIOR_DEG
    from ins.simulate.ground import Journey as J
    tr = GroundTruth(J(duration_s=30.0, speed_steps=()))
    ms = align_anywhere(synthesize_imu(tr, 100.0), rtk_fixes(tr, seed=1))
    e, head = _errors_deg(tr, ms)
    assert ms.heading_from == "gyrocompass" and "gyrocompassing" in ms.how
    assert np.all(np.abs(e) < 1e-4) and abs(head) < 1e-4
    assert ms.alignment.att_std_deg[2] == STATIC_HEADING_PRIOR_DEG
    assert ms.heading_floor_deg < 0.1
    assert np.linalg.norm(ms.gyro_bias_b) < np.deg2rad(1e-3 / 3600)


def _process(tmp_path, journey_log, extra=""):
    """``ins.process`` of a journey's files with the consumer preset."""
    from ins.estimation.pipeline.presets import apply_preset
    from ins.estimation.pipeline.process import process
    from ins.estimation.pipeline.config import load_config
    from ins.io.gnss import write_gnss
    from ins.io.imu_files import write_kfgins_text
    truth, imu, gnss = journey_log
    write_kfgins_text(tmp_path / "imu.txt", imu)
    write_gnss(tmp_path / "gnss.txt", gnss)
    (tmp_path / "c.toml").write_text('[files]\nimu = "imu.txt"\ngnss = "gnss.txt"\n' + extra)
    cfg = apply_preset(load_config(tmp_path / "c.toml"), "consumer")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return truth, process(cfg, accept_poor=True)


def _h_err(truth, traj):
    from ins.nav import earth
    s = truth.evaluate(traj.time)
    dn = earth.ned_offset(s.lla, traj.lla)
    return np.hypot(dn[:, 0], dn[:, 1])


def test_process_starts_anywhere_with_no_attitude_given(tmp_path, car):
    truth, res = _process(tmp_path, car)
    assert res.alignment.method == "anywhere" and "rest" in res.start_how
    assert np.sqrt(np.mean(_h_err(truth, res.smoothed) ** 2)) < 0.05
    assert res.counts["rejected"] < 0.05 * res.quality["tested"]


def test_a_wrong_start_recovers_instead_of_rejecting_every_fix(tmp_path, car):
    """A heading 40 deg off with a stated sigma of 0.5 deg: the gate rejects the fixes
    once the car drives; without the recovery it rejects all of them to the end and
    the solution runs away, with it the run of rejections ends in a recovery."""
    truth, imu, gnss = car
    s = truth.evaluate(truth.t_start)
    rpy = Rotation.from_quat(s.q_nb[0]).as_euler("ZYX", degrees=True)[::-1] + [0, 0, 40.0]
    lat, lon, h = (float(x) for x in (np.rad2deg(s.lla[0, 0]), np.rad2deg(s.lla[0, 1]),
                                      s.lla[0, 2]))
    extra = (f"[initial]\nlat_deg = {lat!r}\nlon_deg = {lon!r}\nh_m = {h!r}\n"
             f"vel_ned_mps = [0.0, 0.0, 0.0]\nrpy_deg = {[float(x) for x in rpy]}\n"
             f"time_s = {float(truth.t_start)!r}\natt_std_deg = [0.5, 0.5, 0.5]\n")
    _, bad = _process(tmp_path, car, extra + "[filter]\nrecover = false\n")
    _, good = _process(tmp_path, car, extra)
    e_bad, e_good = _h_err(truth, bad.forward), _h_err(truth, good.forward)
    end = bad.forward.time > truth.t_end - 10.0
    assert bad.counts["recoveries"] == 0 and e_bad[end].max() > 10.0
    assert good.counts["recoveries"] >= 1
    assert e_good[end].max() < 0.5
    assert good.counts["rejected"] < 0.5 * bad.counts["rejected"]


#: The walk of :data:`SHORT_WALK` with a 15 s outage while walking, as the low-cost bench
#: runs it at full length (``bench/bench_low_cost.py``).
WALK_OUTAGE = Journey(duration_s=75.0, speed_steps=((5.0, 3.0, 1.4), (60.0, 2.0, -1.4)),
                      turns=((25.0, 4.0, 90.0), (48.0, 3.0, -45.0)), heading0_deg=120.0,
                      bounce_m=0.03, mounting_rpy_deg=(3.0, -25.0, -80.0),
                      lla0_deg=(-33.9, 151.2, 40.0), outages=((30.0, 15.0),))


def test_walk_outage_with_the_consumer_preset_and_the_facts_only(tmp_path):
    """A new user's run of a handheld walk: consumer IMU at 167 Hz, 4 Hz centimetre
    fixes whose velocities are 0.125 s late, a 15 s outage while walking; the config
    holds the lever arm and the velocity latency, nothing else.  Exit 0; the forward
    filter stays within 1.5 m over the outage (a filter that drifts 3-4 m there is not
    good enough even when the smoother rescues it), the smoothed solution within 0.1 m."""
    import subprocess
    import sys

    from ins.io.gnss import write_gnss
    from ins.io.imu_files import write_kfgins_text
    from ins.io.navfiles import read_nav
    from ins.nav import earth
    truth = GroundTruth(WALK_OUTAGE)
    imu = apply_errors(synthesize_imu(truth, 167.0), ImuErrorModel.preset("consumer"), seed=8)
    write_kfgins_text(tmp_path / "imu.txt", imu)
    write_gnss(tmp_path / "gnss.txt", rtk_fixes(truth, lever_b_m=(0.0, 0.0, -0.15), seed=8))
    (tmp_path / "c.toml").write_text('[files]\nimu = "imu.txt"\ngnss = "gnss.txt"\n[gnss]\n'
                                     "lever_arm_b_m = [0.0, 0.0, -0.15]\n"
                                     "velocity_time_shift_s = -0.125\n")
    ins = str(Path(sys.executable).parent / "ins")
    proc = subprocess.run([ins, "process", "--config", str(tmp_path / "c.toml"), "--preset",
                           "consumer", "-o", str(tmp_path / "out"), "--forward", "--no-plots"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    for name, bound in (("forward", 1.5), ("solution", 0.1)):
        traj = read_nav(tmp_path / "out" / f"{name}.nav")
        rel = traj.time - truth.t_start
        gap = (rel >= 30.0) & (rel < 45.0)
        s = truth.evaluate(traj.time[gap])
        dn = earth.ned_offset(s.lla, traj.lla[gap])
        assert np.hypot(dn[:, 0], dn[:, 1]).max() < bound, name


def test_noise_from_the_rest_when_none_is_given(car):
    """The white noise measured over the rest is the simulator's (consumer grade: ARW
    0.4 deg/sqrt(h), VRW 0.1 m/s/sqrt(h)); the 300-612 deg/h gyro offsets pick the
    consumer priors, a tactical IMU's the tactical ones."""
    from ins.estimation.pipeline.presets import noise_from_rest
    truth, imu, gnss = car
    ms = align_anywhere(imu, gnss)
    noise, text = noise_from_rest(imu, ms.alignment.time, ms.alignment.time + ms.rest_s,
                                  ms.gyro_bias_b)
    arw, vrw = np.max(noise.arw_deg_sqrth), np.max(noise.vrw_mps_sqrth)
    assert 0.33 < arw < 0.48 and 0.08 < vrw < 0.12
    assert np.all(noise.gyro_bias_std_dph == 3600.0) and "'consumer' preset" in text
    tac = apply_errors(synthesize_imu(truth, 100.0, truth.t_start, truth.t_start + 12.0),
                       ImuErrorModel.preset("tactical"), seed=2)
    noise, text = noise_from_rest(tac, truth.t_start, truth.t_start + 11.0,
                                  np.deg2rad(np.array([1.0, -0.8, 0.6]) / 3600))
    assert np.all(noise.gyro_bias_std_dph == 1.0) and "'tactical' preset" in text
    assert 0.09 < np.max(noise.arw_deg_sqrth) < 0.15          # the tactical grade's 0.12
