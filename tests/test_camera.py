"""Tests of photogrammetry.orientation.camera: pixel convention, Brown distortion (against OpenCV),
undistortion as the inverse, mounting checks and the camera file."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from ins.common.errors import InputError
from photogrammetry.orientation.camera import (
    NADIR_AXES,
    CameraMounting,
    FrameCamera,
    read_camera,
    write_camera,
)
from photogrammetry.orientation.rotation import boresight_matrix

rng = np.random.default_rng(3)
CAM = FrameCamera(100.0, 0.01, 8000, 6000, (3999.5, 2999.5),
                  radial_k=(-2e-5, 3e-9, -1e-13), tangential_p=(2e-6, -1.5e-6))


def test_pixel_convention():
    cam = FrameCamera(50.0, 0.005, 4, 2, (1.5, 0.5))
    # top-left pixel centre is left of and above the principal point: x < 0, y > 0
    assert_allclose(cam.pixel_to_photo([0, 0]), [-0.0075, 0.0025])
    uv = rng.uniform(0, 4, (10, 2))
    assert_allclose(cam.photo_to_pixel(cam.pixel_to_photo(uv)), uv, atol=1e-12)
    assert cam.inside([-0.5, -0.5]) and cam.inside([3.5, 1.5])
    assert not cam.inside([3.51, 1.0]) and not cam.inside([1.0, -0.6])
    assert not cam.inside([0.0, 0.0], margin_px=1)
    assert_allclose(cam.rays([[1.0, 2.0]]), [[1.0, 2.0, -50.0]])


def test_distortion_matches_opencv():
    cv2 = pytest.importorskip("cv2")
    f = CAM.focal_length_mm
    xy = rng.uniform(-40, 40, (50, 2)) * [1, 0.75]
    ours = CAM.distort(xy)
    # OpenCV: normalised image coordinates, y down; k scaled by f^(2i), p by f,
    # and with y flipped the tangential terms read p1_cv = -p2, p2_cv = p1.
    k1, k2, k3 = CAM.radial_k
    p1, p2 = CAM.tangential_p
    dist = np.array([k1 * f**2, k2 * f**4, -p2 * f, p1 * f, k3 * f**6])
    pts = np.column_stack([xy[:, 0] / f, -xy[:, 1] / f, np.ones(len(xy))])
    K = np.array([[f, 0, 0], [0, f, 0], [0, 0, 1.0]])
    uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, dist)
    assert_allclose(ours, uv[:, 0] * [1, -1], atol=1e-10)


def test_undistort_is_inverse():
    xy = rng.uniform(-40, 40, (2000, 2)) * [1, 0.75]
    obs = CAM.distort(xy)
    assert np.abs(obs - xy).max() > 0.5            # a strong distortion (mm)
    back = CAM.undistort(obs)
    assert np.abs(back - xy).max() < 1e-9
    assert np.abs(CAM.distort(back) - obs).max() < 1e-9
    plain = FrameCamera(100.0, 0.01, 10, 10, (4.5, 4.5))
    assert_allclose(plain.undistort(xy), xy, atol=0)
    bad = FrameCamera(100.0, 0.01, 10, 10, (4.5, 4.5), radial_k=(-1.0, 0, 0))
    with pytest.raises(ValueError, match="converge|fold"):
        bad.undistort([[10.0, 10.0]])


@pytest.mark.parametrize("kwargs, match", [
    (dict(focal_length_mm=0.0), "focal_length_mm.*mm"),
    (dict(pixel_size_mm=-0.01), "pixel_size_mm.*mm"),
    (dict(width_px=0), "width_px"),
    (dict(height_px=10.5), "height_px"),
    (dict(principal_point_px=(1.0,)), "principal_point_px"),
    (dict(radial_k=(0, 0)), "radial_k"),
])
def test_camera_validation(kwargs, match):
    base = dict(focal_length_mm=100.0, pixel_size_mm=0.01, width_px=10, height_px=10,
                principal_point_px=(4.5, 4.5))
    base.update(kwargs)
    with pytest.raises(InputError, match=match):
        FrameCamera(**base)


def test_mounting():
    b = np.deg2rad([0.01, -0.02, 0.05])
    m = CameraMounting(NADIR_AXES, [0.1, 0.2, -0.3], b)
    assert_allclose(m.C_bc, np.array(NADIR_AXES) @ boresight_matrix(b), atol=0)
    # nadir camera: its -z (viewing direction) is body down
    assert_allclose(m.axes @ [0, 0, -1], [0, 0, 1])
    with pytest.raises(InputError, match="det = \\+1"):
        CameraMounting(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(InputError, match="orthonormal"):
        CameraMounting(np.diag([1.0, 2.0, 0.5]))
    with pytest.raises(InputError, match="lever_arm_m"):
        CameraMounting(NADIR_AXES, [0.0, 1.0])
    with pytest.raises(ValueError):
        m.lever_arm_m[0] = 3.0        # frozen, read-only arrays


def test_camera_file_round_trip(tmp_path):
    mnt = CameraMounting(NADIR_AXES, [0.1, 0.2, -0.3], np.deg2rad([0.01, -0.02, 0.05]))
    p = tmp_path / "camera.toml"
    write_camera(p, CAM, mnt)
    cam2, mnt2 = read_camera(p)
    assert cam2 == CAM
    assert_allclose(mnt2.boresight_rad, mnt.boresight_rad, rtol=1e-15)
    assert np.array_equal(mnt2.axes, mnt.axes)
    assert np.array_equal(mnt2.lever_arm_m, mnt.lever_arm_m)


def test_camera_file_errors(tmp_path):
    p = tmp_path / "cam.toml"
    p.write_text('[camera]\nmodel = "frame"\nfocal_length_mm = 100.0\n')
    with pytest.raises(InputError, match=r"cam.toml: \[camera\] pixel_size_mm: missing "
                                         r"required key \(expected mm"):
        read_camera(p)
    p.write_text('[camera]\nfocal_length_mm = -1\npixel_size_mm = 0.01\nwidth_px = 10\n'
                 'height_px = 10\nprincipal_point_px = [4.5, 4.5]\n')
    with pytest.raises(InputError, match=r"cam.toml: \[camera\] focal_length_mm"):
        read_camera(p)
    p.write_text('[camera]\nfocal_length_mm = 100\npixel_size_mm = 0.01\nwidth_px = 10\n'
                 'height_px = 10\nprincipal_point_px = [4.5, 4.5]\n'
                 '[mounting]\naxes = [[1, 0, 0], [0, 1, 0], [0, 0, -1]]\n')
    with pytest.raises(InputError, match=r"cam.toml: \[mounting\] axes.*det"):
        read_camera(p)
    p.write_text("[camera\n")
    with pytest.raises(InputError, match="cam.toml: not valid TOML"):
        read_camera(p)
