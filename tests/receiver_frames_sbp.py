"""Swift Navigation SBP messages written from Swift's public SBP specification
(libsbp's "Swift Navigation Binary Protocol" document), to test the conversion of SBP
logs (ins.gnss.receiver_formats) against known values.

- Frame: ``55``, message type U2, sender U2, payload length U1, payload, CRC-16 CCITT
  (polynomial 0x1021, seed 0) of type..payload, little-endian.  Sender 0 is the base
  station's relayed stream: a receiver's own messages carry its sender id.
- MSG_OBS (0x004A): GPSTime (tow U4 ms, ns_residual I4, wn U2), n_obs U1 (total
  messages of the epoch in the high nibble, this one's index in the low), then 17
  bytes an observation: P U4 (2 cm), L (i I4 cycles, f U1 1/256 cycle), D (i I2 Hz,
  f U1 1/256 Hz), cn0 U1 (0.25 dB-Hz), lock U1 (the RTCM DF402 lock-time indicator),
  flags U1 (bit 0 code valid, 1 carrier valid, 2 half-cycle resolved, 3 Doppler
  valid), sid (sat U1, code U1: 0 GPS L1 C/A, 6 GPS L2 P); at most 14 a message.
- MSG_EPHEMERIS_GPS (0x008A): common (sid, toe GPSTimeSec (tow U4 s, wn U2), ura F4
  m, fit_interval U4 s, valid U1, health_bits U1), tgd F4, c_rs, c_rc, c_uc, c_us,
  c_ic, c_is F4, dn, m0, ecc, sqrta, omega0, omegadot, w, inc, inc_dot F8 (rad, rad/s,
  m^1/2), af0, af1, af2 F4, toc GPSTimeSec, iode U1, iodc U2.
"""
import struct

import numpy as np

from receiver_frames import _lock4, _rinex2_arcs
from receiver_frames_sbf import crc16_ccitt_spec

MSG_OBS, MSG_EPH_GPS = 0x004A, 0x008A
CODE_L1CA, CODE_L2P = 0, 6
SENDER = 0x1234


def sbp_frame(msg_type, payload, sender=SENDER):
    body = struct.pack("<HHB", msg_type, sender, len(payload)) + payload
    return b"\x55" + body + struct.pack("<H", crc16_ccitt_spec(body))


def msg_obs(week, tow_s, obs):
    """MSG_OBS frames of an epoch (14 observations a frame): ``obs`` a list of (prn,
    code, pseudorange m, carrier phase cycles or None, Doppler Hz or None, C/N0
    dB-Hz, lock-time indicator)."""
    ms = int(np.floor(tow_s * 1000.0))
    ns = round((tow_s * 1000.0 - ms) * 1e6)
    parts = [obs[i:i + 14] for i in range(0, len(obs), 14)] or [[]]
    out = b""
    for k, part in enumerate(parts):
        payload = struct.pack("<IiHB", ms, ns, week, (len(parts) << 4) | k)
        for prn, code, pr, cp, dop, cno, lock in part:
            li = fi = di = df = 0
            if cp is not None:
                c = round(cp * 256.0)
                li, fi = c >> 8, c & 0xFF
            if dop is not None:
                d = round(dop * 256.0)
                di, df = d >> 8, d & 0xFF
            flags = 0x01 | (0x06 if cp is not None else 0) | (0x08 if dop is not None else 0)
            payload += struct.pack("<IiBhBBBBBB", round(pr / 0.02), li, fi, di, df,
                                   round(cno * 4.0), lock, flags, prn, code)
        out += sbp_frame(MSG_OBS, payload)
    return out


def eph_gps(eph, rtk):
    """MSG_EPHEMERIS_GPS of an RTKLIB ``eph_t``."""
    w = rtk.Arr1Dint(1)
    toe = rtk.time2gpst(eph.toe, w)
    toe_week = w[0]
    toc = rtk.time2gpst(eph.toc, w)
    ura = (2.4, 3.4, 4.85, 6.85, 9.65, 13.65, 24.0, 48.0)[min(eph.sva, 7)]
    fit = int((eph.fit if eph.fit > 0 else 4.0) * 3600)
    payload = struct.pack("<BBIHfIBB", eph.sat, CODE_L1CA, round(toe), toe_week, ura, fit,
                          1, eph.svh)
    payload += struct.pack("<7f", eph.tgd[0], eph.crs, eph.crc, eph.cuc, eph.cus,
                           eph.cic, eph.cis)
    payload += struct.pack("<9d", eph.deln, eph.M0, eph.e, np.sqrt(eph.A), eph.OMG0,
                           eph.OMGd, eph.omg, eph.i0, eph.idot)
    payload += struct.pack("<3fIHBH", eph.f0, eph.f1, eph.f2, round(toc), w[0], eph.iode,
                           eph.iodc)
    return sbp_frame(MSG_EPH_GPS, payload)


def simulation_log(epochs, lock_s=10.0):
    """MSG_OBS of each epoch of :func:`receiver_frames.simulated_epochs`."""
    return b"".join(msg_obs(w, tow, [(p, code, *v[band], _lock4(lock_s + tow - epochs[0][1]))
                                     for p, v in sats.items()
                                     for band, code in (("L1", CODE_L1CA),
                                                        ("L2", CODE_L2P))])
                    for w, tow, sats in epochs)


def rinex2_to_sbp(path, interval_s=30.0):
    """The GPS C1/L1 (L1 C/A) and P2/L2 (L2 P) observations of a RINEX 2.10 file as
    MSG_OBS frames, phases shifted near the ranges (the carrier's integer cycles are
    32 bits, :func:`receiver_frames._rinex2_arcs`); the lock-time indicator 0 at an
    arc's start, else DF402 of the lock time plus one ``interval_s`` (RTKLIB's SBP
    slip test reads a rise from 0 to 16 s over a 30 s step as a slip)."""
    epochs, shifts = _rinex2_arcs(path, {"L1": ("C1", "L1"), "L2": ("P2", "L2")})
    code = {"L1": CODE_L1CA, "L2": CODE_L2P}
    data = b""
    for week, tow, sats in epochs:
        obs = []
        for p, bands in sorted(sats.items()):
            for band, (pr, cp, dop, cnr, lock) in sorted(bands.items()):
                if pr is None:
                    continue
                obs.append((p, code[band], pr, cp, dop, cnr,
                            0 if lock < 1.0 else _lock4(lock + interval_s)))
        data += msg_obs(week, tow, obs)
    return data, shifts


def nav_to_sbp(nav_path, rtk):
    """MSG_EPHEMERIS_GPS of every GPS ephemeris of a RINEX navigation file, and the
    ephemerides."""
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(nav_path), 1, "", obs, nav, sta)
    ephs = [nav.eph[i] for i in range(nav.n)]
    return b"".join(eph_gps(e, rtk) for e in ephs), ephs
