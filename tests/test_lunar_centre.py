"""Moon centre from the lit limb, on rendered Moons of known centre.

The renderer point-samples 8x with hard edges and blurs with a Moffat PSF (beta 3) on
the fine grid; the centre fit assumes a Gaussian core + wing PSF, a fitted mix of four
shading laws and an anti-aliased edge, so the test is not circular (the bias across
shading laws is measured on the integrating renderer of test_lunar_truth.py).
"""
import numpy as np
import pytest

from photogrammetry.lunar.moon_centre import MoonNotFoundError, extract_centre, lit_centroid
from photogrammetry.lunar.render import render_moon

RADII = (7.5, 10.0, 20.0, 30.0)


def _trial(rng, radius, phase_deg):
    c = radius + 20 + rng.random(2)
    b = rng.uniform(0, 2 * np.pi)
    size = int(2 * radius + 40)
    img = render_moon((size, size), c, radius, phase_deg, np.rad2deg(b), noise_sigma=5,
                      rng=rng, psf="moffat")
    return img, c, b


@pytest.mark.parametrize("phase", [0, 45, 90, 120])
def test_lit_limb_centre_unbiased(phase):
    rng = np.random.default_rng(100 + phase)
    along, z2, cent = [], [], []
    for radius in RADII:
        for _ in range(5):
            img, c, b = _trial(rng, radius, phase)
            s = np.array([np.cos(b), np.sin(b)])
            m = extract_centre(img, sun_angle=b, phase_angle=np.deg2rad(phase))
            e = m.uv - c
            along.append(e @ s)
            z2.append(e @ np.linalg.solve(m.cov_uv, e) / 2)
            assert np.linalg.norm(e) < 0.1
            if radius == 20.0:
                cent.append((lit_centroid(img) - c) @ s)
    # unbiased along the Sun's direction (std of one image: about 0.01-0.02 px)
    assert abs(np.mean(along)) < 0.02
    # sigma realistic: mean squared normalized error per axis near 1
    assert 0.3 < np.mean(z2) < 3.0
    # the lit-area centroid is pulled towards the Sun by at least the uniform-disk value
    # (4 R / 3 pi)(1 - cos phase); the limb fit is not
    expect = 4 * 20.0 / (3 * np.pi) * (1 - np.cos(np.deg2rad(phase)))
    assert np.mean(cent) > 0.9 * expect - 0.05


def test_sun_side_from_image_and_errors():
    img = render_moon((100, 100), (50.3, 48.8), 20, 60, 200, noise_sigma=5, rng=1)
    m = extract_centre(img)                       # lit side estimated from the image
    assert np.linalg.norm(m.uv - (50.3, 48.8)) < 0.3
    assert abs(np.angle(np.exp(1j * (m.sun_angle - np.deg2rad(200))))) < np.deg2rad(15)
    sky = np.random.default_rng(2).normal(100, 5, (80, 80))
    with pytest.raises(MoonNotFoundError, match="no Moon"):
        extract_centre(sky)


