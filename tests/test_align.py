"""``ins align``: static alignment at rest without GNSS (ins.estimation.alignment.fine).

Truths: exact increments of an IMU at rest (f_b = -C_bn g_n, w_b = C_bn w_ie_n) give
the attitude exactly; a simulated tactical IMU (biases drawn per seed from the stated
sigmas, the simulator's ARW, instability, scale, non-orthogonality, quantization) gives
heading errors whose scatter matches the stated sigma; the stated sigma matches the
closed-form budget written with literal constants."""
import warnings

import numpy as np
import pytest
import tomllib
from scipy.spatial.transform import Rotation

from ins.cli import main as cli
from ins.common.errors import InputError
from ins.estimation.alignment.fine import align_at_rest
from ins.estimation.core.error_model import DEG_SQRTH, DPH, MGAL
from ins.io.imu_files import write_kfgins_binary
from ins.nav import earth
from ins.nav.imu import ImuLog
from ins.simulate.sensor_errors import ImuErrorModel, apply_errors

# tactical preset of the simulator: ARW 0.12 deg/sqrt(h), instability 0.5 deg/h (1 h),
# accelerometer instability 100 mGal, non-orthogonality 100 arcsec (g * 100 arcsec =
# 475 mGal of apparent horizontal bias); turn-on biases drawn per seed
GYRO_BIAS_DPH, ACCEL_BIAS_MGAL = 1.0, 1000.0
GYRO_PRIOR_DPH = float(np.hypot(1.0, 0.5))
ACCEL_PRIOR_MGAL = float(np.sqrt(1000.0 ** 2 + 100.0 ** 2 + 475.0 ** 2))


def static_log(rpy_deg, lat, h=50.0, duration=300.0, rate=100.0, t0=0.0):
    """Exact increments of an IMU at rest at ``rpy_deg`` (C_nb = Rz Ry Rx) and ``lat``."""
    n = int(round(duration * rate)) + 1
    dt = 1.0 / rate
    C_nb = Rotation.from_euler("ZYX", np.asarray(rpy_deg, float)[::-1], degrees=True).as_matrix()
    f_b = C_nb.T @ (-earth.gravity_n(lat, h))
    w_b = C_nb.T @ earth.earth_rate_n(lat)
    return ImuLog(t0 + np.arange(n) * dt, np.tile(w_b * dt, (n, 1)),
                  np.tile(f_b * dt, (n, 1))), C_nb


def tactical_log(seed, lat, duration):
    rng = np.random.default_rng(1000 + seed)
    rpy = [rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-180, 180)]
    log, _ = static_log(rpy, lat, duration=duration)
    model = ImuErrorModel.preset("tactical", gyro_bias_dph=rng.normal(0, GYRO_BIAS_DPH, 3),
                                 accel_bias_mgal=rng.normal(0, ACCEL_BIAS_MGAL, 3))
    return apply_errors(log, model, seed=seed), np.array(rpy)


def tactical_priors():
    return dict(arw=0.12 * DEG_SQRTH, vrw=0.05 / 60, gyro_bias_std=GYRO_PRIOR_DPH * DPH,
                accel_bias_std=ACCEL_PRIOR_MGAL * MGAL)


def _run(capsys, *argv):
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as exc:           # argparse: a missing or malformed option
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("rpy, lat_deg", [([1.0, -2.0, 30.0], 30.0),
                                          ([-3.0, 4.0, -160.0], -45.0),
                                          ([0.5, 0.2, 179.9], 60.0)])
def test_exact_static_log_gives_the_exact_attitude(rpy, lat_deg):
    lat = np.deg2rad(lat_deg)
    log, _ = static_log(rpy, lat, h=100.0, duration=60.0)
    al = align_at_rest(log, [lat, 0.3, 100.0])
    assert al.heading_known and al.method == "fine" and al.n_updates == 60
    d = np.rad2deg(al.rpy) - rpy
    d[2] = (d[2] + 180.0) % 360.0 - 180.0
    np.testing.assert_allclose(d, 0.0, atol=1e-7)
    np.testing.assert_allclose(np.rad2deg(al.coarse_rpy[:2]), rpy[:2], atol=1e-9)
    assert al.noise.sources == {"arw": "log", "vrw": "log", "gyro_bias_std": "log",
                                "accel_bias_std": "log"}


