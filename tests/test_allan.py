"""Allan deviation: analytic white noise; recovery of the injected noise densities from
a static simulation; the `ins allan` command."""
import numpy as np
import pytest

from ins.allan import allan_deviation, noise_densities
from ins.cli import main
from ins.imu import write_kfgins_text
from ins.simulate.sensor_errors import DEG_SQRTH, MPS_SQRTH, ImuErrorModel, apply_errors
from test_sensor_errors import static_log


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
    rows = [line.split() for line in out.splitlines() if line[:1] in "xyz"]
    assert len(rows) == 3
    assert np.allclose([float(r[1]) for r in rows], 0.2, rtol=0.15)
    assert np.allclose([float(r[3]) for r in rows], 0.05, rtol=0.15)
    assert png.stat().st_size > 1000


def test_cli_bad_file(tmp_path, capsys):
    path = tmp_path / "imu.txt"
    path.write_text("1 2 3\n")
    assert main(["allan", str(path)]) == 2
    assert str(path) in capsys.readouterr().err
