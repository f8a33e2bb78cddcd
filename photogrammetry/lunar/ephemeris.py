"""Apparent topocentric direction of the Moon (and the Sun) at a station, offline.

Skyfield with the JPL DE421 ephemeris shipped by the ``skyfield-data`` package; UTC to
UT1 from skyfield's builtin IERS table (a user-given DUT1 overrides it); polar motion
from the IERS ``finals2000A.all`` file that ``skyfield-data`` ships.  Nothing is
downloaded.

The chain (it fixes erratum 3 of the lunar paper, ``conventions.md``):

- the hour angle is ``GAST(UT1) + lambda - alpha`` (skyfield's Earth rotation: GAST runs
  1.00273790935 times faster than UT1; the paper's ``S0 + T_ut1`` omits the factor);
- alpha, delta are the Moon's *topocentric* apparent coordinates (light time, aberration,
  precession-nutation, and the lunar parallax of up to about 1 deg);
- refraction from pressure and temperature (skyfield's formula, Bennett / Saemundsson);
- altitude and azimuth with ``atan2`` (no quadrant cases).

Horizon frame ``h`` = NED at the station (north, east, down; the INS frame ``n``).
Azimuth from north, clockwise (towards east), in [0, 2 pi).  A direction of altitude
``alt`` and azimuth ``az`` is ``r_h = (cos alt cos az, cos alt sin az, -sin alt)``.
"""
import functools
import os
import warnings
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError, InputWarning

__all__ = ["SkyDirections", "moon_sun_directions", "direction_ned", "altaz_from_hour_angle",
           "standard_pressure_hpa", "timescale_range", "refraction_flattening"]

SECONDS_PER_DAY = 86400.0
MOON_RADIUS_M = 1737.4e3


@functools.lru_cache(maxsize=1)
def _skyfield():
    """(load, wgs84, timescale with polar motion, ephemeris) from shipped files only."""
    import skyfield_data
    from skyfield.api import Loader, wgs84
    from skyfield.data import iers

    with warnings.catch_warnings():          # skyfield-data warns when its files "expire"
        warnings.simplefilter("ignore")
        path = skyfield_data.get_skyfield_data_path()
    load = Loader(path, verbose=False)        # a loader confined to the package's folder
    ts = load.timescale(builtin=True)
    finals = os.path.join(path, "finals2000A.all")
    if os.path.isfile(finals):
        with open(finals, "rb") as f:
            iers.install_polar_motion_table(ts, iers.parse_x_y_dut1_from_finals_all(f))
    eph = load(os.path.join(path, "de421.bsp"))
    return load, wgs84, ts, eph


def timescale_range():
    """UTC range of the builtin UT1 table as two skyfield ``Time`` (first, last day)."""
    _, _, ts, _ = _skyfield()
    tt = ts.delta_t_table[0]
    return ts.tt_jd(tt[0]), ts.tt_jd(tt[-1])


def standard_pressure_hpa(h):
    """Pressure of the ICAO standard atmosphere at ellipsoidal height ``h`` (m), hPa."""
    return 1013.25 * (1.0 - 2.25577e-5 * np.asarray(h, dtype=float)) ** 5.25588


def direction_ned(alt, az):
    """Unit vector(s) in NED of altitude ``alt`` and azimuth ``az`` (rad), shape (..., 3)."""
    alt, az = np.asarray(alt, float), np.asarray(az, float)
    return np.stack([np.cos(alt) * np.cos(az), np.cos(alt) * np.sin(az), -np.sin(alt)], -1)


def altaz_from_hour_angle(ha, dec, lat):
    """Altitude and azimuth (rad) from hour angle, declination and latitude (rad).

    The paper's eqs. (6)-(7) with ``atan2`` and azimuth converted from south-based
    (astronomical, positive to the west) to north-based, clockwise:
    ``sin h = sin phi sin d + cos phi cos d cos t``,
    ``A_south = atan2(cos d sin t, sin phi cos d cos t - sin d cos phi)``, ``az = A_south + pi``.
    """
    ha, dec, lat = (np.asarray(x, float) for x in (ha, dec, lat))
    alt = np.arcsin(np.clip(np.sin(lat) * np.sin(dec)
                            + np.cos(lat) * np.cos(dec) * np.cos(ha), -1, 1))
    a_south = np.arctan2(np.cos(dec) * np.sin(ha),
                         np.sin(lat) * np.cos(dec) * np.cos(ha) - np.sin(dec) * np.cos(lat))
    return alt, np.mod(a_south + np.pi, 2 * np.pi)


