"""The independent renderer of ``tests/lunar_truth.py`` against closed forms, then the
centre fit's bias on its images across shading laws, phases, radii, blur and saturation.

Closed forms (R the radius, a the phase angle): lit area of a flat phased disk
``pi R^2 (1 + cos a) / 2`` with its centroid ``4 R (1 - cos a) / (3 pi)`` towards the
Sun; Lambert's integrated brightness ``(2/3) R^2 (sin a + (pi - a) cos a)``;
Lommel-Seeliger's ``(pi R^2 / 2) (1 - sin(a/2) tan(a/2) ln cot(a/4))``.
"""
import numpy as np
import pytest
from lunar_truth import LAWS, cell_integrals, render

from photogrammetry.lunar.moon_centre import extract_centre


def _closed_form(law, R, a):
    if law == "flat":
        return np.pi * R * R * (1 + np.cos(a)) / 2
    if law == "lambert":
        return 2 / 3 * R * R * (np.sin(a) + (np.pi - a) * np.cos(a))
    if a == 0:
        return np.pi * R * R / 2
    return np.pi * R * R / 2 * (1 - np.sin(a / 2) * np.tan(a / 2) * np.log(1 / np.tan(a / 4)))


@pytest.mark.parametrize("law", ["flat", "lambert", "lommel-seeliger"])
@pytest.mark.parametrize("phase_deg", [0, 40, 100, 140])
def test_cell_integrals_closed_forms(law, phase_deg):
    R, c, n = 9.3, (20.37, 19.81), 8
    a = np.deg2rad(phase_deg)
    b = 0.7                                                   # Sun's direction on the image
    F = cell_integrals((42, 42), c, R, (np.sin(a) * np.cos(b), np.sin(a) * np.sin(b),
                                       np.cos(a)), law, a, n)
    assert F.sum() == pytest.approx(_closed_form(law, R, a), rel=5e-4)
    cu = (np.arange(42 * n) + 0.5) / n - 0.5
    centroid = np.array([F.sum(0) @ cu, F.sum(1) @ cu]) / F.sum() - c
    if law == "flat":
        expect = 4 * R * (1 - np.cos(a)) / (3 * np.pi) * np.array([np.cos(b), np.sin(b)])
        np.testing.assert_allclose(centroid, expect, atol=2e-3)
    else:                                     # symmetric about the Sun's direction
        assert abs(centroid @ [-np.sin(b), np.cos(b)]) < 2e-3


def test_blur_keeps_flux_and_centre():
    c = (30.4, 29.65)
    uu, vv = np.meshgrid(np.arange(60), np.arange(60))
    for sigma in (0.0, 1.5):
        img = render((60, 60), c, 12, 0, 0, "lambert", sigma_px=sigma, peak=None,
                     background=0)
        assert img.sum() == pytest.approx(_closed_form("lambert", 12, 0.0), rel=1e-5)
        np.testing.assert_allclose([(img * uu).sum(), (img * vv).sum()] / img.sum(), c,
                                   atol=1e-3)


def _bias(law, phase, R, sigma=0.8, saturation=None, trials=4, seed=0):
    """Mean error of the centre along the Sun's direction, px (noise 3 of 3000 counts)."""
    rng = np.random.default_rng(seed)
    along = []
    for _ in range(trials):
        size = int(2 * R + 30)
        c = np.array([size / 2, size / 2]) + rng.random(2)
        b = rng.uniform(0, 2 * np.pi)
        sat = None if saturation is None else 100 + saturation * 3000
        img = render((size, size), c, R, phase, np.rad2deg(b), law, sigma, noise_sigma=3,
                     rng=rng, saturation=sat)
        m = extract_centre(img, sun_angle=b, phase_angle=np.deg2rad(phase),
                           radius_prior=(R, 2e-3 * R),
                           saturation=None if sat is None else sat - 1e-6)
        along.append((m.uv - c) @ [np.cos(b), np.sin(b)])
    return np.mean(along)


@pytest.mark.parametrize("law", LAWS[:4])
def test_centre_bias_across_laws(law):
    """Under 0.02 px whatever the shading (the fit's law is a free mix of four)."""
    for phase, R in [(0, 5.0), (70, 9.0), (140, 20.0)]:
        assert abs(_bias(law, phase, R)) < 0.02, (law, phase, R)


@pytest.mark.slow
@pytest.mark.parametrize("law", LAWS[:4])
def test_centre_bias_blur_and_saturation(law):
    assert abs(_bias(law, 60, 12.0, sigma=1.6)) < 0.02
    assert abs(_bias(law, 60, 12.0, saturation=0.6)) < 0.02


@pytest.mark.slow
def test_centre_bias_hapke_large_crescent():
    """The corner the three-law basis missed (0.021-0.030 px): a Hapke-like law on a
    40 px Moon at phase 120-140 deg; the fitted mix now includes Hapke's multiple
    scattering term, so the bias stays under 0.02 px (measured 0.003-0.004 px)."""
    for phase in (120, 140):
        assert abs(_bias("hapke", phase, 40.0, trials=3)) < 0.02, phase
