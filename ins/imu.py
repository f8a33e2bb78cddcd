"""IMU logs: the :class:`ImuLog` type, file readers and writers, checks, error compensation.

An IMU log holds, per epoch ``k``, the angle increment ``dtheta_b[k]`` (rad) and the
velocity increment ``dvel_b[k]`` (m/s) in the body frame ``b`` (forward-right-down), both
integrated over ``(time[k-1], time[k]]``: increments are stamped at the END of their
interval.  Time is in s (continuous, GPS seconds of week by default).

File formats
------------
``kfgins`` (text)
    One epoch a line, 7 or more whitespace- or comma-separated columns:
    ``time [s], dtheta x y z [rad], dvel x y z [m/s]``; extra columns are ignored;
    blank lines and ``#``/``%`` comment lines are skipped.
``kfgins-bin`` (binary)
    The same 7 numbers per record as little-endian float64 (56 bytes a record).
``csv``
    A header line naming the columns with their units, then the data; see
    :func:`read_csv`.

With ``rates=True`` the kfgins columns hold rates instead: angular rate (rad/s) and
specific force (m/s^2).  They are turned into increments by the rule of
:func:`rates_to_increments`.

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

Checks
------
Every reader raises :class:`~ins.errors.InputError` naming the file and the 1-based line
(binary: the record) for: an empty file or no data lines; a line with too few columns or
another column count than the first data line; text in a number; NaN or inf; time not
strictly increasing (``"duplicated epoch"`` for the same time twice); a log of one epoch;
and increments whose median magnitude per second no IMU reaches (a file of rates read as
increments, see :data:`MAX_MEDIAN_SPECIFIC_FORCE`).  Gaps (an interval longer than
1.5 nominal intervals) are not an error here: :meth:`ImuLog.find_gaps` finds them.
Readers never modify the file.
"""
import math
import os
import warnings
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from . import textfiles, textformat, textparse
from .errors import InputError, InputWarning
from .fileio import atomic_open

__all__ = [
    "ImuLog", "DPH", "MGAL", "PPM", "G0", "AXES", "C_frd_axes",
    "MAX_MEDIAN_SPECIFIC_FORCE", "MAX_MEDIAN_ANGULAR_RATE",
    "compensate", "rates_to_increments",
    "read_imu", "read_kfgins_text", "read_kfgins_binary", "read_csv",
    "write_kfgins_text", "write_kfgins_binary", "write_csv",
]

#: rad/s per deg/h (gyro bias).
DPH = math.pi / 180.0 / 3600.0
#: m/s^2 per mGal (accelerometer bias).
MGAL = 1e-5
#: dimensionless per ppm (scale factor).
PPM = 1e-6
#: Standard gravity, m/s^2 (the unit ``g`` of CSV accelerometer columns).
G0 = 9.80665

#: Median |dvel|/dt above which increments are refused as implausible, m/s^2 (10.2 g).
#: The median over a log of any vehicle is about 1 g (9.8 m/s^2); a file of specific
#: forces read as increments gives ``9.8 / dt`` (1960 m/s^2 at 200 Hz).  Detection
#: works for logs faster than about 10 Hz.
MAX_MEDIAN_SPECIFIC_FORCE = 100.0
#: Median |dtheta|/dt above which increments are refused, rad/s (about 1150 deg/s,
#: the full range of common gyros; no log turns that fast most of the time).
MAX_MEDIAN_ANGULAR_RATE = 20.0
#: With ``rates=True``, a median specific force below this (m/s^2) draws an
#: :class:`~ins.errors.InputWarning` (increments read as rates; or free fall).
MIN_MEDIAN_SPECIFIC_FORCE_RATES = 0.5

#: Accepted ``axes`` values.
AXES = ("FRD", "FLU", "RFU", "FUR")
_C_FRD_AXES = {
    "FRD": np.eye(3),
    "FLU": np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]),
    "RFU": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]),
    "FUR": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]),
}

#: Accepted ``format`` values of :func:`read_imu`.
FORMATS = ("kfgins", "kfgins-bin", "csv")

