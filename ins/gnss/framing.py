"""Checksums and frame recognition of binary GNSS receiver formats, to tell a raw log's
format from its content (:func:`ins.gnss.receiver_formats.detect_format`).

Each recogniser counts the frames of its format, in a block of bytes, whose framing AND
checksum are valid: random data (or another format's payload) passes a 16- or 24-bit
check once in 65536 or 16.7 million tries, so the format with the most valid frames is
the file's.  The checksums are written from the formats' public descriptions:

- RTCM 10403.x (RTCM3): ``D3``, 6 reserved zero bits, 10-bit length, payload, CRC-24Q
  (polynomial 0x1864CFB, initial value 0, over the preamble to the payload's end);
- NovAtel OEM4/6/7 binary: ``AA 44 12``, header length, ..., message length (U2 at
  byte 8), CRC-32 (the manual's ``CalculateBlockCRC32``: reflected polynomial
  0xEDB88320, initial value 0, no final inversion) over header and message; Unicore's
  binary the same with ``AA 44 B5``, a 24-byte header and the length at byte 6;
- u-blox UBX: ``B5 62``, class, id, length, 8-bit Fletcher checksum
  (:func:`ins.io.ublox.ubx_checksum`);
- Septentrio SBF: ``$@``, CRC-16 (CCITT polynomial 0x1021, initial value 0) over the
  block from its ID, the length a multiple of 4;
- Swift SBP: ``55``, type, sender, length, CRC-16 CCITT over type..payload;
- SkyTraq: ``A0 A1``, length (big-endian), payload, XOR of the payload, ``0D 0A``;
- Trimble RT17 (GSOF-style packets): ``02`` status, type, length, data, checksum
  (sum of status..data mod 256), ``03``;
- BINEX (UNAVCO's description), the big-endian, regular-CRC, forward records RTKLIB
  decodes: ``E2``, record ID (00-03, 7D-7F), the message length as a 1-4 byte ubnxi,
  message, then over record ID..message (n bytes) an 8-bit XOR (n < 128) or CRC-16
  CCITT, big-endian (n < 4096; RTKLIB reads no longer record); a record counts when
  the next begins right after it (or the data ends);
- Hemisphere ``$BIN``: ``$BIN``, block ID, data length (U2 each), data, the 16-bit
  sum of the data bytes, ``0D 0A``;
- Javad GREIS: the receiver-time message every epoch opens with, ``~~005``, its
  milliseconds of the day (4 bytes) and the GREIS checksum (from 0: rotate left by 2,
  XOR each byte of the ID, length and body; rotated once more);
- NVS BINR, which has no checksum: DLE (``10``), ID, data with each DLE doubled, DLE
  ETX (``10 03``), followed by the next message's DLE (or the data's end); counted
  only for the messages RTKLIB reads whose length and content fit their layout
  (0xF5 raw data: 27 + 30 n bytes, week < 4096, signal types 1/2/4; 0xF7 ephemeris:
  GPS 138 bytes, GLONASS at least 93);
- RTCM 2 (RTCM 10402.3), a bit stream in the 6-of-8 format (bytes ``01xxxxxx``, the
  6 bits first-sent in bit 0; other bytes skipped as RTKLIB does) of 30-bit words
  with the GPS parity (IS-GPS-200 table 20-XIV; the data bits complemented after a
  D30* of 1): a message counts when its header (preamble 0x66, the number of data
  words) and every word pass the parity and the next message's header follows it
  (or the data end).
"""
import struct
import zlib

import numpy as np

from ins.io.ublox import ubx_checksum

__all__ = ["crc24q", "crc32_novatel", "crc16_ccitt", "ubnxi", "greis_checksum", "count_frames",
           "unstuff_binr", "rtcm2_words", "RECOGNISERS"]


def _crc24q_table():
    table = []
    for i in range(256):
        c = i << 16
        for _ in range(8):
            c = ((c << 1) ^ 0x1864CFB) if c & 0x800000 else (c << 1)
        table.append(c & 0xFFFFFF)
    return tuple(table)


_CRC24Q = _crc24q_table()


