"""Drone image metadata (EXIF GPS, DJI XMP) to exterior orientation.

DJI writes, in the image's XMP packet (namespace ``drone-dji``,
``http://www.dji.com/drone-dji/1.0/``): ``GpsLatitude``, ``GpsLongtitude`` (sic; also
read as ``GpsLongitude``), ``AbsoluteAltitude`` (m), ``GimbalRollDegree``,
``GimbalPitchDegree``, ``GimbalYawDegree`` (deg) and with RTK ``RtkFlag``,
``RtkStdLat``, ``RtkStdLon``, ``RtkStdHgt`` (m).  The position falls back to the EXIF GPS
tags (pillow for JPEG; tifffile's GPS IFD or GDAL's metadata tag 42112 for TIFF).

The gimbal angles are the NED Euler angles (``C_ng = Rz(yaw) Ry(pitch) Rx(roll)``, the
INS's order, ``conventions.md``) of the camera body ``g``: x along the optical axis (the
viewing direction), y to the right of the image, z down the image.  Pitch 0 looks at the
horizon, -90 straight down; at pitch -90 and yaw 0 the top of the image points north.
The photogrammetric camera frame ``c`` (x right, y up on the image, z backwards) has in
``g`` the axes ``x_c = y_g``, ``y_c = -z_g``, ``z_c = -x_g``, so
``C_gc = [[0, 0, -1], [1, 0, 0], [0, -1, 0]]`` (:data:`DJI_CAMERA_AXES`) and

    C_mc = C_mn C_ng C_gc [boresight]

the chain of ``photogrammetry eo`` with the gimbal in place of the IMU body.

The camera (:func:`camera_from_dji`) comes from ``DewarpData``
(``date;fx,fy,cx,cy,k1,k2,p1,p2,k3``: focal lengths and the principal point's offset
from the centre ``(CalibratedOpticalCenterX, CalibratedOpticalCenterY)`` in pixels of
the full sensor ``2 CalibratedOpticalCenterX x 2 CalibratedOpticalCenterY``, OpenCV's
distortion of normalised coordinates, as Pix4D and ODM read it), scaled to the image's
size; the frame camera has square pixels, so ``f`` is the mean of fx and fy (their
difference is stated by the caller).  The drone's
position is taken as the perspective centre's (no lever arm).  Sigmas: the RTK standard
deviations (north, east, down) when ``RtkFlag`` is not 0, else a stated position sigma;
a stated gimbal sigma per angle (roll, pitch, yaw) propagated into the angle system.
"""
import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.nav.rotation import euler_to_dcm
from photogrammetry.orientation.exposure import ExposureOrientation, _angle_jacobian, _propagate
from photogrammetry.orientation.rotation import boresight_matrix, check_system, matrix_to_angles

__all__ = ["DroneShot", "read_drone_shot", "parse_dji_xmp", "read_xmp_packet",
           "eo_from_drone", "gimbal_angles", "camera_from_dji", "DJI_CAMERA_AXES", "DJI_NS"]

DJI_NS = "http://www.dji.com/drone-dji/1.0/"
#: ``C_gc``: the camera frame c in the DJI gimbal body g (x optical axis, y right, z down).
DJI_CAMERA_AXES = ((0.0, 0.0, -1.0), (1.0, 0.0, 0.0), (0.0, -1.0, 0.0))
_XMP_RE = re.compile(rb"<x:xmpmeta.*?</x:xmpmeta>", re.S)
_SCAN_BYTES = 4 << 20
_GPS_EPOCH_UNIX = 315964800.0
_LEAP_S = 18.0


@dataclass(frozen=True)
class DroneShot:
    """Metadata of one drone image.

    Attributes
    ----------
    path, image_id : str
    lat_deg, lon_deg, alt_m : float
        Position (deg, deg, m; the altitude as the drone writes it).
    gimbal_rpy_deg : ndarray (3,)
        Gimbal roll, pitch, yaw, deg (module docstring).
    rtk_std_m : ndarray (3,) or None
        RTK standard deviations north, east, up, m.
    time_s : float
        GPS seconds of week of EXIF DateTimeOriginal taken as UTC (NaN if absent;
        DJI clocks often keep local time: for ordering only).
    source : str
        Where the position came from (``"xmp"`` or ``"exif"``).
    """
    path: str
    image_id: str
    lat_deg: float
    lon_deg: float
    alt_m: float
    gimbal_rpy_deg: np.ndarray
    rtk_std_m: np.ndarray
    time_s: float
    source: str


