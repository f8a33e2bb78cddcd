"""Equisolid fisheye camera with the radial terms of the lunar paper's eq. (1).

Model (pixel units; ``r`` and ``f`` in px, the angles in rad)::

    s       = arcsin(r / (2 f))
    theta_c = 2 s + k1 s**2 + k2 s**3 + k3 s**4         (eq. 1)

so ``k1, k2, k3`` are in rad (they multiply powers of the dimensionless ``s``); with
``k = 0`` this is the ideal equisolid projection ``r = 2 f sin(theta / 2)``.

Camera frame ``c`` (``conventions.md``): x, y along the image axes of the photo
coordinates ``x = (u - u0) * pixel``, ``y = -(v - v0) * pixel`` (x right, y up), z
opposite to the viewing direction.  A pixel with off-axis angle ``theta`` and image
azimuth ``A = atan2(y, x)`` sees the unit direction
``d_c = (sin theta cos A, sin theta sin A, -cos theta)``.  The paper's frame (Zc along
the viewing direction and its eq. (3) quadrant cases, which are ``atan2``) is not used:
the heading is defined on the x axis of this frame (see ``solve``).
"""
from dataclasses import dataclass

import numpy as np

from ins import textfiles
from ins.errors import InputError
from ins.tomlschema import Table, check_keys

__all__ = ["FisheyeCamera", "read_camera", "FISHEYE_KEYS"]


@dataclass(frozen=True)
class FisheyeCamera:
    """Equisolid fisheye camera.

    Attributes
    ----------
    focal_length_px : float
        Focal length ``f`` in pixels.
    width_px, height_px : int
        Image size, px.
    principal_point_px : tuple of float
        ``(u0, v0)``: column, row of the principal point; pixel centres at integers.
    radial_k : tuple of float
        ``(k1, k2, k3)`` of eq. (1), rad.
    pixel_size_mm : float or None
        Pixel pitch, mm (informative: the model works in pixels).
    """
    focal_length_px: float
    width_px: int
    height_px: int
    principal_point_px: tuple
    radial_k: tuple = (0.0, 0.0, 0.0)
    pixel_size_mm: float | None = None

    def _theta_of_s(self, s):
        k1, k2, k3 = self.radial_k
        return 2 * s + k1 * s**2 + k2 * s**3 + k3 * s**4

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
        y = -(uv[..., 1] - self.principal_point_px[1])
        r = np.hypot(x, y)
        s = np.arcsin(np.clip(r / (2 * self.focal_length_px), 0.0, 1.0))
        theta = self._theta_of_s(s)
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
        s = theta / 2
        k1, k2, k3 = self.radial_k
        for _ in range(30):                               # Newton on eq. (1) for s
            g = self._theta_of_s(s) - theta
            dg = 2 + 2 * k1 * s + 3 * k2 * s**2 + 4 * k3 * s**3
            step = g / dg
            s = s - step
            if np.all(np.abs(step) < 1e-15):
                break
        r = 2 * self.focal_length_px * np.sin(s)
        u = self.principal_point_px[0] + r * np.cos(a)
        v = self.principal_point_px[1] - r * np.sin(a)
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
#: (:mod:`ins.tomlschema`).  Optional: ``principal_point_px`` (the image centre),
#: ``radial_k`` (zeros), ``pixel_size_mm`` (needed only with ``focal_length_mm``).
FISHEYE_KEYS = {"camera": ("model", "focal_length_px", "focal_length_mm", "pixel_size_mm",
                           "width_px", "height_px", "principal_point_px", "radial_k")}


def read_camera(path):
    """Read a fisheye camera file (TOML).

    ``[camera]`` keys: ``model = "fisheye-equisolid"``; ``focal_length_px``, or
    ``focal_length_mm`` with ``pixel_size_mm``; ``width_px``, ``height_px``;
    ``principal_point_px = [u0, v0]`` (default: the image centre); ``radial_k =
    [k1, k2, k3]`` in rad (eq. 1; default zeros).  Any other section or key is an
    error (:data:`FISHEYE_KEYS`).

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
    model = cam.string("model", unit='"fisheye-equisolid"')
    if model != "fisheye-equisolid":
        raise cam.error("model", f"expected \"fisheye-equisolid\", got {model!r}")
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
    cam.finish()
    return FisheyeCamera(focal_length_px=f_px, width_px=int(width), height_px=int(height),
                         principal_point_px=pp, radial_k=k, pixel_size_mm=pixel)

