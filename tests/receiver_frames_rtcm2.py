"""RTCM 2 messages written from RTCM 10402.3 ("RTCM Recommended Standards for
Differential GNSS Service, Version 2.3"), to test the conversion of RTCM 2 logs
(ins.gnss.receiver_formats) against known values.

- 30-bit words, the GPS navigation message's (IS-GPS-200 table 20-XIV): 24 data bits
  d1..d24 then 6 parity bits D25..D30 from the data and the previous word's D29*,
  D30*; when D30* is 1 the data bits are sent complemented.
- The 6-of-8 format: each byte carries 6 bits of the word stream in bits 0..5, the
  first sent in bit 0 ("byte roll"), with bits 7..6 = 01 (marking, spacing).
- Header: word 1 preamble 0x66 (8 bits), message type (6), reference station ID
  (10); word 2 modified Z-count (13 bits, 0.6 s within the hour), sequence number
  (3), number of data words (5), station health (3).
- Type 3, reference station parameters: ECEF X, Y, Z, 32 bits each, 0.01 m.
- Type 18, uncorrected carrier phases: frequency indicator F (2 bits: 0 L1, 2 L2),
  2 spare, GNSS time of measurement (20 bits, us past the Z-count); then two words a
  satellite: multiple message indicator M (1: another message of this epoch
  follows), P-code indicator, GLONASS, satellite ID (5, 0 for 32), data quality (3),
  cumulative loss-of-continuity indicator (5), carrier phase (32 bits signed, 1/256
  cycle; full cycles rolling over; of the sign opposite to RINEX's as RTKLIB reads
  it).
- Type 19, uncorrected pseudoranges: F (2), smoothing interval (2), time of
  measurement (20); two words a satellite: M, P-code indicator, GLONASS, satellite
  ID (5), data quality (4), multipath error (4), pseudorange (32 bits unsigned,
  0.02 m).
"""
import numpy as np

#: IS-GPS-200 table 20-XIV: the data bits (1..24) in each parity bit, and which of
#: D29* (29) / D30* (30) of the previous word enters it.
PARITY = ((29, (1, 2, 3, 5, 6, 10, 11, 12, 13, 14, 17, 18, 20, 23)),
          (30, (2, 3, 4, 6, 7, 11, 12, 13, 14, 15, 18, 19, 21, 24)),
          (29, (1, 3, 4, 5, 7, 8, 12, 13, 14, 15, 16, 19, 20, 22)),
          (30, (2, 4, 5, 6, 8, 9, 13, 14, 15, 16, 17, 20, 21, 23)),
          (30, (1, 3, 5, 6, 7, 9, 10, 14, 15, 16, 17, 18, 21, 22, 24)),
          (29, (3, 5, 6, 8, 9, 10, 11, 13, 15, 19, 22, 23, 24)))


def words30(data24, d29=0, d30=0):
    """The 30-bit words (as sent: complemented after a D30* of 1) of the 24-bit data
    words ``data24``, the first after a word ending in ``d29``, ``d30``."""
    out = []
    for d in data24:
        bits = [(d >> (23 - i)) & 1 for i in range(24)]          # d1..d24
        par = []
        for star, members in PARITY:
            p = d29 if star == 29 else d30
            for m in members:
                p ^= bits[m - 1]
            par.append(p)
        sent = [b ^ d30 for b in bits] + par
        out.append(int("".join(map(str, sent)), 2))
        d29, d30 = par[4], par[5]
    return out


def six_of_eight(words):
    """The bytes of 30-bit words in the 6-of-8 format (5 bytes a word)."""
    out = bytearray()
    for w in words:
        for k in range(5):
            six = (w >> (24 - 6 * k)) & 0x3F                      # sent first: bit 5
            out.append(0x40 | int(f"{six:06b}"[::-1], 2))
    return bytes(out)


class _Bits:
    def __init__(self):
        self.bits = []

    def put(self, n, value):
        value = int(value) & ((1 << n) - 1)
        self.bits += [(value >> (n - 1 - i)) & 1 for i in range(n)]

    def words24(self):
        bits = self.bits + [0] * (-len(self.bits) % 24)
        return [int("".join(map(str, bits[i:i + 24])), 2) for i in range(0, len(bits), 24)]


