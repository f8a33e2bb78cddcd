"""SkyTraq binary messages written from SkyTraq's public application notes (AN0039
"Binary Messages of Raw Measurement Data Extension of SkyTraq Phoenix GNSS Receiver",
AN0030 for the subframe message), to test the conversion of SkyTraq logs
(ins.gnss.receiver_formats) against known values.

- Message: ``A0 A1``, payload length U2, payload (the message ID first), checksum (the
  XOR of the payload bytes), ``0D 0A``.  Numbers are big-endian.
- 0xE5 extended raw measurement data v.1: version U1 (1), IOD U1, GPS week U2, TOW U4
  (ms), measurement period U2 (ms), measurement indicator U1, reserved U1, number of
  signals U1, then 31 bytes a signal: GNSS type (bits 0-3: 0 GPS) and signal type
  (bits 4-7: 0 L1 C/A, 2 L2C), SVID U1, frequency ID / lock-time indicator U1, C/N0
  U1 (dB-Hz), pseudorange F8 m, accumulated carrier cycles F8, Doppler F4 Hz, the
  three standard deviations U1, channel indicator U2 (bit 0 pseudorange valid, 1
  Doppler valid, 2 carrier valid, 3 cycle slip), reserved U2.
- 0xE0 GPS subframe: SVID U1, subframe ID U1, the 10 words' 24 data bits (30 bytes,
  without parity).
"""
import struct

import numpy as np

SIG_L1CA, SIG_L2C = 0, 2


def stq_message(payload):
    x = 0
    for byte in payload:
        x ^= byte
    return b"\xa0\xa1" + struct.pack(">H", len(payload)) + payload + bytes([x]) + b"\r\n"


def rawx_e5(week, tow_s, sigs, iod=0, period_ms=1000):
    """0xE5 of an epoch: ``sigs`` a list of (svid, signal type, pseudorange m, carrier
    cycles or None, Doppler Hz or None, C/N0 dB-Hz, slip)."""
    payload = struct.pack(">BBBHIHBBB", 0xE5, 1, iod & 0xFF, week,
                          round(tow_s * 1000.0), period_ms, 0, 0, len(sigs))
    for svid, sig, pr, cp, dop, cno, slip in sigs:
        ind = 0x01 | (0x02 if dop is not None else 0) | (0x04 if cp is not None else 0) | \
            (0x08 if slip else 0)
        payload += struct.pack(">BBBBddfBBBHH", (sig << 4) | 0, svid, 0, round(cno), pr,
                               0.0 if cp is None else cp, 0.0 if dop is None else dop,
                               0, 0, 0, ind, 0)
    return stq_message(payload)


def subframe_e0(svid, sfid, words24):
    body = b"".join((w & 0xFFFFFF).to_bytes(3, "big") for w in words24)
    return stq_message(bytes([0xE0, svid, sfid]) + body)


def simulation_log(epochs):
    """0xE5 of each epoch of :func:`receiver_frames.simulated_epochs`."""
    return b"".join(rawx_e5(w, tow, [(p, sig, *v[band], False) for p, v in sats.items()
                                     for band, sig in (("L1", SIG_L1CA), ("L2", SIG_L2C))],
                            iod=k)
                    for k, (w, tow, sats) in enumerate(epochs))


def rinex2_to_skytraq(path):
    """The GPS C1/L1 (L1 C/A) and P2/L2 (as signal type 2, the only GPS L2 type of the
    message) observations of a RINEX 2.10 file as 0xE5 messages, the phases as they
    are (doubles), the slip bit at a loss-of-lock flag."""
    from ubx_frames import read_rinex2_obs
    out = b""
    for k, (week, tow, rows) in enumerate(read_rinex2_obs(path)):
        sigs = []
        for prn, v in sorted(rows.items()):
            if not prn.startswith("G"):
                continue
            for sig, (pr_t, cp_t) in ((SIG_L1CA, ("C1", "L1")), (SIG_L2C, ("P2", "L2"))):
                pr = v.get(pr_t, (np.nan, 0))[0]
                cp, lli = v.get(cp_t, (np.nan, 0))
                if np.isnan(pr):
                    continue
                sigs.append((int(prn[1:]), sig, pr, None if np.isnan(cp) else cp, None,
                             45.0, bool(lli & 1)))
        out += rawx_e5(week, tow, sigs, iod=k, period_ms=30000)
    return out


def nav_to_skytraq(nav_path, rtk):
    """0xE0 subframes 1-3 of every GPS ephemeris of a RINEX navigation file."""
    from ubx_frames import lnav_subframes
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(nav_path), 1, "", obs, nav, sta)
    ephs = [nav.eph[i] for i in range(nav.n)]
    return b"".join(subframe_e0(e.sat, k + 1, words) for e in ephs
                    for k, words in enumerate(lnav_subframes(e, rtk))), ephs
