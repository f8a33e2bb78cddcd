"""Hemisphere (Crescent / Eclipse) binary messages written from Hemisphere's public GPS
Technical Reference (the ``$BIN`` messages), to test the conversion of Hemisphere logs
(ins.gnss.receiver_formats) against known values.

- Message: ``$BIN``, block ID U2, data length U2, data, checksum U2 (the sum of the
  data bytes modulo 2^16), ``0D 0A``.  Numbers are little-endian.
- Bin 76 (dual-frequency code and phase, 448 bytes): GPS time of week F8 s, week U2,
  spares (U2, U4), 12 L2P observation packets, 15 L1CA observation packets, 15 L1CA
  code MSB words, 12 spare words.  A packet (12 bytes): word 1 (bits 0-11 SNR: C/N0
  = 10 log10(k SNR) + 30 dB-Hz, k 0.1024 on L1 and 0.1164 on L2; 12-14 phase-track
  quality; 24-31 cycle-slip counter), word 2 (1-23 |Doppler| in 1/512 Hz, 24 Doppler
  sign, 25-31 the phase's 7 top bits), word 3 (0-15 the code's 16 low bits in 1/256
  m, 16-31 16 more phase bits): the phase in 1/1024 cycle modulo 8192 cycles (the
  receiver's value, rebuilt near the pseudorange / wavelength).  The MSB word: bits
  0-7 PRN, 13-31 the L1CA code's 19 top bits (256 m).  L2P pairs with L1CA channel i
  < 12; its code is the 16 low bits alone (within 128 m of L1's).  The Doppler's sign:
  the opposite of RINEX's.
- Bin 95 (a GPS ephemeris, 128 bytes): PRN U2, spares (U2, U4), subframes 1-3 as 10
  U4 words each (the 24 data bits above 6 parity bits).
"""
import struct

from receiver_frames import _rinex2_arcs

_K = {"L1": 0.1024, "L2": 0.1164}


def bin_message(block_id, data):
    return b"$BIN" + struct.pack("<HH", block_id, len(data)) + data + \
        struct.pack("<H", sum(data) & 0xFFFF) + b"\r\n"


def _packet(band, cp, dop, cnr, slips, code_low):
    sn = min(round(10.0 ** ((cnr - 30.0) / 10.0) / _K[band]), 0xFFF)
    w1 = sn | ((slips & 0xFF) << 24)
    v = round(cp * 1024.0) % (1 << 23) if cp is not None else 0
    d = 0 if dop is None else -dop                     # the message's sign
    w2 = ((min(round(abs(d) * 512.0), 0x7FFFFF)) << 1) | ((d < 0) << 24) | ((v >> 16) << 25)
    w3 = (code_low & 0xFFFF) | ((v & 0xFFFF) << 16)
    return struct.pack("<III", w1, w2, w3)


def bin76(week, tow_s, sats):
    """Bin 76 of an epoch: ``sats`` ``{prn: {"L1": (psr m, carrier cycles, Doppler Hz
    or None, C/N0 dB-Hz, slip count), "L2": (...)}}``, at most 15 (12 with L2)."""
    prns = sorted(sats, key=lambda p: "L2" not in sats[p])
    if len(prns) > 15 or sum("L2" in sats[p] for p in prns) > 12:
        raise ValueError("bin 76 holds 15 L1CA and 12 L2P channels")
    l2 = [b"\x00" * 12] * 12
    l1 = [b"\x00" * 12] * 15
    msb = [0] * 15
    for i, p in enumerate(prns):
        pr, cp, dop, cnr, slips = sats[p]["L1"]
        u = round(pr * 256.0)
        msb[i] = p | ((u >> 16) << 13)
        l1[i] = _packet("L1", cp, dop, cnr, slips, u & 0xFFFF)
        if "L2" in sats[p]:
            pr2, cp2, dop2, cnr2, slips2 = sats[p]["L2"]
            l2[i] = _packet("L2", cp2, dop2, cnr2, slips2, round(pr2 * 256.0) & 0xFFFF)
    data = struct.pack("<dHHI", tow_s, week, 0, 0) + b"".join(l2) + b"".join(l1) + \
        struct.pack("<15I", *msb) + b"\x00" * 48
    return bin_message(76, data)


def bin95(prn, words24):
    """Bin 95 of one GPS ephemeris: ``words24`` subframes 1-3 of 10 24-bit words."""
    data = struct.pack("<HHI", prn, 0, 0) + b"".join(
        struct.pack("<I", (w & 0xFFFFFF) << 6) for sf in words24 for w in sf)
    return bin_message(95, data)


def simulation_log(epochs):
    """Bin 76 of each epoch of :func:`receiver_frames.simulated_epochs`."""
    return b"".join(bin76(w, tow, {p: {b: v[b] + (0,) for b in ("L1", "L2")}
                                   for p, v in sats.items()}) for w, tow, sats in epochs)


def rinex2_to_bin76(path):
    """The GPS C1/L1 and P2/L2 observations of a RINEX 2.10 file as Bin 76 messages,
    the phases shifted near the ranges (the message keeps them modulo 8192 cycles,
    :func:`receiver_frames._rinex2_arcs`), the slip counters counting arc restarts; a
    signal without phase, or a satellite without C1, left out.  Returns the messages,
    the shifts and the left out ``{(tow, "Gnn", band)}``."""
    epochs, shifts = _rinex2_arcs(path, {"L1": ("C1", "L1"), "L2": ("P2", "L2")})
    data, left, slips = b"", set(), {}
    for week, tow, sats in epochs:
        meas = {}
        for p, bands in sats.items():
            m = {}
            for band in ("L1", "L2"):
                if band not in bands:
                    continue
                pr, cp, _, cnr, lock = bands[band]
                if pr is None or cp is None or (band == "L2" and not m):
                    left.add((tow, f"G{p:02d}", band))
                    continue
                key = (p, band)
                slips[key] = slips.get(key, -1) + (lock < 1.0)
                m[band] = (pr, cp, None, cnr, slips[key])
            if m:
                meas[p] = m
        data += bin76(week, tow, meas)
    return data, shifts, left


def nav_to_bin95(nav_path, rtk):
    """Bin 95 of every GPS ephemeris of a RINEX navigation file, and the ephemerides."""
    from ubx_frames import lnav_subframes
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(nav_path), 1, "", obs, nav, sta)
    ephs = [nav.eph[i] for i in range(nav.n)]
    return b"".join(bin95(e.sat, lnav_subframes(e, rtk)) for e in ephs), ephs

