"""Sub-pixel centre of the Moon from its lit limb.

1. Find the Moon: the brightest connected region above a robust sky threshold.
2. Cast rays from the lit-area centroid and take, on each, the sub-pixel point where the
   brightness falls through half of the ray's peak above the sky (the limb is the outer
   edge of the bright rim).  Only rays within ``half_width`` of the Sun's direction on the
   image are used: those end on the lit limb; the others end on the terminator, which is
   not on the Moon's circle and would pull the centre towards the Sun.
3. Fit a circle to the limb points (robust loss, then a 3-sigma cut and a least-squares
   refit).  With a camera the points become directions and the fit is a cone of the
   apparent semidiameter around the Moon's direction (the fisheye draws the Moon as an
   ellipse off-axis; the cone is exact).  The centre's covariance comes from the fit,
   inflated for rays that sample the same pixels.

Pixel coordinates ``(u, v)``: column, row; pixel centres at integers.
"""
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.optimize import least_squares

from ins.errors import InputError

from . import _limb_model

__all__ = ["MoonCentre", "MoonNotFoundError", "extract_centre", "fit_lit_limb", "lit_centroid",
           "sun_direction_in_image"]


class MoonNotFoundError(InputError):
    """No Moon in the image (nothing bright enough above the sky)."""


@dataclass
class MoonCentre:
    """Result of `extract_centre`.

    Attributes
    ----------
    uv : ndarray, shape (2,)
        Centre ``(u, v)``, px.
    cov_uv : ndarray, shape (2, 2)
        Its covariance, px^2.
    radius_px : float
        Fitted radius, px (with a camera: semidiameter times the local scale).
    n_points : int
        Limb points used.
    rms_px : float
        RMS distance of the limb points from the fitted circle, px.
    centroid_uv : ndarray, shape (2,)
        Centroid of the lit area (the biased estimate, for comparison).
    sun_angle : float
        Direction of the Sun on the image used to choose the limb, rad from +u to +v.
    """
    uv: np.ndarray
    cov_uv: np.ndarray
    radius_px: float
    n_points: int
    rms_px: float
    centroid_uv: np.ndarray
    sun_angle: float

    @property
    def sigma_px(self):
        """sqrt of the mean variance of u and v, px."""
        return float(np.sqrt(np.trace(self.cov_uv) / 2))


def _blob(img, threshold):
    """Pixels (rows, cols) of the connected region above ``threshold`` with the most flux."""
    labels, n = ndimage.label(img > threshold)
    if n == 0:
        return None
    flux = np.bincount(labels.ravel(), weights=img.ravel() - threshold, minlength=n + 1)[1:]
    return np.nonzero(labels == int(np.argmax(flux)) + 1)


