"""UBX frames written from the u-blox interface description (public): the framing
``B5 62 class id length(U2 LE) payload CK_A CK_B`` with the 8-bit Fletcher checksum over
class..payload, and RXM-RAWX (0x02 0x15) version 1 payloads; and a plain reader of RINEX
2.10 observation files.  Test helpers: the observations of a RINEX file re-encoded as a
u-blox log, to check the conversion against the original values."""
import struct

import numpy as np

#: GPS (gnssId 0) signal ids of RXM-RAWX version 1: L1 C/A, L2 CL
SIG_L1CA, SIG_L2CL = 0, 3


def fletcher(data):
    """UBX checksum (CK_A, CK_B) over ``data`` (class, id, length, payload)."""
    a = b = 0
    for byte in data:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return bytes((a, b))


def frame(cls, msg_id, payload):
    body = struct.pack("<BBH", cls, msg_id, len(payload)) + payload
    return b"\xb5\x62" + body + fletcher(body)


def rawx(week, tow_s, meas):
    """RXM-RAWX frame; ``meas``: (pr_m, cp_cyc, gnss_id, sv_id, sig_id, locktime_ms,
    cno_dbhz) per signal (pr or cp 0: not valid)."""
    head = struct.pack("<dHbBBB2x", tow_s, week, 14, len(meas), 0x01, 1)
    body = b""
    for pr, cp, gnss, sv, sig, lock_ms, cno in meas:
        trk = (0x01 if pr else 0) | (0x06 if cp else 0)    # prValid, cpValid + halfCyc
        body += struct.pack("<ddfBBBBHBBBBBx", pr, cp, 0.0, gnss, sv, sig, 0,
                            min(int(lock_ms), 0xFFFF), cno, 5, 1, 0, trk)
    return frame(0x02, 0x15, head + body)


