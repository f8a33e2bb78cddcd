"""Raw GNSS receiver logs in every format RTKLIB decodes, converted to RINEX 3.04 with
RTKLIB's ``convrnx`` (the engine of ``convbin``, through the optional ``pyrtklib5``
binding) on the way to :func:`ins.gnss.rtklib_engine.solve` and the tight coupling.

Formats (:data:`FORMATS`; the names of ``--gnss-format``/``--base-format`` and of
``[rtklib] rover_format``/``base_format``): ``rinex`` (observation files as they are)
and the receiver formats of the binding's ``STRFMT_*`` (pyrtklib5 0.2.8, RTKLIB demo5
2.5.0, which has no NovAtel OEM3 decoder): ``rtcm2``, ``rtcm3`` (MSM4-7, 1002/1004/
1010/1012, ephemerides 1019/1020/1045/1046/...), ``oem4`` (NovAtel OEM4/6/7 binary:
RANGEB/RANGECMPB, RAWEPHEMB, GLOEPHEMERISB, ...), ``ubx`` (u-blox RXM-RAWX, RXM-SFRBX),
``sbf`` (Septentrio), ``hemisphere`` (Hemisphere/Crescent ``$BIN``), ``skytraq``,
``javad`` (GREIS), ``nvs`` (NVS BINR), ``binex``, ``rt17`` (Trimble RT17), ``unicore``
and ``swift`` (Swift Navigation SBP).

Detection (:func:`detect_format`): a RINEX header (``RINEX VERSION / TYPE`` in the
first line); else the binary format with the most frames of valid framing and checksum
in the first 256 KiB (:mod:`ins.gnss.framing`: UBX, RTCM3, OEM4, Unicore, SBF, SBP,
SkyTraq, RT17, BINEX big-endian regular-CRC records, Javad GREIS receiver-time
messages, Hemisphere ``$BIN``, NVS BINR 0xF5/0xF7 of their layout, RTCM 2 messages of
30-bit words with the GPS parity); else BINEX of another kind (its sync byte
``C2``/``C8``/``E8`` first: RTKLIB decodes none, :func:`convert_raw` says so); else
the extension (``.ubx``, ``.rtcm3``, ``.sbf``, ``.jps``, ...).

Time: several formats give the week modulo 1024 or no week at all (RTCM3 gives the time
of week only, RTCM 2 the time within the hour), which RTKLIB completes from the
computer's clock (``adjgpsweek``, or for RTCM ``rnxopt_t.trtcm``): an old log would land
in a wrong week or 1024-week era. The conversion therefore sets RTKLIB's clock
(``timeset``; reset after, callers serialize RTKLIB calls) and ``trtcm`` to the log's
own first epoch where the format gives a complete week (UBX RXM-RAWX, OEM4 and Unicore
headers, SBF, SBP MSG_OBS, SkyTraq 0xE5/0xDC, Hemisphere Bin 76/96, NVS 0xF5, Javad [~~]
+ [RD]: RTKLIB's Unicore, SBP, SkyTraq, NVS and Javad ephemeris decoders pass even a
full week through ``adjgpsweek``, and the subframe decoders (SkyTraq 0xE0, Hemisphere
Bin 95, ...) the 10-bit week, which without the clock set moves a log older than 2009 by
1024 weeks), else to the first ephemeris of the navigation files given with it.
"""
import os
import struct

from ins.common.errors import InputError
from ins.io.ublox import ubx_checksum

__all__ = ["FORMATS", "RAW_FORMATS", "detect_format", "convert_raw", "observations",
           "first_epoch", "first_rawx_time", "nav_epoch", "obs_epoch", "RINEX_VERSION",
           "format_names", "check_format"]

#: RINEX version of the converted files (x100, RTKLIB's rnxopt_t.rnxver).
RINEX_VERSION = 304
_N_OUTPUT_FILES = 9          # convbin: obs, nav, gnav, hnav, qnav, lnav, cnav, inav, sbas
_SNIFF_BYTES = 1 << 18

