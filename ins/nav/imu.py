"""IMU logs: the :class:`ImuLog` type, axes, error compensation, rates to increments.

An IMU log holds, per epoch ``k``, the angle increment ``dtheta_b[k]`` (rad) and the
velocity increment ``dvel_b[k]`` (m/s) in the body frame ``b`` (forward-right-down), both
integrated over ``(time[k-1], time[k]]``: increments are stamped at the END of their
interval.  Time is in s (continuous, GPS seconds of week by default).

Axes
----
``axes`` names what the IMU's x, y, z axes point to; the readers map them into FRD with
the fixed signed permutation ``C_frd_axes`` (:func:`C_frd_axes`), applied to both the
angle and the velocity increments (``v_frd = C_frd_axes @ v_axes``):

======  ======================  ==================================
axes    IMU x, y, z             ``C_frd_axes`` (rows: F, R, D)
======  ======================  ==================================
FRD     forward, right, down    ``[[1,0,0], [0,1,0], [0,0,1]]``
FLU     forward, left, up       ``[[1,0,0], [0,-1,0], [0,0,-1]]``
RFU     right, forward, up      ``[[0,1,0], [1,0,0], [0,0,-1]]``
FUR     forward, up, right      ``[[1,0,0], [0,0,1], [0,-1,0]]``
======  ======================  ==================================

All four are proper rotations (determinant +1), so the same matrix serves the angular
(axial) and linear vectors.

The file readers and writers are in :mod:`ins.io.imu_files`.
"""
import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

__all__ = [
    "ImuLog", "DPH", "MGAL", "PPM", "G0", "AXES", "C_frd_axes",
    "MAX_MEDIAN_SPECIFIC_FORCE", "MAX_MEDIAN_ANGULAR_RATE", "MIN_MEDIAN_SPECIFIC_FORCE_RATES",
    "MAX_ANGULAR_RATE", "MAX_SPECIFIC_FORCE", "MAX_TIME_S",
    "compensate", "rates_to_increments",
]

#: rad/s per deg/h (gyro bias).
DPH = math.pi / 180.0 / 3600.0
#: m/s^2 per mGal (accelerometer bias).
MGAL = 1e-5
#: dimensionless per ppm (scale factor).
PPM = 1e-6
#: Standard gravity, m/s^2 (the unit ``g`` of CSV accelerometer columns).
G0 = 9.80665

#: Median ``|dvel|/dt`` above which increments are refused as implausible, m/s^2 (10.2 g).
#: The median over a log of any vehicle is about 1 g (9.8 m/s^2); a file of specific
#: forces read as increments gives ``9.8 / dt`` (1960 m/s^2 at 200 Hz).  Detection
#: works for logs faster than about 10 Hz.
MAX_MEDIAN_SPECIFIC_FORCE = 100.0
#: Median ``|dtheta|/dt`` above which increments are refused, rad/s (about 1150 deg/s,
#: the full range of common gyros; no log turns that fast most of the time).
MAX_MEDIAN_ANGULAR_RATE = 20.0
#: Largest angular rate of any one sample, rad/s (5700 deg/s: beyond the range of any
#: gyro); a sample above it is refused by the readers with its line.
MAX_ANGULAR_RATE = 100.0
#: Largest specific force of any one sample, m/s^2 (102 g: beyond the range of any
#: navigation accelerometer); a sample above it is refused by the readers with its line.
MAX_SPECIFIC_FORCE = 1000.0
#: Largest magnitude of a time stamp, s (3000 years: a Unix time in ms or ns read as s
#: is refused).
MAX_TIME_S = 1.0e11
#: With ``rates=True``, a median specific force below this (m/s^2) draws an
#: :class:`~ins.common.errors.InputWarning` (increments read as rates; or free fall).
MIN_MEDIAN_SPECIFIC_FORCE_RATES = 0.5

#: Accepted ``axes`` values.
AXES = ("FRD", "FLU", "RFU", "FUR")
_C_FRD_AXES = {
    "FRD": np.eye(3),
    "FLU": np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]),
    "RFU": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]),
    "FUR": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
}



