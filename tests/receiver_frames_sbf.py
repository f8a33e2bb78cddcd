"""Septentrio SBF blocks written from the public SBF Reference Guide (the "Septentrio
Binary Format" chapter of the receivers' reference guides), to test the conversion of
SBF logs (ins.gnss.receiver_formats) against known values.

- Block: ``$@`` sync, CRC U2, ID U2 (bits 0-12 block number, 13-15 revision), Length
  U2 (the whole block, a multiple of 4: padded with zero bytes), then TOW U4 (ms) and
  WNc U2 (full GPS week); the CRC is the CRC-16 CCITT (polynomial 0x1021, seed 0)
  of the block from the ID to its end.
- MeasEpoch (4027, revision 2): N1, SB1Length, SB2Length, CommonFlags, CumClkJumps,
  a reserved byte, then N1 Type-1 sub-blocks (20 bytes: RxChannel, Type (bits 0-4
  signal number, 5-7 antenna), SVID, Misc (bits 0-3 CodeMSB), CodeLSB U4, Doppler I4
  of 1e-4 Hz, CarrierLSB U2, CarrierMSB I1, CN0 U1 of 0.25 dB-Hz (+10 dB-Hz for the
  signals other than GPS L1P/L2P), LockTime U2 s, ObsInfo, N2), each followed by its
  N2 Type-2 sub-blocks (12 bytes: Type, LockTime U1 s, CN0, OffsetsMSB (bits 0-2
  CodeOffsetMSB, 3-7 DopplerOffsetMSB, signed), CarrierMSB I1, ObsInfo, CodeOffsetLSB
  U2, CarrierLSB U2, DopplerOffsetLSB U2).  Pseudorange = (CodeMSB 2^32 + CodeLSB)
  mm; carrier phase = pseudorange / wavelength + (CarrierMSB 2^16 + CarrierLSB) 0.001
  cycles; Type 2: pseudorange = that of Type 1 + code offset (mm), Doppler = Type 1's
  x f2 / f1 + Doppler offset (1e-4 Hz).  Do-not-use values: Doppler -2^31, carrier
  MSB -128 with LSB 0, CN0 255, LockTime 65535 / 255, code offset MSB -4 with LSB 0,
  Doppler offset MSB -16 with LSB 0.
- MeasEpochEnd (5922): the end of an epoch's measurement blocks.
- GPSRawCA (4017): SVID, CRCPassed, ViterbiCount, Source, FreqNr, RxChannel, then the
  300 bits of a GPS L1 C/A subframe as 10 U4 words (each the 30-bit word, parity in
  the 6 low bits, the 2 top bits unused).
Signal numbers: 0 GPS L1 C/A, 2 GPS L2 P(Y), 3 GPS L2C.
"""
import struct

import numpy as np

from receiver_frames import CLIGHT, FREQ_L1, FREQ_L2, _rinex2_arcs

ID_MEASEPOCH, ID_MEASEPOCH_END, ID_GPSRAWCA = 4027, 5922, 4017
SIG_L1CA, SIG_L2P, SIG_L2C = 0, 2, 3
_FREQ = {SIG_L1CA: FREQ_L1, SIG_L2P: FREQ_L2, SIG_L2C: FREQ_L2}


def crc16_ccitt_spec(data):
    """CRC-16 CCITT bit by bit (generator 0x1021, seed 0, no reflection)."""
    crc = 0
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc


def sbf_block(block_id, week, tow_s, body, revision=0):
    """The block: header, TOW/WNc, ``body``, zero padding to a multiple of 4."""
    data = struct.pack("<IH", round(tow_s * 1000.0), week) + body
    length = 8 + len(data)
    data += b"\x00" * (-length % 4)
    rest = struct.pack("<HH", block_id | (revision << 13), 8 + len(data)) + data
    return b"$@" + struct.pack("<H", crc16_ccitt_spec(rest)) + rest


def _split(value, low_bits, high_bits):
    """(signed high part, low part) of an integer."""
    high = value >> low_bits
    if not -(1 << (high_bits - 1)) <= high < (1 << (high_bits - 1)):
        raise ValueError(f"offset {value} beyond {high_bits}+{low_bits} bits")
    return high, value & ((1 << low_bits) - 1)


def _cn0(sig, cnr):
    return 255 if cnr is None else round((cnr - (0.0 if sig in (1, 2) else 10.0)) * 4)


