"""COLMAP models: cameras and tie points in (pycolmap, extra ``colmap``); refined EO out
as a COLMAP text model.

COLMAP's pixel coordinates put the centre of the top-left pixel at ``(0.5, 0.5)``
(ours at ``(0, 0)``: ``u = u_colmap - 0.5``).  Its camera is the computer-vision one
(x right, y down, z along the view); an image's pose ``cam_from_world`` ``(R_cw, t)``
maps a world point ``X`` to ``R_cw X + t``, the centre is ``-R_cw^T t`` and
``C_mc = R_cw^T diag(1, -1, -1)`` (:func:`photogrammetry.orientation.rotation.from_cv_rotation`).

Camera models read (``params`` in COLMAP's order), all with OpenCV's distortion of the
normalised coordinates ``x_n = x/z``, ``y_n = y/z``:

=============== ==============================================
SIMPLE_PINHOLE  f, cx, cy
PINHOLE         fx, fy, cx, cy (fx = fy)
SIMPLE_RADIAL   f, cx, cy, k
RADIAL          f, cx, cy, k1, k2
OPENCV          fx, fy, cx, cy, k1, k2, p1, p2 (fx = fy)
FULL_OPENCV     fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6 (fx = fy, k4 = k5 = k6 = 0)
=============== ==============================================

``x_d = x_n (1 + k1 r2 + k2 r2^2 + k3 r2^3) + 2 p1 x_n y_n + p2 (r2 + 2 x_n^2)``,
``y_d = y_n (...) + p1 (r2 + 2 y_n^2) + 2 p2 x_n y_n``, pixel ``(fx x_d + cx, fy y_d + cy)``:
the OpenSfM "brown" polynomial, so the conversion into the camera file is the same
(:mod:`photogrammetry.sfm.opensfm`): ``f = fx * pixel_size``, ``k1' = k1/f^2``,
``k2' = k2/f^4``, ``k3' = k3/f^6``, ``p1' = p2/f``, ``p2' = -p1/f``,
``(u0, v0) = (cx - 0.5, cy - 0.5)``.

The text model written (:func:`write_colmap_text`): ``cameras.txt`` (one OPENCV camera,
or FULL_OPENCV when k3 is not 0), ``images.txt`` (``IMAGE_ID QW QX QY QZ TX TY TZ
CAMERA_ID NAME`` with the quaternion of ``R_cw``, then an empty line of 2-D points),
``points3D.txt`` (empty): the poses COLMAP's ``point_triangulator`` takes as known.
"""
import os

import numpy as np

from ins.common.errors import InputError
from ins.common.fileio import atomic_open
from photogrammetry.orientation.camera import FrameCamera
from photogrammetry.orientation.exposure import ExposureOrientation
from photogrammetry.orientation.rotation import (
    check_system,
    from_cv_rotation,
    matrix_to_angles,
    to_cv_rotation,
)

__all__ = ["camera_from_colmap", "camera_to_colmap", "read_colmap", "ColmapModel",
           "write_colmap_text", "COLMAP_FRAME"]

#: The ``# frame =`` value of an EO in a COLMAP model's own world frame.
COLMAP_FRAME = "colmap model world frame (as the model's georegistration left it)"
_EXTRA = "pip install 'insphoto[colmap]'"


def _need_pycolmap():
    try:
        import pycolmap
    except ImportError:
        raise InputError(f"reading a COLMAP model needs pycolmap: {_EXTRA}") from None
    return pycolmap


#: Plausible magnitudes: an image side (px), a focal length / principal point (px), a
#: distortion coefficient, a world coordinate (m).
MAX_SIDE_PX = 200_000
MAX_FOCAL_PX = 1e7
MAX_COEFF = 1e3
MAX_WORLD_M = 1e7


