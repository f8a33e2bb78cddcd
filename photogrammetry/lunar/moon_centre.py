"""Sub-pixel centre of the Moon from its lit limb.

1. Find the Moon: the brightest connected region above a robust sky threshold.
2. Cast rays from the lit-area centroid and take, on each, the sub-pixel point where the
   brightness falls through half of the ray's peak above the sky (the limb is the outer
   edge of the bright rim).  Only rays within ``half_width`` of the Sun's direction on the
   image are used: those end on the lit limb; the others end on the terminator, which is
   not on the Moon's circle and would pull the centre towards the Sun.
3. Fit a circle to the limb points (algebraic start, geometric Gauss-Newton, a 3-sigma
   cut and a refit; with a known radius the last fit keeps it).  With a camera the
   points become directions and the fit is a cone of the apparent semidiameter around
   the Moon's direction (the fisheye draws the Moon as an ellipse off-axis; the cone is
   exact).  The centre's covariance comes from the fit, inflated for rays that sample
   the same pixels.
4. With the Sun's direction and the phase known, that circle starts the fit of the
   blurred phased disk to the lit limb's pixels (`fit_lit_limb`, `_limb_model`): the
   photometric law is fitted too (a non-negative mix of flat, Lambert, Lommel-Seeliger
   shading and Hapke's multiple scattering), so the centre does not depend on the
   Moon's shading;
   clipped (saturated) pixels are left out; refraction's flattening can be given.

Pixel coordinates ``(u, v)``: column, row; pixel centres at integers.
"""
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ins.common.errors import InputError
from photogrammetry.lunar import _limb_kernels, _limb_model

