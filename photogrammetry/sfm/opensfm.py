"""OpenSfM / ODM projects: cameras, shots and tracks in; refined EO out.

``reconstruction.json`` (a list of reconstructions; the first is read) holds
``cameras`` (per camera: ``projection_type``, ``width``, ``height`` and the parameters),
``shots`` (per image: ``camera``, ``rotation`` = axis-angle of ``R_cw`` (world to
camera, computer-vision axes: x right, y down, z along the view) and ``translation``
``t``, so a world point ``X`` is ``R_cw X + t`` in the camera and the centre is
``-R_cw^T t``), ``points`` and ``reference_lla`` (the world frame is the topocentric
ENU frame at ``latitude``, ``longitude``, ``altitude``: our :class:`EnuFrame` there).

Cameras (normalised coordinates: divided by ``s = max(width, height)``; a pixel centre
``(u, v)`` of ``docs/interfaces.md`` is ``((u + 0.5 - w/2)/s, (v + 0.5 - h/2)/s)``):

- ``brown``: ``x_n = x/z``, ``y_n = y/z`` (CV camera), ``r2 = x_n^2 + y_n^2``,
  ``x_d = x_n (1 + k1 r2 + k2 r2^2 + k3 r2^3) + 2 p1 x_n y_n + p2 (r2 + 2 x_n^2)``,
  ``y_d = y_n (...) + p1 (r2 + 2 y_n^2) + 2 p2 x_n y_n``, then
  ``(focal_x x_d + c_x, focal_y y_d + c_y)`` normalised;
- ``perspective``: ``focal``, ``k1``, ``k2`` (principal point at the centre, no p, k3).

Into the camera file (square pixels of ``pixel_size_mm``, an arbitrary scale the
angles do not depend on): ``f = focal * s * pixel_size``; our photo coordinates are
``x = f x_n``, ``y = -f y_n`` (y up), which turns OpenSfM's polynomial into ours with
``k1' = k1/f^2``, ``k2' = k2/f^4``, ``k3' = k3/f^6`` and, for the tangential terms,
``p1' = p2/f``, ``p2' = -p1/f`` (mm^-1); the principal point is
``u0 = c_x s + (w - 1)/2``, ``v0 = c_y s + (h - 1)/2``.  ``focal_x`` must equal
``focal_y`` (to 1e-9).

``tracks.csv``: an optional first line ``OPENSFM_TRACKS_VERSION_v1`` or ``_v2``, then
tab-separated ``image  track_id  feature_id  x  y  size  R  G  B [segmentation
instance]`` with ``x, y`` the observed keypoint in normalised coordinates.
"""
import json
import math
import os

import numpy as np

from ins.common.errors import InputError
from ins.common.fileio import atomic_open
from photogrammetry.orientation.camera import FrameCamera
from photogrammetry.orientation.exposure import ExposureOrientation
from photogrammetry.orientation.mapping import EnuFrame
from photogrammetry.orientation.rotation import (
    check_system,
    from_cv_rotation,
    matrix_to_angles,
    to_cv_rotation,
)

__all__ = ["OpenSfmProject", "read_reconstruction", "camera_from_opensfm",
           "camera_to_opensfm", "read_tracks", "write_reconstruction",
           "write_orthority_csv"]

DEFAULT_PIXEL_SIZE_MM = 0.01


class OpenSfmProject:
    """The first reconstruction of a ``reconstruction.json``.

    Attributes
    ----------
    path : str
    cameras : dict name -> (FrameCamera, dict of the file's parameters)
    shot_camera : dict image id -> camera name
    eo : ExposureOrientation
        Centres and angles in the reference ENU frame (``frame`` says where).
    points : dict point id -> ndarray (3,) in the same frame, m
    reference_lla_deg : (lat, lon, alt)
    """

    def __init__(self, path, cameras, shot_camera, eo, points, reference):
        self.path, self.cameras, self.shot_camera = path, cameras, shot_camera
        self.eo, self.points, self.reference_lla_deg = eo, points, reference


def _num(d, key, path, where, lo=None, hi=None, unit="", default=None):
    """``d[key]`` as a finite float in ``[lo, hi]`` (InputError naming `where` and `key`
    otherwise; `default` when the key is absent and a default is given)."""
    if key not in d and default is not None:
        return float(default)
    try:
        v = d[key]
        if isinstance(v, bool):
            raise TypeError
        v = float(v)
    except KeyError:
        raise InputError(f"{where}: missing {key!r}", path=path) from None
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{where}: {key} = {_short(d[key])} is not a number"
                         + (f" ({unit})" if unit else ""), path=path) from None
    if not math.isfinite(v):
        raise InputError(f"{where}: {key} = {v} is not finite", path=path)
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        rng = f"[{lo:g}, {hi:g}]" if lo is not None and hi is not None else (
            f">= {lo:g}" if lo is not None else f"<= {hi:g}")
        raise InputError(f"{where}: {key} = {v:g}{' ' + unit if unit else ''} is out of "
                         f"range (expected {rng}{' ' + unit if unit else ''})", path=path)
    return v