@dataclass
class SkyDirections:
    """Apparent topocentric directions at the exposure times.

    Attributes
    ----------
    moon_h : ndarray, shape (n, 3)
        Unit vector to the Moon's centre in the horizon frame (NED), refracted when a
        pressure was given.
    sun_h : ndarray, shape (n, 3)
        Unit vector to the Sun (NED, unrefracted; used for the lit side of the limb).
    alt, az : ndarray, shape (n,)
        The Moon's altitude and azimuth, rad (azimuth from north, clockwise).
    semidiameter : ndarray, shape (n,)
        The Moon's topocentric apparent semidiameter, rad.
    phase_angle : ndarray, shape (n,)
        Sun-Moon-observer angle, rad (0 = full Moon).
    dut1 : ndarray, shape (n,)
        UT1 - UTC used, s.
    refraction : ndarray, shape (n,)
        Refraction added to the altitude, rad (0 without pressure).
    flattening : ndarray, shape (n, 2)
        ``(k_h, k_v)``: the refracted disk's horizontal and vertical semi-axes over the
        semidiameter (`refraction_flattening`; ones without pressure).
    """
    moon_h: np.ndarray
    sun_h: np.ndarray
    alt: np.ndarray
    az: np.ndarray
    semidiameter: np.ndarray
    phase_angle: np.ndarray
    dut1: np.ndarray
    refraction: np.ndarray
    flattening: np.ndarray = None


def _times(ts, utc):
    """skyfield Time from an array of numpy datetime64 (UTC)."""
    utc = np.atleast_1d(np.asarray(utc, dtype="datetime64[ns]"))
    day0 = utc.min().astype("datetime64[D]")
    sec = (utc - day0).astype("int64") / 1e9
    y, m, d = (int(x) for x in str(day0).split("-"))
    return ts.utc(y, m, d, 0, 0, sec)


def _check_range(ts, t):
    tt = ts.delta_t_table[0]
    if np.any(t.tt < tt[0]) or np.any(t.tt > tt[-1]):
        first, last = ts.tt_jd(tt[0]).utc_strftime("%Y-%m-%d"), ts.tt_jd(tt[-1]).utc_strftime("%Y-%m-%d")
        warnings.warn(f"exposure time outside the builtin IERS UT1 table ({first} .. {last}): "
                      "UT1 is extrapolated (give --dut1 for full accuracy)", InputWarning,
                      stacklevel=3)


