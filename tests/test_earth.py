"""ins.nav.earth against closed forms, pymap3d and the GRS80 normal-gravity field."""
import numpy as np
import pymap3d
import pytest
from pymap3d import rcurve

from ins.nav import earth

RNG = np.random.default_rng(7)
LAT = np.deg2rad(RNG.uniform(-89.9, 89.9, 500))
H = RNG.uniform(-400.0, 12000.0, 500)
WGS84 = pymap3d.Ellipsoid.from_name("wgs84")


def test_constants_match_pymap3d():
    assert earth.A == WGS84.semimajor_axis
    assert earth.F == pytest.approx(WGS84.flattening, rel=1e-15)
    assert earth.E2 == pytest.approx(WGS84.eccentricity ** 2, rel=1e-14)


def test_radii_against_pymap3d():
    M, N = earth.radii(LAT)
    np.testing.assert_allclose(M, rcurve.meridian(LAT, WGS84, deg=False), rtol=1e-14)
    np.testing.assert_allclose(N, rcurve.transverse(LAT, WGS84, deg=False), rtol=1e-14)


def test_radii_are_derivatives_of_ecef_arc():
    # M = |d r_e / d lat|, (N) cos(lat) = |d r_e / d lon| on the ellipsoid (h = 0)
    lat = np.deg2rad(np.array([0.0, 12.0, 45.0, 67.0, 89.0]))
    d = 1e-7
    x1 = np.array(pymap3d.geodetic2ecef(lat + d, 0.0 * lat, 0.0 * lat, WGS84, deg=False)).T
    x0 = np.array(pymap3d.geodetic2ecef(lat - d, 0.0 * lat, 0.0 * lat, WGS84, deg=False)).T
    M, N = earth.radii(lat)
    np.testing.assert_allclose(np.linalg.norm(x1 - x0, axis=1) / (2 * d), M, rtol=1e-8)
    y1 = np.array(pymap3d.geodetic2ecef(lat, 0.0 * lat + d, 0.0 * lat, WGS84, deg=False)).T
    y0 = np.array(pymap3d.geodetic2ecef(lat, 0.0 * lat - d, 0.0 * lat, WGS84, deg=False)).T
    np.testing.assert_allclose(np.linalg.norm(y1 - y0, axis=1) / (2 * d), N * np.cos(lat),
                               rtol=1e-8)


def _grs80_normal_gravity(lat, h):
    """Somigliana's closed form on GRS80 and its second-order height expansion
    (Moritz 1980 / Hofmann-Wellenhof & Moritz eq. 2-215): an independent reference."""
    a, f = 6378137.0, 1 / 298.257222101
    gm, omega = 3.986005e14, 7.292115e-5
    b = a * (1 - f)
    e2 = f * (2 - f)
    ge, gp = 9.7803267715, 9.8321863685                 # GRS80 equatorial/polar gravity
    k = b * gp / (a * ge) - 1
    s2 = np.sin(lat) ** 2
    g0 = ge * (1 + k * s2) / np.sqrt(1 - e2 * s2)
    m = omega ** 2 * a ** 2 * b / gm
    return g0 * (1 - 2 / a * (1 + f + m - 2 * f * s2) * h + 3 / a ** 2 * h ** 2)


def test_normal_gravity_against_somigliana():
    g = earth.normal_gravity(LAT, H)
    # The a1..a6 series is a fit to the closed form: agreement to 0.15 mGal up to 12 km
    # (the worst place is the pole, 0.12 mGal).
    np.testing.assert_allclose(g, _grs80_normal_gravity(LAT, H), atol=1.5e-6)
    np.testing.assert_allclose(earth.normal_gravity(np.deg2rad(45.0), 0.0),
                               _grs80_normal_gravity(np.deg2rad(45.0), 0.0), atol=1e-7)


def test_normal_gravity_published_values():
    assert earth.normal_gravity(0.0, 0.0) == pytest.approx(9.7803267715, abs=1e-10)
    # GRS80 normal gravity at the pole: 9.8321863685 m/s^2; the series is 0.12 mGal low
    assert earth.normal_gravity(np.pi / 2, 0.0) == pytest.approx(9.8321863685, abs=1.5e-6)
    # free-air gradient about -0.3086 mGal/m at mid latitudes
    dg = earth.normal_gravity(np.deg2rad(45), 1.0) - earth.normal_gravity(np.deg2rad(45), 0.0)
    assert dg == pytest.approx(-3.086e-6, rel=2e-3)


def test_gravity_vector_points_down():
    g = earth.gravity_n(LAT[:3], H[:3])
    assert g.shape == (3, 3)
    np.testing.assert_array_equal(g[:, :2], 0.0)
    np.testing.assert_allclose(g[:, 2], earth.normal_gravity(LAT[:3], H[:3]))


