"""The lag of a receiver's velocities behind its own positions, from the GNSS log alone.

A receiver's velocity (Doppler) and position solutions are not always of the same
instant: a u-blox RTK receiver's velocities lag its positions by about 0.125 s.  Taken at
face value, a lagged velocity in a turn or a brake is wrong by ``a * lag`` (0.4 m/s at
3 m/s^2), and a filter that believes it at 6 cm/s rejects the positions that follow.

Rule (:func:`velocity_lag`): at each fix ``k`` with both neighbours (no gap longer than
:data:`MAX_GAP_FACTOR` times the median interval) the positions give the velocity by
the central difference ``(p_k+1 - p_k-1) / (t_k+1 - t_k-1)`` and the receiver's
velocities the acceleration ``(v_k+1 - v_k-1) / (t_k+1 - t_k-1)``.  A velocity stamped
``t`` that holds the state of ``t - lag`` is, to first order, ``v(t) - lag a(t)``: the
shift ``s = -lag`` (added to the velocities' epochs, as ``[gnss]
velocity_time_shift_s`` does) is the least-squares slope of ``v_reported - v_positions``
on ``-a`` over the three axes and every such fix, iterated twice with the second-order
term ``s^2 / 2 da/dt``.  Its sigma is ``sigma_r / sqrt(sum |a|^2)``, ``sigma_r`` the
residuals' RMS per axis.

Why not shift the velocities and interpolate the differenced positions: the
differenced series' noise is anticorrelated from one interval to the next, so its
interpolated value is least noisy half-way between two midpoints, and a search over
the shift is drawn to the fix epochs (a 0.125 s lag of a 4 Hz receiver came out
0.154 s on a simulated track).  Here the noise of each term does not depend on ``s``,
and the acceleration from the velocities (not the positions' second difference) leaves
the slope unattenuated.
"""
from dataclasses import dataclass

import numpy as np

from ins.nav import earth

#: Largest lag reported, s (the first-order model holds well within it).
MAX_LAG_S = 0.5
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


def velocity_lag(gnss):
    """The shift of the GNSS velocities' epochs that makes them agree with the positions
    (module notes), or ``None`` when the log has no velocities (or they have their own
    epochs already) or too few fixes with both neighbours.

    Parameters
    ----------
    gnss : ins.io.gnss_log.GnssLog

    Returns
    -------
    VelocityLag or None
    """
    n = len(gnss)
    if not gnss.has_velocity or gnss.vel_time is not None or n < MIN_RECORDS + 2:
        return None
    t = np.asarray(gnss.time, float)
    dt = np.diff(t)
    pos = dt[dt > 0]
    if not len(pos):
        return None
    ok = (dt > 0) & (dt <= MAX_GAP_FACTOR * float(np.median(pos)))
    use = np.zeros(n, bool)
    use[1:-1] = ok[:-1] & ok[1:]
    v = np.asarray(gnss.v_n, float)
    use &= np.all(np.isfinite(v), axis=1)
    use[1:-1] &= np.all(np.isfinite(v[:-2]), axis=1) & np.all(np.isfinite(v[2:]), axis=1)
    k = np.flatnonzero(use)
    if len(k) < MIN_RECORDS:
        return None
    p = _ned(gnss.lla)
    span = (t[k + 1] - t[k - 1])[:, None]
    v_pos = (p[k + 1] - p[k - 1]) / span
    a = (v[k + 1] - v[k - 1]) / span
    da = np.gradient(a, t[k], axis=0)
    r0 = v[k] - v_pos
    info = float(np.sum(a ** 2))
    if not info > 0:
        return None
    s_est = 0.0
    for _ in range(2):
        model = s_est * a + 0.5 * s_est ** 2 * da       # v(t + s) - v(t), second order
        s_est += float(np.sum(a * (r0 - model))) / info
    r = r0 - (s_est * a + 0.5 * s_est ** 2 * da)
    sigma_r = float(np.sqrt(np.mean(r ** 2)))
    s_est = float(np.clip(s_est, -MAX_LAG_S, MAX_LAG_S))
    return VelocityLag(s_est, sigma_r / np.sqrt(info), int(len(k)),
                       float(np.sqrt(np.mean(np.sum(r ** 2, axis=1)))),
                       float(np.sqrt(np.mean(np.sum(r0 ** 2, axis=1)))))


def _ned(lla):
    """NED of every fix about the first, m (:func:`ins.nav.earth.ned_offset`)."""
    lla = np.asarray(lla, float)
    return earth.ned_offset(np.broadcast_to(lla[0], lla.shape), lla)
