"""Allan deviation: analytic white noise; recovery of the injected noise densities from
a static simulation; the `ins allan` command."""
import numpy as np
import pytest
from test_sensor_errors import static_log

from ins.cli.main import main
from ins.estimation.tools.allan import allan_deviation, noise_densities
from ins.io.imu_files import write_kfgins_text
from ins.simulate.sensor_errors import DEG_SQRTH, MPS_SQRTH, ImuErrorModel, apply_errors


def test_white_noise_is_n_over_sqrt_tau():
    rng = np.random.default_rng(0)
    dt, N = 0.01, 2e-3
    rate = N / np.sqrt(dt) * rng.standard_normal(400_000)
    tau, adev = allan_deviation(rate, dt, taus=[0.01, 0.1, 1.0, 10.0], increments=False)
    assert np.allclose(adev, N / np.sqrt(tau), rtol=0.05)


def test_recovers_injected_noise_from_static_simulation():
    log = static_log(0.6, 50.0, 100.0, 1800.0)
    model = ImuErrorModel.from_units(arw_deg_sqrth=[0.15, 0.3, 0.5],
                                     vrw_mps_sqrth=[0.03, 0.06, 0.1], gyro_bias_dph=2.0,
                                     gyro_bias_instability_dph=0.5, corr_time_h=0.2,
                                     accel_bias_mgal=300.0)
    y = apply_errors(log, model, seed=11)
    tau, ag = allan_deviation(y.dtheta_b, log.nominal_dt)
    _, aa = allan_deviation(y.dvel_b, log.nominal_dt)
    arw, _ = noise_densities(tau, ag)
    vrw, _ = noise_densities(tau, aa)
    assert np.allclose(arw / DEG_SQRTH, [0.15, 0.3, 0.5], rtol=0.10)
    assert np.allclose(vrw / MPS_SQRTH, [0.03, 0.06, 0.1], rtol=0.10)


