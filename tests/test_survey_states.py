"""The optional state groups against the simulator's truth: non-orthogonality injected by
the IMU error model, a lever-arm error and an IMU-GNSS time offset injected into the GNSS
log (ins.simulate.gnss.simulate_gnss); each estimate within 3 sigma of what was injected,
and the sigma small enough that the test could fail (a state that learns nothing would
pass the 3-sigma check with its prior)."""
import functools
import shutil
from pathlib import Path

import numpy as np
import pytest
import tomllib
from test_filter import PLAN, given_config, short_flight

from ins.estimation.core.error_model import StateLayout
from ins.estimation.pipeline.process import process
from ins.estimation.pipeline.config import config_from_manifest

ARCSEC = np.pi / 180 / 3600
GYRO_MIS = [150.0, -120.0, 100.0]           # arcsec
ACCEL_MIS = [200.0, -200.0, 150.0]


def _misaligned_plan():
    plan = PLAN.replace("gyro_misalignment_arcsec = [0.0, 0.0, 0.0]",
                        f"gyro_misalignment_arcsec = {GYRO_MIS}")
    plan = plan.replace("accel_misalignment_arcsec = [0.0, 0.0, 0.0]",
                        f"accel_misalignment_arcsec = {ACCEL_MIS}")
    assert plan != PLAN
    return plan


@pytest.mark.slow
def test_misalignment_states_against_injected():
    folder = short_flight(seed=4, plan=_misaligned_plan())
    man = tomllib.loads((Path(folder) / "manifest.toml").read_text())
    assert man["imu"]["gyro_misalignment_arcsec"] == GYRO_MIS
    cfg = given_config(folder)
    cfg.layout = StateLayout(("gyro_misalignment", "accel_misalignment"))
    cfg.priors = {"gyro_misalignment_std_arcsec": 300.0, "accel_misalignment_std_arcsec": 300.0}
    res = process(cfg)
    L = res.fwd.layout
    for group, truth in (("gyro_misalignment", GYRO_MIS), ("accel_misalignment", ACCEL_MIS)):
        sl = getattr(L, group)
        est = res.smoothed_sensors[-1, sl.start - 9:sl.stop - 9] / ARCSEC
        std = res.smoothed_std[-1, sl] / ARCSEC
        assert np.all(np.abs(est - truth) < 3 * std), (group, est, std)
        assert np.min(std) < 150.0, (group, std)          # learnt something on some axis
    # the gyro non-orthogonality is observable in the turns: every axis below the prior
    sl = L.gyro_misalignment
    assert np.all(res.smoothed_std[-1, sl] / ARCSEC < 0.5 * 300.0)
    # and the attitude is better than with the 21 states
    cfg21 = given_config(folder)
    cfg21.layout = StateLayout(())
    from ins.common.errors import QualityWarning
    with pytest.warns(QualityWarning, match="rejected by the innovation test"):
        res21 = process(cfg21, accept_poor=True)        # it loses the fixes
    tilt = lambda r: np.sqrt(np.mean(r.errors_smoothed.att_n[:, :2] ** 2))  # noqa: E731
    assert tilt(res) < tilt(res21)


def _with_gnss_errors(src, dst, time_offset_s, lever_error_b_m):
    """A copy of flight folder ``src`` whose gnss.txt holds the antenna with a lever-arm
    error and a time offset (simulate_gnss, the same epochs and noise level)."""
    from ins.io.gnss import read_gnss, write_gnss
    from ins.simulate.gnss import simulate_gnss
    from ins.simulate.plan_read import load_plan
    from ins.simulate.truth import build_truth
    shutil.copytree(src, dst)
    man = tomllib.loads((Path(src) / "manifest.toml").read_text())
    plan = load_plan(Path(src) / man["flight"]["plan"])
    truth = build_truth(plan)
    old = read_gnss(Path(src) / "gnss.txt")
    arm = man["lever_arm"]
    log = simulate_gnss(truth, old.time, arm["imu_to_platform_centre_b_m"],
                        arm["platform_centre_to_antenna_a_m"], plan.gnss.sigma_ned_m,
                        np.random.default_rng(11), time_offset_s=time_offset_s,
                        lever_error_b_m=lever_error_b_m)
    write_gnss(Path(dst) / "gnss.txt", log)
    return dst