def crc24q(data):
    """CRC-24Q of RTCM 10403 (Qualcomm; polynomial 0x1864CFB, initial 0, no reflection,
    no final XOR), as an int."""
    c = 0
    for byte in data:
        c = ((c << 8) & 0xFFFFFF) ^ _CRC24Q[(c >> 16) ^ byte]
    return c


def crc32_novatel(data):
    """NovAtel's 32-bit CRC (OEM4/6/7 binary logs): the reflected CRC-32 polynomial
    0xEDB88320 with initial value 0 and no final inversion (the manual's
    ``CalculateBlockCRC32``); that is zlib's CRC-32 with both inversions undone."""
    return (~zlib.crc32(bytes(data), 0xFFFFFFFF)) & 0xFFFFFFFF


def _crc16_table():
    table = []
    for i in range(256):
        c = i << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x1021) if c & 0x8000 else (c << 1)
        table.append(c & 0xFFFF)
    return tuple(table)


_CRC16 = _crc16_table()


def crc16_ccitt(data, value=0):
    """CRC-16 CCITT (polynomial 0x1021, not reflected, initial ``value`` 0 as SBF and
    SBP use it, no final XOR)."""
    c = value
    for byte in data:
        c = ((c << 8) & 0xFFFF) ^ _CRC16[(c >> 8) ^ byte]
    return c


def _scan(data, sync, check):
    """Frames at each occurrence of ``sync`` that ``check(data, k)`` accepts (it returns
    the frame's end or 0): their number, skipping over accepted frames."""
    n, k = 0, data.find(sync)
    while k >= 0:
        end = check(data, k)
        if end:
            n += 1
            k = data.find(sync, end)
        else:
            k = data.find(sync, k + 1)
    return n


def _rtcm3(data, k):
    if k + 6 > len(data) or data[k + 1] & 0xFC:
        return 0
    length = ((data[k + 1] & 0x03) << 8) | data[k + 2]
    end = k + 3 + length
    if end + 3 > len(data):
        return 0
    return end + 3 if crc24q(data[k:end]) == int.from_bytes(data[end:end + 3], "big") else 0


def _oem4(data, k):
    if k + 10 > len(data):
        return 0
    hlen = data[k + 3]
    end = k + hlen + struct.unpack_from("<H", data, k + 8)[0]
    if hlen < 10 or end + 4 > len(data):
        return 0
    crc = struct.unpack_from("<I", data, end)[0]
    return end + 4 if crc32_novatel(data[k:end]) == crc else 0


def _unicore(data, k):
    if k + 8 > len(data):
        return 0
    end = k + 24 + struct.unpack_from("<H", data, k + 6)[0]     # 24-byte header
    if end + 4 > len(data):
        return 0
    crc = struct.unpack_from("<I", data, end)[0]
    return end + 4 if crc32_novatel(data[k:end]) == crc else 0


def _ubx(data, k):
    if k + 8 > len(data):
        return 0
    end = k + 6 + struct.unpack_from("<H", data, k + 4)[0]
    if end + 2 > len(data):
        return 0
    return end + 2 if ubx_checksum(data[k + 2:end]) == data[end:end + 2] else 0


def _sbf(data, k):
    if k + 8 > len(data):
        return 0
    crc, _, length = struct.unpack_from("<HHH", data, k + 2)
    if length < 8 or length % 4 or k + length > len(data):
        return 0
    return k + length if crc16_ccitt(data[k + 4:k + length]) == crc else 0


def _sbp(data, k):
    if k + 8 > len(data):
        return 0
    end = k + 6 + data[k + 5]
    if end + 2 > len(data):
        return 0
    crc = struct.unpack_from("<H", data, end)[0]
    return end + 2 if crc16_ccitt(data[k + 1:end]) == crc else 0


def _skytraq(data, k):
    if k + 7 > len(data):
        return 0
    length = struct.unpack_from(">H", data, k + 2)[0]
    end = k + 4 + length
    if not length or end + 3 > len(data) or data[end + 1:end + 3] != b"\r\n":
        return 0
    x = 0
    for byte in data[k + 4:end]:
        x ^= byte
    return end + 3 if x == data[end] else 0


