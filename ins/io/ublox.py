"""A u-blox receiver's own solution as a GNSS log (:class:`~ins.io.gnss_log.GnssLog`):
UBX NAV-PVT messages of a binary log, or NMEA GGA (+ RMC for the date, + GST for the
sigmas) of a text log.

Heights: a u-blox receiver reports the height above mean sea level (``hMSL`` of NAV-PVT,
the altitude of GGA) beside or instead of the ellipsoidal one; the toolkit's heights are
ellipsoidal, so

- NAV-PVT: ``height`` (above the ellipsoid, mm) is taken; ``hMSL`` only checks that the
  receiver's geoid separation ``height - hMSL`` is plausible (within 150 m);
- GGA: ``h = altitude + separation`` with the geoid separation of field 11 (the
  receiver's own geoid, u-blox: EGM96); a GGA without it gets ``h = altitude + N`` of
  the model named by ``geoid`` (:func:`ins.io.geoid.ellipsoidal_from_geodetic`; default
  EGM96, with a warning).

Time: GPS seconds of the week of the first epoch, continuous across a week's end.
NAV-PVT: ``iTOW`` (ms of the GPS week); the week from the UTC date when valid.  NMEA: UTC
time of day (GGA) on the date of the last RMC, to GPS with the leap seconds of that date;
a GGA before any RMC is an error naming the line.

Quality (RTKLIB's Q): NAV-PVT carrier solution fixed 1, float 2, differential 4, else 5
(single); epochs without gnssFixOK, with invalidLlh or a fix type other than 3D (3) or
GNSS + dead reckoning (4) are dropped.  GGA quality 4 (RTK fixed) 1, 5 (float) 2, 2
(DGPS) 4, 1 (GPS) 5; 0 and 6 (dead reckoning) dropped.

Sigmas: NAV-PVT ``hAcc`` / sqrt(2) north and east, ``vAcc`` down, ``sAcc`` per velocity
axis (u-blox's accuracy estimates); NMEA: the GST of the same second (latitude,
longitude, altitude error sigmas), else ``HDOP x`` :data:`NMEA_UERE_M` of the quality
horizontally and twice that vertically, stated in an :class:`InputWarning`.
"""
import os
import struct
import warnings

import numpy as np

from ins.common.errors import InputError, InputWarning
from ins.io.gnss_log import GnssLog

__all__ = ["read_nav_pvt", "read_nmea", "looks_like_nmea", "has_nav_pvt", "NMEA_UERE_M"]

_WEEK_S = 604800
_SYNC = b"\xb5\x62"
_NAV_PVT = b"\x01\x07"
_PVT_LEN = 92
#: Nominal 1-sigma range error (m) by GGA quality, scaled by HDOP when no GST is given.
NMEA_UERE_M = {4: 0.02, 5: 0.3, 2: 0.7, 1: 2.5}
_GGA_Q = {4: 1, 5: 2, 2: 4, 1: 5}


def ubx_checksum(body):
    """The UBX Fletcher-8 checksum (CK_A, CK_B) of ``body`` (class, id, length, payload)."""
    a = b = 0
    for byte in body:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return bytes((a, b))


def _frames(data, cls_id):
    """(offset, payload) of the checksummed UBX messages of class/id ``cls_id``."""
    k = data.find(_SYNC + cls_id)
    while 0 <= k and k + 8 <= len(data):
        length = struct.unpack_from("<H", data, k + 4)[0]
        end = k + 6 + length
        if end + 2 <= len(data) and data[end:end + 2] == ubx_checksum(data[k + 2:end]):
            yield k, data[k + 6:end]
            k = data.find(_SYNC + cls_id, end + 2)
        else:
            k = data.find(_SYNC + cls_id, k + 2)


def has_nav_pvt(path, limit_bytes=1 << 20):
    """Whether the first ``limit_bytes`` of ``path`` hold a checksummed NAV-PVT."""
    with open(path, "rb") as f:
        data = f.read(limit_bytes)
    return next(_frames(data, _NAV_PVT), None) is not None


def _gps_week_tow(year, month, day, hour, minute, second):
    """GPS week and seconds of week of a UTC date and time (integer arrays)."""
    from ins.io.rtklib import utc_to_gps_seconds
    days = (np.array([np.datetime64(f"{y:04d}-{m:02d}-{d:02d}") for y, m, d in
                      zip(year, month, day)], dtype="datetime64[D]")
            - np.datetime64("1980-01-06")).astype(np.int64)
    utc = days * 86400 + np.asarray(hour) * 3600 + np.asarray(minute) * 60 + np.asarray(second)
    gps = utc_to_gps_seconds(utc)
    return gps // _WEEK_S, gps % _WEEK_S


