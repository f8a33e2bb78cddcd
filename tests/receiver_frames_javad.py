"""Javad GREIS messages written from Javad's public GREIS reference ("GNSS Receiver
External Interface Specification"), to test the conversion of Javad logs
(ins.gnss.receiver_formats) against known values.

- Standard message: two ID characters, the body's length as three upper-case hex
  digits, the body; the body's last byte is the checksum: over the ID, length and body
  before it, cs = rotate-left-2(cs) XOR byte from cs = 0, then rotate-left-2 once
  more.  Numbers are little-endian.  Each message here ends with a line feed (the
  separator GREIS allows; RTKLIB's decoder needs a CR or LF before each header).
- An epoch: [~~] receiver time (ms of the day U4), [RD] receiver date (year U2, month
  U1, day U1, time scale U1: 0 GPS), [SI] satellite indices (U1 each: GPS PRN 1-37),
  then per signal one value a satellite: [RC] / [R2] pseudoranges (F8 s, CA/L1, P/L2),
  [PC] / [P2] carrier phases (F8 cycles), [DC] / [D2] Doppler (I4 of 1e-4 Hz, the
  opposite sign of RINEX's), [EC] / [E2] C/N0 (U1 dB-Hz), [TC] CA/L1 continuous
  tracking time (U2 s), then [::] epoch time (ms of the day U4).  No value: F8 0, I4
  0x7FFFFFFF, U1 255.
- [GE] GPS ephemeris, the reference's ``GPSEphemeris``: sv U1, tow U4 (s), flags U1 (bit
  0 curve fit interval, bit 1 L2 P data flag, bits 2-3 code on L2), iodc I2, toc I4 (s),
  ura I1, health U1, week I2, tgd F4 (s), af2 F4, af1 F4, af0 F4, toe I4 (s), iode I2,
  sqrt A F8, e F8, M0, Omega0, i0, omega F8 (semicircles), delta n, Omega dot, IDOT F4
  (semicircles/s), crc, crs F4 (m), cuc, cus, cic, cis F4 (rad).
- A log opens with the [JP] file identifier ("RLOGF JPS ..."), as a receiver writes
  it: RTKLIB's convrnx never runs the decoder's start-of-file step, so a log whose
  very first byte began a data message (no line feed before it) converted to blank
  observations.
"""
import struct

import numpy as np

CLIGHT = 299792458.0


def _rotl2(x):
    return ((x << 2) | (x >> 6)) & 0xFF


def greis_checksum(data):
    cs = 0
    for byte in data:
        cs = _rotl2(cs) ^ byte
    return _rotl2(cs)


def greis_message(ident, payload):
    head = ident.encode() + f"{len(payload) + 1:03X}".encode()
    return head + payload + bytes([greis_checksum(head + payload)]) + b"\n"


def epoch(date, tod_ms, sats):
    """The messages of an epoch: ``date`` (y, m, d) of GPS time, ``sats`` ``{prn: {"L1":
    (psr m, carrier cycles or None, Doppler Hz or None, C/N0 dB-Hz, lock s), "L2":
    (...)}}``."""
    prns = sorted(sats)
    out = greis_message("~~", struct.pack("<I", tod_ms))
    out += greis_message("RD", struct.pack("<HBBB", *date, 0))
    out += greis_message("SI", bytes(prns))
    for band, sig in (("L1", "C"), ("L2", "2")):
        vals = [sats[p].get(band) for p in prns]
        out += greis_message("R" + sig, b"".join(
            struct.pack("<d", 0.0 if v is None else v[0] / CLIGHT) for v in vals))
        out += greis_message("P" + sig, b"".join(
            struct.pack("<d", 0.0 if v is None or v[1] is None else v[1]) for v in vals))
        out += greis_message("D" + sig, b"".join(
            struct.pack("<i", 0x7FFFFFFF if v is None or v[2] is None else
                        -round(v[2] * 1e4)) for v in vals))
        out += greis_message("E" + sig, bytes(255 if v is None else round(v[3])
                                              for v in vals))
    out += greis_message("TC", b"".join(
        struct.pack("<H", min(int(sats[p]["L1"][4]), 65534)) for p in prns))
    return out + greis_message("::", struct.pack("<I", tod_ms))