def C_frd_axes(axes):
    """Matrix taking a vector from the IMU's ``axes`` into FRD: ``v_frd = C @ v_axes``.

    Parameters
    ----------
    axes : {"FRD", "FLU", "RFU", "FUR"}
        What the IMU's x, y, z axes point to (F forward, R right, D down, L left,
        U up).

    Returns
    -------
    ndarray, shape (3, 3)
        A signed permutation matrix (a new array).

    Raises
    ------
    ValueError
        For any other value, naming the accepted ones.
    """
    key = axes.upper() if isinstance(axes, str) else axes
    if key not in _C_FRD_AXES:
        raise ValueError(f"axes must be one of {', '.join(AXES)} (the IMU's x, y, z "
                         f"directions), got {axes!r}")
    return _C_FRD_AXES[key].copy()


def _frozen(a):
    a.flags.writeable = False
    return a


# ---------------------------------------------------------------------------------------
# ImuLog

@dataclass(frozen=True, eq=False)
class ImuLog:
    """Increments of an IMU in the body frame (FRD), stamped at the end of their interval.

    Attributes
    ----------
    time : ndarray, shape (n,)
        Epochs, s.  ``dtheta_b[k]`` and ``dvel_b[k]`` cover ``(time[k-1], time[k]]``.
    dtheta_b : ndarray, shape (n, 3)
        Angle increments about the body axes (forward, right, down), rad.
    dvel_b : ndarray, shape (n, 3)
        Velocity increments (integrated specific force) along the body axes, m/s.

    Notes
    -----
    The arrays are stored as read-only float64 copies: the log is immutable and never
    aliases the caller's arrays.  Equality is identity (``eq=False``); compare the
    arrays to compare contents.  Readers guarantee strictly increasing time; the
    constructor checks shapes only.
    """

    time: np.ndarray
    dtheta_b: np.ndarray
    dvel_b: np.ndarray

    def __post_init__(self):
        arrays = {}
        for name in ("time", "dtheta_b", "dvel_b"):
            value = getattr(self, name)
            try:
                arrays[name] = np.array(value, dtype=np.float64, order="C", copy=True)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"ImuLog.{name} must be an array of numbers: {exc}") from None
        time = arrays["time"]
        if time.ndim != 1:
            raise ValueError(f"ImuLog.time must have shape (n,), got {time.shape}")
        n = time.shape[0]
        for name in ("dtheta_b", "dvel_b"):
            if arrays[name].shape != (n, 3):
                raise ValueError(f"ImuLog.{name} must have shape ({n}, 3) to match time "
                                 f"of shape ({n},), got {arrays[name].shape}")
        for name, a in arrays.items():
            object.__setattr__(self, name, _frozen(a))

    @classmethod
    def adopt(cls, time, dtheta_b, dvel_b):
        """A log around arrays just made (by a reader, the simulator, a filter), without
        copying them again: contiguous float64 ones are used as they are and made
        read-only, so the caller must not keep writable references.  No shape checks."""
        log = object.__new__(cls)
        for name, a in (("time", time), ("dtheta_b", dtheta_b), ("dvel_b", dvel_b)):
            object.__setattr__(log, name, _frozen(np.ascontiguousarray(a, dtype=np.float64)))
        return log

    def __len__(self):
        return self.time.shape[0]

    def __repr__(self):
        n = len(self)
        if n == 0:
            return "ImuLog(n=0)"
        return (f"ImuLog(n={n}, time={float(self.time[0])!r}..{float(self.time[-1])!r} s, "
                f"nominal_dt={self.nominal_dt!r} s)")

    @cached_property
    def nominal_dt(self):
        """Nominal sampling interval: the median of ``diff(time)``, s (NaN if n < 2)."""
        if len(self) < 2:
            return float("nan")
        return float(np.median(np.diff(self.time)))

    @cached_property
    def dt(self):
        """Interval of each increment, shape (n,), s (read-only).

        ``dt[k] = time[k] - time[k-1]``; ``dt[0]`` is :attr:`nominal_dt`, since the
        first row's interval is not in the log (also after :meth:`slice_time`).
        """
        d = np.empty(len(self))
        if len(self):
            d[1:] = np.diff(self.time)
            d[0] = self.nominal_dt
        return _frozen(d)

    def slice_time(self, start=None, end=None):
        """The rows with ``start <= time <= end`` (s; ``None``: unbounded), a new log.

        The first kept row's ``dt`` becomes the nominal interval of the new log.
        """
        keep = np.ones(len(self), dtype=bool)
        if start is not None:
            keep &= self.time >= start
        if end is not None:
            keep &= self.time <= end
        return ImuLog.adopt(self.time[keep], self.dtheta_b[keep], self.dvel_b[keep])

    def find_gaps(self, factor=1.5):
        """Indices ``k`` with ``time[k] - time[k-1] > factor * nominal_dt``.

        Returns
        -------
        ndarray of int64
            Row indices (>= 1) of the rows that end a gap, increasing.
        """
        if len(self) < 2:
            return np.empty(0, dtype=np.int64)
        return (np.flatnonzero(np.diff(self.time) > factor * self.nominal_dt) + 1).astype(np.int64)


