"""Strapdown mechanization in the local-level NED frame (the INS paper, section 3).

The step is the two-sample algorithm on increments (previous and current row):

1. **Velocity.** The body increment gets the rotation compensation
   ``0.5 dtheta x dvel + (1/6) dtheta x (dtheta x dvel)`` (the second term is the next
   order of the exact solution for a constant rate; without it a body turning at
   10 deg/s under a transverse specific force of 5 m/s^2 drifts by 2e-7 m/s^2 at 200 Hz)
   and the two-sample sculling term ``(dtheta_prev x dvel + dvel_prev x dtheta) / 12``;
   it is projected into ``n`` with the attitude at the start of the interval and rotated
   to mid-interval by ``(I - 0.5 [zeta x])``, ``zeta = (w_ie_n + w_en_n) dt``.  Gravity
   (normal gravity of the paper) and the Coriolis term ``-(2 w_ie_n + w_en_n) x v_n``
   are evaluated at the mid-interval position and velocity, extrapolated from the start
   of the interval.
2. **Position.** ``(lat, lon, h)`` advance by ``D^-1 v dt`` with the mean of the old and
   new velocity and the radii M, N at mid-interval.
3. **Attitude.** ``q_nb(k) = q(-zeta) * q_nb(k-1) * q(phi)`` with the body rotation
   vector ``phi = dtheta + (dtheta_prev x dtheta) / 12`` (coning) and ``zeta`` the
   rotation of the n frame over the interval, evaluated at mid-interval; then
   normalisation.

The loop runs in :mod:`ins.nav._kernels` (compiled, Cython).  Sensor errors are removed beforehand with
:func:`ins.nav.imu.compensate`.
"""
import warnings
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError, InputWarning
from ins.nav import _kernels
from ins.nav.rotation import euler_to_quat
from ins.nav.trajectory import Trajectory

#: Epochs per kernel call when streaming (bounds the memory of the output buffers).
CHUNK_EPOCHS = 1 << 16


@dataclass(frozen=True)
class NavState:
    """Navigation state at one epoch.

    Attributes
    ----------
    lla : ndarray, shape (3,)
        Latitude (rad), longitude (rad), ellipsoidal height (m).
    v_n : ndarray, shape (3,)
        Velocity relative to the Earth, NED, m/s.
    q_nb : ndarray, shape (4,)
        Attitude quaternion (scalar last) taking b to n.
    """

    lla: np.ndarray
    v_n: np.ndarray
    q_nb: np.ndarray

    def __post_init__(self):
        for name, size in (("lla", 3), ("v_n", 3), ("q_nb", 4)):
            value = np.array(getattr(self, name), dtype=float)
            if value.shape != (size,):
                raise ValueError(f"{name} must have shape ({size},), got {value.shape}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{name} must be finite, got {value}")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if abs(self.lla[0]) > np.pi / 2:
            raise ValueError(f"latitude must be within +-90 deg, got {np.rad2deg(self.lla[0])} deg")
        norm = np.linalg.norm(self.q_nb)
        if abs(norm - 1.0) > 1e-6:
            raise ValueError(f"q_nb must be a unit quaternion, got norm {norm}")

    @classmethod
    def from_degrees(cls, lat_deg, lon_deg, h_m, v_n_mps, rpy_deg):
        """State from latitude, longitude (deg), height (m), NED velocity (m/s) and
        roll, pitch, yaw (deg)."""
        return cls(np.array([np.deg2rad(lat_deg), np.deg2rad(lon_deg), h_m], dtype=float),
                   np.asarray(v_n_mps, dtype=float),
                   euler_to_quat(np.asarray(rpy_deg, dtype=float), degrees=True))

    def as_vector(self):
        """The kernels' float64[10] layout: lat, lon, h, vN, vE, vD, qx, qy, qz, qw."""
        return np.concatenate([self.lla, self.v_n, self.q_nb])


def count_gaps(time, i0, i1, factor=1.5):
    """Number of intervals in ``time[i0:i1]`` longer than ``factor`` x the median."""
    d = np.diff(time[i0:i1])
    return int(np.count_nonzero(d > factor * np.median(d)))