_RECORD_BYTES = 56
_KFGINS_NAMES = ("time", "dtheta_x", "dtheta_y", "dtheta_z", "dvel_x", "dvel_y", "dvel_z")
_KFGINS_RATE_NAMES = ("time", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")


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
    def _adopt(cls, time, dtheta_b, dvel_b):
        """A log around arrays this package has just made, without copying them again
        (contiguous float64 ones are used as they are and made read-only)."""
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
        return ImuLog._adopt(self.time[keep], self.dtheta_b[keep], self.dvel_b[keep])

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
    return ImuLog._adopt(log.time, dtheta, dvel)


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


def _norms(a):
    return np.sqrt(np.einsum("ij,ij->i", a, a))


# ---------------------------------------------------------------------------------------
# checks shared by the readers

def _where(row_line, k):
    """Location keywords of row k for InputError: the line (text) or the record."""
    if row_line is None:
        return {"record": k + 1}
    return {"line": int(row_line[k])}


def _describe_where(row_line, k):
    return f"record {k + 1}" if row_line is None else f"line {int(row_line[k])}"


def _finish(path, table, cols, names, scale, row_line, rates, axes, hint):
    """Checks, unit scaling, rates -> increments, axes; returns an ImuLog.

    ``table`` (n, w) holds the parsed values; ``cols`` the 7 used columns (time, 3 gyro,
    3 accel); ``names`` their names for messages; ``scale`` unit factors to SI (or
    None); ``row_line`` the row -> line map (None for binary: records).
    """
    path = os.fspath(path)
    n = table.shape[0]
    if n == 0:
        raise InputError("no data (empty file)", path=path)
    cols = list(cols)
    block = table[:, :7] if cols == list(range(7)) else table[:, cols]
    finite = np.isfinite(block)
    if not finite.all():
        bad_rows = np.flatnonzero(~finite.all(axis=1))
        k = int(bad_rows[0])
        j = int(np.flatnonzero(~finite[k])[0])
        raise InputError(f"non-finite value {float(block[k, j])!r} in {names[j]}", path=path,
                         **_where(row_line, k))
    if n < 2:
        raise InputError("only one epoch: at least two are needed to know the sampling "
                         "interval", path=path, **_where(row_line, 0))
    time = block[:, 0]
    d = np.diff(time)
    if not np.all(d > 0):
        k = int(np.flatnonzero(~(d > 0))[0]) + 1
        if d[k - 1] == 0:
            msg = (f"duplicated epoch: time {float(time[k])!r} s already on "
                   f"{_describe_where(row_line, k - 1)}")
        else:
            msg = (f"time not increasing: {float(time[k])!r} s after "
                   f"{float(time[k - 1])!r} s on {_describe_where(row_line, k - 1)}")
        raise InputError(msg, path=path, **_where(row_line, k))
    gyro = block[:, 1:4]
    accel = block[:, 4:7]
    if scale is not None:
        scale = np.asarray(scale, dtype=np.float64)
        if np.any(scale[1:4] != 1.0):
            gyro = gyro * scale[1:4]
        if np.any(scale[4:7] != 1.0):
            accel = accel * scale[4:7]
    dt = np.empty(n)
    dt[1:] = d
    dt[0] = np.median(d)
    if rates:
        f_med = float(np.median(_norms(accel)))
        if f_med < MIN_MEDIAN_SPECIFIC_FORCE_RATES:
            warnings.warn(f"{path}: read as rates, but the median specific force is only "
                          f"{f_med:.3g} m/s^2 (about 9.8 at rest or in flight): the file may "
                          f"hold increments (read it without rates)", InputWarning,
                          stacklevel=3)
        dtheta = gyro * dt[:, None]
        dvel = accel * dt[:, None]
    else:
        dtheta, dvel = gyro, accel
        f_med = float(np.median(_norms(dvel) / dt))
        w_med = float(np.median(_norms(dtheta) / dt))
        if f_med > MAX_MEDIAN_SPECIFIC_FORCE:
            raise InputError(
                f"implausible velocity increments: median |dvel|/dt is {f_med:.4g} m/s^2 "
                f"(median |dvel| {np.median(_norms(dvel)):.4g} m/s per {dt[0]:.4g} s sample), "
                f"above {MAX_MEDIAN_SPECIFIC_FORCE:g} m/s^2 that no IMU log reaches; "
                f"the columns look like rates (m/s^2, rad/s), not increments: {hint}",
                path=path)
        if w_med > MAX_MEDIAN_ANGULAR_RATE:
            raise InputError(
                f"implausible angle increments: median |dtheta|/dt is {w_med:.4g} rad/s, "
                f"above {MAX_MEDIAN_ANGULAR_RATE:g} rad/s that no IMU log reaches; "
                f"the columns look like rates (rad/s), not increments: {hint}", path=path)
    C = _C_FRD_AXES[axes]
    if axes != "FRD":
        dtheta = dtheta @ C.T
        dvel = dvel @ C.T
    return ImuLog._adopt(time, dtheta, dvel)


def _check_axes(axes):
    C_frd_axes(axes)
    return axes.upper()


_RATES_HINT = "read them with rates=True (command line: --rates)"


# ---------------------------------------------------------------------------------------
# readers

def _parse_error(path, buf, res, ncols_min, ncols_max, names, layout):
    msg = textparse.table_error_message(res, buf, ncols_min, ncols_max, names)
    if res.status == textparse.TOO_FEW_COLUMNS or msg.startswith("binary data"):
        msg += f" ({layout})"
    return InputError(msg, path=os.fspath(path), line=res.err_line or None)


def read_kfgins_text(path, axes="FRD", rates=False):
    """Read a KF-GINS text IMU log.

    Parameters
    ----------
    path : str or os.PathLike
        Text file, 7 or more columns a line (whitespace and/or commas between fields):
        ``time [s], dtheta x y z [rad], dvel x y z [m/s]``; extra columns ignored.
    axes : {"FRD", "FLU", "RFU", "FUR"}
        The IMU's axes (see the module notes); mapped into FRD.
    rates : bool
        The columns hold rates: angular rate (rad/s) and specific force (m/s^2),
        turned into increments by :func:`rates_to_increments`' rule.

    Returns
    -------
    ImuLog

    Raises
    ------
    InputError
        Bad or implausible data, naming the file and line (see the module notes).
    ValueError
        Unknown ``axes``.
    """
    axes = _check_axes(axes)
    names = _KFGINS_RATE_NAMES if rates else _KFGINS_NAMES
    layout = ("KF-GINS text: time [s], gyro x y z [rad/s], accel x y z [m/s^2]" if rates
              else "KF-GINS text: time [s], dtheta x y z [rad], dvel x y z [m/s]")
    values, row_line = textfiles.read_table(path, 7, 1 << 30, column_names=names, hint=layout)
    return _finish(path, values, range(7), names, None, row_line, rates, axes, _RATES_HINT)


def read_kfgins_binary(path, axes="FRD", rates=False):
    """Read a KF-GINS binary IMU log: little-endian float64 x 7 per record.

    Parameters
    ----------
    path : str or os.PathLike
        Records of ``time [s], dtheta x y z [rad], dvel x y z [m/s]`` (56 bytes each).
    axes, rates
        As in :func:`read_kfgins_text`.

    Returns
    -------
    ImuLog

    Raises
    ------
    InputError
        Empty file, a size that is not a multiple of 56 bytes (naming the byte count
        and the incomplete record), and the data checks (naming the 1-based record).
    """
    axes = _check_axes(axes)
    path_s = os.fspath(path)
    with open(path_s, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        if size == 0:
            raise InputError("empty file (no records)", path=path_s)
        if size % _RECORD_BYTES:
            k = size // _RECORD_BYTES
            raise InputError(f"file size {size} bytes is not a multiple of {_RECORD_BYTES} "
                             f"(7 little-endian float64 a record): record {k + 1} at byte "
                             f"{k * _RECORD_BYTES} has only {size - k * _RECORD_BYTES} bytes",
                             path=path_s, record=k + 1)
        table = np.fromfile(f, dtype="<f8", count=size // 8)
    if table.size * 8 != size:   # the file shrank while being read
        raise InputError(f"read {table.size * 8} bytes of {size}", path=path_s)
    table = table.astype(np.float64, copy=False).reshape(-1, 7)
    names = _KFGINS_RATE_NAMES if rates else _KFGINS_NAMES
    return _finish(path_s, table, range(7), names, None, None, rates, axes, _RATES_HINT)


# CSV column names: quantity_axis_unit (time: time_unit); unit factors to SI.
_CSV_UNITS = {
    "time": {"s": 1.0},
    "dtheta": {"rad": 1.0, "deg": math.pi / 180.0},
    "dvel": {"mps": 1.0},
    "gyro": {"radps": 1.0, "dps": math.pi / 180.0, "dph": DPH},
    "accel": {"mps2": 1.0, "g": G0},
}
_CSV_UNIT_TEXT = {"s": "s", "rad": "rad", "deg": "deg", "mps": "m/s", "radps": "rad/s",
                  "dps": "deg/s", "dph": "deg/h", "mps2": "m/s^2", "g": f"g = {G0} m/s^2"}
_CSV_INCREMENTS = ("dtheta", "dvel")
_CSV_RATES = ("gyro", "accel")


def _accepted(quantity, axis="x"):
    stem = "time" if quantity == "time" else f"{quantity}_{axis}"
    return ", ".join(f"{stem}_{u} ({_CSV_UNIT_TEXT[u]})" for u in _CSV_UNITS[quantity])


def _next_newline(buf, pos, n):
    """Offset of the next newline byte at or after ``pos`` (``n`` when none)."""
    step = 4096
    while pos < n:
        hit = np.flatnonzero(buf[pos:min(pos + step, n)] == 10)
        if hit.size:
            return pos + int(hit[0])
        pos += step
        step *= 4
    return n


def _csv_header(path, buf):
    """(header line number, list of column names) of a CSV file."""
    n = buf.size - 1
    pos, line = 0, 0
    while pos < n:
        line += 1
        stop = _next_newline(buf, pos, n)
        text = bytes(buf[pos:stop]).decode("utf-8", errors="replace").strip()
        pos = stop + 1
        if text and text[0] not in "#%":
            names = [c.strip().strip('"').strip("'").strip() for c in
                     (text.split(",") if "," in text else text.split())]
            return line, names
    raise InputError("empty file: no header line (a CSV IMU file starts with a header "
                     "like time_s,dtheta_x_rad,...,dvel_z_mps)", path=os.fspath(path))


def read_csv(path, axes="FRD", rates=None):
    """Read a CSV IMU log whose header names the columns and their units.

    The first line that is not blank or a ``#``/``%`` comment is the header:
    comma-separated column names (case-insensitive), ``quantity_axis_unit``:

    ================  ===================================================
    column            accepted names (unit)
    ================  ===================================================
    time              ``time_s`` or ``t_s`` (s)
    angle increment   ``dtheta_x_rad`` (rad), ``dtheta_x_deg`` (deg)
    velocity incr.    ``dvel_x_mps`` (m/s)
    angular rate      ``gyro_x_radps`` (rad/s), ``gyro_x_dps`` (deg/s),
                      ``gyro_x_dph`` (deg/h)
    specific force    ``accel_x_mps2`` (m/s^2), ``accel_x_g`` (g = 9.80665 m/s^2)
    ================  ===================================================

    (and likewise ``_y``, ``_z``).  A file holds either the six increment columns or
    the six rate columns; other columns (names starting with another word) are
    ignored; columns may come in any order.  Rates are turned into increments by the
    rule of :func:`rates_to_increments` (``increment[k] = rate[k] * (time[k] -
    time[k-1])``, the first row with the median interval: exact for piecewise-constant
    rates, first-order otherwise).  The data lines are comma (or blank) separated
    numbers, one field per header column.

    Parameters
    ----------
    path : str or os.PathLike
    axes : {"FRD", "FLU", "RFU", "FUR"}
        The IMU's axes (see the module notes); mapped into FRD.
    rates : bool or None
        ``None``: the header decides.  ``True``/``False`` require rate/increment
        columns (an ``InputError`` otherwise).

    Returns
    -------
    ImuLog

    Raises
    ------
    InputError
        A header column of a known quantity with an unknown unit or a malformed name
        (naming the column and listing the accepted names), missing or duplicated
        columns, and the data checks of every reader (naming the file and line).
    """
    axes = _check_axes(axes)
    path_s = os.fspath(path)
    buf = textfiles.file_buffer(path_s)
    hline, names = _csv_header(path_s, buf)
    found = {}       # (quantity, axis) -> (column index, factor)
    for j, raw in enumerate(names):
        name = raw.lower()
        if not name:
            raise InputError(f"header column {j + 1} has no name", path=path_s, line=hline)
        parts = name.split("_")
        quantity = parts[0]
        if quantity == "t":
            quantity = "time"
        if quantity not in _CSV_UNITS:
            continue
        if quantity == "time":
            axis, unit = "", "_".join(parts[1:])
        else:
            if len(parts) < 3 or parts[1] not in ("x", "y", "z"):
                raise InputError(
                    f"header column {j + 1} {raw!r}: expected {quantity}_<x|y|z>_<unit>; "
                    f"accepted: {_accepted(quantity)} (likewise _y, _z)",
                    path=path_s, line=hline)
            axis, unit = parts[1], "_".join(parts[2:])
        if unit not in _CSV_UNITS[quantity]:
            what = "no unit" if not unit else f"unknown unit {unit!r}"
            raise InputError(
                f"header column {j + 1} {raw!r}: {what}; accepted: "
                f"{_accepted(quantity, axis or 'x')}"
                + ("" if quantity == "time" else " (likewise the other axes)"),
                path=path_s, line=hline)
        key = (quantity, axis)
        if key in found:
            raise InputError(f"header column {j + 1} {raw!r}: {quantity} {axis} is "
                             f"already column {found[key][0] + 1}", path=path_s, line=hline)
        found[key] = (j, _CSV_UNITS[quantity][unit])

    def complete(quantities):
        return all((q, a) in found for q in quantities for a in "xyz")

    def missing(quantities):
        return [f"{q}_{a}_*" for q in quantities for a in "xyz" if (q, a) not in found]

    has_inc = any(k[0] in _CSV_INCREMENTS for k in found)
    has_rate = any(k[0] in _CSV_RATES for k in found)
    if ("time", "") not in found:
        if names and all(textparse.is_number(c) for c in names):
            raise InputError("no header line: a CSV IMU file starts with a header like "
                             "time_s,dtheta_x_rad,...,dvel_z_mps (for a KF-GINS text file "
                             "without header use format 'kfgins')", path=path_s, line=hline)
        raise InputError(f"header has no time column; accepted: {_accepted('time')}",
                         path=path_s, line=hline)
    if has_inc and has_rate:
        raise InputError("header mixes increment (dtheta/dvel) and rate (gyro/accel) "
                         "columns: give one kind", path=path_s, line=hline)
    if not has_inc and not has_rate:
        raise InputError("header names neither increments (dtheta_x_rad, ..., dvel_z_mps) "
                         "nor rates (gyro_x_radps, ..., accel_z_mps2)", path=path_s,
                         line=hline)
    kinds = _CSV_RATES if has_rate else _CSV_INCREMENTS
    if not complete(kinds):
        raise InputError(f"header misses column(s) {', '.join(missing(kinds))}",
                         path=path_s, line=hline)
    is_rates = has_rate
    if rates is not None and bool(rates) != is_rates:
        raise InputError(f"rates={bool(rates)} was asked, but the header names "
                         f"{'rates' if is_rates else 'increments'}", path=path_s, line=hline)
    order = [("time", "")] + [(q, a) for q in kinds for a in "xyz"]
    cols = [found[k][0] for k in order]
    scale = [found[k][1] for k in order]
    ncols = len(names)
    res = textparse.parse_table(buf, ncols, ncols, skip_header_lines=hline)
    if res.status != textparse.OK:
        if res.status == textparse.NO_DATA:
            raise InputError("no data lines after the header", path=path_s, line=hline)
        if res.status in (textparse.TOO_FEW_COLUMNS, textparse.TOO_MANY_COLUMNS):
            raise InputError(f"{res.err_col} columns, but the header (line {hline}) names "
                             f"{ncols}", path=path_s, line=res.err_line)
        raise _parse_error(path_s, buf, res, ncols, ncols, names, "")
    del buf
    used_names = [names[c] for c in cols]
    hint = ("if the columns hold rates, name them gyro_x_radps ... accel_z_mps2 in the "
            "header")
    return _finish(path_s, res.values, cols, used_names, scale, res.row_line, is_rates, axes, hint)


def read_imu(path, format=None, rates=False, axes="FRD"):
    """Read an IMU log in any supported format.

    Parameters
    ----------
    path : str or os.PathLike
    format : {None, "kfgins", "kfgins-bin", "csv"}
        ``None`` guesses from the extension: ``.bin``/``.imu`` binary, ``.csv`` CSV,
        anything else KF-GINS text.
    rates : bool
        The kfgins text/binary columns hold rates (rad/s, m/s^2); see
        :func:`read_kfgins_text`.  For CSV the header decides; ``rates=True`` then
        requires rate columns.
    axes : {"FRD", "FLU", "RFU", "FUR"}
        The IMU's axes, mapped into FRD.

    Returns
    -------
    ImuLog
    """
    if format is None:
        ext = os.path.splitext(os.fspath(path))[1].lower()
        format = {".bin": "kfgins-bin", ".imu": "kfgins-bin", ".csv": "csv"}.get(ext, "kfgins")
    if format == "kfgins":
        return read_kfgins_text(path, axes=axes, rates=rates)
    if format == "kfgins-bin":
        return read_kfgins_binary(path, axes=axes, rates=rates)
    if format == "csv":
        return read_csv(path, axes=axes, rates=True if rates else None)
    raise ValueError(f"format must be one of {', '.join(FORMATS)} or None, got {format!r}")


# ---------------------------------------------------------------------------------------
# writers

def _table(log):
    if not isinstance(log, ImuLog):
        raise TypeError(f"log must be an ImuLog, got {type(log).__name__}")
    table = np.column_stack([log.time, log.dtheta_b, log.dvel_b])
    finite = np.isfinite(table)
    if not finite.all():
        k = int(np.flatnonzero(~finite.all(axis=1))[0])
        raise ValueError(f"log row {k} holds a non-finite value; not written")
    return table


def _decimals(table):
    """Time: the fewest decimals (3..9) that read back exactly, else %.17e; rest %.17e."""
    d_time = textformat.roundtrip_decimals(table[:, 0], max_decimals=9, min_decimals=3)
    return np.array([d_time] + [-1] * 6, dtype=np.int64)


def write_kfgins_text(path, log):
    """Write a KF-GINS text IMU log (FRD increments), atomically.

    Time is written in fixed point with the fewest decimals (at least 3, at most 9) that
    read back to the same float64 (``%.17e`` when none does); the increments as
    ``%.17e`` (18 significant digits).  Every value reads back bit-exact.  The file
    appears only when complete (temporary file + rename).

    Returns
    -------
    int
        Number of epochs written.
    """
    table = _table(log)
    text = textformat.format_table(table, _decimals(table))
    with atomic_open(path, "wb") as f:
        f.write(text.data)
    return table.shape[0]


def write_csv(path, log):
    """Write a CSV IMU log with the increments header, atomically.

    Header ``time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dvel_x_mps,dvel_y_mps,
    dvel_z_mps``; numbers as in :func:`write_kfgins_text` (bit-exact round trip).

    Returns
    -------
    int
        Number of epochs written.
    """
    table = _table(log)
    text = textformat.format_table(table, _decimals(table), sep=",")
    header = b"time_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dvel_x_mps,dvel_y_mps,dvel_z_mps\n"
    with atomic_open(path, "wb") as f:
        f.write(header)
        f.write(text.data)
    return table.shape[0]


def write_kfgins_binary(path, log):
    """Write a KF-GINS binary IMU log (little-endian float64 x 7 a record), atomically.

    Returns
    -------
    int
        Number of epochs written.
    """
    table = _table(log)
    data = np.ascontiguousarray(table, dtype="<f8")
    with atomic_open(path, "wb") as f:
        f.write(data.tobytes())
    return table.shape[0]
