"""Forward filter: consistency (NEES in its chi-square band) on simulated flights, bias
estimates, innovation test, node schedule."""
import os
from pathlib import Path

import numpy as np
import pytest
import tomllib
from scipy.stats import chi2

from ins.estimation.core.filter import run_forward, schedule_nodes
from ins.estimation.core.filter_settings import FilterSettings
from ins.estimation.core.lever_arm import LeverArm
from ins.estimation.pipeline.process import _initial
from ins.estimation.pipeline.config import ProcessConfig, config_from_manifest
from ins.estimation.core.smoother import smooth
from ins.io import imu_files
from ins.io.gnss import read_gnss
from ins.io.gnss_log import GnssLog
from ins.io.mount import read_mount
from ins.io.navfiles import read_nav
from ins.nav.accuracy import compare
from ins.nav.trajectory import Trajectory

ROOT = Path(__file__).resolve().parents[1]
FLIGHT_CACHE = Path(os.environ.get("INS_TEST_FLIGHTS", ROOT / ".cache" / "ins-test-flights"))

# --- a short simulated flight (helper shared by the processing tests) -----------------
# Self-contained plan (not the demo plan, which may change): a minute static on the
# ground, take-off, two 1.5 km strips at 60 m/s with 8 m/s wind (crab: the mount yaws),
# turbulence (the mount levels), navigation-grade IMU WITHOUT misalignment (the filter has
# no misalignment states), 1 Hz GNSS with a 30 s outage.
PLAN = """
[block]
origin_lat_deg = 30.5
origin_lon_deg = 114.3
origin_h_m = 20.0
strip_azimuth_deg = 90.0
strip_length_m = 1500.0
n_strips = 2
side_overlap_percent = 30.0
forward_overlap_percent = 60.0

[flight]
height_agl_m = 1000.0
ground_speed_mps = 60.0
bank_deg = 4.0
climb_rate_mps = 5.0
start = "ground"
stationary_s = 60.0
run_in_m = 500.0
takeoff_accel_mps2 = 2.0
gps_week = 2300
start_time_s = 100000.0

[wind]
speed_mps = 8.0
from_deg = 30.0

[turbulence]
roll_amp_deg = [0.3, 0.1]
roll_freq_hz = [0.15, 0.8]
pitch_amp_deg = [0.2, 0.05]
pitch_freq_hz = [0.1, 0.6]
yaw_amp_deg = [0.2]
yaw_freq_hz = [0.07]
heave_amp_m = [0.5, 0.1]
heave_freq_hz = [0.05, 0.4]
seed = 1

[mount]
enabled = true
level_limit_deg = 5.0
azimuth_limit_deg = 30.0
servo_lag_s = 0.1
log_rate_hz = 50.0
imu_to_platform_centre_b_m = [0.1, 0.05, -0.1]
platform_centre_to_antenna_a_m = [0.5, 0.2, -1.5]

[imu]
grade = "navigation"
rate_hz = 200.0
gyro_misalignment_arcsec = [0.0, 0.0, 0.0]
accel_misalignment_arcsec = [0.0, 0.0, 0.0]

[gnss]
rate_hz = 1.0
sigma_ned_m = [0.02, 0.02, 0.04]
velocity = false
sigma_vel_mps = 0.01
outages = [[400.0, 30.0]]

[camera]
focal_length_mm = 100.0
pixel_size_mm = 0.01
width_px = 8000
height_px = 6000
principal_point_px = [3999.5, 2999.5]
radial_k = [0.0, 0.0, 0.0]
tangential_p = [0.0, 0.0]
axes = [[1, 0, 0], [0, -1, 0], [0, 0, -1]]
lever_arm_m = [0.0, 0.0, 0.2]
boresight_deg = [0.0, 0.0, 0.0]

[terrain]
relief_m = 20.0
wavelength_m = 2000.0
seed_offset = 0

[tie_points]
per_image = 5
sigma_px = 0.5
"""


