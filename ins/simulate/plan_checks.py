"""Feasibility of a flight plan: cross-checks between its sections (the bank of the
turns, the wind, the mount) and the crab angle of the wind."""
import math

import numpy as np

from ins.common.errors import InputError
from ins.simulate.plan_model import MOUNT_KNEE

__all__ = ["check_feasible", "crab_angle", "max_crab_angle"]


def check_feasible(plan, data):
    """Cross-checks between sections: the bank of the turns, the wind and the mount.

    In the turns the mount runs into its level limit and saturates (smoothly): that is
    normal.  On the strips it must follow: the crab (both flight directions) plus the
    yaw turbulence, and the roll and pitch turbulence, must stay below the start of the
    soft limit (:data:`MOUNT_KNEE` of the azimuth and level limits), and the run-in must
    leave the servos time (3 servo lags) to recover from the turn.
    """
    src = plan.source
    f, m, tb = plan.flight, plan.mount, plan.turbulence
    air = plan.wind.speed
    if air >= 0.8 * f.ground_speed:
        raise InputError(f"[wind] speed_mps: {air:g} m/s is too strong for the ground speed "
                         f"{f.ground_speed:g} m/s (expected below 80 % of it)", path=src)
    if f.bank > f.max_bank:
        key = "bank_deg" if "bank_deg" in data.get("flight", {}) else "turn_rate_deg_s"
        raise InputError(
            f"[flight] {key}: the turns bank {math.degrees(f.bank):.2f} deg = atan(V "
            f"turn_rate / g), more than the aircraft's maximum {math.degrees(f.max_bank):g} "
            f"deg ([flight] max_bank_deg; expected a gentler turn)", path=src)
    if not m.enabled:
        return
    knee = 100 * MOUNT_KNEE
    az = plan.block.strip_azimuth
    crab = max(abs(crab_angle(f.ground_speed, plan.wind, a)) for a in (az, az + math.pi))
    yaw_turb = sum(tb.yaw_amp)
    if crab + yaw_turb >= MOUNT_KNEE * m.azimuth_limit:
        raise InputError(
            f"[wind] speed_mps: the mount cannot follow: on the strips the crab angle "
            f"{math.degrees(crab):.2f} deg (+ yaw turbulence {math.degrees(yaw_turb):.2f} "
            f"deg) exceeds {knee:g} % of the mount's azimuth limit "
            f"{math.degrees(m.azimuth_limit):g} deg ([mount] azimuth_limit_deg)", path=src)
    for name in ("roll", "pitch"):
        amp = sum(getattr(tb, f"{name}_amp"))
        if amp >= MOUNT_KNEE * m.level_limit:
            raise InputError(
                f"[turbulence] {name}_amp_deg: the mount cannot follow: the {name} "
                f"turbulence sums to {math.degrees(amp):.2f} deg, beyond {knee:g} % of the "
                f"mount's level limit {math.degrees(m.level_limit):g} deg ([mount] "
                f"level_limit_deg)", path=src)
    if plan.block.n_strips > 1 and f.run_in < 3 * m.servo_lag * f.ground_speed:
        raise InputError(
            f"[flight] run_in_m: {f.run_in:g} m leaves the mount less than 3 servo lags "
            f"({3 * m.servo_lag:g} s at {f.ground_speed:g} m/s) to recover from the turn "
            f"before the strip (expected >= {3 * m.servo_lag * f.ground_speed:g} m)",
            path=src)


def crab_angle(ground_speed, wind, track):
    """Crab angle (rad, heading minus track) flying ``track`` (rad) at ``ground_speed``."""
    wn, we = wind.w_n
    along = ground_speed - (wn * np.cos(track) + we * np.sin(track))
    right = wn * np.sin(track) - we * np.cos(track)
    return np.arctan2(right, along)


def max_crab_angle(ground_speed, wind, n=3600):
    """Largest ``|crab angle|`` (rad) over all tracks at a constant ground speed."""
    track = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    return float(np.max(np.abs(crab_angle(ground_speed, wind, track))))