__all__ = ["MoonCentre", "MoonNotFoundError", "extract_centre", "fit_lit_limb", "lit_centroid",
           "sun_direction_in_image", "default_saturation"]


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
    extent_px : float
        Half the largest extent of the bright region, px (about the radius whatever the
        phase: horn to horn on a crescent; nan from `fit_lit_limb`).
    """
    uv: np.ndarray
    cov_uv: np.ndarray
    radius_px: float
    n_points: int
    rms_px: float
    centroid_uv: np.ndarray
    sun_angle: float
    extent_px: float = float("nan")

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
    """(centroid_uv, radius guess, sky, sky noise) of the Moon: the brightest blob.

    Large images are searched on their 4 x 4 block maxima (one pass over the frame, in
    its own type), then only a window around the blob is read at full resolution.
    """
    big = img.size > 250_000
    if big:
        step = 8 if img.size > 1_000_000 else 4
        sample = img[::step, ::step]
        coarse = _limb_kernels.block_max(img, 4)
        top = float(coarse.max())
    else:
        sample = img
        top = float(img.max())
    sky = float(np.median(sample))
    noise = 1.4826 * float(np.median(np.abs(sample - sky))) + 1e-12
    if top - sky < 10 * noise or top - sky <= 0:
        raise MoonNotFoundError(f"no Moon found (peak {top - sky:.3g} counts above the sky, "
                                f"sky noise {noise:.3g})")
    threshold = sky + max(5 * noise, 0.25 * (top - sky))
    r0 = c0 = 0
    if big:                                # locate on 4x4 block maxima, then refine
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


def _tangent_basis(d0):
    """Unit vectors ``e1, e2`` normal to the unit vector ``d0`` (right-handed with it)."""
    e1 = _limb_kernels.cross3(d0, np.array([1.0, 0.0, 0.0] if abs(d0[0]) < 0.9
                                           else [0.0, 1.0, 0.0]))
    e1 /= np.linalg.norm(e1)
    return e1, _limb_kernels.cross3(d0, e1)


def _circle_gn(data, p, camera, f, keep, iterations=6, fixed_radius=False):
    """Gauss-Newton of the geometric circle (or cone) fit on the points ``keep``.

    ``p``: flat ``(u, v, R)`` px; cone ``(axis (3,), R = f * half angle)``.  Returns
    (p, residuals of all points (px), Jacobian (m, 3) of the kept ones in px per
    (centre shift px, R))."""
    for _ in range(iterations + 1):
        if camera is None:
            d = data - p[:2]
            dist = np.hypot(d[:, 0], d[:, 1])
            r = dist - p[2]
            J = np.column_stack([-d / dist[:, None], -np.ones(len(d))])
        else:
            e1, e2 = _tangent_basis(p[0])
            cosang = np.clip(data @ p[0], -1.0, 1.0)
            t = data - cosang[:, None] * p[0]
            sinang = np.linalg.norm(t, axis=1)
            r = f * np.arctan2(sinang, cosang) - p[1]
            t /= np.maximum(sinang, 1e-15)[:, None]
            J = np.column_stack([-(t @ e1), -(t @ e2), -np.ones(len(t))])
        Jk, rk = J[keep], r[keep]
        if fixed_radius:
            step = np.append(np.linalg.lstsq(Jk[:, :2], -rk, rcond=None)[0], 0.0)
        else:
            step = np.linalg.lstsq(Jk, -rk, rcond=None)[0]
        if _ == iterations or np.max(np.abs(step)) < 1e-7:
            return p, r, Jk
        if camera is None:
            p = p + step
        else:
            a = p[0] + (step[0] / f) * e1 + (step[1] / f) * e2
            p = (a / np.linalg.norm(a), p[1] + step[2])


def _fit(pts, c0, r0, camera, radius=None):
    """Circle (or cone) fit with a 3-sigma cut; (centre uv, cov uv, radius px, rms px,
    inlier mask).

    Start: the algebraic fit, linear and exact for a circle (Kasa: ``u^2 + v^2 = 2 a u +
    2 b v + c``) or a cone (directions ``d`` with ``d . w = 1``, ``w = axis / cos r``);
    then Gauss-Newton on the geometric residuals (px; with a camera the angle to the axis
    times ``f``), a cut at 3 MAD-sigmas (at least 0.02 px) and Gauss-Newton again.  With
    a known ``radius`` (px) the last Gauss-Newton keeps it fixed (a short arc of a thin
    crescent does not tell its curvature).
    """
    if camera is None:
        f, data = 1.0, np.asarray(pts, float)
        A = np.column_stack([2 * (data - c0), np.ones(len(data))])
        a = np.linalg.lstsq(A, ((data - c0) ** 2).sum(1), rcond=None)[0]
        p = np.array([c0[0] + a[0], c0[1] + a[1], np.sqrt(max(a[2] + a[:2] @ a[:2], 1e-6))])
    else:
        f, data = camera.focal_length_px, camera.image_to_direction(pts)
        w = np.linalg.lstsq(data, np.ones(len(data)), rcond=None)[0]
        p = (w / np.linalg.norm(w), f * np.arccos(min(1.0 / np.linalg.norm(w), 1.0)))
    keep = np.ones(len(data), bool)
    p, r, _ = _circle_gn(data, p, camera, f, keep)
    mad = 1.4826 * np.median(np.abs(r - np.median(r))) + 1e-6
    keep = np.abs(r) < max(3 * mad, 0.02)
    if keep.sum() < 5:
        keep[:] = True
    if radius is not None:
        p = (np.append(p[:2], radius) if camera is None else (p[0], float(radius)))
    p, r, J = _circle_gn(data, p, camera, f, keep, fixed_radius=radius is not None)
    rk = r[keep]
    s2 = float(rk @ rk) / max(keep.sum() - 3, 1)
    cov_p = s2 * np.linalg.pinv(J.T @ J)[:2, :2]
    if camera is None:
        return p[:2].copy(), cov_p, float(p[2]), float(np.sqrt(s2)), keep
    # the centre's covariance in px through the Jacobian of the image of the axis
    e1, e2 = _tangent_basis(p[0])
    uv = camera.direction_to_image(p[0])
    G = np.column_stack([(camera.direction_to_image(p[0] + 1e-6 * e) - uv) / (1e-6 * f)
                         for e in (e1, e2)])
    return uv, G @ cov_p @ G.T, float(p[1]), float(np.sqrt(s2)), keep


def extract_centre(image, sun_angle=None, camera=None, half_width_deg=70.0, n_rays=None,
                   phase_angle=None, sun_c=None, radius_prior=None, saturation=None,
                   flattening=None):
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
    radius_prior : (float, float), optional
        Known radius and its sigma, px (with a camera: the semidiameter times the focal
        length), for the fit of the phased disk (see `fit_lit_limb`).
    saturation : float, optional
        Pixels at or above this level (counts) are clipped: left out of the fit of the
        phased disk.  Default: `default_saturation` (an integer image's plateau at its
        maximum, or its type's largest value; none for float images).
    flattening : (float, float, array_like), optional
        With a camera: ``(k_h, k_v, up_c)`` of the refraction (see `fit_lit_limb`).

    Returns
    -------
    MoonCentre

    Raises
    ------
    MoonNotFoundError
        When nothing bright enough is found or too few limb points remain.
    """
    img = np.asarray(image)
    if img.ndim != 2:
        raise InputError(f"expected a 2-D grayscale image, got shape {img.shape}")
    saturation = default_saturation(img, saturation)
    c0, radius, sky, _ = _find(img)
    extent = radius
    half = int(2 * radius + 12)           # work on a crop around the Moon (as float)
    u0, v0 = max(int(c0[0]) - half, 0), max(int(c0[1]) - half, 0)
    img = img[v0:int(c0[1]) + half + 1, u0:int(c0[0]) + half + 1].astype(float)
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
    uv, cov, rad, rms, keep = _fit(pts, c0, radius, camera,
                                   None if radius_prior is None else radius_prior[0])
    # neighbouring rays share pixels: about one independent point per px of limb arc
    arc_px = radius * (np.ptp(ang) if sun_angle is not None else 2 * np.pi)
    inflate = max(1.0, keep.sum() / max(arc_px, 1.0))
    n_used, cov = int(keep.sum()), cov * inflate
    if sun_angle is not None and ((camera is None and phase_angle is not None)
                                  or (camera is not None and sun_c is not None)):
        r_sigma = None
        if radius_prior is not None:
            rad, r_sigma = radius_prior
        fit = fit_lit_limb(img, uv, rad, sun_angle, phase_angle, camera, sun_c, half_width_deg,
                           radius_sigma_px=r_sigma, saturation=saturation,
                           flattening=flattening)
        uv, cov, rad, rms, n_used = fit.uv, fit.cov_uv, fit.radius_px, fit.rms_px, fit.n_points
    return MoonCentre(uv=np.asarray(uv) + off, cov_uv=cov, radius_px=rad,
                      n_points=n_used, rms_px=rms, centroid_uv=c0 + off,
                      sun_angle=float("nan") if sun_angle is None else sun_angle,
                      extent_px=float(extent))


