"""Is an IMU log at rest?  Decided from what a rotation does to gravity and to the gyro's
own scatter, not from the mean rate.

A log at rest gives the Allan deviation of the sensors; a log that moves gives the
motion's.  What motion looks like in the data:

- a rotation of angle ``a`` about any axis but the vertical turns gravity's direction in
  the body by up to ``a``: the directions of the mean specific force in long windows
  spread by that angle (test 2; accelerometer biases do not move with the body, so
  a drift of a horizontal bias by ``db`` counts as ``db / g`` rad);
- a rotation about the vertical leaves gravity where it is: the gyro alone sees it, as
  window means of the rate that depart from their neighbours (a local median) by many
  times the noise of a window mean (test 3);
- a translation: window means of the specific force depart in the same way (test 3).

A constant rate is NOT motion by itself: a MEMS gyro's bias reaches several deg/s
(ADIS16405: 3 deg/s initial bias), and the Allan variance does not see a constant
(a steady spin about the vertical, the one motion that looks like a bias, adds nothing
to it either).  Slow drifts of the biases (warm-up) are the sensors' noise, which the
Allan deviation is there to measure: the window tests compare a window with a local
median over :data:`MEDIAN_S`, not with the whole log.
"""
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter

__all__ = ["static_check", "StaticCheck", "GRAVITY_RANGE", "GRAVITY_MARGIN", "WINDOW_S",
           "MEDIAN_S", "N_SIGMA", "MIN_RATE_DEPARTURE", "MIN_FORCE_DEPARTURE",
           "TILT_WINDOW_S", "MAX_TILT"]

#: Normal gravity on the WGS84 ellipsoid from the equator to the poles, m/s^2
#: (conventions.md; at 6 km height it is 0.019 m/s^2 less).
GRAVITY_RANGE = (9.780, 9.832)
#: Tolerance on the log's mean specific force against :data:`GRAVITY_RANGE`, m/s^2
#: (0.3 m/s^2 ~ 31 mg: accelerometer biases and scale factors of MEMS grade included).
GRAVITY_MARGIN = 0.3
#: Length of the short windows whose mean rate and specific force are compared, s
#: (a bump, a tap, a turn by hand last about a second).
WINDOW_S = 1.0
#: Length of the running median that a short window is compared with, s: bias drifts
#: (warm-up: an ADIS16405's gyro bias moves 0.01 deg/s per deg C) change little within
#: it, a turn or a bump of a few seconds does not move it.
MEDIAN_S = 301.0
#: A short window moves when its mean departs from the running median by more than
#: N_SIGMA times the noise of a window mean.  That noise is estimated from the
#: differences of consecutive window means (median absolute deviation, robust to a few
#: moving windows), so it is the sensor's noise at the window's scale whatever its
#: colour (a filtered MEMS output has sample-to-sample differences that understate it).
#: 7 sigma: no false alarm in 10^5 windows of Gaussian noise.
N_SIGMA = 7.0
#: ... and by more than these floors, rad/s and m/s^2: 0.01 deg/s = 36 deg/h and
#: 0.05 m/s^2 ~ 5 mg (bias instability and drifts of quiet sensors).
MIN_RATE_DEPARTURE = np.deg2rad(0.01)
MIN_FORCE_DEPARTURE = 0.05
#: Length of the windows whose mean specific force gives gravity's direction, s (at
#: most 500 windows: longer ones for a longer log).
TILT_WINDOW_S = 60.0
#: Largest angle between gravity's directions in two windows, rad: 0.3 deg.  A drift
#: of a horizontal accelerometer bias by 5 mg (warm-up of a MEMS part) turns the
#: direction by 0.3 deg without any motion; a rotation of 1 deg about a horizontal
#: axis is refused.  The threshold is N_SIGMA times the noise of the angle when that
#: is larger.
MAX_TILT = np.deg2rad(0.3)


