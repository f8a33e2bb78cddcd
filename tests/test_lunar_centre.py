"""Moon centre from the lit limb, on rendered Moons of known centre."""
import numpy as np
import pytest

from photogrammetry.lunar.moon_centre import MoonNotFoundError, extract_centre, lit_centroid
from photogrammetry.lunar.render import render_moon


@pytest.mark.parametrize("radius", [10.0, 30.0])
def test_lit_limb_centre_unbiased(radius):
    rng = np.random.default_rng(7)
    for phase in (0, 45, 90, 120):
        along, cent = [], []
        for _ in range(6):
            c = radius + 30 + rng.random(2)
            b = rng.uniform(0, 2 * np.pi)
            s = np.array([np.cos(b), np.sin(b)])
            size = int(2 * radius + 60)
            img = render_moon((size, size), c, radius, phase, np.rad2deg(b), noise_sigma=5, rng=rng)
            m = extract_centre(img, sun_angle=b)
            along.append((m.uv - c) @ s)
            cent.append((lit_centroid(img) - c) @ s)
            assert np.linalg.norm(m.uv - c) < (0.6 if phase <= 90 else 1.2)
        # the lit-area centroid is pulled towards the Sun, at least by the uniform-disk
        # value (4 R / 3 pi)(1 - cos phase); the limb fit is not
        expect = 4 * radius / (3 * np.pi) * (1 - np.cos(np.deg2rad(phase)))
        assert np.mean(cent) > 0.9 * expect - 0.05
        assert abs(np.mean(along)) < max(0.25, 0.05 * np.mean(cent))


def test_sun_side_from_image_and_errors():
    img = render_moon((100, 100), (50.3, 48.8), 20, 60, 200, noise_sigma=5, rng=1)
    m = extract_centre(img)                       # lit side estimated from the image
    assert np.linalg.norm(m.uv - (50.3, 48.8)) < 0.3
    assert abs(np.angle(np.exp(1j * (m.sun_angle - np.deg2rad(200))))) < np.deg2rad(15)
    sky = np.random.default_rng(2).normal(100, 5, (80, 80))
    with pytest.raises(MoonNotFoundError, match="no Moon"):
        extract_centre(sky)
