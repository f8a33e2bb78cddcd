"""IMU-GNSS clock offset estimated from the data: the horizontal acceleration seen by the
GNSS against the specific force of the accelerometers (cross-correlation with a
sub-sample peak and a sigma).

Model
-----
The accelerometers' specific force is taken along the levelled forward axis ``x_h``
and the levelled right axis ``y_h`` of the body, with down ``d_b = -mean(f_b) /
|mean(f_b)|`` (gravity's direction in the body averaged over the log: a vehicle that
stays roughly level, as cars, ships and survey aircraft do), and integrated:
``V_x(t) = sum(dvel_b . x_h)``, ``V_y(t) = sum(dvel_b . y_h)``.  The GNSS gives the
horizontal speed ``s(t)`` and the track ``psi(t)`` (its velocity columns, or the
differences of consecutive positions at their mid times).  Over a window of ``W``
seconds centred on each fix, the speed change and the lateral velocity change of the
turn agree with the integrated specific force, up to slowly varying terms (gravity
through the road grade or the bank, accelerometer bias, the crab angle)::

    s(t+W/2) - s(t-W/2)               = V_x(t-offset+W/2) - V_x(t-offset-W/2) + b_x(t)
    s(t) [psi(t+W/2) - psi(t-W/2)]    = V_y(t-offset+W/2) - V_y(t-offset-W/2) + b_y(t)

``b_x``, ``b_y`` are piecewise linear in time (knots every ``knot_s`` seconds), fitted
by linear least squares at each trial offset.  ``offset`` is the GNSS clock minus the
IMU clock: a record stamped ``t`` holds the state at IMU time ``t - offset``; shifting
the GNSS stamps by ``-offset`` puts them on the IMU's time scale.  The residual sum of
squares over a grid of offsets (step ``step_s``) is the (negative) cross-correlation
curve; its minimum is refined by a parabola fitted over +-0.1 s around the best trial
offset (sub-sample peak; the real curve wiggles at the scale of the GNSS interval),
and the sigma is that of the parabola's curvature,
``sigma^2 = 2 s0^2 / rss''`` with ``s0^2`` the residual variance, inflated by
``sqrt(n / n_eff)`` (``n_eff`` from the residuals' autocorrelation summed to its first
zero crossing: the windowed differences and the GNSS noise are correlated).

Positions and velocities of one receiver may carry different delays (a u-blox's
position can lead its Doppler velocity): ``source = "velocity"`` uses the velocity
columns, ``"position"`` the position differences; estimate both and compare.  The
information is in the accelerations: a log at constant velocity has none (refused).
Units: s, m/s inside.
"""
from dataclasses import dataclass

import numpy as np

from .errors import InputError

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
#: Default speed below which a fix is not used, m/s.
MIN_SPEED_MPS = 3.0
#: Smallest RMS of the GNSS velocity changes over the window (m/s) for an estimate.
MIN_SIGNAL_MPS = 0.02
SOURCES = ("velocity", "position")


