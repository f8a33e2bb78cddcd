"""Unicore binary messages (UM980/UM982, "N4" products) written from Unicore's public
Commands and Logs Reference (the NovAtel-like layout), to test the conversion of
Unicore logs (ins.gnss.receiver_formats) against known values.

- Frame: the 24-byte header (``AA 44 B5``, CPU idle U1, message ID U2, message length
  U2 (the body's), time reference U1 (0 GPST), time status U1 (0 valid), GPS week U2,
  GPS ms U4, reserved U4, version U1, leap seconds U1, output delay ms U2), the body,
  the CRC-32 of header and body (NovAtel's reflected 0xEDB88320, seed 0).
- OBSVMB (ID 12, the master antenna's observations): number of observations U4, then
  40 bytes per signal: system frequency U2 (GLONASS FCN + 7), PRN U2, psr F8 m, adr F8
  cycles (the accumulated Doppler range: the NEGATIVE of the carrier phase, as the
  reference's example records show), psr std U2 (0.01 m), adr std U2 (0.0001 cycle),
  Doppler F4 Hz, C/N0 U2 (0.01 dB-Hz), reserved U2, lock time F4 s, channel tracking
  status U4 (bit 10 phase lock, 11 parity known, 12 code lock, 16-18 system 0 GPS,
  21-25 signal type: GPS 0 L1 C/A, 9 L2 P(Y), 17 L2C(L)).
- GPSEPHB (ID 106): PRN U4, tow F8, health U4, IODE1 U4, IODE2 U4, week U4, Z week U4,
  toe F8, A F8 (m, not its square root), dN, M0, e, omega, cuc, cus, crc, crs, cic,
  cis, I0, IDOT, Omega0, Omega dot (F8, rad, rad/s, m), IODC U4, toc F8, tgd F8, af0,
  af1, af2 F8, anti-spoofing U4, corrected mean motion N F8, URA F8 (m).
"""
import struct

import numpy as np

from receiver_frames import crc32_novatel_spec

ID_OBSVM, ID_GPSEPH = 12, 106
SIG_L1CA, SIG_L2P, SIG_L2C = 0, 9, 17
_GM = 3.986005e14                      # m^3/s^2, WGS 84 (IS-GPS-200)
#: URA (m) of each URA index (IS-GPS-200 20.3.3.3.1.3, the upper bounds)
URA_M = (2.4, 3.4, 4.85, 6.85, 9.65, 13.65, 24.0, 48.0, 96.0, 192.0, 384.0, 768.0,
         1536.0, 3072.0, 6144.0)


def unicore_frame(msg_id, week, tow_s, body, time_status=0):
    head = struct.pack("<BBBBHHBBHIIBBH", 0xAA, 0x44, 0xB5, 20, msg_id, len(body), 0,
                       time_status, week, round(tow_s * 1000.0), 0, 1, 18, 0)
    data = head + body
    return data + struct.pack("<I", crc32_novatel_spec(data))


def track_status(sig, phase_lock=True):
    return (4 if sig == SIG_L1CA else 11) | (int(phase_lock) << 10) | (1 << 11) | \
        (1 << 12) | (0 << 16) | (sig << 21)


def obsvmb(week, tow_s, obs):
    """OBSVMB of an epoch: ``obs`` a list of (prn, signal type, psr m, carrier phase
    cycles or None (no phase lock), Doppler Hz or None, C/N0 dB-Hz, lock time s)."""
    body = struct.pack("<I", len(obs))
    for prn, sig, psr, cp, dop, cno, lock in obs:
        body += struct.pack("<HHddHHfHHfI", 0, prn, psr, 0.0 if cp is None else -cp,
                            100, 50, 0.0 if dop is None else dop, round(cno * 100), 0,
                            lock, track_status(sig, cp is not None))
    return unicore_frame(ID_OBSVM, week, tow_s, body)


def gpsephb(eph, rtk):
    """GPSEPHB of an RTKLIB ``eph_t`` (read from a RINEX navigation file), stamped with
    its time of transmission."""
    w = rtk.Arr1Dint(1)
    ttr = rtk.time2gpst(eph.ttr, w)
    week = w[0]
    toc = rtk.time2gpst(eph.toc, w)
    n = np.sqrt(_GM / eph.A ** 3) + eph.deln
    body = struct.pack("<IdIIIII", eph.sat, ttr, eph.svh, eph.iode, eph.iode, week, week)
    body += struct.pack("<16d", eph.toes, eph.A, eph.deln, eph.M0, eph.e, eph.omg,
                        eph.cuc, eph.cus, eph.crc, eph.crs, eph.cic, eph.cis, eph.i0,
                        eph.idot, eph.OMG0, eph.OMGd)
    body += struct.pack("<Iddddd", eph.iodc, toc, eph.tgd[0], eph.f0, eph.f1, eph.f2)
    body += struct.pack("<Idd", 0, n, URA_M[min(eph.sva, 14)])
    return unicore_frame(ID_GPSEPH, week, ttr, body)


def simulation_log(epochs, l2_sig=SIG_L2P, lock0=10.0):
    """OBSVMB of each epoch of :func:`receiver_frames.simulated_epochs`."""
    out = b""
    for week, tow, sats in epochs:
        lock = lock0 + tow - epochs[0][1]
        out += obsvmb(week, tow, [(p, sig, *v[band], lock) for p, v in sats.items()
                                  for band, sig in (("L1", SIG_L1CA), ("L2", l2_sig))])
    return out


def rinex2_to_obsvmb(path):
    """The GPS C1/L1 (L1 C/A) and P2/L2 (L2 P(Y)) observations of a RINEX 2.10 file as
    OBSVMB logs, the phases as they are (adr is a double); lock times restart at a
    loss-of-lock flag."""
    from ubx_frames import read_rinex2_obs
    out, since = b"", {}
    for week, tow, rows in read_rinex2_obs(path):
        obs = []
        for prn, v in sorted(rows.items()):
            if not prn.startswith("G"):
                continue
            for sig, (pr_t, cp_t) in ((SIG_L1CA, ("C1", "L1")), (SIG_L2P, ("P2", "L2"))):
                pr = v.get(pr_t, (np.nan, 0))[0]
                cp, lli = v.get(cp_t, (np.nan, 0))
                if np.isnan(pr):
                    continue
                key = (prn, sig)
                if lli & 1 or key not in since:
                    since[key] = tow
                obs.append((int(prn[1:]), sig, pr, None if np.isnan(cp) else cp, None,
                            45.0, tow - since[key] + 0.5))
        out += obsvmb(week, tow, obs)
    return out


def nav_to_gpsephb(nav_path, rtk):
    """GPSEPHB logs of every GPS ephemeris of a RINEX navigation file, and the
    ephemerides."""
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(nav_path), 1, "", obs, nav, sta)
    ephs = [nav.eph[i] for i in range(nav.n)]
    return b"".join(gpsephb(e, rtk) for e in ephs), ephs