def iter_mechanize(imu, initial, *, start=None, end=None, every=1, strict=False,
                   chunk_epochs=CHUNK_EPOCHS, progress=None):
    """Mechanize an IMU log, yielding the trajectory in chunks (bounded memory).

    Parameters
    ----------
    imu : ins.nav.imu.ImuLog
        Compensated increments (body FRD), stamped at the end of their interval.
    initial : NavState
        State at the first epoch used, ``t0`` = the first IMU time >= ``start``.  The
        increment of that row (which ends at ``t0``) only serves as the previous sample
        of the two-sample corrections.
    start, end : float, optional
        Time window, s (same time scale as the log).
    every : int
        Output every ``every``-th epoch (counted from ``t0``; ``t0`` itself is output).
    strict : bool
        Refuse a log with gaps longer than 1.5 nominal intervals (``InputError``);
        otherwise they are integrated across with an ``InputWarning`` counting them.
    progress : callable, optional
        Called as ``progress(done_epochs, total_epochs)`` after each chunk.

    Yields
    ------
    Trajectory
        Consecutive pieces of the output, the first starting at ``t0``.
    """
    time = imu.time
    i0 = 0 if start is None else int(np.searchsorted(time, start - 1e-9, side="left"))
    i1 = len(time) if end is None else int(np.searchsorted(time, end + 1e-9, side="right"))
    total = max(i1 - i0 - 1, 0)
    yield from iter_mechanize_blocks([imu], initial, start=start, end=end, every=every,
                                     strict=strict, chunk_epochs=chunk_epochs,
                                     progress=progress, total=total)


def iter_mechanize_blocks(blocks, initial, *, start=None, end=None, every=1, strict=False,
                          errors=None, chunk_epochs=CHUNK_EPOCHS, progress=None, total=None):
    """Mechanize an IMU log given as consecutive pieces (e.g. read block by block with
    :func:`ins.io.imu_blocks.iter_imu`): memory is one piece and one output chunk,
    whatever the length of the log.  The result is the same as for the whole log.

    Parameters
    ----------
    blocks : iterable of ins.nav.imu.ImuLog
        Consecutive pieces of one log (time increasing across pieces).
    initial, start, end, every, strict, progress
        As :func:`iter_mechanize`; the gap test uses the median interval of the first
        piece.
    errors : dict, optional
        Keyword arguments of :func:`ins.nav.imu.compensate` (SI), applied piece by piece with
        the exact interval of each piece's first row.
    total : int, optional
        Expected number of epochs, for ``progress`` (an estimate is fine).

    Yields
    ------
    Trajectory
    """
    from ins.nav.imu import ImuLog, compensate
    every = int(every)
    if every < 1:
        raise ValueError(f"every must be a positive integer, got {every}")
    state = initial.as_vector().copy()
    out = np.empty((chunk_epochs, _kernels.N_STATE))
    prev_raw = prev = None           # last raw / compensated row of the previous piece
    t_first = t_last = None
    counter = gaps = done = 0        # epochs after t0, gaps, epochs integrated
    nominal = None
    for raw in blocks:
        if len(raw) == 0:
            continue
        t_first = raw.time[0] if t_first is None else t_first
        t_last = raw.time[-1]
        log = raw
        if errors:
            if prev_raw is None:
                log = compensate(raw, **errors)
            else:
                ext = ImuLog.adopt(np.concatenate([prev_raw.time, raw.time]),
                                   np.concatenate([prev_raw.dtheta_b, raw.dtheta_b]),
                                   np.concatenate([prev_raw.dvel_b, raw.dvel_b]))
                c = compensate(ext, **errors)
                log = ImuLog.adopt(c.time[1:], c.dtheta_b[1:], c.dvel_b[1:])
        prev_raw = ImuLog.adopt(raw.time[-1:], raw.dtheta_b[-1:], raw.dvel_b[-1:])
        time, dth, dv = log.time, log.dtheta_b, log.dvel_b
        stop = len(time) if end is None else int(np.searchsorted(time, end + 1e-9,
                                                                   side="right"))
        if prev is None:                                      # t0 not reached yet
            i0 = 0 if start is None else int(np.searchsorted(time, start - 1e-9, side="left"))
            if i0 >= stop:
                if stop < len(time):
                    break
                continue
            yield _trajectory(time[i0:i0 + 1], state[None, :].copy())
            time, dth, dv = time[i0:stop], dth[i0:stop], dv[i0:stop]
        else:
            time = np.concatenate([prev[0], time[:stop]])
            dth = np.concatenate([prev[1], dth[:stop]])
            dv = np.concatenate([prev[2], dv[:stop]])
        prev = (time[-1:], dth[-1:], dv[-1:])
        if len(time) > 1:
            d = np.diff(time)
            nominal = np.median(d) if nominal is None else nominal
            n_gaps = int(np.count_nonzero(d > 1.5 * nominal))
            if n_gaps and strict:
                k = int(np.flatnonzero(d > 1.5 * nominal)[0])
                raise InputError(f"{n_gaps} gap(s) longer than 1.5 x the nominal interval "
                                 f"{nominal:.6g} s, the first of {d[k]:.6g} s between "
                                 f"{time[k]} and {time[k + 1]} s (refused: strict mode)")
            gaps += n_gaps
        for piece in _integrate(time, dth, dv, state, out, counter, every):
            yield piece
        counter += len(time) - 1
        done += len(time) - 1
        if progress is not None:
            progress(done, max(total or 0, done))
        if stop < len(log.time):
            break
    if prev is None and start is not None and t_last is not None and start > t_last:
        raise InputError(f"start time {start} s is after the last IMU epoch {t_last} s")
    if prev is None or counter == 0:
        span = "an empty log" if t_first is None else f"log covers {t_first} .. {t_last} s"
        raise InputError(f"fewer than 2 IMU epochs between start {start} and end {end} s "
                         f"({span})")
    if gaps:
        warnings.warn(f"{gaps} gap(s) longer than 1.5 x the nominal interval {nominal:.6g} s: "
                      "integrated across", InputWarning, stacklevel=2)