def test_stated_heading_sigma_is_the_error_budget():
    """Stated heading sigma against hypot(b_g, ARW / sqrt(T)) / (W_ie cos lat) written
    with literal constants (W_ie = 15.041067 deg/h); the filter's broad heading prior
    (30 deg) takes 1.5 % off it.  Tilt: the accelerometer bias over g."""
    lat = np.deg2rad(30.0)
    imu, _ = tactical_log(0, lat, 300.0)
    al = align_at_rest(imu, [lat, 0.3, 50.0], **tactical_priors())
    budget_deg = np.rad2deg(np.hypot(GYRO_PRIOR_DPH, 0.12 / np.sqrt(300.0 / 3600.0))
                            / (15.041067 * np.cos(lat)))
    assert np.rad2deg(al.rpy_std[2]) == pytest.approx(budget_deg, rel=0.03)
    assert np.rad2deg(al.rpy_std[2]) < budget_deg
    tilt_arcsec = ACCEL_PRIOR_MGAL * 1e-5 / 9.7933 * 206264.8
    np.testing.assert_allclose(np.rad2deg(al.rpy_std[:2]) * 3600, tilt_arcsec, rtol=0.02)
    np.testing.assert_allclose(np.hypot(al.heading_std_bias, al.heading_std_noise),
                               np.deg2rad(budget_deg), rtol=2e-3)


