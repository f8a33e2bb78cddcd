"""RTKLIB ``.pos`` solutions (rtkpost, rnx2rtkp, rtknavi) read into a :class:`~ins.io.gnss_log.GnssLog`.

Layout (RTKLIB 2.4 ``outsolheads``/``outsols``): ``%`` comment lines, the last of which
names the columns, then one epoch a line, fields separated by blanks (or the separator
the user chose, e.g. a comma)::

    %  GPST          latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m) ...
    2086 259200.000   35.123456789  139.123456789    50.1234   1   8   0.0030   0.0020 ...

Every variant RTKLIB writes is read; the column header decides:

=============  =====================================================================
time           ``GPST``, ``UTC`` or ``JST`` (the header's first word); either GPS week
               and seconds of week (``2086 259200.000``) or ``yyyy/mm/dd hh:mm:ss.sss``
position       ``latitude(deg) longitude(deg) height(m)``; ``latitude(d'")
               longitude(d'")`` (degrees, minutes, seconds as three fields, the sign on
               the degrees: ``-35 07 24.44444``); ``x-ecef(m) y-ecef(m) z-ecef(m)``
               (WGS84); ``e-baseline(m) n-baseline(m) u-baseline(m)`` (from the base
               in the ``% ref pos :`` header line, lat lon deg h m, or ``ref_lla_deg``)
quality        ``Q`` (1 fix, 2 float, 3 SBAS, 4 DGPS, 5 single, 6 PPP), ``ns`` satellites
sigma          ``sdn sde sdu sdne sdeu sdun`` (llh, in the local ENU frame), ``sdx sdy
               sdz sdxy sdyz sdzx`` (ECEF), ``sde sdn sdu sden sdnu sdue`` (ENU); the
               off-diagonal columns are RTKLIB's signed square roots of the covariance,
               ``sign(c) sqrt(|c|)``, so ``c = s |s|``
other          ``age(s)``, ``ratio``; velocity ``vn ve vu`` (m/s, ENU) with ``sdvn sdve
               sdvu sdvne sdveu sdvun``, or ``vx vy vz`` (ECEF) with ``sdvx ... sdvzx``
=============  =====================================================================

Conversions (into the conventions of :mod:`ins.io.gnss`):

- time: GPS time, as seconds of the GPS week of the first epoch (continuous across a
  week's end: 604800 s is added rather than wrapping); a file whose epochs all run
  backwards (RTKLIB's backward solution) is read in time order; UTC is turned into GPS time with
  the leap seconds of its date (:data:`LEAP_SECONDS`, GPS - UTC = 18 s since 2017), JST
  is UTC + 9 h.  RTKLIB's headers do not state the leap seconds: the table does.
- position: WGS84 latitude, longitude (rad) and ellipsoidal height (m).  A header stating
  geodetic (geoid) heights, ``height=WGS84/geodetic``, has them converted back:
  ``h = H + N`` with N of the geoid model named by ``geoid`` (EGM96, EGM2008:
  :mod:`ins.io.geoid`).  RTKLIB's header does not say which model it used (its
  ``out-geoid`` option: internal, EGM96, EGM2008 ...); unnamed, EGM96 is taken (the
  model of RTKLIB's internal 1x1 deg table), with an
  :class:`~ins.common.errors.InputWarning` saying so; with no EGM96 grid installed the
  heights stay as they are, with a warning.  The Tokyo datum is refused.
- covariance: first screened (:mod:`ins.io.pos_screen`: a matrix that no rounding of a
  covariance prints is repaired or the record dropped, a sigma out of all proportion to
  those of its quality drops the record; counted in ``GnssLog.screen`` and reported by
  an :class:`~ins.common.errors.InputWarning` naming the file and lines), then the full
  3x3 covariance rotated into NED (``cov_ned_m2``; ECEF through ``C_ne``, ENU by swapping
  N and E and negating D); ``sigma_ned_m`` is the square root of its diagonal.  Values printed as 0.0000 (below RTKLIB's 0.1 mm resolution) are
  raised to :data:`SIGMA_FLOOR_M`, and a covariance made indefinite by the rounding of
  the printed roots has its eigenvalues raised to ``SIGMA_FLOOR_M**2``.
- velocity: into NED (``v_n``), its sigmas from the velocity covariance's diagonal.

The quality policy (:func:`apply_quality`) keeps some Q values and scales the sigmas of
others.  Errors name the file and the line.

:func:`write_pos` writes a :class:`~ins.io.gnss_log.GnssLog` in the llh layout (GPST week and
seconds of week, the full covariance as RTKLIB's signed roots; 12 decimals in the
degrees and 9 in the sigmas instead of RTKLIB's 9 and 4, so that nothing is lost):
``ins import-bag`` uses it to keep a NavSatFix covariance.
"""
import os
import re
import warnings