@pytest.mark.slow
def test_lever_arm_and_time_offset_states_against_injected(tmp_path):
    tau, dl = 0.012, np.array([0.10, -0.08, 0.05])
    folder = _with_gnss_errors(short_flight(), tmp_path / "flight", tau, dl)
    cfg = given_config(folder)
    cfg.layout = StateLayout(("lever_arm", "time_offset"))
    cfg.priors = {"lever_arm_std_m": 0.3, "time_offset_std_ms": 30.0}
    res = process(cfg)
    L = res.fwd.layout
    lever = res.smoothed_sensors[-1, L.lever_arm.start - 9:L.lever_arm.stop - 9]
    lever_sd = res.smoothed_std[-1, L.lever_arm]
    off = res.smoothed_sensors[-1, L.time_offset.start - 9]
    off_sd = res.smoothed_std[-1, L.time_offset.start]
    assert np.all(np.abs(lever - dl) < 3 * lever_sd), (lever, lever_sd)
    assert abs(off - tau) < 3 * off_sd, (off, off_sd)
    # far below the priors (the horizontal arm through the turns; the vertical one is
    # hardly observable with a levelled platform and only has to be consistent)
    assert np.all(lever_sd[:2] < 0.05) and off_sd < 0.001
    # the trust check accounts for the estimated offset and arm: no quality error above,
    # and the solution's antenna within a few cm of the fixes
    assert res.quality["error"] is None


def test_manifest_gives_the_misalignment_priors(tmp_path):
    folder = short_flight()
    cfg = config_from_manifest(str(folder))
    assert cfg.layout.groups == ("gyro_misalignment", "accel_misalignment")
    np.testing.assert_array_equal(cfg.priors["gyro_misalignment_std_arcsec"], [1.0, 1.0, 1.0])
    over = tmp_path / "over.toml"
    over.write_text('[states]\nlayout = "kfgins"\nlever_arm = true\nlever_arm_std_m = 0.2\n')
    cfg = config_from_manifest(str(folder), over)
    assert cfg.layout.groups == ("lever_arm",)
    np.testing.assert_array_equal(cfg.priors["lever_arm_std_m"], [0.2, 0.2, 0.2])


def _static_part(flight, **settings):
    """Forward filter over the first ``STATIC_S`` s of the short flight (on the ground,
    at rest), from the true state with the given measurement settings; returns the
    forward result and its velocity errors at the nodes (m/s, NED)."""
    from dataclasses import replace

    from ins.estimation.core.filter import run_forward
    from ins.estimation.core.filter_settings import FilterSettings
    from ins.estimation.core.lever_arm import LeverArm
    from ins.io.navfiles import read_nav
    from ins.nav.accuracy import compare
    from ins.nav.mechanization import NavState
    from ins.nav.trajectory import Trajectory
    cfg = given_config(flight, varying=False)
    man = tomllib.loads((Path(flight) / "manifest.toml").read_text())
    ini, t0 = man["initial"], man["flight"]["start_time_s"]
    imu, gnss = _static_logs(cfg.imu, cfg.gnss, t0)
    # GNSS only in the first seconds: the velocity after that comes from the IMU and
    # whatever the measurements under test give
    keep = gnss.time < t0 + 5.0
    gnss = replace(gnss, time=gnss.time[keep], lla=gnss.lla[keep],
                   sigma_ned_m=gnss.sigma_ned_m[keep])
    state = NavState.from_degrees(ini["lat_deg"], ini["lon_deg"], ini["h_m"],
                                  ini["vel_ned_mps"], ini["rpy_deg"])
    fs = FilterSettings(noise=cfg.noise, lever=LeverArm(cfg.lever_bp + cfg.lever_ap),
                        **settings)
    fwd = run_forward(imu, gnss, state, fs, start=t0, end=t0 + STATIC_S)
    s = fwd.node_states
    e = compare(Trajectory(fwd.node_time, s[:, 0:3], s[:, 3:6], s[:, 6:10]),
                read_nav(cfg.truth))
    return fwd, e


STATIC_S = 55.0


@functools.lru_cache(maxsize=2)
def _static_logs(imu_path, gnss_path, t0):
    """The IMU rows of the static minute and the GNSS log (read once)."""
    from ins.io.gnss import read_gnss
    from ins.io.imu_files import read_imu
    from ins.nav.imu import ImuLog
    imu = read_imu(imu_path)
    k = np.searchsorted(imu.time, t0 + STATIC_S + 2.0)
    return (ImuLog.adopt(imu.time[:k].copy(), imu.dtheta_b[:k].copy(), imu.dvel_b[:k].copy()),
            read_gnss(gnss_path))


