"""Moon ephemeris: against astropy (same DE421), errata of the lunar paper, offline."""
import socket
import warnings

import numpy as np
import pytest

from ins.common.errors import InputError, InputWarning
from photogrammetry.lunar import ephemeris as E

ARCSEC = np.deg2rad(1 / 3600)
LAT, LON, H = np.deg2rad(40.0), np.deg2rad(116.0), 50.0
UTC = np.datetime64("2017-05-12T15:00:00") + np.arange(4) * np.timedelta64(300, "s")


@pytest.fixture
def no_network(monkeypatch):
    def refuse(*args, **kwargs):
        raise OSError("network blocked by the test")
    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket.socket, "connect_ex", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    monkeypatch.setattr(socket, "getaddrinfo", refuse)


def _astropy_altaz(utc, pressure_hpa=0.0, temperature_c=10.0):
    pytest.importorskip("astropy")
    import os

    import astropy.units as u
    import skyfield_data
    from astropy.coordinates import AltAz, EarthLocation, get_body, solar_system_ephemeris
    from astropy.time import Time
    from astropy.utils import iers
    iers.conf.auto_download = False
    path = os.path.join(skyfield_data.get_skyfield_data_path(), "de421.bsp")
    loc = EarthLocation.from_geodetic(np.rad2deg(LON) * u.deg, np.rad2deg(LAT) * u.deg, H * u.m)
    t = Time([str(x) for x in utc.astype("datetime64[ns]")], scale="utc")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with solar_system_ephemeris.set(path):
            moon = get_body("moon", t, loc)
        aa = moon.transform_to(AltAz(obstime=t, location=loc, pressure=pressure_hpa * u.hPa,
                                     temperature=temperature_c * u.deg_C,
                                     relative_humidity=0, obswl=0.55 * u.micron))
    return aa.alt.rad, aa.az.rad


def test_offline(no_network):
    E._skyfield.cache_clear()                  # load every table again, network blocked
    E._timescale_fixed.cache_clear()
    sky = E.moon_sun_directions(UTC, LAT, LON, H, dut1_s=0.3, pressure_hpa=1000.0)
    assert np.all(np.isfinite(sky.moon_h)) and np.allclose(sky.dut1, 0.3)


def test_against_astropy():
    alt, az = _astropy_altaz(UTC)
    sky = E.moon_sun_directions(UTC, LAT, LON, H)
    assert np.abs(sky.alt - alt).max() < 0.5 * ARCSEC
    assert np.abs((sky.az - az) * np.cos(alt)).max() < 0.5 * ARCSEC


def test_refraction_against_astropy():
    sky = E.moon_sun_directions(UTC, LAT, LON, H, pressure_hpa=1000.0, temperature_c=10.0)
    alt, _ = _astropy_altaz(UTC, 1000.0, 10.0)
    alt0, _ = _astropy_altaz(UTC)
    # about 2.4 arcmin at 21 deg altitude; Bennett's formula (skyfield) and ERFA's
    # A tan z + B tan^3 z (astropy) differ by ~2.5 % there (Bennett: +-4" above 15 deg)
    assert np.all(sky.refraction > 100 * ARCSEC)
    assert np.abs(sky.refraction / (alt - alt0) - 1).max() < 0.04


def test_sidereal_rate_erratum():
    """Hour angle = GAST(UT1) + lon - RA: reproduces skyfield's alt/az through eqs. (6)-(7);
    the paper's S0 + T_ut1 (no 1.0027379 factor) is ~30 arcmin off at UT1 = 12 h."""
    _, wgs84, ts, eph = E._skyfield()
    t = ts.utc(2017, 5, 12, 12, 0, 0)
    obs = (eph["earth"] + wgs84.latlon(np.rad2deg(LAT), np.rad2deg(LON), elevation_m=H)).at(t)
    app = obs.observe(eph["moon"]).apparent()
    ra, dec, _ = app.radec(epoch="date")
    alt_ref, az_ref, _ = app.altaz()
    ha = np.deg2rad(t.gast * 15) + LON - ra.radians
    alt, az = E.altaz_from_hour_angle(ha, dec.radians, LAT)
    assert abs(alt - alt_ref.radians) < 1 * ARCSEC            # (polar motion ~0.3")
    assert abs((az - az_ref.radians) * np.cos(alt)) < 1 * ARCSEC
    ut1_h = (t.ut1 - np.floor(t.ut1 - 0.5) - 0.5) * 24
    s0 = ts.ut1_jd(np.floor(t.ut1 - 0.5) + 0.5).gast            # GAST at 0h UT1
    ha_paper = np.deg2rad((s0 + ut1_h) * 15) + LON - ra.radians
    err = np.angle(np.exp(1j * (ha_paper - ha)))
    assert 25 * 60 * ARCSEC < abs(err) < 35 * 60 * ARCSEC


