"""Forward GNSS/INS error-state Kalman filter with closed-loop feedback.

How it runs
-----------
The filter works on *nodes*: every GNSS epoch, plus extra nodes so that no two nodes are
more than ``node_interval_s`` apart (GNSS outages).  Between two nodes the IMU rows are
mechanized at the full IMU rate in a compiled loop (:mod:`ins.estimation.core._filter_kernels`), with the
current bias and scale estimates removed, while the integrals that the covariance step
needs are accumulated; the covariance (21 states, or the layout's
:class:`ins.estimation.core.error_model.StateLayout`) is then propagated once per node interval
(:func:`ins.estimation.core.error_model.discretize`: ``Phi = I + A + A^2/2 + A^3/6``,
``A = int F dt``; compiled with the prior ``Phi P Phi^T + Q_d``:
:func:`ins.estimation.core._kalman_kernels.node_predict`).
On the benchmark flight (1 Hz GNSS) propagating at 1 s instead of 0.1 s changes the
position RMS by less than 0.1 mm and the heading RMS by 0.02 arcsec, at 2.6 times the
cost (``bench/bench_process.py``, "Covariance step").

A GNSS record at time ``t_g`` between IMU epochs ``t_j <= t_g < t_j+1`` is processed at
node ``j``: the predicted antenna position is the state at ``t_j`` advanced by
``D^-1 (v dt + a dt^2 / 2)``, ``dt = t_g + offset - t_j`` (``offset`` the estimated
IMU-GNSS time offset when the layout has one; ``a`` the node's acceleration from its
last specific force, :func:`ins.estimation.core.measurements.node_acceleration`), the predicted
velocity by ``v + a dt``, with the lever arm at ``t_g`` (plus the estimated
correction); the error state over those few ms is taken as unchanged.  Velocities
with their own epochs (``[gnss] velocity_time_shift_s``: ``GnssLog.vel_time``) are
separate update events at the node of their own epoch
(:meth:`ins.io.gnss_log.GnssLog.update_events`); the time-offset state is one for
both, on top of the two shifts.  Dual-antenna
headings, zero-velocity and non-holonomic updates
(:class:`ins.estimation.core.filter_settings.FilterSettings`) follow the GNSS records of a node.

Every measurement is an object of :mod:`ins.estimation.core.measurements` (predicted value, ``H``,
``R``); the update (:func:`ins.estimation.core.measurements.kalman_update`) factorises
``S = H P H^T + R`` once (Cholesky), tests ``nu^T S^-1 nu`` against the chi-square
quantile of ``1 - reject_probability`` (as many dof as the measurement has axes),
counts the rejected records and keeps the per-axis standardized innovations of every
tested one (``ForwardResult.records``, ``innovations.txt``).  After each accepted update
the estimated errors are fed back (closed loop): the navigation state is corrected
(:mod:`ins.estimation.core.error_model` sign rules), the sensor estimates updated, and the error state
reset to zero.

The per-node linear algebra (prior covariance, update, smoother step) runs in compiled
kernels (:mod:`ins.estimation.core._kalman_kernels`) on ``n x n`` matrices, ``n`` the layout's
number of states; filterpy's ``predict`` and ``update`` are the reference they are
tested against (tests/test_kalman_kernels.py), not part of the run (the import of
filterpy, with scipy.stats, cost more than the whole filter).
"""
import warnings

import numpy as np

from ins.common.errors import InputError, InputWarning
from ins.estimation.core import _filter_kernels
from ins.estimation.core import _kalman_kernels
from ins.estimation.core.error_model import (
    KFGINS,
    NAV,
    checked_std,
    noise_matrix,
)
from ins.estimation.core.filter_stores import (
    NodeStore,
    Rows,
    TrajectoryStore,
    as_array,
    measurement_stores,
    read_rows,
)
from ins.estimation.core.updates import Updater
from ins.nav import earth
from ins.nav.mechanization import check_finite