def _short(v, n=40):
    """A short repr of a JSON value for a message."""
    r = repr(v)
    return r if len(r) <= n else r[:n] + "..."


def _vec3(d, key, path, where, bound, unit):
    """``d[key]`` as 3 finite floats of magnitude <= bound (InputError otherwise)."""
    v = d.get(key) if isinstance(d, dict) else None
    if (not isinstance(v, (list, tuple)) or len(v) != 3
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in v)):
        raise InputError(f"{where}: {key} must be a list of 3 numbers ({unit}), got "
                         f"{_short(v)}", path=path)
    out = [float(x) for x in v]
    for i, x in enumerate(out):
        if not math.isfinite(x) or abs(x) > bound:
            raise InputError(f"{where}: {key}[{i}] = {x:g} is "
                             + ("not finite" if not math.isfinite(x) else
                                f"out of range (|value| <= {bound:g} {unit})"), path=path)
    return out


#: Plausible magnitudes: an image side (px), a normalised focal length / principal
#: point / distortion coefficient, a coordinate in the topocentric world frame (m).
MAX_SIDE_PX = 200_000
MAX_NORMALISED = 1e3
MAX_WORLD_M = 1e7
#: A keypoint of tracks.csv, normalised by the larger side (the image spans +-0.5).
MAX_TRACK_XY = 1.0


def camera_from_opensfm(params, pixel_size_mm=DEFAULT_PIXEL_SIZE_MM, path=None, name="?"):
    """Our :class:`FrameCamera` of an OpenSfM camera (module docstring).

    Parameters
    ----------
    params : dict
        The camera's entry of ``reconstruction.json`` (or ``camera_models.json``).
    pixel_size_mm : float
        Pixel pitch to express the focal length in mm.
    """
    where = f"camera {name!r}"
    kind = params.get("projection_type")
    if not isinstance(params, dict):
        raise InputError(f"{where}: expected an object of camera parameters, got "
                         f"{_short(params)}", path=path)
    w = _num(params, "width", path, where, 1, MAX_SIDE_PX, "px")
    h = _num(params, "height", path, where, 1, MAX_SIDE_PX, "px")
    if w != int(w) or h != int(h):
        raise InputError(f"{where}: width, height = {w:g}, {h:g} px must be whole numbers",
                         path=path)
    w, h = int(w), int(h)
    s = max(w, h)
    M = MAX_NORMALISED

    def num(n, lo=-M, hi=M):
        return _num(params, n, path, where, lo, hi, "normalised")
    if kind == "brown":
        fx, fy = num("focal_x", 1e-6), num("focal_y", 1e-6)
        if abs(fx - fy) > 1e-9 * max(abs(fx), 1.0):
            raise InputError(f"{where}: focal_x {fx} != focal_y {fy}; the frame camera has "
                             "square pixels", path=path)
        cx, cy = num("c_x", -1.0, 1.0), num("c_y", -1.0, 1.0)
        k = [num(n) for n in ("k1", "k2", "k3")]
        p1, p2 = num("p1"), num("p2")
    elif kind == "perspective":
        fx, cx, cy = num("focal", 1e-6), 0.0, 0.0
        k = [num("k1"), num("k2"), 0.0]
        p1 = p2 = 0.0
    else:
        raise InputError(f"{where}: projection_type {kind!r} is not read (brown, "
                         "perspective)", path=path)
    f = fx * s * pixel_size_mm
    return FrameCamera(f, pixel_size_mm, w, h,
                       (cx * s + (w - 1) / 2.0, cy * s + (h - 1) / 2.0),
                       (k[0] / f ** 2, k[1] / f ** 4, k[2] / f ** 6), (p2 / f, -p1 / f))


def camera_to_opensfm(camera):
    """The ``brown`` camera of OpenSfM for our camera (inverse of
    :func:`camera_from_opensfm`)."""
    w, h = camera.width_px, camera.height_px
    s = max(w, h)
    f = camera.focal_length_mm
    k1, k2, k3 = camera.radial_k
    p1, p2 = camera.tangential_p
    u0, v0 = camera.principal_point_px
    focal = f / (s * camera.pixel_size_mm)
    return {"projection_type": "brown", "width": w, "height": h, "focal_x": focal,
            "focal_y": focal, "c_x": (u0 - (w - 1) / 2.0) / s, "c_y": (v0 - (h - 1) / 2.0) / s,
            "k1": k1 * f ** 2, "k2": k2 * f ** 4, "k3": k3 * f ** 6,
            "p1": -p2 * f, "p2": p1 * f}