#: name -> (pyrtklib5 STRFMT_* constant name, what it is, the observation messages).
FORMATS = {
    "rtcm2": ("STRFMT_RTCM2", "RTCM 2", "messages 18/19 (or 20/21)"),
    "rtcm3": ("STRFMT_RTCM3", "RTCM 3", "MSM4-MSM7 (1074-1137) or 1002/1004/1010/1012 "
              "messages"),
    "oem4": ("STRFMT_OEM4", "NovAtel OEM4/6/7 binary", "RANGEB or RANGECMPB logs"),
    "ubx": ("STRFMT_UBX", "u-blox UBX", "UBX RXM-RAWX messages: enable them on the "
            "receiver, e.g. with u-center"),
    "sbf": ("STRFMT_SEPT", "Septentrio SBF", "MeasEpoch or Meas3Ranges blocks"),
    "hemisphere": ("STRFMT_CRES", "Hemisphere/Crescent binary", "$BIN 76/96 messages"),
    "skytraq": ("STRFMT_STQ", "SkyTraq binary", "raw measurement messages (0xDD/0xE5)"),
    "javad": ("STRFMT_JAVAD", "Javad GREIS", "RD/R1/PC/... messages"),
    "nvs": ("STRFMT_NVS", "NVS BINR", "F5 raw data messages"),
    "binex": ("STRFMT_BINEX", "BINEX", "record 0x7F-05 observations"),
    "rt17": ("STRFMT_RT17", "Trimble RT17", "RAWDATA (0x57) records"),
    "unicore": ("STRFMT_UNICORE", "Unicore binary", "OBSVMB logs"),
    "swift": ("STRFMT_SBP", "Swift Navigation SBP", "MSG_OBS messages"),
}
RAW_FORMATS = tuple(FORMATS)
_EXTENSIONS = {".ubx": "ubx", ".rtcm3": "rtcm3", ".rtcm": "rtcm3", ".rtc": "rtcm3",
               ".rtcm2": "rtcm2", ".sbf": "sbf", ".gps": "oem4", ".oem4": "oem4",
               ".bnx": "binex", ".binex": "binex", ".jps": "javad", ".stq": "skytraq",
               ".nvs": "nvs", ".rt17": "rt17", ".sbp": "swift", ".unc": "unicore"}
_BINEX_SYNC = (0xC2, 0xE2, 0xC8, 0xE8)
_BINEX_RECORDS = (0x00, 0x01, 0x02, 0x03, 0x7D, 0x7E, 0x7F)


def format_names():
    """``"rinex, rtcm2, rtcm3, ..."``: the names a format is given by."""
    return ", ".join(("rinex",) + RAW_FORMATS)


def check_format(name, where):
    """``name`` (lower case) if it is a format name (or None), else an InputError
    naming ``where`` (the option or key) and the names."""
    if name is None:
        return None
    if not isinstance(name, str) or name.lower() not in ("rinex",) + RAW_FORMATS:
        raise InputError(f"{where}: unknown GNSS receiver format {name!r}; expected one of "
                         f"{format_names()}")
    return name.lower()


def detect_format(path):
    """The format name of the observation file ``path``: ``"rinex"`` or one of
    :data:`RAW_FORMATS` (module notes).

    Raises
    ------
    InputError
        Naming the file and the format names: nothing recognised.
    """
    path = os.fspath(path)
    try:
        with open(path, "rb") as f:
            data = f.read(_SNIFF_BYTES)
    except OSError as e:
        raise InputError(f"cannot read the GNSS observations: {e.strerror}", path=path) from None
    first = data.split(b"\n", 1)[0]
    if b"RINEX VERSION / TYPE" in first or b"CRINEX VERS" in first:
        return "rinex"
    from ins.gnss.framing import count_frames
    counts = count_frames(data)
    if counts:
        return max(counts, key=counts.get)
    if len(data) > 1 and data[0] in _BINEX_SYNC and data[1] in _BINEX_RECORDS:
        return "binex"
    ext = os.path.splitext(path)[1].lower()
    if ext in _EXTENSIONS:
        return _EXTENSIONS[ext]
    raise InputError(f"cannot tell the receiver format of these GNSS observations from "
                     f"their content (no RINEX header, no valid UBX/RTCM3/NovAtel/SBF/"
                     f"Unicore/SBP/SkyTraq/RT17/Javad/$BIN/NVS/RTCM2 frame, no BINEX "
                     f"record) nor from the extension {ext or '(none)'!r}: name it with "
                     f"--gnss-format / --base-format or [rtklib] rover_format / "
                     f"base_format, one of {format_names()}", path=path)


