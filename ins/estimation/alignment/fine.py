"""Alignment of an IMU at rest without GNSS: coarse levelling and gyrocompassing, then a
fine alignment by a Kalman filter with zero-velocity updates (``ins align``).

Frames and conventions: ``n`` north-east-down, ``b`` forward-right-down,
``C_nb = Rz(yaw) Ry(pitch) Rx(roll)``; the error states are those of
:mod:`ins.estimation.core.error_model` (attitude error ``phi`` in ``n``,
``C_nb_est = (I - [phi x]) C_nb_true``; bias errors truth minus estimate).

Coarse
------
Roll and pitch from the mean specific force, heading from the mean rate levelled into
the horizontal plane (:func:`ins.estimation.alignment.initial.static_attitude`).

Fine
----
The IMU rows of the window are mechanized with the current bias estimates removed
(:func:`ins.estimation.core._filter_kernels.propagate_rows`, the forward filter's loop), and
every ``step_s`` the 15 error states (position, velocity, attitude, gyro bias,
accelerometer bias; :func:`ins.estimation.core.error_model.interval_matrix`,
:func:`~ins.estimation.core.error_model.discretize`) are propagated and updated with the
velocity being zero (``R = zupt_sigma_mps^2``), the errors fed back (closed loop).
The heading prior is broad (:data:`HEADING_PRIOR_DEG`): the heading comes from the data.

What the data support (error budget, small angles)
--------------------------------------------------
At rest the east gyro bias and the heading error are one observable: a heading error
``psi`` tilts the computed platform about east at ``W_ie cos(lat) psi``, exactly what an
east gyro bias ``b_E`` does.  The filter therefore cannot beat

    sigma_psi^2 = (sigma_bE^2 + ARW^2 / T) / (W_ie cos lat)^2

(the gyro bias prior projected on east, and the angle random walk over the window's
length ``T``); likewise a horizontal accelerometer bias is one with a tilt:
``sigma_tilt = sigma_ba / g``.  Its stated sigmas are these figures (the filter's
covariance); :func:`heading_budget` gives them in closed form.

Where the gyro errors come from: the options (prior sigma of the gyro bias, ARW), or
when not given, from the log itself: the ARW and VRW from the sample-to-sample scatter
of the increments (the first differences: a bias and its drift do not count); the gyro bias sigma from the two components of the bias that ARE
observable at rest, north and down (the measured rate in ``n`` less the Earth rate),
``sigma_b^2 = (b_N^2 + b_D^2) / 2 - ARW^2 / T``: a two-sample estimate (uncertain by a
factor of about two, heavy tailed), which the output says; the accelerometer bias
sigma from the one observable component, the vertical (``| |f| - g |``, at least
:data:`MIN_ACCEL_BIAS_MGAL`; it also holds the gravity anomaly).  A stated ARW/VRW
smaller than the log's is raised to the log's.

The heading is unknown when ``sigma_psi`` exceeds ``max_heading_std`` (default
:data:`MAX_HEADING_STD_DEG`): the gyro cannot resolve the Earth rate's horizontal
component (``W_ie cos lat``, 13 deg/h at 30 deg) over the window (a consumer MEMS gyro
with 0.5 deg/s = 1800 deg/h of bias; any gyro near the poles); roll and pitch are then
given from the coarse levelling (sigma ``hypot(sigma_ba, VRW / sqrt(T)) / g``).
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.estimation.alignment.initial import _window, check_rate, check_steady, static_attitude
from ins.nav import earth
from ins.nav.rotation import dcm_to_euler, euler_to_dcm, euler_to_quat, quat_to_dcm, rotvec_to_dcm

#: 1-sigma heading (deg) above which the heading is reported unknown.
MAX_HEADING_STD_DEG = 10.0
#: Prior sigma of the heading of the fine filter (deg): broad, the data decide.
HEADING_PRIOR_DEG = 30.0
#: Prior sigma of roll and pitch of the fine filter (deg).
TILT_PRIOR_DEG = 1.0
#: Floor of the accelerometer bias sigma estimated from the log (mGal).
MIN_ACCEL_BIAS_MGAL = 25.0
#: Largest departure of the mean specific force from normal gravity (fraction).
GRAVITY_TOLERANCE = 0.05


@dataclass(frozen=True)
class RestNoise:
    """The IMU errors an alignment used (SI, per body axis x, y, z) and where each came
    from (``sources``: ``"given"``, ``"log"`` or ``"given, raised to the log's"``).

    Attributes
    ----------
    arw : ndarray (3,)
        rad/sqrt(s).
    vrw : ndarray (3,)
        m/s/sqrt(s).
    gyro_bias_std : ndarray (3,)
        rad/s.
    accel_bias_std : ndarray (3,)
        m/s^2.
    sources : dict
        Keys ``arw``, ``vrw``, ``gyro_bias_std``, ``accel_bias_std``.
    """

    arw: np.ndarray
    vrw: np.ndarray
    gyro_bias_std: np.ndarray
    accel_bias_std: np.ndarray
    sources: dict


@dataclass(frozen=True)
class RestAlignment:
    """Result of :func:`align_at_rest` (rad, s, SI).

    Attributes
    ----------
    time, time_end : float
        First and last IMU epoch of the window (s); the attitude holds for the whole
        window (at rest).
    lla : ndarray (3,)
        lat, lon (rad), h (m), as given.
    rpy : ndarray (3,)
        Roll, pitch, yaw (rad), yaw in (-pi, pi]; yaw NaN when the heading is unknown.
    rpy_std : ndarray (3,)
        1-sigma (rad); the heading's NaN when unknown.
    heading_known : bool
    heading_std_bias, heading_std_noise : float
        The two parts of the heading sigma (rad, :func:`heading_budget`): the east gyro
        bias prior and the ARW over the window.
    coarse_rpy : ndarray (3,)
        The coarse (levelling and gyrocompassing) angles, rad.
    gyro_bias_b, accel_bias_b : ndarray (3,)
        Bias estimates of the fine filter (rad/s, m/s^2); NaN without it.
    noise : RestNoise
    n_updates : int
        Zero-velocity updates of the fine filter (0: levelling only).
    nis_mean : float
        Mean normalized innovation squared of the updates (3 expected; much larger:
        the IMU moved or vibrated more than the noise model says).
    method : str
        ``"fine"`` or ``"level"``.
    """

    time: float
    time_end: float
    lla: np.ndarray
    rpy: np.ndarray
    rpy_std: np.ndarray
    heading_known: bool
    heading_std_bias: float
    heading_std_noise: float
    coarse_rpy: np.ndarray
    gyro_bias_b: np.ndarray
    accel_bias_b: np.ndarray
    noise: RestNoise
    n_updates: int
    nis_mean: float
    method: str

    @property
    def duration_s(self):
        return self.time_end - self.time


def white_noise(increments, dt):
    """Per-axis white-noise density (unit/sqrt(s)) of increments sampled every ``dt``
    (s), from the scatter of their first differences (a bias and its slow drift drop
    out; a median-based estimate would be biased by a quantization of the increments
    comparable to their noise)."""
    d = np.diff(np.asarray(increments, dtype=float), axis=0)
    return np.std(d, axis=0) / np.sqrt(2.0 * dt)


def heading_budget(C_nb, lat, duration_s, gyro_bias_std, arw):
    """The two parts of the heading sigma (rad) at rest: ``(sigma_bE, ARW_E / sqrt(T))``
    over ``W_ie cos lat`` with the per-axis gyro bias sigma (rad/s) and ARW
    (rad/sqrt(s)) projected on east through ``C_nb``."""
    east = np.asarray(C_nb)[1] ** 2
    w_h = earth.OMEGA_IE * np.cos(lat)
    return (float(np.sqrt(east @ np.asarray(gyro_bias_std) ** 2)) / w_h,
            float(np.sqrt(east @ np.asarray(arw) ** 2 / duration_s)) / w_h)


def _per_axis(value):
    return None if value is None else np.broadcast_to(np.asarray(value, float), 3).copy()


def _noise(imu, i0, i1, span, lat, rpy0, w_b, f_b, g, arw, vrw, gyro_bias_std,
           accel_bias_std):
    dt = float(np.median(np.diff(imu.time[i0 - 1:i1])))
    arw_log = white_noise(imu.dtheta_b[i0:i1], dt)
    vrw_log = white_noise(imu.dvel_b[i0:i1], dt)
    src = {}
    values = {}
    for key, given, log in (("arw", arw, arw_log), ("vrw", vrw, vrw_log)):
        given = _per_axis(given)
        if given is None:
            values[key], src[key] = log, "log"
        elif np.any(log > 1.05 * given):
            values[key], src[key] = np.maximum(given, log), "given, raised to the log's"
        else:
            values[key], src[key] = given, "given"
    if gyro_bias_std is None:
        # the observable components of the bias: north and down of the rate in n
        b_n = euler_to_dcm(rpy0) @ w_b - earth.earth_rate_n(lat)
        var = 0.5 * (b_n[0] ** 2 + b_n[2] ** 2) - float(np.mean(values["arw"] ** 2)) / span
        values["gyro_bias_std"] = np.full(3, np.sqrt(max(var, 0.0)))
        src["gyro_bias_std"] = "log"
    else:
        values["gyro_bias_std"], src["gyro_bias_std"] = _per_axis(gyro_bias_std), "given"
    if accel_bias_std is None:
        s_a = max(abs(float(np.linalg.norm(f_b)) - g), MIN_ACCEL_BIAS_MGAL * 1e-5)
        values["accel_bias_std"], src["accel_bias_std"] = np.full(3, s_a), "log"
    else:
        values["accel_bias_std"], src["accel_bias_std"] = _per_axis(accel_bias_std), "given"
    return RestNoise(sources=src, **values)


def align_at_rest(imu, lla, t_start=None, t_end=None, *, arw=None, vrw=None,
                  gyro_bias_std=None, accel_bias_std=None, level_only=False,
                  max_heading_std=np.deg2rad(MAX_HEADING_STD_DEG), zupt_sigma_mps=1e-3,
                  step_s=1.0):
    """Coarse and fine alignment of an IMU at rest on ``[t_start, t_end]`` (module notes).

    Parameters
    ----------
    imu : ins.nav.imu.ImuLog
    lla : array_like (3,)
        lat, lon (rad), ellipsoidal height (m) of the IMU.
    t_start, t_end : float, optional
        Window, s (default: the whole log).
    arw, vrw : float or array_like (3,), optional
        Angle random walk (rad/sqrt(s)), velocity random walk (m/s/sqrt(s)); default
        from the log.
    gyro_bias_std, accel_bias_std : float or array_like (3,), optional
        Prior 1-sigma of the gyro bias (rad/s) and accelerometer bias (m/s^2) per axis
        over the window (turn-on bias and instability); default estimated from the log.
    level_only : bool
        Roll and pitch only (no fine filter, heading unknown).
    max_heading_std : float
        rad; a larger heading sigma makes the heading unknown.
    zupt_sigma_mps : float
        Sigma of the zero-velocity measurement, m/s (vibration, sway).
    step_s : float
        Interval of the filter's covariance steps and updates, s.

    Returns
    -------
    RestAlignment

    Raises
    ------
    InputError
        A latitude outside +-90 deg; a window with fewer than 10 epochs; a log that moves
        (mean specific force more than 5 % from gravity, window means of the rate or
        specific force departing from the median: :func:`ins.estimation.alignment.static_check.static_check`;
        with a stated gyro bias, a mean rate too far from the Earth rate).
    """
    from ins.estimation.alignment.static_check import static_check
    from ins.estimation.core.error_model import DEG_SQRTH, DPH, ImuNoise
    lla = np.asarray(lla, dtype=float)
    if not abs(lla[0]) <= np.pi / 2:
        raise InputError(f"latitude {np.rad2deg(lla[0]):g} deg is outside +-90 deg")
    t_start = float(imu.time[0]) if t_start is None else float(t_start)
    t_end = float(imu.time[-1]) if t_end is None else float(t_end)
    i0, i1 = _window(imu, t_start, t_end)
    t0, t1 = float(imu.time[i0 - 1]), float(imu.time[i1 - 1])
    span = t1 - t0
    where = f"{t0:.3f} .. {t1:.3f} s"
    f_b = imu.dvel_b[i0:i1].sum(axis=0) / span
    w_b = imu.dtheta_b[i0:i1].sum(axis=0) / span
    lat = float(lla[0])
    g = float(earth.normal_gravity(lat, lla[2]))
    if abs(np.linalg.norm(f_b) - g) > GRAVITY_TOLERANCE * g:
        raise InputError(f"window {where}: not at rest: the mean specific force is "
                         f"{np.linalg.norm(f_b):.3f} m/s^2, normal gravity {g:.3f} m/s^2")
    check = static_check(imu.time[i0:i1], imu.dtheta_b[i0:i1], imu.dvel_b[i0:i1])
    if check.spans:
        spans = ", ".join(f"{a:.1f} .. {b:.1f} s" for a, b in check.spans[:3])
        more = f" and {len(check.spans) - 3} more" if len(check.spans) > 3 else ""
        raise InputError(f"window {where}: not at rest: the IMU moves in {spans}{more} "
                         f"({check.moving_s:.1f} s in all: 1 s means of the rate or the "
                         f"specific force depart from the median beyond their noise); "
                         f"choose a window at rest with --start/--end")
    rpy0 = static_attitude(f_b, w_b)
    noise = _noise(imu, i0, i1, span, lat, rpy0, w_b, f_b, g, arw, vrw, gyro_bias_std,
                   accel_bias_std)
    arw_meas = float(np.max(noise.arw))
    stated = None
    if noise.sources["gyro_bias_std"] == "given":
        stated = ImuNoise(arw_deg_sqrth=noise.arw / DEG_SQRTH,
                          gyro_bias_std_dph=noise.gyro_bias_std / DPH)
        check_rate(span, w_b, stated, arw_meas, where)
    check_steady(imu, i0, i1, span, w_b, stated, arw_meas, where)
    C0 = euler_to_dcm(rpy0)
    h_bias, h_noise = heading_budget(C0, lat, span, noise.gyro_bias_std, noise.arw)
    known = not level_only and np.hypot(h_bias, h_noise) <= max_heading_std
    common = dict(time=t0, time_end=t1, lla=lla.copy(), heading_std_bias=h_bias,
                  heading_std_noise=h_noise, coarse_rpy=rpy0, noise=noise)
    if not known:
        tilt = np.hypot(np.max(noise.accel_bias_std),
                        np.max(noise.vrw) / np.sqrt(span)) / g
        return RestAlignment(rpy=np.array([rpy0[0], rpy0[1], np.nan]),
                             rpy_std=np.array([tilt, tilt, np.nan]), heading_known=False,
                             gyro_bias_b=np.full(3, np.nan), accel_bias_b=np.full(3, np.nan),
                             n_updates=0, nis_mean=np.nan, method="level", **common)
    q, P, sensors, n, nis = _fine(imu, i0, i1, lla, rpy0, noise, zupt_sigma_mps, step_s)
    C = quat_to_dcm(q)
    rpy = dcm_to_euler(C)
    J = _euler_jacobian(C)
    cov = J @ P[6:9, 6:9] @ J.T
    return RestAlignment(rpy=rpy, rpy_std=np.sqrt(np.diag(cov)), heading_known=True,
                         gyro_bias_b=sensors[0:3].copy(), accel_bias_b=sensors[3:6].copy(),
                         n_updates=n, nis_mean=nis, method="fine", **common)


def _euler_jacobian(C, eps=1e-7):
    """``d euler(Rot(phi) C) / d phi`` at ``phi = 0`` (3 x 3): how an attitude error in
    ``n`` (rad) moves roll, pitch, yaw."""
    e0 = dcm_to_euler(C)
    J = np.empty((3, 3))
    for k in range(3):
        d = np.zeros(3)
        d[k] = eps
        diff = dcm_to_euler(rotvec_to_dcm(d) @ C) - e0
        J[:, k] = (diff + np.pi) % (2 * np.pi) - np.pi
    return J / eps


def _fine(imu, i0, i1, lla, rpy0, noise, zupt_sigma_mps, step_s):
    """The zero-velocity Kalman filter over rows ``i0 .. i1-1`` (module notes).
    Returns the final ``q_nb``, the 15-state covariance, the 12 sensor estimates, the
    number of updates and the mean NIS."""
    from ins.estimation.core import _filter_kernels
    from ins.estimation.core.error_model import discretize, navigation_matrix
    state = np.concatenate([lla, np.zeros(3), euler_to_quat(rpy0)])
    sensors = np.zeros(12)
    C0 = euler_to_dcm(rpy0)
    n_s = 15
    P = np.zeros((n_s, n_s))
    P[0:3, 0:3] = np.eye(3) * 0.1 ** 2
    P[3:6, 3:6] = np.eye(3) * zupt_sigma_mps ** 2
    P[6:9, 6:9] = np.diag(np.deg2rad([TILT_PRIOR_DEG, TILT_PRIOR_DEG, HEADING_PRIOR_DEG]) ** 2)
    P[9:12, 9:12] = np.diag(noise.gyro_bias_std ** 2)
    P[12:15, 12:15] = np.diag(noise.accel_bias_std ** 2)
    GQG = np.zeros((n_s, n_s))
    GQG[3:6, 3:6] = C0 @ np.diag(noise.vrw ** 2) @ C0.T
    GQG[6:9, 6:9] = C0 @ np.diag(noise.arw ** 2) @ C0.T
    R = np.eye(3) * zupt_sigma_mps ** 2
    # navigation block of F at rest (v = 0).  The specific force is the reaction to
    # gravity: the noisy measured one would couple the heading error into the velocity
    # through the accelerometer noise and make the heading look observable.
    F_nav = navigation_matrix(lla[0], lla[2], np.zeros(3), -earth.gravity_n(lla[0], lla[2]))
    t = imu.time
    dt_nom = float(np.median(np.diff(t[i0 - 1:i1])))
    m = max(1, int(round(step_s / dt_nom)))
    out = np.empty((m, 10))
    acc = np.zeros((10, 3))
    A = np.zeros((n_s, n_s))
    nis_sum, n_up = 0.0, 0
    x = np.zeros(n_s)                  # the heading error is kept, not fed back
    for k0 in range(i0, i1, m):
        k1 = min(k0 + m, i1)
        acc[:] = 0.0
        _filter_kernels.propagate_rows(t, imu.dtheta_b, imu.dvel_b, k0, k1, state, sensors,
                                       out[:k1 - k0], acc)
        dt = float(t[k1 - 1] - t[k0 - 1])
        A[0:9, 0:9] = F_nav * dt                   # int F dt (error_model.interval_matrix)
        A[3:6, 12:15] = acc[0:3]
        A[6:9, 9:12] = -acc[0:3]
        Phi, Qd = discretize(A, GQG, dt)
        x = Phi @ x
        P = Phi @ P @ Phi.T + Qd
        # zero-velocity update (H selects the velocity error; Joseph form)
        z = state[3:6] - x[3:6]
        S = P[3:6, 3:6] + R
        S_inv = np.linalg.inv(S)
        K = P[:, 3:6] @ S_inv
        IKH = np.eye(n_s)
        IKH[:, 3:6] -= K
        P = IKH @ P @ IKH.T + K @ R @ K.T
        P = 0.5 * (P + P.T)
        nis_sum += float(z @ S_inv @ z)
        n_up += 1
        x = x + K @ z
        heading = x[8]
        x[8] = 0.0
        _filter_kernels.correct_state(state, x[:9])
        sensors[:6] += x[9:15]
        x[:] = 0.0
        x[8] = heading
    _filter_kernels.correct_state(state, x[:9])
    return state[6:10], P, sensors, n_up, nis_sum / max(n_up, 1)