class ForwardResult:
    """What the forward pass leaves for the smoother and the outputs.

    Attributes
    ----------
    trajectory : TrajectoryStore
        Forward (filtered) states at every IMU epoch (node rows: after the update);
        :attr:`time` and :attr:`states` give them as arrays (in memory).
    nodes : NodeStore
        ``P_prior``, ``P_post`` (covariance before and after the node's updates) and
        ``Phi`` (from node ``j - 1`` to node ``j``; ``Phi[0] = I``); :attr:`P_prior`,
        :attr:`P_post`, :attr:`Phi` give them as (m, 21, 21) arrays.
    node_rows : ndarray, shape (m,) of int
        Row of each node in the trajectory (first 0, last n - 1).
    node_time : ndarray, shape (m,)
        Time of each node, s.
    dx : ndarray, shape (m, 21)
        Correction fed back at each node (sum over the node's updates).
    sensors : ndarray, shape (m, 12)
        Sensor estimates after the node's updates: gyro bias rad/s, accel bias m/s^2,
        gyro scale, accel scale.
    n_updates, n_rejected, n_outside, n_mount_fallback : int
        Accepted GNSS measurements (positions and velocities), rejected by the innovation
        test, GNSS records outside the IMU time span, records processed with the static
        arm for lack of mount data.
    nis : ndarray
        Normalized innovation squared of every tested position record.
    nis_record : ndarray of int
        Index (in the GNSS log) of the record of each ``nis``.
    nis_threshold : float
        The innovation test's chi-square bound (3 dof).
    innovation_m : ndarray, shape (len(nis), 3)
        Position innovation (predicted antenna minus fix, NED m) of each tested record.
    node_states : ndarray, shape (m, 10)
        Forward states at the nodes (after the update).
    recoveries : list of (float, float, int, float)
        Recoveries from a run of rejected position fixes: time of the first rejected fix
        and of the fix that recovered (s), the fixes rejected in the run, the factor on
        the navigation states' covariance.
    reanchors : list of (float, float, int, float)
        Re-anchorings after a GNSS gap (:mod:`ins.estimation.core.updates`): the same fields.
    n_gnss_steps : int
        Rejected position fixes that stepped away from the GNSS track itself.
    records : ins.estimation.core.filter_stores.RecordStore
        Every tested measurement (GNSS position and velocity, heading, zero velocity,
        non-holonomic), in processing order: iterating yields
        :class:`ins.estimation.core.measurements.UpdateRecord` s (innovations per axis, NIS,
        accepted); compact numeric rows, on disk with a work folder.
    stores : dict
        Where the per-node quantities and the NIS live: arrays, or, for a run with a
        work folder, :class:`ins.estimation.core.filter_stores.Rows` in temporary files there
        (memory does not grow with the number of nodes).  The attributes above read them
        whole; :meth:`node_rows_of` reads a block of nodes.
    layout : ins.estimation.core.error_model.StateLayout
        The error states (``dx`` has ``layout.n`` columns, ``sensors`` ``layout.n - 9``:
        the 12 of the KF-GINS layout, then the optional groups' estimates).
    updater : object
        The object that processed the GNSS events (``FilterSettings.updater``), for
        its own counts (tight coupling: satellites used per epoch).
    """

    def __init__(self, trajectory, nodes, node_rows, node_time, dx, sensors):
        self.trajectory, self.nodes = trajectory, nodes
        # arrays, or (a run with a work folder) filter_stores.Rows read when asked for
        self.stores = {"node_rows": node_rows, "node_time": node_time, "dx": dx,
                       "sensors": sensors, "node_states": None, "nis": None,
                       "nis_record": None, "innovation_m": None}
        self.n_updates = self.n_rejected = self.n_outside = self.n_mount_fallback = 0
        self.nis_threshold = np.inf
        self.records = []
        self.recoveries = []
        self.reanchors = []
        self.n_gnss_steps = 0
        self.layout = KFGINS
        self._whole = None

    def _arrays(self):
        if self._whole is None:
            self._whole = self.trajectory.whole()
        return self._whole

    def __getattr__(self, name):
        # node_rows, node_time, dx, sensors, node_states, nis, nis_record, innovation_m:
        # arrays (read whole from their store); filter_stores.read_rows reads blocks
        stores = self.__dict__.get("stores", {})
        if name in stores:
            x = stores[name]
            return None if x is None else as_array(x)
        raise AttributeError(name)

    def __setattr__(self, name, value):
        if name in self.__dict__.get("stores", {}):
            self.stores[name] = value
        else:
            object.__setattr__(self, name, value)

    @property
    def node_count(self):
        """Number of nodes."""
        return len(self.stores["node_time"])

    def node_rows_of(self, name, j0, j1):
        """Rows ``j0 .. j1-1`` of a per-node quantity (``node_time``, ``dx`` ...)."""
        return read_rows(self.stores[name], j0, j1)

    time = property(lambda self: self._arrays()[0])
    states = property(lambda self: self._arrays()[1])
    P_prior = property(lambda self: self.nodes.block(0, self.nodes.count)[:, 0])
    P_post = property(lambda self: self.nodes.block(0, self.nodes.count)[:, 1])
    Phi = property(lambda self: self.nodes.block(0, self.nodes.count)[:, 2])