# ---------------------------------------------------------------------------------------
# compensation and conversions

def _per_axis(value, n, name):
    a = np.asarray(value, dtype=np.float64)
    if a.shape not in ((), (3,), (n, 3)):
        raise ValueError(f"{name} must be a scalar, shape (3,) or ({n}, 3), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return a


def compensate(log, gyro_bias=None, accel_bias=None, gyro_scale=None, accel_scale=None):
    """Remove sensor biases and scale-factor errors from increments.

    Per axis, as the INS paper writes it::

        dvel   = (dvel_raw   - b_a * dt) / (1 + s_a)
        dtheta = (dtheta_raw - b_g * dt) / (1 + s_g)

    with ``dt`` = :attr:`ImuLog.dt` (the first row uses the nominal interval).

    Parameters
    ----------
    log : ImuLog
        Raw increments (body FRD).  Not modified.
    gyro_bias : array_like, shape (3,) or (n, 3) or scalar, optional
        Gyro bias ``b_g``, rad/s (``bias_dph * DPH``).
    accel_bias : array_like, optional
        Accelerometer bias ``b_a``, m/s^2 (``bias_mgal * MGAL``).
    gyro_scale, accel_scale : array_like, optional
        Scale-factor errors ``s_g``, ``s_a``, dimensionless (``ppm * PPM``); must be
        greater than -1.

    Returns
    -------
    ImuLog
        A new log with the compensated increments and the same time (``log`` itself
        when no error is given).
    """
    if gyro_bias is None and accel_bias is None and gyro_scale is None and accel_scale is None:
        return log                                  # immutable: nothing to remove
    n = len(log)
    dt = log.dt[:, None]
    dtheta = np.array(log.dtheta_b)
    dvel = np.array(log.dvel_b)
    if gyro_bias is not None:
        dtheta -= _per_axis(gyro_bias, n, "gyro_bias") * dt
    if accel_bias is not None:
        dvel -= _per_axis(accel_bias, n, "accel_bias") * dt
    for name, s, arr in (("gyro_scale", gyro_scale, dtheta), ("accel_scale", accel_scale, dvel)):
        if s is None:
            continue
        s = _per_axis(s, n, name)
        if np.any(s <= -1.0):
            raise ValueError(f"{name} must be greater than -1, got {s!r}")
        arr /= 1.0 + s
    return ImuLog.adopt(log.time, dtheta, dvel)


def _intervals(time):
    """dt[k] = time[k] - time[k-1], dt[0] = median interval (n >= 2)."""
    dt = np.empty(time.shape[0])
    d = np.diff(time)
    dt[1:] = d
    dt[0] = np.median(d)
    return dt


def rates_to_increments(time, gyro, accel):
    """Increments from sampled rates, by the end-of-interval mean-rate rule.

    The sample at ``time[k]`` is taken as the mean rate over ``(time[k-1], time[k]]``,
    so ``increment[k] = rate[k] * (time[k] - time[k-1])``, and the first row uses the
    median interval.  This is exact for rates that are piecewise constant over the
    sample intervals (what an IMU that averages internally reports) and first-order
    accurate otherwise (an error of order ``d(rate)/dt * dt**2 / 2`` per increment).
    Across a gap the last rate is taken as the mean over the whole gap.

    Parameters
    ----------
    time : array_like, shape (n,), n >= 2
        Strictly increasing, s.
    gyro : array_like, shape (n, 3)
        Angular rate, rad/s.
    accel : array_like, shape (n, 3)
        Specific force, m/s^2.

    Returns
    -------
    dtheta : ndarray, shape (n, 3)
        rad.
    dvel : ndarray, shape (n, 3)
        m/s.
    """
    time = np.asarray(time, dtype=np.float64)
    if time.ndim != 1 or time.shape[0] < 2:
        raise ValueError(f"time must have shape (n,) with n >= 2, got {time.shape}")
    dt = _intervals(time)[:, None]
    return np.asarray(gyro, dtype=np.float64) * dt, np.asarray(accel, dtype=np.float64) * dt

