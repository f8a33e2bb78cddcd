"""Fisheye camera models of the lunar heading: the paper's equisolid lens with its radial
terms, the other ideal fisheye projections and OpenCV's fisheye (Kannala-Brandt) model.

Each model maps the off-axis angle ``theta`` (rad) to the radius ``r`` (px) from the
principal point; ``f`` is the focal length in px:

==========================  =============================================================
``model``                   projection
==========================  =============================================================
``fisheye-equisolid``       ``r = 2 f sin(theta / 2)``, with the paper's eq. (1):
                            ``s = arcsin(r / (2 f))``,
                            ``theta = 2 s + k1 s**2 + k2 s**3 + k3 s**4`` (``radial_k``,
                            rad: they multiply powers of the dimensionless ``s``)
``fisheye-equidistant``     ``r = f theta``
``fisheye-stereographic``   ``r = 2 f tan(theta / 2)``
``fisheye-orthographic``    ``r = f sin(theta)`` (theta <= 90 deg)
``opencv-fisheye``          ``r = f theta_d``, ``theta_d = theta (1 + k1 theta**2 +
                            k2 theta**4 + k3 theta**6 + k4 theta**8)`` (``opencv_k``:
                            OpenCV's ``cv2.fisheye`` ``D``, with ``fx = f``,
                            ``cx, cy`` = the principal point, no skew)
==========================  =============================================================

Non-square pixels (OpenCV's ``fy != fx``): ``focal_length_y_px`` (``fy``; default ``f``)
scales the image's rows, in every model: the radius and azimuth above hold for
``(x, y * f / fy)`` with ``x, y`` the pixel offsets from the principal point.

Camera frame ``c`` (``conventions.md``): x, y along the image axes of the photo
coordinates ``x = (u - u0) * pixel``, ``y = -(v - v0) * pixel`` (x right, y up), z
opposite to the viewing direction.  A pixel with off-axis angle ``theta`` and image
azimuth ``A = atan2(y, x)`` sees the unit direction
``d_c = (sin theta cos A, sin theta sin A, -cos theta)``.  (OpenCV's camera frame is
``(x, -y, -z)`` of this one: y down, z along the view.)  The paper's frame (Zc along
the viewing direction and its eq. (3) quadrant cases, which are ``atan2``) is not used:
the heading is defined on the x axis of this frame (see ``solve``).
"""
from dataclasses import dataclass

import numpy as np

from ins.common import textfiles
from ins.common.errors import InputError
from ins.common.tomlschema import Table, check_keys

__all__ = ["FisheyeCamera", "read_camera", "camera_file_text", "FISHEYE_KEYS", "MODELS"]


#: The lens models of the camera file's ``model`` key.
MODELS = ("fisheye-equisolid", "fisheye-equidistant", "fisheye-stereographic",
          "fisheye-orthographic", "opencv-fisheye")