def test_cli_prints_table_and_plot(tmp_path, capsys):
    log = static_log(0.6, 50.0, 100.0, 600.0)
    y = apply_errors(log, ImuErrorModel.from_units(arw_deg_sqrth=0.2, vrw_mps_sqrth=0.05), 1)
    path = tmp_path / "imu.txt"
    write_kfgins_text(path, y)
    png = tmp_path / "allan.png"
    assert main(["allan", str(path), "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    rows = [line.split() for line in out.splitlines() if line[:2] in ("g ", "a ")]
    assert len(rows) == 6                     # N: the 6th field (after Q and its interval)
    assert np.allclose([float(r[5]) for r in rows[:3]], 0.2, rtol=0.15)
    assert np.allclose([float(r[5]) for r in rows[3:]], 0.05, rtol=0.15)
    assert png.stat().st_size > 1000


def test_cli_bad_file(tmp_path, capsys):
    path = tmp_path / "imu.txt"
    path.write_text("1 2 3\n")
    assert main(["allan", str(path)]) == 2
    assert str(path) in capsys.readouterr().err


# ---------------------------------------------------------------------------------------
# a moving log is refused (issue 12): the static check and --start/--end/--allow-motion

from ins.estimation.alignment.static_check import (  # noqa: E402
    GRAVITY_MARGIN,
    GRAVITY_RANGE,
    MIN_FORCE_DEPARTURE,
    MIN_RATE_DEPARTURE,
    static_check,
)
from ins.nav import earth  # noqa: E402
from ins.nav.imu import ImuLog  # noqa: E402
from ins.nav.rotation import euler_to_dcm  # noqa: E402
from ins.simulate.sensor_errors import PRESETS  # noqa: E402


def _tilted_static(grade, duration_s, rate_hz=100.0, seed=5, rpy_deg=(3.0, -4.0, 130.0)):
    """A static log of ``grade`` with the IMU tilted and turned (gravity and Earth rate on
    every axis), with the grade's sensor errors."""
    lat, h = 0.6, 50.0
    log = static_log(lat, h, rate_hz, duration_s)
    C_bn = euler_to_dcm(np.deg2rad(rpy_deg)).T
    log = ImuLog(log.time + 1000.0, log.dtheta_b @ C_bn.T, log.dvel_b @ C_bn.T)
    return apply_errors(log, ImuErrorModel.preset(grade), seed), lat, h


@pytest.mark.parametrize("grade", sorted(PRESETS))
def test_static_logs_of_every_grade_pass(grade):
    """No false alarm on an hour at rest of each grade; the mean force is normal gravity
    (independent formula of conventions.md) and the mean rate the Earth rate plus the
    preset's gyro bias."""
    log, lat, h = _tilted_static(grade, 3600.0)
    check = static_check(log.time, log.dtheta_b, log.dvel_b)
    assert check.static, check.reasons
    assert check.spans == [] and check.moving_s == 0.0
    s2 = np.sin(lat) ** 2
    g = 9.7803267715 * (1 + 0.0052790414 * s2 + 0.0000232718 * s2 ** 2) \
        + (-0.0000030876910891 + 0.0000000043977311 * s2) * h + 0.0000000000007211 * h ** 2
    bias_a = np.linalg.norm(PRESETS[grade]["accel_bias_mgal"]) * 1e-5
    assert abs(check.mean_force - g) <= bias_a * 1.05 + 1e-3
    bias_g = np.deg2rad(np.linalg.norm(PRESETS[grade]["gyro_bias_dph"]) / 3600.0)
    assert abs(check.mean_rate - earth.OMEGA_IE) <= bias_g * 1.05 + np.deg2rad(0.5 / 3600)
    assert GRAVITY_RANGE[0] - GRAVITY_MARGIN < check.mean_force < GRAVITY_RANGE[1] + GRAVITY_MARGIN


def _with_motion(log, turn=(100.0, 103.0), bump=(200.0, 201.5)):
    """``log`` with a turn of 5 deg/s about the body z axis in ``turn`` (s from the
    start) and a forward acceleration of 0.5 m/s^2 in ``bump``."""
    t = log.time - log.time[0]
    dth, dv = log.dtheta_b.copy(), log.dvel_b.copy()
    dt = log.nominal_dt
    dth[(t > turn[0]) & (t <= turn[1]), 2] += np.deg2rad(5.0) * dt
    dv[(t > bump[0]) & (t <= bump[1]), 0] += 0.5 * dt
    return ImuLog(log.time, dth, dv)


def test_moving_spans_are_found_where_the_motion_is():
    log, _, _ = _tilted_static("tactical", 300.0)
    moving = _with_motion(log)
    check = static_check(moving.time, moving.dtheta_b, moving.dvel_b)
    assert not check.static
    t0 = log.time[0]
    assert len(check.spans) == 2, check.spans
    for (a, b), (u, v) in zip(check.spans, [(100.0, 103.0), (200.0, 201.5)]):
        assert u - 1.0 - 1e-6 <= a - t0 <= u + 1e-6      # within one window of the truth
        assert v - 1e-6 <= b - t0 <= v + 1.0 + 1e-6
    assert "moves in" in check.reasons[-1]
    # the departures are far above the thresholds, which are the floors or above
    assert check.rate_threshold >= MIN_RATE_DEPARTURE
    assert check.force_threshold >= MIN_FORCE_DEPARTURE
    # a steady turn of 0.2 deg/s over the whole log about the body z axis, 5 deg from
    # the vertical: gravity's direction in the body turns on a cone of 5 deg, by
    # 2 sin(5 deg) sin(60 deg / 2) ~ 5 deg between the first and the last minute
    t = log.time - log.time[0]
    w = np.deg2rad(0.2)
    C = np.stack([np.cos(w * t), np.sin(w * t)], axis=1)       # Rz(w t)^T on x, y
    dv = log.dvel_b.copy()
    dv[:, 0], dv[:, 1] = C[:, 0] * log.dvel_b[:, 0] + C[:, 1] * log.dvel_b[:, 1], \
        -C[:, 1] * log.dvel_b[:, 0] + C[:, 0] * log.dvel_b[:, 1]
    steady = ImuLog(log.time, log.dtheta_b + np.array([0, 0, w]) * log.nominal_dt, dv)
    check = static_check(steady.time, steady.dtheta_b, steady.dvel_b)
    assert not check.static and "gravity's direction" in check.reasons[0], check.reasons
    assert 3.0 < np.rad2deg(check.tilt) < 5.5
    # the same steady rate on a level IMU (a turntable's steady spin about the vertical,
    # or a gyro bias): nothing the Allan variance can see, accepted
    level, _, _ = _tilted_static("tactical", 300.0, rpy_deg=(0.0, 0.0, 130.0))
    spin = ImuLog(level.time, level.dtheta_b + np.array([0, 0, w]) * level.nominal_dt,
                  level.dvel_b)
    check = static_check(spin.time, spin.dtheta_b, spin.dvel_b)
    assert check.static, check.reasons


def test_cli_refuses_a_moving_log_and_cuts_or_allows(tmp_path, capsys):
    log, _, _ = _tilted_static("tactical", 600.0, seed=8)
    path = tmp_path / "imu.txt"
    write_kfgins_text(path, _with_motion(log, turn=(100.0, 103.0), bump=(400.0, 401.0)))
    png = tmp_path / "allan.png"
    assert main(["allan", str(path), "--plot", str(png)]) == 2
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ins allan: error: ")
    assert f"{path} is not a static log" in err and "--start/--end" in err
    # windows of 1 s from the first increment's start (999.99 s): the turn (1100 ..
    # 1103 s) and the bump (1400 .. 1401 s) each within one window
    assert "moving: 1099.99 .. 1103.99 s, 1399.99 .. 1400.99 s" in err, err
    assert out == "" and not png.exists()
    # the static part between the two motions: accepted, the noise recovered
    code = main(["allan", str(path), "--start", "1110", "--end=1395", "--plot", str(png)])
    out, err = capsys.readouterr()
    assert code == 0 and err == "", err
    rows = [line.split() for line in out.splitlines() if line[:2] == "g "]
    assert np.allclose([float(r[5]) for r in rows], PRESETS["tactical"]["arw_deg_sqrth"],
                       rtol=0.2)
    assert png.stat().st_size > 1000
    # --allow-motion: computed, with one warning line; the turn and the bump are not
    # noise of the model's kinds: exit 3 unless --accept-poor
    assert main(["allan", str(path), "--allow-motion"]) == 3
    out, err = capsys.readouterr()
    assert "does not describe" in err
    assert main(["allan", str(path), "--allow-motion", "--accept-poor"]) == 0
    out, err = capsys.readouterr()
    warns = [x for x in err.splitlines() if x.strip()]
    assert len(warns) == 1 and warns[0].startswith("warning: ") and "not a static" in warns[0]


@pytest.mark.parametrize("argv, words", [
    (["--start", "2000"], "no epoch"),
    (["--start", "1200", "--end", "1100"], "not before --end"),
    (["--start", "1000", "--end", "1000.5"], "too few"),
])
def test_cli_bad_start_end(tmp_path, capsys, argv, words):
    log, _, _ = _tilted_static("navigation", 30.0)
    path = tmp_path / "imu.txt"
    write_kfgins_text(path, log)
    assert main(["allan", str(path), *argv]) == 2
    assert words in capsys.readouterr().err


def test_simulated_flight_is_refused(tmp_path, capsys):
    """The issue's case: a flight log gave an 'ARW' without a word.  Refused now, naming
    the moving span; --allow-motion computes with a warning."""
    from pathlib import Path

    from ins.simulate.folder import simulate_flight
    plan = Path(__file__).parent / "data" / "flights" / "short.toml"
    folder = simulate_flight(plan, tmp_path / "flight", seed=0)
    imu = str(folder / "imu.txt")
    assert main(["allan", imu]) == 2
    err = capsys.readouterr().err
    assert "is not a static log" in err and "moves in" in err and "gravity's direction" in err
    assert main(["allan", imu, "--allow-motion", "--accept-poor"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("warning: ") and "--allow-motion" in err