def _C_ne(lat, lon):
    """NED axes from pymap3d (an ECEF unit step along each NED axis), as rows of C_ne."""
    rows = []
    for n, e, d in np.eye(3):
        rows.append(pymap3d.enu2ecefv(e, n, -d, lat, lon, deg=False))
    return np.array(rows)


def test_earth_rate_is_projection_of_ecef_rate():
    for lat, lon in zip(LAT[:20], RNG.uniform(-np.pi, np.pi, 20)):
        w_ie_n = _C_ne(lat, lon) @ np.array([0.0, 0.0, earth.OMEGA_IE])
        np.testing.assert_allclose(earth.earth_rate_n(lat), w_ie_n, atol=1e-18)


def test_dcm_en_against_pymap3d():
    for lat, lon in zip(LAT[:20], RNG.uniform(-np.pi, np.pi, 20)):
        np.testing.assert_allclose(earth.dcm_en(lat, lon), _C_ne(lat, lon).T, atol=1e-15)


def test_transport_rate_and_lla_rate_by_finite_differences():
    """Move a point with a NED velocity in ECEF (pymap3d), differentiate lat/lon/h and the
    NED frame: w_en_n from C_en^T dC_en/dt and D^-1 v from the positions."""
    for lat, h in zip(LAT[:30], H[:30]):
        if abs(lat) > np.deg2rad(85):
            continue
        lon = 0.3
        v_n = RNG.normal(0, 150, 3)
        x0 = np.array(pymap3d.geodetic2ecef(lat, lon, h, deg=False))
        v_e = _C_ne(lat, lon).T @ v_n
        dt = 0.05   # s; long enough that pymap3d's 1e-9 m height noise is negligible
        llas = []
        for s in (-1, 1):
            llas.append(np.array(pymap3d.ecef2geodetic(*(x0 + s * dt * v_e), deg=False)))
        rate_fd = (llas[1] - llas[0]) / (2 * dt)
        rate = earth.lla_rate(lat, h, v_n)
        np.testing.assert_allclose(rate[:2], rate_fd[:2], rtol=1e-7, atol=1e-15)
        np.testing.assert_allclose(rate[2], rate_fd[2], atol=1e-7)   # m/s
        C1 = _C_ne(*llas[1][:2]).T
        C0 = _C_ne(*llas[0][:2]).T
        Om = _C_ne(lat, lon) @ (C1 - C0) / (2 * dt)
        w_fd = np.array([Om[2, 1], Om[0, 2], Om[1, 0]])
        np.testing.assert_allclose(earth.transport_rate_n(lat, h, v_n), w_fd, rtol=1e-6,
                                   atol=1e-13)


def test_broadcasting_and_shapes():
    assert earth.transport_rate_n(0.5, 100.0, [10.0, 20.0, 0.0]).shape == (3,)
    assert earth.transport_rate_n(LAT[:4], 100.0, [10.0, 20.0, 0.0]).shape == (4, 3)
    assert earth.earth_rate_n(LAT[:4]).shape == (4, 3)
    with pytest.raises(ValueError, match="v_n"):
        earth.transport_rate_n(0.5, 100.0, [1.0, 2.0])


def test_ned_offset_against_pymap3d():
    a = np.array([np.deg2rad(30.4), np.deg2rad(114.5), 1000.0])
    b = np.array([np.deg2rad(30.5), np.deg2rad(114.3), 1230.0])
    ref = pymap3d.geodetic2ned(b[0], b[1], b[2], a[0], a[1], a[2], deg=False)
    np.testing.assert_allclose(earth.ned_offset(a, b), ref, atol=1e-8)


def test_offset_lla_against_pymap3d_and_inverse_of_ned_offset():
    rng = np.random.default_rng(7)
    lla = np.column_stack([np.deg2rad(rng.uniform(-80, 80, 20)),
                           np.deg2rad(rng.uniform(-180, 180, 20)), rng.uniform(-50, 3000, 20)])
    off = rng.uniform(-2000, 2000, (20, 3))
    got = earth.offset_lla(lla, off)
    lat, lon, h = pymap3d.ned2geodetic(off[:, 0], off[:, 1], off[:, 2], lla[:, 0], lla[:, 1],
                                       lla[:, 2], deg=False)
    assert np.allclose(got[:, 0], lat, atol=1e-12) and np.allclose(got[:, 1], lon, atol=1e-12)
    assert np.allclose(got[:, 2], h, atol=1e-6)
    assert np.allclose(earth.ned_offset(lla, got), off, atol=1e-6)