def _next_node(time, cur, t_node, t_gnss, stop, last, interval):
    """Row of the next node after row ``cur`` among rows ``< stop`` of ``time``, or -1.

    Candidates: the row of the next GNSS record (the last epoch at or before it, known
    once a later epoch is in ``time``), the last epoch at most ``interval`` after the
    previous node (at least ``cur + 1``), and the last row when ``last``.
    """
    best = stop - 1 if last else -1
    if t_gnss is not None and _row_known(t_gnss, time, stop - 1):
        rg = int(np.searchsorted(time, t_gnss + 1e-9, side="right")) - 1
        best = rg if best < 0 else min(best, rg)
    rf = max(int(np.searchsorted(time, t_node + interval * (1 + 1e-9), side="right")) - 1,
             cur + 1)
    if rf < stop:
        best = rf if best < 0 else min(best, rf)
    return best


def _row_known(t_gnss, time, r):
    """True when the GNSS record at ``t_gnss`` belongs to a row ``<= r`` of ``time``
    (the last epoch at or before it): a later epoch is past it, or, at the end of the
    log, it is not after the last epoch."""
    return t_gnss + 1e-9 < time[r + 1] if r + 1 < len(time) else t_gnss <= time[-1]


def schedule_nodes(time, gnss_time, node_interval_s):
    """Node rows over a whole time axis (the rule of :func:`run_forward`): 0, the last
    row, the row of every GNSS record (last IMU epoch at or before it) and fill-in rows
    so that nodes are at most ``node_interval_s`` apart."""
    g = np.sort(gnss_time[(gnss_time >= time[0]) & (gnss_time <= time[-1])])
    rows, cur, gj = [0], 0, 0
    while gj < len(g) and _row_known(g[gj], time, 0):
        gj += 1
    while cur < len(time) - 1:
        cur = _next_node(time, cur, time[cur], g[gj] if gj < len(g) else None, len(time),
                         True, node_interval_s)
        rows.append(cur)
        while gj < len(g) and _row_known(g[gj], time, cur):
            gj += 1
    return np.array(rows)


#: Zero-velocity detection also needs the filter's speed below this (m/s): a vehicle in
#: smooth straight motion has steady specific force and small rates too.
ZUPT_MAX_SPEED_MPS = 2.0