def test_eq10_vector_erratum():
    """S_h' = (cos h cos A, -cos h sin A, sin h) in (south, east, up), A from south to
    west, is the NED direction; the paper's printed (.., -cos h cos A, ..) is not."""
    sky = E.moon_sun_directions(UTC, LAT, LON, H)
    A = sky.az - np.pi                                          # from south, westward
    h = sky.alt
    s_seu = np.stack([np.cos(h) * np.cos(A), -np.cos(h) * np.sin(A), np.sin(h)], -1)
    ned_from_seu = np.array([[-1, 0, 0], [0, 1, 0], [0, 0, -1]])
    assert np.allclose(s_seu @ ned_from_seu.T, sky.moon_h, atol=1e-12)
    printed = np.stack([np.cos(h) * np.cos(A), -np.cos(h) * np.cos(A), np.sin(h)], -1)
    assert np.all(np.linalg.norm(printed @ ned_from_seu.T - sky.moon_h, axis=1) > 0.1)


def _astropy_moon_sun(utc):
    """astropy's geocentric Moon (direction and distance), topocentric Moon and Sun at the
    station: the independent reference for the parallax, semidiameter and phase."""
    pytest.importorskip("astropy")
    import os

    import astropy.units as u
    import skyfield_data
    from astropy.coordinates import (
        GCRS,
        AltAz,
        EarthLocation,
        SkyCoord,
        get_body,
        solar_system_ephemeris,
    )
    from astropy.time import Time
    from astropy.utils import iers
    iers.conf.auto_download = False
    path = os.path.join(skyfield_data.get_skyfield_data_path(), "de421.bsp")
    loc = EarthLocation.from_geodetic(np.rad2deg(LON) * u.deg, np.rad2deg(LAT) * u.deg, H * u.m)
    t = Time([str(x) for x in utc.astype("datetime64[ns]")], scale="utc")
    frame = AltAz(obstime=t, location=loc)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with solar_system_ephemeris.set(path):
            geo = get_body("moon", t)
            topo = get_body("moon", t, loc)
            sun = get_body("sun", t, loc)
        # the geocentric direction as a direction only (no distance: no parallax)
        geo_aa = SkyCoord(geo.ra, geo.dec, frame=GCRS(obstime=t)).transform_to(frame)
        elongation = sun.separation(topo).rad
    r_station = np.linalg.norm(u.Quantity([loc.x, loc.y, loc.z]).to_value(u.m))
    return dict(geo_h=E.direction_ned(geo_aa.alt.rad, geo_aa.az.rad),
                geo_alt=geo_aa.alt.rad, geo_dist=geo.distance.to_value(u.m),
                topo_dist=topo.distance.to_value(u.m), sun_dist=sun.distance.to_value(u.m),
                elongation=elongation, r_station=r_station)


def test_topocentric_parallax_semidiameter_phase_against_astropy():
    """Our Moon direction is topocentric: it is the lunar parallax away from astropy's
    geocentric direction (sine rule, sin p = rho sin z / Delta_geo, about 50 arcmin here),
    and lower in the sky; the semidiameter and the phase angle follow astropy's distances
    and elongation."""
    ref = _astropy_moon_sun(UTC)
    sky = E.moon_sun_directions(UTC, LAT, LON, H)
    shift = np.arccos(np.clip(np.sum(sky.moon_h * ref["geo_h"], axis=1), -1, 1))
    z = np.pi / 2 - sky.alt
    parallax = np.arcsin(ref["r_station"] / ref["geo_dist"] * np.sin(z))
    assert np.all(parallax > np.deg2rad(0.8))
    assert np.abs(shift / parallax - 1).max() < 0.005          # measured 0.12 %
    assert np.all(sky.alt < ref["geo_alt"] - 0.9 * parallax)
    # semidiameter from the topocentric distance (the radius prior of the limb fit)
    np.testing.assert_allclose(sky.semidiameter, np.arcsin(E.MOON_RADIUS_M / ref["topo_dist"]),
                               rtol=1e-6)
    # Sun-Moon-observer angle from the elongation E and the distances:
    # tan i = R_sun sin E / (Delta - R_sun cos E)
    el, r_sun, dist = ref["elongation"], ref["sun_dist"], ref["topo_dist"]
    phase = np.arctan2(r_sun * np.sin(el), dist - r_sun * np.cos(el))
    assert np.abs(sky.phase_angle - phase).max() < 0.1 * ARCSEC      # measured 0.003"
    assert np.all(np.abs(np.linalg.norm(sky.moon_h, axis=1) - 1) < 1e-12)


def test_dut1_override_and_range():
    base = E.moon_sun_directions(UTC[:1], LAT, LON, H)
    shifted = E.moon_sun_directions(UTC[:1], LAT, LON, H, dut1_s=float(base.dut1[0]) + 1.0)
    assert np.isclose(shifted.dut1[0], base.dut1[0] + 1.0, atol=1e-6)
    # 1 s more of Earth rotation: the Moon moves ~15 arcsec * cos(dec) westward on the sky
    sep = np.arccos(np.clip(base.moon_h[0] @ shifted.moon_h[0], -1, 1))
    assert 8 * ARCSEC < sep < 16 * ARCSEC
    with pytest.warns(InputWarning, match="outside the builtin IERS"):
        E.moon_sun_directions(np.array(["2040-01-01T00:00"], "datetime64[ns]"), LAT, LON, H)
    with pytest.raises(InputError, match="latitude"):
        E.moon_sun_directions(UTC, np.deg2rad(95), LON, H)
