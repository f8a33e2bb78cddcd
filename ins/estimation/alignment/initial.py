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
simulated data.  The stated sigma uses the gyro that logged the window, not an assumed
grade: the larger of the stated ARW and the one measured from the scatter of the
increments, and the stated gyro bias (without ``noise``: the misfit between the
measured rate and the Earth rate, a lower bound).

Stationarity: the mean specific force must be within 5 % of normal gravity and the
mean rotation rate within ``5 sigma`` of the Earth rate (sigma from the gyro bias and
ARW: ``hypot(sqrt(3) b_g, ARW / sqrt(T))``; without ``noise``, within the Earth rate
itself plus 5 ARW sigma): a turning vehicle is refused (``InputError``).  A vehicle
that turned and came back (rocking, a turn and its return) keeps a mean rate close to
the Earth rate; the integrated rotation's departure from a constant rate, beyond
``5 ARW sqrt(T)`` and :data:`MAX_STATIC_ROTATION_DEG`, is an ``InputWarning``.

In-air start
------------
From two GNSS epochs (or the GNSS velocity columns): velocity NED, heading = track
``atan2(vE, vN)``; the position is the antenna's (the lever arm is within its sigma).
The stated accuracy is what the start really knows, because the filter needs it: in
straight level flight the heading is observable only through the Earth-rate coupling
(a heading error ``psi`` tilts the platform at ``W_ie cos(lat) psi``, which the filter
cannot tell from an east gyro bias) and the small lever-arm motion, so the forward
filter shares the observed east tilt rate between the gyro bias and the heading in
the ratio of their prior variances.  A heading sigma of 5 deg against a 1 deg/h gyro
bias (its equivalent: 1.1 deg/h) sends a correct heading several degrees off before the
first turn (the demo flight: 4 deg after 90 s; see :func:`align_gnss_heading`).

- IMU on the aircraft: heading = track + crab angle (unknown: up to ``asin(wind /
  speed)``, 8 deg at 8 m/s and 60 m/s), pitch = flight path angle (the angle of attack
  unknown), roll 0: sigmas 3, 3, 5 deg.
- IMU on a stabilized mount (``stabilized=True``): the mount keeps the platform level
  and turned to the flight line (drift compensation), so roll = pitch = 0 and heading =
  track within the mount's levelling and azimuth-tracking accuracy
  (:data:`MOUNT_LEVEL_STD_DEG`, :data:`MOUNT_AZIMUTH_STD_DEG`), to which the track's
  own noise (GNSS position noise over the 1-epoch baseline) is added.
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.nav import earth
from ins.nav.mechanization import NavState
from ins.nav.rotation import euler_to_dcm, euler_to_quat


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


#: A static window whose integrated rotation departs from a constant rate by more than
#: this (deg, and more than 5 ARW sqrt(T)) is flagged as moving.
MAX_STATIC_ROTATION_DEG = 0.05


def _check_rotation(imu, i0, i1, span, w_b, lat, noise, arw_meas, where):
    """Refuse (InputError) or flag (InputWarning) a window in which the body rotates
    (module notes).  Returns the rate misfit ``| |w_b| - W_ie |`` (rad/s)."""
    misfit = check_rate(span, w_b, noise, arw_meas, where)
    check_steady(imu, i0, i1, span, w_b, noise, arw_meas, where)
    return misfit


def check_rate(span, w_b, noise, arw_meas, where):
    """Refuse (InputError) a window whose mean rotation rate ``w_b`` (rad/s, b) is
    farther from the Earth rate than the gyro errors allow (module notes; ``noise`` an
    ``ImuNoise`` or None, ``arw_meas`` rad/sqrt(s), ``span`` s).  Returns the misfit
    ``| |w_b| - W_ie |`` (rad/s)."""
    from ins.estimation.core.error_model import DEG_SQRTH, DPH
    w_ie = earth.OMEGA_IE
    rate = float(np.linalg.norm(w_b))
    misfit = abs(rate - w_ie)
    if noise is not None:
        b_g = float(np.max(noise.gyro_bias_std_dph)) * DPH
        arw = max(float(np.max(noise.arw_deg_sqrth)) * DEG_SQRTH, arw_meas)
        allow = 5.0 * np.hypot(np.sqrt(3.0) * b_g, arw / np.sqrt(span))
        grade = (f"a gyro bias sigma of {b_g / DPH:g} deg/h and an ARW of "
                 f"{arw / DEG_SQRTH:.3g} deg/sqrt(h)")
    else:
        allow = w_ie + 5.0 * arw_meas / np.sqrt(span)
        grade = "an unknown gyro grade (no noise given)"
    if misfit > allow:
        raise InputError(f"window {where}: not stationary: the mean rotation rate is "
                         f"{np.rad2deg(rate) * 3600:.2f} deg/h against the Earth rate "
                         f"{np.rad2deg(w_ie) * 3600:.2f} deg/h (at most "
                         f"{np.rad2deg(allow) * 3600:.2f} deg/h apart for {grade}): "
                         f"the vehicle turns, or the gyro errors are larger than stated")
    return misfit


