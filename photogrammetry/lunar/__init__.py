"""Heading of a fisheye camera from a series of Moon images and their times alone.

The lunar paper's method (seed 004) with its errata fixed (``conventions.md``, erratum
3): the Moon's centre in the camera frame (`moon_centre`, `fisheye`) and in the horizon
frame NED (`ephemeris`), the rotation ``C_hc`` between them (`solve`) and the heading
= azimuth of the camera x axis.

`heading_from_centres` and `heading_from_images` chain the steps.
"""
from dataclasses import dataclass

import numpy as np

from ins.errors import InputError

from .ephemeris import moon_sun_directions
from .moon_centre import MoonNotFoundError, _Offset, extract_centre, sun_direction_in_image
from .solve import solve_heading

__all__ = ["LunarHeading", "heading_from_centres", "heading_from_images", "centre_directions"]


@dataclass
class LunarHeading:
    """Result of the pipeline: the solution, the inputs to it and the per-image data."""
    solution: object            # solve.HeadingSolution
    sky: object                 # ephemeris.SkyDirections
    uv: np.ndarray              # (n, 2) centres, px
    cov_uv: np.ndarray          # (n, 2, 2) px^2
    S_c: np.ndarray             # (n, 3)
    cov_c: np.ndarray           # (n, 3, 3)


def centre_directions(camera, uv, cov_uv):
    """Camera-frame directions of pixel centres and their covariances (rad^2)."""
    uv = np.asarray(uv, float)
    J = camera.direction_jacobian(uv)
    return camera.image_to_direction(uv), np.einsum("nij,njk,nlk->nil", J, cov_uv, J)


def heading_from_centres(camera, uv, cov_uv, utc, lat, lon, h, **sky_options):
    """Heading from measured centres (px) at UTC times; ``lat, lon`` rad, ``h`` m.

    ``sky_options`` go to `ephemeris.moon_sun_directions` (pressure_hpa, temperature_c,
    dut1_s).  Returns `LunarHeading`.
    """
    if len(uv) < 2:
        raise InputError(f"at least 2 usable images are needed, got {len(uv)}")
    sky = moon_sun_directions(utc, lat, lon, h, **sky_options)
    S_c, cov_c = centre_directions(camera, uv, cov_uv)
    return LunarHeading(solve_heading(sky.moon_h, S_c, cov_c), sky, np.asarray(uv, float),
                        np.asarray(cov_uv, float), S_c, cov_c)


def _crop(img, uv, half):
    c0 = max(int(uv[0] - half), 0)
    r0 = max(int(uv[1] - half), 0)
    return img[r0:int(uv[1] + half) + 1, c0:int(uv[0] + half) + 1].copy(), np.array([c0, r0])


def heading_from_images(camera, images, utc, lat, lon, h, load=None, progress=None,
                        **sky_options):
    """Heading from Moon images in two passes.

    Pass 1: limb circle with the lit side taken from the image; first solution.  Pass 2:
    the Sun's direction in the camera from it; limb circle on the lit limb, then the
    blurred phased disk fitted to the lit limb's pixels (`moon_centre.fit_lit_limb`);
    final solution.

    Parameters
    ----------
    camera : FisheyeCamera
    images : sequence
        Arrays, or paths read with ``load``.
    utc : array of datetime64, shape (n,)
    lat, lon : float
        rad.  h : float, m.
    load : callable, optional
        ``load(path) -> 2-D array`` (e.g. `io.load_image`).
    progress : callable, optional
        ``progress(done, total)`` over the 2 n extractions.

    Raises
    ------
    InputError
        An image without a Moon (named), or fewer than 2 images.
    """
    n = len(images)
    if n < 2:
        raise InputError(f"at least 2 usable images are needed, got {n}")
    sky = moon_sun_directions(utc, lat, lon, h, **sky_options)
    crops, uv, cov = [], np.empty((n, 2)), np.empty((n, 2, 2))
    for k, item in enumerate(images):
        img = load(item) if load is not None else np.asarray(item, float)
        try:
            m = extract_centre(img, camera=camera)
        except MoonNotFoundError as exc:
            raise InputError(exc.reason, item if isinstance(item, str) else f"image {k + 1}") \
                from None
        crop, off = _crop(img, m.uv, 3 * m.radius_px + 12)
        crops.append((crop, off))
        uv[k], cov[k] = m.uv, m.cov_uv
        if progress:
            progress(k + 1, 2 * n)
    S_c, cov_c = centre_directions(camera, uv, cov)
    sol = solve_heading(sky.moon_h, S_c, cov_c)
    sun_c = sky.sun_h @ sol.C_hc
    for k, (crop, off) in enumerate(crops):
        ang = sun_direction_in_image(camera, uv[k], sun_c[k])
        m = extract_centre(crop, sun_angle=ang, camera=_Offset(camera, off), sun_c=sun_c[k])
        uv[k], cov[k] = m.uv + off, m.cov_uv
        if progress:
            progress(n + k + 1, 2 * n)
    S_c, cov_c = centre_directions(camera, uv, cov)
    return LunarHeading(solve_heading(sky.moon_h, S_c, cov_c), sky, uv, cov, S_c, cov_c)
