"""The lag of a receiver's velocities behind its own positions, from the GNSS log alone.

A receiver's velocity (Doppler) and position solutions are not always of the same
instant: a u-blox RTK receiver's velocities lag its positions by about 0.125 s.  Taken at
face value, a lagged velocity in a turn or a brake is wrong by ``a * lag`` (0.4 m/s at
3 m/s^2), and a filter that believes it at 6 cm/s rejects the positions that follow.

Rule (:func:`velocity_lag`): between consecutive fixes ``k, k+1`` (no gap longer than
:data:`MAX_GAP_FACTOR` times the median interval) the positions give the mean velocity
``(p_k+1 - p_k) / dt``, an estimate of the velocity at the midpoint epoch.  The
velocities, moved by a shift ``s`` (s, added to their epochs as ``[gnss]
velocity_time_shift_s`` does), must equal that series interpolated at their shifted
epochs.  ``s`` minimizes the sum of squared differences over a grid of
:data:`GRID_STEP_S` within +-:data:`MAX_LAG_S`, refined by a parabola through the best
three; its sigma is the Gauss-Newton one, ``sigma_r / sqrt(sum |dv/dt|^2)``, with
``sigma_r`` the residuals' RMS per axis and ``dv/dt`` the acceleration of the
differenced series.  Only records of fixes with both neighbours (positions and
velocities finite) count; a log with too little acceleration says so (``None``).
"""
from dataclasses import dataclass

import numpy as np

from ins.nav import earth

#: Largest lag searched, s.
MAX_LAG_S = 0.5
#: Grid step of the search, s.
GRID_STEP_S = 0.005
#: Two fixes farther apart than this many median intervals are not differenced (a gap).
MAX_GAP_FACTOR = 1.5
#: Fewest velocity records in the fit.
MIN_RECORDS = 20
#: A lag is applied only when it is at least this many of its sigmas from zero ...
SIGNIFICANT_SIGMAS = 5.0
#: ... and at least this long, s (half the 100 Hz IMU interval matters little).
SIGNIFICANT_S = 0.01


@dataclass(frozen=True)
class VelocityLag:
    """The measured lag: ``shift_s`` to add to the velocities' epochs (negative: they
    lag the positions), its sigma (s), the records used, the residual RMS (m/s) at the
    shift and with none, and whether it is significant (:data:`SIGNIFICANT_SIGMAS`,
    :data:`SIGNIFICANT_S`)."""

    shift_s: float
    sigma_s: float
    n: int
    rms_mps: float
    rms_unshifted_mps: float

    @property
    def significant(self):
        return (abs(self.shift_s) >= SIGNIFICANT_SIGMAS * self.sigma_s
                and abs(self.shift_s) >= SIGNIFICANT_S)

    def describe(self):
        return (f"GNSS velocities {-self.shift_s * 1e3:+.0f} +- {self.sigma_s * 1e3:.0f} ms "
                f"behind the positions (from the log: {self.n} records, velocity "
                f"residual {self.rms_unshifted_mps:.3f} -> {self.rms_mps:.3f} m/s)")


def _differenced(gnss):
    """Midpoint epochs, mean velocities (NED m/s) between consecutive fixes without a gap,
    and the interval's end index."""
    t = np.asarray(gnss.time, float)
    dt = np.diff(t)
    if len(dt) < 2:
        return None
    ok = (dt > 0) & (dt <= MAX_GAP_FACTOR * np.median(dt[dt > 0]))
    lla = np.asarray(gnss.lla, float)
    ref = lla[0]
    # local NED of every fix about the first (small area: the linear map is exact to
    # well below the fixes' centimetres over tens of km for differences of neighbours)
    rm, rn = earth.radii(ref[0])
    ned = np.column_stack([(lla[:, 0] - ref[0]) * (rm + ref[2]),
                           (lla[:, 1] - ref[1]) * (rn + ref[2]) * np.cos(lla[:, 0]),
                           -(lla[:, 2] - ref[2])])
    v = np.diff(ned, axis=0) / np.where(dt > 0, dt, 1.0)[:, None]
    return 0.5 * (t[:-1] + t[1:]), v, ok


def velocity_lag(gnss):
    """The shift of the GNSS velocities' epochs that makes them agree with the positions
    (module notes), or ``None`` when the log has no velocities or too little motion.

    Parameters
    ----------
    gnss : ins.io.gnss_log.GnssLog

    Returns
    -------
    VelocityLag or None
    """
    if not gnss.has_velocity or len(gnss) < MIN_RECORDS + 2:
        return None
    d = _differenced(gnss)
    if d is None:
        return None
    tm, vm, ok = d
    t_v = np.asarray(gnss.velocity_time, float)
    v_rep = np.asarray(gnss.v_n, float)
    # a velocity record counts when the differenced series is continuous around it
    # (both intervals beside its own epoch are gap-free), within the largest lag
    seg = np.flatnonzero(ok)
    if len(seg) < MIN_RECORDS:
        return None
    good = np.zeros(len(tm), bool)
    good[seg] = True
    # continuous runs of good intervals: a velocity is used only well inside one
    k = np.searchsorted(tm, t_v)
    span = int(np.ceil(MAX_LAG_S / max(float(np.median(np.diff(tm))), 1e-3))) + 1
    use = np.zeros(len(t_v), bool)
    csum = np.concatenate([[0], np.cumsum(good)])
    lo, hi = k - span - 1, k + span + 1
    inside = (lo >= 0) & (hi <= len(tm))
    use[inside] = (csum[hi[inside]] - csum[lo[inside]]) == (hi - lo)[inside]
    use &= np.all(np.isfinite(v_rep), axis=1)
    if np.count_nonzero(use) < MIN_RECORDS:
        return None
    tv, vr = t_v[use], v_rep[use]
    shifts = np.arange(-MAX_LAG_S, MAX_LAG_S + 0.5 * GRID_STEP_S, GRID_STEP_S)
    cost = np.array([_cost(tm, vm, tv + s, vr) for s in shifts])
    j = int(np.clip(np.argmin(cost), 1, len(shifts) - 2))
    c0, c1, c2 = cost[j - 1:j + 2]
    curv = c0 - 2.0 * c1 + c2
    step = 0.5 * (c0 - c2) / curv if curv > 0 else 0.0
    s_best = float(shifts[j] + np.clip(step, -1.0, 1.0) * GRID_STEP_S)
    r = vr - _interp(tm, vm, tv + s_best)
    acc = np.gradient(vm, tm, axis=0)
    a = _interp(tm, acc, tv + s_best)
    sigma_r = float(np.sqrt(np.mean(r ** 2)))
    info = float(np.sum(a ** 2))
    sigma = sigma_r / np.sqrt(info) if info > 0 else np.inf
    r0 = vr - _interp(tm, vm, tv)
    return VelocityLag(s_best, float(sigma), int(len(tv)),
                       float(np.sqrt(np.mean(np.sum(r ** 2, axis=1)))),
                       float(np.sqrt(np.mean(np.sum(r0 ** 2, axis=1)))))


def _interp(t, v, at):
    return np.column_stack([np.interp(at, t, v[:, i]) for i in range(v.shape[1])])


def _cost(tm, vm, at, v_rep):
    return float(np.sum((v_rep - _interp(tm, vm, at)) ** 2))
