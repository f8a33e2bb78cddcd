"""Drone metadata: a hand-written DJI XMP packet in a JPEG, EXIF GPS written by pillow,
the camera axes of the gimbal angles checked against geometry worked by hand, and the
real DJI images against the bundle adjustment (skipped without ../shared/real)."""
import struct
from pathlib import Path

import cv2
import numpy as np
import pytest

from ins.common.errors import InputError
from photogrammetry.cli.main import main
from photogrammetry.orientation.drone import eo_from_drone, read_drone_shot
from photogrammetry.orientation.exposure import read_eo_csv
from photogrammetry.orientation.mapping import EnuFrame, parse_frame
from photogrammetry.orientation.rotation import angles_to_matrix

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "real" / "odm_drone_block"

XMP = """<x:xmpmeta xmlns:x="adobe:ns:meta/">
 <rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">
  <rdf:Description rdf:about="DJI Meta Data"
    xmlns:drone-dji="http://www.dji.com/drone-dji/1.0/"
   drone-dji:AbsoluteAltitude="+{alt}"
   drone-dji:GpsLatitude="{lat}"
   drone-dji:GpsLongtitude="{lon}"
   drone-dji:GimbalRollDegree="{roll}"
   drone-dji:GimbalYawDegree="{yaw}"
   drone-dji:GimbalPitchDegree="{pitch}"
   drone-dji:RtkFlag="{flag}"
   drone-dji:RtkStdLon="0.02"
   drone-dji:RtkStdLat="0.01"
   drone-dji:RtkStdHgt="0.03">
  </rdf:Description>
 </rdf:RDF>
</x:xmpmeta>"""


def _jpeg_with_xmp(path, xmp):
    """A JPEG whose APP1 segment holds the XMP packet (the layout DJI writes)."""
    ok, jpg = cv2.imencode(".jpg", np.full((48, 64), 128, np.uint8))
    payload = b"http://ns.adobe.com/xap/1.0/\x00" + xmp.encode()
    app1 = b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload
    data = jpg.tobytes()
    Path(path).write_bytes(data[:2] + app1 + data[2:])
    return str(path)


def _shot(tmp_path, name="DJI_0001.JPG", roll=0.0, pitch=-90.0, yaw=0.0, flag=50,
          lat=30.0, lon=114.0, alt=120.0):
    return read_drone_shot(_jpeg_with_xmp(tmp_path / name, XMP.format(
        roll=roll, pitch=pitch, yaw=yaw, flag=flag, lat=lat, lon=lon, alt=alt)))


def _C(tmp_path, **kw):
    s = _shot(tmp_path, **kw)
    frame = EnuFrame(np.deg2rad(s.lat_deg), np.deg2rad(s.lon_deg), 0.0)
    eo = eo_from_drone([s], frame, "phi-omega-kappa", np.deg2rad([0.5, 0.5, 2.0]), 3.0)
    return eo, angles_to_matrix(eo.angles, eo.system)[0]


def test_xmp_fields(tmp_path):
    s = _shot(tmp_path, roll=1.5, pitch=-60, yaw=92.9, lat=24.5, lon=-120.25, alt=186.57)
    assert s.image_id == "DJI_0001" and s.source == "xmp"
    assert (s.lat_deg, s.lon_deg, s.alt_m) == (24.5, -120.25, 186.57)
    np.testing.assert_array_equal(s.gimbal_rpy_deg, [1.5, -60, 92.9])
    np.testing.assert_array_equal(s.rtk_std_m, [0.01, 0.02, 0.03])
    assert _shot(tmp_path, flag=0).rtk_std_m is None          # no RTK fix: no RTK sigma


def test_nadir_yaw_zero_is_identity(tmp_path):
    """Pitch -90, yaw 0: image right = east, image top = north, view down: R = I."""
    eo, R = _C(tmp_path)
    np.testing.assert_allclose(R, np.eye(3), atol=1e-12)


def test_nadir_yaw_90_image_top_east(tmp_path):
    """Yaw 90: the top of the image points east, its right side south."""
    _, R = _C(tmp_path, yaw=90.0)
    np.testing.assert_allclose(R[:, 1], [1, 0, 0], atol=1e-12)     # y_c (image up) = east
    np.testing.assert_allclose(R[:, 0], [0, -1, 0], atol=1e-12)    # x_c (right) = south
    np.testing.assert_allclose(R[:, 2], [0, 0, 1], atol=1e-12)     # z_c backwards = up