@dataclass(frozen=True)
class StaticCheck:
    """Result of :func:`static_check` (SI units).

    Attributes
    ----------
    static : bool
        True when no test flags motion.
    reasons : list of str
        One sentence per failed test (deg/s, m/s^2, deg in the text).
    spans : list of (float, float)
        Time spans (s, window bounds) whose short windows move, in time order.
    moving_s : float
        Total length of those spans, s.
    mean_force : float
        Magnitude of the mean specific force over the log, m/s^2.
    mean_rate : float
        Magnitude of the mean angular rate over the log, rad/s (Earth rate plus gyro
        biases; information only).
    rate_threshold, force_threshold : float
        Departure thresholds of the short windows, rad/s and m/s^2.
    tilt : float
        Largest angle between gravity's directions (mean specific force) in two tilt
        windows, rad.
    tilt_threshold : float
        Threshold on ``tilt``, rad.
    """

    static: bool
    reasons: list
    spans: list
    moving_s: float
    mean_force: float
    mean_rate: float
    rate_threshold: float
    force_threshold: float
    tilt: float = 0.0
    tilt_threshold: float = float("nan")


#: Quantile of |consecutive differences| that gives the noise of a window mean, and the
#: same quantile of |N(0, 1)| (Phi^-1(0.625)): robust to up to 75 % moving windows (a
#: median, robust to 50 %, took half a log of driving for noise).
NOISE_QUANTILE, NOISE_QUANTILE_Z = 0.25, 0.31863936396437514


def _mean_noise(means):
    """Noise sigma of window means (largest axis), from consecutive differences."""
    d = np.diff(means, axis=0)
    q = np.quantile(np.abs(d - np.median(d, axis=0)), NOISE_QUANTILE, axis=0)
    return float(np.max(q / NOISE_QUANTILE_Z / np.sqrt(2.0)))


def _window_means(inc, n_win, dt):
    k = len(inc) // n_win
    return inc[:k * n_win].reshape(k, n_win, 3).sum(axis=1) / (n_win * dt)


def _largest_angle(u):
    """Largest angle between two of the unit vectors ``u`` (k, 3), rad."""
    cross = np.linalg.norm(np.cross(u[:, None, :], u[None, :, :]), axis=2)
    dot = u @ u.T
    return float(np.max(np.arctan2(cross, dot)))