def read_nav_pvt(path):
    """Read the NAV-PVT messages of a UBX log (module notes); records = messages."""
    path_s = os.fspath(path)
    with open(path_s, "rb") as f:
        data = f.read()
    recs = []
    for n, (off, p) in enumerate(_frames(data, _NAV_PVT), start=1):
        if len(p) != _PVT_LEN:
            raise InputError(f"NAV-PVT of {len(p)} bytes (expected {_PVT_LEN}: UBX protocol "
                             "15 or later)", path=path_s, record=n)
        (itow, year, month, day, hour, minute, sec, valid, _tacc, _nano, fix, flags, _f2,
         nsv, lon, lat, height, hmsl, hacc, vacc, vn, ve, vd, _gs, _hm, sacc, _ha, _pdop,
         flags3) = struct.unpack_from("<IHBBBBBBIiBBBBiiiiIIiiiiiIIHH", p, 0)
        recs.append((n, itow, year, month, day, hour, minute, sec, valid, fix, flags, lon,
                     lat, height, hmsl, hacc, vacc, vn, ve, vd, sacc, flags3))
    if not recs:
        raise InputError("no NAV-PVT message (UBX class 0x01 id 0x07) in the log: enable "
                         "it on the receiver, or give its raw observations with --rover",
                         path=path_s)
    r = np.array(recs, dtype=np.int64)
    ok = ((r[:, 10] & 1) == 1) & np.isin(r[:, 9], (3, 4)) & ((r[:, 21] & 1) == 0)
    if not np.any(ok):
        raise InputError(f"none of the {len(r)} NAV-PVT epochs has a valid 3-D fix "
                         "(gnssFixOK, fix type 3 or 4)", path=path_s)
    r = r[ok]
    sep = (r[:, 13] - r[:, 14]) / 1000.0
    bad = np.flatnonzero(np.abs(sep) > 150.0)
    if bad.size:
        raise InputError(f"height - hMSL = {sep[bad[0]]:.3f} m: not a geoid separation "
                         "(|N| < 150 m); the heights are not what NAV-PVT defines",
                         path=path_s, record=int(r[bad[0], 0]))
    tow = r[:, 1] / 1000.0
    valid_date = (r[:, 8] & 3) == 3
    if np.any(valid_date):
        i = int(np.flatnonzero(valid_date)[0])
        week_i, tow_i = _gps_week_tow(*(r[i:i + 1, c] for c in range(2, 8)))
        # the week of the first epoch: that of the dated one, less the weeks rolled since
        week0 = int(week_i[0]) - int(np.sum(np.diff(tow[:i + 1]) < -_WEEK_S / 2))
    else:
        week0 = 0
    time = tow + _WEEK_S * np.concatenate([[0], np.cumsum(np.diff(tow) < -_WEEK_S / 2)])
    back = np.flatnonzero(np.diff(time) <= 0)
    if back.size:
        raise InputError(f"NAV-PVT time not increasing ({time[back[0]]!r} then "
                         f"{time[back[0] + 1]!r} s)", path=path_s, record=int(r[back[0] + 1, 0]))
    lla = np.column_stack([np.deg2rad(r[:, 12] * 1e-7), np.deg2rad(r[:, 11] * 1e-7),
                           r[:, 13] / 1000.0])
    sig = np.column_stack([r[:, 15] / 1000.0 / np.sqrt(2.0)] * 2 + [r[:, 16] / 1000.0])
    v_n = r[:, 17:20] / 1000.0
    sig_v = np.repeat(r[:, 20:21] / 1000.0, 3, axis=1)
    carr = (r[:, 10] >> 6) & 3
    q = np.where(carr == 2, 1, np.where(carr == 1, 2, np.where((r[:, 10] & 2) != 0, 4, 5)))
    floor = 1e-3
    del week0                    # the times are seconds of the first epoch's week
    return GnssLog(time, lla, np.maximum(sig, floor), v_n, np.maximum(sig_v, floor),
                   line=r[:, 0], path=path_s, quality=q)


# NMEA ------------------------------------------------------------------------------------

def looks_like_nmea(path, limit_lines=64):
    """Whether the first lines of ``path`` hold NMEA sentences (``$G?GGA``, ``$G?RMC``)."""
    try:
        with open(path, "rb") as f:
            for _, raw in zip(range(limit_lines), f):
                s = raw.strip()
                if s.startswith(b"$") and s[3:6] in (b"GGA", b"RMC", b"GST"):
                    return True
    except OSError:
        return False
    return False


def _nmea_fields(text, path, line):
    body, _, ck = text[1:].partition("*")
    if ck:
        c = 0
        for ch in body.encode("ascii", "replace"):
            c ^= ch
        if ck[:2].upper() != f"{c:02X}":
            raise InputError(f"NMEA checksum {ck[:2]!r} wrong (computed {c:02X})", path=path,
                             line=line)
    return body.split(",")


def _latlon(value, hemi, deg_digits, what, path, line):
    if not value:
        return None
    try:
        d = float(value[:deg_digits]) + float(value[deg_digits:]) / 60.0
    except ValueError:
        raise InputError(f"{what} {value!r}: expected (d)ddmm.mmmm", path=path,
                         line=line) from None
    if hemi not in ("N", "S", "E", "W"):
        raise InputError(f"{what} hemisphere {hemi!r}: expected N/S or E/W", path=path,
                         line=line)
    return -d if hemi in ("S", "W") else d