def _load(path):
    path = str(path)
    if not os.path.isfile(path):
        raise InputError("file not found", path=path)
    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"not a JSON file: {exc}", path=path) from None
    if isinstance(doc, dict):
        doc = [doc]
    if not isinstance(doc, list) or not doc or not isinstance(doc[0], dict):
        raise InputError("expected a list of reconstructions (OpenSfM reconstruction.json)",
                         path=path)
    return doc[0]


def read_reconstruction(path, system="omega-phi-kappa", pixel_size_mm=DEFAULT_PIXEL_SIZE_MM):
    """Read the first reconstruction of an OpenSfM/ODM ``reconstruction.json``.

    Returns
    -------
    OpenSfmProject
    """
    path = str(path)
    check_system(system)
    rec = _load(path)
    cams = rec.get("cameras") or {}
    shots = rec.get("shots") or {}
    if not isinstance(cams, dict) or not isinstance(shots, dict):
        raise InputError("cameras and shots must be objects (name -> entry)", path=path)
    if not cams or not shots:
        raise InputError("no cameras or no shots in the reconstruction", path=path)
    cameras = {n: (camera_from_opensfm(c, pixel_size_mm, path, n), c) for n, c in cams.items()}
    ref = rec.get("reference_lla") or {}
    if not isinstance(ref, dict):
        raise InputError(f"reference_lla must be an object (latitude, longitude, altitude), "
                         f"got {_short(ref)}", path=path)
    reference = (_num(ref, "latitude", path, "reference_lla", -90, 90, "deg", 0.0),
                 _num(ref, "longitude", path, "reference_lla", -180, 360, "deg", 0.0),
                 _num(ref, "altitude", path, "reference_lla", -1e4, 1e5, "m", 0.0))
    ids, pos, R, shot_camera, times = [], [], [], {}, []
    for sid in sorted(shots):
        sh = shots[sid]
        where = f"shot {sid!r}"
        if not isinstance(sh, dict):
            raise InputError(f"{where}: expected an object, got {_short(sh)}", path=path)
        r = np.array(_vec3(sh, "rotation", path, where, 1e3, "rad, axis-angle"))
        t = np.array(_vec3(sh, "translation", path, where, MAX_WORLD_M, "m"))
        if not isinstance(sh.get("camera"), str) or sh["camera"] not in cameras:
            raise InputError(f"{where}: camera {sh.get('camera')!r} is not in cameras",
                             path=path)
        from scipy.spatial.transform import Rotation
        R_cw = Rotation.from_rotvec(r).as_matrix()
        ids.append(os.path.splitext(sid)[0])
        shot_camera[ids[-1]] = sh["camera"]
        pos.append(-R_cw.T @ t)
        R.append(from_cv_rotation(R_cw))
        times.append(_num(sh, "capture_time", path, where, -1e12, 1e12, "s", 0.0))
    frame = EnuFrame.from_degrees(*reference)
    eo = ExposureOrientation(ids, np.zeros(len(ids)), np.array(pos),
                             matrix_to_angles(np.array(R), system), system, frame.header())
    pts = rec.get("points") or {}
    if not isinstance(pts, dict):
        raise InputError(f"points must be an object (id -> point), got {_short(pts)}",
                         path=path)
    points = {str(k): np.array(_vec3(v, "coordinates", path, f"point {k!r}", MAX_WORLD_M,
                                     "m"))
              for k, v in pts.items() if isinstance(v, dict) and "coordinates" in v}
    return OpenSfmProject(path, cameras, shot_camera, eo, points, reference)


