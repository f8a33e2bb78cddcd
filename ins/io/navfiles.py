"""KF-GINS ``.nav`` trajectory files, and :func:`read_trajectory`, which also reads an
Applanix SBET (:mod:`ins.io.sbet`), telling them apart by the extension (``.out``/``.sbet``)
or the content.

The ``.nav`` layout (KF-GINS navigation result), one epoch a line::

    week  t  lat  lon  h  vN  vE  vD  roll  pitch  yaw

with t in s, lat/lon in deg, h in m (ellipsoidal), velocity NED in m/s, roll/pitch/yaw in
deg (yaw in [0, 360)).  Written with 12 decimals in lat/lon (1e-12 deg = 0.1 um),
5 in h, 6 in velocity and 9 in the angles (4e-6 arcsec): finer than 0.1 mm.
"""
import os

import numpy as np

from ins.common import limits, textfiles, textformat, textrows
from ins.common.errors import InputError
from ins.common.fileio import atomic_open
from ins.nav.imu import MAX_TIME_S
from ins.nav.trajectory import Trajectory

#: Decimals of the 11 ``.nav`` columns.
NAV_DECIMALS = np.array([0, 6, 12, 12, 5, 6, 6, 6, 9, 9, 9], dtype=np.int64)


def format_nav(traj, week=0):
    """Text of the ``.nav`` lines of ``traj`` (bytes)."""
    return textformat.format_fixed(traj.nav_rows(week), NAV_DECIMALS).tobytes()


def write_nav(path, pieces, week=0):
    """Write trajectory pieces (a Trajectory or an iterable of them) to a ``.nav`` file.

    The file appears only when complete (atomic rename).  Returns the number of epochs.
    """
    if isinstance(pieces, Trajectory):
        pieces = [pieces]
    n = 0
    with atomic_open(path, "wb") as f:
        for piece in pieces:
            f.write(format_nav(piece, week))
            n += len(piece)
    return n


def read_nav(path):
    """Read a ``.nav`` file (11 or more columns) into a :class:`Trajectory`."""
    rows, row_line = textfiles.read_table(path, ncols_min=11, ncols_max=64,
                                        hint="KF-GINS .nav: week t lat lon h vN vE vD "
                                             "roll pitch yaw")
    rows = rows[:, :11]
    textrows.check_rows(rows, row_line, path, time_col=1)
    if np.any(np.abs(rows[:, 2]) > 90.0):
        k = int(np.flatnonzero(np.abs(rows[:, 2]) > 90.0)[0])
        raise InputError(f"latitude {float(rows[k, 2])!r} deg outside +-90 deg (expected "
                         f"week t lat lon ..., deg)", path=str(path),
                         line=int(row_line[k]))
    L = limits
    textrows.check_ranges(rows, row_line, path, [
        (1, -MAX_TIME_S, MAX_TIME_S, "t", "s"), (3, -180.0, 360.0, "lon", "deg"),
        (4, L.MIN_HEIGHT_M, L.MAX_HEIGHT_M, "h", "m")]
        + [(c, -L.MAX_SPEED_MPS, L.MAX_SPEED_MPS, f"v{a}", "m/s")
           for c, a in zip((5, 6, 7), "NED")]
        + [(c, -720.0, 720.0, a, "deg") for c, a in zip((8, 9, 10), ("roll", "pitch", "yaw"))])
    return Trajectory.from_nav_rows(rows)


def read_nav_week(path):
    """The GPS week (first column) of the first epoch of a ``.nav`` file, or None when the
    file has no epoch or the column is not an integer."""
    with open(path, "rb") as f:
        for raw in f:
            fields = raw.split()
            if not fields or fields[0].startswith(b"#"):
                continue
            try:
                week = float(fields[0])
            except ValueError:
                return None
            return int(week) if week.is_integer() and week >= 0 else None
    return None


#: Accepted ``format`` values of :func:`read_trajectory` (``None``: detected).
TRAJECTORY_FORMATS = ("nav", "sbet")


def trajectory_format(path):
    """``"sbet"`` for an ``.out``/``.sbet`` extension or binary content that looks like an
    SBET (:func:`ins.io.sbet.is_sbet`), else ``"nav"``."""
    from ins.io.sbet import is_sbet
    if os.path.splitext(os.fspath(path))[1].lower() in (".out", ".sbet"):
        return "sbet"
    return "sbet" if is_sbet(path) else "nav"


def read_trajectory(path, format=None):
    """Read a trajectory file: KF-GINS ``.nav`` or Applanix SBET (``format`` None:
    :func:`trajectory_format`).  Errors name the file and the line or record."""
    fmt = trajectory_format(path) if format is None else format
    if fmt == "sbet":
        from ins.io.sbet import read_sbet
        return read_sbet(path)
    if fmt == "nav":
        return read_nav(path)
    raise ValueError(f"format must be one of {', '.join(TRAJECTORY_FORMATS)} or None, "
                     f"got {format!r}")