def _find(img):
    """(centroid_uv, radius guess, sky, sky noise) of the Moon: the brightest blob."""
    sample = img[::4, ::4] if img.size > 250_000 else img
    sky = float(np.median(sample))
    noise = 1.4826 * float(np.median(np.abs(sample - sky))) + 1e-12
    top = float(img.max())
    if top - sky < 10 * noise or top - sky <= 0:
        raise MoonNotFoundError(f"no Moon found (peak {top - sky:.3g} counts above the sky, "
                                f"sky noise {noise:.3g})")
    threshold = sky + max(5 * noise, 0.25 * (top - sky))
    r0 = c0 = 0
    if img.size > 250_000:                 # locate on 4x4 block maxima, then refine
        rows, cols = (img.shape[0] // 4) * 4, (img.shape[1] // 4) * 4
        coarse = img[:rows, :cols].reshape(rows // 4, 4, cols).max(axis=1)
        coarse = coarse.reshape(rows // 4, cols // 4, 4).max(axis=2)
        rr, cc = _blob(coarse, threshold)
        r0, c0 = max(4 * rr.min() - 4, 0), max(4 * cc.min() - 4, 0)
        img = img[r0:4 * rr.max() + 8, c0:4 * cc.max() + 8]
    rows, cols = _blob(img, threshold)
    if len(rows) < 3:
        raise MoonNotFoundError(f"no Moon found (brightest blob has {len(rows)} pixels)")
    w = img[rows, cols] - sky
    rows, cols = rows + r0, cols + c0
    centroid = np.array([np.sum(w * cols), np.sum(w * rows)]) / np.sum(w)
    ang = np.linspace(0, np.pi, 8, endpoint=False)
    proj = cols[:, None] * np.cos(ang) + rows[:, None] * np.sin(ang)
    radius = 0.5 * (np.max(proj.max(0) - proj.min(0)) + 1.0)
    return centroid, radius, sky, noise


def lit_centroid(image):
    """Brightness-weighted centroid of the Moon's lit area ``(u, v)``, px (biased by the phase)."""
    return _find(np.asarray(image, dtype=float))[0]


def _edges(img, c0, radius, angles, sky, step=0.1):
    """Half-peak crossings along rays: (points (m, 2), ray angles (m,), ray peak radii (m,)).

    Each ray is sampled every ``step`` px (cubic spline); the limb point is where the
    brightness, beyond the ray's peak, falls through half of that peak above the sky.
    """
    radii = np.arange(0.0, 1.6 * radius + 4.0, step)
    U = c0[0] + np.cos(angles)[:, None] * radii
    V = c0[1] + np.sin(angles)[:, None] * radii
    prof = ndimage.map_coordinates(img, [V, U], order=3, mode="nearest") - sky
    imax = np.argmax(prof, axis=1)
    peak = prof[np.arange(len(angles)), imax]
    level = 0.5 * peak
    idx = np.arange(len(radii))
    below = (prof < level[:, None]) & (idx[None, :] > imax[:, None])
    ok = below.any(axis=1) & (peak > 0)
    j = np.argmax(below, axis=1)
    rows = np.nonzero(ok)[0]
    j = j[rows]
    p_in, p_out = prof[rows, j - 1], prof[rows, j]
    r = radii[j - 1] + step * (p_in - level[rows]) / (p_in - p_out)
    pts = np.stack([c0[0] + r * np.cos(angles[rows]), c0[1] + r * np.sin(angles[rows])], -1)
    return pts, angles[rows], radii[imax[rows]]


def sun_direction_in_image(camera, moon_uv, sun_c):
    """Direction of the Sun on the image at the Moon, rad from +u towards +v.

    Parameters
    ----------
    camera : FisheyeCamera
    moon_uv : array_like, shape (2,)
        The Moon's position, px.
    sun_c : array_like, shape (3,)
        Direction to the Sun in the camera frame.
    """
    m = camera.image_to_direction(moon_uv)
    s = np.asarray(sun_c, float)
    t = s - (s @ m) * m
    t /= np.linalg.norm(t)
    duv = camera.direction_to_image(m + 1e-4 * t) - np.asarray(moon_uv, float)
    return float(np.arctan2(duv[1], duv[0]))


def _fit(pts, c0, r0, camera):
    """Robust circle (or cone) fit; (centre uv, cov uv, radius px, rms px, inlier mask)."""
    if camera is None:
        def centre(p):
            return c0 + p[:2]

        def resid(p, q):
            return np.hypot(q[:, 0] - c0[0] - p[0], q[:, 1] - c0[1] - p[1]) - p[2]
        data, x0 = pts, np.array([0.0, 0.0, r0])
    else:
        d0 = camera.image_to_direction(c0)
        e1 = np.cross(d0, [1.0, 0.0, 0.0] if abs(d0[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(d0, e1)
        f = camera.focal_length_px

        def axis(p):
            d = d0 + p[0] * e1 + p[1] * e2
            return d / np.linalg.norm(d)

        def centre(p):
            return camera.direction_to_image(axis(p))

        def resid(p, q):     # angle to the axis minus the semidiameter, in px at scale f
            d = axis(p)
            return f * (np.arctan2(np.linalg.norm(np.cross(q, d), axis=1), q @ d) - p[2] / f)
        data, x0 = camera.image_to_direction(pts), np.array([0.0, 0.0, r0])
        x0[2] = f * np.arccos(np.clip(data @ d0, -1, 1)).mean()
        x0[:2] = 0.0
        scale = 1.0 / f
        x_scale = np.array([scale, scale, 1.0])
    if camera is None:
        x_scale = np.ones(3)
    fun = (lambda p, q: resid(p, q))
    res = least_squares(fun, x0, args=(data,), loss="soft_l1", f_scale=0.2, x_scale=x_scale)
    r = fun(res.x, data)
    mad = 1.4826 * np.median(np.abs(r - np.median(r))) + 1e-6
    keep = np.abs(r) < max(3 * mad, 0.02)
    if keep.sum() < 5:
        keep[:] = True
    res = least_squares(fun, res.x, args=(data[keep],), x_scale=x_scale)
    r = res.fun
    dof = max(keep.sum() - 3, 1)
    s2 = float(r @ r) / dof
    cov_p = s2 * np.linalg.pinv(res.jac.T @ res.jac)[:2, :2]
    # the centre's covariance in px through the Jacobian of centre(p)
    J = np.empty((2, 2))
    for k in range(2):
        dp = np.zeros(3)
        h = 1e-3 * x_scale[k]
        dp[k] = h
        J[:, k] = (centre(res.x + dp) - centre(res.x - dp)) / (2 * h)
    return centre(res.x), J @ cov_p @ J.T, float(res.x[2]), float(np.sqrt(s2)), keep


def extract_centre(image, sun_angle=None, camera=None, half_width_deg=70.0, n_rays=None,
                   phase_angle=None, sun_c=None):
    """Centre of the Moon from the lit limb of one grayscale image.

    Parameters
    ----------
    image : array_like, shape (rows, cols)
        Grayscale image (any numeric type; the Moon bright on a dark sky).
    sun_angle : float, optional
        Direction of the Sun on the image at the Moon, rad from +u towards +v (see
        `sun_direction_in_image`).  Without it the lit side is taken from the image (rays
        whose brightness peaks near the limb); near full Moon all rays are used.
    camera : FisheyeCamera, optional
        Fit a cone on the sphere of directions instead of a circle on the image.
    half_width_deg : float
        Rays within this angle of the Sun's direction are used, deg (< 90 keeps away
        from the horns).
    n_rays : int, optional
        Rays over the full circle (default: about 2 per px of circumference, at least 96).
    phase_angle : float, optional
        Sun-Moon-observer angle, rad (flat images, with ``sun_angle``).
    sun_c : array_like, shape (3,), optional
        Direction to the Sun in the camera frame (with ``camera``).  With the Sun known
        (``sun_angle`` and ``phase_angle``, or ``camera`` and ``sun_c``) the limb circle
        is the initial value of a least-squares fit of the blurred phased disk to the
        pixels of the lit limb (`_limb_model`), which removes the rim's bias along the
        Sun's direction; otherwise the limb circle is the result.

    Returns
    -------
    MoonCentre

    Raises
    ------
    MoonNotFoundError
        When nothing bright enough is found or too few limb points remain.
    """
    img = np.asarray(image, dtype=float)
    if img.ndim != 2:
        raise InputError(f"expected a 2-D grayscale image, got shape {img.shape}")
    c0, radius, sky, _ = _find(img)
    half = int(2 * radius + 12)           # work on a crop around the Moon
    u0, v0 = max(int(c0[0]) - half, 0), max(int(c0[1]) - half, 0)
    img = img[v0:int(c0[1]) + half + 1, u0:int(c0[0]) + half + 1]
    off = np.array([u0, v0], float)
    c0 = c0 - off
    if camera is not None:
        camera = _Offset(camera, off)
    n = n_rays or max(96, int(4 * np.pi * radius))
    angles = np.linspace(-np.pi, np.pi, n, endpoint=False)
    if sun_angle is None:
        pts, ang, rpeak = _edges(img, c0, radius, angles, sky)
        limbish = rpeak > 0.5 * radius
        resultant = np.mean(np.exp(1j * ang[limbish])) if limbish.any() else 0.0
        if abs(resultant) > 0.2:
            sun_angle = float(np.angle(resultant))
    if sun_angle is not None:
        half = np.deg2rad(half_width_deg)
        angles = sun_angle + np.linspace(-half, half, max(int(n * half / np.pi), 16))
    pts, ang, _ = _edges(img, c0, radius, angles, sky)
    if len(pts) < 6:
        raise MoonNotFoundError(f"only {len(pts)} limb points found")
    uv, cov, rad, rms, keep = _fit(pts, c0, radius, camera)
    # neighbouring rays share pixels: about one independent point per px of limb arc
    arc_px = radius * (np.ptp(ang) if sun_angle is not None else 2 * np.pi)
    inflate = max(1.0, keep.sum() / max(arc_px, 1.0))
    n_used, cov = int(keep.sum()), cov * inflate
    if sun_angle is not None and ((camera is None and phase_angle is not None)
                                  or (camera is not None and sun_c is not None)):
        fit = fit_lit_limb(img, uv, rad, sun_angle, phase_angle, camera, sun_c, half_width_deg)
        uv, cov, rad, rms, n_used = fit.uv, fit.cov_uv, fit.radius_px, fit.rms_px, fit.n_points
    return MoonCentre(uv=np.asarray(uv) + off, cov_uv=cov, radius_px=rad,
                      n_points=n_used, rms_px=rms, centroid_uv=c0 + off,
                      sun_angle=float("nan") if sun_angle is None else sun_angle)


def fit_lit_limb(image, uv, radius_px, sun_angle, phase_angle=None, camera=None, sun_c=None,
                 half_width_deg=70.0):
    """Centre from a least-squares fit of the blurred, phased disk to the lit limb's pixels.

    Parameters
    ----------
    image : array_like, shape (rows, cols)
        Grayscale image.
    uv : array_like, shape (2,)
        Initial centre, px (within about 1 px; e.g. the limb circle of `extract_centre`).
    radius_px : float
        Initial radius, px (with a camera: semidiameter times the focal length).
    sun_angle : float
        Direction of the Sun on the image at the Moon, rad from +u towards +v.
    phase_angle : float, optional
        Sun-Moon-observer angle, rad (required without a camera).
    camera : FisheyeCamera, optional
        Fit the cone of the semidiameter around the Moon's direction.
    sun_c : array_like, shape (3,), optional
        Direction to the Sun in the camera frame (required with a camera).
    half_width_deg : float
        The limb band spans this angle either side of the Sun's direction, deg.

    Returns
    -------
    MoonCentre
        ``rms_px`` is the RMS pixel residual (counts); ``n_points`` the pixels fitted.
    """
    img = np.asarray(image, dtype=float)
    uv = np.asarray(uv, float)
    half = int(np.ceil(radius_px + _limb_model.BAND_PX + _limb_model.MARGIN_PX + 3))
    u0, v0 = max(int(round(uv[0])) - half, 0), max(int(round(uv[1])) - half, 0)
    crop = img[v0:int(round(uv[1])) + half + 1, u0:int(round(uv[0])) + half + 1]
    off = np.array([u0, v0], float)
    cam = None if camera is None else _Offset(camera, off)
    sun3 = None
    if camera is None:
        a = phase_angle
        sun3 = (np.sin(a) * np.cos(sun_angle), np.sin(a) * np.sin(sun_angle), np.cos(a))
    model = _limb_model.LimbModel(crop, uv - off, radius_px, sun3=sun3, camera=cam, sun_c=sun_c,
                                  sun_angle=sun_angle, half_width=np.deg2rad(half_width_deg))
    c, cov, rad, _, rms, n_pix = _limb_model.fit_limb_model(model, uv - off, radius_px)
    return MoonCentre(uv=c + off, cov_uv=cov, radius_px=rad, n_points=n_pix, rms_px=rms,
                      centroid_uv=np.full(2, np.nan), sun_angle=float(sun_angle))


class _Offset:
    """A camera seen from a crop whose pixel (0, 0) is pixel ``offset`` (u, v) of the image."""

    def __init__(self, camera, offset):
        self.camera, self.offset = camera, np.asarray(offset, float)
        self.focal_length_px = camera.focal_length_px

    def image_to_direction(self, uv):
        return self.camera.image_to_direction(np.asarray(uv, float) + self.offset)

    def direction_to_image(self, d):
        return self.camera.direction_to_image(d) - self.offset

    def direction_jacobian(self, uv):
        return self.camera.direction_jacobian(np.asarray(uv, float) + self.offset)