def test_monte_carlo_heading_errors_match_the_stated_sigma():
    """100 seeds of a tactical IMU at rest, 5 min at 30 deg: the normalized heading
    errors are about N(0, 1) (RMS within 0.7 .. 1.4, ~68 % within 1 sigma, ~95 % within
    2 sigma); the tilts too."""
    lat = np.deg2rad(30.0)
    z = []
    for seed in range(100):
        imu, rpy = tactical_log(seed, lat, 300.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            al = align_at_rest(imu, [lat, 0.3, 50.0], **tactical_priors())
        d = al.rpy - np.deg2rad(rpy)
        d[2] = (d[2] + np.pi) % (2 * np.pi) - np.pi
        z.append(d / al.rpy_std)
    z = np.array(z)
    rms = np.sqrt(np.mean(z ** 2, axis=0))
    assert np.all((0.7 < rms) & (rms < 1.4)), rms
    within1 = np.mean(np.abs(z) < 1, axis=0)
    within2 = np.mean(np.abs(z) < 2, axis=0)
    assert np.all((0.55 < within1) & (within1 < 0.82)), within1
    assert np.all(within2 >= 0.88), within2


def test_consumer_gyro_heading_is_unknown(tmp_path, capsys):
    """0.5 deg/s of gyro bias, ARW 0.5 deg/sqrt(h): the Earth rate (13 deg/h) is out of
    reach: heading unknown (NaN, not a number), roll/pitch with sigmas; the command
    exits 3 naming the gyro error, 0 with --level-only."""
    lat = np.deg2rad(30.0)
    log, C_nb = static_log([2.0, -1.0, 70.0], lat)
    imu = apply_errors(log, ImuErrorModel.from_units(
        gyro_bias_dph=[1800.0, -1800.0, 1800.0], arw_deg_sqrth=0.5,
        accel_bias_mgal=[30.0, -20.0, 40.0], vrw_mps_sqrth=0.1), seed=2)
    for priors in ({}, dict(gyro_bias_std=1800 * DPH, arw=0.5 * DEG_SQRTH)):
        al = align_at_rest(imu, [lat, 0.3, 50.0], **priors)
        assert not al.heading_known and np.isnan(al.rpy[2]) and np.isnan(al.rpy_std[2])
        np.testing.assert_allclose(np.rad2deg(al.rpy[:2]), [2.0, -1.0], atol=0.01)
        assert np.all(np.isfinite(al.rpy_std[:2]))
    path = tmp_path / "consumer.bin"
    write_kfgins_binary(path, imu)
    code, out, err = _run(capsys, "align", path, "--lla", "30,7,50")
    assert code == 3
    assert "heading    unknown" in out and "roll" in out
    assert "heading unknown" in err and "deg/h" in err and len(err.strip().splitlines()) == 1
    code, out, err = _run(capsys, "align", path, "--lla", "30,7,50", "--level-only")
    assert code == 0 and "unknown" in out


def test_cli_writes_an_initial_state_for_ins_process(tmp_path, capsys):
    """Southern latitude typed as it is (--lla -33.9,...); the TOML is a config that
    ins process reads as its initial state (method 'given')."""
    from ins.estimation.pipeline.config import load_config
    lat = np.deg2rad(-33.9)
    log, _ = static_log([1.0, -2.0, 200.0], lat, duration=120.0, t0=5000.0)
    path = tmp_path / "imu.bin"
    write_kfgins_binary(path, log)
    out = tmp_path / "initial.toml"
    code, stdout, err = _run(capsys, "align", path, "--lla", "-33.9,151.2,50",
                             "--start", "5010", "-o", out)
    assert code == 0, err
    assert "heading" in stdout and f"wrote {out}" in stdout
    doc = tomllib.loads(out.read_text())
    init = doc["initial"]
    np.testing.assert_allclose(init["rpy_deg"], [1.0, -2.0, 200.0], atol=1e-6)
    assert (init["lat_deg"], init["lon_deg"], init["h_m"]) == (-33.9, 151.2, 50.0)
    assert init["time_s"] == pytest.approx(5010.0) and init["vel_ned_mps"] == [0, 0, 0]
    assert len(init["att_std_deg"]) == 3 and doc["alignment"]["method"] == "given"
    cfg = load_config(out, files={"imu": str(path), "gnss": str(path)})
    assert cfg.method == "given" and cfg.initial["rpy_deg"][2] == pytest.approx(200.0)
    assert "--lla" in cli.build_parser()._subparsers._group_actions[0].choices[
        "align"].format_help()


@pytest.mark.parametrize("argv, needle", [
    ([], "--lla"),
    (["--lla", "91,7,50"], "--lla: latitude 91"),
    (["--lla", "30,7"], "--lla"),
    (["--lla", "30,7,50", "--gyro-bias-std-dph", "-1"], "--gyro-bias-std-dph"),
    (["--lla", "30,7,50", "--level-only", "-o", "x.toml"], "-o"),
])
def test_bad_options_exit_2(tmp_path, capsys, argv, needle):
    log, _ = static_log([0, 0, 0], np.deg2rad(30.0), duration=20.0)
    path = tmp_path / "imu.bin"
    write_kfgins_binary(path, log)
    code, out, err = _run(capsys, "align", path, *argv)
    assert code == 2 and needle in err
    assert not (tmp_path / "x.toml").exists()


def test_moving_log_is_refused(tmp_path, capsys):
    """A vehicle driving back and forth (0.5 m/s^2 along x at 0.2 Hz): exit 2 naming
    the file and the moving spans; a window at rest before it is accepted."""
    lat = np.deg2rad(30.0)
    log, _ = static_log([0.0, 0.0, 45.0], lat, duration=120.0)
    a = np.where(log.time > 60.0, 0.5 * np.sin(2 * np.pi * 0.2 * log.time), 0.0)
    dv = log.dvel_b.copy()
    dv[:, 0] += a * 0.01
    moving = ImuLog(log.time, log.dtheta_b, dv)
    path = tmp_path / "drive.bin"
    write_kfgins_binary(path, moving)
    code, out, err = _run(capsys, "align", path, "--lla", "30,7,50")
    assert code == 2 and str(path) in err and "not at rest" in err
    assert len(err.strip().splitlines()) == 1
    code, out, err = _run(capsys, "align", path, "--lla", "30,7,50", "--end", "59")
    assert code == 0, err
    with pytest.raises(InputError, match="not at rest"):
        align_at_rest(moving, [lat, 0.0, 50.0])
