"""Equisolid fisheye model (eq. 1): inverse/forward, ideal case, camera file."""
import numpy as np
import pytest

from ins.errors import InputError
from photogrammetry.lunar.fisheye import FisheyeCamera, read_camera

CAM = FisheyeCamera(800.0, 1600, 1600, (799.5, 801.25), (0.01, -0.02, 0.005))


def test_roundtrip():
    rng = np.random.default_rng(1)
    uv = rng.uniform(100, 1500, (50, 2))
    d = CAM.image_to_direction(uv)
    assert np.allclose(np.linalg.norm(d, axis=1), 1)
    assert np.abs(CAM.direction_to_image(d) - uv).max() < 1e-9


def test_ideal_equisolid_and_axes():
    cam = FisheyeCamera(800.0, 1600, 1600, (799.5, 799.5))
    theta = np.deg2rad(60.0)
    r = 2 * 800 * np.sin(theta / 2)               # r = 2 f sin(theta/2)
    # a point right of the principal point (+u) is +x; above it (-v) is +y; z = -cos theta
    d = cam.image_to_direction([[799.5 + r, 799.5], [799.5, 799.5 - r]])
    assert np.allclose(d[0], [np.sin(theta), 0, -np.cos(theta)])
    assert np.allclose(d[1], [0, np.sin(theta), -np.cos(theta)])


def test_eq1_distortion_terms():
    uv = np.array([[1100.0, 500.0]])
    x, y = uv[0, 0] - 799.5, -(uv[0, 1] - 801.25)
    s = np.arcsin(np.hypot(x, y) / 1600)
    theta = 2 * s + 0.01 * s**2 - 0.02 * s**3 + 0.005 * s**4
    d = CAM.image_to_direction(uv)[0]
    assert np.isclose(np.arccos(-d[2]), theta, atol=1e-12)
    assert np.isclose(np.arctan2(d[1], d[0]), np.arctan2(y, x))


def test_read_camera(tmp_path):
    path = tmp_path / "cam.toml"
    path.write_text('[camera]\nmodel = "fisheye-equisolid"\nfocal_length_mm = 4.4\n'
                    'pixel_size_mm = 0.0055\nwidth_px = 1600\nheight_px = 1200\n'
                    'radial_k = [0.1, 0.0, 0.0]\n')
    cam = read_camera(path)
    assert np.isclose(cam.focal_length_px, 800.0)
    assert cam.principal_point_px == (799.5, 599.5)
    assert cam.radial_k == (0.1, 0.0, 0.0)
    path.write_text('[camera]\nmodel = "fisheye-equisolid"\nfocal_length_px = 800\n'
                    'width_px = 1600\nheight_px = 1200\nradial_k = [0.1, 0.0]\n')
    with pytest.raises(InputError, match=r"cam.toml.*radial_k"):
        read_camera(path)
    path.write_text('[camera]\nmodel = "frame"\n')
    with pytest.raises(InputError, match="model"):
        read_camera(path)
