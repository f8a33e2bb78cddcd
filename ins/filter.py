"""Forward GNSS/INS error-state Kalman filter with closed-loop feedback.

How it runs
-----------
The filter works on *nodes*: every GNSS epoch, plus extra nodes so that no two nodes are
more than ``node_interval_s`` apart (GNSS outages).  Between two nodes the IMU rows are
mechanized at the full IMU rate in a numba loop (:mod:`ins._filter_kernels`), with the
current bias and scale estimates removed, while the integrals that the covariance step
needs are accumulated; the 21-state covariance is then propagated once per node interval
(:func:`ins.error_model.discretize`: ``Phi = I + A + A^2/2`` with ``A = int F dt``).  On
the benchmark flight (1 Hz GNSS) propagating at 1 s instead of 0.1 s changes the
position RMS by less than 0.1 mm and the heading RMS by 0.02 arcsec, at 2.6 times the
cost (``bench/bench_process.py``, "Covariance step").

A GNSS record at time ``t_g`` between IMU epochs ``t_j <= t_g < t_j+1`` is processed at
node ``j``: the predicted antenna position is the state at ``t_j`` advanced by
``D^-1 v (t_g - t_j)`` (the neglected acceleration term is below 0.1 mm for a 5 ms IMU
interval), with the lever arm at ``t_g``; the error state over those few ms is taken
as unchanged.

Each update is preceded by an innovation test: ``nu^T S^-1 nu`` against the chi-square
quantile of ``1 - reject_probability``; rejected records are counted.  After each
accepted update the estimated errors are fed back (closed loop): the navigation state
is corrected (:mod:`ins.error_model` sign rules), the sensor estimates updated, and
the error state reset to zero.

filterpy carries the covariance algebra: :func:`filterpy.kalman.predict` and
:func:`filterpy.kalman.update` (Joseph form).  Its ``KalmanFilter`` object is not
used: the transition and noise change at every node and the state is reset after each
update, so the object would only hold what the functions are given.
"""
import warnings
from dataclasses import dataclass, field

import numpy as np
from filterpy.kalman import predict as kf_predict
from filterpy.kalman import update as kf_update
from scipy.stats import chi2

from . import _filter_kernels, earth
from .error_model import (ATT, N_STATES, POS, VEL, ImuNoise, discretize, interval_matrix,
                          noise_matrix)
from .errors import InputError, InputWarning
from .lever_arm import (LeverArm, antenna_lla, antenna_velocity, position_jacobian,
                        velocity_jacobian)
from .mechanization import _epoch_range
from .rotation import quat_to_dcm

DEG = np.pi / 180.0


@dataclass
class FilterSettings:
    """Settings of the forward filter.

    Parameters
    ----------
    noise : ImuNoise
        IMU noise (also gives the initial sigma of the sensor states).
    lever : LeverArm
        Antenna lever arm.
    pos_std_ned_m, vel_std_ned_mps : array_like, shape (3,)
        Initial position (m) and velocity (m/s) standard deviations, NED.
    att_std_deg : array_like, shape (3,)
        Initial attitude standard deviations (roll, pitch, heading), deg.
    initial_sensors : array_like, shape (12,)
        Initial gyro bias (rad/s), accel bias (m/s^2), gyro and accel scale (1).
    use_velocity : bool
        Use the GNSS velocity columns when the file has them.
    reject_probability : float
        Innovation-test false-rejection probability (chi-square with 3 dof).
    node_interval_s : float
        Longest interval between two covariance steps, s.
    """

    noise: ImuNoise = field(default_factory=ImuNoise)
    lever: LeverArm = field(default_factory=lambda: LeverArm(np.zeros(3)))
    pos_std_ned_m: object = (0.05, 0.05, 0.05)
    vel_std_ned_mps: object = (0.02, 0.02, 0.02)
    att_std_deg: object = (0.01, 0.01, 0.1)
    initial_sensors: object = None
    use_velocity: bool = True
    reject_probability: float = 1e-5
    node_interval_s: float = 1.0

    def initial_covariance(self):
        std = np.concatenate([np.broadcast_to(np.asarray(self.pos_std_ned_m, float), 3),
                              np.broadcast_to(np.asarray(self.vel_std_ned_mps, float), 3),
                              np.broadcast_to(np.asarray(self.att_std_deg, float), 3) * DEG,
                              self.noise.sensor_std])
        if np.any(~np.isfinite(std)) or np.any(std <= 0):
            raise InputError(f"initial standard deviations must be > 0, got {std[:9]}")
        return np.diag(std ** 2)


