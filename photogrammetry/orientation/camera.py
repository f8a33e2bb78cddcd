"""Frame camera: interior orientation, Brown distortion, mounting on the IMU; camera file.

Pixel convention (``docs/interfaces.md``): pixel centres at integer ``(u, v)`` = (column,
row), ``(0, 0)`` the centre of the top-left pixel, so the image covers
``[-0.5, width - 0.5] x [-0.5, height - 0.5]``.  Photo coordinates in mm from the
principal point, x right and y up on the image: ``x = (u - u0) * pixel_size``,
``y = -(v - v0) * pixel_size``.  The camera frame ``c`` has x, y along these axes and z
opposite to the viewing direction; the ray of an ideal photo point is ``(x, y, -f)``.

Distortion (Brown), ideal ``(x, y)`` to observed, ``r^2 = x^2 + y^2`` (mm)::

    x_d = x + x (k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 x^2) + 2 p2 x y
    y_d = y + y (k1 r^2 + k2 r^4 + k3 r^6) + p2 (r^2 + 2 y^2) + 2 p1 x y

The fisheye model of the lunar camera lives in ``photogrammetry.lunar``.
"""
import math
from dataclasses import dataclass, field

import numpy as np
import tomli_w

from ins.common import textfiles
from ins.common.errors import InputError
from ins.common.fileio import atomic_open
from ins.common.tomlschema import REQUIRED, Table, check_keys
from photogrammetry.orientation.rotation import boresight_matrix

__all__ = ["FrameCamera", "CameraMounting", "read_camera", "write_camera", "NADIR_AXES",
           "CAMERA_KEYS"]

#: Nominal axes of a nadir-looking camera with x_c forward: ``C_bc`` rows.
NADIR_AXES = ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0))

_UNDISTORT_TOL_MM = 1e-9
_UNDISTORT_ITER = 50


def _floats(value, name, n, unit):
    try:
        t = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be {n} numbers ({unit}), got {value!r}") from None
    if len(t) != n or not all(math.isfinite(v) for v in t):
        raise InputError(f"{name} must be {n} finite numbers ({unit}), got {value!r}")
    return t


def _xy(a, name):
    a = np.asarray(a, dtype=float)
    if a.ndim == 0 or a.shape[-1] != 2:
        raise ValueError(f"{name} must have shape (2,) or (..., 2), got {a.shape}")
    return a