def first_epoch(path, fmt, limit_bytes=1 << 22):
    """``(week, tow_s)`` of the first measurement epoch with a complete GPS week in the
    first ``limit_bytes`` of a log, for the formats that give one (UBX RXM-RAWX; OEM4
    and Unicore headers; SBF block headers; SBP MSG_OBS; SkyTraq 0xE5 / 0xDC;
    Hemisphere Bin 76 / 96; NVS 0xF5; Javad [~~] + [RD]), else None."""
    if fmt == "ubx":
        return first_rawx_time(path, limit_bytes)
    if fmt == "nvs":
        return _first_binr_epoch(path, limit_bytes)
    if fmt == "javad":
        return _first_greis_epoch(path, limit_bytes)
    if fmt not in ("oem4", "unicore", "sbf", "swift", "skytraq", "hemisphere"):
        return None
    from ins.gnss.framing import RECOGNISERS
    with open(path, "rb") as f:
        data = f.read(limit_bytes)
    sync, check = RECOGNISERS[fmt]
    k = data.find(sync)
    while k >= 0:
        if check(data, k):
            if fmt == "swift":                  # MSG_OBS (0x004A): tow ms, ns, week
                if struct.unpack_from("<H", data, k + 1)[0] != 0x004A or data[k + 5] < 10:
                    k = data.find(sync, k + 1)
                    continue
                ms, _, week = struct.unpack_from("<IiH", data, k + 6)
            elif fmt == "hemisphere":           # Bin 76 (tow F8, week), Bin 96 (week, tow)
                block = struct.unpack_from("<H", data, k + 4)[0]
                if block not in (76, 96):
                    k = data.find(sync, k + 1)
                    continue
                if block == 76:
                    tow, week = struct.unpack_from("<dH", data, k + 8)
                else:
                    week, tow = struct.unpack_from("<Hd", data, k + 10)
                if 0 < week < 0xFFFF and 0.0 <= tow < 604800.0:
                    return int(week), float(tow)
                k = data.find(sync, k + 1)
                continue
            elif fmt == "skytraq":              # 0xE5 raw (week, tow ms), 0xDC epoch
                where = {0xE5: 7, 0xDC: 6}.get(data[k + 4])
                if where is None or struct.unpack_from(">H", data, k + 2)[0] < where + 2:
                    k = data.find(sync, k + 1)
                    continue
                week, ms = struct.unpack_from(">HI", data, k + where)
            elif fmt == "oem4":
                week, ms = struct.unpack_from("<HI", data, k + 14)
            elif fmt == "unicore":
                week, ms = struct.unpack_from("<HI", data, k + 10)
            else:
                ms, week = struct.unpack_from("<IH", data, k + 8)
                week = 0 if week == 0xFFFF or ms == 0xFFFFFFFF else week
            if 0 < week < 0xFFFF:
                return int(week), ms / 1000.0
        k = data.find(sync, k + 1)
    return None


def _first_binr_epoch(path, limit_bytes):
    """``(week, GPS tow_s)`` of the first NVS BINR 0xF5 raw data message (the UTC time
    of measurement plus the GPS-UTC shift, ms), or None."""
    from ins.gnss.framing import RECOGNISERS, unstuff_binr
    check = RECOGNISERS["nvs"][1]
    with open(path, "rb") as f:
        data = f.read(limit_bytes)
    k = data.find(b"\x10\xf5")
    while k >= 0:
        end = check(data, k)
        if end:
            _, body, _ = unstuff_binr(data, k)
            utc_ms, week, shift_ms = struct.unpack_from("<dHd", body, 0)
            tow = (utc_ms + shift_ms) / 1000.0
            if 1024 <= week and 0.0 <= tow < 604800.0:     # a full week only
                return int(week), tow
        k = data.find(b"\x10\xf5", k + 1)
    return None


