"""Trajectory: time, geodetic position, NED velocity and attitude; the KF-GINS ``.nav`` file.

The ``.nav`` layout (KF-GINS navigation result), one epoch a line::

    week  t  lat  lon  h  vN  vE  vD  roll  pitch  yaw

with t in s, lat/lon in deg, h in m (ellipsoidal), velocity NED in m/s, roll/pitch/yaw in
deg (yaw in [0, 360)).  Written with 12 decimals in lat/lon (1e-12 deg = 0.1 um),
5 in h, 6 in velocity and 9 in the angles (4e-6 arcsec): finer than 0.1 mm.

:func:`read_trajectory` reads a ``.nav`` or an Applanix SBET (:mod:`ins.sbet`), telling
them apart by the extension (``.out``/``.sbet``) or the content.
"""
import os
from dataclasses import dataclass

import numpy as np

from . import textfiles, textformat, textrows
from .errors import InputError
from .fileio import atomic_open
from .rotation import euler_to_quat, quat_to_euler

#: Decimals of the 11 ``.nav`` columns.
NAV_DECIMALS = np.array([0, 6, 12, 12, 5, 6, 6, 6, 9, 9, 9], dtype=np.int64)


@dataclass(frozen=True)
class Trajectory:
    """Navigation solution at a series of epochs.

    Attributes
    ----------
    time : ndarray, shape (n,)
        Time, s.
    lla : ndarray, shape (n, 3)
        Latitude (rad), longitude (rad), ellipsoidal height (m).
    v_n : ndarray, shape (n, 3)
        Velocity NED, m/s.
    q_nb : ndarray, shape (n, 4)
        Attitude quaternion taking b to n (scalar last).
    """

    time: np.ndarray
    lla: np.ndarray
    v_n: np.ndarray
    q_nb: np.ndarray

    def __post_init__(self):
        n = np.shape(self.time)[0] if np.ndim(self.time) == 1 else None
        if n is None:
            raise ValueError(f"time must have shape (n,), got {np.shape(self.time)}")
        for name, width in (("lla", 3), ("v_n", 3), ("q_nb", 4)):
            if np.shape(getattr(self, name)) != (n, width):
                raise ValueError(f"{name} must have shape ({n}, {width}), "
                                 f"got {np.shape(getattr(self, name))}")

    def __len__(self):
        return len(self.time)

    def rpy(self, degrees=False):
        """Roll, pitch, yaw (ZYX), shape (n, 3); yaw in (-pi, pi]."""
        return quat_to_euler(self.q_nb, degrees=degrees)

    @classmethod
    def concatenate(cls, pieces):
        """One trajectory from consecutive pieces."""
        pieces = list(pieces)
        if not pieces:
            raise ValueError("no trajectory pieces to concatenate")
        return cls(*(np.concatenate([getattr(p, f) for p in pieces])
                     for f in ("time", "lla", "v_n", "q_nb")))

    @classmethod
    def from_nav_rows(cls, rows):
        """From rows of the 11 ``.nav`` columns (deg, m, m/s)."""
        rows = np.asarray(rows, dtype=float)
        return cls(time=rows[:, 1].copy(),
                   lla=np.column_stack([np.deg2rad(rows[:, 2:4]), rows[:, 4]]),
                   v_n=rows[:, 5:8].copy(),
                   q_nb=euler_to_quat(rows[:, 8:11], degrees=True))

    def nav_rows(self, week=0):
        """The 11 ``.nav`` columns, shape (n, 11), yaw in [0, 360)."""
        rpy = self.rpy(degrees=True)
        rpy[:, 2] = np.mod(rpy[:, 2], 360.0)
        rpy[:, 2][rpy[:, 2] >= 360.0] = 0.0   # mod of a tiny negative number
        return np.column_stack([np.full(len(self), float(week)), self.time,
                                np.rad2deg(self.lla[:, :2]), self.lla[:, 2], self.v_n, rpy])


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
    return Trajectory.from_nav_rows(rows)


#: Accepted ``format`` values of :func:`read_trajectory` (``None``: detected).
TRAJECTORY_FORMATS = ("nav", "sbet")


def trajectory_format(path):
    """``"sbet"`` for an ``.out``/``.sbet`` extension or binary content that looks like an
    SBET (:func:`ins.sbet.is_sbet`), else ``"nav"``."""
    from .sbet import is_sbet
    if os.path.splitext(os.fspath(path))[1].lower() in (".out", ".sbet"):
        return "sbet"
    return "sbet" if is_sbet(path) else "nav"


def read_trajectory(path, format=None):
    """Read a trajectory file: KF-GINS ``.nav`` or Applanix SBET (``format`` None:
    :func:`trajectory_format`).  Errors name the file and the line or record."""
    fmt = trajectory_format(path) if format is None else format
    if fmt == "sbet":
        from .sbet import read_sbet
        return read_sbet(path)
    if fmt == "nav":
        return read_nav(path)
    raise ValueError(f"format must be one of {', '.join(TRAJECTORY_FORMATS)} or None, "
                     f"got {format!r}")