def _rt17(data, k):
    if k + 6 > len(data) or data[k + 2] not in (0x40, 0x55, 0x57):
        return 0
    end = k + 4 + data[k + 3]
    if end + 2 > len(data) or data[end + 1] != 0x03:
        return 0
    return end + 2 if sum(data[k + 1:end]) & 0xFF == data[end] else 0


def ubnxi(data, k):
    """``(value, number of bytes)`` of the BINEX 1-4 byte unsigned integer at ``k``
    (7 bits a byte with a continuation bit, the 4th byte's 8 bits), or None past the
    end."""
    value = 0
    for i in range(4):
        if k + i >= len(data):
            return None
        byte = data[k + i]
        if i == 3:
            return (value << 8) | byte, 4
        value = (value << 7) | (byte & 0x7F)
        if not byte & 0x80:
            return value, i + 1


_BINEX_RECORDS = (0x00, 0x01, 0x02, 0x03, 0x7D, 0x7E, 0x7F)


def _binex(data, k):
    if k + 4 > len(data) or data[k + 1] not in _BINEX_RECORDS:
        return 0
    got = ubnxi(data, k + 2)
    if got is None:
        return 0
    length, nlen = got
    end = k + 2 + nlen + length                    # the message's end
    n = end - (k + 1)
    if n >= 4096 or end + (1 if n < 128 else 2) > len(data):
        return 0
    if n < 128:
        x = 0
        for byte in data[k + 1:end]:
            x ^= byte
        stop = end + 1 if x == data[end] else 0
    else:
        crc = int.from_bytes(data[end:end + 2], "big")
        stop = end + 2 if crc16_ccitt(data[k + 1:end]) == crc else 0
    # a BINEX file is records end to end: one followed by another's sync (or the
    # block's end) only, which the 8-bit XOR alone would pass once in 256 chances
    return stop if stop and (stop == len(data) or data[stop] == 0xE2) else 0


def _hemisphere(data, k):
    if k + 12 > len(data):
        return 0
    end = k + 8 + struct.unpack_from("<H", data, k + 6)[0]
    if end + 4 > len(data) or data[end + 2:end + 4] != b"\r\n":
        return 0
    total = sum(data[k + 8:end]) & 0xFFFF
    return end + 4 if total == struct.unpack_from("<H", data, end)[0] else 0


def greis_checksum(data):
    """The 8-bit checksum of a Javad GREIS message (``data``: its ID, length and body
    before the checksum byte)."""
    cs = 0
    for byte in data:
        cs = (((cs << 2) | (cs >> 6)) & 0xFF) ^ byte
    return ((cs << 2) | (cs >> 6)) & 0xFF


def _javad(data, k):
    if k + 10 > len(data) or data[k + 2:k + 5] != b"005":
        return 0
    return k + 10 if greis_checksum(data[k:k + 9]) == data[k + 9] else 0


def unstuff_binr(data, k):
    """``(message ID, data, end)`` of the NVS BINR message whose DLE is at ``k`` (the
    doubled DLEs made single; ``end`` just after its DLE ETX), or None: no valid DLE
    framing (a DLE inside followed by neither DLE nor ETX, or no end)."""
    if k + 4 > len(data) or data[k + 1] in (0x10, 0x03):
        return None
    parts, i = [], k + 2
    while True:
        j = data.find(b"\x10", i)
        if j < 0 or j + 1 >= len(data):
            return None
        parts.append(data[i:j])
        if data[j + 1] == 0x03:
            return data[k + 1], b"".join(parts), j + 2
        if data[j + 1] != 0x10:
            return None
        parts.append(b"\x10")
        i = j + 2


def _nvs(data, k):
    got = unstuff_binr(data, k)
    if got is None:
        return 0
    ident, body, end = got
    if end < len(data) and data[end] != 0x10:
        return 0
    if ident == 0xF5:
        n, rest = divmod(len(body) - 27, 30)
        if n < 0 or rest or struct.unpack_from("<H", body, 8)[0] >= 4096 or \
                any(body[27 + 30 * i] not in (1, 2, 4) for i in range(n)):
            return 0
        return end
    if ident == 0xF7 and len(body) >= 2 and (len(body) == 138 if body[0] == 1 else
                                             body[0] == 2 and len(body) >= 93):
        return end
    return 0