def _tilt(dv, dt, span, sigma_f1, n_win1):
    """Gravity's turn over the log and its threshold (rad)."""
    n = len(dv)
    win = max(TILT_WINDOW_S, span / 500.0)
    n_tw = int(round(win / dt))
    if n // n_tw < 4:                       # a short log: four windows over it
        n_tw = max(n_win1, n // 4)
    if n // n_tw < 2:
        return 0.0, MAX_TILT
    f = _window_means(dv, n_tw, dt)
    g = np.linalg.norm(f, axis=1)
    tilt = _largest_angle(f / g[:, None])
    sigma_dir = sigma_f1 * np.sqrt(n_win1 / n_tw) / float(np.median(g))
    return tilt, max(MAX_TILT, N_SIGMA * np.sqrt(2.0) * sigma_dir)


def static_check(time, dtheta_b, dvel_b, window_s=WINDOW_S):
    """Whether an IMU log is at rest, and where it moves.

    Tests (thresholds and their reasons in the module constants):

    1. the magnitude of the mean specific force over the log lies within
       :data:`GRAVITY_MARGIN` of normal gravity (:data:`GRAVITY_RANGE`);
    2. gravity's direction in the body (mean specific force in windows of
       :data:`TILT_WINDOW_S`) turns by at most :data:`MAX_TILT` over the log: a
       rotation about any axis but the vertical;
    3. in windows of ``window_s``, the mean rate and the mean specific force (vectors)
       stay within ``max(N_SIGMA * sigma_window, floor)`` of their running median over
       :data:`MEDIAN_S`, ``sigma_window`` the noise of a window mean, the floors
       :data:`MIN_RATE_DEPARTURE` and :data:`MIN_FORCE_DEPARTURE`: a turn about the
       vertical (gyro) or a bump (accelerometers).  Windows that fail are the moving
       spans.

    The mean rate is not tested: a constant gyro bias is not motion.

    Parameters
    ----------
    time : ndarray, shape (n,)
        s, increasing (increments stamped at the end of their interval).
    dtheta_b, dvel_b : ndarray, shape (n, 3)
        Increments, rad and m/s, body frame.
    window_s : float
        Short window length, s (at least 10 samples are used per window).

    Returns
    -------
    StaticCheck
    """
    time = np.asarray(time, dtype=float)
    dth = np.asarray(dtheta_b, dtype=float)
    dv = np.asarray(dvel_b, dtype=float)
    n = len(time)
    dt = float(np.median(np.diff(time))) if n > 1 else float("nan")
    span = time[-1] - time[0] + dt
    mean_w = dth.sum(axis=0) / span
    mean_f = dv.sum(axis=0) / span
    reasons = []
    g_lo, g_hi = GRAVITY_RANGE
    f_mag, w_mag = float(np.linalg.norm(mean_f)), float(np.linalg.norm(mean_w))
    if not g_lo - GRAVITY_MARGIN <= f_mag <= g_hi + GRAVITY_MARGIN:
        reasons.append(f"the mean specific force is {f_mag:.3f} m/s^2, not normal gravity "
                       f"({g_lo}..{g_hi} m/s^2 +- {GRAVITY_MARGIN})")
    n_win = max(10, int(round(window_s / dt)))
    k = n // n_win
    spans, moving = [], 0.0
    tol_w = tol_f = float("nan")
    tilt, tol_tilt = 0.0, float("nan")
    if k >= 3:
        w_win = _window_means(dth, n_win, dt)
        f_win = _window_means(dv, n_win, dt)
        sigma_f = _mean_noise(f_win)
        tilt, tol_tilt = _tilt(dv, dt, span, sigma_f, n_win)
        if tilt > tol_tilt:
            reasons.append(f"gravity's direction in the body turns by {np.rad2deg(tilt):.3g} "
                           f"deg over the log (threshold {np.rad2deg(tol_tilt):.2g} deg): "
                           f"it rotates about a horizontal axis")
        tol_w = max(N_SIGMA * _mean_noise(w_win), MIN_RATE_DEPARTURE)
        tol_f = max(N_SIGMA * sigma_f, MIN_FORCE_DEPARTURE)
        size = min(k, 2 * (int(round(MEDIAN_S / (n_win * dt))) // 2) + 1)
        med_w = median_filter(w_win, size=(size, 1), mode="nearest")
        med_f = median_filter(f_win, size=(size, 1), mode="nearest")
        dep_w = np.linalg.norm(w_win - med_w, axis=1)
        dep_f = np.linalg.norm(f_win - med_f, axis=1)
        bad = (dep_w > tol_w) | (dep_f > tol_f)
        starts = time[0] - dt + np.arange(k) * n_win * dt
        for i in np.flatnonzero(bad):
            t0, t1 = float(starts[i]), float(starts[i] + n_win * dt)
            if spans and t0 - spans[-1][1] <= 1e-9 + n_win * dt:    # one window apart
                spans[-1] = (spans[-1][0], t1)
            else:
                spans.append((t0, t1))
        moving = float(bad.sum() * n_win * dt)
        if bad.any():
            reasons.append(
                f"it moves in {moving:.1f} s of {span:.1f} s: window means ({n_win * dt:g} "
                f"s) depart from their running median by up to "
                f"{np.rad2deg(dep_w.max()):.3g} deg/s (threshold {np.rad2deg(tol_w):.2g}) "
                f"and {dep_f.max():.3g} m/s^2 (threshold {tol_f:.2g})")
    return StaticCheck(static=not reasons, reasons=reasons, spans=spans, moving_s=moving,
                       mean_force=f_mag, mean_rate=w_mag, rate_threshold=tol_w,
                       force_threshold=tol_f, tilt=tilt, tilt_threshold=tol_tilt)
