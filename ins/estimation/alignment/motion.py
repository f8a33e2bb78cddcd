"""Start anywhere: the attitude of an IMU at the start of a log from the IMU and the GNSS
alone, at rest, at walking pace or moving, with no hand-written attitude and no
assumption on how the IMU is mounted.

1. Rest.  The log starts at rest when the GNSS speed stays below
   :data:`REST_SPEED_MPS` (and the gyro shows no turn).  Over the rest the mean specific
   force gives roll and pitch (``static_attitude``; an accelerometer bias ``b`` tilts
   them by ``b / g``, which the filter later separates), and the mean rate gives the
   gyro biases, once the heading is known (2.) less the Earth rate in the body (15 deg/h:
   more than a tactical gyro's bias; left in, it made the gyro look like a MEMS one to
   the grade choice of
   :func:`ins.estimation.pipeline.presets.noise_from_rest`).
2. Heading by velocity matching.  With the gyro (less those biases) the body's rotation
   since the reference epoch ``t_a`` is known, so the specific force can be integrated in
   a frame ``L`` that is level at ``t_a`` and has an arbitrary azimuth: the velocity
   change ``dv_L(t)`` (gravity removed).  The GNSS sees the same change in NED,
   ``dv_n(t) = Rz(psi) dv_L(t)``: ``psi`` is the 2-D rotation between the two series,
   in closed form ``atan2(sum x_L x y_n, sum x_L . y_n)`` (orthogonal Procrustes), after
   an offset and a drift ``c0 + c1 t`` are regressed out of both (an error of the
   starting velocity, and an accelerometer bias seen through the level error).  This
   works for any mounting (a phone held sideways, a roof box) because it compares
   accelerations, not the track with the IMU's forward axis.  It needs a change of
   horizontal velocity (starting, braking, turning): the window grows from the first
   motion until the change reaches :data:`EXCITATION_MPS` (plus
   :data:`SETTLE_S`), at most :data:`MAX_WINDOW_S`.
3. A start while moving levels first with the mean specific force of the first
   :data:`LEVEL_WINDOW_S` (as if unaccelerated), then by the drift of the velocity
   mismatch over the whole matching window (:func:`_level_drift`, iterated with the
   heading): a tilt error makes the integrated velocity drift by ``g`` times it.  The
   window is tens of seconds, so positions differenced into velocities (a file without
   them: 1 m of noise at 1 Hz) still level to a tenth of a degree, where the GNSS
   acceleration over the first seconds left errors of 10 deg stated as 1.

4. A log that never moves (at rest to the end of the GNSS or of the IMU given: a
   surveyor's static test, a van waiting for the fix) has no velocity change to match:
   level and gyro biases from the rest (at most :data:`MAX_STATIC_S` of it), the heading
   by gyrocompassing (``static_attitude``), carried by the filter from a broad prior,
   at least :data:`STATIC_HEADING_PRIOR_DEG` and at most the uniform circle's
   :data:`UNKNOWN_HEADING_STD_DEG`.  At rest this is sound although the error-state
   filter linearizes small angles: with the specific force vertical a heading error
   does not enter the velocity, only the east tilt through the Earth rate
   (``W_ie cos(lat) psi``), the same as an east gyro bias, so the filter's gyrocompassing
   ends at ``sigma_bE / (W_ie cos lat)`` (``ins.estimation.alignment.fine.heading_budget``):
   4.7 deg for 1 deg/h at 35 deg latitude, the honest sigma; a consumer gyro leaves the
   prior.  The broad prior is what keeps it honest: the rest's data enter once, in the
   filter (a prior equal to the budget would count them twice).  A horizontal lever arm
   makes the IMU's position as uncertain as the heading turns it.  The filter's own
   heading sigma at rest can fall below that bound: its linear model takes the
   horizontal part of the computed specific force (accelerometer noise, the tilt
   errors between fixes) as an excitation of the heading, a second-order effect that it
   overstates (a tactical IMU over an hour: 2.6 deg against the bound's 4.7; a consumer
   one: 4 deg where nothing is known).  The stated heading sigma of such a run is
   therefore the larger of the two (``ins.estimation.pipeline.trust.start_report``).
   ``ins process`` turns the zero-velocity updates on for such a log (unless
   ``[measurements] zupt`` says otherwise): between sparse fixes (a 30 s static
   observation) the angle random walk of a tactical gyro tilts the platform enough to
   move the position by 10 cm between them.
5. An IMU log that starts more than :data:`FIX_DELAY_S` before the first GNSS fix
   (:func:`rest_before_fix`): when the GNSS is at rest at the first fix and the IMU at
   rest before it (no velocity change beyond :data:`REST_SPEED_MPS` and no rotation
   beyond :data:`PRE_FIX_ROTATION_DEG`, integrated back from the fix, where the velocity
   is zero), the run starts where that rest begins (at most :data:`MAX_PRE_FIX_REST_S`
   before the fix); otherwise at the first fix.  The IMU before is not processed.

The sigmas state what the data support: the heading's from the residual of the fit
against the excitation (times :data:`HEADING_SIGMA_FACTOR` for what the model leaves
out, at least :data:`MIN_HEADING_STD_DEG`); the level's from the accelerometer bias
prior and, moving, the drift's fit (times the same factor).
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.estimation.alignment.initial import Alignment, static_attitude
from ins.nav import earth
from ins.nav.mechanization import NavState
from ins.nav.rotation import euler_to_dcm, euler_to_quat, quat_to_dcm, rotvec_to_quat

__all__ = ["MotionStart", "align_anywhere", "gnss_velocities", "rest_before_fix",
           "REST_SPEED_MPS", "EXCITATION_MPS", "MAX_WINDOW_S", "FIX_DELAY_S", "MAX_PRE_FIX_REST_S",
           "MAX_STATIC_S"]

#: GNSS horizontal speed below which the carrier counts as at rest, m/s (RTK velocity
#: noise is a few cm/s; a walker's slowest steps are 0.5 m/s).
REST_SPEED_MPS = 0.2
#: Change of horizontal velocity that ends the matching window, m/s.
EXCITATION_MPS = 1.0
#: Time kept after the excitation is reached, s.
SETTLE_S = 3.0
#: Longest matching window after the first motion, s.
MAX_WINDOW_S = 60.0
#: Factor on the fitted heading sigma for what the model leaves out (gyro drift over the
#: window, the lever arm's velocity in turns, the level error).
HEADING_SIGMA_FACTOR = 3.0
#: Smallest stated heading sigma, deg.
MIN_HEADING_STD_DEG = 1.0
#: The rest ends this long before the first fix at :data:`REST_SPEED_MPS`, s (a start
#: at 1 m/s^2 reaches 0.2 m/s in well under a second; the rest must not hold it).
REST_MARGIN_S = 1.5
#: A start while moving levels over this long, s (the GNSS acceleration over the same
#: span is removed).
LEVEL_WINDOW_S = 3.0
#: The matching window grows by GROW_S (s) until the stated heading sigma is at most
#: GOOD_HEADING_STD_DEG (deg) or the window is MAX_WINDOW_S long.
GROW_S = 5.0
GOOD_HEADING_STD_DEG = 3.0
#: Shortest rest that gives gyro biases, s.
MIN_REST_S = 2.0
#: A log that never moves: the rest's first MAX_STATIC_S (s) give the level, the gyro
#: biases and the gyrocompass heading (the filter uses the whole log).
MAX_STATIC_S = 600.0
#: Smallest prior sigma of a gyrocompass heading given to the filter, deg (the filter's
#: own gyrocompassing decides: module notes, 4.); the largest, that of a heading
#: uniform on the circle, 180 / sqrt(3) deg.
STATIC_HEADING_PRIOR_DEG = 30.0
UNKNOWN_HEADING_STD_DEG = 180.0 / np.sqrt(3.0)
#: The first GNSS fix must lie at most this long after the start (s); a later one
#: moves the start (module notes, 5.).
FIX_DELAY_S = 5.0
#: Longest rest before the first fix that a run may start with, s.
MAX_PRE_FIX_REST_S = 600.0
#: Largest rotation of the IMU over a rest before the first fix, deg (beyond five times
#: the angle random walk over it): a turn, a car driving and steering.
PRE_FIX_ROTATION_DEG = 1.0


@dataclass(frozen=True)
class MotionStart:
    """Result of :func:`align_anywhere`: the alignment at the log's start, the gyro
    biases found at rest (rad/s, b; None when the start moves), what was done and what
    gave the heading (``"velocity matching"``, or ``"gyrocompass"`` for a log that never
    moves: its ``att_std_deg[2]`` is then the filter's broad prior and
    ``heading_floor_deg`` the heading sigma the rest allows at best, module notes 4.)."""
    alignment: Alignment
    gyro_bias_b: np.ndarray
    rest_s: float
    window_s: tuple
    how: str
    heading_from: str = "velocity matching"      # or "gyrocompass" (a log that never moves)
    heading_floor_deg: float = None              # gyrocompass: the bound at rest, deg


def gnss_velocities(gnss):
    """Horizontal and vertical GNSS velocities NED (m/s) at the records: the file's own,
    else central differences of the positions."""
    if gnss.has_velocity:
        return np.asarray(gnss.v_n, float)
    n = len(gnss)
    if n < 2:
        raise InputError("a start without a given attitude needs at least two GNSS fixes",
                         path=gnss.path)
    d = np.array([earth.ned_offset(gnss.lla[k], gnss.lla[k + 1]) for k in range(n - 1)])
    v = d / np.diff(gnss.time)[:, None]
    out = np.empty((n, 3))
    out[0], out[-1] = v[0], v[-1]
    out[1:-1] = 0.5 * (v[:-1] + v[1:])
    return out


def _rest_end(t_g, speed, t0):
    """End of the rest at the start (s), or None when the first fix already moves."""
    k0 = int(np.searchsorted(t_g, t0 - 1e-9))
    if k0 >= len(t_g) or speed[k0] >= REST_SPEED_MPS:
        return None
    moving = np.flatnonzero(speed[k0:] >= REST_SPEED_MPS)
    if not len(moving):
        return float(t_g[-1])
    t_end = float(t_g[k0 + moving[0]]) - REST_MARGIN_S     # the start of the motion is
    return t_end if t_end > t0 else None                   # slower than the threshold


def _window_end(t_g, v_h, t_a):
    """End of the matching window from ``t_a`` (s): excitation reached + SETTLE_S."""
    k_a = int(np.searchsorted(t_g, t_a - 1e-9))
    change = np.linalg.norm(v_h[k_a:] - v_h[k_a], axis=1)
    hit = np.flatnonzero(change >= EXCITATION_MPS)
    t_hit = t_g[k_a + hit[0]] if len(hit) else t_a + MAX_WINDOW_S
    return float(min(t_hit + SETTLE_S, t_a + MAX_WINDOW_S, t_g[-1]))


def _integrate(imu, i0, i1, bias_b, C_Lb0):
    """Velocity change in the frame L (level at imu.time[i0], its azimuth arbitrary) at
    the epochs imu.time[i0:i1+1] (first 0), gravity removed (m/s, (m, 3))."""
    th = imu.dtheta_b[i0 + 1:i1 + 1] - np.outer(imu.dt[i0 + 1:i1 + 1], bias_b)
    dv = imu.dvel_b[i0 + 1:i1 + 1]
    q = rotvec_to_quat(th)
    C = quat_to_dcm(q)
    out = np.zeros((i1 - i0 + 1, 3))
    C_Lb = C_Lb0.copy()
    acc = np.zeros(3)
    for k in range(len(dv)):
        C_mid = C_Lb @ (np.eye(3) + 0.5 * (C[k] - np.eye(3)))   # half the step's rotation
        acc = acc + C_mid @ dv[k]
        C_Lb = C_Lb @ C[k]
        out[k + 1] = acc
    return out


def _match(t_imu, dv_L, t_g, v_n, t_a, t_e, g, order=1):
    """Azimuth of L in n (rad) and its sigma from the velocity changes over [t_a, t_e];
    a polynomial of ``order`` in time regressed out of both (1: offset and drift; 2 also
    the tilt drift of an uncalibrated gyro bias, ``g b t^2 / 2``)."""
    sel = (t_g >= t_a) & (t_g <= t_e)
    tg = t_g[sel]
    if len(tg) < 4:
        return None, None
    x = np.column_stack([np.interp(tg, t_imu, dv_L[:, i]) for i in range(3)])
    x[:, 2] += g * (tg - t_imu[0])                           # gravity: L is level
    y = v_n[sel] - v_n[sel][0]
    A = np.vander(tg - tg[0], order + 1)
    P = np.eye(len(tg)) - A @ np.linalg.pinv(A)              # offset and drift out
    xh, yh = P @ x[:, :2], P @ y[:, :2]
    cross = float(np.sum(xh[:, 0] * yh[:, 1] - xh[:, 1] * yh[:, 0]))
    dot = float(np.sum(xh * yh))
    psi = np.arctan2(cross, dot)
    excite = float(np.sum(xh ** 2))
    if excite < (0.5 * EXCITATION_MPS) ** 2:
        return None, None
    c, s = np.cos(psi), np.sin(psi)
    r = yh - xh @ np.array([[c, s], [-s, c]])
    dof = max(2 * (len(tg) - order - 1) - 1, 1)
    sigma_v = np.sqrt(np.sum(r ** 2) / dof)
    return psi, sigma_v / np.sqrt(excite)


def _level_drift(t_imu, dv_L, t_g, v_n, t_a, t_e, g, psi, order=1):
    """Tilt of the level at ``t_a`` (rad, n: a small rotation that takes the computed
    specific force onto the true one) and its sigma (rad) from the horizontal drift of
    the velocity mismatch ``Rz(psi) dv_L - dv_n`` over the matching window (module
    notes, 3.): a tilt ``phi`` adds ``f x phi``, with ``f`` about ``-g`` down, to the
    computed acceleration, so the mismatch's slope at ``t_a`` is ``(g phi_E, -g phi_N)``
    (with an accelerometer bias, which it cannot be told from: the level's sigma holds
    it)."""
    sel = (t_g >= t_a) & (t_g <= t_e)
    tg = t_g[sel]
    x = np.column_stack([np.interp(tg, t_imu, dv_L[:, i]) for i in range(2)])
    c, s = np.cos(psi), np.sin(psi)
    d = x @ np.array([[c, s], [-s, c]]) - (v_n[sel][:, :2] - v_n[sel][0, :2])
    A = np.vander(tg - t_a, order + 1, increasing=True)       # 1, t (, t^2)
    coef, *_ = np.linalg.lstsq(A, d, rcond=None)
    r = d - A @ coef
    dof = max(2 * (len(tg) - order - 1), 1)
    s_slope = np.sqrt(np.sum(r ** 2) / dof * np.linalg.inv(A.T @ A)[1, 1])
    delta = np.array([coef[1, 0], coef[1, 1], 0.0])
    tilt = np.cross(delta, np.array([0.0, 0.0, -g])) / g ** 2
    return tilt, float(s_slope / g)


def align_anywhere(imu, gnss, t_start=None, noise=None, fix_delay_s=FIX_DELAY_S):
    """Initial attitude, velocity and position at the first IMU epoch >= ``t_start``
    from the IMU and the GNSS alone (module notes).

    Parameters
    ----------
    imu : ins.nav.imu.ImuLog
        The log from the start to at least the end of the matching window.
    gnss : ins.io.gnss_log.GnssLog
    t_start : float, optional
        s (default: the IMU's first epoch).
    noise : ins.estimation.core.error_model.ImuNoise, optional
        For the level sigma (accelerometer bias prior; 30 mg without it) and, for a log
        that never moves, the gyrocompass budget.
    fix_delay_s : float
        Largest delay of the first GNSS fix after the start, s (more for a start at the
        IMU's rest before the first fix: :func:`rest_before_fix`).

    Returns
    -------
    MotionStart
        The alignment holds the antenna's position (the caller removes the lever arm).
        A log at rest to the end of the IMU or of the GNSS given starts from the
        gyrocompass (module notes, 4.).

    Raises
    ------
    InputError
        No GNSS fix near the start; a log that moves but never enough to find the
        heading.
    """
    from ins.estimation.core.error_model import MGAL
    t0 = float(imu.time[0]) if t_start is None else float(t_start)
    i0 = int(np.searchsorted(imu.time, t0 - 1e-9))
    t0 = float(imu.time[i0])
    t_g = np.asarray(gnss.time, float)
    k0 = int(np.searchsorted(t_g, t0 - 1e-9))
    if k0 >= len(t_g) or t_g[k0] - t0 > fix_delay_s:
        raise InputError(f"no GNSS fix within {fix_delay_s:g} s after the start {t0:.3f} s: "
                         f"the start position and attitude come from the fixes", path=gnss.path)
    v_n = gnss_velocities(gnss)
    speed = np.hypot(v_n[:, 0], v_n[:, 1])
    lat = float(gnss.lla[k0, 0])
    g = float(earth.normal_gravity(lat, gnss.lla[k0, 2]))
    t_rest = _rest_end(t_g, speed, t0)
    if t_rest is not None and (not np.any(speed[k0:] >= REST_SPEED_MPS)
                               or t_rest >= imu.time[-1]):
        # never moves within the GNSS or the IMU given: the gyrocompass (module notes, 4.)
        t_end = min(t_rest, float(imu.time[-1]), t0 + MAX_STATIC_S)
        return _gyrocompass_start(imu, i0, t_end, gnss, k0, noise)
    rest_s = 0.0 if t_rest is None else t_rest - t0
    bias_b = None
    if rest_s >= MIN_REST_S:
        i1 = int(np.searchsorted(imu.time, t_rest, side="right")) - 1
        span = imu.time[i1] - imu.time[i0]
        f_b = imu.dvel_b[i0 + 1:i1 + 1].sum(axis=0) / span
        bias_b = imu.dtheta_b[i0 + 1:i1 + 1].sum(axis=0) / span
        roll, pitch, _ = static_attitude(f_b, bias_b)
        t_a = max(t0, t_rest - 1.0)
        how = f"at rest for {rest_s:.1f} s: level and gyro biases from the rest"
    else:
        i1 = int(np.searchsorted(imu.time, t0 + LEVEL_WINDOW_S, side="right")) - 1
        span = imu.time[i1] - imu.time[i0]
        f_b = imu.dvel_b[i0 + 1:i1 + 1].sum(axis=0) / span
        roll, pitch, _ = static_attitude(f_b, np.zeros(3))
        t_a = t0
        how = ("moving at the start: level from the drift of the velocity mismatch over "
               "the matching window")
    t_e = _window_end(t_g, v_n[:, :2], t_a)
    ia = int(np.searchsorted(imu.time, t_a - 1e-9))
    ie = int(np.searchsorted(imu.time, t_e, side="right")) - 1
    if ie - ia < 10 or imu.time[ie] < t_e - 1.0:
        raise InputError(f"the IMU log ends before the heading could be found ({t_e:.1f} s "
                         f"needed)")
    b = np.zeros(3) if bias_b is None else bias_b
    # relative attitude t0 -> t_a (rest: no rotation) then the matching
    psi, s_psi = None, None
    order = 1 if bias_b is not None else 2
    for _ in range(3):
        C_Lb0 = euler_to_dcm([roll, pitch, 0.0])
        while True:                       # grow the window until the heading is found
            ie = int(np.searchsorted(imu.time, t_e, side="right")) - 1
            dv_L = _integrate(imu, ia, ie, b, C_Lb0)
            psi, s_psi = _match(imu.time[ia:ie + 1], dv_L, t_g, v_n, t_a, t_e, g, order)
            good = psi is not None and np.rad2deg(s_psi) * HEADING_SIGMA_FACTOR \
                <= GOOD_HEADING_STD_DEG
            if good or t_e >= min(t_a + MAX_WINDOW_S, imu.time[-1], t_g[-1]) - 1e-9:
                break
            t_e = min(t_e + GROW_S, t_a + MAX_WINDOW_S, imu.time[-1], t_g[-1])
        if psi is None:
            break
        if bias_b is not None:                    # the rest's level needs no iteration
            break
        # level while moving: the drift of the velocity mismatch over the window
        tilt, s_tilt = _level_drift(imu.time[ia:ie + 1], dv_L, t_g, v_n, t_a, t_e, g, psi,
                                    order)
        C_nb = euler_to_dcm([roll, pitch, psi])
        C_nb = (np.eye(3) + np.array([[0.0, -tilt[2], tilt[1]], [tilt[2], 0.0, -tilt[0]],
                                      [-tilt[1], tilt[0], 0.0]])) @ C_nb
        roll = float(np.arctan2(C_nb[2, 1], C_nb[2, 2]))
        pitch = float(-np.arcsin(np.clip(C_nb[2, 0], -1.0, 1.0)))
    if psi is None:
        raise InputError(f"the heading cannot be found from the start {t0:.1f} s to "
                         f"{t_e:.1f} s: the horizontal velocity never changes by "
                         f"{EXCITATION_MPS:g} m/s (no start, stop or turn); give "
                         f"[initial] rpy_deg or start the log before the vehicle moves")
    if bias_b is not None:
        # the rest's mean rate holds the Earth's rate (15 deg/h, more than a tactical
        # gyro's bias): it is taken out with the attitude found (a heading error of
        # 3 deg leaves 0.8 deg/h of it)
        bias_b = bias_b - euler_to_dcm([roll, pitch, psi]).T @ earth.earth_rate_n(lat)
    head_std = max(np.rad2deg(s_psi) * HEADING_SIGMA_FACTOR, MIN_HEADING_STD_DEG)
    b_a = (30.0 * 980.665 if noise is None else float(np.max(noise.accel_bias_std_mgal))) * MGAL
    level_std = np.rad2deg(b_a / g) + (0.0 if bias_b is not None else 1.0)
    if bias_b is None:                 # the drift's own sigma (module notes, 3.)
        level_std = float(np.hypot(level_std, np.rad2deg(HEADING_SIGMA_FACTOR * s_tilt)))
    q = euler_to_quat([roll, pitch, psi])
    if bias_b is not None:
        v0, lla0 = np.zeros(3), gnss.lla[k0].copy()
    else:
        v0 = np.array([np.interp(t0, t_g, v_n[:, i]) for i in range(3)])
        lla0 = earth.offset_lla(gnss.lla[k0], -v0 * (t_g[k0] - t0))[0]
    state = NavState(lla0, v0, q)
    vel_std = 0.01 if bias_b is not None else 0.2
    al = Alignment(state, t0, np.array([level_std, level_std, head_std]),
                   np.maximum(np.asarray(gnss.sigma_ned_m[k0], float) * 2, 0.05),
                   np.full(3, vel_std), "anywhere")
    how += (f"; heading by velocity matching over {t_a:.1f} .. {t_e:.1f} s: "
            f"{np.rad2deg(psi) % 360:.2f} +- {head_std:.2f} deg")
    return MotionStart(al, bias_b, rest_s, (t_a, t_e), how)


def _gyrocompass_start(imu, i0, t_end, gnss, k0, noise):
    """The start of a log at rest from ``imu.time[i0]`` to ``t_end`` (s) and beyond, with
    no motion to find the heading by (module notes, 4.): level, gyro biases and the
    gyrocompass heading over the rest, the heading's sigma the filter's broad prior."""
    from ins.estimation.alignment.fine import heading_budget, white_noise
    from ins.estimation.core.error_model import DEG_SQRTH, DPH, MGAL
    t0 = float(imu.time[i0])
    i1 = int(np.searchsorted(imu.time, t_end, side="right")) - 1
    if i1 - i0 < 10:
        raise InputError(f"the IMU log holds {max(i1 - i0, 0)} epochs at rest after the start "
                         f"{t0:.3f} s (at least 10 needed to level it)")
    span = float(imu.time[i1] - imu.time[i0])
    f_b = imu.dvel_b[i0 + 1:i1 + 1].sum(axis=0) / span
    w_b = imu.dtheta_b[i0 + 1:i1 + 1].sum(axis=0) / span
    lat, h = float(gnss.lla[k0, 0]), float(gnss.lla[k0, 2])
    g = float(earth.normal_gravity(lat, h))
    if abs(np.linalg.norm(f_b) - g) > 0.05 * g:
        raise InputError(f"the GNSS shows the carrier at rest from {t0:.3f} s, but the IMU's "
                         f"mean specific force over {t0:.1f} .. {t_end:.1f} s is "
                         f"{np.linalg.norm(f_b):.3f} m/s^2, not gravity ({g:.3f} m/s^2): "
                         f"check the IMU's units and rates", path=gnss.path)
    rpy = static_attitude(f_b, w_b)
    C_nb = euler_to_dcm(rpy)
    w_ie = earth.earth_rate_n(lat)
    bias_b = w_b - C_nb.T @ w_ie
    arw_log = white_noise(imu.dtheta_b[i0 + 1:i1 + 1], float(np.median(np.diff(
        imu.time[i0:i1 + 1]))))
    if noise is None:          # the observable part of the rest's offset (north, down)
        b_n = C_nb @ w_b - w_ie
        var = 0.5 * (b_n[0] ** 2 + b_n[2] ** 2) - float(np.mean(arw_log ** 2)) / span
        gyro_std, arw = np.full(3, np.sqrt(max(var, 0.0))), arw_log
        b_a = 30.0 * 980.665 * MGAL
    else:
        inst = noise.gyro_bias_instability_dph
        gyro_std = np.hypot(noise.gyro_bias_std_dph, 0.0 if inst is None else inst) * DPH
        arw = np.maximum(np.asarray(noise.arw_deg_sqrth, float) * DEG_SQRTH, arw_log)
        b_a = float(np.max(noise.accel_bias_std_mgal)) * MGAL
    budget = np.rad2deg(np.hypot(*heading_budget(C_nb, lat, span, gyro_std, arw)))
    prior = float(np.clip(budget, STATIC_HEADING_PRIOR_DEG, UNKNOWN_HEADING_STD_DEG))
    level_std = np.rad2deg(b_a / g)
    al = Alignment(NavState(gnss.lla[k0].copy(), np.zeros(3), euler_to_quat(rpy)), t0,
                   np.array([level_std, level_std, prior]),
                   np.maximum(np.asarray(gnss.sigma_ned_m[k0], float) * 2, 0.05),
                   np.full(3, 0.01), "anywhere")
    how = (f"at rest from {t0:.1f} s with no motion in the log to find the heading by: level "
           f"and gyro biases from {span:.1f} s of the rest; heading "
           f"{np.rad2deg(rpy[2]) % 360:.2f} deg by gyrocompassing, carried by the filter "
           f"from a {prior:.0f} deg prior (the gyro's bias and noise allow "
           f"{budget:.3g} deg at rest); zero-velocity updates where the IMU is at rest")
    return MotionStart(al, bias_b, span, (t0, t0 + span), how, heading_from="gyrocompass",
                       heading_floor_deg=float(min(budget, UNKNOWN_HEADING_STD_DEG)))


def rest_before_fix(imu, gnss, k_fix, noise=None):
    """Where the IMU's rest before the first GNSS fix begins (module notes, 5.).

    Parameters
    ----------
    imu : ins.nav.imu.ImuLog
        The log up to (at least) the fix.
    gnss : ins.io.gnss_log.GnssLog
    k_fix : int
        Index of the first usable fix.
    noise : ins.estimation.core.error_model.ImuNoise, optional
        For the allowances (random walks); without it those of the log's own scatter.

    Returns
    -------
    float or None
        Start of the rest (s, an IMU epoch), at most :data:`MAX_PRE_FIX_REST_S` before
        the fix; None when the GNSS moves at the fix or the IMU is not at rest for
        :data:`MIN_REST_S` before it.
    """
    from ins.estimation.alignment.fine import white_noise
    from ins.estimation.core.error_model import DEG_SQRTH
    t_fix = float(gnss.time[k_fix])
    v = gnss_velocities(gnss)[k_fix]
    if np.hypot(v[0], v[1]) >= REST_SPEED_MPS:
        return None
    t = imu.time
    ie = int(np.searchsorted(t, t_fix, side="right")) - 1
    if ie < 2 or t[ie] < t_fix - 1.0:
        return None
    dt = float(np.median(np.diff(t[:ie + 1])))
    lo = int(np.searchsorted(t, max(t[0], t_fix - MAX_PRE_FIX_REST_S) - 1e-9))
    # whole seconds back from the fix, as rows; the sums of the increments after each
    rows = np.unique(np.searchsorted(t, t[ie] - np.arange(0.0, t[ie] - t[lo] + 1e-9, 1.0)
                                     - 1e-9))[::-1]
    if len(rows) < 3:
        return None
    S_th = np.concatenate([[np.zeros(3)], np.cumsum(imu.dtheta_b[lo + 1:ie + 1], axis=0)])
    S_dv = np.concatenate([[np.zeros(3)], np.cumsum(imu.dvel_b[lo + 1:ie + 1], axis=0)])
    r = rows - lo
    th_back = S_th[ie - lo] - S_th[r]          # increments over (t[row], t[ie]]
    dv_back = S_dv[ie - lo] - S_dv[r]
    T = t[ie] - t[rows]
    if noise is None:
        arw = float(np.max(white_noise(imu.dtheta_b[lo + 1:ie + 1], dt)))
        vrw = float(np.max(white_noise(imu.dvel_b[lo + 1:ie + 1], dt)))
    else:
        arw = max(float(np.max(noise.arw_deg_sqrth)) * DEG_SQRTH,
                  float(np.max(white_noise(imu.dtheta_b[lo + 1:ie + 1], dt))))
        vrw = max(float(np.max(noise.vrw_mps_sqrth)) / 60.0,
                  float(np.max(white_noise(imu.dvel_b[lo + 1:ie + 1], dt))))
    g = float(earth.normal_gravity(gnss.lla[k_fix, 0], gnss.lla[k_fix, 2]))
    start = None
    for j in range(1, len(rows)):
        # at rest over (t[rows[j]], t_fix]: the mean rate and specific force are the
        # sensors' (Earth rate, gravity, biases); what departs from them integrated
        # back from the fix (velocity zero there) is the velocity and the rotation
        w_ref, f_ref = th_back[j] / T[j], dv_back[j] / T[j]
        vel = np.linalg.norm(dv_back[:j + 1] - np.outer(T[:j + 1], f_ref), axis=1)
        rot = np.linalg.norm(th_back[:j + 1] - np.outer(T[:j + 1], w_ref), axis=1)
        still = (abs(np.linalg.norm(f_ref) - g) <= 0.05 * g
                 and vel.max() <= REST_SPEED_MPS + 5.0 * vrw * np.sqrt(T[j])
                 and rot.max() <= max(np.deg2rad(PRE_FIX_ROTATION_DEG),
                                      5.0 * arw * np.sqrt(T[j])))
        if not still:
            break
        start = float(t[rows[j]])
    if start is None or t_fix - start < MIN_REST_S:
        return None
    return start
