"""Plausibility bounds of the values the readers and the command line accept.

A value outside them is refused as bad input (:class:`~ins.common.errors.InputError`
naming the file and line, the TOML key or the option, with the bound and its unit):
they are far beyond anything a survey aircraft, a land vehicle or a handheld device
produces, so they catch typos (a lever arm in mm typed as m, a misplaced exponent) and
corrupt files before any arithmetic, not real data.
"""
import math

__all__ = ["MAX_LEVER_ARM_M", "MAX_SPEED_MPS", "MIN_HEIGHT_M", "MAX_HEIGHT_M",
           "MAX_TIME_SHIFT_S", "MAX_SIGMA_M", "out_of_bounds", "check_vector", "check_position"]

#: Largest component of a lever arm or an antenna / scanner / platform offset, m.
MAX_LEVER_ARM_M = 100.0
#: Largest component of a velocity, m/s (orbital speed is 7.8 km/s).
MAX_SPEED_MPS = 1.0e4
#: Ellipsoidal heights accepted, m (the Dead Sea shore is -430 m, the geoid at most
#: -106 m below the ellipsoid; 1000 km is far above any aircraft).
MIN_HEIGHT_M = -1.0e4
MAX_HEIGHT_M = 1.0e6
#: Largest time shift of a log, s (one GPS week).
MAX_TIME_SHIFT_S = 604800.0
#: Largest position sigma, m (larger is not a measurement: 1000 km).
MAX_SIGMA_M = 1.0e6


def out_of_bounds(value, lo=None, hi=None):
    """True when ``value`` is not a finite number within ``[lo, hi]``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return True
    return not (math.isfinite(v) and (lo is None or v >= lo) and (hi is None or v <= hi))


def check_vector(values, bound, what, unit):
    """``None`` when every component is finite with ``|x| <= bound``; else the message
    ``"{what}: component 2 is 1e+06 m, beyond +-100 m"`` (plain floats, no repr)."""
    for k, v in enumerate(values):
        v = float(v)
        if not math.isfinite(v):
            return f"{what}: component {k + 1} is {v:g}, expected a finite number ({unit})"
        if abs(v) > bound:
            return f"{what}: component {k + 1} is {v:g} {unit}, beyond +-{bound:g} {unit}"
    return None


def check_position(lat_deg, lon_deg, h_m, what):
    """``None`` for a plausible geodetic position; else a one-line message naming
    ``what`` (latitude within +-90 deg, longitude within -180..360 deg, height within
    :data:`MIN_HEIGHT_M` .. :data:`MAX_HEIGHT_M`)."""
    if out_of_bounds(lat_deg, -90.0, 90.0):
        return f"{what}: latitude {float(lat_deg):g} deg is outside +-90 deg"
    if out_of_bounds(lon_deg, -180.0, 360.0):
        return f"{what}: longitude {float(lon_deg):g} deg is outside -180 .. 360 deg"
    if out_of_bounds(h_m, MIN_HEIGHT_M, MAX_HEIGHT_M):
        return (f"{what}: height {float(h_m):g} m is outside {MIN_HEIGHT_M:g} .. "
                f"{MAX_HEIGHT_M:g} m")
    return None