def check_steady(imu, i0, i1, span, w_b, noise, arw_meas, where):
    """Flag (InputWarning) a window whose integrated rotation departs from the constant
    rate ``w_b`` by more than ``5 ARW sqrt(T)`` and :data:`MAX_STATIC_ROTATION_DEG`
    (rocking, a turn and its return; rows ``i0 .. i1-1`` of ``imu``)."""
    import warnings

    from ins.common.errors import InputWarning
    from ins.estimation.core.error_model import DEG_SQRTH
    angle = np.cumsum(imu.dtheta_b[i0:i1], axis=0) - np.outer(
        imu.time[i0:i1] - imu.time[i0 - 1], w_b)
    dev = float(np.max(np.linalg.norm(angle, axis=1)))
    arw = arw_meas if noise is None else max(
        float(np.max(noise.arw_deg_sqrth)) * DEG_SQRTH, arw_meas)
    bound = max(5.0 * arw * np.sqrt(span), np.deg2rad(MAX_STATIC_ROTATION_DEG))
    if dev > bound:
        warnings.warn(f"window {where}: the body rotated by up to {np.rad2deg(dev):.3f} deg "
                      f"away from a constant rate during the static alignment (more than "
                      f"{np.rad2deg(bound):.3f} deg): the vehicle moved (rocked or turned "
                      f"and came back); the levelling and the heading are degraded",
                      InputWarning, stacklevel=4)


def align_static(imu, t_start, t_end, lla, noise=None):
    """Coarse alignment on the stationary window ``[t_start, t_end]`` of ``imu``.

    Parameters
    ----------
    imu : ins.nav.imu.ImuLog
    t_start, t_end : float
        Window, s.
    lla : array_like, shape (3,)
        Position of the IMU (lat, lon rad, h m), e.g. from GNSS.
    noise : ins.estimation.core.error_model.ImuNoise, optional
        The IMU's stated errors, for the stationarity test and the stated accuracy.
        Without it the accuracy uses what the window shows: the measured ARW, the
        rate misfit as gyro bias (a lower bound) and a 25 mGal accelerometer bias.

    Returns
    -------
    Alignment
        At the first IMU epoch >= ``t_start`` with zero velocity; ``att_std_deg`` from
        the gyro that logged the window (module notes).

    Raises
    ------
    InputError
        Too few epochs; a mean specific force more than 5 % from gravity; a mean
        rotation rate too far from the Earth rate (the vehicle turns).
    """
    from ins.estimation.core.error_model import DEG_SQRTH, DPH, MGAL
    i0, i1 = _window(imu, t_start, t_end)
    span = imu.time[i1 - 1] - imu.time[i0 - 1]
    f_b = imu.dvel_b[i0:i1].sum(axis=0) / span
    w_b = imu.dtheta_b[i0:i1].sum(axis=0) / span
    g = float(earth.normal_gravity(lla[0], lla[2]))
    where = f"{t_start} .. {t_end} s"
    if abs(np.linalg.norm(f_b) - g) > 0.05 * g:
        raise InputError(f"window {where} is not stationary: mean specific "
                         f"force {np.linalg.norm(f_b):.3f} m/s^2, gravity {g:.3f} m/s^2")
    # ARW from the scatter of the increments (white angle noise: std = ARW sqrt(dt))
    dt = np.diff(imu.time[i0 - 1:i1])
    rates = imu.dtheta_b[i0:i1] / dt[:, None]
    arw_meas = float(np.max(np.std(rates, axis=0)) * np.sqrt(np.median(dt)))
    misfit = _check_rotation(imu, i0, i1, span, w_b, lla[0], noise, arw_meas, where)
    rpy = static_attitude(f_b, w_b)
    if noise is None:
        acc = static_accuracy(lla[0], span, 25 * MGAL, misfit, arw_meas)
    else:
        acc = static_accuracy(lla[0], span, float(np.max(noise.accel_bias_std_mgal)) * MGAL,
                              float(np.max(noise.gyro_bias_std_dph)) * DPH,
                              max(float(np.max(noise.arw_deg_sqrth)) * DEG_SQRTH, arw_meas))
    t0 = float(imu.time[i0 - 1])
    state = NavState(np.asarray(lla, dtype=float), np.zeros(3),
                     euler_to_quat(rpy))
    return Alignment(state, t0, np.rad2deg(np.maximum(acc, 1e-7)), np.full(3, 1.0),
                     np.full(3, 0.01), "static")


