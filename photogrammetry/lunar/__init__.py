"""Heading of a fisheye camera from a series of Moon images and their times alone.

The lunar paper's method (seed 004) with its errata fixed (``conventions.md``, erratum
3): the Moon's centre in the camera frame (`moon_centre`, `fisheye`) and in the horizon
frame NED (`ephemeris`), the rotation ``C_hc`` between them (`solve`) and the heading
= azimuth of the camera x axis.

`heading_from_centres` and `heading_from_images` chain the steps.
"""
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from photogrammetry.lunar.ephemeris import moon_sun_directions
from photogrammetry.lunar.io import load_image_meta
from photogrammetry.lunar.moon_centre import (
    MoonNotFoundError,
    _Offset,
    default_saturation,
    extract_centre,
    sun_direction_in_image,
)
from photogrammetry.lunar.solve import solve_heading

__all__ = ["LunarHeading", "heading_from_centres", "heading_from_images", "centre_directions",
           "check_crescent", "MIN_LIT_WIDTH_PX"]

#: Relative sigma of the Moon's image radius predicted from the ephemeris' semidiameter.
RADIUS_SIGMA_REL = 2e-3
#: Narrowest usable crescent: lit width ``R (1 + cos phase)`` on the image, px (the centre
#: bias grows beyond 0.02 px on thinner ones: bench/bench_lunar_bias.py).
MIN_LIT_WIDTH_PX = 2.0


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
    return (img[r0:int(uv[1] + half) + 1, c0:int(uv[0] + half) + 1].astype(float),
            np.array([c0, r0]))


def _first_pass(camera, item, k, load, saturation):
    """Load one image, find the Moon, limb circle (lit side from the image); keep a crop
    and the image's clipping level."""
    name = item if isinstance(item, (str, os.PathLike)) else f"image {k + 1}"
    if load is not None:
        img = load(item)
    elif isinstance(item, (str, os.PathLike)):
        img, meta = load_image_meta(item)
        if saturation is None:
            saturation = meta.get("saturation")
    else:
        img = np.asarray(item)
    sat = default_saturation(img, saturation)
    try:
        m = extract_centre(img, camera=camera, saturation=sat)
    except MoonNotFoundError as exc:
        raise InputError(exc.reason, name) from None
    crop, off = _crop(img, m.uv, 3 * m.radius_px + 12)
    return crop, off, m.uv, m.cov_uv, sat, name, m.extent_px


def _second_pass(camera, crop, off, uv, sun_c, radius_px, radius_sigma_px, saturation, name,
                 flattening):
    """Limb circle on the lit limb of a crop, then the blurred phased disk fitted to it."""
    ang = sun_direction_in_image(camera, uv, sun_c)
    try:
        m = extract_centre(crop, sun_angle=ang, camera=_Offset(camera, off), sun_c=sun_c,
                           radius_prior=(radius_px, radius_sigma_px), saturation=saturation,
                           flattening=flattening)
    except MoonNotFoundError as exc:
        raise InputError(exc.reason, name) from None
    return m.uv + off, m.cov_uv


#: The brightest object's radius on the image over the Moon's predicted one: outside
#: these bounds it is not the Moon (a lamp, a planet, a cloud lit by the Moon).
SIZE_RATIO = (0.5, 2.0)


def _check_size(first, radius):
    """Refuse an image whose bright object has not the Moon's size (half its largest
    extent, horn to horn on a crescent, vs f times the semidiameter)."""
    for f, r in zip(first, radius):
        if not SIZE_RATIO[0] <= f[6] / r <= SIZE_RATIO[1]:
            raise InputError(f"no Moon found: the brightest object at pixel ({f[2][0]:.0f}, "
                             f"{f[2][1]:.0f}) is {f[6]:.1f} px in radius, the Moon's is "
                             f"{r:.1f} px (focal length times the semidiameter)", f[5])


def check_crescent(sky, camera, min_width_px=None):
    """Refuse a session whose Moon is too thin a crescent: the lit width along the Sun's
    direction, ``R (1 + cos a)`` (R the Moon's radius on the image = f times the
    semidiameter, px; a the phase angle), under `MIN_LIT_WIDTH_PX` at some image.

    Raises
    ------
    InputError
        Naming the phase angle, the radius and the width.
    """
    min_width_px = MIN_LIT_WIDTH_PX if min_width_px is None else min_width_px
    radius = camera.focal_length_px * np.asarray(sky.semidiameter, float)
    width = radius * (1 + np.cos(sky.phase_angle))
    k = int(np.argmin(width))
    if width[k] < min_width_px:
        raise InputError(
            f"the Moon is too thin a crescent to use: phase angle "
            f"{np.rad2deg(sky.phase_angle[k]):.1f} deg, radius {radius[k]:.2f} px, lit width "
            f"R (1 + cos phase) = {width[k]:.2f} px < {min_width_px:g} px (image {k + 1}); "
            f"a longer focal length or a date nearer full Moon")