@dataclass
class ForwardResult:
    """What the forward pass leaves for the smoother and the outputs.

    Attributes
    ----------
    time : ndarray, shape (n,)
        IMU epochs of the solution, s.
    states : ndarray, shape (n, 10)
        Forward (filtered) navigation states, ``ins._kernels`` layout; node rows hold the
        state after the update.
    node_rows : ndarray, shape (m,) of int
        Row of each node in ``states`` (first 0, last n - 1).
    dx : ndarray, shape (m, 21)
        Correction fed back at each node (sum over the node's updates).
    P_prior, P_post : ndarray, shape (m, 21, 21)
        Covariance before and after the node's updates.
    Phi : ndarray, shape (m, 21, 21)
        ``Phi[j]`` takes the error state from node ``j - 1`` to node ``j`` (``Phi[0] = I``).
    sensors : ndarray, shape (m, 12)
        Sensor estimates after the node's updates: gyro bias rad/s, accel bias m/s^2,
        gyro scale, accel scale.
    n_updates, n_rejected, n_outside, n_mount_fallback : int
        Accepted GNSS records (position or velocity), rejected by the innovation test,
        outside the IMU time span, processed with the static arm for lack of mount data.
    nis : ndarray
        Normalized innovation squared of every tested position record.
    """

    time: np.ndarray
    states: np.ndarray
    node_rows: np.ndarray
    dx: np.ndarray
    P_prior: np.ndarray
    P_post: np.ndarray
    Phi: np.ndarray
    sensors: np.ndarray
    n_updates: int = 0
    n_rejected: int = 0
    n_outside: int = 0
    n_mount_fallback: int = 0
    nis: np.ndarray = None


def schedule_nodes(time, gnss_time, node_interval_s):
    """Node rows: 0, the last row, the row of every GNSS record (last IMU epoch at or
    before it) and fill-in rows so that nodes are at most ``node_interval_s`` apart."""
    rows = np.searchsorted(time, gnss_time + 1e-9, side="right") - 1
    base = np.unique(np.concatenate([[0, len(time) - 1], rows]))
    gaps = np.diff(time[base])
    extra = []
    for a, b, gap in zip(base[:-1], base[1:], gaps):
        if gap > node_interval_s * (1 + 1e-9):
            n = int(np.ceil(gap / node_interval_s))
            targets = time[a] + gap * np.arange(1, n) / n
            extra.append(np.searchsorted(time, targets))
    if extra:
        base = np.unique(np.concatenate([base] + extra))
    return base[(base >= 0) & (base < len(time))]


class _Updater:
    """GNSS measurement updates at one node, with feedback into the state."""

    def __init__(self, settings, gnss):
        self.s = settings
        self.gnss = gnss
        self.threshold = float(chi2.ppf(1.0 - settings.reject_probability, 3))
        self.n_updates = self.n_rejected = self.n_fallback = 0
        self.nis = []

    def _apply(self, state, sensors, P, z, R, H):
        S = H @ P @ H.T + R
        nis = float(z @ np.linalg.solve(S, z))
        if nis > self.threshold:
            self.n_rejected += 1
            return P, None, nis
        x, P = kf_update(np.zeros(N_STATES), P, z, R, H)
        _filter_kernels.correct_state(state, x)
        sensors += x[9:21]
        self.n_updates += 1
        return P, x, nis

    def update(self, k, t_row, state, sensors, P, w_ib_b):
        """Process GNSS record ``k`` at the node of time ``t_row``; returns (P, dx)."""
        g = self.gnss
        dx = np.zeros(N_STATES)
        tg = g.time[k]
        l_b, dl_b, valid = self.s.lever.at(tg)
        l_b, dl_b = l_b[0], dl_b[0]
        if not valid[0]:
            self.n_fallback += 1
        lla = state[0:3] + earth.lla_rate(state[0], state[2], state[3:6]) * (tg - t_row)
        C_nb = quat_to_dcm(state[6:10])
        z = earth.ned_offset(g.lla[k], antenna_lla(lla, C_nb, l_b))
        R = np.diag(g.std_ned[k] ** 2)
        P, x, nis = self._apply(state, sensors, P, z, R, position_jacobian(C_nb, l_b))
        self.nis.append(nis)
        if x is not None:
            dx += x
        if self.s.use_velocity and g.has_velocity:
            C_nb = quat_to_dcm(state[6:10])
            w_in_n = (earth.earth_rate_n(state[0])
                      + earth.transport_rate_n(state[0], state[2], state[3:6]))
            v_ant = antenna_velocity(state[3:6], C_nb, w_ib_b, w_in_n, l_b, dl_b)
            H = velocity_jacobian(C_nb, w_ib_b, w_in_n, l_b, dl_b)
            R = np.diag(g.std_vel_n[k] ** 2)
            P, x, _ = self._apply(state, sensors, P, v_ant - g.vel_n[k], R, H)
            if x is not None:
                dx += x
        return P, dx


