"""Overlapping Allan deviation of IMU data and the noise terms read from it.

For a rate signal ``y`` sampled every ``dt`` (or increments ``y dt``), with the running
integral ``theta_k = sum_{j<=k} y_j dt`` and ``tau = m dt``::

    sigma^2(tau) = sum_k (theta_{k+2m} - 2 theta_{k+m} + theta_k)^2 / (2 tau^2 (N - 2m))

(IEEE Std 952, overlapping estimator; all k at once from the cumulative sum).  White
rate noise of density ``N`` (angle/velocity random walk, rad/sqrt(s) or m/s/sqrt(s))
gives ``sigma(tau) = N / sqrt(tau)``: ``N`` is read on the slope -1/2 at tau = 1 s.
Flicker (bias instability ``B``) gives the flat minimum ``0.664 B``.

The Allan deviation means something only for a log at rest: :func:`static_check`
finds the parts of a log that move (see its thresholds) so that the command can refuse
a moving log instead of reporting the motion as noise.
"""
from dataclasses import dataclass

import numpy as np

__all__ = ["allan_deviation", "noise_densities", "static_check", "StaticCheck",
           "GRAVITY_RANGE", "GRAVITY_MARGIN", "MAX_MEAN_RATE", "WINDOW_S", "N_SIGMA",
           "MIN_RATE_DEPARTURE", "MIN_FORCE_DEPARTURE"]

#: Normal gravity on the WGS84 ellipsoid from the equator to the poles, m/s^2
#: (conventions.md; at 6 km height it is 0.019 m/s^2 less).
GRAVITY_RANGE = (9.780, 9.832)
#: Tolerance on the log's mean specific force against :data:`GRAVITY_RANGE`, m/s^2
#: (0.3 m/s^2 ~ 31 mg: accelerometer biases and scale factors of MEMS grade included).
GRAVITY_MARGIN = 0.3
#: Largest magnitude of the log's mean angular rate, rad/s (0.1 deg/s = 360 deg/h: the
#: Earth rate, 15.04 deg/h, plus gyro biases of MEMS grade; a log that turns steadily
#: is not at rest).
MAX_MEAN_RATE = np.deg2rad(0.1)
#: Length of the windows whose mean rate and specific force are compared, s.
WINDOW_S = 1.0
#: A window moves when its mean departs from the log's median by more than N_SIGMA
#: times the white noise of a window mean (estimated from the sample-to-sample
#: differences of the log itself) ...
N_SIGMA = 7.0
#: ... and by more than these floors (bias instability, temperature drift), rad/s and
#: m/s^2: 0.01 deg/s = 36 deg/h and 0.05 m/s^2 ~ 5 mg.
MIN_RATE_DEPARTURE = np.deg2rad(0.01)
MIN_FORCE_DEPARTURE = 0.05


@dataclass(frozen=True)
class StaticCheck:
    """Result of :func:`static_check` (SI units).

    Attributes
    ----------
    static : bool
        True when no test flags motion.
    reasons : list of str
        One sentence per failed test (deg/s, m/s^2 in the text).
    spans : list of (float, float)
        Time spans (s, window bounds) whose windows move, in time order.
    moving_s : float
        Total length of those spans, s.
    mean_force : float
        Magnitude of the mean specific force over the log, m/s^2.
    mean_rate : float
        Magnitude of the mean angular rate over the log, rad/s.
    rate_threshold, force_threshold : float
        Departure thresholds used for the windows, rad/s and m/s^2.
    """

    static: bool
    reasons: list
    spans: list
    moving_s: float
    mean_force: float
    mean_rate: float
    rate_threshold: float
    force_threshold: float


def _window_noise(inc, n_win, dt):
    """White-noise sigma of a window mean of the rate, from the increments' first
    differences (robust: median absolute deviation), the largest axis."""
    d = np.diff(inc, axis=0)
    if len(d) < 2:
        return 0.0
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    sigma_rate = 1.4826 * mad / np.sqrt(2.0) / dt         # per sample, rate units
    return float(np.max(sigma_rate) / np.sqrt(n_win))