import numpy as np

from ins.common import limits, textfiles, textparse, textrows
from ins.common.errors import InputError, InputWarning
from ins.io.gnss_log import GnssLog
from ins.io.gnss_quality import QUALITY_NAME
from ins.io.pos_screen import screen

__all__ = ["read_pos", "write_pos", "looks_like_pos", "LEAP_SECONDS", "SIGMA_FLOOR_M",
           "utc_to_gps_seconds", "gps_to_utc_seconds"]


#: Smallest standard deviation kept, m (RTKLIB prints 4 decimals: 0.0000 is below 0.05 mm).
SIGMA_FLOOR_M = 1e-4

#: GPS - UTC (s) from each UTC date on (year, month, day): the leap seconds since the GPS
#: epoch 1980-01-06 (IERS Bulletin C; none announced after 2017-01-01).
LEAP_SECONDS = ((1981, 7, 1, 1), (1982, 7, 1, 2), (1983, 7, 1, 3), (1985, 7, 1, 4),
                (1988, 1, 1, 5), (1990, 1, 1, 6), (1991, 1, 1, 7), (1992, 7, 1, 8),
                (1993, 7, 1, 9), (1994, 7, 1, 10), (1996, 1, 1, 11), (1997, 7, 1, 12),
                (1999, 1, 1, 13), (2006, 1, 1, 14), (2009, 1, 1, 15), (2012, 7, 1, 16),
                (2015, 7, 1, 17), (2017, 1, 1, 18))

_WEEK_S = 604800
_TIME_NAMES = ("GPST", "UTC", "JST")
# column header words (lower case, unit dropped) -> (role, number of numeric fields)
_POSITION = {
    "llh": ("latitude", "longitude", "height"),
    "xyz": ("x-ecef", "y-ecef", "z-ecef"),
    "enu": ("e-baseline", "n-baseline", "u-baseline"),
}
_SIGMA = {
    # names of the six sigma columns in file order -> (i, j) of the covariance in the
    # position layout's own axes (llh: ENU, xyz: ECEF, enu: ENU)
    "llh": (("sdn", (1, 1)), ("sde", (0, 0)), ("sdu", (2, 2)), ("sdne", (1, 0)),
            ("sdeu", (0, 2)), ("sdun", (2, 1))),
    "xyz": (("sdx", (0, 0)), ("sdy", (1, 1)), ("sdz", (2, 2)), ("sdxy", (0, 1)),
            ("sdyz", (1, 2)), ("sdzx", (2, 0))),
    "enu": (("sde", (0, 0)), ("sdn", (1, 1)), ("sdu", (2, 2)), ("sden", (0, 1)),
            ("sdnu", (1, 2)), ("sdue", (2, 0))),
}
_VEL = {
    "llh": (("vn", "ve", "vu"), (("sdvn", (1, 1)), ("sdve", (0, 0)), ("sdvu", (2, 2)),
                                 ("sdvne", (1, 0)), ("sdveu", (0, 2)), ("sdvun", (2, 1)))),
    "xyz": (("vx", "vy", "vz"), (("sdvx", (0, 0)), ("sdvy", (1, 1)), ("sdvz", (2, 2)),
                                 ("sdvxy", (0, 1)), ("sdvyz", (1, 2)), ("sdvzx", (2, 0)))),
}
# ENU (x east, y north, z up) -> NED
_C_NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def _word(name):
    """A header word without its unit, lower case: ``sdn(m)`` -> ``sdn``."""
    return name.split("(")[0].strip().lower()