#: An integer image whose maximum is held by at least this many pixels is clipped there.
CLIPPED_PIXELS = 3


def default_saturation(image, saturation=None):
    """The clipping level of an image: ``saturation`` when given; for an integer image
    its maximum when at least `CLIPPED_PIXELS` pixels hold it (a clipped core: sensor or
    file clipping leaves a plateau of equal values), else its type's largest value; None
    for float images."""
    if saturation is not None:
        return float(saturation)
    img = np.asarray(image)
    if not np.issubdtype(img.dtype, np.integer):
        return None
    top = img.max()
    if np.count_nonzero(img == top) >= CLIPPED_PIXELS:
        return float(top)
    return float(np.iinfo(img.dtype).max)


def fit_lit_limb(image, uv, radius_px, sun_angle, phase_angle=None, camera=None, sun_c=None,
                 half_width_deg=70.0, radius_sigma_px=None, saturation=None,
                 flattening=None):
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
    radius_sigma_px : float, optional
        When given, ``radius_px`` is known (e.g. the ephemeris' semidiameter times the
        focal length) with this sigma, px, and enters the fit as a prior: with one limb
        the radius and the centre along the Sun are nearly degenerate.
    saturation : float, optional
        Pixels at or above this level are left out (clipped).
    flattening : (float, float, array_like), optional
        With a camera: ``(k_h, k_v, up_c)``, the refracted disk's horizontal and vertical
        semi-axes over the semidiameter (`ephemeris.refraction_flattening`) and the
        zenith's direction in the camera frame; the limb is fitted as that ellipse.

    Returns
    -------
    MoonCentre
        ``rms_px`` is the RMS pixel residual (counts); ``n_points`` the pixels fitted.
    """
    img = np.asarray(image)
    uv = np.asarray(uv, float)
    half = int(np.ceil(radius_px + _limb_model.BAND_PX + _limb_model.MARGIN_PX + 3))
    u0, v0 = max(int(round(uv[0])) - half, 0), max(int(round(uv[1])) - half, 0)
    crop = img[v0:int(round(uv[1])) + half + 1, u0:int(round(uv[0])) + half + 1].astype(float)
    off = np.array([u0, v0], float)
    cam = None if camera is None else _Offset(camera, off)
    sun3 = None
    if camera is None:
        a = phase_angle
        sun3 = (np.sin(a) * np.cos(sun_angle), np.sin(a) * np.sin(sun_angle), np.cos(a))
    try:
        model = _limb_model.LimbModel(crop, uv - off, radius_px, sun3=sun3, camera=cam,
                                      sun_c=sun_c, sun_angle=sun_angle,
                                      half_width=np.deg2rad(half_width_deg),
                                      saturation=saturation, flattening=flattening)
    except ValueError as exc:
        raise MoonNotFoundError(f"Moon at pixel ({uv[0]:.0f}, {uv[1]:.0f}): {exc}") from None
    prior = None if radius_sigma_px is None else (radius_px, radius_sigma_px)
    c, cov, rad, _, rms, n_pix = _limb_model.fit_limb_model(model, uv - off, radius_px,
                                                            radius_prior=prior)
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
