"""Equisolid fisheye model (eq. 1): inverse/forward, ideal case, camera file."""
import numpy as np
import pytest

from ins.common.errors import InputError
from photogrammetry.lunar.fisheye import FisheyeCamera, camera_file_text, read_camera

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


# ---------------------------------------------------------------------------------------
# the other lens models: each against its closed form, OpenCV's fisheye as the oracle of
# the Kannala-Brandt model

PP = (640.3, 479.8)
CLOSED = {"fisheye-equidistant": lambda t, f: f * t,
          "fisheye-stereographic": lambda t, f: 2 * f * np.tan(t / 2),
          "fisheye-orthographic": lambda t, f: f * np.sin(t),
          "fisheye-equisolid": lambda t, f: 2 * f * np.sin(t / 2)}


@pytest.mark.parametrize("model", sorted(CLOSED))
def test_lens_closed_forms(model):
    f = 410.0
    cam = FisheyeCamera(f, 1280, 960, PP, model=model)
    theta = np.deg2rad([0.5, 10.0, 35.0, 60.0, 85.0])
    az = np.deg2rad([0.0, 47.0, 133.0, 210.0, 300.0])
    r = CLOSED[model](theta, f)
    uv = np.column_stack([PP[0] + r * np.cos(az), PP[1] - r * np.sin(az)])
    d = np.column_stack([np.sin(theta) * np.cos(az), np.sin(theta) * np.sin(az),
                         -np.cos(theta)])
    np.testing.assert_allclose(cam.direction_to_image(d), uv, atol=1e-9)
    np.testing.assert_allclose(cam.image_to_direction(uv), d, atol=1e-12)
    np.testing.assert_allclose(cam.image_to_direction(cam.direction_to_image(3.0 * d)), d,
                               atol=1e-12)


KB = (0.021, -0.0135, 0.0041, -0.0007)       # a real 190-deg lens's order of magnitude


def _cv_setup(f=410.0):
    cam = FisheyeCamera(f, 1280, 960, PP, model="opencv-fisheye", opencv_k=KB)
    K = np.array([[f, 0, PP[0]], [0, f, PP[1]], [0, 0, 1.0]])
    rng = np.random.default_rng(4)
    theta = rng.uniform(0.01, np.deg2rad(85), 200)
    az = rng.uniform(0, 2 * np.pi, 200)
    d = np.column_stack([np.sin(theta) * np.cos(az), np.sin(theta) * np.sin(az),
                         -np.cos(theta)])
    return cam, K, d


def test_opencv_fisheye_project_matches_cv2():
    cv2 = pytest.importorskip("cv2")
    cam, K, d = _cv_setup()
    d_cv = d * [1, -1, -1]                               # OpenCV: y down, z along the view
    uv_cv, _ = cv2.fisheye.projectPoints(d_cv[:, None, :], np.zeros(3), np.zeros(3), K,
                                         np.array(KB))
    np.testing.assert_allclose(cam.direction_to_image(d), uv_cv[:, 0], atol=1e-8)


def test_opencv_fisheye_unproject_matches_cv2():
    cv2 = pytest.importorskip("cv2")
    cam, K, d = _cv_setup()
    uv = cam.direction_to_image(d)
    ab = cv2.fisheye.undistortPoints(uv[:, None, :].astype(np.float64), K, np.array(KB),
                                     criteria=(cv2.TERM_CRITERIA_COUNT
                                               | cv2.TERM_CRITERIA_EPS, 50, 1e-14))[:, 0]
    back = cam.image_to_direction(uv) * [1, -1, -1]
    np.testing.assert_allclose(back[:, :2] / back[:, 2:], ab, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("model,extra,ok", [
    ("fisheye-equidistant", "", True),
    ("fisheye-stereographic", "", True),
    ("fisheye-orthographic", "", True),
    ("opencv-fisheye", "opencv_k = [0.02, -0.01, 0.004, -0.0007]\n", True),
    ("opencv-fisheye", "radial_k = [0.1, 0.0, 0.0]\n", False),
    ("fisheye-equidistant", "opencv_k = [0.02, -0.01, 0.004, -0.0007]\n", False),
    ("opencv-fisheye", "opencv_k = [0.02, -0.01, 0.004]\n", False),
    ("kannala-brandt", "", False),
])
def test_read_lens_models(tmp_path, model, extra, ok):
    from photogrammetry.lunar.fisheye import camera_file_text
    path = tmp_path / "cam.toml"
    path.write_text(f'[camera]\nmodel = "{model}"\nfocal_length_px = 410\nwidth_px = 1280\n'
                    f'height_px = 960\n{extra}')
    if not ok:
        with pytest.raises(InputError, match=r"cam.toml.*(opencv_k|radial_k|model)"):
            read_camera(path)
        return
    cam = read_camera(path)
    assert cam.model == model
    if "opencv_k" in extra:
        assert cam.opencv_k == (0.02, -0.01, 0.004, -0.0007)
    path.write_text(camera_file_text(cam))                  # written, read back the same
    assert read_camera(path) == cam


def test_opencv_fisheye_non_square_pixels_match_cv2():
    """fy != fx (``focal_length_y_px``): projection and its inverse against OpenCV's
    fisheye with K = [[fx, 0, cx], [0, fy, cy]]."""
    cv2 = pytest.importorskip("cv2")
    _, _, d = _cv_setup()
    fx, fy = 410.0, 412.7
    cam = FisheyeCamera(fx, 1280, 960, PP, model="opencv-fisheye", opencv_k=KB,
                        focal_length_y_px=fy)
    K = np.array([[fx, 0, PP[0]], [0, fy, PP[1]], [0, 0, 1.0]])
    uv_cv, _ = cv2.fisheye.projectPoints((d * [1, -1, -1])[:, None, :], np.zeros(3),
                                         np.zeros(3), K, np.array(KB))
    np.testing.assert_allclose(cam.direction_to_image(d), uv_cv[:, 0], atol=1e-8)
    back = cam.image_to_direction(uv_cv[:, 0])
    np.testing.assert_allclose(back, d, atol=1e-9)
    square = FisheyeCamera(fx, 1280, 960, PP, model="opencv-fisheye", opencv_k=KB)
    assert np.max(np.abs(square.direction_to_image(d) - uv_cv[:, 0])) > 0.5   # it matters


def test_non_square_pixels_in_the_camera_file(tmp_path):
    cam = FisheyeCamera(800.0, 1600, 1600, (799.5, 799.5), radial_k=(0.002, 0, 0),
                        focal_length_y_px=801.2)
    p = tmp_path / "cam.toml"
    p.write_text(camera_file_text(cam))
    got = read_camera(p)
    assert got == cam and got.y_scale == pytest.approx(801.2 / 800.0)
    p.write_text(camera_file_text(cam).replace("801.2", "2000.0"))
    with pytest.raises(InputError, match=r"focal_length_y_px.*aspect outside 0.5-2"):
        read_camera(p)