def read_rinex2_obs(path):
    """Epochs of a RINEX 2.10 observation file: a list of (week, tow_s, {prn: {type:
    (value or nan, lli)}}); event records (flags 2-5) skipped."""
    lines = open(path).read().splitlines()
    k = 0
    types = []
    while "END OF HEADER" not in lines[k]:
        if "# / TYPES OF OBSERV" in lines[k]:
            types += lines[k][6:60].split()
        k += 1
    k += 1
    out = []
    while k < len(lines):
        ep = lines[k]
        if not ep.strip():
            k += 1
            continue
        flag = int(ep[28]) if ep[28].strip() else 0
        n = int(ep[29:32])
        if flag > 1:                                  # event: n header lines follow
            k += 1 + n
            continue
        yy, mo, dd, hh, mi = (int(ep[i:i + 3]) for i in range(0, 15, 3))
        sec = float(ep[15:26])
        sats = ep[32:68].ljust(36)
        for _ in range((n - 1) // 12):             # 12 satellites a line
            k += 1
            sats += lines[k][32:68].ljust(36)
        prns = [sats[3 * i:3 * i + 3] for i in range(n)]
        k += 1
        rows = {}
        per_sat = (len(types) + 4) // 5
        for prn in prns:
            text = "".join(lines[k + j].ljust(80) for j in range(per_sat))
            k += per_sat
            vals = {}
            for j, t in enumerate(types):
                f = text[16 * j:16 * j + 16]
                v = f[:14].strip()
                lli = f[14:15].strip()
                vals[t] = (float(v) if v else np.nan, int(lli) if lli else 0)
            rows[prn.replace(" ", "0")] = vals
        year = 2000 + yy if yy < 80 else 1900 + yy
        days = (np.datetime64(f"{year:04d}-{mo:02d}-{dd:02d}") - np.datetime64("1980-01-06")
                ).astype(int)
        week, dow = divmod(int(days), 7)
        out.append((week, dow * 86400.0 + hh * 3600.0 + mi * 60.0 + sec, rows))
    return out


def rinex2_to_ubx(path):
    """The GPS observations of a RINEX 2.10 file (types C1, L1, P2, L2) as RXM-RAWX
    frames: C1/L1 on L1 C/A, P2/L2 on L2 CL (the values themselves; no Doppler, C/N0 45
    dBHz, lock time counted from the start or the last loss-of-lock flag)."""
    data = b""
    since = {}
    for week, tow, rows in read_rinex2_obs(path):
        meas = []
        for prn, v in sorted(rows.items()):
            if not prn.startswith("G"):
                continue
            sv = int(prn[1:])
            for pr_t, cp_t, sig in (("C1", "L1", SIG_L1CA), ("P2", "L2", SIG_L2CL)):
                pr, cp = v.get(pr_t, (np.nan, 0))[0], v.get(cp_t, (np.nan, 0))
                slip = cp[1] & 1
                key = (sv, sig)
                if slip or key not in since:
                    since[key] = tow
                lock_ms = 1000.0 * (tow - since[key]) + 500.0
                meas.append((0.0 if np.isnan(pr) else pr, 0.0 if np.isnan(cp[0]) else cp[0],
                             0, sv, sig, lock_ms, 45))
        data += rawx(week, tow, meas)
    return data


def read_rinex3_obs(path):
    """Epochs of a RINEX 3 observation file: a list of ((y, mo, d, h, mi, s), {sat:
    {type: value or nan}}) (types of the ``SYS / # / OBS TYPES`` records)."""
    lines = open(path).read().splitlines()
    k = 0
    types = {}
    last = None
    while "END OF HEADER" not in lines[k]:
        if "SYS / # / OBS TYPES" in lines[k]:
            line = lines[k]
            if line[0] != " ":
                last = line[0]
                types[last] = []
            types[last] += line[7:60].split()
        k += 1
    out = []
    for line in lines[k + 1:]:
        if line.startswith(">"):
            f = line[2:].split()
            out.append(((*map(int, f[:5]), float(f[5])), {}))
        elif line.strip():
            sat, rows = line[:3], out[-1][1]
            vals = {}
            for j, t in enumerate(types[sat[0]]):
                v = line[3 + 16 * j:3 + 16 * j + 14].strip()
                vals[t] = float(v) if v else np.nan
            rows[sat] = vals
    return out


SC2RAD = 3.1415926535898            # GPS pi (IS-GPS-200), as RTKLIB scales semicircles


class _Bits:
    """A big-endian bit string of ``n`` bits, filled field by field."""

    def __init__(self, n):
        self.bits = [0] * n

    def put(self, pos, length, value):
        value = int(value) & ((1 << length) - 1)          # two's complement for < 0
        for k in range(length):
            self.bits[pos + k] = (value >> (length - 1 - k)) & 1
        return pos + length

    def words24(self):
        return [int("".join(map(str, self.bits[24 * i:24 * i + 24])), 2) for i in range(10)]


def _q(value, scale):
    """The integer of a broadcast field (value / scale, exact for decoded values)."""
    return int(round(value / scale))


def lnav_subframes(eph, rtk):
    """GPS LNAV subframes 1-3 (IS-GPS-200 layout, 10 x 24 data bits each, parity not
    computed) of an RTKLIB ``eph_t`` read from a RINEX navigation file."""
    w = rtk.Arr1Dint(1)
    toc = rtk.time2gpst(eph.toc, w)
    tow = rtk.time2gpst(eph.ttr, w)
    week = w[0]                          # subframe 1 holds the week of transmission
    out = []
    for sf in (1, 2, 3):
        b = _Bits(240)
        b.put(0, 8, 0x8B)                                 # TLM preamble
        b.put(24, 17, int(tow // 6) + sf - 1)             # HOW: TOW count
        i = b.put(43, 3, sf) + 2
        if sf == 1:
            i = b.put(i, 10, week % 1024)
            i = b.put(i, 2, eph.code)
            i = b.put(i, 4, eph.sva)
            i = b.put(i, 6, eph.svh)
            i = b.put(i, 2, eph.iodc >> 8)
            i = b.put(i, 1, eph.flag) + 87
            i = b.put(i, 8, _q(eph.tgd[0], 2.0 ** -31))
            i = b.put(i, 8, eph.iodc & 0xFF)
            i = b.put(i, 16, _q(toc, 16.0))
            i = b.put(i, 8, _q(eph.f2, 2.0 ** -55))
            i = b.put(i, 16, _q(eph.f1, 2.0 ** -43))
            b.put(i, 22, _q(eph.f0, 2.0 ** -31))
        elif sf == 2:
            i = b.put(i, 8, eph.iode)
            i = b.put(i, 16, _q(eph.crs, 2.0 ** -5))
            i = b.put(i, 16, _q(eph.deln, 2.0 ** -43 * SC2RAD))
            i = b.put(i, 32, _q(eph.M0, 2.0 ** -31 * SC2RAD))
            i = b.put(i, 16, _q(eph.cuc, 2.0 ** -29))
            i = b.put(i, 32, _q(eph.e, 2.0 ** -33))
            i = b.put(i, 16, _q(eph.cus, 2.0 ** -29))
            i = b.put(i, 32, _q(np.sqrt(eph.A), 2.0 ** -19))
            i = b.put(i, 16, _q(eph.toes, 16.0))
            b.put(i, 1, 0 if eph.fit <= 4.0 else 1)
        else:
            i = b.put(i, 16, _q(eph.cic, 2.0 ** -29))
            i = b.put(i, 32, _q(eph.OMG0, 2.0 ** -31 * SC2RAD))
            i = b.put(i, 16, _q(eph.cis, 2.0 ** -29))
            i = b.put(i, 32, _q(eph.i0, 2.0 ** -31 * SC2RAD))
            i = b.put(i, 16, _q(eph.crc, 2.0 ** -5))
            i = b.put(i, 32, _q(eph.omg, 2.0 ** -31 * SC2RAD))
            i = b.put(i, 24, _q(eph.OMGd, 2.0 ** -43 * SC2RAD))
            i = b.put(i, 8, eph.iode)
            b.put(i, 14, _q(eph.idot, 2.0 ** -43 * SC2RAD))
        out.append(b.words24())
    return out


def sfrbx(sv_id, words24):
    """RXM-SFRBX frame (0x02 0x13) of one GPS L1 C/A subframe: 10 words, the 24 data
    bits of each above 6 (zero) parity bits."""
    head = struct.pack("<BBBBBBBx", 0, sv_id, 0, 0, len(words24), 0, 2)
    return frame(0x02, 0x13, head + b"".join(struct.pack("<I", w << 6) for w in words24))


def nav_to_sfrbx(nav_path, rtk):
    """RXM-SFRBX frames of every GPS ephemeris of a RINEX navigation file (read with
    RTKLIB's readrnx), and the ephemerides themselves."""
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(nav_path), 1, "", obs, nav, sta)
    ephs = [nav.eph[i] for i in range(nav.n)]
    data = b""
    for e in ephs:
        for words in lnav_subframes(e, rtk):
            data += sfrbx(e.sat, words)                  # sat number = PRN for GPS
    return data, ephs


def rinex2_to_ubx_with_nav(obs_path, nav_path, rtk):
    """:func:`rinex2_to_ubx` with the ephemerides of ``nav_path`` as RXM-SFRBX frames
    after the first epoch."""
    raw = rinex2_to_ubx(obs_path)
    first = 8 + struct.unpack("<H", raw[4:6])[0]         # end of the first RXM-RAWX frame
    nav, ephs = nav_to_sfrbx(nav_path, rtk)
    return raw[:first] + nav + raw[first:], ephs
