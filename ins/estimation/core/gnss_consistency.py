"""The GNSS track's agreement with itself: each fix against the one before it, through the
receiver's own velocities, so that the screening can tell a drifted INS from a wrong fix
(:mod:`ins.estimation.core.updates`).

Rule (:func:`track_consistency`): for consecutive fixes ``k-1, k`` no more than
:data:`MAX_GAP_FACTOR` median intervals apart, the step

    d_k = p_k - p_k-1 - (v_k-1 + v_k) dt / 2          (trapezoid of the GNSS velocities)

has the covariance ``C_k + C_k-1 + dt^2 / 4 (Cv_k + Cv_k-1) + (A dt^2 / 2)^2 I`` (the
fixes', the velocities', and an unmodelled acceleration :data:`UNMODELLED_ACCEL_MPS2`
for what the trapezoid misses in a sharp manoeuvre); the fix is *consistent* with its
predecessor when ``d_k^T S^-1 d_k`` is within the chi-square bound of 3 dof at
:data:`STEP_PROBABILITY`.  Without velocities the step is the position difference against
the one before (``p_k - 2 p_k-1 + p_k-2``, constant velocity) with the same acceleration
term.  A fix after a gap (or the first) has no predecessor: ``gap_before``.
"""
from dataclasses import dataclass

import numpy as np

from ins.estimation.core.measurements import chi2_upper_quantile
from ins.nav import earth

#: Two fixes farther apart than this many median intervals have a gap between them.
MAX_GAP_FACTOR = 2.5
#: Acceleration the trapezoid of the velocities may miss, m/s^2 (its error is
#: ``jerk dt^3 / 12``; this also covers a velocity a few ms off its epoch in a brake).
UNMODELLED_ACCEL_MPS2 = 2.0
#: False-alarm probability of the step test.
STEP_PROBABILITY = 1e-4


@dataclass(frozen=True)
class TrackConsistency:
    """Per record of the GNSS log: ``gap_before`` (no predecessor within the gap bound),
    ``step_nis`` (Mahalanobis square of the step, NaN after a gap) and ``consistent``
    (the step within its bound; False after a gap) and ``step`` (the step tested and
    beyond its bound: the GNSS track jumped at this fix)."""

    gap_before: np.ndarray
    step_nis: np.ndarray
    consistent: np.ndarray
    threshold: float

    @property
    def step(self):
        return np.isfinite(self.step_nis) & (self.step_nis > self.threshold)


def track_consistency(gnss):
    """Each fix of ``gnss`` (:class:`ins.io.gnss_log.GnssLog`) against its predecessor
    (module notes)."""
    n = len(gnss)
    t = np.asarray(gnss.time, float)
    thr = chi2_upper_quantile(STEP_PROBABILITY, 3)
    gap = np.ones(n, bool)
    nis = np.full(n, np.nan)
    if n < 2:
        return TrackConsistency(gap, nis, np.zeros(n, bool), thr)
    dt = np.diff(t)
    pos = dt[dt > 0]
    med = float(np.median(pos)) if len(pos) else 1.0
    gap[1:] = ~((dt > 0) & (dt <= MAX_GAP_FACTOR * med))
    p = _ned(gnss.lla)
    cov = (np.asarray(gnss.cov_ned_m2, float) if gnss.cov_ned_m2 is not None
           else np.einsum("ni,ij->nij", np.asarray(gnss.sigma_ned_m, float) ** 2, np.eye(3)))
    acc = (0.5 * UNMODELLED_ACCEL_MPS2 * dt ** 2) ** 2
    if gnss.has_velocity:
        v = np.asarray(gnss.v_n, float)
        sv = np.asarray(gnss.sigma_vel_ned_mps, float) ** 2
        if gnss.vel_time is not None:    # the velocities at the positions' epochs
            tv = np.asarray(gnss.vel_time, float)
            v = np.column_stack([np.interp(t, tv, v[:, i]) for i in range(3)])
            sv = np.column_stack([np.interp(t, tv, sv[:, i]) for i in range(3)])
        d = p[1:] - p[:-1] - 0.5 * (v[1:] + v[:-1]) * dt[:, None]
        S = (cov[1:] + cov[:-1] + np.einsum("n,ni,ij->nij", 0.25 * dt ** 2, sv[1:] + sv[:-1],
                                             np.eye(3))
             + acc[:, None, None] * np.eye(3))
        ok = ~gap[1:]
        idx = np.flatnonzero(ok) + 1
    else:                           # no velocities: three fixes
        if n < 3:
            return TrackConsistency(gap, nis, np.zeros(n, bool), thr)
        ratio = dt[1:] / np.where(dt[:-1] > 0, dt[:-1], 1.0)
        d = p[2:] - p[1:-1] - (p[1:-1] - p[:-2]) * ratio[:, None]
        S = (cov[2:] + cov[1:-1] * (1 + ratio[:, None, None]) ** 2
             + cov[:-2] * ratio[:, None, None] ** 2 + acc[1:, None, None] * np.eye(3))
        ok = ~gap[2:] & ~gap[1:-1]
        idx = np.flatnonzero(ok) + 2
    dd, SS = d[ok], S[ok]
    if len(dd):
        nis[idx] = np.einsum("ni,ni->n", dd, np.linalg.solve(SS, dd[..., None])[..., 0])
    consistent = np.isfinite(nis) & (nis <= thr)
    return TrackConsistency(gap, nis, consistent, thr)


def _ned(lla):
    """NED of every fix about the first, m (:func:`ins.nav.earth.ned_offset`)."""
    lla = np.asarray(lla, float)
    return earth.ned_offset(np.broadcast_to(lla[0], lla.shape), lla)