def _pieces(imu, start, end):
    """``(time, dtheta_b, dvel_b, last)`` blocks of the rows within [start, end] (s),
    preceded by up to two earlier rows (the two-sample corrections' previous samples)."""
    from ins.nav.imu import ImuLog
    blocks = iter([imu] if isinstance(imu, ImuLog) else imu)
    lo, hi = (-np.inf if start is None else start - 1e-9), (np.inf if end is None else end + 1e-9)
    before, nxt = None, next(blocks, None)
    while nxt is not None:
        cur, nxt = nxt, next(blocks, None)
        t = cur.time
        k0 = int(np.searchsorted(t, lo, side="left"))
        k1 = int(np.searchsorted(t, hi, side="right"))
        if k0 == len(t):                    # all before the start: keep the last two rows
            before = (t[-2:], cur.dtheta_b[-2:], cur.dvel_b[-2:])
            continue
        last = nxt is None or k1 < len(t)
        yield t[:k1], cur.dtheta_b[:k1], cur.dvel_b[:k1], k0, before, last
        before = None
        if last:
            return


def run_forward(imu, gnss, initial, settings, *, start=None, end=None, progress=None,
                workdir=None, initial_time=None):
    """Forward filter over an IMU log with GNSS updates, streaming the log.

    Parameters
    ----------
    imu : ins.nav.imu.ImuLog or iterable of ImuLog
        Raw increments (body FRD), whole or as consecutive pieces (:func:`ins.io.imu_blocks
        .iter_imu`); minus the filter's bias and scale estimates.  Memory: one piece.
    gnss : ins.io.gnss_log.GnssLog
        Antenna positions (velocities).
    initial : ins.nav.mechanization.NavState
        State at the first IMU epoch >= ``start`` (or at ``initial_time``).
    settings : FilterSettings
    progress : callable, optional
        ``progress(done_epochs, total_epochs)``; the total is estimated from the GNSS
        time span and the IMU interval until the last block.
    workdir : str, optional
        Folder for the temporary files holding the forward trajectory and the node
        matrices (bounded memory for long logs); ``None``: in memory.
    initial_time : float, optional
        Time (s) of ``initial`` when it is not an IMU epoch (e.g. a GNSS fix): its
        position is moved along its velocity to the first IMU epoch >= ``start``.

    Returns
    -------
    ForwardResult
        A non-finite state raises InputError with the epoch as ``time_s``.
    """
    run = _ForwardRun(gnss, settings, workdir)
    for t, th, dv, k0, before, last in _pieces(imu, start, end):
        if run.state is None:                      # the first block: the first node
            t, th, dv, cur = _first_rows(t, th, dv, k0, before)
            if cur + 1 >= len(t) and last:
                raise InputError(f"fewer than 2 IMU epochs between start {start} and end "
                                 f"{end} s")
            run.first_node(t, cur, initial, initial_time)
        else:                                      # rows held back from the last block
            t, th, dv, cur = run.join_carry(t, th, dv)
        run.block(t, th, dv, cur, last)
        if progress is not None:
            progress(*run.progress(t, last))
    if run.state is None:
        raise InputError(f"start time {start} s is after the last IMU epoch")
    if run.n_rows < 2:
        raise InputError(f"fewer than 2 IMU epochs between start {start} and end {end} s")
    out = run.result()
    if out.n_mount_fallback:
        warnings.warn(f"{out.n_mount_fallback} GNSS record(s) without mount data: the static "
                      f"lever arm l_bp + l_ap was used", InputWarning, stacklevel=2)
    return out


def _first_rows(t, th, dv, k0, before):
    """The first block from two rows before the start row ``k0`` (the two-sample
    corrections' previous samples, from the block before when ``before``); returns
    ``(t, th, dv, k0)`` with ``k0`` the start row in the trimmed arrays."""
    if before is not None:
        t, th, dv = (np.concatenate([c, x]) for c, x in zip(before, (t, th, dv)))
        k0 += len(before[0])
    cut = max(k0 - 2, 0)
    return t[cut:], th[cut:], dv[cut:], k0 - cut


