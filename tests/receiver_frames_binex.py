"""BINEX records written from UNAVCO's public BINEX description (binex.unavco.org), to
test the conversion of BINEX logs (ins.gnss.receiver_formats) against known values.

- Record (big-endian, regular CRC, forward: the kind RTKLIB decodes): sync ``E2``,
  record ID, the message length as a ubnxi (1-4 bytes: 7 bits each with bit 7 set
  when another byte follows, the 4th byte's 8 bits), the message, then a checksum of
  record ID + length + message (n bytes): their XOR (n < 128) or the CRC-16 CCITT
  (polynomial 0x1021, seed 0), big-endian (n < 4096).
- 0x00 site metadata: minutes since the GPS epoch U4, quarter seconds U1, source U1,
  then fields: a field ID ubnxi and its content; 0x08 site name (ubnxi length +
  characters), 0x1d antenna ECEF position (a reference-frame name as ubnxi length +
  characters, then X, Y, Z as F8 m).
- 0x01-01 decoded GPS ephemeris: subrecord 0x01, PRN - 1 U1, week U2, tow I4 (s),
  toe I4 (s), tgd F4 (s), IODC I4, af2 F4, af1 F4, af0 F4, IODE I4, delta n F4
  (semicircles/s), M0 F8 (rad), e F8, sqrt A F8, cic, crc, cis, crs, cuc, cus F4,
  Omega0, omega, i0 F8 (rad), Omega dot F4, IDOT F4 (semicircles/s), URA F4 (0.1 m
  steps as RTKLIB reads it), SV health U2, flags U2 (fit interval h bits 0-7, L2 P
  data flag bit 8, codes on L2 bits 9-10).
- 0x7f-05 GNSS observables (the Trimble NetR8 prototyping record): subrecord 0x05,
  minutes since the GPS epoch U4, ms of the minute U2, a byte (bits 0-5: number of
  satellites - 1; 6: system time offsets follow; 7: receiver clock offset follows),
  then per satellite: PRN U1, a byte (bits 6-4 number of observables, 3-0 system: 0
  GPS), then per observable: a byte (bit 7 flag bytes follow, bit 5 slip, bits 4-0
  observation code: GPS 0 L1 C/A, 10 L2 P(W)), its flag bytes (bit 7 another follows,
  bits 0-1 the flag byte's number; byte 0: 0x04 Doppler follows, 0x08 slip count
  follows, 0x20 phase in 0.1 mm (else 0.02 mm), 0x40 extended ranges), C/N0 U1 of 0.4
  dB-Hz, then (the first observable) 40 bits: 2 signed bits of 0.1 dB-Hz on the C/N0,
  the range in 64 mm (32 bits) and 1 mm (6 bits); (the others, extended) 24 bits: 2
  signed bits of C/N0, 2 spare, the range minus the first's (20 signed bits, mm);
  the phase range minus the range (extended: 24 signed bits); the Doppler (24 signed
  bits of 1/256 Hz).
"""
import struct

import numpy as np

from receiver_frames import CLIGHT, FREQ_L1, FREQ_L2, Bits, _rinex2_arcs
from receiver_frames_sbf import crc16_ccitt_spec

OBS_L1CA, OBS_L2W = 0, 10
_FREQ = {OBS_L1CA: FREQ_L1, OBS_L2W: FREQ_L2}
SC2RAD = 3.1415926535898                 # GPS pi (IS-GPS-200)


def ubnxi_spec(value):
    """The BINEX ubnxi bytes of ``value`` (0 <= value < 2^29)."""
    if value < 1 << 7:
        return bytes([value])
    if value < 1 << 14:
        return bytes([0x80 | (value >> 7), value & 0x7F])
    if value < 1 << 21:
        return bytes([0x80 | (value >> 14), 0x80 | ((value >> 7) & 0x7F), value & 0x7F])
    return bytes([0x80 | (value >> 22), 0x80 | ((value >> 15) & 0x7F),
                  0x80 | ((value >> 8) & 0x7F), value & 0xFF])


def binex_record(record_id, message):
    body = bytes([record_id]) + ubnxi_spec(len(message)) + message
    if len(body) < 128:
        x = 0
        for byte in body:
            x ^= byte
        check = bytes([x])
    elif len(body) < 4096:
        check = crc16_ccitt_spec(body).to_bytes(2, "big")
    else:
        raise ValueError("record too long for a CRC-16")
    return b"\xe2" + body + check


def _gps_minutes(week, tow_s):
    """(minutes since 1980-01-06 GPS, ms of the minute)."""
    ms = round((week * 604800.0 + tow_s) * 1000.0)
    return ms // 60000, ms % 60000


