"""Checks of the rows of a numeric table read from a file: finite values, strictly
increasing time; errors name the file and the line (through the row-to-line map of
:func:`ins.common.textfiles.read_table`)."""
import os

import numpy as np

from ins.common.errors import InputError

__all__ = ["check_rows"]


def check_rows(rows, row_line, path, time_col=0, name_duplicates=True):
    """Every value finite and the time column strictly increasing, else an
    :class:`InputError` naming the file and line (a duplicated epoch named as such
    unless ``name_duplicates`` is false)."""
    path = os.fspath(path)
    bad = np.flatnonzero(~np.all(np.isfinite(rows), axis=1))
    if bad.size:
        raise InputError("non-finite value", path=path, line=int(row_line[bad[0]]))
    t = rows[:, time_col]
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        k = back[0] + 1
        what = ("duplicated epoch" if name_duplicates and t[k] == t[k - 1]
                else "time not increasing")
        raise InputError(f"{what}: t = {float(t[k])!r} s after {float(t[k - 1])!r} s",
                         path=path, line=int(row_line[k]))


def check_ranges(rows, row_line, path, ranges):
    """Every value of the columns within its plausible range, else an
    :class:`InputError` naming the file, the line of the first offending row, the column
    and the range with its unit.

    ``ranges``: ``(column, lo, hi, name, unit)`` tuples (``lo``/``hi`` inclusive; use
    the bounds of :mod:`ins.common.limits`).  ``row_line`` None: a binary file, whose
    1-based record is named instead of a line.
    """
    path = os.fspath(path)
    first = None
    for col, lo, hi, name, unit in ranges:
        v = rows[:, col]
        bad = np.flatnonzero(~((v >= lo) & (v <= hi)))
        if bad.size and (first is None or bad[0] < first[0]):
            first = (int(bad[0]), float(v[bad[0]]), lo, hi, name, unit)
    if first is not None:
        k, value, lo, hi, name, unit = first
        where = {"record": k + 1} if row_line is None else {"line": int(row_line[k])}
        span = (f"above {hi:g} {unit}" if lo == -np.inf else f"below {lo:g} {unit}"
                if hi == np.inf else f"outside {lo:g} .. {hi:g} {unit}")
        raise InputError(f"{name} = {value:g} {unit} is {span}", path=path, **where)
