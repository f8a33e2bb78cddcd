"""GNSS logs of the antenna (:class:`ins.io.gnss_log.GnssLog`): the KF-GINS text layout
(reader and writer) and :func:`read_gnss`, which also reads RTKLIB ``.pos`` solutions (:mod:`ins.io.rtklib`,
detected from the file's header).

KF-GINS text layout: one epoch a line, whitespace- or comma-separated, ``#``/``%`` comment lines skipped::

    time_s  lat_deg  lon_deg  h_m  std_n_m  std_e_m  std_d_m  [vn ve vd  std_vn std_ve std_vd]

Position of the antenna phase centre (WGS84 latitude, longitude in deg, ellipsoidal
height in m) with its standard deviations north, east, down (m); optionally the antenna
velocity NED (m/s) and its standard deviations (m/s).  Time in s on the IMU's time
scale (GPS seconds of week).

Formats (``format`` of :func:`read_gnss`): ``"kfgins"`` (above), ``"rtklib"`` (an RTKLIB
``.pos`` solution in any of its layouts, :mod:`ins.io.rtklib`), ``"ubx"`` (a u-blox
receiver's own NAV-PVT solutions in a UBX log) and ``"nmea"`` (GGA/RMC/GST sentences),
:mod:`ins.io.ublox`; ``None`` (sniffed: a ``.pos`` extension, or a ``%`` header naming a
GPST/UTC/JST time column, means RTKLIB; a ``.ubx`` extension or the UBX sync characters
UBX; NMEA sentences in the first lines NMEA).
"""
import os

import numpy as np

from ins.common import limits, textfiles, textformat, textrows
from ins.common.errors import InputError
from ins.common.fileio import atomic_open
from ins.io.gnss_log import GnssLog
from ins.nav.imu import MAX_TIME_S

_HINT = ("KF-GINS GNSS: time lat lon h std_n std_e std_d, optionally vn ve vd std_vn std_ve "
         "std_vd")


#: Accepted ``format`` values of :func:`read_gnss` (``None``: sniffed).
FORMATS = ("kfgins", "rtklib", "ubx", "nmea")


def sniff_format(path):
    """``"rtklib"`` for an RTKLIB ``.pos`` solution (the extension ``.pos``, or a ``%``
    comment header naming the GPST/UTC/JST time column in its first 64 lines), else
    ``"kfgins"``."""
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext == ".pos":
        return "rtklib"
    if ext == ".ubx":
        return "ubx"
    try:
        with open(path, "rb") as f:
            if f.read(2) == b"\xb5\x62":
                return "ubx"
    except OSError:
        pass
    from ins.io.rtklib import looks_like_pos
    from ins.io.ublox import looks_like_nmea
    if looks_like_pos(path):
        return "rtklib"
    return "nmea" if looks_like_nmea(path) else "kfgins"


def read_gnss(path, format=None, time_shift_s=0.0, quality=None, quality_scale=None,
              velocity_time_shift_s=None, geoid=None):
    """Read a GNSS log of the antenna: KF-GINS text or an RTKLIB ``.pos`` solution.

    Parameters
    ----------
    path : str or os.PathLike
    format : {None, "kfgins", "rtklib", "ubx", "nmea"}
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
    velocity_time_shift_s : float, optional
        Added to the epochs of the velocities instead (s), when they are stamped
        differently from the positions (:meth:`GnssLog.shifted`: the log then has its
        own ``vel_time``); ``None`` (default): ``time_shift_s`` for both.
    geoid : str, optional
        RTKLIB, NMEA: the geoid model of heights above the geoid (RTKLIB's geodetic
        heights, a GGA without the geoid separation), converted to ellipsoidal
        (:func:`ins.io.rtklib.read_pos`, :func:`ins.io.ublox.read_nmea`).

    Returns
    -------
    GnssLog

    Raises
    ------
    InputError
        Naming the file and line (see :func:`read_kfgins_gnss` and
        :func:`ins.io.rtklib.read_pos`); a quality policy for a file without quality flags.
    """
    fmt = sniff_format(path) if format is None else format
    if fmt == "rtklib":
        from ins.io.gnss_quality import apply_quality
        from ins.io.rtklib import read_pos
        log = apply_quality(read_pos(path, geoid=geoid), quality, quality_scale)
    elif fmt in ("ubx", "nmea"):
        from ins.io.gnss_quality import apply_quality
        from ins.io.ublox import read_nav_pvt, read_nmea
        log = read_nav_pvt(path) if fmt == "ubx" else read_nmea(path, geoid=geoid)
        log = apply_quality(log, quality, quality_scale)
    elif fmt == "kfgins":
        if quality is not None or quality_scale:
            raise InputError("a GNSS quality policy (quality, quality_scale) needs quality "
                             "flags: only RTKLIB .pos solutions have them (Q column)",
                             path=os.fspath(path))
        log = read_kfgins_gnss(path)
    else:
        raise ValueError(f"format must be one of {', '.join(FORMATS)} or None, got {format!r}")
    return log.shifted(time_shift_s, velocity_time_shift_s)


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
    L = limits
    textrows.check_ranges(rows, row_line, path_s, [
        (0, -MAX_TIME_S, MAX_TIME_S, "time_s", "s"), (2, -180.0, 360.0, "lon_deg", "deg"),
        (3, L.MIN_HEIGHT_M, L.MAX_HEIGHT_M, "h_m", "m")]
        + [(c, -np.inf, L.MAX_SIGMA_M, f"std_{a}_m", "m") for c, a in zip((4, 5, 6), "ned")]
        + ([(c, -L.MAX_SPEED_MPS, L.MAX_SPEED_MPS, f"v{a}_mps", "m/s")
            for c, a in zip((7, 8, 9), "ned")]
           + [(c, -np.inf, L.MAX_SPEED_MPS, f"std_v{a}_mps", "m/s")
              for c, a in zip((10, 11, 12), "ned")] if ncols == 13 else []))
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
    atomically.  Returns the number of records.  A log whose velocities have their own
    epochs (``vel_time``) is refused (ValueError): one epoch a line."""
    if log.has_velocity and log.vel_time is not None:
        raise ValueError("the GNSS log's velocities have their own epochs (vel_time): the "
                         "KF-GINS layout holds one epoch a line; not written")
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