def _first_greis_epoch(path, limit_bytes):
    """``(week, tow_s)`` of the first Javad GREIS [~~] receiver time (ms of the day)
    followed by an [RD] receiver date (year U2, month U1, day U1, time scale U1), both
    with a valid checksum, or None."""
    import datetime

    from ins.gnss.framing import RECOGNISERS, greis_checksum
    check = RECOGNISERS["javad"][1]
    with open(path, "rb") as f:
        data = f.read(limit_bytes)
    k = data.find(b"~~005")
    while k >= 0:
        j = data.find(b"RD006", k + 10, k + 16)
        if check(data, k) and j > 0 and j + 11 <= len(data) and \
                greis_checksum(data[j:j + 10]) == data[j + 10]:
            ms = struct.unpack_from("<I", data, k + 5)[0]
            year, month, day = struct.unpack_from("<HBB", data, j + 5)
            try:
                days = (datetime.date(year, month, day) - datetime.date(1980, 1, 6)).days
            except ValueError:
                days = -1
            if days >= 0 and ms < 86400000:
                return days // 7, (days % 7) * 86400.0 + ms / 1000.0
        k = data.find(b"~~005", k + 1)
    return None


def first_rawx_time(path, limit_bytes=1 << 22):
    """``(week, tow_s)`` of the first RXM-RAWX message (with a valid checksum) in the
    first ``limit_bytes`` of a UBX log, or None."""
    with open(path, "rb") as f:
        data = f.read(limit_bytes)
    k = data.find(b"\xb5\x62\x02\x15")
    while 0 <= k and k + 8 + 16 <= len(data):
        length = struct.unpack_from("<H", data, k + 4)[0]
        end = k + 6 + length
        if end + 2 <= len(data) and data[end:end + 2] == ubx_checksum(data[k + 2:end]):
            tow, week = struct.unpack_from("<dH", data, k + 6)
            if week > 0:
                return int(week), float(tow)
        k = data.find(b"\xb5\x62\x02\x15", k + 2)
    return None


def nav_epoch(navs, rtk):
    """``(week, tow_s)`` of the first GPS ephemeris's toe in the RINEX navigation files
    ``navs``, or None (copied out before RTKLIB's arrays are freed)."""
    for p in navs or ():
        obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
        try:
            if rtk.readrnx(os.fspath(p), 1, "", obs, nav, sta) and nav.n > 0:
                w = rtk.Arr1Dint(1)
                tow = rtk.time2gpst(nav.eph[0].toe, w)
                return int(w[0]), float(tow)
        finally:
            rtk.freeobs(obs)
            rtk.freenav(nav, 0xFF)
    return None


def obs_epoch(path, rtk):
    """``(week, tow_s)`` of the first epoch of a RINEX observation file (RTKLIB's
    ``readrnx``), or None."""
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    try:
        if rtk.readrnx(os.fspath(path), 1, "", obs, nav, sta) and obs.n > 0:
            w = rtk.Arr1Dint(1)
            tow = rtk.time2gpst(obs.data[0].time, w)
            return int(w[0]), float(tow)
    finally:
        rtk.freeobs(obs)
        rtk.freenav(nav, 0xFF)
    return None