@dataclass(frozen=True)
class TimeOffset:
    """An estimated IMU-GNSS clock offset.

    Attributes
    ----------
    offset_s : float
        GNSS clock minus IMU clock, s: the GNSS stamps less this are on the IMU's scale.
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


def level_axes_b(imu):
    """The increments' velocity changes resolved in the body frame of the first epoch
    (attitude from the gyros alone) and that frame's levelled forward and right axes:
    ``(dvel_0 (n, 3), x_h, y_h, d)``; down ``d`` is the direction of the mean specific
    force resolved so, reversed."""
    from ._time_offset_kernels import resolve_increments
    dvel_0 = resolve_increments(np.ascontiguousarray(imu.dtheta_b, dtype=float),
                                np.ascontiguousarray(imu.dvel_b, dtype=float))
    f = np.sum(dvel_0, axis=0)
    norm = np.linalg.norm(f)
    if norm == 0:
        raise InputError("the IMU log has no specific force: no down axis")
    d = -f / norm
    x = np.array([1.0, 0.0, 0.0]) - d[0] * d
    if np.linalg.norm(x) < 0.5:
        raise InputError("the body's forward axis points within 30 deg of the vertical: "
                         "the IMU axes are not forward-right-down (give --axes)")
    x /= np.linalg.norm(x)
    return dvel_0, x, np.cross(d, x), d


def imu_velocity(imu):
    """Integrated specific force along the levelled forward and right axes of the first
    epoch's body frame: ``(time, V)`` with ``V`` shape (n+1, 2), m/s, 0 at the start of
    the first increment (its interval taken as the next one)."""
    dvel_0, x, y, _ = level_axes_b(imu)
    t = np.asarray(imu.time)
    dv = dvel_0 @ np.column_stack([x, y])
    t0 = t[0] - (t[1] - t[0])
    return np.concatenate([[t0], t]), np.vstack([np.zeros(2), np.cumsum(dv, axis=0)])


def gnss_velocity(gnss, source="velocity"):
    """``(time, v_ne)`` of the GNSS: the velocity columns (``"velocity"``) or the
    differences of consecutive positions at their mid times (``"position"``), m/s."""
    from . import earth
    if source not in SOURCES:
        raise InputError(f"source {source!r}: expected one of {', '.join(SOURCES)}")
    if source == "velocity":
        if not gnss.has_velocity:
            raise InputError(f"{gnss.path or 'the GNSS log'}: no velocity columns (use the "
                             f"position differences)")
        return np.asarray(gnss.time), np.asarray(gnss.v_n)[:, :2]
    d = earth.ned_offset(gnss.lla[:-1], gnss.lla[1:])[:, :2]
    return 0.5 * (gnss.time[1:] + gnss.time[:-1]), d / np.diff(gnss.time)[:, None]


def _hat(t, knots):
    """Piecewise-linear (hat) basis at ``t`` on ``knots``, shape (len(t), len(knots))."""
    return np.column_stack([np.interp(t, knots, np.eye(len(knots))[j])
                            for j in range(len(knots))])


def _n_eff(e):
    """Effective number of independent samples of a correlated residual series."""
    n = len(e)
    e = e - e.mean()
    c0 = float(e @ e)
    if c0 == 0:
        return float(n)
    s = 0.0
    for k in range(1, n // 2):
        rho = float(e[:-k] @ e[k:]) / c0
        if rho <= 0:
            break
        s += rho
    return float(min(n, n / (1.0 + 2.0 * s)))


class _Problem:
    """The observations at the used GNSS epochs and the residuals at a trial offset."""

    def __init__(self, imu, gnss, source, window_s, knot_s, max_offset_s, min_speed_mps):
        self.t_i, self.V = imu_velocity(imu)
        t_g, v = gnss_velocity(gnss, source)
        speed = np.hypot(v[:, 0], v[:, 1])
        h = 0.5 * window_s
        margin = max_offset_s + h
        use = ((t_g - margin >= self.t_i[0]) & (t_g + margin <= self.t_i[-1])
               & (t_g - h >= t_g[0]) & (t_g + h <= t_g[-1]) & (speed >= min_speed_mps))
        self.t = t_g[use]
        self.h = h
        self.dv_ne = (np.column_stack([np.interp(self.t + h, t_g, v[:, j]) for j in (0, 1)])
                      - np.column_stack([np.interp(self.t - h, t_g, v[:, j]) for j in (0, 1)]))
        self.obs = self.dv_ne.ravel()
        if len(self.t) >= 2:
            knots = np.arange(self.t[0], self.t[-1] + knot_s, knot_s)
            B = _hat(self.t, knots)
            Z = np.zeros_like(B)
            self.A = np.block([[B, Z], [Z, B]])
            self.segment = np.minimum(((self.t - self.t[0]) // knot_s).astype(int),
                                      len(knots) - 2 if len(knots) > 1 else 0)

    def residuals(self, offset):
        ts = self.t - offset
        dV = (np.column_stack([np.interp(ts + self.h, self.t_i, self.V[:, j]) for j in (0, 1)])
              - np.column_stack([np.interp(ts - self.h, self.t_i, self.V[:, j])
                                 for j in (0, 1)]))
        # the GNSS velocity change into the first epoch's levelled body axes: one
        # rotation about down per knot interval (start heading, gyro drift), by 2-D
        # Procrustes
        u = self.dv_ne
        cross = u[:, 0] * dV[:, 1] - u[:, 1] * dV[:, 0]
        dot = np.einsum("ij,ij->i", u, dV)
        n = self.segment.max() + 1
        alpha = np.arctan2(np.bincount(self.segment, cross, n),
                           np.bincount(self.segment, dot, n))[self.segment]
        ca, sa = np.cos(alpha), np.sin(alpha)
        u = np.column_stack([ca * u[:, 0] - sa * u[:, 1], sa * u[:, 0] + ca * u[:, 1]])
        r = np.concatenate([u[:, 0] - dV[:, 0], u[:, 1] - dV[:, 1]])
        coef, *_ = np.linalg.lstsq(self.A, r, rcond=None)
        return r - self.A @ coef


def estimate_time_offset(imu, gnss, source="velocity", max_offset_s=MAX_OFFSET_S,
                         step_s=STEP_S, window_s=WINDOW_S, knot_s=KNOT_S,
                         min_speed_mps=MIN_SPEED_MPS):
    """Estimate the IMU-GNSS clock offset (module notes).

    Parameters
    ----------
    imu : ins.imu.ImuLog
        Increments in the body frame (FRD), stamped at the end of their interval.
    gnss : ins.gnss.GnssLog
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
    if n < 4 * p.A.shape[1] if n >= 2 else True:
        raise InputError(f"{n} GNSS epochs at {min_speed_mps:g} m/s or faster inside the "
                         f"IMU span (less {max_offset_s + 0.5 * window_s:g} s at each "
                         f"end): too few for a time offset with knots every {knot_s:g} s")
    signal = float(np.sqrt(np.mean(p.obs ** 2)))
    if signal < MIN_SIGNAL_MPS:
        raise InputError(f"the GNSS velocity changes by {signal:.3g} m/s RMS over "
                         f"{window_s:g} s: a log without accelerations or turns holds no "
                         f"information on the time offset")
    lags = np.arange(-max_offset_s, max_offset_s + 0.5 * step_s, step_s)
    rss = np.array([float(np.sum(p.residuals(x) ** 2)) for x in lags])
    k = int(np.argmin(rss))
    if k == 0 or k == len(lags) - 1:
        raise InputError(f"the best time offset is at the edge of the searched range "
                         f"+-{max_offset_s:g} s: widen it")
    # a parabola fitted over +-FIT_S around the grid minimum: the vertex (sub-sample
    # peak) and the curvature of the curve's shape, not of its local wiggles
    near = np.abs(lags - lags[k]) <= max(FIT_S, 2 * step_s)
    a2, a1, _ = np.polyfit(lags[near] - lags[k], rss[near], 2)
    if not a2 > 0:
        raise InputError("the residual curve has no minimum near its lowest point: no "
                         "usable information on the time offset")
    curv = 2.0 * a2
    x = float(np.clip(lags[k] - a1 / (2 * a2), lags[k] - FIT_S, lags[k] + FIT_S))
    e = p.residuals(x)
    dof = max(len(e) - p.A.shape[1] - 1, 1)
    s2 = float(e @ e) / dof
    n_eff = _n_eff(e)
    sigma = float(np.sqrt(2.0 * s2 / curv * len(e) / n_eff))
    return TimeOffset(offset_s=float(x), sigma_s=sigma, source=source, n_fixes=n,
                      n_eff=n_eff, residual_rms_mps=float(np.sqrt(np.mean(e ** 2))),
                      signal_rms_mps=signal, lags_s=lags, rss=rss)


def shift_gnss(gnss, offset_s):
    """``gnss`` on the IMU's time scale: every stamp less ``offset_s`` (s); a new log."""
    from dataclasses import replace
    return replace(gnss, time=np.asarray(gnss.time) - float(offset_s))
