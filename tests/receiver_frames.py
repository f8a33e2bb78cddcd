"""Receiver log frames written from the public format descriptions, to test the
conversion of raw GNSS logs (ins.gnss.receiver_formats) against known values.

- RTCM 10403.3 MSM4 / MSM7 (GPS 1074 / 1077): the frame ``D3``, 6 zero bits, 10-bit
  length, the message, CRC-24Q; the MSM header (DF002 type, DF003 station, DF004 GPS
  epoch time ms, DF393 multiple message bit, DF409 IODS, 7 reserved, DF411 clock
  steering, DF412 external clock, DF417 smoothing, DF418 interval, DF394 satellite mask
  64, DF395 signal mask 32, DF396 cell mask), then the satellite data (DF397 integer ms,
  [MSM7: extended info 4 bits], DF398 range mod 1 ms in 2^-10 ms, [MSM7: DF399 rough
  phase-range rate m/s]) and the signal data (MSM4: DF400 fine pseudorange 15 bits of
  2^-24 ms, DF401 fine phase range 22 bits of 2^-29 ms, DF402 lock indicator 4 bits,
  DF420 half-cycle, DF403 CNR 6 bits of 1 dB-Hz; MSM7: DF405 20 bits of 2^-29 ms, DF406
  24 bits of 2^-31 ms, DF407 lock 10 bits, DF420, DF408 CNR 10 bits of 2^-4 dB-Hz,
  DF404 fine phase-range rate 15 bits of 0.0001 m/s), each field for all satellites
  (cells) before the next; ranges in light-milliseconds (299792.458 m).
- NovAtel OEM4/6/7 binary (OEM7 Commands and Logs Reference Manual): the 28-byte header
  (``AA 44 12 1C``, message ID, type, port, length, sequence, idle, time status 180
  FINESTEERING, GPS week, GPS ms, receiver status, reserved, software build), RANGEB
  (ID 43: number of observations, then per observation PRN U2, GLONASS frequency U2,
  psr F8 m, psr sigma F4, adr F8 cycles (the NEGATIVE of the carrier phase), adr sigma
  F4, Doppler F4 Hz, C/No F4 dB-Hz, lock time F4 s, channel tracking status U4) and
  RAWEPHEMB (ID 41: PRN, reference week, reference seconds, subframes 1-3 of 30 bytes),
  each followed by the manual's CRC-32.
"""
import struct

import numpy as np

CLIGHT = 299792458.0
RANGE_MS = CLIGHT * 0.001
FREQ_L1, FREQ_L2 = 1575.42e6, 1227.60e6

# ---------------------------------------------------------------------------------------
# checksums, written from the format descriptions (the library's are checked against them)


def crc24q_spec(data):
    """CRC-24Q bit by bit (RTCM 10403 section 4: generator 0x1864CFB, seed 0)."""
    crc = 0
    for byte in data:
        crc ^= byte << 16
        for _ in range(8):
            crc <<= 1
            if crc & 0x1000000:
                crc ^= 0x1864CFB
    return crc & 0xFFFFFF


def crc32_novatel_spec(data):
    """The NovAtel manual's CRC32Value / CalculateBlockCRC32 (bitwise form)."""
    crc = 0
    for byte in data:
        c = (crc ^ byte) & 0xFF
        for _ in range(8):
            c = (c >> 1) ^ 0xEDB88320 if c & 1 else c >> 1
        crc = ((crc >> 8) & 0x00FFFFFF) ^ c
    return crc


# ---------------------------------------------------------------------------------------
# RTCM 3

class Bits:
    """A big-endian bit string, appended field by field."""

    def __init__(self):
        self.bits = []

    def put(self, length, value):
        value = int(value) & ((1 << length) - 1)
        self.bits += [(value >> (length - 1 - k)) & 1 for k in range(length)]

    def bytes(self):
        bits = self.bits + [0] * (-len(self.bits) % 8)
        return bytes(int("".join(map(str, bits[i:i + 8])), 2) for i in range(0, len(bits), 8))