@dataclass(frozen=True)
class FrameCamera:
    """Interior orientation of a frame camera.

    Parameters
    ----------
    focal_length_mm : float
        Principal distance f, mm (> 0).
    pixel_size_mm : float
        Pixel pitch, mm (> 0, square pixels).
    width_px, height_px : int
        Image format, pixels (> 0).
    principal_point_px : (float, float)
        Principal point ``(u0, v0)`` = (column, row), pixels.
    radial_k : (float, float, float)
        k1 (mm^-2), k2 (mm^-4), k3 (mm^-6).
    tangential_p : (float, float)
        p1, p2 (mm^-1).
    """

    focal_length_mm: float
    pixel_size_mm: float
    width_px: int
    height_px: int
    principal_point_px: tuple
    radial_k: tuple = (0.0, 0.0, 0.0)
    tangential_p: tuple = (0.0, 0.0)

    def __post_init__(self):
        for name, unit in (("focal_length_mm", "mm"), ("pixel_size_mm", "mm")):
            v = getattr(self, name)
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise InputError(f"{name} must be a number ({unit}), got {v!r}") from None
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"{name} must be positive and finite ({unit}), got {v!r}")
            object.__setattr__(self, name, v)
        for name in ("width_px", "height_px"):
            v = getattr(self, name)
            if isinstance(v, bool) or not float(v).is_integer() or v <= 0:
                raise InputError(f"{name} must be a positive integer (pixels), got {v!r}")
            object.__setattr__(self, name, int(v))
        object.__setattr__(self, "principal_point_px",
                           _floats(self.principal_point_px, "principal_point_px", 2, "pixels"))
        object.__setattr__(self, "radial_k",
                           _floats(self.radial_k, "radial_k", 3, "mm^-2, mm^-4, mm^-6"))
        object.__setattr__(self, "tangential_p",
                           _floats(self.tangential_p, "tangential_p", 2, "mm^-1"))

    @property
    def has_distortion(self):
        return any(self.radial_k) or any(self.tangential_p)

    def pixel_to_photo(self, uv):
        """Pixel ``(u, v)`` (..., 2) to photo coordinates ``(x, y)`` in mm (no undistortion)."""
        uv = _xy(uv, "uv")
        u0, v0 = self.principal_point_px
        return np.stack([(uv[..., 0] - u0) * self.pixel_size_mm,
                         -(uv[..., 1] - v0) * self.pixel_size_mm], axis=-1)

    def photo_to_pixel(self, xy):
        """Photo coordinates ``(x, y)`` mm (..., 2) to pixel ``(u, v)``."""
        xy = _xy(xy, "xy")
        u0, v0 = self.principal_point_px
        return np.stack([u0 + xy[..., 0] / self.pixel_size_mm,
                         v0 - xy[..., 1] / self.pixel_size_mm], axis=-1)

    def _delta(self, x, y):
        k1, k2, k3 = self.radial_k
        p1, p2 = self.tangential_p
        r2 = x * x + y * y
        radial = r2 * (k1 + r2 * (k2 + r2 * k3))
        return (x * radial + p1 * (r2 + 2 * x * x) + 2 * p2 * x * y,
                y * radial + p2 * (r2 + 2 * y * y) + 2 * p1 * x * y)

    def distort(self, xy_ideal):
        """Ideal photo coordinates (mm, (..., 2)) to observed (distorted) ones."""
        xy = _xy(xy_ideal, "xy_ideal")
        dx, dy = self._delta(xy[..., 0], xy[..., 1])
        return np.stack([xy[..., 0] + dx, xy[..., 1] + dy], axis=-1)

    def undistort(self, xy_observed):
        """Observed photo coordinates (mm, (..., 2)) to ideal ones.

        Newton iteration on ``distort(xy) = xy_observed`` with the analytic Jacobian,
        until every point moves less than 1e-9 mm.

        Raises
        ------
        ValueError
            If the iteration does not converge, or converges beyond the fold of the
            polynomial (Jacobian determinant or ``1 + k1 r^2 + ...`` not positive).
        """
        obs = _xy(xy_observed, "xy_observed")
        if not self.has_distortion:
            return obs.copy()
        k1, k2, k3 = self.radial_k
        p1, p2 = self.tangential_p
        x, y = obs[..., 0].copy(), obs[..., 1].copy()
        for _ in range(_UNDISTORT_ITER):
            dx, dy = self._delta(x, y)
            fx, fy = x + dx - obs[..., 0], y + dy - obs[..., 1]
            r2 = x * x + y * y
            rad = r2 * (k1 + r2 * (k2 + r2 * k3))
            drad = 2 * (k1 + r2 * (2 * k2 + 3 * r2 * k3))   # d(rad)/d(r2) * 2
            j11 = 1 + rad + x * x * drad + 6 * p1 * x + 2 * p2 * y
            j22 = 1 + rad + y * y * drad + 6 * p2 * y + 2 * p1 * x
            j12 = x * y * drad + 2 * p1 * y + 2 * p2 * x
            det = j11 * j22 - j12 * j12
            sx = (j22 * fx - j12 * fy) / det
            sy = (j11 * fy - j12 * fx) / det
            x, y = x - sx, y - sy
            if np.all(np.hypot(sx, sy) < _UNDISTORT_TOL_MM):
                if np.any((det <= 0) | (1 + rad <= 0)):
                    raise ValueError("undistortion: a point lies beyond the fold of the "
                                     "distortion polynomial (not invertible there)")
                return np.stack([x, y], axis=-1)
        raise ValueError(f"undistortion did not converge to {_UNDISTORT_TOL_MM} mm in "
                         f"{_UNDISTORT_ITER} iterations (distortion not invertible there)")

    def rays(self, xy_ideal):
        """Camera-frame rays ``(x, y, -f)`` in mm of ideal photo points, shape (..., 3)."""
        xy = _xy(xy_ideal, "xy_ideal")
        return np.concatenate([xy, np.full(xy.shape[:-1] + (1,), -self.focal_length_mm)],
                              axis=-1)

    def inside(self, uv, margin_px=0):
        """Whether pixels lie on the image (extent -0.5 .. size - 0.5) with a margin."""
        uv = _xy(uv, "uv")
        m = float(margin_px)
        return ((uv[..., 0] >= -0.5 + m) & (uv[..., 0] <= self.width_px - 0.5 - m)
                & (uv[..., 1] >= -0.5 + m) & (uv[..., 1] <= self.height_px - 0.5 - m))