@dataclass(frozen=True)
class FisheyeCamera:
    """Fisheye camera (see the module for the models).

    Attributes
    ----------
    focal_length_px : float
        Focal length ``f`` in pixels.
    width_px, height_px : int
        Image size, px.
    principal_point_px : tuple of float
        ``(u0, v0)``: column, row of the principal point; pixel centres at integers.
    radial_k : tuple of float
        ``(k1, k2, k3)`` of eq. (1), rad (``fisheye-equisolid`` only).
    pixel_size_mm : float or None
        Pixel pitch, mm (informative: the model works in pixels).
    model : str
        One of `MODELS`.
    opencv_k : tuple of float
        ``(k1, k2, k3, k4)`` of OpenCV's fisheye model (``opencv-fisheye`` only).
    focal_length_y_px : float or None
        ``fy``, px, for non-square pixels (None: ``focal_length_px``).
    """
    focal_length_px: float
    width_px: int
    height_px: int
    principal_point_px: tuple
    radial_k: tuple = (0.0, 0.0, 0.0)
    pixel_size_mm: float | None = None
    model: str = "fisheye-equisolid"
    opencv_k: tuple = (0.0, 0.0, 0.0, 0.0)
    focal_length_y_px: float | None = None

    @property
    def y_scale(self):
        """``fy / f``: the rows' scale against the columns' (1 for square pixels)."""
        fy = self.focal_length_y_px
        return 1.0 if fy is None else fy / self.focal_length_px

    def __post_init__(self):
        if self.model not in MODELS:
            raise ValueError(f"model must be one of {', '.join(MODELS)}, not {self.model!r}")

    def _theta_of_s(self, s):
        k1, k2, k3 = self.radial_k
        return 2 * s + k1 * s**2 + k2 * s**3 + k3 * s**4

    def _kb(self, theta):
        """OpenCV's ``theta_d`` and its derivative in ``theta``."""
        k1, k2, k3, k4 = self.opencv_k
        t2 = theta * theta
        poly = 1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4)))
        dpoly = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))
        return theta * poly, dpoly

    def theta_of_radius(self, r):
        """Off-axis angle (rad) of image radii ``r`` (px) from the principal point."""
        f, r = self.focal_length_px, np.asarray(r, float)
        if self.model == "fisheye-equisolid":
            return self._theta_of_s(np.arcsin(np.clip(r / (2 * f), 0.0, 1.0)))
        if self.model == "fisheye-equidistant":
            return r / f
        if self.model == "fisheye-stereographic":
            return 2 * np.arctan(r / (2 * f))
        if self.model == "fisheye-orthographic":
            return np.arcsin(np.clip(r / f, 0.0, 1.0))
        theta_d = r / f                                    # opencv-fisheye: Newton
        theta = theta_d.copy()
        for _ in range(30):
            g, dg = self._kb(theta)
            step = (g - theta_d) / dg
            theta = theta - step
            if np.all(np.abs(step) < 1e-15):
                break
        return theta

    def radius_of_theta(self, theta):
        """Image radius (px) of off-axis angles ``theta`` (rad); NaN where the model has
        no image (orthographic beyond 90 deg)."""
        f, theta = self.focal_length_px, np.asarray(theta, float)
        if self.model == "fisheye-equisolid":
            s = theta / 2
            k1, k2, k3 = self.radial_k
            for _ in range(30):                           # Newton on eq. (1) for s
                step = (self._theta_of_s(s) - theta) / (2 + 2 * k1 * s + 3 * k2 * s**2
                                                        + 4 * k3 * s**3)
                s = s - step
                if np.all(np.abs(step) < 1e-15):
                    break
            return 2 * f * np.sin(s)
        if self.model == "fisheye-equidistant":
            return f * theta
        if self.model == "fisheye-stereographic":
            return 2 * f * np.tan(theta / 2)
        if self.model == "fisheye-orthographic":
            return np.where(theta <= np.pi / 2, f * np.sin(theta), np.nan)
        return f * self._kb(theta)[0]

    def image_to_direction(self, uv):
        """Unit directions in the camera frame of pixel positions (the inverse model).

        Parameters
        ----------
        uv : array_like, shape (2,) or (n, 2)
            Column ``u`` and row ``v``, px.

        Returns
        -------
        ndarray, shape (3,) or (n, 3)
            ``d_c``, unit vectors in the camera frame.
        """
        uv = np.asarray(uv, dtype=float)
        x = uv[..., 0] - self.principal_point_px[0]
        y = -(uv[..., 1] - self.principal_point_px[1]) / self.y_scale
        theta = self.theta_of_radius(np.hypot(x, y))
        a = np.arctan2(y, x)
        return np.stack([np.sin(theta) * np.cos(a), np.sin(theta) * np.sin(a),
                         -np.cos(theta)], axis=-1)

    def direction_to_image(self, d_c):
        """Pixel positions of camera-frame directions (the forward model).

        Parameters
        ----------
        d_c : array_like, shape (3,) or (n, 3)
            Directions in the camera frame (any length).

        Returns
        -------
        ndarray, shape (2,) or (n, 2)
            ``(u, v)``, px.
        """
        d = np.asarray(d_c, dtype=float)
        theta = np.arctan2(np.hypot(d[..., 0], d[..., 1]), -d[..., 2])
        a = np.arctan2(d[..., 1], d[..., 0])
        r = self.radius_of_theta(theta)
        u = self.principal_point_px[0] + r * np.cos(a)
        v = self.principal_point_px[1] - r * np.sin(a) * self.y_scale
        return np.stack([u, v], axis=-1)

    def direction_jacobian(self, uv, step_px=1e-3):
        """Derivative of ``image_to_direction`` with respect to ``(u, v)``, shape (n, 3, 2), 1/px."""
        uv = np.atleast_2d(np.asarray(uv, dtype=float))
        J = np.empty((len(uv), 3, 2))
        for k in range(2):
            e = np.zeros(2)
            e[k] = step_px
            J[:, :, k] = (self.image_to_direction(uv + e)
                          - self.image_to_direction(uv - e)) / (2 * step_px)
        return J


#: Keys of a fisheye camera file (one section ``[camera]``); any other key is refused
#: (:mod:`ins.common.tomlschema`).  Optional: ``principal_point_px`` (the image centre),
#: ``radial_k`` (zeros; equisolid only), ``opencv_k`` (zeros; opencv-fisheye only),
#: ``pixel_size_mm`` (needed only with ``focal_length_mm``).
FISHEYE_KEYS = {"camera": ("model", "focal_length_px", "focal_length_mm", "pixel_size_mm",
                           "width_px", "height_px", "principal_point_px", "radial_k",
                           "opencv_k", "focal_length_y_px")}


