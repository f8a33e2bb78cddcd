"""IMU-GNSS clock offset estimated from the data: the horizontal acceleration seen by the
GNSS against the specific force of the accelerometers (cross-correlation with a
sub-sample peak and a sigma).

Model
-----
The velocity increments of the IMU are resolved in the body frame of its first epoch
(``0``) by the attitude integrated from the gyros alone (no Earth or transport rate)
and summed: ``V_0(t)``.  Over a window of ``W`` seconds centred on each GNSS epoch the
accelerometers see the velocity change less gravity, in NED::

    C_n0 [V_0(t+offset+W/2) - V_0(t+offset-W/2)] = v(t+W/2) - v(t-W/2) - g_n W + b(t)

with ``v`` the GNSS velocity (its velocity columns, or the differences of consecutive
positions at their mid times; a missing vertical velocity written as 0 matters little
next to ``g W``).  ``C_n0`` is fitted per knot interval (every ``knot_s`` seconds: gyro
drift, Earth rate) by Kabsch's least squares: gravity fixes its tilt, the horizontal
changes its heading, so the IMU may sit in any attitude and the vehicle may bank,
crab or turn.  The north and east residuals are then freed of ``b``: slowly varying
terms (accelerometer bias, the tilt drift) piecewise linear in time on the same knots.
All of it is linear least squares at each trial offset.

Sign (one convention across the toolkit): ``offset`` is the IMU clock minus the GNSS
clock, a record stamped ``t`` holds the state at IMU time ``t + offset``.  It is the
value to paste into ``[gnss] time_shift_s`` (``--gnss-time-shift-s``, added to the GNSS
stamps at read time: ``t_imu = t_gnss + shift``; ``[imu] time_shift_s`` would take
``-offset``), and the sign of the filter's ``time_offset`` state (``states.txt``,
``[states] time_offset``) and of the simulator's injected offset
(``ins.simulate.gnss.simulate_gnss``).  The residual sum
of squares over a grid of offsets (step ``step_s``) is the (negative) cross-correlation
curve; its minimum is refined by a parabola fitted over +-0.1 s around the best trial
offset (sub-sample peak; the real curve wiggles at the scale of the GNSS interval).
The sigma is that of linearized least squares, ``sigma^2 = J' S J / (J'J)^2`` with ``J``
the derivative of the residuals with respect to the offset and ``S`` the residuals'
covariance estimated from their products over the overlapping windows (Newey-West,
Bartlett weights): the windowed differences and the GNSS noise are correlated.  On a
simulated flight the sigma is 2 to 4 times the scatter of the estimate over noise seeds
(conservative); on the comma2k19 segment the estimate moves by about +-0.01 s with the
window (0.4 to 1 s), twice its sigma there: a model error (lever arm, vehicle flexing,
the receiver's filter) the sigma does not hold.

Positions and velocities of one receiver may carry different delays (a u-blox's
position can lead its Doppler velocity): ``source = "velocity"`` uses the velocity
columns, ``"position"`` the position differences; estimate both: the position's offset
is the value of ``[gnss] time_shift_s``, the velocity's that of ``[gnss]
velocity_time_shift_s``.  The information is in the accelerations: a log at constant
velocity has none (refused).

A constant accelerometer bias ``b`` (body frame) adds ``U(t) b`` to ``V_0``, with
``U(t) = int C_0b dt``: it turns with the IMU, so the slowly varying terms in NED do not
hold it.  At a car's or an aircraft's accelerations it is small; at walking pace
(velocity changes of 0.15 m/s RMS over 0.5 s) a 10 mg bias is as large as the signal,
and without it the offset of a simulated walk moved by 0.016 s (4 sigma).  It is fitted
(3 unknowns, Gauss-Newton on the same residuals with the rotations refitted, a ridge
of ``BIAS_PRIOR_MPS2``) at the offset found without it (a horizontal bias and a tilt
differ only through the turns); when it lowers the residuals significantly
(``BIAS_CHI2``) the offset is searched again with it (and the bias refitted there),
else the offset without it stands (an aircraft's, a car's: unchanged).
Units: s, m/s inside.
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError

#: Default half-width of the searched offsets, s.
MAX_OFFSET_S = 1.0
#: Default step of the trial offsets, s.
STEP_S = 0.005
#: Half-width of the parabola fitted around the minimum of the residual curve, s.
FIT_S = 0.1
#: Default window of the differences, s.
WINDOW_S = 0.5
#: Default spacing of the knots of the slowly varying terms, s.
KNOT_S = 10.0
#: Default speed below which a fix is not used, m/s (a stop holds no information; a
#: walk at 1-2 m/s has enough in its turns and speed changes).
MIN_SPEED_MPS = 0.5
#: Smallest RMS of the GNSS velocity changes over the window (m/s) for an estimate.
MIN_SIGNAL_MPS = 0.02
#: Prior sigma of the accelerometer bias (m/s^2, a ridge on its estimate), and the
#: most Gauss-Newton steps, their convergence and the step of the numerical Jacobian
#: (m/s^2).
BIAS_PRIOR_MPS2 = 0.5
BIAS_ITERATIONS = 10
BIAS_TOL_MPS2 = 1e-5
BIAS_STEP_MPS2 = 1e-4
#: The bias is used when it lowers the residual sum of squares by more than this many
#: times its mean square (chi-square, 3 dof, p = 0.001).
BIAS_CHI2 = 16.3
SOURCES = ("velocity", "position")


@dataclass(frozen=True)
class TimeOffset:
    """An estimated IMU-GNSS clock offset.

    Attributes
    ----------
    offset_s : float
        IMU clock minus GNSS clock, s: a record stamped ``t`` was taken at IMU time
        ``t + offset_s``; the GNSS stamps plus this are on the IMU's scale (the value of
        ``[gnss] time_shift_s``; the sign of the filter's ``time_offset`` state).
    sigma_s : float
        1-sigma of ``offset_s`` (correlation-inflated), s.
    source : str
        ``"velocity"`` or ``"position"`` (what the GNSS side was made of).
    n_fixes : int
        GNSS epochs used.
    n_eff : float
        Independent samples the residuals amount to.
    residual_rms_mps : float
        RMS of the residual velocity changes at the estimate, m/s.
    signal_rms_mps : float
        RMS of the GNSS velocity changes over the window, m/s (the signal).
    lags_s, rss : ndarray
        The trial offsets (s) and the residual sum of squares at each (m^2/s^2).
    accel_bias_b_mps2 : ndarray, shape (3,) or None
        The accelerometer bias fitted with it (m/s^2, IMU axes; its vertical part is
        weakly determined when the IMU stays level); ``None`` when not significant
        (``BIAS_CHI2``) and not used.
    """

    offset_s: float
    sigma_s: float
    source: str
    n_fixes: int
    n_eff: float
    residual_rms_mps: float
    signal_rms_mps: float
    lags_s: np.ndarray
    rss: np.ndarray
    accel_bias_b_mps2: np.ndarray = None


def imu_velocity(imu):
    """Specific force integrated in the body frame of the first epoch (attitude from the
    gyros alone, ``ins.estimation.tools._time_offset_kernels``): ``(time, V)`` with ``V`` shape (n+1, 3),
    m/s, 0 at the start of the first increment (its interval taken as the next one)."""
    from ins.estimation.tools._time_offset_kernels import resolve_increments
    dvel_0 = resolve_increments(np.ascontiguousarray(imu.dtheta_b, dtype=float),
                                np.ascontiguousarray(imu.dvel_b, dtype=float))
    t = np.asarray(imu.time)
    t0 = t[0] - (t[1] - t[0])
    return np.concatenate([[t0], t]), np.vstack([np.zeros(3), np.cumsum(dvel_0, axis=0)])


def imu_attitude_integral(imu):
    """``int C_0b dt`` from the start (s), shape (n+1, 3, 3), on the times of
    :func:`imu_velocity`: a constant accelerometer bias ``b_b`` adds ``U(t) @ b_b`` to
    ``V_0(t)``."""
    from ins.estimation.tools._time_offset_kernels import resolve_increments
    t = np.asarray(imu.time, dtype=float)
    dt = np.diff(np.concatenate([[t[0] - (t[1] - t[0])], t]))
    th = np.ascontiguousarray(imu.dtheta_b, dtype=float)
    cols = [resolve_increments(th, np.ascontiguousarray(np.outer(dt, e))) for e in np.eye(3)]
    dU = np.stack(cols, axis=2)                          # (n, 3, 3): column j = C_0b e_j dt
    return np.concatenate([np.zeros((1, 3, 3)), np.cumsum(dU, axis=0)])


def gnss_velocity(gnss, source="velocity"):
    """``(time, v_ned)`` of the GNSS, m/s: the velocity columns (``"velocity"``) or the
    differences of consecutive positions at their mid times (``"position"``)."""
    from ins.nav import earth
    if source not in SOURCES:
        raise InputError(f"source {source!r}: expected one of {', '.join(SOURCES)}")
    if source == "velocity":
        if not gnss.has_velocity:
            raise InputError(f"{gnss.path or 'the GNSS log'}: no velocity columns (use the "
                             f"position differences)")
        return np.asarray(gnss.time), np.asarray(gnss.v_n)
    d = earth.ned_offset(gnss.lla[:-1], gnss.lla[1:])
    return 0.5 * (gnss.time[1:] + gnss.time[:-1]), d / np.diff(gnss.time)[:, None]


def _rotations(src, dst, segment, n):
    """Per segment, the rotation ``R`` minimizing ``sum |R src - dst|^2`` (Kabsch),
    shape (n, 3, 3)."""
    prod = (src[:, :, None] * dst[:, None, :]).reshape(len(src), 9)
    H = np.column_stack([np.bincount(segment, prod[:, k], minlength=n)
                         for k in range(9)]).reshape(n, 3, 3)
    U, _, Vt = np.linalg.svd(H)
    det = np.sign(np.linalg.det(np.einsum("nij,njk->nik", U, Vt)))
    D = np.zeros((n, 3, 3))
    D[:, 0, 0] = 1.0
    D[:, 1, 1] = 1.0
    D[:, 2, 2] = det
    return np.einsum("nji,njk,nlk->nil", Vt, D, U)


def _hat(t, knots):
    """Piecewise-linear (hat) basis at ``t`` on ``knots``, shape (len(t), len(knots))."""
    return np.column_stack([np.interp(t, knots, np.eye(len(knots))[j])
                            for j in range(len(knots))])


def _hac_sigma(J, e, n_series, lags):
    """Standard deviation of a one-parameter least-squares estimate with correlated
    residuals (Newey-West): ``sqrt(sum_k w_k sum_i g_i g_(i+k)) / (J.J)`` with
    ``g = J e`` per series (``J``, ``e`` are ``n_series`` series end to end), Bartlett
    weights ``w_k = 1 - |k| / (lags + 1)`` up to ``lags``.  Also returns the number of
    independent samples the residuals amount to for this estimate (white / HAC variance
    times the count)."""
    g = (J * e).reshape(n_series, -1)
    var = float(np.sum(g * g))
    for k in range(1, lags + 1):
        var += 2.0 * (1.0 - k / (lags + 1.0)) * float(np.sum(g[:, :-k] * g[:, k:]))
    var = max(var, 1e-30)
    jj = float(J @ J)
    white = float(e @ e) / len(e) / jj
    return float(np.sqrt(var) / jj), float(len(e) * white / (var / jj ** 2))


class _Problem:
    """The observations at the used GNSS epochs and the residuals at a trial offset."""

    def __init__(self, imu, gnss, source, window_s, knot_s, max_offset_s, min_speed_mps):
        from ins.nav import earth
        self.t_i, self.V = imu_velocity(imu)
        self.U = imu_attitude_integral(imu)
        t_g, v = gnss_velocity(gnss, source)
        speed = np.hypot(v[:, 0], v[:, 1])
        h = 0.5 * window_s
        margin = max_offset_s + h
        use = ((t_g - margin >= self.t_i[0]) & (t_g + margin <= self.t_i[-1])
               & (t_g - h >= t_g[0]) & (t_g + h <= t_g[-1]) & (speed >= min_speed_mps))
        self.t = t_g[use]
        self.h = h
        dv = (np.column_stack([np.interp(self.t + h, t_g, v[:, j]) for j in range(3)])
              - np.column_stack([np.interp(self.t - h, t_g, v[:, j]) for j in range(3)]))
        self.obs = dv[:, :2].ravel()
        # what the accelerometers see over the window: dv - g W (g down, NED)
        g = float(earth.normal_gravity(gnss.lla[0, 0], gnss.lla[0, 2]))
        self.target = dv - np.array([0.0, 0.0, g * window_s])
        if len(self.t) >= 2:
            knots = np.arange(self.t[0], self.t[-1] + knot_s, knot_s)
            B = _hat(self.t, knots)
            Z = np.zeros_like(B)
            self.A = np.block([[B, Z], [Z, B]])
            self.Q = np.linalg.qr(self.A)[0]       # the slowly varying terms' span
            self.segment = np.minimum(((self.t - self.t[0]) // knot_s).astype(int),
                                      max(len(knots) - 2, 0))

    def _window(self, ts, series):
        """``series(ts + h) - series(ts - h)`` of series on the IMU times (linear
        interpolation, the ends held), one search for all of them."""
        out = []
        for x in (ts + self.h, ts - self.h):
            k = np.clip(np.searchsorted(self.t_i, x, side="right"), 1, len(self.t_i) - 1)
            t0, t1 = self.t_i[k - 1], self.t_i[k]
            w = np.clip((x - t0) / (t1 - t0), 0.0, 1.0)
            out.append([s[k - 1] + (w.reshape((-1,) + (1,) * (s.ndim - 1)))
                        * (s[k] - s[k - 1]) for s in series])
        return [hi - lo for hi, lo in zip(*out)]

    def residuals(self, offset, b=None):
        """North and east residuals at ``offset`` (s), freed of the slowly varying terms,
        with the accelerometer bias ``b`` (m/s^2, b; ``None``: 0) removed."""
        ts = self.t + offset                   # the records' IMU times (module notes)
        # dU @ b_b: a constant accelerometer bias integrated over the window (frame 0)
        dV, dU = self._window(ts, (self.V, self.U))
        c = dV if b is None else dV - dU @ np.asarray(b, dtype=float)
        # the first epoch's body frame into NED: one rotation per knot interval
        # (Kabsch; gravity fixes the tilt, the horizontal changes the heading; drift)
        R = _rotations(c, self.target, self.segment, int(self.segment.max()) + 1)
        e = np.einsum("nij,nj->ni", R[self.segment], c) - self.target
        r = np.concatenate([e[:, 0], e[:, 1]])
        return r - self.Q @ (self.Q.T @ r)

    def bias(self, offset):
        """The accelerometer bias (m/s^2, b) at ``offset`` minimizing the residuals'
        sum of squares (the rotations refitted with it: a horizontal bias and a tilt
        differ only through the turns) plus a ridge of ``BIAS_PRIOR_MPS2`` at the
        residuals' scale: Gauss-Newton with a numerical Jacobian and step halving."""
        b = np.zeros(3)
        r = self.residuals(offset, b)
        ridge = float(np.mean(r ** 2)) / BIAS_PRIOR_MPS2 ** 2
        f = float(r @ r)
        for _ in range(BIAS_ITERATIONS):
            J = np.column_stack([(self.residuals(offset, b + BIAS_STEP_MPS2 * e) - r)
                                 / BIAS_STEP_MPS2 for e in np.eye(3)])
            step = np.linalg.solve(J.T @ J + ridge * np.eye(3), -(J.T @ r + ridge * b))
            for alpha in (1.0, 0.5, 0.25, 0.125):
                b1 = b + alpha * step
                r1 = self.residuals(offset, b1)
                f1 = float(r1 @ r1 + ridge * b1 @ b1)
                if f1 < f:
                    break
            else:
                break
            b, r, f = b1, r1, f1
            if np.max(np.abs(alpha * step)) < BIAS_TOL_MPS2:
                break
        return b