def rtcm3_frame(message):
    body = bytes([0xD3, (len(message) >> 8) & 0x03, len(message) & 0xFF]) + message
    return body + crc24q_spec(body).to_bytes(3, "big")


#: MSM signal ids (RTCM 10403.3 table 3.5-91) of GPS L1 C/A and L2 C (L) / L2 P(Y)
MSM_SIG_1C, MSM_SIG_2L, MSM_SIG_2W = 2, 16, 10
_WAVELENGTH = {MSM_SIG_1C: CLIGHT / FREQ_L1, MSM_SIG_2L: CLIGHT / FREQ_L2,
               MSM_SIG_2W: CLIGHT / FREQ_L2}


def msm_gps(kind, tow_s, sats, station=0, last=True):
    """One GPS MSM4 (``kind`` 4) or MSM7 (7) frame of an epoch.

    Parameters
    ----------
    sats : dict
        ``{prn: {sig_id: (pseudorange m, carrier phase cycles, Doppler Hz, cnr dB-Hz,
        lock time s)}}``; a None value is sent as the format's "invalid" (a satellite
        needs one pseudorange for its rough range).
    """
    prns = sorted(sats)
    sigs = sorted({s for v in sats.values() for s in v})
    b = Bits()
    b.put(12, 1070 + kind)
    b.put(12, station)
    b.put(30, round(tow_s * 1000.0))
    b.put(1, 0 if last else 1)
    for length in (3, 7, 2, 2, 1, 3):      # IODS, reserved, clock steering/ext, smoothing
        b.put(length, 0)
    for p in range(1, 65):
        b.put(1, p in prns)
    for s in range(1, 33):
        b.put(1, s in sigs)
    cells = []
    for p in prns:
        for s in sigs:
            b.put(1, s in sats[p])
            if s in sats[p]:
                cells.append((p, s))
    rough, rate = {}, {}                  # ms (to 2^-10 ms), m/s (integer) of each sat
    for p in prns:
        s, v = next((s, v) for s, v in sorted(sats[p].items()) if v[0] is not None)
        rough[p] = round(v[0] / RANGE_MS * 1024.0) / 1024.0
        rate[p] = None if v[2] is None else round(-v[2] * _WAVELENGTH[s])
    for p in prns:
        b.put(8, int(rough[p]))
    if kind == 7:
        for p in prns:
            b.put(4, 0)
    for p in prns:
        b.put(10, round((rough[p] - int(rough[p])) * 1024.0))
    if kind == 7:
        for p in prns:
            b.put(14, -8192 if rate[p] is None else rate[p])
    values = [(p, s, *sats[p][s]) for p, s in cells]
    npr, ncp = (15, 22) if kind == 4 else (20, 24)
    spr, scp = (2 ** 24, 2 ** 29) if kind == 4 else (2 ** 29, 2 ** 31)
    for p, s, pr, *_ in values:
        b.put(npr, -(1 << (npr - 1)) if pr is None else round((pr / RANGE_MS - rough[p]) * spr))
    for p, s, _, cp, *_ in values:
        b.put(ncp, -(1 << (ncp - 1)) if cp is None else
              round((cp * _WAVELENGTH[s] / RANGE_MS - rough[p]) * scp))
    for *_, lock_s in values:
        b.put(4 if kind == 4 else 10, _lock4(lock_s) if kind == 4 else _lock10(lock_s))
    for _ in values:
        b.put(1, 0)                                   # half-cycle ambiguity: none
    for *_, cnr, _ in values:
        if kind == 4:
            b.put(6, round(cnr))
        else:
            b.put(10, round(cnr * 16))
    if kind == 7:
        for p, s, _, _, dop, *_ in values:
            b.put(15, -16384 if dop is None or rate[p] is None else
                  round((-dop * _WAVELENGTH[s] - rate[p]) * 1e4))
    return rtcm3_frame(b.bytes())