def _header_lines(path, max_lines=64):
    """The leading comment lines (``%``/``#``) of the file, as (line number, text), and
    the first data line (or None)."""
    head = []
    first = None
    with open(path, "rb") as f:
        for k, raw in enumerate(f, start=1):
            text = raw.decode("utf-8", errors="replace").strip()
            if not text:
                continue
            if text[0] in "%#":
                head.append((k, text))
                continue
            first = (k, text)
            break
    return head, first


def looks_like_pos(path):
    """True when the file starts with RTKLIB's ``%`` header naming a GPST/UTC/JST time
    column (within its first 64 lines)."""
    try:
        with open(path, "rb") as f:
            for k, raw in enumerate(f):
                if k >= 64:
                    return False
                text = raw.decode("utf-8", errors="replace").strip()
                if not text:
                    continue
                if text[0] != "%":
                    return False
                words = text[1:].split()
                if words and words[0] in _TIME_NAMES and len(words) > 3:
                    return True
    except OSError:
        return False
    return False


class _Layout:
    """What the column header says: time system, position layout, column indices."""

    def __init__(self, path, head):
        self.path = path
        self.time_system = None
        self.position = None
        self.height = "ellipsoidal"
        self.datum = "WGS84"
        self.ref_lla_deg = None
        self.columns = None            # [(word, width)] after the time fields
        self.header_line = None
        for line, text in head:
            body = text[1:].strip()
            m = re.match(r"\((?:lat/lon/height=(\w+)/(\w+))", body)
            if m:
                self.datum, self.height = m.group(1), m.group(2)
            if body.lower().startswith("ref pos"):
                self.ref_lla_deg = self._ref_pos(body, line)
            words = body.replace(",", " ").split()
            if words and words[0] in _TIME_NAMES and len(words) > 3:
                self.time_system = words[0]
                self.header_line = line
                self.columns = self._columns(words[1:], line)
        if self.columns is None:
            raise InputError("not an RTKLIB .pos solution: no '%  GPST|UTC|JST ...' column "
                             "header line among the leading comment lines", path=path)
        if self.datum.upper() != "WGS84":
            raise InputError(f"datum {self.datum}: only WGS84 solutions are read (set the "
                             f"RTKLIB output datum to WGS84)", path=path)

    def _ref_pos(self, body, line):
        text = body.split(":", 1)[1] if ":" in body else ""
        try:
            v = [float(x) for x in text.replace(",", " ").split()]
        except ValueError:
            return None
        if len(v) == 3 and abs(v[0]) <= 90:             # lat lon (deg) h
            return np.array(v)
        if len(v) == 7:                                 # d m s d m s h
            return np.array([_dms(*v[0:3], negative=text.split()[0].startswith("-")),
                             _dms(*v[3:6], negative=text.split()[3].startswith("-")), v[6]])
        if len(v) == 3:                                 # ECEF (m)
            import pymap3d
            lat, lon, h = pymap3d.ecef2geodetic(*v)
            return np.array([lat, lon, h])
        return None

    def _columns(self, words, line):
        names = [_word(w) for w in words]
        for kind, triple in _POSITION.items():
            if names[:3] == list(triple):
                self.position = kind
                break
        else:
            raise InputError(f"RTKLIB column header: the position columns {' '.join(words[:3])!r} "
                             f"are not latitude/longitude/height, x/y/z-ecef or "
                             f"e/n/u-baseline", path=self.path, line=line)
        dms = self.position == "llh" and "d'" in words[0]
        cols = []
        for k, name in enumerate(names):
            if name == "sdue" and self.position == "llh":
                name = "sdun"          # RTKLIB's d'" header names the 6th sigma sdue
            cols.append((name, 3 if dms and k < 2 else 1))
        self.dms = dms
        return cols

    def index(self):
        """Word -> first numeric field index (after the time fields)."""
        out, k = {}, 0
        for name, width in self.columns:
            out.setdefault(name, k)
            k += width
        return out, k


