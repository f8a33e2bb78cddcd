"""Trimble RT-17 packets written from Trimble's public Serial Reference Specification
(the RAWDATA 57h "real-time survey data" report, as in the OEM BD9xx receivers' ICD),
to test the conversion of RT-17 logs (ins.gnss.receiver_formats) against known values.

- Packet: STX ``02``, status, packet type (57h RAWDATA), length (of the data), data,
  checksum (the sum of status, type, length and data modulo 256), ETX ``03``.
  RAWDATA data: record type (0: real-time GPS survey data, "type 17"), page (the
  page's number in the high nibble, the number of pages in the low one), reply number,
  record interpretation flags (bit 0 concise format, bit 1 enhanced), then the record's
  bytes, split over pages of at most 244 bytes.  Numbers are big-endian.
- Type 17 record, concise: receive time F8 (ms of the GPS week), clock offset F8 (ms,
  0 unknown), number of satellites U1, then per satellite: PRN U1, FLAGS1 U1 (bit 0 L2
  data loaded, 1 L1 cycle slip, 2 L2 cycle slip, 4 L1 phase valid, 5 L2 range and
  phase valid, 6 L1 data valid), FLAGS2 U1 (bit 0 L1 P code, 1 L2 P code, 2 L2
  encrypted code), elevation I1 deg, azimuth I2 deg, [L1 data] signal strength U1
  (dB x 4), pseudorange F8 m, continuous phase F8 cycles (Trimble's sign: the
  NEGATIVE of the RINEX phase), Doppler F4 Hz; [L2 data] signal strength U1, phase
  F8 cycles (negative), range minus the L1 range F4 m.
- RETSVDATA 55h, subtype 1 GPS ephemeris: subtype U1, PRN U1, ephemeris week U2,
  IODC U2, reserved U1, IODE U1, TOW I4 (s), toc I4 (s), toe U4 (s), then F8: T_GD
  (s), a_f2, a_f1, a_f0, C_rs (m), delta n (semicircles/s), M0 (semicircles), C_uc
  (semicircles), e, C_us, sqrt A, C_ic, Omega0, C_is, i0, C_rc, omega, Omega dot,
  IDOT, then flags U4 (bit 0 L2 P data flag, bits 1-2 code on L2, bits 4-9 health,
  bit 10 fit interval flag, bits 11-14 URA index).  Not paged.
The record gives no GPS week: RTKLIB takes it from an ephemeris before it, else from
the computer's clock (set by the conversion from the navigation files or, for a base,
the rover's first epoch).
"""
import struct

import numpy as np
from receiver_frames import _rinex2_arcs

RAWDATA = 0x57


def rt17_packets(record_type, record, rif=0x01, reply=0, status=0):
    """The record split into RAWDATA pages, each a packet."""
    chunks = [record[i:i + 244] for i in range(0, len(record), 244)] or [b""]
    out = b""
    for k, chunk in enumerate(chunks):
        data = bytes([record_type, ((k + 1) << 4) | len(chunks), reply & 0xFF, rif]) + chunk
        body = bytes([status, RAWDATA, len(data)]) + data
        out += b"\x02" + body + bytes([sum(body) & 0xFF, 0x03])
    return out


RETSVDATA = 0x55
SC2RAD = 3.1415926535898                  # IS-GPS-200's pi


def rt17_packet(ptype, data, status=0):
    body = bytes([status, ptype, len(data)]) + data
    return b"\x02" + body + bytes([sum(body) & 0xFF, 0x03])


def ephemeris_55(e, rtk):
    """RETSVDATA GPS ephemeris packet of an RTKLIB ``eph_t``."""
    w = rtk.Arr1Dint(1)
    toc = rtk.time2gpst(e.toc, w)
    tow = rtk.time2gpst(e.ttr, w)
    flags = (e.flag & 1) | (e.code & 3) << 1 | (e.svh & 0x3F) << 4 | \
        (1 << 10 if e.fit > 4.0 else 0) | (e.sva & 15) << 11
    sc = (e.tgd[0], e.f2, e.f1, e.f0, e.crs, e.deln / SC2RAD, e.M0 / SC2RAD,
          e.cuc / SC2RAD, e.e, e.cus / SC2RAD, np.sqrt(e.A), e.cic / SC2RAD,
          e.OMG0 / SC2RAD, e.cis / SC2RAD, e.i0 / SC2RAD, e.crc, e.omg / SC2RAD,
          e.OMGd / SC2RAD, e.idot / SC2RAD)
    data = struct.pack(">BBHHBBiiI19dI", 1, e.sat, e.week, e.iodc, 0, e.iode & 0xFF,
                       int(tow), int(round(toc)), int(round(e.toes)), *sc, flags)
    return rt17_packet(RETSVDATA, data)