def site_position(week, tow_s, xyz_m, name="3040"):
    """Record 0x00 with the site name (field 0x08) and antenna position (0x1d)."""
    minutes, ms = _gps_minutes(week, tow_s)
    msg = struct.pack(">IBB", minutes, ms // 250, 0)
    msg += ubnxi_spec(0x08) + ubnxi_spec(len(name)) + name.encode()
    frame = b"ITRF"
    msg += ubnxi_spec(0x1D) + ubnxi_spec(len(frame)) + frame + struct.pack(">3d", *xyz_m)
    return binex_record(0x00, msg)


def _cnr_parts(cnr):
    """(U1 of 0.4 dB-Hz, signed 2-bit 0.1 dB-Hz) closest to ``cnr``."""
    a = round(cnr / 0.4)
    b = round((cnr - 0.4 * a) / 0.1)
    if b > 1:
        a, b = a + 1, b - 4
    return a, max(b, -2)


def obs_7f05(week, tow_s, sats):
    """Record 0x7f-05 of an epoch: ``sats`` ``{prn: [(code, range m, carrier phase
    cycles, Doppler Hz or None, C/N0 dB-Hz, slip), ...]}`` (GPS; the first observable
    of each satellite its full range)."""
    minutes, ms = _gps_minutes(week, tow_s)
    msg = struct.pack(">BIHB", 0x05, minutes, ms, len(sats) - 1)
    for prn, meas in sorted(sats.items()):
        msg += bytes([prn, (len(meas) << 4) | 0])
        r0 = None
        for i, (code, rng, cp, dop, cnr, slip) in enumerate(meas):
            flags = 0x20 | 0x40 | (0x04 if dop is not None else 0)
            msg += bytes([0x80 | (0x20 if slip else 0) | code, flags])
            a, b = _cnr_parts(cnr)
            msg += bytes([a])
            f = Bits()
            mm = round(rng * 1000.0)
            if i == 0:
                r0 = mm
                f.put(2, b)
                f.put(32, mm // 64)
                f.put(6, mm % 64)
            else:
                f.put(2, b)
                f.put(2, 0)
                f.put(20, mm - r0)
            phase_m = cp * CLIGHT / _FREQ[code]
            off = round((phase_m - mm * 0.001) / 1e-4)
            if not -(1 << 23) <= off < 1 << 23:
                raise ValueError(f"phase {off} x 0.1 mm from the range: beyond 24 bits")
            f.put(24, off)
            if dop is not None:
                f.put(24, round(dop * 256.0))
            msg += f.bytes()
    return binex_record(0x7F, msg)


def _q(value, scale):
    return round(value / scale) * scale


def eph_0101(eph, rtk):
    """Record 0x01-01 of an RTKLIB ``eph_t`` (the broadcast values quantized to their
    IS-GPS-200 scale factors, as the satellite sends them)."""
    w = rtk.Arr1Dint(1)
    ttr = rtk.time2gpst(eph.ttr, w)
    week = rtk.Arr1Dint(1)
    rtk.time2gpst(eph.toe, week)
    msg = struct.pack(">BBHiififffi", 0x01, eph.sat - 1, week[0], int(ttr),
                      int(round(eph.toes)), _q(eph.tgd[0], 2.0 ** -31), eph.iodc,
                      _q(eph.f2, 2.0 ** -55), _q(eph.f1, 2.0 ** -43),
                      _q(eph.f0, 2.0 ** -31), eph.iode)
    msg += struct.pack(">fddd6fdddff", _q(eph.deln / SC2RAD, 2.0 ** -43),
                       _q(eph.M0 / SC2RAD, 2.0 ** -31) * SC2RAD, _q(eph.e, 2.0 ** -33),
                       _q(np.sqrt(eph.A), 2.0 ** -19), _q(eph.cic, 2.0 ** -29),
                       _q(eph.crc, 2.0 ** -5), _q(eph.cis, 2.0 ** -29),
                       _q(eph.crs, 2.0 ** -5), _q(eph.cuc, 2.0 ** -29),
                       _q(eph.cus, 2.0 ** -29),
                       _q(eph.OMG0 / SC2RAD, 2.0 ** -31) * SC2RAD,
                       _q(eph.omg / SC2RAD, 2.0 ** -31) * SC2RAD,
                       _q(eph.i0 / SC2RAD, 2.0 ** -31) * SC2RAD,
                       _q(eph.OMGd / SC2RAD, 2.0 ** -43), _q(eph.idot / SC2RAD, 2.0 ** -43))
    ura = (2.4, 3.4, 4.85, 6.85, 9.65, 13.65, 24.0, 48.0)[min(eph.sva, 7)]
    fit = 4 if eph.fit <= 4.0 else int(eph.fit)
    msg += struct.pack(">fHH", ura * 10.0, eph.svh, fit | (eph.flag << 8) | (eph.code << 9))
    return binex_record(0x01, msg)


def simulation_log(epochs):
    """Records 0x7f-05 of each epoch of :func:`receiver_frames.simulated_epochs`."""
    return b"".join(obs_7f05(w, tow, {p: [(OBS_L1CA, *v["L1"], False),
                                          (OBS_L2W, *v["L2"], False)]
                                      for p, v in sats.items()})
                    for w, tow, sats in epochs)


def rinex2_to_binex(path):
    """The GPS C1/L1 (L1 C/A) and P2/L2 (L2 P(W)) observations of a RINEX 2.10 file as
    0x7f-05 records, the phases shifted near the ranges
    (:func:`receiver_frames._rinex2_arcs`), the slip bit at each arc's start; a
    signal without phase (the record has no "no phase" value) or a satellite without
    C1 is left out.  Returns the records, the shifts and the left out
    ``{(tow, "Gnn", band)}``."""
    epochs, shifts = _rinex2_arcs(path, {"L1": ("C1", "L1"), "L2": ("P2", "L2")})
    code = {"L1": OBS_L1CA, "L2": OBS_L2W}
    data, left = b"", set()
    for week, tow, sats in epochs:
        meas = {}
        for p, bands in sats.items():
            m = []
            for band in ("L1", "L2"):
                if band not in bands:
                    continue
                pr, cp, dop, cnr, lock = bands[band]
                if pr is None or cp is None or (band == "L2" and not m):
                    left.add((tow, f"G{p:02d}", band))
                    continue
                m.append((code[band], pr, cp, dop, cnr, lock < 1.0))
            if m:
                meas[p] = m
        data += obs_7f05(week, tow, meas)
    return data, shifts, left


def nav_to_0101(nav_path, rtk):
    """Records 0x01-01 of every GPS ephemeris of a RINEX navigation file, and the
    ephemerides."""
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(nav_path), 1, "", obs, nav, sta)
    ephs = [nav.eph[i] for i in range(nav.n)]
    return b"".join(eph_0101(e, rtk) for e in ephs), ephs