def _dms(d, m, s, negative=False):
    value = abs(d) + m / 60.0 + s / 3600.0
    return -value if negative else value


def _days_from_civil(y, m, d):
    """Days since 1970-01-01 of the Gregorian dates (vectorized, H. Hinnant's rule)."""
    y = y - (m <= 2)
    era = np.floor_divide(y, 400)
    yoe = y - era * 400
    mp = (m + 9) % 12
    doy = (153 * mp + 2) // 5 + d - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return era * 146097 + doe - 719468


_GPS_EPOCH_DAYS = 3657         # 1980-01-06 in days since 1970-01-01


def _leap_seconds(utc_s):
    """GPS - UTC (s) at UTC seconds since the GPS epoch (int64 array)."""
    starts = np.array([(_days_from_civil(np.int64(y), np.int64(m), np.int64(d))
                        - _GPS_EPOCH_DAYS) * 86400 for y, m, d, _ in LEAP_SECONDS])
    values = np.array([0] + [v for *_, v in LEAP_SECONDS])
    return values[np.searchsorted(starts, utc_s, side="right")]


def utc_to_gps_seconds(utc_s):
    """GPS seconds since the GPS epoch (1980-01-06) of UTC seconds since that epoch
    (integer arrays): ``utc_s + (GPS - UTC)`` with the leap seconds of the date."""
    utc_s = np.asarray(utc_s, np.int64)
    return utc_s + _leap_seconds(utc_s)


def gps_to_utc_seconds(gps_s):
    """UTC seconds since the GPS epoch of GPS seconds since that epoch (integer arrays):
    ``gps_s - (GPS - UTC)`` with the leap seconds of the date (the inverse of
    :func:`utc_to_gps_seconds`; a GPS second inside an inserted leap second maps to the
    UTC second before it)."""
    gps_s = np.asarray(gps_s, np.int64)
    utc = gps_s - _leap_seconds(gps_s)
    return gps_s - _leap_seconds(utc)


def _gps_time(time_fields, date_format, system):
    """(integer seconds since the GPS epoch, fractional seconds) in GPS time."""
    if date_format:
        y, mo, d, hh, mi = (np.rint(time_fields[:, k]).astype(np.int64) for k in range(5))
        whole = (_days_from_civil(y, mo, d) - _GPS_EPOCH_DAYS) * 86400 + hh * 3600 + mi * 60
        frac = time_fields[:, 5]
    else:
        week = np.rint(time_fields[:, 0]).astype(np.int64)
        whole = week * _WEEK_S
        frac = time_fields[:, 1]
    if system == "JST":
        whole = whole - 9 * 3600
    if system in ("UTC", "JST"):
        whole = whole + _leap_seconds(whole + np.floor(frac).astype(np.int64))
    return whole, frac


#: First GPS week not accepted (the year 2171): a larger week is a corrupted field, whose
#: conversion to integer seconds would overflow.
MAX_GPS_WEEK = 10000


def _check_time_fields(tf, date_format, row_line, path):
    if date_format:
        checks = ((0, 1980, 2199, "year"), (1, 1, 12, "month"), (2, 1, 31, "day"),
                  (3, 0, 23, "hour"), (4, 0, 59, "minute"), (5, 0, 61, "second"))
        for col, lo, hi, what in checks:
            bad = np.flatnonzero(~((tf[:, col] >= lo) & (tf[:, col] < hi + 1)))
            if bad.size:
                k = bad[0]
                raise InputError(f"{what} {float(tf[k, col]):g} is not a valid time (expected "
                                 f"yyyy/mm/dd hh:mm:ss.sss)", path=path, line=int(row_line[k]))
    else:
        bad = np.flatnonzero(~((tf[:, 1] >= 0) & (tf[:, 1] < _WEEK_S + 1) & (tf[:, 0] >= 0)
                               & (tf[:, 0] < MAX_GPS_WEEK)))
        if bad.size:
            k = bad[0]
            raise InputError(f"GPS week {float(tf[k, 0]):g}, seconds of week {float(tf[k, 1])!r}: expected "
                             f"0 <= week < {MAX_GPS_WEEK} and 0 <= tow < 604800 s", path=path,
                             line=int(row_line[k]))