#: Largest gyrocompassing heading error (deg, 1 sigma) a static alignment accepts.
MAX_STATIC_HEADING_DEG = 2.0


def check_static_heading(noise, lat, duration_s, gnss=None, fallback="gnss-heading"):
    """Refuse gyrocompassing with gyros too poor to find north.

    The heading error of :func:`static_attitude` is ``b_g / (W_ie cos lat)``: 1 deg/h of
    gyro bias (a tactical-grade IMU) gives about 4.4 deg at 30 deg latitude.  When the
    stated gyro bias (``noise.gyro_bias_std_dph``) makes it worse than
    :data:`MAX_STATIC_HEADING_DEG`, an :class:`~ins.common.errors.InputWarning` names the grade
    and the start to be used instead (``fallback``: ``"gnss-heading"``, the GNSS track
    once the vehicle moves at speed; ``"anywhere"``, velocity matching at the first
    motion, or the gyrocompass heading carried by the filter with a broad prior when
    the log never moves: :mod:`ins.estimation.alignment.motion`); ``InputError`` when
    there is no GNSS log to fall back on.

    Returns
    -------
    bool
        True when gyrocompassing is accurate enough.
    """
    import warnings

    from ins.common.errors import InputWarning
    from ins.estimation.core.error_model import DEG_SQRTH, DPH
    b_dph = float(np.max(noise.gyro_bias_std_dph))
    head = np.rad2deg(static_accuracy(lat, max(duration_s, 1.0), 0.0, b_dph * DPH,
                                      float(np.max(noise.arw_deg_sqrth)) * DEG_SQRTH)[2])
    if head <= MAX_STATIC_HEADING_DEG:
        return True
    grade = "tactical" if b_dph < 10 else "consumer/MEMS"
    msg = (f"static alignment refused: with a gyro bias of {b_dph:g} deg/h ({grade} grade) "
           f"gyrocompassing gives a heading error of {head:.1f} deg (more than "
           f"{MAX_STATIC_HEADING_DEG:g} deg)")
    if gnss is None:
        raise InputError(msg + "; give the initial heading ([alignment] method = 'given')")
    if fallback == "gnss-heading":
        tail = "the heading is taken from the GNSS track once the vehicle moves"
    else:
        tail = ("the vehicle never reaches the in-air start's speed: the heading is found "
                "at the first start, stop or turn (velocity matching), or, if it never "
                "moves, carried by the filter from the gyrocompass with a broad prior")
    warnings.warn(f"{msg}; {tail} (method '{fallback}')", InputWarning, stacklevel=3)
    return False


#: Ground speed from which the in-air start takes the heading from the track, m/s.
GNSS_HEADING_MIN_SPEED_MPS = 5.0


def gnss_heading_epoch(gnss, t_start=None, min_speed_mps=GNSS_HEADING_MIN_SPEED_MPS):
    """Index of the first GNSS epoch at or after ``t_start`` (s) whose ground speed
    reaches ``min_speed_mps`` (the in-air start's, :func:`align_gnss_heading`), or None."""
    k = 0 if t_start is None else int(np.searchsorted(gnss.time, t_start - 1e-9))
    while k + 1 < len(gnss):
        v_n = _gnss_velocity(gnss, k)
        if np.hypot(v_n[0], v_n[1]) >= min_speed_mps:
            return k
        k += 1
    return None