def test_oblique_pitch_minus_60_looks_north_and_down(tmp_path):
    """Pitch -60, yaw 0: the view 60 deg below the horizon towards north; roll 10 deg
    turns the image clockwise about the view (right side down)."""
    _, R = _C(tmp_path, pitch=-60.0)
    c, s = np.cos(np.deg2rad(60)), np.sin(np.deg2rad(60))
    np.testing.assert_allclose(-R[:, 2], [0, c, -s], atol=1e-12)    # viewing direction
    np.testing.assert_allclose(R[:, 0], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(R[:, 1], [0, s, c], atol=1e-12)
    _, R = _C(tmp_path, pitch=0.0, roll=10.0)                       # at the horizon
    r = np.deg2rad(10)
    np.testing.assert_allclose(-R[:, 2], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(R[:, 0], [np.cos(r), 0, -np.sin(r)], atol=1e-12)


def test_sigmas(tmp_path):
    """Nadir, yaw 0: RTK sigmas N, E, D -> Y, X, Z; at pitch -90 the roll axis is the
    vertical too (gimbal lock of yaw-pitch-roll), so kappa takes yaw and roll sigmas."""
    eo, _ = _C(tmp_path)
    np.testing.assert_allclose(eo.position_sigma[0], [0.02, 0.01, 0.03], atol=1e-12)
    np.testing.assert_allclose(np.rad2deg(eo.angle_sigma[0, 2]), np.hypot(2.0, 0.5), rtol=1e-6)


def test_exif_gps_fallback(tmp_path):
    """No position in the XMP: the EXIF GPS IFD (written by pillow) gives it."""
    from PIL import Image
    xmp = XMP.replace('drone-dji:GpsLatitude="{lat}"', "").replace(
        'drone-dji:GpsLongtitude="{lon}"', "")
    p = tmp_path / "e.jpg"
    exif = Image.Exif()
    exif.get_ifd(0x8825).update({1: "S", 2: (33.0, 52.0, 7.2), 3: "E", 4: (151.0, 12.0, 36.0),
                                 5: 0, 6: 58.5})
    Image.fromarray(np.full((32, 32), 100, np.uint8)).save(p, exif=exif,
                                                           xmp=xmp.format(
                                                               roll=0, pitch=-90, yaw=0,
                                                               flag=0, alt=1).encode())
    s = read_drone_shot(p)
    assert s.source == "exif"
    assert s.alt_m == pytest.approx(58.5)
    assert s.lat_deg == pytest.approx(-(33 + 52 / 60 + 7.2 / 3600))
    assert s.lon_deg == pytest.approx(151 + 12 / 60 + 36 / 3600)


def test_no_xmp_is_refused(tmp_path, capsys):
    p = tmp_path / "plain.jpg"
    cv2.imwrite(str(p), np.zeros((10, 10), np.uint8))
    with pytest.raises(InputError, match="gimbal"):
        read_drone_shot(p)
    assert main(["eo", "--from-exif", str(p), "-o", str(tmp_path / "eo.csv")]) == 2
    assert "plain.jpg" in capsys.readouterr().err
    assert main(["eo", "--from-exif", str(tmp_path / "none.jpg"), "-o",
                 str(tmp_path / "eo.csv")]) == 2


@pytest.mark.skipif(not REAL.is_dir(), reason="../shared/real is absent")
def test_real_dji_images_against_bundle(tmp_path):
    """The DJI block: positions in UTM 51N as odm_xyz_opk.csv has them (the RTK GPS,
    5 cm); angles in the bundle's ENU frame within 1.5 deg of the OpenSfM bundle
    adjustment (0.5-1.25 deg measured; a wrong axis convention would be tens of
    degrees off)."""
    from scipy.spatial.transform import Rotation

    from photogrammetry.sfm.opensfm import read_reconstruction
    images = sorted(str(p) for p in (REAL / "images").glob("*.tif"))
    out = tmp_path / "eo.csv"
    assert main(["eo", "--from-exif", *images, "--frame", "EPSG:32651", "--system",
                 "omega-phi-kappa", "-o", str(out), "-q"]) == 0
    eo = read_eo_csv(out)
    assert eo.frame == parse_frame("EPSG:32651").header()
    rows = [ln.replace("'", "").split() for ln in (REAL / "odm_xyz_opk.csv").read_text()
            .splitlines()[1:] if ln.strip()]
    ref = {r[0]: np.array([float(v) for v in r[1:4]]) for r in rows}
    for k, iid in enumerate(eo.image_id):
        np.testing.assert_allclose(eo.position[k], ref[iid], atol=0.05)
    assert np.all(eo.position_sigma < 0.03)
    bundle = read_reconstruction(REAL / "opensfm" / "reconstruction.json")
    lat, lon, h = bundle.reference_lla_deg
    assert main(["eo", "--from-exif", *images, "--origin", f"{lat},{lon},{h}", "-o",
                 str(out), "-q", "--system", "omega-phi-kappa"]) == 0
    eo = read_eo_csv(out)
    assert eo.frame == bundle.eo.frame
    for k, iid in enumerate(eo.image_id):
        j = bundle.eo.image_id.index(iid)
        d = Rotation.from_matrix(eo.matrices()[k].T @ bundle.eo.matrices()[j]).magnitude()
        assert np.rad2deg(d) < 1.5


def test_dji_dewarp_camera_projects_as_opencv(tmp_path):
    """DewarpData (full sensor 5472 x 3648, fx = fy here) on a 1368 x 912 image: our
    camera projects as cv2.projectPoints with the scaled matrix (principal point W0/2 +
    cx in corner coordinates, then to pixel centres) and OpenCV's distortion."""
    from photogrammetry.orientation.drone import camera_from_dji
    xmp = XMP.replace('drone-dji:RtkFlag="{flag}"', 'drone-dji:RtkFlag="{flag}"\n'
                      '   drone-dji:CalibratedOpticalCenterX="2736.000000"\n'
                      '   drone-dji:CalibratedOpticalCenterY="1824.000000"\n'
                      '   drone-dji:DewarpData="2018-09-07;3657.02,3657.02,-4.03,23.10,'
                      '-0.267098,0.111977,0.000924881,0.0000882056,-0.0331614"')
    ok, jpg = cv2.imencode(".jpg", np.full((912, 1368), 128, np.uint8))
    payload = b"http://ns.adobe.com/xap/1.0/\x00" + xmp.format(
        roll=0, pitch=-90, yaw=0, flag=0, lat=1, lon=2, alt=3).encode()
    data = jpg.tobytes()
    p = tmp_path / "d.jpg"
    p.write_bytes(data[:2] + b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload
                  + data[2:])
    cam, aniso = camera_from_dji(p)
    assert aniso == 0 and (cam.width_px, cam.height_px) == (1368, 912)
    s = 0.25
    K = np.array([[3657.02 * s, 0, (2736 - 4.03) * s - 0.5],
                  [0, 3657.02 * s, (1824 + 23.10) * s - 0.5], [0, 0, 1]])
    dist = np.array([-0.267098, 0.111977, 0.000924881, 0.0000882056, -0.0331614])
    rng = np.random.default_rng(2)
    X = np.column_stack([rng.uniform(-0.6, 0.6, 50), rng.uniform(-0.4, 0.4, 50),
                         np.ones(50)]) * rng.uniform(10, 90, (50, 1))
    uv_cv, _ = cv2.projectPoints(X, np.zeros(3), np.zeros(3), K, dist)
    X_c = X * [1, -1, -1]
    xy = -cam.focal_length_mm * X_c[:, :2] / X_c[:, 2:3]
    np.testing.assert_allclose(cam.photo_to_pixel(cam.distort(xy)), uv_cv[:, 0], atol=1e-6)


def test_gimbal_angles_invert_the_chain(tmp_path):
    """eo_from_drone then gimbal_angles gives the XMP's roll, pitch, yaw back (oblique,
    away from the pitch -90 lock), with a boresight too."""
    from photogrammetry.orientation.drone import gimbal_angles
    s = _shot(tmp_path, roll=1.2, pitch=-60.0, yaw=-175.8)
    frame = EnuFrame(np.deg2rad(29.9), np.deg2rad(113.9), 0.0)
    bore = np.deg2rad([0.3, -0.2, 0.5])
    eo = eo_from_drone([s], frame, "omega-phi-kappa", np.deg2rad([0.5, 0.5, 2.0]), 3.0,
                       bore)
    lla = np.array([[np.deg2rad(s.lat_deg), np.deg2rad(s.lon_deg), s.alt_m]])
    rpy = gimbal_angles(eo.matrices(), frame.C_mn(lla), bore)
    np.testing.assert_allclose(np.rad2deg(rpy[0]), [1.2, -60.0, -175.8], atol=1e-9)
