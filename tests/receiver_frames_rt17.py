"""Trimble RT-17 packets written from Trimble's public Serial Reference Specification
(the RAWDATA 57h "real-time survey data" report, as in the OEM BD9xx receivers' ICD),
to test the conversion of RT-17 logs (ins.gnss.receiver_formats) against known values.

- Packet: STX ``02``, status, packet type (57h RAWDATA), length (of the data), data,
  checksum (the sum of status, type, length and data modulo 256), ETX ``03``.
  RAWDATA data: record type (0: real-time GPS survey data, "type 17"), page (the
  page's number in the high nibble, the number of pages in the low one), reply number,
  record interpretation flags (bit 0 concise format, bit 1 enhanced), then the record's
  bytes, split over pages of at most 244 bytes.  Numbers are big-endian.
- Type 17 record, concise: receive time F8 (ms of the GPS week), clock offset F8 (ms,
  0 unknown), number of satellites U1, then per satellite: PRN U1, FLAGS1 U1 (bit 0 L2
  data loaded, 1 L1 cycle slip, 2 L2 cycle slip, 4 L1 phase valid, 5 L2 range and
  phase valid, 6 L1 data valid), FLAGS2 U1 (bit 0 L1 P code, 1 L2 P code, 2 L2
  encrypted code), elevation I1 deg, azimuth I2 deg, [L1 data] signal strength U1
  (dB x 4), pseudorange F8 m, continuous phase F8 cycles (Trimble's sign: the
  NEGATIVE of the RINEX phase), Doppler F4 Hz; [L2 data] signal strength U1, phase
  F8 cycles (negative), range minus the L1 range F4 m.
The record gives no GPS week: RTKLIB takes it from the computer's clock (set by the
conversion from the navigation files or, for a base, the rover's first epoch).
"""
import struct

from receiver_frames import _rinex2_arcs

RAWDATA = 0x57


def rt17_packets(record_type, record, rif=0x01, reply=0, status=0):
    """The record split into RAWDATA pages, each a packet."""
    chunks = [record[i:i + 244] for i in range(0, len(record), 244)] or [b""]
    out = b""
    for k, chunk in enumerate(chunks):
        data = bytes([record_type, ((k + 1) << 4) | len(chunks), reply & 0xFF, rif]) + chunk
        body = bytes([status, RAWDATA, len(data)]) + data
        out += b"\x02" + body + bytes([sum(body) & 0xFF, 0x03])
    return out


def type17(tow_s, sats, reply=0):
    """A concise type 17 record of an epoch: ``sats`` ``{prn: {"L1": (psr m, carrier
    cycles or None, Doppler Hz or None, C/N0 dB-Hz, slip), "L2": (psr, carrier, _,
    C/N0, slip)}}`` (an L2 needs its phase: one flag tells range and phase valid)."""
    rec = struct.pack(">ddB", tow_s * 1000.0, 0.0, len(sats))
    for prn, bands in sorted(sats.items()):
        l1, l2 = bands.get("L1"), bands.get("L2")
        f1 = 0x40 | (0x10 if l1[1] is not None else 0) | (0x02 if l1[4] else 0)
        if l2 is not None:
            f1 |= 0x01 | 0x20 | (0x04 if l2[4] else 0)
        rec += struct.pack(">BBBbh", prn, f1, 0x04 if l2 is not None else 0, 45, 180)
        pr, cp, dop, cno, _ = l1
        rec += struct.pack(">Bddf", round(cno * 4), pr, 0.0 if cp is None else -cp,
                           0.0 if dop is None else dop)
        if l2 is not None:
            rec += struct.pack(">Bdf", round(l2[3] * 4), -l2[1], l2[0] - pr)
    return rt17_packets(0, rec, reply=reply)


def simulation_log(epochs):
    """Type 17 records of each epoch of :func:`receiver_frames.simulated_epochs`."""
    return b"".join(type17(tow, {p: {"L1": v["L1"] + (False,), "L2": v["L2"] + (False,)}
                                 for p, v in sats.items()}, reply=k)
                    for k, (_, tow, sats) in enumerate(epochs))


def rinex2_to_rt17(path):
    """The GPS C1/L1 and P2/L2 observations of a RINEX 2.10 file as type 17 records
    (the phases shifted near the ranges like a receiver's new arcs, the slip flag at
    an arc's start; a double would hold the file's phases, the shift keeps the
    comparison the same as for the other formats); an L2 without its phase, or a
    satellite without C1, left out.  Returns the packets, the shifts and the left out
    ``{(tow, "Gnn", band)}``."""
    epochs, shifts = _rinex2_arcs(path, {"L1": ("C1", "L1"), "L2": ("P2", "L2")})
    data, left = b"", set()
    for k, (_, tow, sats) in enumerate(epochs):
        meas = {}
        for p, bands in sats.items():
            l1, l2 = bands.get("L1"), bands.get("L2")
            if l1 is None or l1[0] is None:
                left |= {(tow, f"G{p:02d}", b) for b in bands}
                continue
            m = {"L1": (l1[0], l1[1], None, l1[3], l1[4] < 1.0)}
            if l2 is not None:
                if l2[0] is None or l2[1] is None:
                    left.add((tow, f"G{p:02d}", "L2"))
                else:
                    m["L2"] = (l2[0], l2[1], None, l2[3], l2[4] < 1.0)
            meas[p] = m
        data += type17(tow, meas, reply=k)
    return data, shifts, left