class _ForwardRun:
    """What the forward pass carries from one IMU block to the next: the state, sensor
    estimates and covariance, the integrals since the last node, the stores and the
    per-node records, the next GNSS record ``gj`` and the rows held back."""

    def __init__(self, gnss, settings, workdir):
        self.layout = L = settings.layout
        self.settings = settings
        self.GQG = noise_matrix(settings.noise, L, settings.clock_psd)
        self.tau = settings.noise.decay_time_s
        self.interval = settings.node_interval_s
        self.sensors = np.zeros(L.n - 9)
        if settings.initial_sensors is not None:
            init = np.asarray(settings.initial_sensors, dtype=float).ravel()
            if len(init) not in (12, L.n - 9):
                raise InputError(f"initial_sensors: expected 12 or {L.n - 9} values, got "
                                 f"{len(init)}")
            self.sensors[:len(init)] = init
        self.mis = (L.gyro_misalignment is not None or L.accel_misalignment is not None)
        # first index of the misalignment groups for the compiled A (-1: absent)
        self.gyro_mis = -1 if L.gyro_misalignment is None else L.gyro_misalignment.start
        self.accel_mis = -1 if L.accel_misalignment is None else L.accel_misalignment.start
        self.clock_i = -1 if getattr(L, "clock", None) is None else L.clock.start
        self.headings = sorted(settings.heading, key=lambda m: m.time)
        self.hj = 0
        self.P = settings.initial_covariance()
        self.workdir = workdir
        self.traj, self.nodes = TrajectoryStore(workdir), NodeStore(workdir)
        w = {"workdir": workdir}
        self.node_rows, self.node_time = Rows((), np.int64, **w), Rows((), **w)
        self.dxs, self.sens = Rows((L.n,), **w), Rows((L.n - 9,), **w)
        self.node_states = Rows((10,), **w)
        self.updater = (settings.updater or Updater)(settings, gnss)
        if workdir is not None:           # a record per tested measurement: on disk too
            up = self.updater
            up.records, up.nis, up.nis_record, up.innovation = measurement_stores(workdir)
        self.g_time = self.updater.ev_time         # the GNSS update events' epochs
        self.g_pos = (self.updater.ev_kind & 1).astype(bool)     # events with a position
        self.acc = np.zeros((16, 3))
        self.state = self.state_a = self.t_a = None
        self.gj = self.row_base = self.n_rows = 0
        self.carry = None
        self.t_total = None

    def first_node(self, t, k0, initial, initial_time):
        """The initial state at row ``k0`` (moved from ``initial_time`` along its velocity),
        the GNSS records of that row, and the first node."""
        g_time = self.g_time
        state = self.state = initial.as_vector().copy()
        if initial_time is not None:
            state[NAV.lla] += earth.lla_rate(state[0], state[2], state[NAV.vel]) * (
                t[k0] - initial_time)
        P0 = self.P
        self.updater.n_outside = int(np.count_nonzero((g_time < t[k0] - 1e-9) & self.g_pos))
        self.gj = int(np.searchsorted(g_time, t[k0] - 1e-9, side="left"))
        while self.gj < len(g_time) and _row_known(g_time[self.gj], t, k0):
            self.P, _ = self.updater.update(self.gj, t[k0], state, self.sensors, self.P,
                                            np.zeros(3))
            self.gj += 1
        P0, Phi0 = _reinitialized(self.updater, P0, np.eye(self.layout.n))
        self.nodes.append(P0, self.P, Phi0, t[k0])
        self.dxs.append(np.zeros(self.layout.n))
        self.traj.append(t[k0:k0 + 1], state[None, :])
        self.row_base, self.n_rows = -k0, 1
        self._keep_node(k0, t[k0])
        self.t_total = max((g_time[-1] if len(g_time) else t[-1]) - t[k0], 1e-9)

    def join_carry(self, t, th, dv):
        """The rows held back from the last block before this one; returns
        ``(t, th, dv, cur)`` with ``cur`` the row of the current state."""
        carry, cur = self.carry
        t, th, dv = (np.concatenate([c, x]) for c, x in zip(carry, (t, th, dv)))
        return t, th, dv, cur

    def block(self, t, th, dv, cur, last):
        """Mechanize from row ``cur`` to the end of the block (all but the last row unless
        ``last``), with a covariance step and the GNSS updates at each node; store the
        rows and hold back the last two."""
        g_time = self.g_time
        p, stop = cur + 1, len(t) if last else len(t) - 1
        out = np.empty((max(stop - p, 0), 10))
        while cur < stop - 1:
            r = _next_node(t, cur, self.t_a, g_time[self.gj] if self.gj < len(g_time) else None,
                           stop, last, self.interval)
            hi = stop if r < 0 else r + 1
            if self.mis:
                L = self.layout
                mis = np.concatenate([L.estimate(self.sensors, "gyro_misalignment"),
                                      L.estimate(self.sensors, "accel_misalignment")])
                _filter_kernels.propagate_rows_mis(t, th, dv, cur + 1, hi, self.state,
                                                   self.sensors, mis, out[cur + 1 - p:hi - p],
                                                   self.acc)
            else:
                _filter_kernels.propagate_rows(t, th, dv, cur + 1, hi, self.state,
                                               self.sensors, out[cur + 1 - p:hi - p],
                                               self.acc[:10])
            check_finite(self.state, out[cur + 1 - p:hi - p], t[cur + 1:hi],
                         "implausible increments, initial state or GNSS")
            cur = hi - 1
            if r < 0:
                break
            self.P = self.node(t, th, dv, r, lambda k: _row_known(g_time[k], t, r))
            while self.gj < len(g_time) and _row_known(g_time[self.gj], t, r):
                self.gj += 1
            out[r - p] = self.state
            self._keep_node(r, t[r])
            self.acc[:] = 0.0
        self.traj.append(t[p:stop], out)
        self.n_rows += stop - p
        keep = max(cur - 1, 0)                     # the next block starts here
        self.carry = (t[keep:], th[keep:], dv[keep:]), cur - keep
        self.row_base += keep

    def _keep_node(self, r, t_r):
        """Record the node at row ``r`` (of this block) after its updates."""
        self.node_states.append(self.state)
        self.node_rows.append(r + self.row_base)
        self.node_time.append(t_r)
        self.sens.append(self.sensors)
        self.state_a, self.t_a = self.state.copy(), t_r

    def progress(self, t, last):
        """``(done, total)`` epochs; the total estimated from the GNSS span and the IMU
        interval until the last block."""
        total = int(round(self.t_total / max(float(np.median(np.diff(t[-64:]))), 1e-9))) + 1
        return self.n_rows, (max(total, self.n_rows) if not last else self.n_rows)

    def node(self, t, th, dv, r, at_node):
        """Covariance step from the previous node to row ``r``, then the GNSS updates of
        the records from ``gj`` on whose row is ``r`` and the node's other measurements;
        stores the node.  Returns P."""
        L, up = self.layout, self.updater
        dt = t[r] - self.t_a
        mid = 0.5 * (self.state_a + self.state)
        acc = self.acc
        Phi, _, P = _kalman_kernels.node_predict(
            float(mid[0]), float(mid[2]), mid[NAV.vel], acc, float(dt), float(self.tau),
            self.gyro_mis, self.accel_mis, self.clock_i, self.GQG, self.P)
        P_prior = P
        w_meas_b = th[r] / (t[r] - t[r - 1])
        f_meas_b = dv[r] / (t[r] - t[r - 1])
        dx = np.zeros(L.n)
        gj, g_time = self.gj, self.g_time
        while gj < len(g_time) and at_node(gj):
            P, d = up.update(gj, t[r], self.state, self.sensors, P, w_meas_b, f_meas_b)
            dx += d
            gj += 1
        heads = []
        while self.hj < len(self.headings) and self.headings[self.hj].time <= t[r] + 1e-9:
            heads.append(self.headings[self.hj])
            self.hj += 1
        rest = self._in_rest_window(t[r]) or (self.settings.zupt and self._at_rest(t, th, dv, r))
        if heads or rest or self.settings.nhc:
            P, d = up.others(t[r], self.state, self.sensors, P, w_meas_b, rest, heads)
            dx += d
        P = 0.5 * (P + P.T)
        P_prior, Phi = _reinitialized(up, P_prior, Phi)
        self.nodes.append(P_prior, P, Phi, t[r])
        self.dxs.append(dx)
        return P

    def _in_rest_window(self, t_r):
        """Whether the node at ``t_r`` (s) is inside one of the zero-velocity windows
        (used with or without the rest detector of ``zupt``)."""
        return any(a <= t_r <= b for a, b in self.settings.zupt_windows_s)

    def _at_rest(self, t, th, dv, r):
        """Whether the IMU is at rest over the rows since the last node (in this block)
        or the node is inside one of the configured zero-velocity windows."""
        s = self.settings
        if self._in_rest_window(t[r]):
            return True
        if np.linalg.norm(self.state[NAV.vel]) > ZUPT_MAX_SPEED_MPS:
            return False                   # smooth straight flight is not rest
        lo = max(int(np.searchsorted(t, self.t_a, side="right")), 1)
        if r + 1 - lo < 2:
            return False
        dt = np.diff(t[lo - 1:r + 1])[:, None]
        f = np.linalg.norm(dv[lo:r + 1] / dt, axis=1)
        w = np.abs(th[lo:r + 1] / dt - self.sensors[:3])     # less the gyro bias estimate
        return bool(np.std(f) < s.zupt_accel_std_mps2
                    and np.max(w) < np.deg2rad(s.zupt_gyro_dps))

    def result(self):
        up = self.updater
        keep = (lambda x: x) if self.workdir is not None else as_array
        out = ForwardResult(self.traj, self.nodes, keep(self.node_rows), keep(self.node_time),
                            keep(self.dxs), keep(self.sens))
        out.node_states = keep(self.node_states)
        out.n_updates = up.n_updates
        out.n_rejected = up.n_rejected
        out.n_outside = up.n_outside + int(np.count_nonzero(self.g_pos[self.gj:]))
        out.n_mount_fallback = up.n_fallback
        if isinstance(up.nis, Rows):
            out.nis, out.nis_record, out.innovation_m = (
                keep(up.nis), keep(up.nis_record), keep(up.innovation))
        else:
            out.nis = np.array(up.nis)
            out.nis_record = np.array(up.nis_record, dtype=np.int64)
            out.innovation_m = np.array(up.innovation).reshape(-1, 3)
        out.nis_threshold = up.threshold
        out.records = up.records
        out.recoveries = list(up.recoveries)
        out.reanchors = list(getattr(up, "reanchors", []))
        out.n_gnss_steps = int(getattr(up, "n_steps", 0))
        out.layout = self.layout
        out.updater = up
        return out


def _reinitialized(updater, P_prior, Phi):
    """The node's prior covariance and transition with the re-initialization that its
    updater made (:meth:`ins.estimation.core.updates.Updater.reinitialize`)."""
    tr = updater.take_transform()
    if tr is None:
        return P_prior, Phi
    T, q = tr
    P = T @ P_prior @ T.T + q
    return 0.5 * (P + P.T), T @ Phi


def std_of(P, time=None):
    """Standard deviations of a stack of covariances (m, 21, 21) -> (m, 21).

    A negative variance beyond rounding (relative to the largest variance of the same
    state in the stack) raises :class:`~ins.common.errors.QualityError` naming the time and
    the state (:func:`ins.estimation.core.error_model.checked_std`)."""
    var = np.einsum("mii->mi", np.asarray(P, dtype=float))
    return checked_std(var, np.max(np.abs(var), axis=0), time)


__all__ = ["ForwardResult", "run_forward", "schedule_nodes", "std_of"]
