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