def camera_from_colmap(model, width, height, params, pixel_size_mm=0.01, where="camera"):
    """Our :class:`FrameCamera` of a COLMAP camera (module docstring).

    Raises InputError naming `where` for a size or parameter that is not finite or not
    plausible (a focal length <= 0, a principal point far outside the image)."""
    try:
        p = [float(v) for v in params]
    except (TypeError, ValueError):
        raise InputError(f"{where}: parameters must be numbers") from None
    if not all(0 < v <= MAX_SIDE_PX and v == int(v) for v in (float(width), float(height))):
        raise InputError(f"{where}: width, height = {width}, {height} px are not image "
                         f"sizes (1 to {MAX_SIDE_PX} px)")
    bad = [i for i, v in enumerate(p) if not (abs(v) <= MAX_FOCAL_PX)]
    if bad:
        raise InputError(f"{where}: {model} parameter {bad[0] + 1} = {p[bad[0]]:g} is not "
                         f"finite or not plausible (|value| <= {MAX_FOCAL_PX:g})")
    zeros = {"SIMPLE_PINHOLE": 3, "PINHOLE": 4, "SIMPLE_RADIAL": 4, "RADIAL": 5,
             "OPENCV": 8, "FULL_OPENCV": 12}
    if model not in zeros:
        raise InputError(f"{where}: COLMAP model {model} is not read ("
                         + ", ".join(zeros) + ")")
    if len(p) != zeros[model]:
        raise InputError(f"{where}: {model} has {zeros[model]} parameters, got {len(p)}")
    k1 = k2 = k3 = p1 = p2 = 0.0
    if model in ("SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL"):
        fx = fy = p[0]
        cx, cy = p[1], p[2]
        if model == "SIMPLE_RADIAL":
            k1 = p[3]
        elif model == "RADIAL":
            k1, k2 = p[3], p[4]
    else:
        fx, fy, cx, cy = p[:4]
        if model in ("OPENCV", "FULL_OPENCV"):
            k1, k2, p1, p2 = p[4:8]
        if model == "FULL_OPENCV":
            k3 = p[8]
            if any(p[9:12]):
                raise InputError(f"{where}: FULL_OPENCV with k4, k5, k6 = {p[9:12]} (the "
                                 "rational model) is not the frame camera's polynomial")
    if abs(fx - fy) > 1e-9 * max(abs(fx), 1.0):
        raise InputError(f"{where}: fx {fx} != fy {fy}; the frame camera has square pixels")
    if not fx > 1e-3:
        raise InputError(f"{where}: focal length {fx:g} px must be > 0 px")
    if not (abs(cx) <= 2 * MAX_SIDE_PX and abs(cy) <= 2 * MAX_SIDE_PX):
        raise InputError(f"{where}: principal point {cx:g}, {cy:g} px is not plausible")
    if not all(abs(v) <= MAX_COEFF for v in (k1, k2, k3, p1, p2)):
        raise InputError(f"{where}: distortion coefficients k1, k2, k3, p1, p2 = "
                         + ", ".join(f"{v:g}" for v in (k1, k2, k3, p1, p2))
                         + f" are not plausible (|k| <= {MAX_COEFF:g})")
    f = fx * pixel_size_mm
    return FrameCamera(f, pixel_size_mm, int(width), int(height), (cx - 0.5, cy - 0.5),
                       (k1 / f ** 2, k2 / f ** 4, k3 / f ** 6), (p2 / f, -p1 / f))


def camera_to_colmap(camera):
    """``(model, params)`` of COLMAP for our camera (inverse of :func:`camera_from_colmap`)."""
    f = camera.focal_length_mm
    fp = f / camera.pixel_size_mm
    k1, k2, k3 = camera.radial_k
    p1, p2 = camera.tangential_p
    u0, v0 = camera.principal_point_px
    base = [fp, fp, u0 + 0.5, v0 + 0.5, k1 * f ** 2, k2 * f ** 4, -p2 * f, p1 * f]
    if k3:
        return "FULL_OPENCV", base + [k3 * f ** 6, 0.0, 0.0, 0.0]
    return "OPENCV", base


class ColmapModel:
    """A COLMAP model read through pycolmap.

    Attributes
    ----------
    cameras : dict camera id -> FrameCamera
    image_camera : dict image id (name without extension) -> camera id
    eo : ExposureOrientation
        Registered images, in the model's world frame (:data:`COLMAP_FRAME`).
    image_id, point_id : list of str
    xy_mm : ndarray (k, 2)
        Observations of triangulated points: observed photo coordinates, mm (none when
        the model has no points: ``no_tiepoints`` says why).
    no_tiepoints : str or None
        Why the model gives no tie point (points3D file missing, or empty), else None.
    """

    def __init__(self, cameras, image_camera, eo, image_id, point_id, xy_mm,
                 no_tiepoints=None):
        self.cameras, self.image_camera, self.eo = cameras, image_camera, eo
        self.image_id, self.point_id, self.xy_mm = image_id, point_id, xy_mm
        self.no_tiepoints = no_tiepoints