def nav_to_rt17(nav_path, rtk):
    """``[((week, tow) of transmission, RETSVDATA packet)]`` of every GPS ephemeris of
    a RINEX navigation file (its week the toe's, as RINEX gives it)."""
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(nav_path), 1, "", obs, nav, sta)
    out, w = [], rtk.Arr1Dint(1)
    for i in range(nav.n):
        tow = rtk.time2gpst(nav.eph[i].ttr, w)
        out.append(((int(w[0]), float(tow)), ephemeris_55(nav.eph[i], rtk)))
    return sorted(out, key=lambda x: x[0])


def type17(tow_s, sats, reply=0):
    """A concise type 17 record of an epoch: ``sats`` ``{prn: {"L1": (psr m, carrier
    cycles or None, Doppler Hz or None, C/N0 dB-Hz, slip), "L2": (psr, carrier, _,
    C/N0, slip)}}`` (an L2 needs its phase: one flag tells range and phase valid)."""
    rec = struct.pack(">ddB", tow_s * 1000.0, 0.0, len(sats))
    for prn, bands in sorted(sats.items()):
        l1, l2 = bands.get("L1"), bands.get("L2")
        f1 = 0x40 | (0x10 if l1[1] is not None else 0) | (0x02 if l1[4] else 0)
        if l2 is not None:
            f1 |= 0x01 | 0x20 | (0x04 if l2[4] else 0)
        rec += struct.pack(">BBBbh", prn, f1, 0x04 if l2 is not None else 0, 45, 180)
        pr, cp, dop, cno, _ = l1
        rec += struct.pack(">Bddf", round(cno * 4), pr, 0.0 if cp is None else -cp,
                           0.0 if dop is None else dop)
        if l2 is not None:
            rec += struct.pack(">Bdf", round(l2[3] * 4), -l2[1], l2[0] - pr)
    return rt17_packets(0, rec, reply=reply)


def simulation_log(epochs):
    """Type 17 records of each epoch of :func:`receiver_frames.simulated_epochs`."""
    return b"".join(type17(tow, {p: {"L1": v["L1"] + (False,), "L2": v["L2"] + (False,)}
                                 for p, v in sats.items()}, reply=k)
                    for k, (_, tow, sats) in enumerate(epochs))


def rinex2_to_rt17(path, ephemerides=()):
    """The GPS C1/L1 and P2/L2 observations of a RINEX 2.10 file as type 17 records
    (the phases shifted near the ranges like a receiver's new arcs, the slip flag at
    an arc's start; a double would hold the file's phases, the shift keeps the
    comparison the same as for the other formats); an L2 without its phase, or a
    satellite without C1, left out; ``ephemerides`` (:func:`nav_to_rt17`) each sent
    before the first epoch at or after its transmission, as a receiver sends them
    (those of later, at the end).  Returns the packets, the shifts and the left out
    ``{(tow, "Gnn", band)}``."""
    pending = list(ephemerides)
    epochs, shifts = _rinex2_arcs(path, {"L1": ("C1", "L1"), "L2": ("P2", "L2")})
    data, left = b"", set()
    for k, (week, tow, sats) in enumerate(epochs):
        while pending and pending[0][0] <= (week, tow):
            data += pending.pop(0)[1]
        meas = {}
        for p, bands in sats.items():
            l1, l2 = bands.get("L1"), bands.get("L2")
            if l1 is None or l1[0] is None:
                left |= {(tow, f"G{p:02d}", b) for b in bands}
                continue
            m = {"L1": (l1[0], l1[1], None, l1[3], l1[4] < 1.0)}
            if l2 is not None:
                if l2[0] is None or l2[1] is None:
                    left.add((tow, f"G{p:02d}", "L2"))
                else:
                    m["L2"] = (l2[0], l2[1], None, l2[3], l2[4] < 1.0)
            meas[p] = m
        data += type17(tow, meas, reply=k)
    return data + b"".join(p for _, p in pending), shifts, left

