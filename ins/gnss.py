"""GNSS logs of the antenna: :class:`GnssLog`, the KF-GINS text layout (reader and writer)
and :func:`read_gnss`, which also reads RTKLIB ``.pos`` solutions (:mod:`ins.rtklib`,
detected from the file's header).

KF-GINS text layout: one epoch a line, whitespace- or comma-separated, ``#``/``%`` comment lines skipped::

    time_s  lat_deg  lon_deg  h_m  std_n_m  std_e_m  std_d_m  [vn ve vd  std_vn std_ve std_vd]

Position of the antenna phase centre (WGS84 latitude, longitude in deg, ellipsoidal
height in m) with its standard deviations north, east, down (m); optionally the antenna
velocity NED (m/s) and its standard deviations (m/s).  Time in s on the IMU's time
scale (GPS seconds of week).

Formats (``format`` of :func:`read_gnss`): ``"kfgins"`` (above), ``"rtklib"`` (an RTKLIB
``.pos`` solution in any of its layouts, :mod:`ins.rtklib`), ``None`` (sniffed: a
``.pos`` extension, or a ``%`` header naming a GPST/UTC/JST time column, means RTKLIB).
"""
import os
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
    cov_ned_m2 : ndarray, shape (n, 3, 3) or None
        Full position covariance in the n frame (north, east, down), m^2, when the
        source gives one (RTKLIB's sdne/sdeu/sdun); its diagonal is ``sigma_ned_m**2``.
    quality : ndarray, shape (n,) of int or None
        Solution quality flag of the source (RTKLIB Q: 1 fix, 2 float, 3 SBAS, 4 DGPS,
        5 single, 6 PPP), ``None`` when the source has none.
    """

    time: np.ndarray
    lla: np.ndarray
    sigma_ned_m: np.ndarray
    v_n: np.ndarray = None
    sigma_vel_ned_mps: np.ndarray = None
    line: np.ndarray = None
    path: str = None
    cov_ned_m2: np.ndarray = None
    quality: np.ndarray = None

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
                       take(self.sigma_vel_ned_mps), take(self.line), self.path,
                       take(self.cov_ned_m2), take(self.quality))

    def shifted(self, time_shift_s):
        """The same log with ``time_shift_s`` (s) added to every epoch (a clock offset
        between the GNSS time base and the IMU's; 0 gives the log itself)."""
        if not time_shift_s:
            return self
        from dataclasses import replace
        return replace(self, time=self.time + float(time_shift_s))


#: Accepted ``format`` values of :func:`read_gnss` (``None``: sniffed).
FORMATS = ("kfgins", "rtklib")


def sniff_format(path):
    """``"rtklib"`` for an RTKLIB ``.pos`` solution (the extension ``.pos``, or a ``%``
    comment header naming the GPST/UTC/JST time column in its first 64 lines), else
    ``"kfgins"``."""
    if os.path.splitext(os.fspath(path))[1].lower() == ".pos":
        return "rtklib"
    from .rtklib import looks_like_pos
    return "rtklib" if looks_like_pos(path) else "kfgins"


def read_gnss(path, format=None, time_shift_s=0.0, quality=None, quality_scale=None):
    """Read a GNSS log of the antenna: KF-GINS text or an RTKLIB ``.pos`` solution.

    Parameters
    ----------
    path : str or os.PathLike
    format : {None, "kfgins", "rtklib"}
        ``None`` sniffs it (:func:`sniff_format`).
    time_shift_s : float
        Added to every epoch (s) at read time: the offset of the GNSS clock against the
        IMU's (``t_imu = t_gnss + time_shift_s``).
    quality : iterable of str or int, optional
        RTKLIB only: the solution qualities kept (``"fix"``, ``"float"``, ``"sbas"``,
        ``"dgps"``, ``"single"``, ``"ppp"`` or Q numbers 1..6); the others are dropped.
        ``None`` keeps all.
    quality_scale : dict, optional
        RTKLIB only: a factor on the standard deviations per quality (``{"float": 3,
        "single": 10}``; the covariance is scaled by its square).

    Returns
    -------
    GnssLog

    Raises
    ------
    InputError
        Naming the file and line (see :func:`read_kfgins_gnss` and
        :func:`ins.rtklib.read_pos`); a quality policy for a file without quality flags.
    """
    fmt = sniff_format(path) if format is None else format
    if fmt == "rtklib":
        from .rtklib import apply_quality, read_pos
        log = apply_quality(read_pos(path), quality, quality_scale)
    elif fmt == "kfgins":
        if quality is not None or quality_scale:
            raise InputError("a GNSS quality policy (quality, quality_scale) needs quality "
                             "flags: only RTKLIB .pos solutions have them (Q column)",
                             path=os.fspath(path))
        log = read_kfgins_gnss(path)
    else:
        raise ValueError(f"format must be one of {', '.join(FORMATS)} or None, got {format!r}")
    return log.shifted(time_shift_s)


def read_kfgins_gnss(path):
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
