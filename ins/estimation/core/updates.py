"""The measurement updates at a node of the forward filter: GNSS position and velocity,
dual-antenna heading, zero velocity and the non-holonomic constraint, each tested by its
innovation (chi-square at ``reject_probability``) and fed back into the state.

Which sensor is wrong
---------------------
A position fix rejected by the innovation test disagrees with the INS; the GNSS track's
agreement with itself (:mod:`ins.estimation.core.gnss_consistency`: each fix against its
predecessor through the receiver's velocities) says which of the two is wrong:

- a run of rejected fixes that begins after a gap in the GNSS (an outage) and whose
  fixes agree with each other is the INS having drifted: after
  :data:`REANCHOR_AFTER_FIXES` of them over :data:`REANCHOR_AFTER_S` the filter is
  *re-anchored* (the navigation covariance inflated until the fix passes, then the
  update; :attr:`Updater.reanchors`);
- a rejected fix that steps away from its predecessor (the track jumped) is the GNSS
  being wrong: it stays rejected, and a run that begins with such a step never
  re-anchors or recovers (:attr:`Updater.n_steps` counts them);
- a run that begins while tracking, without a step, is the filter running away
  gradually: after :data:`RECOVER_AFTER_FIXES` over :data:`RECOVER_AFTER_S`, its first
  fix only just outside the test (:data:`RECOVER_ENTRY_FACTOR`), a *recovery*
  (:meth:`Updater._recover`; the trust checks count these against the run);
- isolated outliers are left to the innovation test.
"""
import numpy as np

from ins.estimation.core import _filter_kernels
from ins.estimation.core.filter_stores import measurement_stores
from ins.estimation.core.measurements import (
    GnssPosition,
    GnssVelocity,
    NavPoint,
    NonHolonomic,
    UpdateRecord,
    ZeroVelocity,
    chi2_upper_quantile,
    innovation_nll,
    kalman_update,
    node_acceleration,
)

__all__ = ["Updater", "RECOVER_AFTER_FIXES", "RECOVER_AFTER_S", "RECOVER_ENTRY_FACTOR",
           "RECOVER_MAX_FACTOR", "REANCHOR_AFTER_FIXES", "REANCHOR_AFTER_S"]


#: A run of rejected GNSS position fixes triggers a recovery (covariance inflation of the
#: navigation states, :meth:`Updater._recover`) once it holds this many fixes ...
RECOVER_AFTER_FIXES = 3
#: ... spanning at least this long, s: a few outliers are rejected, a stretch of fixes
#: that all disagree with the filter in the same way means the filter has run away.
RECOVER_AFTER_S = 2.0
#: ... and the run's first rejected fix had a NIS of at most this many times the test's
#: bound (a filter that runs away leaves the test gradually; fixes that jump to another
#: place, a wrong fix or multipath, leave it at once, far outside) ...
RECOVER_ENTRY_FACTOR = 10.0
#: ... unless the fix needs the covariance inflated more than this (the filter's sigmas
#: short of its error by more than 100 x): fixes that far off have jumped (a wrong fix,
#: multipath, another time base), the filter has not; they stay rejected and the trust
#: checks judge the run.
RECOVER_MAX_FACTOR = 1e4
#: A run of rejected fixes after a GNSS gap, agreeing with each other, re-anchors the
#: filter once it holds this many fixes ...
REANCHOR_AFTER_FIXES = 3
#: ... spanning at least this long, s.
REANCHOR_AFTER_S = 0.5