def _ordered(pool, fn, args, progress, done, total):
    """``[fn(*a) for a in args]`` in the pool, reporting ``progress`` in order."""
    out = []
    for res in pool.map(lambda a: fn(*a), args):
        out.append(res)
        done += 1
        if progress:
            progress(done, total)
    return out


def heading_from_images(camera, images, utc, lat, lon, h, load=None, progress=None,
                        workers=None, radius_sigma_rel=RADIUS_SIGMA_REL, saturation=None,
                        **sky_options):
    """Heading from Moon images in two passes.

    Pass 1: limb circle (a cone with the camera) with the lit side taken from the image;
    first solution.  Pass 2: the Sun's direction and the zenith in the camera from it;
    limb circle on the lit limb, then the blurred phased disk fitted to the lit limb's
    pixels (`moon_centre.fit_lit_limb`, the photometric law fitted too) with the radius
    known from the ephemeris' semidiameter (a prior: with one limb the radius and the
    centre along the Sun are nearly degenerate) and the disk flattened by refraction
    (`ephemeris.refraction_flattening`: an ellipse on the sky, 0.8 % flatter vertically
    at 10 deg altitude); final solution.  Images are processed in a
    thread pool (the image decoding and the compiled kernels release the GIL).

    Parameters
    ----------
    camera : FisheyeCamera
    images : sequence
        Arrays, or paths read with ``load``.
    utc : array of datetime64, shape (n,)
    lat, lon : float
        rad.  h : float, m.
    load : callable, optional
        ``load(path) -> 2-D array``; default `io.load_image_meta` keeping the file's
        integer type (only a crop around the Moon is converted to float) and reading a
        FITS file's clipping level.
    progress : callable, optional
        ``progress(done, total)`` over the 2 n extractions.
    workers : int, optional
        Threads (default: the CPU count, at most 4).
    radius_sigma_rel : float
        Relative sigma of the Moon's radius on the image predicted from the semidiameter
        and the focal length (calibration of f).
    saturation : float, optional
        Clipping level of the images, counts: pixels at or above it are left out of the
        fit.  Default: a FITS file's SATURATE (or DATAMAX) key, else
        `moon_centre.default_saturation` (an integer image's plateau at its maximum or
        its type's largest value).

    Raises
    ------
    InputError
        An image without a Moon (named), too thin a crescent (`check_crescent`), or
        fewer than 2 images.
    """
    n = len(images)
    if n < 2:
        raise InputError(f"at least 2 usable images are needed, got {n}")
    sky = moon_sun_directions(utc, lat, lon, h, **sky_options)
    check_crescent(sky, camera)
    workers = workers or min(os.cpu_count() or 1, 4)
    with ThreadPoolExecutor(max_workers=workers) as pool:
        first = _ordered(pool, _first_pass, [(camera, item, k, load, saturation)
                                             for k, item in enumerate(images)],
                         progress, 0, 2 * n)
        radius = camera.focal_length_px * np.asarray(sky.semidiameter, float)
        _check_size(first, radius)
        uv = np.array([f[2] for f in first])
        cov = np.array([f[3] for f in first])
        S_c, cov_c = centre_directions(camera, uv, cov)
        sol = solve_heading(sky.moon_h, S_c, cov_c)
        sun_c = sky.sun_h @ sol.C_hc
        up_c = np.array([0.0, 0.0, -1.0]) @ sol.C_hc          # the zenith in the camera
        second = _ordered(pool, _second_pass,
                          [(camera, f[0], f[1], f[2], sun_c[k], radius[k],
                            radius_sigma_rel * radius[k], f[4], f[5],
                            (*sky.flattening[k], up_c)) for k, f in enumerate(first)],
                          progress, n, 2 * n)
    uv = np.array([s[0] for s in second])
    cov = np.array([s[1] for s in second])
    S_c, cov_c = centre_directions(camera, uv, cov)
    return LunarHeading(solve_heading(sky.moon_h, S_c, cov_c), sky, uv, cov, S_c, cov_c)