def measepoch(week, tow_s, sats, common_flags=0):
    """MeasEpoch of an epoch: ``sats`` ``{svid: [(sig, psr m, carrier cycles or None,
    Doppler Hz or None, C/N0 dB-Hz, lock time s), ...]}``, the first signal of each
    satellite its Type-1 sub-block (a pseudorange needed), the others Type 2."""
    body = b""
    for chn, (svid, sigs) in enumerate(sorted(sats.items())):
        sig, pr, cp, dop, cnr, lock = sigs[0]
        code = round(pr * 1000.0)
        pr_enc = code * 0.001
        if cp is None:
            cmsb, clsb = -128, 0
        else:
            cmsb, clsb = _split(round((cp - pr_enc * _FREQ[sig] / CLIGHT) * 1000.0), 16, 8)
        d1 = -(1 << 31) if dop is None else round(dop * 1e4)
        body += struct.pack("<BBBBIiHbBHBB", chn + 1, sig, svid, code >> 32,
                            code & 0xFFFFFFFF, d1, clsb, cmsb, _cn0(sig, cnr),
                            65535 if cp is None else min(int(lock), 65534), 0,
                            len(sigs) - 1)
        for sig2, pr2, cp2, dop2, cnr2, lock2 in sigs[1:]:
            if pr2 is None:
                pmsb, plsb, pr2_enc = -4, 0, None
            else:
                off = round((pr2 - pr_enc) * 1000.0)
                pmsb, plsb = _split(off, 16, 3)
                pr2_enc = pr_enc + off * 0.001
            if cp2 is None or pr2_enc is None:
                cmsb, clsb = -128, 0
            else:
                cmsb, clsb = _split(round((cp2 - pr2_enc * _FREQ[sig2] / CLIGHT) * 1e3),
                                    16, 8)
            if dop2 is None or dop is None:
                dmsb, dlsb = -16, 0
            else:
                ref = d1 * 1e-4 * _FREQ[sig2] / _FREQ[sig]
                dmsb, dlsb = _split(round((dop2 - ref) * 1e4), 16, 5)
            body += struct.pack("<BBBBbBHHH", sig2, 255 if cp2 is None else
                                min(int(lock2), 254), _cn0(sig2, cnr2),
                                (pmsb & 0x07) | ((dmsb & 0x1F) << 3), cmsb, 0, plsb,
                                clsb, dlsb)
    head = struct.pack("<BBBBBB", len(sats), 20, 12, common_flags, 0, 0)
    return sbf_block(ID_MEASEPOCH, week, tow_s, head + body, revision=2)


def measepoch_end(week, tow_s):
    return sbf_block(ID_MEASEPOCH_END, week, tow_s, b"")


def gpsrawca(svid, week, tow_s, words24, crc_passed=1):
    """GPSRawCA of one subframe: 10 words of 24 data bits (parity bits left zero: the
    block's CRCPassed flag vouches for them)."""
    body = struct.pack("<BBBBBB", svid, crc_passed, 0, SIG_L1CA, 0, 1)
    body += b"".join(struct.pack("<I", (w & 0xFFFFFF) << 6) for w in words24)
    return sbf_block(ID_GPSRAWCA, week, tow_s, body)


def simulation_log(epochs, l2_sig=SIG_L2P, lock0=10.0):
    """MeasEpoch + MeasEpochEnd of each epoch of
    :func:`receiver_frames.simulated_epochs` (L1 C/A and ``l2_sig``)."""
    data = b""
    for week, tow, sats in epochs:
        lock = lock0 + tow - epochs[0][1]
        data += measepoch(week, tow, {p: [(SIG_L1CA, *v["L1"], lock),
                                          (l2_sig, *v["L2"], lock)]
                                      for p, v in sats.items()})
        data += measepoch_end(week, tow)
    return data


def rinex2_to_sbf(path):
    """The GPS C1/L1 (L1 C/A) and P2/L2 (L2 P(Y)) observations of a RINEX 2.10 file as
    MeasEpoch + MeasEpochEnd blocks, the phases shifted near the pseudoranges (the
    carrier offsets have 24 bits of 1 mm: :func:`receiver_frames._rinex2_arcs`), and
    the shifts.  A satellite without C1 is left out (its Type-1 sub-block needs it)."""
    epochs, shifts = _rinex2_arcs(path, {"L1": ("C1", "L1"), "L2": ("P2", "L2")})
    sig = {"L1": SIG_L1CA, "L2": SIG_L2P}
    data = b""
    for week, tow, sats in epochs:
        meas = {}
        for p, bands in sats.items():
            if "L1" not in bands or bands["L1"][0] is None:
                continue
            meas[p] = [(sig[b], *bands[b]) for b in ("L1", "L2") if b in bands]
        data += measepoch(week, tow, meas) + measepoch_end(week, tow)
    return data, shifts


def nav_to_gpsrawca(nav_path, rtk):
    """GPSRawCA blocks (subframes 1-3) of every GPS ephemeris of a RINEX navigation
    file (read with RTKLIB's readrnx), and the ephemerides."""
    from ubx_frames import lnav_subframes
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(nav_path), 1, "", obs, nav, sta)
    ephs = [nav.eph[i] for i in range(nav.n)]
    w = rtk.Arr1Dint(1)
    data = b""
    for e in ephs:
        tow = rtk.time2gpst(e.ttr, w)
        for k, words in enumerate(lnav_subframes(e, rtk)):
            data += gpsrawca(e.sat, w[0], float(np.floor(tow)) + 6 * k, words)
    return data, ephs