def convert_raw(path, folder, rtk, stem="rover", fmt=None, navs=(), epoch=None):
    """Convert a receiver log into RINEX 3.04 files in ``folder`` with RTKLIB.

    Parameters
    ----------
    path : str or os.PathLike
        The log.
    folder : str
        An existing folder for the converted files (``<stem>.obs``, ``<stem>.nav``).
    rtk : module
        The imported ``pyrtklib5``.
    stem : str
        Name of the converted files.
    fmt : str, optional
        One of :data:`RAW_FORMATS`; None: :func:`detect_format`.
    navs : sequence of paths
        RINEX navigation files given with the log: their first ephemeris dates a log
        whose format has no complete week (module notes).
    epoch : (int, float), optional
        ``(GPS week, s of week)`` near the log's start, for a format without a complete
        week (RTCM's week; the rover's first epoch for a base station's log); before
        the navigation files'.

    Returns
    -------
    obs_path : str
        RINEX observations (GPS time of the receiver's epochs).
    nav_path : str or None
        RINEX navigation when the log held ephemerides, else None.

    Raises
    ------
    InputError
        Naming the log: RTKLIB converts no observation from it (the messages it needs
        are named), or a format the binding does not have.
    """
    path = os.fspath(path)
    fmt = detect_format(path) if fmt is None else fmt
    if fmt not in FORMATS:
        raise InputError(f"not a receiver format RTKLIB converts: {fmt!r} (expected one of "
                         f"{', '.join(RAW_FORMATS)})", path=path)
    const, what, needs = FORMATS[fmt]
    if not hasattr(rtk, const):
        raise InputError(f"this pyrtklib5 binding has no {what} decoder ({const})", path=path)
    if fmt == "binex":
        _check_binex(path)
    obs_path = os.path.join(folder, stem + ".obs")
    nav_path = os.path.join(folder, stem + ".nav")
    opt = rtk.rnxopt_t()
    opt.rnxver = RINEX_VERSION
    opt.navsys = rtk.SYS_ALL
    opt.obstype = rtk.OBSTYPE_ALL
    opt.freqtype = rtk.FREQTYPE_ALL
    opt.ttol = 0.005                     # s, convbin's default epoch tolerance
    for i in range(7):                   # mask[7][64]: every signal of every system
        for j in range(64):
            opt.mask[i, j] = "1"
    first = first_epoch(path, fmt)
    first = epoch if first is None else first
    first = nav_epoch(navs, rtk) if first is None else first
    when = None if first is None else rtk.gpst2time(*first)
    if when is not None:
        opt.trtcm = when
        rtk.timeset(rtk.gpst2utc(when))
    ofile = [obs_path, nav_path] + [""] * (_N_OUTPUT_FILES - 2)
    try:
        status = rtk.convrnx(getattr(rtk, const), opt, path, ofile)
    finally:
        if when is not None:
            rtk.timereset()
    if status <= 0 or not _has_observation(obs_path):
        raise InputError(f"RTKLIB's convrnx converts no observation from this {what} log "
                         f"(status {status}; expected {needs}; the format named "
                         f"{fmt!r}: another one with --gnss-format / --base-format?)",
                         path=path)
    if not _has_ephemeris(nav_path):
        nav_path = None
    return obs_path, nav_path


def observations(path, folder, rtk, stem="rover", fmt=None, navs=(), epoch=None):
    """``(RINEX observation path, converted navigation path or None)`` of ``path``: a
    RINEX file as it is, a receiver log converted into ``folder``
    (:func:`convert_raw`); ``fmt`` None: :func:`detect_format`."""
    fmt = detect_format(path) if fmt is None else fmt
    if fmt == "rinex":
        return os.fspath(path), None
    return convert_raw(path, folder, rtk, stem, fmt, navs, epoch)


def _check_binex(path):
    """An InputError naming the log when it holds no BINEX record of the kind RTKLIB
    decodes (big-endian, regular CRC, forward: sync byte E2) but starts with another
    kind's sync byte."""
    from ins.gnss.framing import count_frames
    with open(path, "rb") as f:
        data = f.read(_SNIFF_BYTES)
    if count_frames(data).get("binex") or not data or data[0] == 0xE2:
        return
    kinds = {0xC2: "little-endian", 0xC8: "little-endian, enhanced CRC",
             0xE8: "big-endian, enhanced CRC", 0xD2: "little-endian, reversed",
             0xF2: "big-endian, reversed", 0xD8: "little-endian, enhanced CRC, reversed",
             0xF8: "big-endian, enhanced CRC, reversed"}
    if data[0] in kinds:
        raise InputError(f"RTKLIB's BINEX decoder reads only big-endian, regular-CRC, "
                         f"forward records (sync byte 0xE2); this log's records are "
                         f"{kinds[data[0]]} (sync byte 0x{data[0]:02X}): convert it to "
                         f"RINEX with another tool (e.g. teqc) first", path=path)


def _has_observation(path):
    """A RINEX 3 observation file with at least one epoch record (``>``)."""
    if not os.path.isfile(path):
        return False
    with open(path, "rb") as f:
        return any(line.startswith(b">") for line in f)


def _has_ephemeris(path):
    """A RINEX navigation file with a data record after its header."""
    if not os.path.isfile(path):
        return False
    with open(path, "rb") as f:
        body = f.read().split(b"END OF HEADER", 1)
    return len(body) == 2 and bool(body[1].strip())