def test_zero_velocity_updates_on_the_ground():
    flight = short_flight()
    free, e_free = _static_part(flight)
    fwd, e = _static_part(flight, zupt=True)
    zupt = [r for r in fwd.records if r.name == "zero_velocity"]
    assert len(zupt) >= STATIC_S - 3                       # detected at (nearly) every node
    assert all(r.accepted for r in zupt)
    late = e.time > e.time[0] + 20
    # without GNSS the free INS drifts (navigation grade: mm/s); the updates hold it
    assert np.max(np.abs(e.v_n[late])) < 0.3 * np.max(np.abs(e_free.v_n[late]))
    assert np.max(np.abs(e.v_n[late])) < 0.01
    z = np.array([r.standardized for r in zupt])
    assert np.sqrt(np.mean(z ** 2)) < 3.0       # the default sigma (5 mm/s) is generous
    # windows instead of detection: only the nodes inside
    t0 = fwd.node_time[0]
    win, _ = _static_part(flight, zupt=True, zupt_windows_s=((t0 + 10, t0 + 20),),
                          zupt_accel_std_mps2=1e-12)
    times = [r.time for r in win.records if r.name == "zero_velocity"]
    assert len(times) == 11 and min(times) >= t0 + 10 and max(times) <= t0 + 20


def test_nonholonomic_constraint_on_the_ground():
    flight = short_flight()
    _, e_free = _static_part(flight)
    fwd, e = _static_part(flight, nhc=True, nhc_sigma_mps=0.005)
    nhc = [r for r in fwd.records if r.name == "nonholonomic"]
    assert len(nhc) == len(fwd.node_time) - 1 and nhc[0].axes == ("y", "z")
    late = e.time > e.time[0] + 20
    # the constraint holds the cross-track (east: the aircraft points north or south?
    # any heading: the body y and z) velocity; the along-track one drifts freely
    from ins.nav.rotation import quat_to_dcm
    C = quat_to_dcm(fwd.node_states[:, 6:10])
    vb = np.einsum("nji,nj->ni", C, e.v_n)[late]
    vb_free = np.einsum("nji,nj->ni", C, e_free.v_n)[late]
    assert np.max(np.abs(vb[:, 1:])) < 0.3 * np.max(np.abs(vb_free[:, 1:]))


def test_default_misalignment_priors_follow_the_grade():
    """Not given, the non-orthogonality priors are the scale-factor sigmas (1 arcsec per
    ppm, per sensor and axis, at least 1 arcsec); given ones win; the presets' grades."""
    from ins.estimation.core.error_model import LAYOUTS, ImuNoise
    from ins.estimation.core.filter_settings import FilterSettings
    from ins.estimation.pipeline.presets import apply_preset
    from ins.estimation.pipeline.config import ProcessConfig, filter_options
    survey = StateLayout(LAYOUTS["survey"])
    noise = ImuNoise(gyro_scale_std_ppm=[150.0, 0.2, 5.0], accel_scale_std_ppm=300.0)
    s = FilterSettings(noise=noise, layout=survey)
    np.testing.assert_allclose(s.prior_std() / ARCSEC, [150, 1, 5, 300, 300, 300])
    s = FilterSettings(noise=noise, layout=survey, accel_misalignment_std_arcsec=20.0)
    np.testing.assert_allclose(s.prior_std() / ARCSEC, [150, 1, 5, 20, 20, 20])
    # the KF-GINS-like config (1 ppm): 1 arcsec, the 21 states' figures on the benchmark
    s = FilterSettings(noise=ImuNoise(), layout=survey)
    np.testing.assert_allclose(s.prior_std() / ARCSEC, np.ones(6))
    expected = {"tactical": 100.0, "mems": 360.0, "land": 360.0, "consumer": 2000.0}
    for name, arcsec in expected.items():
        cfg = apply_preset(ProcessConfig(imu="i", gnss="g"), name)
        s = FilterSettings(noise=cfg.noise, **filter_options(cfg))
        assert s.layout == survey
        np.testing.assert_allclose(s.prior_std() / ARCSEC, np.full(6, arcsec), err_msg=name)