def _signed_var(s):
    """RTKLIB's signed root back to the (co)variance: ``c = s |s|``."""
    return s * np.abs(s)


def _covariance(values, index, layout_names, path, row_line):
    n = values.shape[0]
    cov = np.zeros((n, 3, 3))
    for name, (i, j) in layout_names:
        if name not in index:
            raise InputError(f"RTKLIB column header has no {name} column", path=path)
        raw = values[:, index[name]]
        big = np.flatnonzero(np.abs(raw) > limits.MAX_SIGMA_M)
        if big.size:
            raise InputError(f"{name} = {float(raw[big[0]]):g}: beyond +-{limits.MAX_SIGMA_M:g} "
                             f"(m or m/s)", path=path, line=int(row_line[big[0]]))
        c = _signed_var(raw)
        cov[:, i, j] = c
        cov[:, j, i] = c
    diag = np.einsum("nii->ni", cov)
    bad = np.argwhere(diag < 0)
    if bad.size:
        k = bad[0, 0]
        raise InputError("negative standard deviation", path=path, line=int(row_line[k]))
    return cov


def _floor_psd(cov):
    """Raise the variances to SIGMA_FLOOR_M**2 and make the matrices positive definite
    (eigenvalues at least SIGMA_FLOOR_M**2) where the rounding broke it (found by the
    leading minors; only those rows are decomposed)."""
    f2 = SIGMA_FLOOR_M ** 2
    idx = np.arange(3)
    cov = cov.copy()
    cov[:, idx, idx] = np.maximum(cov[:, idx, idx], f2)
    a, b, c = cov[:, 0, 0], cov[:, 1, 1], cov[:, 2, 2]
    d, e, f = cov[:, 0, 1], cov[:, 1, 2], cov[:, 0, 2]
    m2 = a * b - d * d
    m3 = a * (b * c - e * e) - d * (d * c - e * f) + f * (d * e - b * f)
    scale = (a * b * c)
    bad = np.flatnonzero((m2 <= 1e-9 * a * b) | (m3 <= 1e-9 * scale))
    if bad.size:
        w, v = np.linalg.eigh(cov[bad])
        w = np.maximum(w, f2)
        cov[bad] = np.einsum("nij,nj,nkj->nik", v, w, v)
    return cov


def _rotate(C, cov):
    """``C cov C^T`` for a (3, 3) or (n, 3, 3) ``C`` (ENU -> NED by indexing)."""
    if C is _C_NED_ENU:
        sign = np.array([1.0, 1.0, -1.0])
        return cov[:, [1, 0, 2]][:, :, [1, 0, 2]] * np.outer(sign, sign)
    return np.matmul(np.matmul(C, cov), np.swapaxes(C, -1, -2))


def _parse(path):
    """(layout, numeric rows, row_line, date_format) of a .pos file."""
    path_s = os.fspath(path)
    head, first = _header_lines(path_s)
    layout = _Layout(path_s, head)
    if first is None:
        raise InputError("no solution lines after the header", path=path_s)
    date_format = "/" in first[1].split()[0]
    ntime = 6 if date_format else 2
    index, nfields = layout.index()
    buf = textfiles.file_buffer(path_s)
    if date_format:                           # the date's separators into blanks
        data = buf[:-1]
        data[(data == ord("/")) | (data == ord(":"))] = ord(" ")
    ncols = ntime + nfields
    res = textparse.parse_table(buf, ncols, ncols)
    if res.status != textparse.OK:
        names = (["year", "month", "day", "hour", "minute", "second"] if date_format
                 else ["week", "tow"])
        for name, width in layout.columns:
            names += [name] * width
        msg = textparse.table_error_message(res, buf, ncols, ncols, names)
        if res.status in (textparse.TOO_FEW_COLUMNS, textparse.TOO_MANY_COLUMNS,
                          textparse.COLUMN_COUNT):
            msg += (f" (RTKLIB .pos: the column header on line {layout.header_line} names "
                    f"{ncols} fields with the {'date' if date_format else 'week/tow'} time)")
        raise InputError(msg, path=path_s, line=res.err_line or None)
    del buf
    return layout, res.values, res.row_line, date_format, ntime, index