#: IS-GPS-200 table 20-XIV: the masks of the data bits d1..d24 (d1 the 24-bit word's
#: top bit) in D25..D30, and whether D29* (0) or D30* (1) of the previous word enters.
_PARITY = tuple((star, sum(1 << (24 - d) for d in bits)) for star, bits in (
    (0, (1, 2, 3, 5, 6, 10, 11, 12, 13, 14, 17, 18, 20, 23)),
    (1, (2, 3, 4, 6, 7, 11, 12, 13, 14, 15, 18, 19, 21, 24)),
    (0, (1, 3, 4, 5, 7, 8, 12, 13, 14, 15, 16, 19, 20, 22)),
    (1, (2, 4, 5, 6, 8, 9, 13, 14, 15, 16, 17, 20, 21, 23)),
    (1, (1, 3, 5, 6, 7, 9, 10, 14, 15, 16, 17, 18, 21, 22, 24)),
    (0, (3, 5, 6, 8, 9, 10, 11, 13, 15, 19, 22, 23, 24))))


def rtcm2_words(data):
    """``(valid, header, data24)`` at every bit of the RTCM 2 bit stream of ``data``
    (bytes): the 30-bit word starting there passes the parity, it is a header's
    first word (preamble 0x66), and its 24 data bits (uncomplemented)."""
    arr = np.frombuffer(bytes(data), dtype=np.uint8)
    arr = arr[(arr & 0xC0) == 0x40]
    bits = ((arr[:, None] >> np.arange(6, dtype=np.uint8)) & 1).reshape(-1)
    n = len(bits) - 29
    if n <= 2:
        return np.zeros(0, bool), np.zeros(0, bool), np.zeros(0, np.int64)
    word = np.zeros(n, dtype=np.int64)
    for j in range(30):
        word = (word << 1) | bits[j:j + n]
    d29 = np.concatenate(([0, 0], bits[:n - 2])).astype(np.int64)
    d30 = np.concatenate(([0], bits[:n - 1])).astype(np.int64)
    d = (word >> 6) ^ (d30 * 0xFFFFFF)
    valid = np.ones(n, bool)
    for k, (star, mask) in enumerate(_PARITY):
        p = (np.bitwise_count(d & mask) & 1) ^ (d30 if star else d29)
        valid &= p == ((word >> (5 - k)) & 1)
    return valid, valid & ((d >> 16) == 0x66), d


def _rtcm2_count(data):
    """The RTCM 2 messages in ``data`` (module notes)."""
    valid, header, d = rtcm2_words(data)
    n, count, i = len(valid), 0, 0
    starts = np.flatnonzero(header)
    for k in starts:
        if k < i or k + 30 >= n or not valid[k + 30]:
            continue
        end = k + 30 * (((d[k + 30] >> 3) & 0x1F) + 2)
        if end <= n + 29 and all(valid[j] for j in range(k + 60, min(end, n), 30)) and \
                (end >= n or header[end]):
            count, i = count + 1, end
    return count


#: format name -> (sync bytes, frame check).
RECOGNISERS = {
    "ubx": (b"\xb5\x62", _ubx),
    "rtcm3": (b"\xd3", _rtcm3),
    "oem4": (b"\xaa\x44\x12", _oem4),
    "unicore": (b"\xaa\x44\xb5", _unicore),
    "sbf": (b"$@", _sbf),
    "swift": (b"\x55", _sbp),
    "skytraq": (b"\xa0\xa1", _skytraq),
    "rt17": (b"\x02", _rt17),
    "binex": (b"\xe2", _binex),
    "javad": (b"~~", _javad),
    "hemisphere": (b"$BIN", _hemisphere),
    "nvs": (b"\x10", _nvs),
}


def count_frames(data):
    """``{format: number of valid frames}`` in ``data`` (bytes) for the formats of
    :data:`RECOGNISERS` (zero counts left out)."""
    counts = {name: _scan(data, sync, check) for name, (sync, check) in RECOGNISERS.items()}
    counts["rtcm2"] = _rtcm2_count(data)
    return {k: v for k, v in counts.items() if v}