def moon_sun_directions(utc, lat, lon, h, pressure_hpa=None, temperature_c=10.0, dut1_s=None):
    """The Moon's apparent topocentric direction (and the Sun's) in the horizon frame.

    Parameters
    ----------
    utc : array_like of numpy.datetime64, shape (n,)
        Exposure times (mid-exposure), UTC.
    lat, lon : float
        Geodetic latitude and longitude of the station, rad (WGS84; the astronomical
        coordinates of the paper differ by the deflection of the vertical).
    h : float
        Ellipsoidal height, m.
    pressure_hpa : float or None
        Air pressure for refraction, hPa; ``None`` gives no refraction (airless).
    temperature_c : float
        Air temperature, deg C (used only with a pressure).
    dut1_s : float or None
        UT1 - UTC, s; overrides the builtin IERS table.

    Returns
    -------
    SkyDirections
    """
    _, wgs84, ts, eph = _skyfield()
    if not abs(lat) <= np.pi / 2:
        raise InputError(f"station latitude {np.rad2deg(lat)} deg is outside +-90 deg")
    t = _times(ts, utc)
    if dut1_s is not None:
        delta_t = float(np.mean(t.delta_t + t.dut1)) - float(dut1_s)   # TT - UT1, s
        ts_user = _timescale_fixed(delta_t)
        t = ts_user.tt_jd(t.tt)
    else:
        _check_range(ts, t)
    station = eph["earth"] + wgs84.latlon(np.rad2deg(lat), np.rad2deg(lon), elevation_m=h)
    obs = station.at(t)
    moon = obs.observe(eph["moon"]).apparent()
    sun = obs.observe(eph["sun"]).apparent()
    if pressure_hpa is None:
        alt, az, dist = moon.altaz()
        refr = np.zeros(len(t))
    else:
        alt, az, dist = moon.altaz(temperature_C=temperature_c, pressure_mbar=pressure_hpa)
        alt0, _, _ = moon.altaz()
        refr = alt.radians - alt0.radians
    salt, saz, _ = sun.altaz()
    r_moon = moon.position.m.T
    r_sun = sun.position.m.T
    to_sun = r_sun - r_moon
    cosphase = -np.sum(to_sun * r_moon, 1) / (np.linalg.norm(to_sun, axis=1)
                                               * np.linalg.norm(r_moon, axis=1))
    return SkyDirections(
        moon_h=direction_ned(alt.radians, az.radians), sun_h=direction_ned(salt.radians, saz.radians),
        alt=alt.radians, az=az.radians, semidiameter=np.arcsin(MOON_RADIUS_M / dist.m),
        phase_angle=np.arccos(np.clip(cosphase, -1, 1)), dut1=np.asarray(t.dut1, float),
        refraction=refr,
        flattening=(np.ones((len(refr), 2)) if pressure_hpa is None else np.column_stack(
            refraction_flattening(alt.radians, pressure_hpa, temperature_c))))


def refraction_flattening(alt, pressure_hpa, temperature_c=10.0):
    """Horizontal and vertical scale of a small disk's image by refraction.

    Refraction ``r(a)`` raises a body seen at apparent altitude ``a`` from its true
    altitude ``a - r(a)``.  A point of the disk a true angle ``delta`` above the centre
    appears ``delta / (1 - r'(a))`` above it (``a = h + r(a)`` differentiated), so the
    vertical semi-axis is the semidiameter times ``k_v = 1 / (1 - dr/da)`` (``dr/da < 0``:
    flattened).  The horizontal semi-axis keeps its azimuth span, whose angle scales with
    the cosine of the altitude: ``k_h = cos(a) / cos(a - r)``.  ``r`` is skyfield's (and
    the ephemeris') Bennett formula, ``r = c / tan(a + 7.31 / (a + 4.4))`` (degrees) with
    ``c = 0.016667 * 0.28 P / (T + 273)``, differentiated analytically.

    Parameters
    ----------
    alt : array_like
        Apparent altitude, rad.
    pressure_hpa, temperature_c : float
        The air's pressure (hPa) and temperature (deg C).

    Returns
    -------
    k_h, k_v : ndarray
        Dimensionless (1 at the zenith; ``k_v`` about 0.9946 at 10 deg altitude, 1013 hPa,
        10 deg C).
    """
    a = np.rad2deg(np.asarray(alt, float))
    c = 0.016667 * 0.28 * pressure_hpa / (temperature_c + 273.0)
    x = np.deg2rad(a + 7.31 / (a + 4.4))
    r = c / np.tan(x)                                        # deg
    dr_da = -c / np.sin(x) ** 2 * (1 - 7.31 / (a + 4.4) ** 2) * np.pi / 180
    live = (a >= -1.0) & (a <= 89.9)                         # skyfield's range
    r, dr_da = np.where(live, r, 0.0), np.where(live, dr_da, 0.0)
    k_v = 1 / (1 - dr_da)
    k_h = np.cos(np.deg2rad(a)) / np.cos(np.deg2rad(a - r))
    return k_h, k_v


@functools.lru_cache(maxsize=8)
def _timescale_fixed(delta_t):
    load, _, ts0, _ = _skyfield()
    ts = load.timescale(delta_t=delta_t)
    ts.polar_motion_table = ts0.polar_motion_table
    return ts