def read_camera(path):
    """Read a fisheye camera file (TOML).

    ``[camera]`` keys: ``model`` (one of `MODELS`); ``focal_length_px``, or
    ``focal_length_mm`` with ``pixel_size_mm``; ``width_px``, ``height_px``;
    ``principal_point_px = [u0, v0]`` (default: the image centre); ``radial_k =
    [k1, k2, k3]`` in rad (eq. 1; default zeros; ``fisheye-equisolid`` only);
    ``opencv_k = [k1, k2, k3, k4]`` (OpenCV's fisheye ``D``; default zeros;
    ``opencv-fisheye`` only); ``focal_length_y_px`` (OpenCV's ``fy`` for non-square
    pixels; default the focal length).  Any other section or key is an error
    (:data:`FISHEYE_KEYS`).

    Raises
    ------
    InputError
        Naming the file and the key, for a missing, unknown or malformed value.
    """
    path = str(path)
    doc = textfiles.read_toml(path, "a TOML fisheye camera file with [camera]")
    check_keys(doc, FISHEYE_KEYS, path)
    if "camera" not in doc:
        raise InputError("[camera]: missing required section (model = "
                         "\"fisheye-equisolid\", focal_length_px, width_px, height_px)", path)
    cam = Table(doc["camera"], "camera", path, FISHEYE_KEYS["camera"], FISHEYE_KEYS)
    model = cam.string("model", unit="one of " + ", ".join(MODELS))
    if model not in MODELS:
        raise cam.error("model", f"expected one of {', '.join(MODELS)}, got {model!r}")
    width = cam.number("width_px", unit="integer px > 0", lo=1, integer=True)
    height = cam.number("height_px", unit="integer px > 0", lo=1, integer=True)
    pixel = cam.number("pixel_size_mm", None, "mm > 0", lo=0.0, lo_open=True)
    cam.either("focal_length_px", "focal_length_mm")
    if cam.has("focal_length_px"):
        f_px = cam.number("focal_length_px", unit="px > 0", lo=0.0, lo_open=True)
    elif cam.has("focal_length_mm"):
        if pixel is None:
            raise cam.error("pixel_size_mm", "missing: needed with focal_length_mm", "mm > 0")
        f_px = cam.number("focal_length_mm", unit="mm > 0", lo=0.0, lo_open=True) / pixel
    else:
        raise cam.error("focal_length_px", "missing required key (or focal_length_mm with "
                        "pixel_size_mm)", "px > 0")
    pp = cam.numbers("principal_point_px", ((width - 1) / 2, (height - 1) / 2),
                     "px (u0, v0)", length=2, scalar=False)
    k = cam.numbers("radial_k", (0.0, 0.0, 0.0), "rad (k1, k2, k3 of eq. 1)", length=3,
                    scalar=False)
    kb = cam.numbers("opencv_k", (0.0, 0.0, 0.0, 0.0), "k1, k2, k3, k4 of OpenCV's fisheye D",
                     length=4, scalar=False)
    fy = cam.number("focal_length_y_px", None, "px > 0", lo=0.0, lo_open=True)
    if fy is not None and not 0.5 < fy / f_px < 2.0:
        raise cam.error("focal_length_y_px", f"{fy!r} px against a focal length of "
                        f"{f_px!r} px: a pixel aspect outside 0.5-2", "px > 0")
    for key, owner in (("radial_k", "fisheye-equisolid"), ("opencv_k", "opencv-fisheye")):
        if cam.has(key) and model != owner:
            raise cam.error(key, f"applies to model = \"{owner}\" only, not {model!r}")
    cam.finish()
    return FisheyeCamera(focal_length_px=f_px, width_px=int(width), height_px=int(height),
                         principal_point_px=pp, radial_k=k, pixel_size_mm=pixel, model=model,
                         opencv_k=kb, focal_length_y_px=fy)


def camera_file_text(camera, title="Fisheye camera"):
    """The text of a camera file that `read_camera` reads back as ``camera``."""
    def num(x):
        return repr(float(x))
    lines = [f"# {title}.", "[camera]", f'model = "{camera.model}"',
             f"focal_length_px = {num(camera.focal_length_px)}"]
    if camera.focal_length_y_px is not None:
        lines.append(f"focal_length_y_px = {num(camera.focal_length_y_px)}   # fy")
    if camera.pixel_size_mm is not None:
        lines.append(f"pixel_size_mm = {num(camera.pixel_size_mm)}")
    lines += [f"width_px = {int(camera.width_px)}", f"height_px = {int(camera.height_px)}",
              "principal_point_px = [" + ", ".join(map(num, camera.principal_point_px))
              + "]   # (column u, row v); pixel centres at integers"]
    if camera.model == "fisheye-equisolid":
        lines.append("radial_k = [" + ", ".join(map(num, camera.radial_k))
                     + "]   # k1, k2, k3 of eq. (1), rad")
    if camera.model == "opencv-fisheye":
        lines.append("opencv_k = [" + ", ".join(map(num, camera.opencv_k))
                     + "]   # k1, k2, k3, k4 of OpenCV's fisheye D")
    return "\n".join(lines) + "\n"