def _lock4(t_s):
    """DF402 (table 3.5-74): 0 below 32 ms, then k for t >= 2^(k+4) ms up to 15."""
    ms = t_s * 1000.0
    k = 0
    while k < 15 and ms >= 2 ** (k + 5):
        k += 1
    return k


def _lock10(t_s):
    """DF407 (table 3.5-75): below 64 ms the ms themselves, then coarser steps."""
    ms = int(t_s * 1000.0)
    if ms < 64:
        return ms
    for i, (lo, step, base) in enumerate(((64, 2, 64), (128, 4, 96), (256, 8, 128),
                                          (512, 16, 160), (1024, 32, 192),
                                          (2048, 64, 224), (4096, 128, 256),
                                          (8192, 256, 288), (16384, 512, 320),
                                          (32768, 1024, 352), (65536, 2048, 384),
                                          (131072, 4096, 416), (262144, 8192, 448),
                                          (524288, 16384, 480), (1048576, 32768, 512),
                                          (2097152, 65536, 544), (4194304, 131072, 576),
                                          (8388608, 262144, 608), (16777216, 524288, 640),
                                          (33554432, 1048576, 672))):
        if ms < 2 * lo:
            return base + (ms - lo) // step
    return 704


# ---------------------------------------------------------------------------------------
# NovAtel OEM4

ID_RANGE, ID_RAWEPHEM = 43, 41
#: channel tracking status of a GPS observation (phase lock bit 10, parity known 11,
#: code lock 12, satellite system 16-18 = 0 GPS, signal type 21-25, tracking state 4 PLL)
_TRACK_L1CA = 4 | (1 << 10) | (1 << 11) | (1 << 12) | (0 << 21)
_TRACK_L2PY = 11 | (1 << 10) | (1 << 11) | (1 << 12) | (9 << 21)
TRACK = {"L1": _TRACK_L1CA, "L2": _TRACK_L2PY}


def oem4_frame(msg_id, week, tow_s, body, sequence=0):
    head = struct.pack("<BBBBHbBHHBBHIIHH", 0xAA, 0x44, 0x12, 28, msg_id, 0, 0x20,
                       len(body), sequence, 0, 180, week, round(tow_s * 1000.0), 0, 0,
                       0x3FFF)
    data = head + body
    return data + struct.pack("<I", crc32_novatel_spec(data))


def rangeb(week, tow_s, obs):
    """RANGEB of an epoch: ``obs`` a list of (prn, band "L1"/"L2", psr m, carrier phase
    cycles or None (no phase lock), Doppler Hz, C/No dB-Hz, lock time s)."""
    body = struct.pack("<I", len(obs))
    for prn, band, psr, cp, dop, cno, lock in obs:
        track = TRACK[band] if cp is not None else TRACK[band] & ~(1 << 10)
        body += struct.pack("<HHdfdffffI", prn, 0, psr, 0.02, 0.0 if cp is None else -cp,
                            0.003, dop, cno, lock, track)
    return oem4_frame(ID_RANGE, week, tow_s, body)


def rawephemb(prn, week, tow_s, words24):
    """RAWEPHEMB of one GPS satellite: subframes 1-3, 10 words of 24 data bits each
    (no parity) = 30 bytes a subframe."""
    sub = b"".join(b"".join(w.to_bytes(3, "big") for w in sf) for sf in words24)
    body = struct.pack("<III", prn, week, int(tow_s)) + sub
    return oem4_frame(ID_RAWEPHEM, week, tow_s, body)


# ---------------------------------------------------------------------------------------
# simulated observations

