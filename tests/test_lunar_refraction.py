"""The Moon's image flattened by refraction: the semi-axes of
``ephemeris.refraction_flattening`` against skyfield's refraction of the true limb points
(a numeric difference across the disk), then a low Moon through a long lens fitted with
and without the flattening."""
import numpy as np
import pytest
from skyfield.earthlib import refract

from photogrammetry.lunar.ephemeris import refraction_flattening
from photogrammetry.lunar.fisheye import FisheyeCamera
from photogrammetry.lunar.moon_centre import extract_centre
from photogrammetry.lunar.render import render_moon_fisheye

S_DEG = 0.26                                     # the Moon's semidiameter, deg


@pytest.mark.parametrize("alt_true", [3.0, 6.0, 10.0, 20.0, 45.0, 80.0])
@pytest.mark.parametrize("pressure,temperature", [(1013.25, 10.0), (850.0, -15.0)])
def test_vertical_and_horizontal_scale(alt_true, pressure, temperature):
    top, mid, bottom = refract(np.array([alt_true + S_DEG, alt_true, alt_true - S_DEG]),
                               temperature, pressure)
    k_h, k_v = refraction_flattening(np.deg2rad(mid), pressure, temperature)
    # the vertical diameter as skyfield refracts the two limb points
    k_v_numeric = (top - bottom) / (2 * S_DEG)
    assert k_v == pytest.approx(k_v_numeric, abs=2e-5 if alt_true >= 6 else 3e-4)
    assert k_v < 1
    # horizontal: the true limb points S either side of the centre along the horizontal
    # great circle, refracted, and their angle apart
    h, s = np.deg2rad(alt_true), np.deg2rad(S_DEG)
    alt_limb = np.degrees(np.arcsin(np.cos(s) * np.sin(h)))
    az = np.arctan2(np.sin(s), np.cos(s) * np.cos(h))
    a = np.deg2rad(refract(np.array([alt_limb]), temperature, pressure)[0])
    sep = np.degrees(np.arccos(np.sin(a) ** 2 + np.cos(a) ** 2 * np.cos(2 * az)))
    assert k_h == pytest.approx(sep / (2 * S_DEG), abs=3e-6)


def test_flattened_moon_fit():
    """A 37 px Moon at 8 deg altitude (0.9 % flatter vertically): the centre without the
    flattening is off by about 0.1 px, with it within 0.02 px."""
    k_h, k_v = refraction_flattening(np.deg2rad(8.0), 1013.25, 10.0)
    assert 0.985 < k_v < 0.995
    cam = FisheyeCamera(8000.0, 160, 160, (79.5, 79.5), model="fisheye-equidistant")
    semi = np.deg2rad(0.265)
    rng = np.random.default_rng(3)
    errs = {False: [], True: []}
    for k in range(2):
        uv = np.array([79.5, 79.5]) + rng.uniform(-2, 2, 2)
        m = cam.image_to_direction(uv)
        up = np.array([np.cos(k), np.sin(k), 0.3])            # the zenith, some direction
        sun = np.cross(m, up) + 0.3 * m                       # lit from the side
        sun = np.array([sun[1], -sun[0], 0.2 * sun[2]]) + 0.5 * np.cross(m, sun)
        flat = (k_h, k_v, up)
        img = render_moon_fisheye(cam, m, sun, semi, noise_sigma=3, rng=k, dtype=np.float64,
                                  flattening=flat, psf_sigma_px=1.0)
        radius = 8000.0 * semi
        for use in (False, True):
            fit = extract_centre(img, camera=cam, sun_c=sun, sun_angle=_sun_angle(cam, uv, sun),
                                 radius_prior=(radius, 2e-3 * radius),
                                 flattening=flat if use else None)
            errs[use].append(np.linalg.norm(fit.uv - uv))
    assert max(errs[True]) < 0.02
    assert np.mean(errs[False]) > 0.05


def _sun_angle(cam, uv, sun):
    from photogrammetry.lunar.moon_centre import sun_direction_in_image
    return sun_direction_in_image(cam, uv, sun)