def read_pos(path, ref_lla_deg=None, screen_covariance=True, geoid=None):
    """Read an RTKLIB ``.pos`` solution (module notes) into a :class:`~ins.io.gnss_log.GnssLog`.

    Parameters
    ----------
    path : str or os.PathLike
    ref_lla_deg : array_like, shape (3,), optional
        Base position (lat, lon deg, ellipsoidal h m) for an ENU-baseline solution whose
        header has no ``% ref pos :`` line.
    screen_covariance : bool
        Screen the position covariances (module notes; :mod:`ins.io.pos_screen`).
    geoid : str, optional
        The geoid model of a solution written with geodetic heights (``"EGM96"``,
        ``"EGM2008"``): they are converted to ellipsoidal, ``h = H + N``.  None: EGM96,
        with a warning (module notes).  Ignored for ellipsoidal heights.

    Returns
    -------
    GnssLog
        With ``cov_ned_m2`` (full covariance), ``quality`` (Q) and ``screen`` (what the
        covariance screen repaired and dropped), and the velocity when the file has
        velocity columns.

    Raises
    ------
    InputError
        Naming the file and line: no column header, unknown position columns, a line
        with another number of fields, text in a number, an invalid date or week/tow,
        time not strictly increasing, a latitude beyond +-90 deg, an unknown Q, a
        negative standard deviation, an ENU solution without a base position.
    """
    path_s = os.fspath(path)
    layout, rows, row_line, date_format, ntime, index = _parse(path_s)
    nonfinite = np.flatnonzero(~np.all(np.isfinite(rows), axis=1))
    if nonfinite.size:
        raise InputError("non-finite value", path=path_s, line=int(row_line[nonfinite[0]]))
    tf = rows[:, :ntime]
    vals = rows[:, ntime:]
    _check_time_fields(tf, date_format, row_line, path_s)
    whole, frac = _gps_time(tf, date_format, layout.time_system)
    week0 = int(np.floor_divide(whole[0] + np.floor(frac[0]).astype(np.int64), _WEEK_S))
    time = (whole - week0 * _WEEK_S).astype(np.float64) + frac
    if time.size > 1 and np.all(np.diff(time) < 0):    # a backward solution: newest first
        time, vals, row_line = time[::-1], vals[::-1], np.asarray(row_line)[::-1]
    back = np.flatnonzero(np.diff(time) <= 0)
    if back.size:
        k = back[0] + 1
        what = "duplicated epoch" if time[k] == time[k - 1] else "time not increasing"
        raise InputError(f"{what}: t = {float(time[k])!r} s after {float(time[k - 1])!r} s (GPS seconds "
                         f"of week {week0})", path=path_s, line=int(row_line[k]))
    q = vals[:, index["q"]] if "q" in index else None
    if q is None:
        raise InputError("RTKLIB column header has no Q column", path=path_s,
                         line=layout.header_line)
    bad_q = np.flatnonzero(~np.isin(q, list(QUALITY_NAME)))
    if bad_q.size:
        k = bad_q[0]
        raise InputError(f"Q = {float(q[k]):g}: expected 1 (fix), 2 (float), 3 (sbas), 4 (dgps), "
                         f"5 (single) or 6 (ppp)", path=path_s, line=int(row_line[k]))
    lla, C_n_layout = _position(layout, vals, index, path_s, row_line, ref_lla_deg, geoid)
    cov = _covariance(vals, index, _SIGMA[layout.position], path_s, row_line)
    keep = report = None
    if screen_covariance:
        cov, keep, report = screen(cov, q, row_line)
        if report:
            warnings.warn(report.message(path_s), InputWarning, stacklevel=2)
    cov_ned = _floor_psd(_rotate(C_n_layout, cov))
    sigma = np.sqrt(np.einsum("nii->ni", cov_ned))
    v_n = sigma_v = None
    if layout.position in _VEL and _VEL[layout.position][0][0] in index:
        names, sig = _VEL[layout.position]
        v = vals[:, [index[nm] for nm in names]]
        cov_v = _covariance(vals, index, sig, path_s, row_line)
        if layout.position == "xyz":                     # ECEF -> NED
            v_n = np.einsum("nij,nj->ni", C_n_layout, v)
        else:                                            # vn ve vu -> NED
            v_n = np.column_stack([v[:, 0], v[:, 1], -v[:, 2]])
        cov_v = _floor_psd(_rotate(C_n_layout, cov_v))
        sigma_v = np.sqrt(np.einsum("nii->ni", cov_v))
    _check_plausible(lla, sigma, v_n, sigma_v, path_s, row_line)
    log = GnssLog(time, lla, sigma, v_n, sigma_v, np.asarray(row_line, np.int64), path_s,
                  cov_ned, q.astype(np.int64), screen=report)
    if keep is not None and not keep.all():
        log = log.select(keep)
        if len(log) == 0:
            raise InputError("no record left after the covariance screen (every record's "
                             "sigma columns invalid)", path=path_s)
    return log