def read_xmp_packet(path):
    """The XMP packet of an image as text, or None (TIFF tag 700, else the first
    ``<x:xmpmeta ...>`` in the file's first 4 MB, as JPEG's APP1 segment holds it)."""
    path = str(path)
    data = None
    if path.lower().endswith((".tif", ".tiff")):
        import tifffile
        with tifffile.TiffFile(path) as tif:
            tag = tif.pages[0].tags.get(700)
            if tag is not None:
                data = tag.value
    if data is None:
        with open(path, "rb") as f:
            data = f.read(_SCAN_BYTES)
    if isinstance(data, str):
        data = data.encode("utf-8", "replace")
    m = _XMP_RE.search(bytes(data))
    return m.group(0).decode("utf-8", "replace") if m else None


def parse_dji_xmp(text, path=None):
    """The ``drone-dji`` fields of an XMP packet, as attributes or as elements:
    ``{local name: text}``."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise InputError(f"XMP packet is not well-formed XML: {exc}", path=path) from None
    out = {}
    prefix = "{" + DJI_NS + "}"
    for el in root.iter():
        for k, v in el.attrib.items():
            if k.startswith(prefix):
                out.setdefault(k[len(prefix):], v.strip())
        if el.tag.startswith(prefix) and el.text and el.text.strip():
            out.setdefault(el.tag[len(prefix):], el.text.strip())
    return out


def _rational(v):
    try:
        return float(v)
    except TypeError:
        return float(v[0]) / float(v[1])


def _dms(values):
    v = list(values)
    if len(v) == 6:                       # tifffile: numerator, denominator pairs
        v = [v[0] / v[1], v[2] / v[3], v[4] / v[5]]
    d, m, s = (_rational(x) for x in v)
    return d + m / 60.0 + s / 3600.0


def _gdal_exif(text):
    items = dict(re.findall(r'<Item name="(EXIF_[A-Za-z]+)"[^>]*>([^<]*)</Item>', text))
    out = {}

    def nums(s):
        return [float(x) for x in re.findall(r"[-+0-9.eE]+", s)]
    if "EXIF_GPSLatitude" in items and "EXIF_GPSLongitude" in items:
        la, lo = nums(items["EXIF_GPSLatitude"]), nums(items["EXIF_GPSLongitude"])
        out["lat"] = (la[0] + la[1] / 60 + la[2] / 3600) * (
            -1 if items.get("EXIF_GPSLatitudeRef", "N").strip() == "S" else 1)
        out["lon"] = (lo[0] + lo[1] / 60 + lo[2] / 3600) * (
            -1 if items.get("EXIF_GPSLongitudeRef", "E").strip() == "W" else 1)
    if "EXIF_GPSAltitude" in items:
        out["alt"] = nums(items["EXIF_GPSAltitude"])[0] * (
            -1 if items.get("EXIF_GPSAltitudeRef", "0x00").strip() in ("0x01", "1") else 1)
    if "EXIF_DateTimeOriginal" in items:
        out["datetime"] = items["EXIF_DateTimeOriginal"].strip()
    return out


def read_exif(path):
    """EXIF GPS position and DateTimeOriginal: dict with ``lat``, ``lon`` (deg), ``alt``
    (m), ``datetime`` (text) where present."""
    path = str(path)
    out = {}
    if path.lower().endswith((".tif", ".tiff")):
        import tifffile
        with tifffile.TiffFile(path) as tif:
            tags = tif.pages[0].tags
            gps = tags.get("GPSTag")
            if gps is not None and "GPSLatitude" in gps.value:
                g = gps.value
                out["lat"] = _dms(g["GPSLatitude"]) * (-1 if g.get("GPSLatitudeRef") == "S"
                                                       else 1)
                out["lon"] = _dms(g["GPSLongitude"]) * (
                    -1 if g.get("GPSLongitudeRef") == "W" else 1)
                if "GPSAltitude" in g:
                    a = g["GPSAltitude"]
                    out["alt"] = (a[0] / a[1] if isinstance(a, tuple) else float(a)) * (
                        -1 if g.get("GPSAltitudeRef") in (1, b"\x01") else 1)
            exif = tags.get("ExifTag")
            if exif is not None and "DateTimeOriginal" in exif.value:
                out["datetime"] = exif.value["DateTimeOriginal"]
            gdal = tags.get(42112)
            if gdal is not None:
                for k, v in _gdal_exif(str(gdal.value)).items():
                    out.setdefault(k, v)
        return out
    from PIL import Image
    with Image.open(path) as im:
        exif = im.getexif()
        g = exif.get_ifd(0x8825)
        if 2 in g and 4 in g:
            out["lat"] = _dms(g[2]) * (-1 if g.get(1) == "S" else 1)
            out["lon"] = _dms(g[4]) * (-1 if g.get(3) == "W" else 1)
            if 6 in g:
                out["alt"] = _rational(g[6]) * (-1 if g.get(5) in (1, b"\x01") else 1)
        dt = exif.get_ifd(0x8769).get(36867)
        if dt:
            out["datetime"] = dt
    return out


def _gps_seconds_of_week(text):
    import datetime
    try:
        t = datetime.datetime.strptime(str(text).strip(), "%Y:%m:%d %H:%M:%S")
    except ValueError:
        return float("nan")
    unix = t.replace(tzinfo=datetime.timezone.utc).timestamp()
    return float((unix - _GPS_EPOCH_UNIX + _LEAP_S) % (7 * 86400.0))


def _number(fields, key, path, unit):
    try:
        v = float(fields[key])
    except ValueError:
        raise InputError(f"XMP drone-dji:{key} = {fields[key]!r} is not a number ({unit})",
                         path=path) from None
    if not np.isfinite(v):
        raise InputError(f"XMP drone-dji:{key} is not finite", path=path)
    return v


def read_drone_shot(path):
    """Read one image's position and gimbal angles (module docstring).

    Raises
    ------
    InputError
        A missing file, no gimbal angles, no position, a reversed camera or gimbal.
    """
    path = str(path)
    if not os.path.isfile(path):
        raise InputError("image not found", path=path)
    try:
        xmp = read_xmp_packet(path)
        exif = read_exif(path)
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"cannot read the image metadata: {exc}", path=path) from None
    dji = parse_dji_xmp(xmp, path) if xmp else {}
    keys = ("GimbalRollDegree", "GimbalPitchDegree", "GimbalYawDegree")
    if not all(k in dji for k in keys):
        raise InputError("no DJI gimbal angles (XMP drone-dji:GimbalRollDegree, "
                         "GimbalPitchDegree, GimbalYawDegree): not a DJI image with XMP",
                         path=path)
    for flag in ("CamReverse", "GimbalReverse"):
        if dji.get(flag, "0").strip() not in ("0", ""):
            raise InputError(f"XMP drone-dji:{flag} = {dji[flag]}: a reversed camera or "
                             "gimbal is not supported", path=path)
    rpy = np.array([_number(dji, k, path, "deg") for k in keys])
    lon_key = "GpsLongtitude" if "GpsLongtitude" in dji else "GpsLongitude"
    if "GpsLatitude" in dji and lon_key in dji and "AbsoluteAltitude" in dji:
        lat, lon = _number(dji, "GpsLatitude", path, "deg"), _number(dji, lon_key, path, "deg")
        alt, source = _number(dji, "AbsoluteAltitude", path, "m"), "xmp"
    elif {"lat", "lon", "alt"} <= set(exif):
        lat, lon, alt, source = exif["lat"], exif["lon"], exif["alt"], "exif"
    else:
        raise InputError("no position: neither XMP drone-dji:GpsLatitude, GpsLongtitude, "
                         "AbsoluteAltitude nor EXIF GPS latitude, longitude, altitude",
                         path=path)
    if not (abs(lat) <= 90 and abs(lon) <= 360):
        raise InputError(f"position {lat}, {lon} deg is out of range", path=path)
    rtk = None
    if all(k in dji for k in ("RtkStdLat", "RtkStdLon", "RtkStdHgt")) and \
            dji.get("RtkFlag", "0").strip() not in ("0", ""):
        rtk = np.array([_number(dji, k, path, "m") for k in ("RtkStdLat", "RtkStdLon",
                                                             "RtkStdHgt")])
        if np.any(rtk <= 0):
            rtk = None
    time_s = _gps_seconds_of_week(exif["datetime"]) if "datetime" in exif else float("nan")
    image_id = os.path.splitext(os.path.basename(path))[0]
    return DroneShot(path, image_id, float(lat), float(lon), float(alt), rpy, rtk, time_s,
                     source)


def eo_from_drone(shots, frame, system, gimbal_sigma_rad, position_sigma_m,
                  boresight_rad=(0.0, 0.0, 0.0)):
    """Exterior orientation of drone shots.

    Parameters
    ----------
    shots : sequence of DroneShot
    frame : EnuFrame or ProjectedFrame
        Mapping frame (:mod:`photogrammetry.orientation.mapping`); the altitudes are taken in its
        height system.
    system : {"phi-omega-kappa", "omega-phi-kappa"}
    gimbal_sigma_rad : array_like (3,)
        Sigma of the gimbal roll, pitch, yaw, rad.
    position_sigma_m : float
        Position sigma per axis for shots without RTK standard deviations, m.
    boresight_rad : array_like (3,)
        Camera-to-gimbal misalignment (rx, ry, rz) as in the camera file:
        ``C_gc = DJI_CAMERA_AXES @ Rx(rx) Ry(ry) Rz(rz)``.

    Returns
    -------
    ExposureOrientation
        Positions in the frame, angles of ``C_mc``, sigmas.
    """
    check_system(system)
    if not shots:
        raise InputError("no images")
    lla = np.array([[np.deg2rad(s.lat_deg), np.deg2rad(s.lon_deg), s.alt_m] for s in shots])
    rpy = np.deg2rad(np.array([s.gimbal_rpy_deg for s in shots]))
    C_mn = frame.C_mn(lla)
    C_gc = np.array(DJI_CAMERA_AXES) @ boresight_matrix(np.asarray(boresight_rad, float))

    def angles_of(rpy_):
        return matrix_to_angles(C_mn @ euler_to_dcm(rpy_) @ C_gc, system)

    angles = angles_of(rpy)
    sig_ang = _propagate(_angle_jacobian(rpy, angles_of),
                         np.broadcast_to(np.asarray(gimbal_sigma_rad, float), rpy.shape))
    std_ned = np.array([s.rtk_std_m if s.rtk_std_m is not None
                        else np.full(3, float(position_sigma_m)) for s in shots])
    sig_pos = np.sqrt(np.einsum("nij,nj->ni", C_mn * C_mn, std_ned ** 2))
    times = [s.time_s if np.isfinite(s.time_s) else 0.0 for s in shots]
    return ExposureOrientation([s.image_id for s in shots], times,
                               frame.position(lla), angles, system, frame.header(),
                               sig_pos, sig_ang)


def gimbal_angles(C_mc, C_mn, boresight_rad=(0.0, 0.0, 0.0)):
    """Gimbal roll, pitch, yaw (rad, the drone's convention) of camera attitudes: the
    inverse of the chain of :func:`eo_from_drone`, ``C_ng = C_mn^T C_mc C_gc^T``.

    Parameters
    ----------
    C_mc, C_mn : array_like (n, 3, 3)
    boresight_rad : array_like (3,)

    Returns
    -------
    ndarray (n, 3)
        Roll, pitch, yaw, rad (yaw in (-pi, pi]).
    """
    from ins.nav.rotation import dcm_to_euler
    C_gc = np.array(DJI_CAMERA_AXES) @ boresight_matrix(np.asarray(boresight_rad, float))
    C_ng = np.swapaxes(np.asarray(C_mn, float), -1, -2) @ np.asarray(C_mc, float) @ C_gc.T
    return dcm_to_euler(C_ng)


def camera_from_dji(path, pixel_size_mm=0.01):
    """The frame camera of a DJI image's XMP ``DewarpData`` (module docstring).

    Returns
    -------
    camera : FrameCamera
    anisotropy : float
        ``(fx - fy) / f``, which the square-pixel camera leaves out.
    """
    from photogrammetry.imagery.images import image_size
    from photogrammetry.orientation.camera import FrameCamera
    path = str(path)
    xmp = read_xmp_packet(path)
    dji = parse_dji_xmp(xmp, path) if xmp else {}
    need = ("DewarpData", "CalibratedOpticalCenterX", "CalibratedOpticalCenterY")
    if not all(k in dji for k in need):
        raise InputError("no DJI camera calibration (XMP drone-dji:DewarpData, "
                         "CalibratedOpticalCenterX/Y)", path=path)
    values = dji["DewarpData"].split(";")[-1].split(",")
    try:
        fx, fy, cx, cy, k1, k2, p1, p2, k3 = (float(v) for v in values)
    except ValueError:
        raise InputError(f"XMP drone-dji:DewarpData = {dji['DewarpData']!r}: expected "
                         "date;fx,fy,cx,cy,k1,k2,p1,p2,k3", path=path) from None
    w0 = 2.0 * _number(dji, "CalibratedOpticalCenterX", path, "px")
    h0 = 2.0 * _number(dji, "CalibratedOpticalCenterY", path, "px")
    w, h = image_size(path)
    s = w / w0
    if abs(h / h0 - s) > 1e-3 * s:
        raise InputError(f"image {w} x {h} px is not the sensor {w0:g} x {h0:g} px scaled "
                         "alike in both directions", path=path)
    fp = 0.5 * (fx + fy) * s
    f = fp * pixel_size_mm
    u0, v0 = (w0 / 2 + cx) * s - 0.5, (h0 / 2 + cy) * s - 0.5
    cam = FrameCamera(f, pixel_size_mm, w, h, (u0, v0),
                      (k1 / f ** 2, k2 / f ** 4, k3 / f ** 6), (p2 / f, -p1 / f))
    return cam, (fx - fy) / (0.5 * (fx + fy))