def _gnss_velocity(gnss, k):
    if gnss.has_velocity:
        return np.asarray(gnss.v_n[k], dtype=float)
    dt = gnss.time[k + 1] - gnss.time[k]
    return earth.ned_offset(gnss.lla[k], gnss.lla[k + 1]) / dt


#: Levelling and azimuth-tracking accuracy of a stabilized mount (deg, 1 sigma) assumed by
#: the in-air start: a servo lag of 0.1 s against 1 deg of roll turbulence at 0.1-0.6 Hz
#: leaves 0.05-0.4 deg of tilt; the drift (crab) compensation follows the flight line
#: to a few tenths of a degree.  Conservative: the demo flight's start is within 0.07 deg.
MOUNT_LEVEL_STD_DEG = 0.5
MOUNT_AZIMUTH_STD_DEG = 0.5
#: Without a mount: roll/pitch (unknown bank and angle of attack) and heading (unknown
#: crab angle) sigmas, deg.
AIRCRAFT_LEVEL_STD_DEG = 3.0
AIRCRAFT_HEADING_STD_DEG = 5.0


def _track_std(gnss, k, speed):
    """1-sigma noise (rad) of the track angle at epoch ``k`` from the GNSS noise: the
    cross-track velocity noise over the ground speed."""
    if gnss.has_velocity:
        sv = float(np.hypot(gnss.sigma_vel_ned_mps[k, 0], gnss.sigma_vel_ned_mps[k, 1])) / np.sqrt(2.0)
    else:
        dt = gnss.time[k + 1] - gnss.time[k]
        sv = float(np.hypot(np.hypot(*gnss.sigma_ned_m[k, :2]),
                            np.hypot(*gnss.sigma_ned_m[k + 1, :2]))) / np.sqrt(2.0) / dt
    return sv / speed


def align_gnss_heading(gnss, t_start=None, min_speed_mps=GNSS_HEADING_MIN_SPEED_MPS,
                       stabilized=False):
    """In-air start at the first GNSS epoch at or after ``t_start`` where the ground
    speed reaches ``min_speed_mps``.

    Uses the GNSS velocity columns when present, else the position difference of two
    epochs (velocity at their mid time, assigned to the first).  The heading is the
    track: right for a platform (stabilized mount) turned to the flight line, off by the
    crab angle otherwise (module notes).

    Parameters
    ----------
    gnss : ins.io.gnss_log.GnssLog
    t_start : float, optional
        s.
    min_speed_mps : float
        m/s.
    stabilized : bool
        The IMU sits on a stabilized mount that levels the platform and turns it to the
        flight line: roll = pitch = 0, stated sigmas :data:`MOUNT_LEVEL_STD_DEG` and
        :data:`MOUNT_AZIMUTH_STD_DEG` (plus the track noise); otherwise pitch = flight
        path angle, sigmas 3, 3, 5 deg.
    """
    k = 0 if t_start is None else int(np.searchsorted(gnss.time, t_start - 1e-9))
    speed = 0.0
    while k + 1 < len(gnss):
        v_n = _gnss_velocity(gnss, k)
        speed = np.hypot(v_n[0], v_n[1])
        if speed >= min_speed_mps:
            break
        k += 1
    else:
        raise InputError(f"ground speed too low for an in-air (gnss-heading) alignment: it "
                         f"needs two GNSS epochs with at least {min_speed_mps} m/s after "
                         f"the start {t_start} s (the last: {speed:.2f} m/s)")
    track_deg = np.rad2deg(_track_std(gnss, k, speed))
    if stabilized:
        rpy = np.array([0.0, 0.0, np.arctan2(v_n[1], v_n[0])])
        std = [MOUNT_LEVEL_STD_DEG, MOUNT_LEVEL_STD_DEG,
               np.hypot(MOUNT_AZIMUTH_STD_DEG, track_deg)]
    else:
        rpy = np.array([0.0, np.arctan2(-v_n[2], speed), np.arctan2(v_n[1], v_n[0])])
        std = [AIRCRAFT_LEVEL_STD_DEG, AIRCRAFT_LEVEL_STD_DEG,
               np.hypot(AIRCRAFT_HEADING_STD_DEG, track_deg)]
    state = NavState(gnss.lla[k].copy(), v_n, euler_to_quat(rpy))
    return Alignment(state, float(gnss.time[k]), np.array(std, dtype=float),
                     np.full(3, 3.0), np.full(3, 1.0), "gnss-heading")