def simulated_epochs(week, tow0, n_epochs=5, prns=(3, 7, 12, 19, 25, 31), seed=1,
                     dt=1.0):
    """Epochs of GPS L1/L2 observations of a simple, smooth simulation: ranges of 20 000
    to 25 000 km drifting at a few hundred m/s, carrier phases = range / wavelength plus
    an integer ambiguity (of at most 2000 cycles: MSM phase ranges stay within 2^-8 ms
    of the rough range), Doppler = -range rate / wavelength, C/N0 in [38, 50] dB-Hz.

    Returns
    -------
    list of (week, tow_s, {prn: {"L1": (psr, cp, dop, cno), "L2": (...)}})
    """
    rng = np.random.default_rng(seed)
    r0 = rng.uniform(20.0e6, 25.0e6, len(prns))
    rdot = rng.uniform(-700.0, 700.0, len(prns))
    amb = rng.integers(-2000, 2000, (len(prns), 2))      # phase range within 400 m
    cno = rng.uniform(38.0, 50.0, (len(prns), 2))
    out = []
    for k in range(n_epochs):
        t = k * dt
        sats = {}
        for i, prn in enumerate(prns):
            r = r0[i] + rdot[i] * t + 0.5 * 0.1 * t * t
            rd = rdot[i] + 0.1 * t
            vals = {}
            for j, (band, f) in enumerate((("L1", FREQ_L1), ("L2", FREQ_L2))):
                lam = CLIGHT / f
                psr = r + (0.0 if j == 0 else 3.1)
                vals[band] = (round(psr, 4), round(r / lam + amb[i, j], 4),
                              round(-rd / lam, 3), round(cno[i, j], 2))
            sats[prn] = vals
        out.append((week, tow0 + t, sats))
    return out


# ---------------------------------------------------------------------------------------
# a RINEX 2 file re-encoded

def _rinex2_arcs(path, pairs):
    """Per epoch ``(week, tow, {prn: {band: (pr, cp, dop, cnr, lock_s)}})`` of the GPS
    satellites of a RINEX 2.10 file, ``pairs`` ``{band: (code type, phase type)}``;
    each phase arc (restarted at a loss-of-lock flag) shifted by the integer number of
    cycles that brings it within half a cycle of its pseudorange at the arc's start
    (returned as ``shifts``: ``{(prn, band, arc start tow): cycles}``), as a receiver
    aligns a new arc (MSM phase ranges must stay near the rough range)."""
    from ubx_frames import read_rinex2_obs
    lam = {"L1": CLIGHT / FREQ_L1, "L2": CLIGHT / FREQ_L2}
    since, shift, shifts, out = {}, {}, {}, []
    for week, tow, rows in read_rinex2_obs(path):
        sats = {}
        for prn, v in sorted(rows.items()):
            if not prn.startswith("G"):
                continue
            sv = int(prn[1:])
            vals = {}
            for band, (pr_t, cp_t) in pairs.items():
                pr = v.get(pr_t, (np.nan, 0))[0]
                cp, lli = v.get(cp_t, (np.nan, 0))
                if np.isnan(pr) and np.isnan(cp):
                    continue
                key = (sv, band)
                if lli & 1 or key not in since or np.isnan(cp) != np.isnan(shift[key]):
                    since[key] = tow
                    shift[key] = (np.nan if np.isnan(cp) or np.isnan(pr)
                                  else float(np.round(cp - pr / lam[band])))
                    shifts[(sv, band, tow)] = shift[key]
                cp_out = None if np.isnan(cp) or np.isnan(shift[key]) else cp - shift[key]
                vals[band] = (None if np.isnan(pr) else pr, cp_out, None, 45.0,
                              tow - since[key] + 0.5)
            if any(x[0] is not None for x in vals.values()):
                sats[sv] = vals
        out.append((week, tow, sats))
    return out, shifts


