"""An IMU log read block by block (bounded memory), for the streaming post-processing.

:func:`iter_imu` yields consecutive :class:`ins.nav.imu.ImuLog` pieces of a file with the
checks of :mod:`ins.nav.imu` (finite values, strictly increasing time also across blocks,
plausible increments, rates turned into increments, axes mapped into FRD): memory is
one block (4 MiB of text, or ``block_rows`` binary records) whatever the length of
the log.  KF-GINS text and binary logs are read in blocks; a CSV log is read whole and
then handed out in pieces.  The text parser releases the GIL, so the blocks can be read
in a thread beside the filter (:func:`prefetch`).
"""
import os
import queue
import threading

import numpy as np

from ins.common import textfiles
from ins.common.errors import InputError
from ins.io import imu_files
from ins.nav import imu as imu_mod

#: Binary records per block (3.7 MB of KF-GINS records); see :data:`TEXT_BLOCK_BYTES`.
BLOCK_ROWS = 1 << 16
#: Text read per block (about 26 000 KF-GINS lines): with the parsed rows, the checked
#: log and the reader thread's queue (:func:`prefetch`) the IMU costs about 8 times this
#: in memory, whatever the length of the log; larger blocks are no faster.
TEXT_BLOCK_BYTES = 4 << 20


def _format_of(path, format):
    if format is None:
        ext = os.path.splitext(os.fspath(path))[1].lower()
        format = {".bin": "kfgins-bin", ".imu": "kfgins-bin", ".csv": "csv"}.get(ext, "kfgins")
    if format not in imu_files.FORMATS:
        raise ValueError(f"format must be one of {', '.join(imu_files.FORMATS)} or None, "
                         f"got {format!r}")
    return format


def _text_tables(path, rates):
    names = imu_files._KFGINS_RATE_NAMES if rates else imu_files._KFGINS_NAMES
    layout = ("KF-GINS text: time [s], gyro x y z [rad/s], accel x y z [m/s^2]" if rates
              else "KF-GINS text: time [s], dtheta x y z [rad], dvel x y z [m/s]")
    for values, row_line in textfiles.iter_table(path, 7, 1 << 30, column_names=names,
                                               hint=layout, block_bytes=TEXT_BLOCK_BYTES):
        yield values[:, :7], row_line


def _binary_tables(path, block_rows):
    size = os.path.getsize(path)
    if size == 0 or size % imu_files._RECORD_BYTES:
        imu_files.read_kfgins_binary(path)          # raises its InputError
    with open(path, "rb") as f:
        while True:
            table = np.fromfile(f, dtype="<f8", count=7 * block_rows)
            if table.size == 0:
                return
            yield table.astype(np.float64, copy=False).reshape(-1, 7), None


def iter_imu(path, format=None, rates=False, axes="FRD", block_rows=BLOCK_ROWS):
    """Consecutive :class:`ins.nav.imu.ImuLog` pieces of the IMU log at ``path``.

    Same arguments as :func:`ins.io.imu_files.read_imu`; the concatenation of the pieces is what
    :func:`ins.io.imu_files.read_imu` returns.  Errors name the file and line (or record).
    """
    format = _format_of(path, format)
    if format == "csv":
        log = imu_files.read_imu(path, format="csv", rates=rates, axes=axes)
        for k in range(0, len(log), block_rows):
            yield imu_mod.ImuLog.adopt(log.time[k:k + block_rows],
                                       log.dtheta_b[k:k + block_rows],
                                       log.dvel_b[k:k + block_rows])
        return
    axes = imu_files._check_axes(axes)
    names = imu_files._KFGINS_RATE_NAMES if rates else imu_files._KFGINS_NAMES
    tables = (_text_tables(path, rates) if format == "kfgins"
              else _binary_tables(os.fspath(path), block_rows))
    prev = prev_line = None
    first_record = 0
    for table, row_line in tables:
        if row_line is None:                      # binary: records, numbered by hand
            n = len(table)
            if prev is not None:
                table = np.concatenate([prev, table])
            log = _finish_records(path, table, names, rates, axes, first_record)
            first_record += n
        else:
            if prev is not None:                  # the previous row: continuity, rates
                table = np.concatenate([prev, table])
                row_line = np.concatenate([prev_line, row_line])
            log = imu_files._finish(path, table, range(7), names, None, row_line, rates, axes,
                                    imu_files._RATES_HINT)
            prev_line = row_line[-1:]
        if prev is not None:
            log = imu_mod.ImuLog.adopt(log.time[1:], log.dtheta_b[1:], log.dvel_b[1:])
        prev = table[-1:].copy()
        if len(log):
            yield log