def static_check(time, dtheta_b, dvel_b, window_s=WINDOW_S):
    """Whether an IMU log is at rest, and where it moves.

    Tests (thresholds in the module constants):

    1. the magnitude of the mean specific force over the log lies within
       :data:`GRAVITY_MARGIN` of normal gravity (:data:`GRAVITY_RANGE`);
    2. the magnitude of the mean angular rate is below :data:`MAX_MEAN_RATE` (the
       Earth rate plus gyro biases);
    3. in windows of ``window_s``, the mean rate and the mean specific force (vectors)
       stay within ``max(N_SIGMA * sigma_window, floor)`` of their medians over the
       log, ``sigma_window`` the white noise of a window mean estimated from the log's
       sample-to-sample differences, the floors :data:`MIN_RATE_DEPARTURE` and
       :data:`MIN_FORCE_DEPARTURE`.  Windows that fail are the moving spans.

    Parameters
    ----------
    time : ndarray, shape (n,)
        s, increasing (increments stamped at the end of their interval).
    dtheta_b, dvel_b : ndarray, shape (n, 3)
        Increments, rad and m/s.
    window_s : float
        Window length, s (at least 10 samples are used per window).

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
    if w_mag > MAX_MEAN_RATE:
        reasons.append(f"the mean angular rate is {np.rad2deg(w_mag):.4g} deg/s, more than "
                       f"the Earth rate and a gyro bias ({np.rad2deg(MAX_MEAN_RATE):g} deg/s)")
    n_win = max(10, int(round(window_s / dt)))
    k = n // n_win
    spans, moving = [], 0.0
    tol_w = tol_f = float("nan")
    if k >= 2:
        w_win = dth[:k * n_win].reshape(k, n_win, 3).sum(axis=1) / (n_win * dt)
        f_win = dv[:k * n_win].reshape(k, n_win, 3).sum(axis=1) / (n_win * dt)
        tol_w = max(N_SIGMA * _window_noise(dth, n_win, dt), MIN_RATE_DEPARTURE)
        tol_f = max(N_SIGMA * _window_noise(dv, n_win, dt), MIN_FORCE_DEPARTURE)
        dep_w = np.linalg.norm(w_win - np.median(w_win, axis=0), axis=1)
        dep_f = np.linalg.norm(f_win - np.median(f_win, axis=0), axis=1)
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
                f"s) depart from the log's median by up to {np.rad2deg(dep_w.max()):.3g} "
                f"deg/s (threshold {np.rad2deg(tol_w):.2g}) and {dep_f.max():.3g} m/s^2 "
                f"(threshold {tol_f:.2g})")
    return StaticCheck(static=not reasons, reasons=reasons, spans=spans, moving_s=moving,
                       mean_force=f_mag, mean_rate=w_mag, rate_threshold=tol_w,
                       force_threshold=tol_f)


def _default_taus(n, dt, per_decade=10):
    m_max = max(1, (n - 1) // 4)
    m = np.unique(np.round(np.logspace(0, np.log10(m_max), int(per_decade * np.log10(m_max)) + 1)))
    return m.astype(np.int64) * dt


def allan_deviation(data, dt, taus=None, increments=True):
    """Overlapping Allan deviation.

    Parameters
    ----------
    data : array_like, shape (n,) or (n, k)
        Increments (rad, m/s) if ``increments``, else rates (rad/s, m/s^2), equally
        spaced by ``dt``.
    dt : float
        Sampling interval, s.
    taus : array_like, optional
        Averaging times, s (rounded to multiples of dt; default 10 per decade from dt to
        a quarter of the record).
    increments : bool
        Whether ``data`` are increments over ``dt`` (the deviation is of the rate).

    Returns
    -------
    tau : ndarray, shape (m,)
        s.
    adev : ndarray, shape (m,) or (m, k)
        Allan deviation of the rate, rad/s or m/s^2.
    """
    y = np.asarray(data, dtype=float)
    one = y.ndim == 1
    y = y.reshape(len(y), -1)
    n = len(y)
    if n < 3:
        raise ValueError(f"need at least 3 samples, got {n}")
    inc = y if increments else y * dt
    theta = np.concatenate([np.zeros((1, y.shape[1])), np.cumsum(inc, axis=0)])
    if taus is None:
        taus = _default_taus(n, dt)
    m = np.unique(np.round(np.asarray(taus, dtype=float) / dt).astype(np.int64))
    m = m[(m >= 1) & (2 * m <= n)]
    adev = np.empty((len(m), y.shape[1]))
    for i, mi in enumerate(m):
        d = theta[2 * mi:] - 2 * theta[mi:-mi] + theta[:-2 * mi]
        adev[i] = np.sqrt(np.mean(d * d, axis=0) / 2.0) / (mi * dt)
    tau = m * dt
    return tau, (adev[:, 0] if one else adev)


def noise_densities(tau, adev):
    """White-noise density and bias instability read from an Allan deviation curve.

    Parameters
    ----------
    tau : ndarray, shape (m,)
    adev : ndarray, shape (m,) or (m, k)

    Returns
    -------
    random_walk : ndarray, shape () or (k,)
        ``sigma(1 s)`` of the slope -1/2 line fitted (in log-log) on the first run of
        points whose local slope is within -0.5 +- 0.15, units of
        adev * sqrt(s) (rad/sqrt(s), m/s/sqrt(s)).
    bias_instability : ndarray
        ``min(adev) / 0.664``, units of adev.
    """
    tau = np.asarray(tau, dtype=float)
    a = np.asarray(adev, dtype=float)
    one = a.ndim == 1
    a = a.reshape(len(a), -1)
    rw = np.empty(a.shape[1])
    if not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise ValueError("the Allan deviation is zero or not finite somewhere: the log "
                         "holds no noise (an exact synthetic log?)")
    for j in range(a.shape[1]):
        la, lt = np.log(a[:, j]), np.log(tau)
        slope = np.gradient(la, lt)
        ok = np.abs(slope + 0.5) < 0.15
        if not ok.any():
            raise ValueError("no part of the Allan deviation has the slope -1/2 of white noise")
        start = int(np.argmax(ok))
        run = ok[start:]
        end = start + (int(np.argmin(run)) if not run.all() else len(run))
        use = np.arange(start, end)
        rw[j] = np.exp(np.mean(la[use] + 0.5 * lt[use]))
    bi = a.min(axis=0) / 0.664
    return (rw[0], bi[0]) if one else (rw, bi)