def short_flight(seed=3, plan=PLAN):
    """The ~15 min flight of ``PLAN`` (or another plan's flight), simulated once (~5 s)
    and cached on disk, keyed on the plan, the seed and the sources of ins/ and
    photogrammetry/ (``benchdata.cached_flight``): a code change simulates it again."""
    from benchdata import cached_flight

    from ins.common.errors import InputError
    from photogrammetry.simulate.folder import simulate_flight

    def simulate(path, folder, seed):
        try:
            simulate_flight(path, folder, seed=seed, force=True)
        except InputError as exc:         # the simulator's plan format moved on
            pytest.skip(f"test flight plan refused by the simulator: {exc}")
    return cached_flight(FLIGHT_CACHE, plan, seed, simulate)


def given_config(folder, varying=True):
    """Config of a flight folder started from its true initial state (lever-arm and
    consistency tests are not about the alignment)."""
    man = tomllib.loads((Path(folder) / "manifest.toml").read_text())
    cfg = config_from_manifest(str(folder))
    cfg.method = "given"
    cfg.initial = dict(man["initial"], time_s=man["flight"]["start_time_s"],
                       pos_std_ned_m=[0.1] * 3, vel_std_ned_mps=[0.05] * 3,
                       att_std_deg=[0.05, 0.05, 0.2])
    if not varying:
        cfg.mount = None
    return cfg


@pytest.fixture(scope="module")
def flight():
    return short_flight()


def nees_band(n_windows, dof, p=0.001):
    """Band of the mean NEES over ``n_windows`` independent windows (chi-square)."""
    return (chi2.ppf(p, dof * n_windows) / n_windows,
            chi2.ppf(1 - p, dof * n_windows) / n_windows)


def forward_and_errors(cfg):
    imu = imu_files.read_imu(cfg.imu)
    gnss = read_gnss(cfg.gnss)
    mount = read_mount(cfg.mount) if cfg.mount else None
    state, t0, _ = _initial(cfg, imu, gnss)
    settings = FilterSettings(noise=cfg.noise, lever=LeverArm(cfg.lever_bp, cfg.lever_ap, mount),
                              pos_std_ned_m=cfg.initial["pos_std_ned_m"],
                              vel_std_ned_mps=cfg.initial["vel_std_ned_mps"],
                              att_std_deg=cfg.initial["att_std_deg"])
    fwd = run_forward(imu, gnss, state, settings, start=t0)
    truth = read_nav(cfg.truth)
    rows = fwd.node_rows

    def errors(states):
        tr = Trajectory(fwd.time[rows], states[rows, 0:3], states[rows, 3:6], states[rows, 6:10])
        e = compare(tr, truth)
        # compare gives rotvec(C_est C_true^T) = -phi
        return np.hstack([e.pos_n, e.v_n, -e.att_n])
    return fwd, errors


def nees(e, P):
    return np.einsum("mi,mij,mj->m", e, np.linalg.inv(P), e)