def _minimum(p, lags, b, max_offset_s):
    """The residual sum of squares over ``lags`` with the bias ``b`` and its minimum
    refined by a parabola: ``(offset, rss)``."""
    rss = np.array([float(np.sum(p.residuals(x, b) ** 2)) for x in lags])
    k = int(np.argmin(rss))
    if k == 0 or k == len(lags) - 1:
        raise InputError(f"the best time offset is at the edge of the searched range "
                         f"+-{max_offset_s:g} s: widen it")
    # a parabola fitted over +-FIT_S around the grid minimum: the vertex (sub-sample
    # peak) and the curvature of the curve's shape, not of its local wiggles
    step = lags[1] - lags[0]
    near = np.abs(lags - lags[k]) <= max(FIT_S, 2 * step)
    a2, a1, _ = np.polyfit(lags[near] - lags[k], rss[near], 2)
    if not a2 > 0:
        raise InputError("the residual curve has no minimum near its lowest point: no "
                         "usable information on the time offset")
    return float(np.clip(lags[k] - a1 / (2 * a2), lags[k] - FIT_S, lags[k] + FIT_S)), rss


def estimate_time_offset(imu, gnss, source="velocity", max_offset_s=MAX_OFFSET_S,
                         step_s=STEP_S, window_s=WINDOW_S, knot_s=KNOT_S,
                         min_speed_mps=MIN_SPEED_MPS):
    """Estimate the IMU-GNSS clock offset (module notes).

    Parameters
    ----------
    imu : ins.nav.imu.ImuLog
        Increments in the body frame (FRD), stamped at the end of their interval.
    gnss : ins.io.gnss_log.GnssLog
        Fixes on the GNSS clock.
    source : {"velocity", "position"}
        The GNSS velocity columns, or the differences of consecutive positions.
    max_offset_s, step_s, window_s, knot_s : float
        Half-width and step of the searched offsets, window of the differences, spacing
        of the knots of the slowly varying terms, s.
    min_speed_mps : float
        Fixes slower than this are not used, m/s.

    Returns
    -------
    TimeOffset

    Raises
    ------
    InputError
        Too few fixes at speed inside the IMU span, no accelerations (no information),
        or a minimum at the edge of the searched range (widen ``max_offset_s``).
    """
    if not (max_offset_s > 0 and 0 < step_s < max_offset_s and window_s > 0 and knot_s > 0):
        raise InputError(f"max offset {max_offset_s!r} s, step {step_s!r} s, window "
                         f"{window_s!r} s, knots {knot_s!r} s: expected 0 < step < max "
                         f"and window, knots > 0")
    p = _Problem(imu, gnss, source, window_s, knot_s, max_offset_s, min_speed_mps)
    n = len(p.t)
    if n < 2 or n < 4 * p.A.shape[1]:
        raise InputError(f"{n} GNSS epochs at {min_speed_mps:g} m/s or faster inside the "
                         f"IMU span (less {max_offset_s + 0.5 * window_s:g} s at each "
                         f"end): too few for a time offset with knots every {knot_s:g} s")
    signal = float(np.sqrt(np.mean(p.obs ** 2)))
    if signal < MIN_SIGNAL_MPS:
        raise InputError(f"the GNSS velocity changes by {signal:.3g} m/s RMS over "
                         f"{window_s:g} s: a log without accelerations or turns holds no "
                         f"information on the time offset")
    lags = np.arange(-max_offset_s, max_offset_s + 0.5 * step_s, step_s)
    # the offset without a bias, the bias there, the offset with that bias (the bias
    # hardly depends on the offset; at walking pace a 10 mg bias turned with the IMU
    # is as large as the signal and moved the offset by 0.016 s)
    x, rss = _minimum(p, lags, None, max_offset_s)
    b = p.bias(x)
    r0, rb = p.residuals(x), p.residuals(x, b)
    if (r0 @ r0 - rb @ rb) / (rb @ rb / len(rb)) < BIAS_CHI2:
        b = None                       # not significant: the offset without it
    else:
        x, rss = _minimum(p, lags, b, max_offset_s)
        b = p.bias(x)
    e = p.residuals(x, b)
    # the sigma of linearized least squares (the noise of the observations cancels in
    # the difference of the residuals) with the residuals' correlation over the
    # overlapping windows and beyond (Newey-West)
    J = (p.residuals(x + step_s, b) - p.residuals(x - step_s, b)) / (2.0 * step_s)
    n_lags = int(np.ceil(window_s / np.median(np.diff(p.t)))) + 2
    sigma, n_eff = _hac_sigma(J, e, 2, n_lags)
    return TimeOffset(offset_s=float(x), sigma_s=sigma, source=source, n_fixes=n,
                      n_eff=n_eff, residual_rms_mps=float(np.sqrt(np.mean(e ** 2))),
                      signal_rms_mps=signal, lags_s=lags, rss=rss, accel_bias_b_mps2=b)


def shift_gnss(gnss, offset_s):
    """``gnss`` on the IMU's time scale: ``offset_s`` (IMU clock minus GNSS clock, s, as
    :func:`estimate_time_offset` gives it) added to every stamp; a new log."""
    from dataclasses import replace
    return replace(gnss, time=np.asarray(gnss.time) + float(offset_s))