def read_nmea(path, geoid=None):
    """Read GGA (+ RMC, GST) sentences of an NMEA log (module notes)."""
    path_s = os.fspath(path)
    date = None
    gst = {}
    rows = []                    # line, utc s of day, date, lat, lon, alt, sep, q, hdop
    with open(path_s, "r", encoding="ascii", errors="replace") as f:
        for line, raw in enumerate(f, start=1):
            s = raw.strip()
            if not s.startswith("$") or len(s) < 6:
                continue
            kind = s[3:6]
            if kind not in ("GGA", "RMC", "GST"):
                continue
            fl = _nmea_fields(s, path_s, line)
            try:
                if kind == "RMC" and len(fl) > 9 and fl[9]:
                    date = (2000 + int(fl[9][4:6]), int(fl[9][2:4]), int(fl[9][0:2]))
                elif kind == "GST" and len(fl) > 8 and fl[1] and fl[6]:
                    gst[fl[1]] = (float(fl[6]), float(fl[7]), float(fl[8]))
                elif kind == "GGA":
                    if len(fl) < 12:
                        raise InputError(f"GGA with {len(fl)} fields (expected 15)",
                                         path=path_s, line=line)
                    q = int(fl[6] or 0)
                    if q not in _GGA_Q or not fl[2] or not fl[9]:
                        continue
                    if date is None:
                        raise InputError("GGA before any RMC: the date is unknown (log RMC "
                                         "sentences too)", path=path_s, line=line)
                    tod = fl[1]
                    utc = int(tod[0:2]) * 3600 + int(tod[2:4]) * 60 + float(tod[4:])
                    rows.append((line, utc, date, _latlon(fl[2], fl[3], 2, "latitude",
                                                          path_s, line),
                                 _latlon(fl[4], fl[5], 3, "longitude", path_s, line),
                                 float(fl[9]), float(fl[11]) if fl[11] else np.nan, q,
                                 float(fl[8] or "nan"), tod))
            except ValueError as exc:
                raise InputError(f"{kind}: {exc}", path=path_s, line=line) from None
    if not rows:
        raise InputError("no GGA sentence with a position (quality 1, 2, 4 or 5)",
                         path=path_s)
    line = np.array([r[0] for r in rows], np.int64)
    whole = np.array([int(np.floor(r[1])) for r in rows], np.int64)
    frac = np.array([r[1] - np.floor(r[1]) for r in rows])
    y, mo, d = (np.array([r[2][i] for r in rows]) for i in range(3))
    week, tow = _gps_week_tow(y, mo, d, whole // 3600, whole // 60 % 60, whole % 60)
    time = (week - week[0]) * _WEEK_S + tow + frac
    back = np.flatnonzero(np.diff(time) <= 0)
    if back.size:
        raise InputError("GGA time not increasing (a day's end without a new RMC?)",
                         path=path_s, line=int(line[back[0] + 1]))
    lat = np.array([r[3] for r in rows])
    lon = np.array([r[4] for r in rows])
    if np.any(np.abs(lat) > 90):
        k = int(np.flatnonzero(np.abs(lat) > 90)[0])
        raise InputError(f"latitude {lat[k]!r} deg outside +-90 deg", path=path_s,
                         line=int(line[k]))
    alt = np.array([r[5] for r in rows])
    sep = np.array([r[6] for r in rows])
    lla = np.column_stack([np.deg2rad(lat), np.deg2rad(lon), alt + np.nan_to_num(sep)])
    missing = np.isnan(sep)
    if np.any(missing):
        from ins.io.geoid import ellipsoidal_from_geodetic
        lla[missing, 2] = ellipsoidal_from_geodetic(
            lla[missing], geoid, path_s, f"{int(missing.sum())} GGA altitudes above mean "
            "sea level without the geoid separation")
    q = np.array([_GGA_Q[r[7]] for r in rows])
    sig = np.full((len(rows), 3), np.nan)
    for k, r in enumerate(rows):
        g = gst.get(r[9])
        if g is not None:
            sig[k] = g
    no_gst = np.isnan(sig[:, 0])
    if np.any(no_gst):
        hdop = np.array([r[8] for r in rows])
        uere = np.array([NMEA_UERE_M[r[7]] for r in rows])
        h = np.where(np.isfinite(hdop), hdop, 1.0) * uere
        sig[no_gst] = np.column_stack([h, h, 2 * h])[no_gst]
        warnings.warn(f"{path_s}: {int(no_gst.sum())} of {len(rows)} GGA epochs without a "
                      "GST sentence: sigmas from HDOP x a nominal range error per quality "
                      f"({', '.join(f'{k}: {v} m' for k, v in NMEA_UERE_M.items())} by GGA "
                      "quality), vertical twice", InputWarning, stacklevel=2)
    log = GnssLog(time, lla, np.maximum(sig, 1e-3), line=line, path=path_s, quality=q)
    return log