def _date_tod(week, tow_s):
    """(GPS (y, m, d), ms of the GPS day) of a GPS week and time of week."""
    days = week * 7 + int(tow_s // 86400)
    d = np.datetime64("1980-01-06") + np.timedelta64(days, "D")
    y, m, dd = (int(x) for x in str(d).split("-"))
    return (y, m, dd), round((tow_s % 86400) * 1000.0)


SC2RAD = 3.1415926535898                  # IS-GPS-200's pi


def ephemeris_ge(e, rtk):
    """[GE] of a GPS ephemeris (an RTKLIB ``eph_t``)."""
    w = rtk.Arr1Dint(1)
    toc = rtk.time2gpst(e.toc, w)
    tow = rtk.time2gpst(e.ttr, w)
    flags = (1 if e.fit > 4.0 else 0) | (e.flag & 1) << 1 | (e.code & 3) << 2
    body = struct.pack("<BIBhibBhffffihddddddfffffffff", e.sat, int(tow), flags, e.iodc,
                       int(round(toc)), e.sva, e.svh, e.week, e.tgd[0], e.f2, e.f1, e.f0,
                       int(round(e.toes)), e.iode, np.sqrt(e.A), e.e, e.M0 / SC2RAD,
                       e.OMG0 / SC2RAD, e.i0 / SC2RAD, e.omg / SC2RAD, e.deln / SC2RAD,
                       e.OMGd / SC2RAD, e.idot / SC2RAD, e.crc, e.crs, e.cuc, e.cus,
                       e.cic, e.cis)
    return greis_message("GE", body)


def nav_to_javad(nav_path, rtk):
    """[GE] of every GPS ephemeris of a RINEX navigation file, and the ephemerides."""
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(nav_path), 1, "", obs, nav, sta)
    ephs = [nav.eph[i] for i in range(nav.n)]
    return b"".join(ephemeris_ge(e, rtk) for e in ephs), ephs


FILE_ID = greis_message("JP", b"RLOGF JPS E/A/D/C/N GREIS test log")


def simulation_log(epochs, lock0=10.0):
    """The epochs of :func:`receiver_frames.simulated_epochs` as GREIS messages."""
    out = FILE_ID
    for week, tow, sats in epochs:
        date, tod = _date_tod(week, tow)
        lock = lock0 + tow - epochs[0][1]
        out += epoch(date, tod, {p: {b: v[b] + (lock,) for b in ("L1", "L2")}
                                 for p, v in sats.items()})
    return out


def rinex2_to_javad(path):
    """The GPS C1/L1 (CA/L1) and P2/L2 (P/L2) observations of a RINEX 2.10 file as
    GREIS epochs, the phases as they are (doubles); the CA/L1 tracking time restarts
    at an L1 loss-of-lock flag (GREIS flags L2 slips only in [F2], which RTKLIB does
    not read)."""
    from ubx_frames import read_rinex2_obs
    out, since = FILE_ID, {}
    for week, tow, rows in read_rinex2_obs(path):
        sats = {}
        for prn, v in sorted(rows.items()):
            if not prn.startswith("G") or np.isnan(v["C1"][0]):
                continue
            cp1, lli = v.get("L1", (np.nan, 0))
            if lli & 1 or prn not in since:
                since[prn] = tow
            m = {"L1": (v["C1"][0], None if np.isnan(cp1) else cp1, None, 45.0,
                        tow - since[prn])}
            if not np.isnan(v["P2"][0]):
                cp2 = v.get("L2", (np.nan, 0))[0]
                m["L2"] = (v["P2"][0], None if np.isnan(cp2) else cp2, None, 45.0, 0)
            sats[int(prn[1:])] = m
        date, tod = _date_tod(week, tow)
        out += epoch(date, tod, sats)
    return out