def run_forward(imu, gnss, initial, settings, *, start=None, end=None, progress=None):
    """Forward filter over an IMU log with GNSS updates.

    Parameters
    ----------
    imu : ins.imu.ImuLog
        Raw increments (body FRD); the filter removes its own bias and scale estimates.
    gnss : ins.gnss.GnssLog
        Antenna positions (velocities).
    initial : ins.mechanization.NavState
        State at the first IMU epoch >= ``start``.
    settings : FilterSettings
    progress : callable, optional
        ``progress(done_epochs, total_epochs)``.

    Returns
    -------
    ForwardResult
    """
    i0, i1 = _epoch_range(imu.time, start, end)
    time = imu.time[i0:i1]
    n = len(time)
    inside = (gnss.time >= time[0]) & (gnss.time <= time[-1])
    node_rows = schedule_nodes(time, gnss.time[inside], settings.node_interval_s)
    g_idx = np.flatnonzero(inside)
    g_rows = np.searchsorted(time, gnss.time[g_idx] + 1e-9, side="right") - 1
    m = len(node_rows)

    states = np.empty((n, 10))
    states[0] = initial.as_vector()
    sensors = (np.zeros(12) if settings.initial_sensors is None
               else np.array(settings.initial_sensors, dtype=float).reshape(12))
    P = settings.initial_covariance()
    GQG = noise_matrix(settings.noise)
    tau = settings.noise.corr_time_s
    out = ForwardResult(time=time, states=states, node_rows=node_rows,
                        dx=np.zeros((m, N_STATES)), P_prior=np.empty((m, N_STATES, N_STATES)),
                        P_post=np.empty((m, N_STATES, N_STATES)),
                        Phi=np.empty((m, N_STATES, N_STATES)), sensors=np.empty((m, 12)),
                        n_outside=int(np.count_nonzero(~inside)))
    out.P_prior[0] = out.P_post[0] = P
    out.Phi[0] = np.eye(N_STATES)
    out.sensors[0] = sensors
    updater = _Updater(settings, gnss)
    acc = np.zeros((10, 3))
    state = states[0].copy()
    gj = 0
    while gj < len(g_rows) and g_rows[gj] == 0:      # records at the first epoch
        P, dx = updater.update(g_idx[gj], time[0], state, sensors, P, np.zeros(3))
        gj += 1
    states[0] = state
    out.P_post[0] = P
    out.sensors[0] = sensors
    last_report = 0
    for j in range(1, m):
        ra, rb = node_rows[j - 1], node_rows[j]
        acc[:] = 0.0
        _filter_kernels.propagate_rows(imu.time, imu.dtheta_b, imu.dvel_b, i0 + ra + 1,
                                       i0 + rb + 1, state, sensors, states[ra + 1:rb + 1], acc)
        if not np.all(np.isfinite(state)):
            raise InputError(f"the solution became non-finite before t = {time[rb]!r} s "
                             f"(implausible increments, initial state or GNSS)")
        dt = time[rb] - time[ra]
        mid = 0.5 * (states[ra] + states[rb])
        A = interval_matrix(mid[0], mid[2], mid[3:6], acc[9] / dt,
                            (acc[0:3], acc[3:6], acc[6:9]), dt, tau)
        Phi, Qd = discretize(A, GQG, dt)
        _, P = kf_predict(np.zeros(N_STATES), P, Phi, Qd)
        out.P_prior[j] = P
        out.Phi[j] = Phi
        k_imu = i0 + rb
        dt_row = imu.time[k_imu] - imu.time[k_imu - 1]
        w_ib_b = (imu.dtheta_b[k_imu] / dt_row - sensors[0:3]) / (1.0 + sensors[6:9])
        while gj < len(g_rows) and g_rows[gj] == rb:
            P, dx = updater.update(g_idx[gj], time[rb], state, sensors, P, w_ib_b)
            out.dx[j] += dx
            gj += 1
        P = 0.5 * (P + P.T)
        states[rb] = state
        out.P_post[j] = P
        out.sensors[j] = sensors
        if progress is not None and (rb - last_report > 20000 or j == m - 1):
            progress(int(rb), n - 1)
            last_report = rb
    out.n_updates = updater.n_updates
    out.n_rejected = updater.n_rejected
    out.n_mount_fallback = updater.n_fallback
    out.nis = np.array(updater.nis)
    if updater.n_fallback:
        warnings.warn(f"{updater.n_fallback} GNSS record(s) without mount data: the static "
                      f"lever arm l_bp + l_ap was used", InputWarning, stacklevel=2)
    return out


def std_of(P):
    """Standard deviations of a stack of covariances (m, 21, 21) -> (m, 21)."""
    return np.sqrt(np.maximum(np.einsum("mii->mi", P), 0.0))


__all__ = ["FilterSettings", "ForwardResult", "run_forward", "schedule_nodes", "std_of",
           "POS", "VEL", "ATT"]
