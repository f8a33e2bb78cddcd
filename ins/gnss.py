"""GNSS logs of the antenna: the KF-GINS text layout, reader and writer.

One epoch a line, whitespace- or comma-separated, ``#``/``%`` comment lines skipped::

    time_s  lat_deg  lon_deg  h_m  std_n_m  std_e_m  std_d_m  [vn ve vd  std_vn std_ve std_vd]

Position of the antenna phase centre (WGS84 latitude, longitude in deg, ellipsoidal
height in m) with its standard deviations north, east, down (m); optionally the antenna
velocity NED (m/s) and its standard deviations (m/s).  Time in s on the IMU's time
scale (GPS seconds of week).
"""
from dataclasses import dataclass

import numpy as np

from . import textfiles, textformat, textrows
from .errors import InputError
from .fileio import atomic_open

_HINT = ("KF-GINS GNSS: time lat lon h std_n std_e std_d, optionally vn ve vd std_vn std_ve "
         "std_vd")


@dataclass(frozen=True)
class GnssLog:
    """Antenna positions (and velocities) with their standard deviations.

    Attributes
    ----------
    time : ndarray, shape (n,)
        s.
    lla : ndarray, shape (n, 3)
        Latitude, longitude (rad), ellipsoidal height (m).
    sigma_ned_m : ndarray, shape (n, 3)
        Position standard deviations N, E, D, m.
    v_n : ndarray, shape (n, 3) or None
        Antenna velocity NED, m/s.
    sigma_vel_ned_mps : ndarray, shape (n, 3) or None
        Velocity standard deviations, m/s.
    line : ndarray, shape (n,) of int
        1-based line of each record in the file (0 when not from a file).
    path : str or None
        The file read.
    """

    time: np.ndarray
    lla: np.ndarray
    sigma_ned_m: np.ndarray
    v_n: np.ndarray = None
    sigma_vel_ned_mps: np.ndarray = None
    line: np.ndarray = None
    path: str = None

    def __len__(self):
        return len(self.time)

    @property
    def has_velocity(self):
        return self.v_n is not None

    def select(self, keep):
        """The records where the boolean mask or index array ``keep`` selects."""
        def take(a):
            return None if a is None else a[keep]
        return GnssLog(self.time[keep], self.lla[keep], self.sigma_ned_m[keep], take(self.v_n),
                       take(self.sigma_vel_ned_mps), take(self.line), self.path)


def read_gnss(path):
    """Read a KF-GINS GNSS text file (7 or 13 columns).

    Raises
    ------
    InputError
        Naming the file and line: wrong column count, text or non-finite value, time not
        strictly increasing, latitude beyond +-90 deg, a zero or negative standard
        deviation.
    """
    path_s = str(path)
    rows, row_line = textfiles.read_table(path, ncols_min=7, ncols_max=13, hint=_HINT)
    ncols = rows.shape[1]
    if ncols not in (7, 13):
        raise InputError(f"{ncols} columns: expected 7 (position) or 13 (position and "
                         f"velocity) ({_HINT})", path=path_s, line=int(row_line[0]))
    textrows.check_rows(rows, row_line, path_s)
    lat_bad = np.flatnonzero(np.abs(rows[:, 1]) > 90.0)
    if lat_bad.size:
        k = lat_bad[0]
        raise InputError(f"latitude {float(rows[k, 1])!r} deg outside +-90 deg", path=path_s,
                         line=int(row_line[k]))
    std_cols = [4, 5, 6] + ([10, 11, 12] if ncols == 13 else [])
    names = ["std_n_m", "std_e_m", "std_d_m", "std_vn_mps", "std_ve_mps", "std_vd_mps"]
    nonpos = rows[:, std_cols] <= 0
    if np.any(nonpos):
        k, j = np.argwhere(nonpos)[0]
        raise InputError(f"{names[j]} = {float(rows[k, std_cols[j]])!r}: a standard deviation must "
                         f"be > 0", path=path_s, line=int(row_line[k]))
    lla = np.column_stack([np.deg2rad(rows[:, 1:3]), rows[:, 3]])
    vel = rows[:, 7:10].copy() if ncols == 13 else None
    std_vel = rows[:, 10:13].copy() if ncols == 13 else None
    return GnssLog(rows[:, 0].copy(), lla, rows[:, 4:7].copy(), vel, std_vel,
                   np.asarray(row_line, dtype=np.int64), path_s)


def write_gnss(path, log):
    """Write ``log`` in the KF-GINS text layout (13 columns when it has velocities),
    atomically.  Returns the number of records."""
    cols = [log.time, np.rad2deg(log.lla[:, 0]), np.rad2deg(log.lla[:, 1]), log.lla[:, 2],
            log.sigma_ned_m]
    decimals = [6, 12, 12, 5, 5, 5, 5]
    if log.has_velocity:
        cols += [log.v_n, log.sigma_vel_ned_mps]
        decimals += [6, 6, 6, 6, 6, 6]
    table = np.column_stack(cols)
    if not np.all(np.isfinite(table)):
        raise ValueError("GNSS log holds a non-finite value; not written")
    text = textformat.format_fixed(table, np.array(decimals, dtype=np.int64)).tobytes()
    with atomic_open(path, "wb") as f:
        f.write(text)
    return len(table)