def _readonly(a):
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class CameraMounting:
    """How the camera sits on the IMU body (FRD).

    Parameters
    ----------
    axes : array_like, shape (3, 3)
        Nominal ``C_bc`` (camera axes to body), a proper rotation (orthonormal,
        det +1), e.g. :data:`NADIR_AXES`.
    lever_arm_m : array_like, shape (3,)
        IMU centre to the perspective centre, in ``b`` (FRD), m.
    boresight_rad : array_like, shape (3,)
        Boresight misalignment ``(rx, ry, rz)``, rad.
    """

    axes: np.ndarray = field(default_factory=lambda: np.array(NADIR_AXES))
    lever_arm_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    boresight_rad: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self):
        try:
            axes = _readonly(self.axes)
        except (TypeError, ValueError):
            raise InputError(f"axes must be a 3x3 rotation matrix, got {self.axes!r}") from None
        if axes.shape != (3, 3) or not np.all(np.isfinite(axes)):
            raise InputError(f"axes must be a finite 3x3 matrix, got shape {axes.shape}")
        ortho = np.abs(axes @ axes.T - np.eye(3)).max()
        if ortho > 1e-6:
            raise InputError(f"axes must be orthonormal (rows of unit length, mutually "
                             f"perpendicular); |A A^T - I| = {ortho:.3g}")
        if np.linalg.det(axes) < 0:
            raise InputError("axes must be a proper rotation (det = +1), got a reflection "
                             "(det = -1): one camera axis is reversed")
        object.__setattr__(self, "axes", axes)
        for name, unit in (("lever_arm_m", "m"), ("boresight_rad", "rad")):
            v = getattr(self, name)
            a = _readonly(_floats(np.ravel(v), name, 3, unit))
            object.__setattr__(self, name, a)

    @property
    def C_bc(self):
        """Camera frame to IMU body: ``axes @ boresight_matrix(boresight_rad)``, (3, 3)."""
        return self.axes @ boresight_matrix(self.boresight_rad)

    def __eq__(self, other):
        if not isinstance(other, CameraMounting):
            return NotImplemented
        return all(np.array_equal(getattr(self, n), getattr(other, n))
                   for n in ("axes", "lever_arm_m", "boresight_rad"))

    __hash__ = None


# --------------------------------------------------------------------------
# camera file (TOML)

#: Sections and keys of a camera file (``docs/interfaces.md``); any other key is refused
#: (:mod:`ins.common.tomlschema`).  Optional: ``[camera] model`` ("frame"), ``radial_k`` and
#: ``tangential_p`` (zeros) and the whole ``[mounting]`` (:data:`NADIR_AXES`, zero lever
#: arm, zero boresight).
CAMERA_KEYS = {
    "camera": ("model", "focal_length_mm", "pixel_size_mm", "width_px", "height_px",
               "principal_point_px", "radial_k", "tangential_p"),
    "mounting": ("axes", "lever_arm_m", "boresight_deg"),
}


