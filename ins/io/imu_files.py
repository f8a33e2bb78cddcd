"""IMU log files: the readers and writers of :class:`ins.nav.imu.ImuLog` and their checks.

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
:func:`ins.nav.imu.rates_to_increments`.

Axes
----
``axes`` names what the IMU's x, y, z axes point to; the readers map both increments
into FRD with :func:`ins.nav.imu.C_frd_axes` (``v_frd = C_frd_axes @ v_axes``).

Checks
------
Every reader raises :class:`~ins.common.errors.InputError` naming the file and the 1-based line
(binary: the record) for: an empty file or no data lines; a line with too few columns or
another column count than the first data line; text in a number; NaN or inf; time not
strictly increasing (``"duplicated epoch"`` for the same time twice); a log of one epoch;
and increments whose median magnitude per second no IMU reaches (a file of rates read as
increments, see :data:`ins.nav.imu.MAX_MEDIAN_SPECIFIC_FORCE`).  Gaps (an interval longer than
1.5 nominal intervals) are not an error here: :meth:`ins.nav.imu.ImuLog.find_gaps` finds them.
Readers never modify the file.
"""
import math
import os
import warnings

import numpy as np

from ins.common import textfiles, textformat, textparse
from ins.common.errors import InputError, InputWarning
from ins.common.fileio import atomic_open
from ins.nav.imu import (
    DPH,
    G0,
    MAX_ANGULAR_RATE,
    MAX_MEDIAN_ANGULAR_RATE,
    MAX_MEDIAN_SPECIFIC_FORCE,
    MAX_SPECIFIC_FORCE,
    MAX_TIME_S,
    MIN_MEDIAN_SPECIFIC_FORCE_RATES,
    C_frd_axes,
    ImuLog,
)

__all__ = [
    "FORMATS", "read_imu", "read_kfgins_text", "read_kfgins_binary", "read_csv",
    "write_kfgins_text", "write_kfgins_binary", "write_csv", "shift_time", "shifted_blocks",
]

#: Accepted ``format`` values of :func:`read_imu`.
FORMATS = ("kfgins", "kfgins-bin", "csv")

_RECORD_BYTES = 56
_KFGINS_NAMES = ("time", "dtheta_x", "dtheta_y", "dtheta_z", "dvel_x", "dvel_y", "dvel_z")
_KFGINS_RATE_NAMES = ("time", "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z")


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
    far = np.flatnonzero(np.abs(time) > MAX_TIME_S)
    if far.size:
        k = int(far[0])
        raise InputError(f"time {float(time[k]):.17g} s is beyond +-{MAX_TIME_S:g} s (seconds "
                         f"expected; a time in ms or ns?)", path=path, **_where(row_line, k))
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
    _check_samples(path, dtheta, dvel, dt, row_line, names, rates)
    C = C_frd_axes(axes)
    if axes != "FRD":
        dtheta = dtheta @ C.T
        dvel = dvel @ C.T
    return ImuLog.adopt(time, dtheta, dvel)


def _check_samples(path, dtheta, dvel, dt, row_line, names, rates):
    """Refuse the first sample whose angular rate or specific force is physically absurd
    (above :data:`~ins.nav.imu.MAX_ANGULAR_RATE` rad/s or
    :data:`~ins.nav.imu.MAX_SPECIFIC_FORCE` m/s^2), naming its line (or record).

    An increment is divided by the longer of its interval and the median interval: a
    time stamp that jitters early does not shorten the interval the sensor integrated.
    """
    dt_eff = np.maximum(dt, np.median(dt))
    for inc, limit, what, unit in ((dtheta, MAX_ANGULAR_RATE, "angular rate", "rad/s"),
                                   (dvel, MAX_SPECIFIC_FORCE, "specific force", "m/s^2")):
        with np.errstate(over="ignore", invalid="ignore"):
            size = _norms(inc) / dt_eff
        bad = np.flatnonzero(~(size <= limit))
        if bad.size:
            k = int(bad[0])
            cols = names[1:4] if what == "angular rate" else names[4:7]
            given = (f"{', '.join(cols)} = {', '.join(f'{float(x):.6g}' for x in inc[k] / (dt[k] if rates else 1.0))}"
                     + ("" if rates else f" in {float(dt[k]):.6g} s"))
            big = f"{float(size[k]):.4g}" if np.isfinite(size[k]) else "beyond 1e308"
            raise InputError(f"implausible {what} {big} {unit} ({given}), "
                             f"above {limit:g} {unit} that no IMU measures",
                             path=path, **_where(row_line, k))


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
        turned into increments by :func:`ins.nav.imu.rates_to_increments`' rule.

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
    rule of :func:`ins.nav.imu.rates_to_increments` (``increment[k] = rate[k] * (time[k] -
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
# time base

def shift_time(log, time_shift_s):
    """``log`` with ``time_shift_s`` (s) added to every stamp (the IMU clock's offset
    against the common time base: ``t = t_imu + time_shift_s``); 0 gives ``log`` itself."""
    if not time_shift_s:
        return log
    return ImuLog.adopt(log.time + float(time_shift_s), log.dtheta_b, log.dvel_b)


def shifted_blocks(blocks, time_shift_s):
    """The IMU blocks of an iterator with ``time_shift_s`` added to their stamps
    (:func:`shift_time`), lazily; the iterator itself when the shift is 0."""
    if not time_shift_s:
        return blocks
    return (shift_time(b, time_shift_s) for b in blocks)


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