def _check_plausible(lla, sigma, v_n, sigma_v, path, row_line):
    """Heights, sigmas and velocities (whatever the layout) within :mod:`ins.common.limits`,
    else an InputError naming the line."""
    L = limits
    cols = [np.rad2deg(lla[:, 1]), lla[:, 2], *sigma.T]
    ranges = [(0, -180.0, 360.0, "longitude", "deg"), (1, L.MIN_HEIGHT_M, L.MAX_HEIGHT_M,
                                                        "height", "m")]
    ranges += [(2 + j, 0.0, L.MAX_SIGMA_M, f"sd{a} (NED)", "m") for j, a in enumerate("ned")]
    if v_n is not None:
        cols += [*v_n.T, *sigma_v.T]
        ranges += [(5 + j, -L.MAX_SPEED_MPS, L.MAX_SPEED_MPS, f"v{a}", "m/s")
                   for j, a in enumerate("ned")]
        ranges += [(8 + j, 0.0, L.MAX_SPEED_MPS, f"sdv{a} (NED)", "m/s")
                   for j, a in enumerate("ned")]
    with np.errstate(invalid="ignore"):
        textrows.check_ranges(np.column_stack(cols), row_line, path, ranges)


def _position(layout, vals, index, path, row_line, ref_lla_deg, geoid=None):
    """(lla rad/m, C taking the sigma layout's axes into NED) per row."""
    if layout.position == "llh":
        if layout.dms:
            neg_lat = np.signbit(vals[:, 0])
            neg_lon = np.signbit(vals[:, 3])
            lat = np.abs(vals[:, 0]) + vals[:, 1] / 60.0 + vals[:, 2] / 3600.0
            lon = np.abs(vals[:, 3]) + vals[:, 4] / 60.0 + vals[:, 5] / 3600.0
            lat = np.where(neg_lat, -lat, lat)
            lon = np.where(neg_lon, -lon, lon)
            h = vals[:, index["height"]]
        else:
            lat, lon, h = vals[:, 0], vals[:, 1], vals[:, index["height"]]
        bad = np.flatnonzero(np.abs(lat) > 90.0)
        if bad.size:
            k = bad[0]
            raise InputError(f"latitude {float(lat[k])!r} deg outside +-90 deg", path=path,
                             line=int(row_line[k]))
        lla = np.column_stack([np.deg2rad(lat), np.deg2rad(lon), h])
        if layout.height.lower() != "ellipsoidal":
            from ins.io.geoid import ellipsoidal_from_geodetic
            lla[:, 2] = ellipsoidal_from_geodetic(lla, geoid, path, f"RTKLIB heights are "
                                                  f"{layout.height} (above the geoid)")
        return lla, _C_NED_ENU
    if layout.position == "xyz":
        import pymap3d
        xyz = vals[:, :3]
        lat, lon, h = pymap3d.ecef2geodetic(xyz[:, 0], xyz[:, 1], xyz[:, 2], deg=False)
        lla = np.column_stack([lat, lon, h])
        from ins.nav.earth import dcm_en
        C_ne = np.swapaxes(dcm_en(lat, lon), 1, 2)
        return lla, C_ne
    ref = layout.ref_lla_deg if ref_lla_deg is None else np.asarray(ref_lla_deg, float)
    if ref is None:
        raise InputError("an ENU-baseline solution needs the base position: the header has "
                         "no '% ref pos :' line (give ref_lla_deg = lat, lon deg, h m)",
                         path=path)
    import pymap3d
    enu = vals[:, :3]
    lat, lon, h = pymap3d.enu2geodetic(enu[:, 0], enu[:, 1], enu[:, 2], ref[0], ref[1], ref[2],
                                       deg=True)
    lla = np.column_stack([np.deg2rad(lat), np.deg2rad(lon), h])
    return lla, _C_NED_ENU


