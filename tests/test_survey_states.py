"""The optional state groups against the simulator's truth: non-orthogonality injected by
the IMU error model, a lever-arm error and an IMU-GNSS time offset injected into the GNSS
log (ins.simulate.gnss.simulate_gnss); each estimate within 3 sigma of what was injected,
and the sigma small enough that the test could fail (a state that learns nothing would
pass the 3-sigma check with its prior)."""
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest

from ins.error_model import StateLayout
from ins.process import process
from ins.process_config import config_from_manifest
from test_filter import PLAN, given_config, short_flight

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
    res21 = process(cfg21, accept_poor=True)
    tilt = lambda r: np.sqrt(np.mean(r.errors_smoothed.att_n[:, :2] ** 2))  # noqa: E731
    assert tilt(res) < tilt(res21)


def _with_gnss_errors(src, dst, time_offset_s, lever_error_b_m):
    """A copy of flight folder ``src`` whose gnss.txt holds the antenna with a lever-arm
    error and a time offset (simulate_gnss, the same epochs and noise level)."""
    from ins.gnss import read_gnss, write_gnss
    from ins.simulate.gnss import simulate_gnss
    from ins.simulate.plan import load_plan
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