class Writer:
    """Messages of one station in sequence (parity chained over the stream)."""

    def __init__(self, station=1):
        self.station, self.seq, self.d29, self.d30, self.out = station, 0, 0, 0, b""

    def message(self, mtype, tow_s, body):
        """Append a message of type ``mtype`` (``body``: a :class:`_Bits` of whole
        words), the Z-count of ``tow_s`` (its 0.6 s within the hour)."""
        sec = tow_s % 3600.0
        z = int(np.floor(sec / 0.6 + 1e-9))
        data = body.words24()
        head = _Bits()
        head.put(8, 0x66)
        head.put(6, mtype)
        head.put(10, self.station)
        head.put(13, z)
        head.put(3, self.seq)
        head.put(5, len(data))
        head.put(3, 0)
        words = words30(head.words24() + data, self.d29, self.d30)
        self.d29, self.d30 = (words[-1] >> 1) & 1, words[-1] & 1
        self.seq = (self.seq + 1) % 8
        self.out += six_of_eight(words)
        return sec - z * 0.6

    def type3(self, tow_s, xyz_m):
        b = _Bits()
        for v in xyz_m:
            b.put(32, round(v / 0.01))
        self.message(3, tow_s, b)

    def obs(self, tow_s, sats, last_types=(18, 19)):
        """Types 18 and 19 for L1 and L2 of an epoch: ``sats`` ``{prn: {"L1": (pr m,
        carrier cycles or None, p_code, loss count), "L2": (...)}}``."""
        sec = tow_s % 3600.0
        usec = round((sec - np.floor(sec / 0.6 + 1e-9) * 0.6) * 1e6)
        plan = [(t, f) for t in (18, 19) for f in ("L1", "L2")
                if any(f in v for v in sats.values())]
        for n, (mtype, band) in enumerate(plan):
            more = n + 1 < len(plan)
            b = _Bits()
            b.put(2, 0 if band == "L1" else 2)
            b.put(2, 0)
            b.put(20, usec)
            for prn in sorted(sats):
                if band not in sats[prn]:
                    continue
                pr, cp, pcode, loss = sats[prn][band]
                if mtype == 18 and cp is None:
                    continue
                b.put(1, more)
                b.put(1, pcode)
                b.put(1, 0)
                b.put(5, prn % 32)
                if mtype == 18:
                    b.put(3, 0)
                    b.put(5, loss)
                    b.put(32, -round(cp * 256.0))          # two's complement, wrapped
                else:
                    b.put(8, 0)
                    b.put(32, round(pr / 0.02))
            self.message(mtype, tow_s, b)


def simulation_log(epochs, xyz=(-3978242.4348, 3382841.1715, 3649902.7667), station=1):
    """Type 3 then types 18/19 (L1 C/A, L2 P) of each epoch of
    :func:`receiver_frames.simulated_epochs`."""
    w = Writer(station)
    w.type3(epochs[0][1], xyz)
    for _, tow, sats in epochs:
        w.obs(tow, {p: {"L1": (v["L1"][0], v["L1"][1], 0, 0),
                        "L2": (v["L2"][0], v["L2"][1], 1, 0)} for p, v in sats.items()})
    return w.out


def rinex2_to_rtcm2(path, xyz, station=1):
    """Type 3 (``xyz``) then the GPS C1/L1 (C/A) and P2/L2 (P code) observations of a
    RINEX 2.10 file as types 18/19 each epoch, the loss-of-continuity count raised
    at each loss-of-lock flag."""
    from ubx_frames import read_rinex2_obs
    w, loss = Writer(station), {}
    epochs = read_rinex2_obs(path)
    w.type3(epochs[0][1], xyz)
    for _, tow, rows in epochs:
        sats = {}
        for prn, v in sorted(rows.items()):
            if not prn.startswith("G") or np.isnan(v["C1"][0]):
                continue
            m = {}
            for band, c, pcode in (("L1", "C1", 0), ("L2", "P2", 1)):
                pr = v.get(c, (np.nan, 0))[0]
                cp, lli = v.get(band, (np.nan, 0))
                if np.isnan(pr):
                    continue
                key = (prn, band)
                loss[key] = (loss.get(key, 0) + (lli & 1)) % 32
                m[band] = (pr, None if np.isnan(cp) else cp, pcode, loss[key])
            sats[int(prn[1:])] = m
        w.obs(tow, sats)
    return w.out