class Updater:
    """The measurement updates at one node (:mod:`ins.estimation.core.measurements`), with feedback into
    the state; keeps a record of every tested measurement."""

    def __init__(self, settings, gnss):
        self.s = settings
        self.layout = settings.layout
        self.gnss = gnss
        self.thresholds = {}
        self.threshold = self._threshold(3)
        self.n_updates = self.n_rejected = self.n_fallback = self.n_outside = 0
        # one compact row per tested measurement (filter_stores; the forward run swaps
        # in stores on disk when it has a work folder)
        self.records, self.nis, self.nis_record, self.innovation = measurement_stores()
        self.cov = getattr(gnss, "cov_ned_m2", None)
        self.ev_time, self.ev_record, self.ev_kind = gnss.update_events(settings.use_velocity)
        self.run = []                 # times of the current run of rejected position fixes
        self.run_entry_nis = np.inf   # NIS of the run's first fix
        self.run_kind = None          # "gap", "step" or "tracking": how the run began
        self.recoveries = []          # (first rejected s, recovered at s, rejected, factor)
        self.reanchors = []           # the same for re-anchorings after a GNSS gap
        self.n_steps = 0              # rejected fixes that step away from the track
        self.track = None
        if getattr(gnss, "lla", None) is not None and len(gnss):
            from ins.estimation.core.gnss_consistency import track_consistency
            self.track = track_consistency(gnss)
        self.last_k = -1              # the last position record processed
        self.transform = None         # (T, q) of states re-initialized at this node
        # robust negative log-likelihood of the GNSS innovations (positions, velocities)
        # and their count: what ins.estimation.tools.noise_identification minimizes
        self.nll = {"gnss_position": 0.0, "gnss_velocity": 0.0}
        self.n_nll = {"gnss_position": 0, "gnss_velocity": 0}

    def reinitialize(self, P, T, q):
        """Re-initialize states at the current node: the error state becomes ``T dx + w``
        (``T`` (n, n), ``w`` white with variances ``q`` (n,)), e.g. an ambiguity slot
        taken by a new satellite or reset after a cycle slip (its row of ``T`` ties it to
        the other states, or is zero).  Returns ``T P T^T + diag(q)``; the forward filter
        applies the same to the node's prior covariance and transition
        (:meth:`take_transform`), so that the smoother sees the re-initialization as part
        of the step to this node."""
        Q = np.diag(np.asarray(q, float))
        Pn = T @ P @ T.T + Q
        if self.transform is not None:    # a second one at the same node: composed
            T0, Q0 = self.transform
            self.transform = (T @ T0, T @ Q0 @ T.T + Q)
        else:
            self.transform = (T, Q)
        return 0.5 * (Pn + Pn.T)

    def take_transform(self):
        """The re-initialization ``(T, Q)`` of this node (``Q`` (n, n)), or ``None``;
        cleared."""
        out, self.transform = self.transform, None
        return out

    def _threshold(self, m):
        if m not in self.thresholds:
            self.thresholds[m] = chi2_upper_quantile(self.s.reject_probability, m)
        return self.thresholds[m]

    def apply(self, meas, point, P):
        """Test and apply one measurement at ``point`` (updated in place); returns
        ``(P, dx or None, nis, z)``."""
        if hasattr(meas, "innovation"):            # predict, residual, jacobian at once
            z, H = meas.innovation(point)
        else:
            z = meas.residual(meas.predict(point), meas.observed)
            H = meas.jacobian(point)
        x, P, nis, sigma, log_det = kalman_update(P, H, meas.R, z, self._threshold(len(z)),
                                                  meas, logdet=True)
        if meas.name in self.nll:
            self.nll[meas.name] += innovation_nll(nis, log_det, len(z))
            self.n_nll[meas.name] += 1
        self.records.append(UpdateRecord(meas.name, meas.axes, meas.unit, meas.time, z,
                                         sigma, nis, x is not None))
        if x is None:
            self.n_rejected += 1
            return P, None, nis, z
        _filter_kernels.correct_state(point.state, x)
        point.sensors += x[self.layout.sensors]
        self.n_updates += 1
        return P, x, nis, z

    def update(self, e, t_row, state, sensors, P, w_meas_b, f_meas_b=None):
        """Process GNSS update event ``e`` (:meth:`ins.io.gnss_log.GnssLog.update_events`:
        a record's position and velocity, or one of them at its own epoch) at the node
        of time ``t_row``; returns (P, dx)."""
        g = self.gnss
        k, kind = self.ev_record[e], self.ev_kind[e]
        dx = np.zeros(self.layout.n)
        tg = g.time[k] if kind & 1 else g.velocity_time[k]
        l_b, dl_b, valid = self.s.lever.at_one(tg)
        if not valid:
            self.n_fallback += 1
        point = NavPoint(t_row, state, sensors, self.layout, w_meas_b, l_b, dl_b)
        if f_meas_b is not None:
            point.a_n = node_acceleration(state, f_meas_b, point.C_nb)
        if kind & 1:
            cov = (np.diag(g.sigma_ned_m[k] ** 2) if self.cov is None else self.cov[k])
            meas = GnssPosition(tg, g.lla[k], cov)
            P, x, nis, z = self.apply(meas, point, P)
            if x is None:
                step = self.track is not None and bool(self.track.step[k])
                self.n_steps += step
                if not self.run:
                    self.run_entry_nis = nis
                    self.run_kind = self._kind(k, step)
                elif step and self.run_kind == "gap":
                    self.run_kind = "step"         # the fixes of the run disagree
                self.run.append(tg)
                if self.run_kind == "gap" and self._reanchor_due():
                    P, x, nis, z = self._recover(meas, point, P, nis, self.reanchors)
                elif self.run_kind == "tracking" and self._run_away():
                    P, x, nis, z = self._recover(meas, point, P, nis)
            else:
                self.run = []
            self.last_k = k
            self.nis.append(nis)
            self.nis_record.append(k)
            self.innovation.append(z)
            if x is not None:
                dx += x
        if kind & 2 and self.s.use_velocity and g.has_velocity:
            meas = GnssVelocity(tg, g.v_n[k], np.diag(g.sigma_vel_ned_mps[k] ** 2))
            P, x, _, _ = self.apply(meas, point, P)
            if x is not None:
                dx += x
        return P, dx

    def _kind(self, k, step):
        """How a run of rejected fixes that begins at record ``k`` began: after a gap
        in the GNSS (or the last processed fix was not its predecessor), with a step
        of the track, or while tracking."""
        if self.track is None:
            return "tracking"
        if self.track.gap_before[k] or self.last_k != k - 1:
            return "gap"
        return "step" if step else "tracking"

    def _reanchor_due(self):
        return (self.s.recover and len(self.run) >= REANCHOR_AFTER_FIXES
                and self.run[-1] - self.run[0] >= REANCHOR_AFTER_S)

    def _run_away(self):
        """Whether the rejected fixes in a row say the filter, not the fixes, is wrong:
        at least :data:`RECOVER_AFTER_FIXES` of them over :data:`RECOVER_AFTER_S`, the
        first of them only just outside the test (:data:`RECOVER_ENTRY_FACTOR`)."""
        return (self.s.recover and len(self.run) >= RECOVER_AFTER_FIXES
                and self.run[-1] - self.run[0] >= RECOVER_AFTER_S
                and self.run_entry_nis <= RECOVER_ENTRY_FACTOR * self._threshold(3))

    def _recover(self, meas, point, P, nis, log=None):
        """Inflate the navigation states' covariance until ``meas`` passes the test with
        margin (``P' = D P D``, ``D`` = sqrt(factor) on position, velocity and attitude),
        then update with it; recorded in ``log`` (default :attr:`recoveries`).  Returns
        as :meth:`apply`."""
        L = self.layout
        nav = np.zeros(L.n, bool)
        nav[L.pos] = nav[L.vel] = nav[L.att] = True
        thr = self._threshold(3)
        factor = max(2.0 * nis / thr, 2.0)
        self._last = self.records.pop()        # the rejected test is repeated below
        self.n_rejected -= 1
        for _ in range(40):
            if factor > RECOVER_MAX_FACTOR:     # the fixes jumped, not the filter
                self.records.append(self._last)
                self.n_rejected += 1
                return P, None, nis, self._last.innovation
            d = np.where(nav, np.sqrt(factor), 1.0)
            Pi = P * np.outer(d, d)
            z = meas.residual(meas.predict(point), meas.observed)
            H = meas.jacobian(point)
            S = H @ Pi @ H.T + meas.R
            if float(z @ np.linalg.solve(S, z)) < 0.5 * thr:
                break
            factor *= 4.0
        (self.recoveries if log is None else log).append(
            (self.run[0], meas.time, len(self.run), factor))
        self.run = []
        return self.apply(meas, point, Pi)

    def others(self, t_row, state, sensors, P, w_meas_b, at_rest, headings):
        """The heading, zero-velocity and non-holonomic updates of a node; (P, dx)."""
        point = NavPoint(t_row, state, sensors, self.layout, w_meas_b)
        dx = np.zeros(self.layout.n)
        meas = list(headings)
        if at_rest:
            meas.append(ZeroVelocity(t_row, self.s.zupt_sigma_mps))
        if self.s.nhc:
            meas.append(NonHolonomic(t_row, self.s.nhc_sigma_mps, self.s.nhc_C_vb))
        for m in meas:
            P, x, _, _ = self.apply(m, point, P)
            if x is not None:
                dx += x
        return P, dx