def _integrate(time, dth, dv, state, out, counter, every):
    """Rows 1.. of (time, dth, dv) from ``state`` (row 0 = the previous sample), in
    chunks of ``len(out)``; yields the selected epochs (``every``, counted by ``counter``)."""
    k, n = 1, len(time)
    while k < n:
        k1 = min(k + len(out), n)
        _kernels.mechanize_rows(time, dth, dv, k, k1, state, out)
        check_finite(state, out[:k1 - k], time[k:k1], "over a pole, or implausible "
                     "increments or initial state")
        sel = (np.arange(k, k1) + counter) % every == 0
        if np.any(sel):
            yield _trajectory(time[k:k1][sel], out[:k1 - k][sel].copy())
        k = k1


def check_finite(state, rows, time, causes):
    """Raise :class:`InputError` when ``state`` (after the rows ``rows`` at the IMU epochs
    ``time``, s) is not finite, naming the epoch of the first non-finite row as a plain
    float and keeping it as the attribute ``time_s``, so that a caller who knows the file
    can name its line (:func:`ins.io.imu_blocks.locate_epoch`)."""
    if np.isfinite(state).all():
        return
    bad = np.flatnonzero(~np.all(np.isfinite(rows), axis=1))
    time_s = float(time[int(bad[0]) if bad.size else len(time) - 1])
    exc = InputError(f"the solution became non-finite at t = {time_s:.6f} s (IMU record; "
                     f"{causes})")
    exc.time_s = time_s
    raise exc


def mechanize(imu, initial, **kwargs):
    """Mechanize an IMU log and return the whole :class:`~ins.nav.trajectory.Trajectory`.

    Same arguments as :func:`iter_mechanize`.
    """
    return Trajectory.concatenate(list(iter_mechanize(imu, initial, **kwargs)))


def _trajectory(time, states):
    return Trajectory(time=np.array(time, dtype=float), lla=states[:, 0:3],
                      v_n=states[:, 3:6], q_nb=states[:, 6:10])
