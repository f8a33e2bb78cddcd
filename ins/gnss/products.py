"""Precise products for RTKLIB: the time spans of SP3 orbit and RINEX clock files,
checked against the observations before RTKLIB runs, and RINEX clock 3.04 files put
into the 3.00 layout that RTKLIB 2.5.0 reads.

Why: RTKLIB's ``postpos`` neither says that a product file misses part of the
observations nor that it could not read one.

- Outside an SP3 file's span a satellite has no orbit; outside a clock file's span
  RTKLIB silently falls back on the SP3 file's clocks (5 or 15 min apart, interpolated)
  and mixes two clock solutions: :func:`check_coverage` refuses both, naming the file,
  its span and the observations'.
- RINEX clock 3.04 (the IGS long file names, e.g. ``COD0MGXFIN_..._CLK.CLK``) writes the
  version line ``F4.2,17X,A1`` and nine-character station/satellite names: RTKLIB 2.5.0
  reads the file type at column 21 of the RINEX 3 layout (``unsupported rinex type``) and
  the epoch after a four-character name, so it reads nothing and the run uses the SP3
  clocks.  :func:`readable_clock` writes a copy in the 3.00 layout (satellite records
  ``AS`` only: RTKLIB uses no receiver clock) that RTKLIB reads.

Times are GPS seconds since 1980-01-06 00:00:00 (the products' time system is GPS for
IGS products; a file that names another is refused).
"""
import calendar
import os

from ins.common.errors import InputError

__all__ = ["sp3_span", "clock_span", "check_coverage", "readable_clock", "gps_seconds",
           "format_gpst", "parse_gpst", "rinex_antenna", "antex_antennas"]

_GPS0 = calendar.timegm((1980, 1, 6, 0, 0, 0))


def gps_seconds(year, month, day, hour, minute, second):
    """GPS seconds since 1980-01-06 of a GPS calendar date (no leap seconds: GPST)."""
    return calendar.timegm((int(year), int(month), int(day), int(hour), int(minute), 0)) \
        - _GPS0 + float(second)


def format_gpst(t):
    """``YYYY-MM-DD hh:mm:ss GPST`` of GPS seconds since 1980-01-06."""
    import time
    return time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime(_GPS0 + round(t))) + " GPST"


def parse_gpst(text, what="time"):
    """GPS seconds since 1980-01-06 of ``YYYY-MM-DDThh:mm:ss`` (or with a space; the
    seconds may have decimals), a date and time in GPST.

    Raises
    ------
    InputError
        Naming ``what`` (e.g. ``--start``) and the expected form.
    """
    import re
    m = re.fullmatch(r"\s*(\d{4})-(\d{1,2})-(\d{1,2})[T ](\d{1,2}):(\d{2}):(\d{2}(?:\.\d*)?)\s*",
                     str(text))
    if m is None:
        raise InputError(f"{what}: expected a GPST date and time YYYY-MM-DDThh:mm:ss, got "
                         f"{text!r}")
    y, mo, d, h, mi = (int(v) for v in m.groups()[:5])
    sec = float(m.group(6))
    if not (1 <= mo <= 12 and 1 <= d <= 31 and h < 24 and mi < 60 and sec < 61):
        raise InputError(f"{what}: not a date and time: {text!r}")
    return gps_seconds(y, mo, d, h, mi, sec)


def _lines(path, what):
    try:
        with open(path, "r", errors="replace") as f:
            return f.read().splitlines()
    except OSError as e:
        raise InputError(f"{what}: cannot read it ({e.strerror})", path=path) from None


def sp3_span(path):
    """(first, last) epoch of an SP3 orbit file, GPS seconds since 1980-01-06.

    Raises
    ------
    InputError
        Naming the file: not SP3 (no ``#`` version line, no ``*`` epoch line), or a
        time system other than GPS.
    """
    path = os.fspath(path)
    what = "precise orbit (SP3)"
    lines = _lines(path, what)
    if not lines or not lines[0].startswith("#") or lines[0][1:2] not in "abcd":
        raise InputError(f"{what}: not an SP3 file (expected '#a'..'#d' on the first line)",
                         path=path)
    for line in lines[:40]:
        if line.startswith("%c") and line[9:12].strip() not in ("", "GPS", "ccc"):
            raise InputError(f"{what}: time system {line[9:12].strip()!r}, expected GPS",
                             path=path)
    epochs = []
    for line in lines:
        if line.startswith("* "):
            f = line[2:].split()
            try:
                epochs.append(gps_seconds(*f[:5], float(f[5])))
            except (ValueError, IndexError):
                raise InputError(f"{what}: bad epoch line {line.strip()!r}", path=path) from None
    if not epochs:
        raise InputError(f"{what}: no epoch ('*' line)", path=path)
    return min(epochs), max(epochs)


def _clock_layout(lines, path):
    """(version, first data line index) of a RINEX clock file."""
    what = "precise clock (RINEX CLK)"
    if not lines or "RINEX VERSION / TYPE" not in lines[0]:
        raise InputError(f"{what}: not a RINEX file (no RINEX VERSION / TYPE line)", path=path)
    head = lines[0]
    try:
        version = float(head[:9])
    except ValueError:
        raise InputError(f"{what}: bad version {head[:9].strip()!r}", path=path) from None
    kind = head[21] if version >= 3.04 else head[20]
    if kind != "C":
        raise InputError(f"{what}: RINEX file of type {kind!r}, expected 'C' (clock)",
                         path=path)
    for i, line in enumerate(lines):
        if "TIME SYSTEM ID" in line and line[3:6].strip() not in ("", "GPS"):
            raise InputError(f"{what}: time system {line[3:6].strip()!r}, expected GPS",
                             path=path)
        if "END OF HEADER" in line:
            return version, i + 1
    raise InputError(f"{what}: no END OF HEADER", path=path)