def rinex2_to_msm(path, kind=7, station=0):
    """The GPS C1/L1 (signal 1C) and P2/L2 (2W) observations of a RINEX 2.10 file as
    MSM4/MSM7 frames, one a epoch; and the phase shifts (:func:`_rinex2_arcs`).  With
    1005 messages the station ids must agree: RTKLIB drops the epoch after a change."""
    epochs, shifts = _rinex2_arcs(path, {"L1": ("C1", "L1"), "L2": ("P2", "L2")})
    sig = {"L1": MSM_SIG_1C, "L2": MSM_SIG_2W}
    data = b""
    for _, tow, sats in epochs:
        data += msm_gps(kind, tow, {p: {sig[b]: v for b, v in bands.items()}
                                    for p, bands in sats.items()}, station=station)
    return data, shifts


def rinex2_to_rangeb(path):
    """The same as RANGEB logs (L1 C/A from C1/L1, L2 P(Y) from P2/L2), with the
    original phases (RANGEB's adr is a double: no shift needed)."""
    from ubx_frames import read_rinex2_obs
    data = b""
    since = {}
    for week, tow, rows in read_rinex2_obs(path):
        obs = []
        for prn, v in sorted(rows.items()):
            if not prn.startswith("G"):
                continue
            for band, (pr_t, cp_t) in (("L1", ("C1", "L1")), ("L2", ("P2", "L2"))):
                pr = v.get(pr_t, (np.nan, 0))[0]
                cp, lli = v.get(cp_t, (np.nan, 0))
                if np.isnan(pr):
                    continue
                key = (prn, band)
                if lli & 1 or key not in since:
                    since[key] = tow
                obs.append((int(prn[1:]), band, pr, None if np.isnan(cp) else cp, 0.0, 45.0,
                            tow - since[key] + 0.5))
        data += rangeb(week, tow, obs)
    return data


def nav_to_rawephemb(nav_path, rtk):
    """RAWEPHEMB logs of every GPS ephemeris of a RINEX navigation file (read with
    RTKLIB's readrnx), and the ephemerides."""
    from ubx_frames import lnav_subframes
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(nav_path), 1, "", obs, nav, sta)
    ephs = [nav.eph[i] for i in range(nav.n)]
    w = rtk.Arr1Dint(1)
    data = b""
    for e in ephs:
        tow = rtk.time2gpst(e.ttr, w)
        data += rawephemb(e.sat, w[0], tow, lnav_subframes(e, rtk))
    return data, ephs


def rtcm1005(station, xyz_m):
    """RTCM 1005 (stationary antenna reference point, no height): DF002, DF003, DF021
    ITRF year 0, DF022-DF024 GPS/GLONASS/Galileo indicators 1/0/0, DF141 physical
    station 0, DF025 X (38 bits of 0.0001 m), DF142 single oscillator 0, a reserved bit,
    DF026 Y, DF364 quarter cycle 0, DF027 Z."""
    b = Bits()
    b.put(12, 1005)
    b.put(12, station)
    b.put(6, 0)
    b.put(1, 1)
    b.put(1, 0)
    b.put(1, 0)
    b.put(1, 0)
    b.put(38, round(xyz_m[0] * 1e4))
    b.put(1, 0)
    b.put(1, 0)
    b.put(38, round(xyz_m[1] * 1e4))
    b.put(2, 0)
    b.put(38, round(xyz_m[2] * 1e4))
    return rtcm3_frame(b.bytes())


def assert_same_solution(reference, solved, horizontal_m, vertical_m, what=""):
    """Two RTKLIB solutions of the GEONET pair (``ins.gnss.rtklib_engine.solve``
    results): the same 120 epochs and fix flags, the positions within ``horizontal_m``
    (north, east) and ``vertical_m`` (down) of each other; returns the largest
    differences N/E/D (m)."""
    from ins.nav.earth import ned_offset
    assert solved.rover_epochs == reference.rover_epochs == 120
    assert np.array_equal(reference.log.time, solved.log.time)
    assert np.array_equal(reference.log.quality, solved.log.quality)
    d = np.abs(ned_offset(reference.log.lla, solved.log.lla)).max(axis=0)
    assert np.all(d[:2] < horizontal_m) and d[2] < vertical_m, (what, d)
    return d
