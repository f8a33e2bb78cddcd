"""Is an IMU log at rest?  Decided from what a rotation does to gravity and to the gyro's
own scatter, not from the mean rate.

A log at rest gives the Allan deviation of the sensors; a log that moves gives the
motion's.  What motion looks like in the data:

- a rotation of angle ``a`` about any axis but the vertical turns gravity's direction in
  the body by up to ``a``, and the gyros integrate it;
- a drift of a horizontal accelerometer bias by ``db`` turns the APPARENT direction by
  ``db / g`` rad without any motion, and the gyros see nothing.  With temperature
  (warm-up, the room) a MEMS bias drifts by a few mg over hours: the real 2.8 h
  ADIS16405 log of issue 32 turns by 0.425 deg (7 mg) at rest.  What tells the two
  apart is the speed and the gyros: a bias drifts at most :data:`MAX_ACCEL_DRIFT_RATE`
  (15 mg/h, 0.014 deg/min of apparent tilt) and by at most :data:`MAX_ACCEL_DRIFT` in
  all (20 mg, 1.15 deg), while a hand, a bump or a carried IMU turns it by tenths of a
  degree in seconds.  So gravity's direction is compared between adjacent windows of
  1, 2, 4, ... s (test 2b): between two windows of length ``S`` (centres ``S`` apart) it
  may turn by the drift ``MAX_ACCEL_DRIFT_RATE * S / g`` plus N_SIGMA times the noise of
  the angle at that scale (measured from the log's own windows, robust to a few that
  move), at least :data:`MIN_TILT_STEP`; the gyros' rotation over the same span (bias:
  their running median) goes in the message, and where they integrate a rotation above
  their own noise that is refused by itself (test 2c).  The total over the log (test 2a)
  is bounded by :data:`MAX_TILT`.  A rotation at a constant rate over many minutes is the
  one case that neither the gyros (it looks like their bias) nor the accelerometers (it
  looks like a drift, if slower than 15 mg/h) can tell: it is refused only when faster
  than the drift or larger than its total;
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
           "TILT_WINDOW_S", "MAX_TILT", "MAX_ACCEL_DRIFT_RATE", "MAX_ACCEL_DRIFT",
           "MIN_TILT_STEP", "MIN_NORM_STEP", "GYRO_SPAN_S", "Step"]

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
#: Largest drift rate of an accelerometer bias with temperature, m/s^2 per s: 15 mg/h.
#: MEMS parts change their bias by 0.1-0.5 mg per deg C (datasheets' "bias temperature
#: coefficient"); a warm-up after power-on or a room's air conditioning changes the
#: part's temperature by up to 30 deg C in an hour.  On a horizontal axis 15 mg/h is
#: 0.86 deg/h (0.014 deg/min) of apparent tilt: the real 2.8 h ADIS16405 log of issue 32
#: drifts by 0.425 deg (0.15 deg/h, 2.6 mg/h on average), a real tilt of 1 deg in 30 min
#: (35 mg/h) is refused.
MAX_ACCEL_DRIFT_RATE = 15e-3 * 9.80665 / 3600.0
#: Largest change of an accelerometer bias over a log, m/s^2: 20 mg (0.2-0.5 mg/deg C
#: over 40-100 deg C of a MEMS part's range), 1.15 deg of apparent tilt.
MAX_ACCEL_DRIFT = 20e-3 * 9.80665
#: Smallest change of gravity's direction that counts as a rotation, rad: 0.1 deg (a
#: horizontal specific force of 1.7 mg), whatever the noise and the drift allow: the
#: window tests' floors, against the few non-Gaussian windows of a real sensor.
MIN_TILT_STEP = np.deg2rad(0.1)
#: ... and of the magnitude of the specific force, m/s^2 (the same 1.7 mg).
MIN_NORM_STEP = 9.80665 * MIN_TILT_STEP
#: Length of the windows whose mean specific force gives gravity's direction for the
#: total turn over the log, s (at most 500 windows: longer ones for a longer log).
TILT_WINDOW_S = 60.0
#: Largest angle between gravity's directions in two windows anywhere in the log, rad:
#: the apparent tilt of :data:`MAX_ACCEL_DRIFT` (1.15 deg), or N_SIGMA times the noise of
#: the angle when that is larger.  (It was 0.3 deg over the whole log, whatever the
#: time: it refused the real ADIS16405 log of issue 32, 0.425 deg in 2.8 h.)
MAX_TILT = MAX_ACCEL_DRIFT / 9.80665
#: The gyros can tell a rotation over a span from their own bias change when the span
#: is much shorter than the running median that gives that bias: spans up to
#: MEDIAN_S / 4 (75 s) get the gyros' rotation in the message.
GYRO_SPAN_S = MEDIAN_S / 4


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
    tilt_step, norm_step, rotation_step : Step or None
        The change of gravity's direction, of the specific force's magnitude and of the
        attitude integrated by the gyros that comes nearest to (or farthest beyond) its
        threshold, over all the scales of :func:`static_check`'s test 3 (None for a log
        of fewer than two windows).
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
    tilt_step: "Step | None" = None
    norm_step: "Step | None" = None
    rotation_step: "Step | None" = None


@dataclass(frozen=True)
class Step:
    """The largest change between two adjacent windows of one length (a scale).

    Attributes
    ----------
    size : float
        The change: rad (gravity's direction, the gyros' rotation) or m/s^2 (the
        magnitude of the specific force).
    threshold : float
        Its threshold at that scale, same unit.
    t0, t1 : float
        Start of the first window and end of the second, s.
    scale_s : float
        Length of each window, s (their centres are that far apart).
    gyro : float
        Rotation about the horizontal that the gyros integrate between the centres of
        the two windows, rad (their bias: the running median of the rate); NaN when the
        windows are longer than :data:`GYRO_SPAN_S` (the gyros cannot tell a slow
        rotation from their own bias drift).
    """

    size: float
    threshold: float
    t0: float
    t1: float
    scale_s: float
    gyro: float = float("nan")

    @property
    def excess(self):
        return self.size / self.threshold


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


#: Fewest non-overlapping windows whose differences give the noise at a scale; longer
#: windows take the noise of the longest scale that has them.
MIN_NOISE_WINDOWS = 32


def _window_sums(c, s):
    """Sums of ``s`` consecutive rows from the cumulative sum ``c`` (k + 1 rows)."""
    return c[s:] - c[:-s]


def _steps(f_win, r_win, block_s, t_first):
    """Largest changes between adjacent windows of 1, 2, 4, ... blocks (module
    docstring, test 2b): gravity's direction and the specific force's magnitude against
    the accelerometers' drift and noise, the attitude integrated by the gyros (``r_win``:
    rates less their running median) against the gyros' noise."""
    k = len(f_win)
    cf = np.concatenate([np.zeros((1, 3)), np.cumsum(f_win, axis=0)])
    theta = np.concatenate([np.zeros((1, 3)), np.cumsum(r_win, axis=0) * block_s])
    tm = 0.5 * (theta[:-1] + theta[1:])          # mean attitude change of each block
    ct = np.concatenate([np.zeros((1, 3)), np.cumsum(tm, axis=0)])
    best = {"tilt": None, "norm": None, "rotation": None}
    sig_f = sig_n = sig_t = None
    s = 1
    while 2 * s <= k:
        F = _window_sums(cf, s) / s                   # window i: blocks i .. i+s-1
        T = _window_sums(ct, s) / s
        g = np.linalg.norm(F, axis=1)
        if k // s >= MIN_NOISE_WINDOWS or sig_f is None:
            sig_f = _mean_noise(F[::s])
            sig_n = _mean_noise(g[::s, None])
            sig_t = _mean_noise(T[::s])
        A, B = F[:-s], F[s:]
        gA, gB = g[:-s], g[s:]
        u = A / gA[:, None]
        ang = np.arctan2(np.linalg.norm(np.cross(A, B), axis=1), np.einsum("ij,ij->i", A, B))
        dn = np.abs(gB - gA)
        phi = T[s:] - T[:-s]                          # rotation between the centres
        g0 = float(np.median(g))
        drift = MAX_ACCEL_DRIFT_RATE * s * block_s
        tols = {"tilt": max(MIN_TILT_STEP, (drift + N_SIGMA * np.sqrt(2.0) * sig_f) / g0),
                "norm": max(MIN_NORM_STEP, drift + N_SIGMA * np.sqrt(2.0) * sig_n),
                "rotation": max(MIN_TILT_STEP, N_SIGMA * np.sqrt(2.0) * sig_t)}
        sizes = {"tilt": ang, "norm": dn}
        if s * block_s <= GYRO_SPAN_S:
            sizes["rotation"] = np.linalg.norm(phi, axis=1)
        for key, size in sizes.items():
            i = int(np.argmax(size))
            if best[key] is None or size[i] / tols[key] > best[key].excess:
                gyro = (float(np.linalg.norm(np.cross(phi[i], u[i])))
                        if s * block_s <= GYRO_SPAN_S else float("nan"))
                best[key] = Step(size=float(size[i]), threshold=float(tols[key]),
                                 t0=float(t_first + i * block_s),
                                 t1=float(t_first + (i + 2 * s) * block_s),
                                 scale_s=float(s * block_s), gyro=gyro)
        s *= 2
    return best["tilt"], best["norm"], best["rotation"]


