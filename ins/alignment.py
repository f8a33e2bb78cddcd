"""Initial alignment: static coarse alignment, in-air start from GNSS, or a given state.

Static coarse alignment (levelling and gyrocompassing)
------------------------------------------------------
At rest the accelerometers sense ``f_b = -C_bn g_n`` and the gyros ``w_b = C_bn w_ie_n``.
With the means over a stationary window:

- levelling: ``roll = atan2(-f_y, -f_z)``, ``pitch = atan2(f_x, hypot(f_y, f_z))``;
- gyrocompassing: the Earth rate levelled into the local horizontal plane,
  ``w_h = C_nb' w_b`` with ``C_nb'`` of roll and pitch only, points north:
  ``yaw = atan2(-w_h,y, w_h,x)``.

Accuracy (small angles, the classical error budget): a tilt error of
``b_a,h / g`` (a horizontal accelerometer bias of 50 mGal gives 10 arcsec) and a heading
error of ``b_g,east / (W_ie cos lat)`` (0.01 deg/h at 30 deg latitude gives 0.044 deg =
2.6 arcmin), to which the noise adds ``ARW / (W_ie cos lat sqrt(T))`` for a window of
``T`` seconds.  :func:`static_accuracy` gives these figures; tests check them on
simulated data.

In-air start
------------
From two GNSS epochs (or the GNSS velocity columns): velocity NED, heading = track
``atan2(vE, vN)`` (crab angle unknown: a heading sigma of a few deg), pitch = flight
path angle, roll 0; the position is the antenna's (the lever arm is within its sigma).
"""
from dataclasses import dataclass

import numpy as np

from . import earth
from .errors import InputError
from .mechanization import NavState
from .rotation import euler_to_dcm, euler_to_quat


@dataclass(frozen=True)
class Alignment:
    """Result of an alignment.

    Attributes
    ----------
    state : NavState
        Initial state at ``time``.
    time : float
        s.
    att_std_deg : ndarray, shape (3,)
        Expected accuracy of roll, pitch, heading, deg.
    pos_std_ned_m, vel_std_ned_mps : ndarray, shape (3,)
        Expected accuracy of position (m) and velocity (m/s).
    method : str
    """

    state: NavState
    time: float
    att_std_deg: np.ndarray
    pos_std_ned_m: np.ndarray
    vel_std_ned_mps: np.ndarray
    method: str


def _window(imu, t_start, t_end):
    i0 = int(np.searchsorted(imu.time, t_start, side="left")) + 1   # increments after t_start
    i1 = int(np.searchsorted(imu.time, t_end, side="right"))
    if i1 - i0 < 10:
        raise InputError(f"stationary window {t_start} .. {t_end} s holds {max(i1 - i0, 0)} "
                         f"IMU epochs (at least 10 needed)")
    return i0, i1


def static_attitude(f_b, w_b):
    """Roll, pitch, yaw (rad) from the mean specific force (m/s^2) and rate (rad/s) in b."""
    fx, fy, fz = f_b
    roll = np.arctan2(-fy, -fz)
    pitch = np.arctan2(fx, np.hypot(fy, fz))
    w_h = euler_to_dcm([roll, pitch, 0.0]) @ np.asarray(w_b, dtype=float)
    yaw = np.arctan2(-w_h[1], w_h[0])
    return np.array([roll, pitch, yaw])


def static_accuracy(lat, duration_s, accel_bias_mps2, gyro_bias_rps, arw_rad_sqrts):
    """Expected 1-sigma roll, pitch, heading errors (rad) of :func:`static_attitude`."""
    g = float(earth.normal_gravity(lat, 0.0))
    w_h = earth.OMEGA_IE * np.cos(lat)
    tilt = accel_bias_mps2 / g
    heading = np.hypot(gyro_bias_rps, arw_rad_sqrts / np.sqrt(duration_s)) / w_h
    return np.array([tilt, tilt, heading])


def align_static(imu, t_start, t_end, lla, noise=None):
    """Coarse alignment on the stationary window ``[t_start, t_end]`` of ``imu``.

    Parameters
    ----------
    imu : ins.imu.ImuLog
    t_start, t_end : float
        Window, s.
    lla : array_like, shape (3,)
        Position of the IMU (lat, lon rad, h m), e.g. from GNSS.
    noise : ins.error_model.ImuNoise, optional
        For the stated accuracy (default: a navigation-grade 0.01 deg/h, 25 mGal).

    Returns
    -------
    Alignment
        At the first IMU epoch >= ``t_start`` with zero velocity.
    """
    from .error_model import DEG_SQRTH, DPH, MGAL
    i0, i1 = _window(imu, t_start, t_end)
    span = imu.time[i1 - 1] - imu.time[i0 - 1]
    f_b = imu.dvel_b[i0:i1].sum(axis=0) / span
    w_b = imu.dtheta_b[i0:i1].sum(axis=0) / span
    g = float(earth.normal_gravity(lla[0], lla[2]))
    if abs(np.linalg.norm(f_b) - g) > 0.05 * g:
        raise InputError(f"window {t_start} .. {t_end} s is not stationary: mean specific "
                         f"force {np.linalg.norm(f_b):.3f} m/s^2, gravity {g:.3f} m/s^2")
    rpy = static_attitude(f_b, w_b)
    if noise is None:
        acc = static_accuracy(lla[0], span, 25 * MGAL, 0.01 * DPH, 0.003 * DEG_SQRTH)
    else:
        acc = static_accuracy(lla[0], span, float(np.max(noise.accel_bias_std_mgal)) * MGAL,
                              float(np.max(noise.gyro_bias_std_dph)) * DPH,
                              float(np.max(noise.arw_deg_sqrth)) * DEG_SQRTH)
    t0 = float(imu.time[i0 - 1])
    state = NavState(np.asarray(lla, dtype=float), np.zeros(3),
                     euler_to_quat(rpy))
    return Alignment(state, t0, np.rad2deg(np.maximum(acc, 1e-7)), np.full(3, 1.0),
                     np.full(3, 0.01), "static")


def align_gnss_heading(gnss, t_start=None):
    """In-air start from the first two GNSS epochs at or after ``t_start``.

    Uses the GNSS velocity columns when present, else the position difference of the
    two epochs (velocity at their mid time, assigned to the first).
    """
    k = 0 if t_start is None else int(np.searchsorted(gnss.time, t_start - 1e-9))
    if k + 1 >= len(gnss):
        raise InputError("an in-air (gnss-heading) alignment needs two GNSS epochs after "
                         f"the start {t_start} s")
    lla = gnss.lla[k]
    if gnss.has_velocity:
        v_n = gnss.vel_n[k]
    else:
        dt = gnss.time[k + 1] - gnss.time[k]
        v_n = earth.ned_offset(gnss.lla[k], gnss.lla[k + 1]) / dt
    speed = np.hypot(v_n[0], v_n[1])
    if speed < 5.0:
        raise InputError(f"ground speed {speed:.2f} m/s at t = {gnss.time[k]} s is too low "
                         f"for a heading from the GNSS track (at least 5 m/s)")
    rpy = np.array([0.0, np.arctan2(-v_n[2], speed), np.arctan2(v_n[1], v_n[0])])
    state = NavState(lla.copy(), np.asarray(v_n, dtype=float),
                     euler_to_quat(rpy))
    return Alignment(state, float(gnss.time[k]), np.array([3.0, 3.0, 5.0]),
                     np.full(3, 3.0), np.full(3, 1.0), "gnss-heading")