def test_forward_and_smoothed_nees_within_chi_square_band(flight):
    fwd, errors = forward_and_errors(given_config(flight))
    settle = fwd.time[fwd.node_rows] > fwd.time[0] + 60.0
    duration = fwd.time[-1] - fwd.time[0] - 60.0
    lo, hi = nees_band(int(duration // 60), 9)         # errors decorrelate within ~60 s
    e_f = errors(fwd.states)
    n_f = nees(e_f, fwd.P_post[:, :9, :9])[settle]
    from ins.estimation.core.smoother import rts_errors
    _, Ps = rts_errors(fwd)
    sm = smooth(fwd)
    n_s = nees(errors(sm.states), Ps[:, :9, :9])[settle]
    assert lo < n_f.mean() < hi, (lo, n_f.mean(), hi)
    assert lo < n_s.mean() < hi, (lo, n_s.mean(), hi)
    # and no stretch of gross inconsistency: few nodes beyond the 99 % quantile
    assert np.mean(n_f > chi2.ppf(0.99, 9)) < 0.05
    assert np.mean(n_s > chi2.ppf(0.99, 9)) < 0.05
    # innovations: NIS mean of 3 dof
    assert 2.5 < fwd.nis.mean() < 3.5
    assert fwd.n_rejected == 0 and fwd.n_updates == len(fwd.nis)


def test_bias_estimates_match_the_injected_ones(flight):
    cfg = given_config(flight)
    fwd, _ = forward_and_errors(cfg)
    man = tomllib.loads((Path(flight) / "manifest.toml").read_text())
    ba_true = np.array(man["imu"]["accel_bias_mgal"]) * 1e-5
    # horizontal accel biases are observable only in turns; the vertical one always
    est = fwd.sensors[-1, 3:6]
    sig = np.sqrt(np.diag(fwd.P_post[-1])[12:15])
    inst = np.array(man["imu"]["accel_bias_instability_mgal"], float) * 1e-5
    assert np.all(np.abs(est - ba_true) < 4 * np.hypot(sig, inst)), (est, ba_true, sig)
    assert abs(est[2] - ba_true[2]) < 0.5 * abs(ba_true[2]) + 3 * inst[2]


def test_outlier_rejected_and_counted(flight):
    cfg = given_config(flight, varying=True)
    gnss = read_gnss(cfg.gnss)
    lla = gnss.lla.copy()
    k = len(gnss) // 2
    lla[k, 2] += 5.0                                     # a 5 m height blunder
    bad = GnssLog(gnss.time, lla, gnss.sigma_ned_m, line=gnss.line)
    imu = imu_files.read_imu(cfg.imu)
    state, t0, _ = _initial(cfg, imu, gnss)
    settings = FilterSettings(noise=cfg.noise, lever=LeverArm(cfg.lever_bp, cfg.lever_ap,
                                                              read_mount(cfg.mount)),
                              pos_std_ned_m=[0.1] * 3, vel_std_ned_mps=[0.05] * 3,
                              att_std_deg=[0.05, 0.05, 0.2])
    fwd = run_forward(imu, bad, state, settings, start=t0, end=gnss.time[k] + 5)
    assert fwd.n_rejected == 1
    assert fwd.nis.max() > 1e3


def test_gnss_between_imu_epochs_is_used_at_its_own_time(flight):
    """Shift every GNSS record by +2.5 ms (half an IMU interval) and move the antenna
    along its velocity accordingly: the solution must not change beyond noise."""
    cfg = given_config(flight, varying=False)
    cfg.end_s = tomllib.loads((Path(flight) / "manifest.toml").read_text())["flight"][
        "start_time_s"] + 200.0
    gnss = read_gnss(cfg.gnss)
    imu = imu_files.read_imu(cfg.imu)
    truth = read_nav(cfg.truth)
    state, t0, _ = _initial(cfg, imu, gnss)
    settings = FilterSettings(noise=cfg.noise, lever=LeverArm(cfg.lever_bp + cfg.lever_ap),
                              pos_std_ned_m=[0.1] * 3, vel_std_ned_mps=[0.05] * 3,
                              att_std_deg=[0.05, 0.05, 0.2])
    from ins.nav import earth
    k = np.searchsorted(truth.time, gnss.time)
    k = np.clip(k, 0, len(truth.time) - 1)
    shift = 0.0025
    rate = earth.lla_rate(truth.lla[k, 0], truth.lla[k, 2], truth.v_n[k])
    moved = GnssLog(gnss.time + shift, gnss.lla + rate * shift, gnss.sigma_ned_m)
    a = run_forward(imu, gnss, state, settings, start=t0, end=cfg.end_s)
    b = run_forward(imu, moved, state, settings, start=t0, end=cfg.end_s)
    mid = slice(4000, len(a.time) - 2000)                # 20 s .. end - 10 s

    def rms(x, y):
        return np.sqrt(np.mean(np.sum(earth.ned_offset(x.states[mid, :3],
                                                       y.states[mid, :3]) ** 2, axis=1)))
    assert rms(a, b) < 1e-3, rms(a, b)
    # a record stamped 2.5 ms late but used as if on the IMU epoch is ~0.15 m off
    c = run_forward(imu, GnssLog(gnss.time + shift, gnss.lla, gnss.sigma_ned_m), state, settings,
                    start=t0, end=cfg.end_s)
    assert rms(a, c) > 0.05


def test_schedule_nodes_fills_outages():
    time = np.arange(0, 100.0001, 0.005)
    g = np.concatenate([np.arange(1, 30), np.arange(70, 100)]) + 0.0025
    rows = schedule_nodes(time, g, 1.0)
    assert rows[0] == 0 and rows[-1] == len(time) - 1
    assert np.max(np.diff(time[rows])) <= 1.0 + 1e-9
    # every GNSS record has its node: the last IMU epoch at or before it
    assert set(np.searchsorted(time, g, side="right") - 1) <= set(rows)


def test_filter_settings_refuse_zero_sigma():
    from ins.common.errors import InputError
    with pytest.raises(InputError, match="> 0"):
        FilterSettings(pos_std_ned_m=[0.0, 1, 1]).initial_covariance()


def test_process_config_dataclass_defaults():
    cfg = ProcessConfig(imu="a", gnss="b")
    assert cfg.method == "auto" and cfg.node_interval_s == 1.0


def test_missing_mount_data_counted_with_a_warning(flight, tmp_path):
    from ins.common.errors import InputWarning
    from ins.io.mount import MountLog
    cfg = given_config(flight)
    t0 = tomllib.loads((Path(flight) / "manifest.toml").read_text())["flight"]["start_time_s"]
    mount = read_mount(cfg.mount)
    keep = mount.time < t0 + 100.0
    short = MountLog(mount.time[keep], mount.rpy[keep])
    imu = imu_files.read_imu(cfg.imu)
    gnss = read_gnss(cfg.gnss)
    state, _, _ = _initial(cfg, imu, gnss)
    settings = FilterSettings(noise=cfg.noise, lever=LeverArm(cfg.lever_bp, cfg.lever_ap, short),
                              pos_std_ned_m=[0.1] * 3, vel_std_ned_mps=[0.05] * 3,
                              att_std_deg=[0.05, 0.05, 0.2])
    with pytest.warns(InputWarning, match=r"\d+ GNSS record\(s\) without mount data"):
        fwd = run_forward(imu, gnss, state, settings, start=t0, end=t0 + 150.0)
    n_after = int(np.count_nonzero((gnss.time > short.time[-1]) & (gnss.time <= t0 + 150.0)))
    assert fwd.n_mount_fallback == n_after > 0


def test_velocity_updates_with_the_varying_arm(flight):
    """GNSS velocities of the antenna (from the truth: central difference of the antenna
    positions, mount included) are accepted by the innovation test and improve the
    velocity over position-only updates."""
    from ins.estimation.core.lever_arm import antenna_lla
    from ins.nav import earth
    from ins.nav.rotation import quat_to_dcm
    cfg = given_config(flight)
    t0 = tomllib.loads((Path(flight) / "manifest.toml").read_text())["flight"]["start_time_s"]
    end = t0 + 300.0
    gnss = read_gnss(cfg.gnss)
    truth = read_nav(cfg.truth)
    mount = read_mount(cfg.mount)
    lever = LeverArm(cfg.lever_bp, cfg.lever_ap, mount)
    sel = (gnss.time > t0 + 1) & (gnss.time < end)
    g = gnss.select(sel)
    k = np.searchsorted(truth.time, g.time - 1e-7)

    def ant(i):
        l_b = lever.at(truth.time[i])[0]
        return np.array([antenna_lla(truth.lla[j], quat_to_dcm(truth.q_nb[j]), l_b[n])
                         for n, j in enumerate(i)])
    dt = truth.time[k + 1] - truth.time[k - 1]
    vel = earth.ned_offset(ant(k - 1), ant(k + 1)) / dt[:, None]
    with_vel = GnssLog(g.time, g.lla, g.sigma_ned_m, vel, np.full((len(g), 3), 0.005))
    imu = imu_files.read_imu(cfg.imu)
    state, _, _ = _initial(cfg, imu, gnss)
    settings = FilterSettings(noise=cfg.noise, lever=lever, pos_std_ned_m=[0.1] * 3,
                              vel_std_ned_mps=[0.05] * 3, att_std_deg=[0.05, 0.05, 0.2])
    a = run_forward(imu, with_vel, state, settings, start=t0, end=end)
    settings.use_velocity = False
    b = run_forward(imu, with_vel, state, settings, start=t0, end=end)
    assert a.n_rejected == 0 and a.n_updates == 2 * len(g)
    assert b.n_updates == len(g)

    def vel_rms(f):
        tr = Trajectory(f.time, f.states[:, :3], f.states[:, 3:6], f.states[:, 6:10])
        e = compare(tr, truth)
        late = e.time > t0 + 60
        return np.sqrt(np.mean(e.v_n[late] ** 2))
    assert vel_rms(a) < 0.8 * vel_rms(b)


def test_negative_variance_in_the_filter_is_a_failure_naming_time_and_state():
    """A negative variance in a node's covariance raises (it used to print as sigma 0),
    naming the node time and the state; rounding-level negatives give 0."""
    from ins.common.errors import QualityError
    from ins.estimation.core.filter import std_of
    from ins.estimation.core.filter_stores import NodeStore
    store = NodeStore()
    P = np.eye(21) * 1e-2
    store.append(P, 0.5 * P, np.eye(21), 10.0)
    bad = 0.5 * P
    bad[4, 4] = -1e-6
    with pytest.raises(QualityError, match=r"at t = 12\.000 s: the forward filter's "
                                           r"posterior covariance has variance -1\.000e-06 "
                                           r"for state vel_E"):
        store.append(P, bad, np.eye(21), 12.0)
    bad = P.copy()
    bad[15, 15] = -1e-6                               # a negative prior variance
    with pytest.raises(QualityError, match=r"t = 13\.000 s: the forward filter's prior "
                                           r"covariance .* state gyro_scale_x"):
        store.append(bad, 0.5 * P, np.eye(21), 13.0)
    tiny = 0.5 * P
    tiny[4, 4] = -1e-14                               # rounding (1e-12 of the prior)
    store.append(P, tiny, np.eye(21), 14.0)
    assert store.post_std[-1][4] == 0.0 and store.count == 2
    stack = np.array([P, bad])
    with pytest.raises(QualityError, match=r"t = 2\.000 s: .* gyro_scale_x"):
        std_of(stack, time=[1.0, 2.0])


def test_manifest_gives_constant_sensor_states_with_the_instability(tmp_path):
    """A flight manifest's bias instability makes the sensor states random constants plus
    the instability (ins.estimation.core.error_model notes): prior = hypot(constant, instability) of the
    hand-written values, decay none, bias driving noise 2 sigma_inst^2 / T, scale none;
    a config without the keys keeps the KF-GINS Gauss-Markov model."""
    (tmp_path / "manifest.toml").write_text(
        '[files]\nimu = "imu.txt"\ngnss = "gnss.txt"\n'
        '[imu]\ngyro_bias_dph = [3.0, -4.0, 0.0]\naccel_bias_mgal = [300.0, 0.0, 0.0]\n'
        'gyro_bias_instability_dph = [4.0, 3.0, 0.5]\n'
        'accel_bias_instability_mgal = [400.0, 100.0, 0.0]\ncorr_time_h = 2.0\n'
        'gyro_scale_ppm = [150.0, -150.0, 150.0]\n')
    noise = config_from_manifest(str(tmp_path)).noise
    dph, mgal = np.pi / 180 / 3600, 1e-5
    np.testing.assert_allclose(noise.gyro_bias_std_dph, [5.0, 5.0, 0.5])
    np.testing.assert_allclose(noise.accel_bias_std_mgal, [500.0, 100.0, 1.0])
    assert noise.constant_sensors and noise.decay_time_s == np.inf
    q = noise.q_continuous()
    np.testing.assert_allclose(q[6:9], 2 * (np.array([4.0, 3.0, 0.5]) * dph) ** 2 / 7200)
    np.testing.assert_allclose(q[9:12], 2 * (np.array([400.0, 100.0, 0.0]) * mgal) ** 2
                               / 7200)
    np.testing.assert_array_equal(q[12:18], 0.0)
    assert not ProcessConfig(imu="imu.txt", gnss="gnss.txt").noise.constant_sensors