def _finish_records(path, table, names, rates, axes, first_record):
    try:
        return imu_files._finish(path, table, range(7), names, None, None, rates, axes,
                                 imu_files._RATES_HINT)
    except InputError as exc:
        if first_record and exc.record is not None:
            raise InputError(exc.reason, path=os.fspath(path),
                             record=exc.record + first_record - 1) from None
        raise


def locate_epoch(path, time_s, format=None, time_shift_s=0.0):
    """Where the record stamped ``time_s`` (s, after ``time_shift_s``) is in the IMU log:
    ``{"line": n}`` (text), ``{"record": n}`` (binary), both 1-based, or ``{}`` when no
    record has that stamp (to 1 microsecond) or the format keeps no line numbers (CSV).

    Used to name the input line of a solution that became non-finite (the exception's
    ``time_s``): the file is scanned again, only on that failure.
    """
    format = _format_of(path, format)
    try:
        if format == "kfgins":
            for values, row_line in textfiles.iter_table(path, 7, 1 << 30):
                hit = np.flatnonzero(np.abs(values[:, 0] + time_shift_s - time_s) <= 1e-6)
                if hit.size:
                    return {"line": int(row_line[hit[0]])}
        elif format == "kfgins-bin":
            first = 0
            for table, _ in _binary_tables(os.fspath(path), BLOCK_ROWS):
                hit = np.flatnonzero(np.abs(table[:, 0] + time_shift_s - time_s) <= 1e-6)
                if hit.size:
                    return {"record": first + int(hit[0]) + 1}
                first += len(table)
    except (InputError, OSError):
        pass
    return {}


def with_location(exc, path, format=None, time_shift_s=0.0):
    """``exc`` (an :class:`InputError` of a non-finite solution, with ``time_s``) again,
    naming the IMU file and the line or record of that epoch."""
    where = locate_epoch(path, exc.time_s, format, time_shift_s)
    new = InputError(exc.reason, path=os.fspath(path), **where)
    new.time_s = exc.time_s
    return new


def prefetch(blocks, depth=2):
    """Iterate ``blocks`` in a background thread, ``depth`` items ahead.

    The reading (file I/O and the compiled parser, both without the GIL) then overlaps the
    work of the consumer.  Exceptions of the reader are raised in the consumer.
    """
    q = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def run():
        try:
            for item in blocks:
                while not stop.is_set():
                    try:
                        q.put(("item", item), timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if stop.is_set():
                    return
            q.put(("end", None))
        except BaseException as exc:   # handed to the consumer (if it still listens)
            while not stop.is_set():
                try:
                    q.put(("error", exc), timeout=0.1)
                    return
                except queue.Full:
                    continue

    thread = threading.Thread(target=run, name="imu-reader", daemon=True)
    thread.start()                 # now, not at the first next(): reading starts at once
    return _Prefetched(q, stop)


class _Prefetched:
    """The consumer side of :func:`prefetch`; the reader stops when this is dropped."""

    def __init__(self, q, stop):
        self._q, self._stop, self._done = q, stop, False

    def __iter__(self):
        return self

    def __next__(self):
        if self._done:
            raise StopIteration
        kind, item = self._q.get()
        if kind == "item":
            return item
        self._done = True
        self._stop.set()
        if kind == "error":
            raise item
        raise StopIteration

    def __del__(self):
        self._stop.set()