def read_tracks(path, project):
    """Tie points of an OpenSfM ``tracks.csv`` with the cameras of `project`.

    Returns
    -------
    image_id, point_id : list of str
    xy_mm : ndarray (k, 2)
        Observed photo coordinates (mm) through each shot's camera.

    Observations of images that are not shots of the reconstruction are left out (with
    their count in the caller's hands: ``n_skipped``); a malformed line is an
    InputError naming it.
    """
    path = str(path)
    if not os.path.isfile(path):
        raise InputError("file not found", path=path)
    ids, pids, xy = [], [], []
    skipped = 0
    with open(path, "rb") as fh:
        raw = fh.read()
    for n, bline in enumerate(raw.splitlines(), 1):
        try:
            s = bline.decode("utf-8")
        except UnicodeDecodeError:
            raise InputError("not UTF-8 text", path=path, line=n) from None
        if not s.strip() or s.startswith("OPENSFM_TRACKS_VERSION"):
            continue
        parts = s.split("\t")
        if len(parts) < 5 or not parts[0].strip() or not parts[1].strip():
            raise InputError("expected tab-separated image, track_id, feature_id, x, y, "
                             "...", path=path, line=n)
        iid = os.path.splitext(parts[0])[0]
        if not parts[1].strip().isdigit():
            raise InputError(f"track_id {parts[1][:30]!r} is not a whole number (OpenSfM "
                             "numbers its tracks)", path=path, line=n)
        try:
            x, y = float(parts[3]), float(parts[4])
        except ValueError:
            raise InputError(f"x, y must be numbers (normalised), got {parts[3][:30]!r}, "
                             f"{parts[4][:30]!r}", path=path, line=n) from None
        if not (abs(x) <= MAX_TRACK_XY and abs(y) <= MAX_TRACK_XY):
            raise InputError(f"x, y = {x:g}, {y:g} are not finite coordinates normalised by "
                             f"the larger image side (|x|, |y| <= {MAX_TRACK_XY:g})",
                             path=path, line=n)
        if iid not in project.shot_camera:
            skipped += 1
            continue
        cam = project.cameras[project.shot_camera[iid]][0]
        w, h = cam.width_px, cam.height_px
        S = max(w, h)
        uv = np.array([x * S - 0.5 + w / 2.0, y * S - 0.5 + h / 2.0])
        ids.append(iid)
        pids.append(parts[1].strip())
        xy.append(cam.pixel_to_photo(uv))
    if not ids:
        raise InputError("no observation of a shot of the reconstruction", path=path)
    return ids, pids, np.array(xy), skipped


def write_reconstruction(path, eo, camera, camera_name="camera"):
    """Write an OpenSfM ``reconstruction.json`` of an EO in an ENU frame and a camera.

    The shots get ``R_cw`` (axis-angle) and ``t = -R_cw X0``; ``reference_lla`` is the
    ENU origin.  An EO in a projected frame is refused (OpenSfM's world is topocentric).
    """
    from scipy.spatial.transform import Rotation
    frame = str(eo.frame)
    if not frame.strip().lower().startswith("enu"):
        raise InputError(f"an OpenSfM reconstruction needs an ENU mapping frame, the EO is "
                         f"in {frame!r} (photogrammetry eo --frame enu)")
    ref = {}
    for part in frame.split(";")[1:]:
        k, v = part.split("=", 1)
        ref[k.strip()] = float(v)
    R_cw = to_cv_rotation(eo.matrices())
    shots = {}
    for k, iid in enumerate(eo.image_id):
        shots[iid] = {"rotation": Rotation.from_matrix(R_cw[k]).as_rotvec().tolist(),
                      "translation": (-R_cw[k] @ eo.position[k]).tolist(),
                      "camera": camera_name, "orientation": 1,
                      "capture_time": float(eo.time[k])}
    doc = [{"cameras": {camera_name: camera_to_opensfm(camera)}, "shots": shots,
            "points": {}, "reference_lla": {
                "latitude": ref.get("origin_lat_deg", 0.0),
                "longitude": ref.get("origin_lon_deg", 0.0),
                "altitude": ref.get("origin_h_m", 0.0)}}]
    with atomic_open(path, "w") as fh:
        json.dump(doc, fh, indent=1)


def write_orthority_csv(path, eo, camera_name=None):
    """The exterior-parameter CSV that orthority reads: a header ``filename x y z omega
    phi kappa [camera]`` and one space-separated line per image (angles in deg,
    omega-phi-kappa, ``R = Rx(omega) Ry(phi) Rz(kappa)`` camera to world with the camera
    x right, y up, z backwards, as ours); for an EPSG frame a ``.prj`` beside it with
    the CRS as WKT."""
    from photogrammetry.orientation.exposure import wrapped_deg
    e = eo.in_system("omega-phi-kappa")
    deg = wrapped_deg(e.angles)
    cols = ["filename", "x", "y", "z", "omega", "phi", "kappa"]
    if camera_name:
        cols.append("camera")
    lines = [" ".join(cols)]
    for k, iid in enumerate(e.image_id):
        x, y, z = e.position[k]
        fields = [f'"{iid}"', f"{x:.4f}", f"{y:.4f}", f"{z:.4f}"] + \
            [f"{v:.8f}" for v in deg[k]]
        if camera_name:
            fields.append(f'"{camera_name}"')
        lines.append(" ".join(fields))
    with atomic_open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    frame = str(e.frame).split(";")[0].strip()
    if frame.upper().startswith("EPSG:"):
        from pyproj import CRS
        with atomic_open(os.path.splitext(str(path))[0] + ".prj", "w") as fh:
            fh.write(CRS.from_user_input(frame).to_wkt())