def _gyro_text(step):
    if not np.isfinite(step.gyro):
        return (f"; windows of {step.scale_s:g} s are too long for the gyros to tell a "
                f"rotation from their own bias drift")
    if step.gyro >= 0.5 * step.size:
        return (f"; the gyros integrate {np.rad2deg(step.gyro):.3g} deg about the "
                f"horizontal over the same span: the body rotates")
    return (f"; the gyros integrate only {np.rad2deg(step.gyro):.3g} deg about the "
            f"horizontal over the same span: not a rotation, a step of the "
            f"accelerometers or an acceleration")


def _step_reasons(tilt_step, norm_step, rotation_step):
    reasons = []
    rate_dpm = np.rad2deg(MAX_ACCEL_DRIFT_RATE / 9.80665) * 60
    mg_h = MAX_ACCEL_DRIFT_RATE / 9.80665e-3 * 3600
    if tilt_step is not None and tilt_step.excess > 1:
        st = tilt_step
        reasons.append(
            f"gravity's direction in the body turns by {np.rad2deg(st.size):.3g} deg between "
            f"two adjacent {st.scale_s:g} s windows ({st.t0:.2f} .. {st.t1:.2f} s), "
            f"{np.rad2deg(st.size) / st.scale_s * 60:.3g} deg/min (threshold "
            f"{np.rad2deg(st.threshold):.2g} deg: an accelerometer bias drifting at "
            f"{mg_h:g} mg/h, {rate_dpm:.2g} deg/min, plus {N_SIGMA:g} sigma of the noise "
            f"at that scale, at least {np.rad2deg(MIN_TILT_STEP):g} deg){_gyro_text(st)}")
    if norm_step is not None and norm_step.excess > 1:
        st = norm_step
        reasons.append(
            f"the specific force's magnitude changes by {st.size:.3g} m/s^2 between two "
            f"adjacent {st.scale_s:g} s windows ({st.t0:.2f} .. {st.t1:.2f} s; threshold "
            f"{st.threshold:.2g} m/s^2: a bias drift of {mg_h:g} mg/h plus {N_SIGMA:g} "
            f"sigma of the noise, at least {MIN_NORM_STEP:.2g}): an acceleration")
    if rotation_step is not None and rotation_step.excess > 1:
        st = rotation_step
        reasons.append(
            f"the gyros integrate a rotation of {np.rad2deg(st.size):.3g} deg between two "
            f"adjacent {st.scale_s:g} s windows ({st.t0:.2f} .. {st.t1:.2f} s; bias: the "
            f"running median of the rate; threshold {np.rad2deg(st.threshold):.2g} deg: "
            f"{N_SIGMA:g} sigma of the gyros' own angle noise at that scale, at least "
            f"{np.rad2deg(MIN_TILT_STEP):g} deg): the body turns")
    return reasons