def read_colmap(path, system="omega-phi-kappa", pixel_size_mm=0.01):
    """Read a COLMAP model folder (binary or text) with pycolmap.

    A model without its ``points3D`` file (cameras and poses only) is read too, from a
    temporary copy with an empty one; observations are kept only for points the model
    holds (an image's reference to an absent point is ignored).

    Returns
    -------
    ColmapModel
    """
    path = str(path)
    check_system(system)
    if not os.path.isdir(path):
        raise InputError("not a folder (a COLMAP model: cameras, images, points3D .bin or "
                         ".txt)", path=path)
    from photogrammetry.sfm.colmap_bin import check_binary_model
    check_binary_model(path)
    rec, missing = _load_model(path)
    cameras = {cid: camera_from_colmap(c.model.name, c.width, c.height, c.params,
                                       pixel_size_mm, f"{path}: camera {cid}")
               for cid, c in rec.cameras.items()}
    ids, pos, R, image_camera = [], [], [], {}
    img_id, pt_id, xy = [], [], []
    points = set(rec.points3D)
    for iid in sorted(rec.images, key=lambda k: rec.images[k].name):
        im = rec.images[iid]
        if not im.has_pose:
            continue
        cfw = im.cam_from_world() if callable(im.cam_from_world) else im.cam_from_world
        q = np.asarray(cfw.rotation.quat, float)
        t_c = np.asarray(cfw.translation, float)
        where = f"image {im.name!r}"
        if not (np.all(np.isfinite(q)) and abs(float(np.linalg.norm(q)) - 1.0) < 1e-3):
            raise InputError(f"{where}: the rotation quaternion is not finite or not of unit "
                             "norm", path=path)
        if not np.all(np.abs(t_c) <= MAX_WORLD_M):
            raise InputError(f"{where}: translation " + ", ".join(f"{v:g}" for v in t_c)
                             + f" m is not finite or beyond {MAX_WORLD_M:g} m", path=path)
        R_cw = np.asarray(cfw.rotation.matrix(), float)
        name = os.path.splitext(im.name)[0]
        ids.append(name)
        pos.append(-R_cw.T @ t_c)
        R.append(from_cv_rotation(R_cw))
        image_camera[name] = im.camera_id
        cam = cameras[im.camera_id]
        for p in im.points2D:
            if p.has_point3D() and p.point3D_id in points:
                uv = np.asarray(p.xy, float)
                if not np.all(np.abs(uv) <= MAX_SIDE_PX):
                    raise InputError(f"{where}: 2-D point " + ", ".join(f"{v:g}" for v in uv)
                                     + " px is not finite or far outside the image",
                                     path=path)
                img_id.append(name)
                pt_id.append(str(p.point3D_id))
                xy.append(cam.pixel_to_photo(uv - 0.5))
    if not ids:
        raise InputError("no registered image in the model", path=path)
    eo = ExposureOrientation(ids, np.zeros(len(ids)), np.array(pos),
                             matrix_to_angles(np.array(R), system), system, COLMAP_FRAME)
    note = None
    if missing:
        note = f"the model has no {missing} file"
    elif not img_id:
        note = "the model's points3D are empty (no triangulated point)"
    return ColmapModel(cameras, image_camera, eo, img_id, pt_id,
                       np.array(xy).reshape(-1, 2), note)


def _load_model(path):
    """``(pycolmap.Reconstruction, missing)``: a model whose points3D file is missing is
    read from a temporary copy with an empty one (``missing`` then names the file)."""
    import shutil
    import tempfile
    pycolmap = _need_pycolmap()
    missing = None
    for ext, empty in ((".bin", b"\0" * 8), (".txt", b"")):
        have = [os.path.isfile(os.path.join(path, n + ext)) for n in ("cameras", "images")]
        if all(have) and not os.path.isfile(os.path.join(path, "points3D" + ext)):
            missing = "points3D" + ext
            break
    try:
        if missing is None:
            return pycolmap.Reconstruction(path), None
        with tempfile.TemporaryDirectory(prefix="insphoto-colmap-") as tmp:
            for name in os.listdir(path):
                if name.endswith(ext) and os.path.isfile(os.path.join(path, name)):
                    shutil.copyfile(os.path.join(path, name), os.path.join(tmp, name))
            with open(os.path.join(tmp, missing), "wb") as fh:
                fh.write(empty)
            return pycolmap.Reconstruction(tmp), missing
    except Exception as exc:
        raise InputError(f"pycolmap cannot read the model: {exc}", path=path) from None


def write_colmap_text(folder, eo, camera, names=None):
    """Write a COLMAP text model (module docstring) of an EO and one camera into an
    existing folder (files written atomically).

    Parameters
    ----------
    folder : str
    eo : ExposureOrientation
    camera : FrameCamera
    names : sequence of str, optional
        Image file names (default: the EO ids).
    """
    from scipy.spatial.transform import Rotation
    names = list(names) if names is not None else list(eo.image_id)
    model, params = camera_to_colmap(camera)
    with atomic_open(os.path.join(folder, "cameras.txt"), "w") as fh:
        fh.write("# Camera list with one line of data per camera:\n"
                 "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
                 f"1 {model} {camera.width_px} {camera.height_px} "
                 + " ".join(repr(float(v)) for v in params) + "\n")
    R_cw = to_cv_rotation(eo.matrices())
    lines = ["# Image list with two lines of data per image:",
             "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME",
             "#   POINTS2D[] as (X, Y, POINT3D_ID)",
             f"# refined exterior orientation, world frame: {eo.frame}"]
    for k, name in enumerate(names):
        x, y, z, w = Rotation.from_matrix(R_cw[k]).as_quat()
        t = -R_cw[k] @ eo.position[k]
        q = " ".join(repr(float(v)) for v in (w, x, y, z, *t))
        lines.append(f"{k + 1} {q} 1 {name}")
        lines.append("")
    with atomic_open(os.path.join(folder, "images.txt"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    with atomic_open(os.path.join(folder, "points3D.txt"), "w") as fh:
        fh.write("# 3D point list (empty: poses only)\n")
