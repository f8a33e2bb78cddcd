"""NVS BINR messages written from NVS's public BINR protocol description ("Navis
Standard Interface Protocol BINR", NV08C-CSM/NAVIOR appendices), to test the
conversion of NVS logs (ins.gnss.receiver_formats) against known values.

- Message: DLE (``10``), the message ID, the data, DLE ETX (``10 03``); a DLE byte
  of the data is sent twice (DLE stuffing).  Numbers are little-endian (INT8U U1,
  INT8S I1, INT16U/S U2/I2, FP32 F4, FP64 F8).
- 0xF5 raw data: time of measurement (UTC, ms of the week) F8, GPS week U2, GPS-UTC
  time-scale shift F8 ms, GLONASS-UTC shift F8 ms, receiver time-scale correction I1,
  then 30 bytes a channel: signal type U1 (1 GLONASS, 2 GPS, 4 SBAS), satellite
  number U1, GLONASS carrier number I1, S/N I1 (dB-Hz), carrier phase F8 (cycles),
  pseudorange F8 (ms), Doppler F8 (Hz), raw data flags U1 (bit 0 signal present,
  bit 1 dithering, bit 2 smoothed, bit 3 carrier phase present, bit 4 pseudorange
  present), reserved U1.
- 0xF7 extended ephemeris, GPS (type 1): PRN U1, then C_rs F4 m, delta n F4 rad/ms,
  M0 F8 rad, C_uc F4 rad, e F8, C_us F4 rad, sqrt A F8 m^1/2, t_oe F8 ms, C_ic F4
  rad, Omega0 F8 rad, C_is F4 rad, i0 F8 rad, C_rc F4 m, omega F8 rad, Omega dot F8
  rad/ms, IDOT F8 rad/ms, T_GD F4 ms, t_oc F8 ms, a_f2 F4 ms/ms^2, a_f1 F4 ms/ms,
  a_f0 F4 ms, URA I2 (m), IODE I2, IODC I2, code on L2 I2, L2 P data flag I2, week
  I2.
"""
import struct

import numpy as np

CLIGHT = 299792458.0
GPS, GLONASS = 2, 1
LEAP_S = 18                  # GPS-UTC the encoder states (any value: F5 gives both)


def binr_message(ident, data):
    """DLE, ID, the data with each DLE doubled, DLE ETX."""
    return b"\x10" + bytes([ident]) + data.replace(b"\x10", b"\x10\x10") + b"\x10\x03"


def raw_f5(week, tow_s, sigs, leap_s=LEAP_S):
    """0xF5 of an epoch: ``sigs`` a list of (PRN, pseudorange m, carrier cycles or None,
    Doppler Hz, S/N dB-Hz), all GPS; the time of measurement given in UTC with the
    GPS-UTC shift, as the receiver sends it."""
    data = struct.pack("<dHddb", tow_s * 1000.0 - leap_s * 1000.0, week,
                       leap_s * 1000.0, (leap_s - 10800) * 1000.0, 0)
    for prn, pr, cp, dop, snr in sigs:
        flags = 0x13 | (0x08 if cp is not None else 0)
        data += struct.pack("<BBbbdddBB", GPS, prn, 0, round(snr),
                            0.0 if cp is None else cp, pr / (CLIGHT * 1e-3), dop, flags, 0)
    return binr_message(0xF5, data)


def ephemeris_f7(e, rtk):
    """0xF7 of a GPS ephemeris (an RTKLIB ``eph_t``), in the description's units."""
    w = rtk.Arr1Dint(1)
    toc = rtk.time2gpst(e.toc, w)
    ura = (2, 3, 4, 6, 9, 13, 24, 48, 96, 192, 384, 768, 1536, 3072, 6144)[min(e.sva, 14)]
    data = struct.pack("<BBffdfdfddfdfdfdddfdfffhhhhhh", 1, e.sat, e.crs, e.deln * 1e-3,
                       e.M0, e.cuc, e.e, e.cus, np.sqrt(e.A), e.toes * 1e3, e.cic,
                       e.OMG0, e.cis, e.i0, e.crc, e.omg, e.OMGd * 1e-3, e.idot * 1e-3,
                       e.tgd[0] * 1e3, toc * 1e3, e.f2 * 1e-3, e.f1, e.f0 * 1e3, ura,
                       e.iode, e.iodc, e.code, e.flag, e.week)
    return binr_message(0xF7, data)


def simulation_log(epochs):
    """0xF5 of each epoch of :func:`receiver_frames.simulated_epochs` (L1 C/A: the only
    signal of the message)."""
    return b"".join(raw_f5(w, tow, [(p, *v["L1"]) for p, v in sats.items()])
                    for w, tow, sats in epochs)


def rinex2_to_nvs(path):
    """The GPS C1/L1 observations of a RINEX 2.10 file as 0xF5 messages, the phases as
    they are, the time of measurement the RINEX epoch's; at an L1 loss-of-lock flag
    the phase is sent absent (raw data flag bit 3 off: RTKLIB flags the slip at the
    next epoch, when the bit comes on again).  Also the ``{(tow, "Gnn", "L1")}`` left
    out so."""
    from ubx_frames import read_rinex2_obs
    out, left = b"", set()
    for week, tow, rows in read_rinex2_obs(path):
        sigs = []
        for prn, v in sorted(rows.items()):
            if not prn.startswith("G") or np.isnan(v["C1"][0]):
                continue
            cp, lli = v.get("L1", (np.nan, 0))
            if lli & 1 and not np.isnan(cp):
                left.add((tow, prn, "L1"))
                cp = np.nan
            sigs.append((int(prn[1:]), v["C1"][0], None if np.isnan(cp) else cp, 0.0,
                         45.0))
        out += raw_f5(week, tow, sigs)
    return out, left


def nav_to_nvs(nav_path, rtk):
    """0xF7 of every GPS ephemeris of a RINEX navigation file, and the ephemerides."""
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(nav_path), 1, "", obs, nav, sta)
    ephs = [nav.eph[i] for i in range(nav.n)]
    return b"".join(ephemeris_f7(e, rtk) for e in ephs), ephs