_POS_HEADER = ("% (lat/lon/height=WGS84/ellipsoidal,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,"
               "ns=# of satellites)\n"
               "%  GPST                  latitude(deg)    longitude(deg)  height(m)   Q  ns"
               "     sdn(m)     sde(m)     sdu(m)    sdne(m)    sdeu(m)    sdun(m) age(s)  ratio\n")


def write_pos(path, log, week, comments=()):
    """Write ``log`` as an RTKLIB ``.pos`` (llh, GPST week/tow; module notes), atomically.

    ``log.time`` is taken as GPS seconds of ``week`` (values of 604800 s and more go to
    the next weeks); the quality is ``log.quality`` (5, single, when None); ``ns`` is
    written 0 (unknown) and age, ratio 0.  Returns the number of records.
    """
    from ins.common.fileio import atomic_open
    n = len(log)
    cov = log.cov_ned_m2
    if cov is None:
        cov = np.zeros((n, 3, 3))
        idx = np.arange(3)
        cov[:, idx, idx] = log.sigma_ned_m ** 2
    root = lambda c: np.sign(c) * np.sqrt(np.abs(c))  # noqa: E731
    wk = week + np.floor_divide(log.time, _WEEK_S).astype(np.int64)
    tow = log.time - (wk - week) * _WEEK_S
    q = np.full(n, 5, np.int64) if log.quality is None else np.asarray(log.quality, np.int64)
    lat, lon = np.rad2deg(log.lla[:, 0]), np.rad2deg(log.lla[:, 1])
    # sdn sde sdu sdne sdeu sdun from the NED covariance (u = -d)
    cols = np.column_stack([np.sqrt(cov[:, 0, 0]), np.sqrt(cov[:, 1, 1]), np.sqrt(cov[:, 2, 2]),
                            root(cov[:, 0, 1]), root(-cov[:, 1, 2]), root(-cov[:, 2, 0])])
    lines = [f"{wk[k]:4d} {tow[k]:11.6f} {lat[k]:17.12f} {lon[k]:17.12f} {log.lla[k, 2]:10.5f} "
             f"{q[k]:3d}   0 " + " ".join(f"{v:12.9f}" for v in cols[k]) + "   0.00    0.0"
             for k in range(n)]
    head = "".join(f"% {c}\n" for c in comments) + _POS_HEADER
    with atomic_open(path, "wb") as f:
        f.write((head + "\n".join(lines) + ("\n" if lines else "")).encode())
    return n