def clock_span(path):
    """(first, last) epoch of the satellite clocks (``AS`` records) of a RINEX clock
    file, GPS seconds since 1980-01-06.

    Raises
    ------
    InputError
        Naming the file: not a RINEX clock file, no satellite clock, a bad record.
    """
    path = os.fspath(path)
    lines = _lines(path, "precise clock (RINEX CLK)")
    version, start = _clock_layout(lines, path)
    at = 13 if version >= 3.04 else 8               # the epoch after the name
    first = last = None
    for line in lines[start:]:
        if line.startswith("AS "):
            try:
                t = gps_seconds(*line[at:at + 16].split(), float(line[at + 16:at + 26]))
            except (ValueError, TypeError):
                raise InputError(f"precise clock (RINEX CLK): bad record {line.strip()!r}",
                                 path=path) from None
            first = t if first is None else min(first, t)
            last = t if last is None else max(last, t)
    if first is None:
        raise InputError("precise clock (RINEX CLK): no satellite clock (AS record)",
                         path=path)
    return first, last


def readable_clock(path, folder):
    """``path`` itself, or for RINEX clock 3.04 and later a copy in the 3.00 layout
    written into ``folder`` (module notes) that RTKLIB 2.5.0 reads."""
    path = os.fspath(path)
    lines = _lines(path, "precise clock (RINEX CLK)")
    version, start = _clock_layout(lines, path)
    if version < 3.04:
        return path
    system = lines[0][42:43]                        # 3.04: F4.2,17X,A1,20X,A1
    out = [f"{3.0:9.2f}{'':11s}C{'':19s}{system:20s}RINEX VERSION / TYPE"]
    out += lines[1:start]
    out += [line[:7] + line[12:] for line in lines[start:] if line.startswith("AS ")]
    stem = os.path.splitext(os.path.basename(path))[0]
    dst = os.path.join(folder, f"{stem}.rnx300.clk")
    n = 0
    while os.path.exists(dst):                      # two files of the same name
        n += 1
        dst = os.path.join(folder, f"{stem}.{n}.rnx300.clk")
    with open(dst, "w") as f:
        f.write("\n".join(out) + "\n")
    return dst


def _union(spans):
    return min(s[0] for s in spans), max(s[1] for s in spans)


def check_coverage(observed, sp3=(), clk=(), margin_s=0.0):
    """Refuse precise products that do not cover the observations.

    Parameters
    ----------
    observed : (float, float)
        First and last observation epoch, GPS seconds since 1980-01-06.
    sp3, clk : sequence of paths
        The orbit and clock files (their spans are joined: files of consecutive days).
    margin_s : float
        Tolerance at both ends, s.

    Returns
    -------
    dict
        ``{"sp3": (first, last) or None, "clk": (first, last) or None}``.

    Raises
    ------
    InputError
        Naming the file(s), their span and the observations' span.
    """
    t0, t1 = observed
    spans = {}
    for key, paths, reader, what in (("sp3", sp3, sp3_span, "precise orbits (--sp3)"),
                                     ("clk", clk, clock_span, "precise clocks (--clk)")):
        paths = [os.fspath(p) for p in paths]
        if not paths:
            spans[key] = None
            continue
        first, last = _union([reader(p) for p in paths])
        spans[key] = (first, last)
        if first > t0 + margin_s or last < t1 - margin_s:
            raise InputError(f"{what} {', '.join(paths)} cover {format_gpst(first)} to "
                             f"{format_gpst(last)}, not the observations' "
                             f"{format_gpst(t0)} to {format_gpst(t1)}: give the products of "
                             f"the whole span, or process a span within theirs (--start, "
                             f"--end)")
    return spans


def rinex_antenna(path):
    """The antenna type (with its radome, e.g. ``"TRM59800.80 NONE"``) of a RINEX
    observation header's ``ANT # / TYPE`` line, or ``""``."""
    with open(os.fspath(path), "r", errors="replace") as f:
        for line in f:
            if "ANT # / TYPE" in line[60:]:
                return " ".join(line[20:40].split())
            if "END OF HEADER" in line[60:]:
                break
    return ""


def antex_antennas(path):
    """The receiver antenna types (with radome) of an ANTEX file: the ``TYPE / SERIAL
    NO`` entries without a satellite code.

    Raises
    ------
    InputError
        The file is not ANTEX (no ``ANTEX VERSION / SYST`` line).
    """
    path = os.fspath(path)
    lines = _lines(path, "antenna file (ANTEX, --atx)")
    if not lines or "ANTEX VERSION / SYST" not in lines[0]:
        raise InputError("antenna file (ANTEX, --atx): not an ANTEX file (no ANTEX VERSION "
                         "/ SYST line)", path=path)
    out = set()
    for line in lines:
        if "TYPE / SERIAL NO" in line[60:] and not line[20:23].strip():
            out.add(" ".join(line[:20].split()))
    return out