def static_check(time, dtheta_b, dvel_b, window_s=WINDOW_S):
    """Whether an IMU log is at rest, and where it moves.

    Tests (thresholds and their reasons in the module constants):

    1. the magnitude of the mean specific force over the log lies within
       :data:`GRAVITY_MARGIN` of normal gravity (:data:`GRAVITY_RANGE`);
    2. gravity's direction in the body, the mean specific force over windows:

       a. over the log (windows of :data:`TILT_WINDOW_S`) it turns by at most
          :data:`MAX_TILT`, the apparent tilt of the largest drift of a bias
          (:data:`MAX_ACCEL_DRIFT`);
       b. between two adjacent windows of ``S`` = 1, 2, 4, ... s (at every start on a
          grid of ``window_s``) it turns by at most
          ``max(MIN_TILT_STEP, (MAX_ACCEL_DRIFT_RATE * S + N_SIGMA sqrt(2) sigma_S) / g)``,
          ``sigma_S`` the noise of a window mean at that scale (largest axis, from the
          differences of non-overlapping windows); the magnitude of the specific force
          changes by at most ``max(MIN_NORM_STEP, MAX_ACCEL_DRIFT_RATE * S + N_SIGMA
          sqrt(2) sigma_S)`` (its own noise);
       c. the attitude the gyros integrate (rate less its running median over
          :data:`MEDIAN_S`) changes between the centres of two adjacent windows of ``S``
          up to :data:`GYRO_SPAN_S` by at most ``max(MIN_TILT_STEP, N_SIGMA sqrt(2)
          sigma)``, ``sigma`` the noise of a window's mean attitude;

       a slow drift (hours, tenths of a degree) passes, a rotation of a few tenths of a
       degree in seconds or minutes does not;
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
    steps = (None, None, None)
    if k >= 3:
        w_win = _window_means(dth, n_win, dt)
        f_win = _window_means(dv, n_win, dt)
        sigma_f = _mean_noise(f_win)
        tilt, tol_tilt = _tilt(dv, dt, span, sigma_f, n_win)
        if tilt > tol_tilt:
            reasons.append(f"gravity's direction in the body turns by {np.rad2deg(tilt):.3g} "
                           f"deg over the log (threshold {np.rad2deg(tol_tilt):.2g} deg: an "
                           f"accelerometer bias drifts by at most "
                           f"{MAX_ACCEL_DRIFT / 9.80665e-3:g} mg over a log): it rotates "
                           f"about a horizontal axis")
        tol_w = max(N_SIGMA * _mean_noise(w_win), MIN_RATE_DEPARTURE)
        tol_f = max(N_SIGMA * sigma_f, MIN_FORCE_DEPARTURE)
        size = min(k, 2 * (int(round(MEDIAN_S / (n_win * dt))) // 2) + 1)
        med_w = median_filter(w_win, size=(size, 1), mode="nearest")
        med_f = median_filter(f_win, size=(size, 1), mode="nearest")
        # the gyros' bias for their rotation: the same running median, mirrored at the
        # ends (a 'nearest' padding repeats the last window's noise half the window)
        bias_w = median_filter(w_win, size=(size, 1), mode="reflect")
        steps = _steps(f_win, w_win - bias_w, n_win * dt, float(time[0] - dt))
        reasons += _step_reasons(*steps)
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
                       force_threshold=tol_f, tilt=tilt, tilt_threshold=tol_tilt,
                       tilt_step=steps[0], norm_step=steps[1], rotation_step=steps[2])