def test_fisheye_pipeline_sigmas_honest():
    """Images to heading on rendered fisheye Moons (3.7 px radius, phase 97 deg, 24 images
    over 15 min): the centres' errors against the truth, normalized by their covariance,
    and the solution's variance factor are within their chi-square bands."""
    from scipy.stats import chi2

    from ins.nav.rotation import euler_to_dcm
    from photogrammetry.lunar import heading_from_images
    from photogrammetry.lunar.ephemeris import moon_sun_directions
    from photogrammetry.lunar.fisheye import FisheyeCamera
    from photogrammetry.lunar.render import render_moon_fisheye

    n, lat, lon = 24, np.deg2rad(40.0), np.deg2rad(116.0)
    utc = np.datetime64("2017-05-02T14:03:00") + np.arange(n) * np.timedelta64(39, "s")
    sky = moon_sun_directions(utc, lat, lon, 50.0, pressure_hpa=1000.0)
    C_hc = euler_to_dcm([0.03, 0.02, np.deg2rad(123.4)])
    full = FisheyeCamera(800.0, 1600, 1600, (799.5, 799.5), (0.002, -0.001, 0.0005))
    truth = full.direction_to_image(sky.moon_h @ C_hc)
    lo = np.floor(truth.min(0)) - 20               # a window of the frame around the track
    cam = FisheyeCamera(800.0, int(np.ptp(truth[:, 0])) + 41, int(np.ptp(truth[:, 1])) + 41,
                        tuple(np.array(full.principal_point_px) - lo), full.radial_k)
    images = [render_moon_fisheye(cam, sky.moon_h[k] @ C_hc, sky.sun_h[k] @ C_hc,
                                  sky.semidiameter[k], noise_sigma=5, rng=k) for k in range(n)]
    res = heading_from_images(cam, images, utc, lat, lon, 50.0, pressure_hpa=1000.0)
    err = res.uv - (truth - lo)
    z2 = np.array([e @ np.linalg.solve(c, e) for e, c in zip(err, res.cov_uv)])
    assert np.all(np.linalg.norm(err, axis=1) < 0.1)
    assert chi2.ppf(0.001, 2 * n) < z2.sum() < chi2.ppf(0.999, 2 * n)
    dof = 2 * n - 3
    s = res.solution
    assert chi2.ppf(0.001, dof) / dof < s.variance_factor < chi2.ppf(0.999, dof) / dof
    assert abs(np.angle(np.exp(1j * (s.heading - np.deg2rad(123.4))))) < 4 * s.heading_sigma


def test_hapke_basis_term_and_its_derivatives():
    """The fourth basis disk is Hapke's isotropic multiple scattering
    ``mu0/(mu0+mu) (H(mu0) H(mu) - 1)``, H(x) = (1+2x)/(1+2 sqrt(1-w) x), w = 0.25,
    written here from the formula; its derivatives in (c1, c2, R) match central
    differences (white-box check of the numba kernel)."""
    from photogrammetry.lunar import _limb_kernels as k
    assert k.LAWS[3] == "hapke-multiple" and k.HAPKE_W == 0.25
    rng = np.random.default_rng(3)
    a, b = np.deg2rad(50.0), 0.7                 # phase angle, Sun position angle
    sun3 = np.array([np.sin(a) * np.cos(b), np.sin(a) * np.sin(b), np.cos(a)])
    c1, c2, R, n = 30.2, 29.7, 20.0, 8
    uv = rng.uniform(8.0, 52.0, (4000, 2))
    P = np.column_stack([uv, np.zeros(len(uv))])
    z3, z23 = np.zeros(3), np.zeros((2, 3))

    def disks(c1, c2, R):
        D, dD = np.empty((4, len(P))), np.empty((4, 3, len(P)))
        k.disk_jac(P, True, c1, c2, R, z3, z3, z23, z23, sun3, z23, 1.0, 1.0, 1.0, 1.0,
                   n, D, dD)
        return D, dD

    D, dD = disks(c1, c2, R)
    X, Y = (uv[:, 0] - c1) / R, (uv[:, 1] - c2) / R
    inner = X ** 2 + Y ** 2 < 0.9 ** 2
    mu = np.sqrt(np.clip(1 - X ** 2 - Y ** 2, 0, None))
    mu0 = X * sun3[0] + Y * sun3[1] + mu * sun3[2]
    lit = inner & (mu0 > 0)
    g = np.sqrt(0.75)
    H = lambda x: (1 + 2 * x) / (1 + 2 * g * x)   # noqa: E731
    expect = mu0[lit] / (mu0[lit] + mu[lit]) * (H(mu0[lit]) * H(mu[lit]) - 1)
    assert lit.sum() > 500 and expect.max() > 0.02
    np.testing.assert_allclose(D[3, lit], expect, rtol=1e-12, atol=1e-14)
    assert np.all(D[3, inner & (mu0 < 0)] == 0)
    # derivatives: central differences, away from the edge's ramp and the terminator
    h = 1e-6
    for j, dq in enumerate(np.eye(3)):
        Dp, _ = disks(*(np.array([c1, c2, R]) + h * dq))
        Dm, _ = disks(*(np.array([c1, c2, R]) - h * dq))
        np.testing.assert_allclose(dD[3, j, lit], (Dp[3, lit] - Dm[3, lit]) / (2 * h),
                                   rtol=1e-5, atol=1e-7)
