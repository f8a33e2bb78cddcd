"""Processing presets (ins.estimation.pipeline.presets, ins process --preset): the preset fills only the keys
the config does not give; the config's own values and a flight manifest's IMU noise win."""
import numpy as np
import pytest

from ins.common.errors import InputError
from ins.estimation.pipeline.presets import PRESETS, apply_preset, names, preset
from ins.estimation.pipeline.config import ProcessConfig, load_config

CONFIG = """\
[files]
imu = "imu.txt"
gnss = "gnss.txt"
[imu_noise]
arw_deg_sqrth = 0.7
[measurements]
nhc = false
"""


def test_names_and_values():
    assert names() == ["consumer", "land", "mems", "tactical"]
    mems = preset("mems")["imu_noise"]
    # the documented MEMS values (docs/real-data.md): deg/sqrt(h), m/s/sqrt(h), deg/h, mGal
    assert (mems["arw_deg_sqrth"], mems["vrw_mps_sqrth"], mems["gyro_bias_std_dph"],
            mems["accel_bias_std_mgal"]) == (0.3, 0.1, 100.0, 5000.0)
    land = preset("land")
    assert land["imu_noise"] == mems
    assert land["measurements"] == {"nhc": True, "zupt": True}
    assert preset("tactical")["imu_noise"]["gyro_bias_std_dph"] < mems["gyro_bias_std_dph"]
    # consumer parts (BMI/ICM/LSM datasheets): offsets up to 1 deg/s and 30 mg
    consumer = preset("consumer")
    assert consumer["imu_noise"]["gyro_bias_std_dph"] == 3600.0
    assert consumer["imu_noise"]["accel_bias_std_mgal"] == 30000.0
    assert consumer["measurements"] == {"zupt": True}
    preset("land")["imu_noise"]["arw_deg_sqrth"] = 99.0      # a copy: the table unchanged
    assert PRESETS["land"]["imu_noise"]["arw_deg_sqrth"] == 0.3
    with pytest.raises(InputError, match="unknown preset; known presets: consumer, land, mems, "
                                         "tactical"):
        preset("car")


def test_config_values_win(tmp_path):
    path = tmp_path / "c.toml"
    path.write_text(CONFIG)
    given = {"imu_noise": {"arw_deg_sqrth": 0.7}, "measurements": {"nhc": False}}
    cfg = load_config(path)
    out = apply_preset(cfg, "land", given)
    assert out is not cfg
    np.testing.assert_allclose(out.noise.arw_deg_sqrth, 0.7)        # the config's
    np.testing.assert_allclose(out.noise.vrw_mps_sqrth, 0.1)        # the preset's
    np.testing.assert_allclose(out.noise.gyro_bias_std_dph, 100.0)
    np.testing.assert_allclose(out.noise.accel_bias_std_mgal, 5000.0)
    assert out.noise.corr_time_h == 1.0
    assert out.measurements == {"nhc": False, "zupt": True}
    # the input config is not modified
    np.testing.assert_allclose(cfg.noise.vrw_mps_sqrth, 0.03)
    assert cfg.measurements == {"nhc": False}


def test_manifest_noise_kept():
    cfg = ProcessConfig(imu="i", gnss="g", source="manifest")
    out = apply_preset(cfg, "land")
    np.testing.assert_allclose(out.noise.arw_deg_sqrth, cfg.noise.arw_deg_sqrth)
    assert out.measurements == {"nhc": True, "zupt": True}


def test_command_line(tmp_path):
    from ins.cli.main import build_parser
    from ins.cli.process import _config
    path = tmp_path / "c.toml"
    path.write_text(CONFIG)
    args = build_parser().parse_args(["process", "--config", str(path), "--preset", "mems",
                                      "-o", str(tmp_path / "out")])
    cfg = _config(args)
    np.testing.assert_allclose(cfg.noise.arw_deg_sqrth, 0.7)
    np.testing.assert_allclose(cfg.noise.gyro_bias_std_dph, 100.0)
    assert cfg.measurements == {"nhc": False}
    args.preset = "bogus"
    with pytest.raises(InputError, match="--preset 'bogus'"):
        _config(args)