def read_camera(path):
    """Read a camera file (``docs/interfaces.md``): ``(FrameCamera, CameraMounting)``.

    Strict: an unknown section or key (``lever_arm`` for ``lever_arm_m``, a table
    ``[mount]``) is an error, never silently replaced by the default.  ``[mounting]`` is
    optional: nadir axes :data:`NADIR_AXES`, zero lever arm, zero boresight.

    Raises
    ------
    InputError
        Naming the file and the ``[section] key`` and the expected unit.
    """
    path = str(path)
    doc = textfiles.read_toml(path, "a TOML camera file with [camera] and [mounting]")
    check_keys(doc, CAMERA_KEYS, path)
    if "camera" not in doc:
        raise InputError("[camera]: missing required section (focal_length_mm, "
                         "pixel_size_mm, width_px, height_px, principal_point_px)", path=path)
    cam = Table(doc["camera"], "camera", path, CAMERA_KEYS["camera"], CAMERA_KEYS)
    model = cam.string("model", "frame", '"frame"')
    if model != "frame":
        raise InputError(f"[camera] model = {model!r}: only 'frame' is read here "
                         "(fisheye cameras: photogrammetry.lunar)", path=path)
    kwargs = dict(
        focal_length_mm=cam.number("focal_length_mm", unit="mm > 0"),
        pixel_size_mm=cam.number("pixel_size_mm", unit="mm > 0"),
        width_px=cam.number("width_px", unit="integer px > 0", integer=True),
        height_px=cam.number("height_px", unit="integer px > 0", integer=True),
        principal_point_px=cam.numbers("principal_point_px", REQUIRED, "px (u0, v0)",
                                       length=2, scalar=False),
        radial_k=cam.numbers("radial_k", (0.0, 0.0, 0.0), "k1 mm^-2, k2 mm^-4, k3 mm^-6",
                             length=3, scalar=False),
        tangential_p=cam.numbers("tangential_p", (0.0, 0.0), "p1, p2 mm^-1", length=2,
                                 scalar=False))
    cam.finish()
    try:
        camera = FrameCamera(**kwargs)
    except InputError as exc:
        raise InputError(f"[camera] {exc.reason}", path=path) from None
    mnt = Table(doc.get("mounting"), "mounting", path, CAMERA_KEYS["mounting"], CAMERA_KEYS)
    axes = mnt.matrix("axes", NADIR_AXES, (3, 3), "rows of C_bc, a rotation matrix")
    lever = mnt.numbers("lever_arm_m", (0.0, 0.0, 0.0), "m, body FRD", length=3,
                        scalar=False)
    bore = mnt.numbers("boresight_deg", (0.0, 0.0, 0.0), "deg (rx, ry, rz)", length=3,
                       scalar=False)
    mnt.finish()
    try:
        mounting = CameraMounting(axes=axes, lever_arm_m=lever, boresight_rad=np.deg2rad(bore))
    except InputError as exc:
        raise InputError(f"[mounting] {exc.reason}", path=path) from None
    return camera, mounting


def camera_to_dict(camera, mounting=None):
    """The camera file's content as nested dicts (TOML-ready)."""
    doc = {"camera": {
        "model": "frame",
        "focal_length_mm": camera.focal_length_mm,
        "pixel_size_mm": camera.pixel_size_mm,
        "width_px": camera.width_px,
        "height_px": camera.height_px,
        "principal_point_px": list(camera.principal_point_px),
        "radial_k": list(camera.radial_k),
        "tangential_p": list(camera.tangential_p)}}
    if mounting is not None:
        doc["mounting"] = {
            "axes": [[float(v) for v in row] for row in mounting.axes],
            "lever_arm_m": [float(v) for v in mounting.lever_arm_m],
            "boresight_deg": [float(v) for v in np.rad2deg(mounting.boresight_rad)]}
    return doc


def write_camera(path, camera, mounting=None):
    """Write a camera file (TOML, atomically); ``read_camera`` gives the same values back
    (the boresight goes through degrees: equal to rounding)."""
    text = tomli_w.dumps(camera_to_dict(camera, mounting))
    with atomic_open(path, "wb") as f:
        f.write(text.encode("utf-8"))
