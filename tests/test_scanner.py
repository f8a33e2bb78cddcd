"""Scanner file: strict keys, defaults, the C_bs convention (hand-written matrices)."""
from pathlib import Path

import numpy as np
import pytest

from ins.common.errors import InputError
from ins.lidar.scanner import Scanner, read_scanner, scanner_rays, write_scanner

ROOT = Path(__file__).resolve().parents[1]


def test_example_file_reads():
    sc = read_scanner(ROOT / "data" / "scanner" / "example_scanner.toml")
    assert sc.model == "polygon"
    assert sc.range_sigma_m == 0.02
    assert np.allclose(sc.lever_arm_m, [0.12, -0.05, 0.25])
    assert np.allclose(np.rad2deg(sc.boresight_sigma_rad), [0.003, 0.003, 0.005])
    assert np.allclose(sc.C_bs, np.eye(3))


def test_defaults(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('[scanner]\nmodel = "oscillating"\n')
    sc = read_scanner(p)
    assert sc.model == "oscillating" and sc.range_sigma_m == 0.0
    assert np.array_equal(sc.C_bs, np.eye(3)) and not sc.lever_arm_m.any()


@pytest.mark.parametrize("text, words", [
    ('[scanner]\nmodel = "polygon"\nrange_sigma = 0.1\n', ["range_sigma", "range_sigma_m"]),
    ('[scanner]\nmodel = "conical"\n', ["model", "polygon"]),
    ('[scanner]\nmodel = "polygon"\nrange_sigma_m = -1.0\n', ["range_sigma_m", ">= 0"]),
    ('[scanner]\nmodel = "polygon"\n[mount]\nlever_arm_m = [0, 0, 0]\n', ["mount"]),
    ('[scanner]\nmodel = "polygon"\n[mounting]\nlever_arm_m = [0, 0]\n', ["lever_arm_m", "3"]),
    ('[scanner]\nmodel = "polygon"\n[mounting]\naxes = [[1,0,0],[0,1,0],[0,0,-1]]\n',
     ["reflection"]),
    ('[mounting]\nlever_arm_m = [0, 0, 0]\n', ["[scanner]"]),
])
def test_strict_keys(tmp_path, text, words):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(InputError) as e:
        read_scanner(p)
    msg = str(e.value)
    assert "bad.toml" in msg
    for w in words:
        assert w in msg


def test_boresight_convention_hand_written():
    """C_bs = axes Rx(rx) Ry(ry) Rz(rz), active rotations written out by hand."""
    rx, ry, rz = 0.01, -0.02, 0.03
    Rx = np.array([[1, 0, 0], [0, np.cos(rx), -np.sin(rx)], [0, np.sin(rx), np.cos(rx)]])
    Ry = np.array([[np.cos(ry), 0, np.sin(ry)], [0, 1, 0], [-np.sin(ry), 0, np.cos(ry)]])
    Rz = np.array([[np.cos(rz), -np.sin(rz), 0], [np.sin(rz), np.cos(rz), 0], [0, 0, 1]])
    axes = np.array([[0.0, 1, 0], [-1, 0, 0], [0, 0, 1]])
    sc = Scanner(axes=axes, boresight_rad=[rx, ry, rz])
    assert np.allclose(sc.C_bs, axes @ Rx @ Ry @ Rz, atol=1e-15)


def test_round_trip(tmp_path):
    sc = Scanner(model="oscillating", forward_tilt_rad=0.1, range_sigma_m=0.03,
                 scan_angle_sigma_rad=1e-5, lever_arm_m=[1, 2, 3],
                 boresight_rad=[1e-3, -2e-3, 3e-3], lever_arm_sigma_m=[0.01, 0.02, 0.03],
                 boresight_sigma_rad=[1e-4, 2e-4, 3e-4])
    from ins.lidar.scanner import BoresightCalibration
    cal = BoresightCalibration([100.0, 250.5], [1e-6, 2e-6, 3e-6], [4e-5, 0.0, 5e-4])
    for s in (sc, sc.__class__(**{**{n: getattr(sc, n) for n in sc.__dataclass_fields__},
                                   "on": "aircraft",
                                   "imu_to_platform_centre_b_m": [0.1, -0.2, 0.3]}),
              sc.replace(calibration=cal)):
        write_scanner(tmp_path / "s.toml", s)
        back = read_scanner(tmp_path / "s.toml")
        for name in s.__dataclass_fields__:
            a, b = getattr(s, name), getattr(back, name)
            if name in ("model", "on"):
                assert a == b
            elif name == "calibration":
                assert (a is None) == (b is None)
                if a is not None:
                    for f in ("time_span_s", "boresight_sigma_rad", "attitude_sigma_rad"):
                        assert np.allclose(getattr(a, f), getattr(b, f), rtol=1e-12,
                                           atol=1e-15), f
            else:
                assert np.allclose(a, b, rtol=1e-12, atol=1e-15), name
    # a new boresight drops the record of the old one's calibration
    assert sc.replace(calibration=cal).with_boresight([0, 0, 0]).calibration is None


def test_platform_arm_only_on_aircraft(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text('[scanner]\nmodel = "polygon"\n[mounting]\n'
                 'imu_to_platform_centre_b_m = [0, 0, 0.1]\n')
    with pytest.raises(InputError, match="imu_to_platform_centre_b_m.*aircraft"):
        read_scanner(p)


def test_rays():
    """Scan angle positive to the right (+y_s), tilt towards +x_s."""
    r = scanner_rays([100.0, 100.0, 100.0], np.deg2rad([0.0, 30.0, -30.0]))
    assert np.allclose(r, [[0, 0, 100], [0, 50, 100 * np.cos(np.pi / 6)],
                           [0, -50, 100 * np.cos(np.pi / 6)]])
    r = scanner_rays([10.0], [0.0], forward_tilt_rad=np.deg2rad(30))
    assert np.allclose(r, [[5.0, 0, 10 * np.cos(np.pi / 6)]])
