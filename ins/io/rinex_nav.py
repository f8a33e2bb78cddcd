"""GPS broadcast ephemerides from RINEX 2.x / 3.x navigation files (own parser).

Only the GPS records are read (a RINEX 2 ``N`` file, or the ``G`` records of a RINEX 3
``N`` file); records of other systems are skipped.  The header's Klobuchar coefficients
(RINEX 2 ``ION ALPHA`` / ``ION BETA``, RINEX 3 ``IONOSPHERIC CORR`` ``GPSA`` / ``GPSB``)
and ``LEAP SECONDS`` are kept.  Every record is eight lines: the epoch line (PRN, time of
clock, ``af0 af1 af2``) and seven "broadcast orbit" lines of four numbers (``D`` or ``E``
exponents), in the order of the RINEX specification (IS-GPS-200 names and units: s,
s/s, s/s^2, m, rad, rad/s, sqrt(m)).

Times are GPS time as (week, seconds of week): the clock epoch ``toc`` from the record's
calendar date, ``toe`` from the record with the record's (continuous) GPS week.

:func:`span_text` gives the header and the records of a time span verbatim (the copy
of the navigation file that goes beside simulated observations).
"""
import datetime as _dt
from dataclasses import dataclass

from ins.common.errors import InputError

__all__ = ["GpsEphemeris", "NavData", "read_gps_nav", "gps_week_sow", "span_text",
           "SECONDS_PER_WEEK"]

SECONDS_PER_WEEK = 604800.0
_GPS_EPOCH = _dt.datetime(1980, 1, 6)

#: Names of the 29 numbers of a GPS record after the clock epoch, in file order.
_FIELDS = ("af0", "af1", "af2",
           "iode", "crs", "delta_n", "m0",
           "cuc", "e", "cus", "sqrt_a",
           "toe", "cic", "omega0", "cis",
           "i0", "crc", "omega", "omega_dot",
           "idot", "l2_codes", "week", "l2p_flag",
           "sv_accuracy", "health", "tgd", "iodc",
           "transmission_time", "fit_interval")


@dataclass(frozen=True)
class GpsEphemeris:
    """One GPS broadcast ephemeris (IS-GPS-200 Table 20-III, SI units).

    Attributes
    ----------
    prn : int
    week : int
        GPS week of ``toe`` (continuous, from the record).
    toc : float
        Time of clock, GPS s of week ``toc_week``.
    toc_week : int
    af0, af1, af2 : float
        Clock polynomial, s, s/s, s/s^2.
    iode, iodc : int
    crs, crc, cus, cuc, cis, cic : float
        Harmonic corrections: m (``crs``, ``crc``), rad (the others).
    delta_n, m0, omega0, i0, omega, omega_dot, idot : float
        rad, rad/s.
    e : float
        Eccentricity.
    sqrt_a : float
        sqrt(m).
    toe : float
        Time of ephemeris, GPS s of week ``week``.
    tgd : float
        Group delay L1-L2, s.
    health : int
    sv_accuracy : float
        URA, m.
    fit_interval : float
        h (0: 4 h).
    """

    prn: int
    week: int
    toc: float
    toc_week: int
    af0: float
    af1: float
    af2: float
    iode: int
    crs: float
    delta_n: float
    m0: float
    cuc: float
    e: float
    cus: float
    sqrt_a: float
    toe: float
    cic: float
    omega0: float
    cis: float
    i0: float
    crc: float
    omega: float
    omega_dot: float
    idot: float
    sv_accuracy: float
    health: int
    tgd: float
    iodc: int
    fit_interval: float


@dataclass(frozen=True)
class NavData:
    """The GPS content of a RINEX navigation file.

    Attributes
    ----------
    ephemerides : tuple of GpsEphemeris
        In file order.
    ion_alpha, ion_beta : tuple of 4 float or None
        Klobuchar coefficients (s, s/semicircle, s/semicircle^2, s/semicircle^3; and s,
        s/semicircle, ...), None when the header has none.
    leap_seconds : int or None
    version : float
    path : str
    """

    ephemerides: tuple
    ion_alpha: tuple | None
    ion_beta: tuple | None
    leap_seconds: int | None
    version: float
    path: str

    def prns(self):
        """Sorted PRNs with at least one ephemeris."""
        return sorted({e.prn for e in self.ephemerides})


def gps_week_sow(year, month, day, hour, minute, second):
    """GPS week and seconds of week of a GPS-time calendar date (``second`` may be float)."""
    d = _dt.datetime(int(year), int(month), int(day), int(hour), int(minute))
    delta = (d - _GPS_EPOCH).total_seconds() + float(second)
    week = int(delta // SECONDS_PER_WEEK)
    return week, delta - week * SECONDS_PER_WEEK


def _numbers(text, start, count, path, line):
    out = []
    for k in range(count):
        field = text[start + 19 * k:start + 19 * (k + 1)].strip()
        if not field:
            out.append(0.0)      # blank optional fields (spare, fit interval) read as 0
            continue
        try:
            out.append(float(field.replace("D", "E").replace("d", "e")))
        except ValueError:
            raise InputError(f"expected a number (D19.12) in columns {start + 19 * k + 1}-"
                             f"{start + 19 * (k + 1)}, got {field!r}", path=path,
                             line=line) from None
    return out


def _header(lines, path):
    version, alpha, beta, leap = None, None, None, None
    for k, line in enumerate(lines):
        label = line[60:].strip()
        if label == "RINEX VERSION / TYPE":
            try:
                version = float(line[:9])
            except ValueError:
                raise InputError("bad RINEX version", path=path, line=k + 1) from None
            kind, system = line[20:21].upper(), line[40:41].upper()
            if kind not in ("N", "G") or (version >= 3 and system not in ("G", "M", " ", "")):
                raise InputError("not a GPS navigation file (RINEX VERSION / TYPE)",
                                 path=path, line=k + 1)
        elif label == "ION ALPHA":
            alpha = tuple(_ion(line[2:50], path, k + 1))
        elif label == "ION BETA":
            beta = tuple(_ion(line[2:50], path, k + 1))
        elif label == "IONOSPHERIC CORR" and line[:4] in ("GPSA", "GPSB"):
            vals = tuple(_ion(line[5:53], path, k + 1))
            if line[:4] == "GPSA":
                alpha = vals
            else:
                beta = vals
        elif label == "LEAP SECONDS":
            try:
                leap = int(line[:6])
            except ValueError:
                pass
        elif label == "END OF HEADER":
            if version is None:
                raise InputError("no RINEX VERSION / TYPE line", path=path, line=1)
            return version, alpha, beta, leap, k + 1
    raise InputError("no END OF HEADER line (expected a RINEX navigation file)", path=path)


def _ion(text, path, line):
    parts = text.replace("D", "E").replace("d", "e").split()
    if len(parts) != 4:
        # fixed width 4 x D12.4 without separating blanks
        parts = [text[12 * k:12 * (k + 1)].replace("D", "E") for k in range(4)]
    try:
        return [float(p) for p in parts]
    except ValueError:
        raise InputError("expected 4 Klobuchar coefficients (D12.4)", path=path,
                         line=line) from None


def _record(lines, k, version, path):
    """The GPS record starting at ``lines[k]`` (or None for another system), next index."""
    first = lines[k]
    if version >= 3:
        system = first[0]
        n_lines = {"G": 8, "E": 8, "J": 8, "C": 8, "I": 8, "R": 4, "S": 4}.get(system)
        if n_lines is None:
            raise InputError(f"unknown satellite system {system!r}", path=path, line=k + 1)
        if system != "G":
            return None, k + n_lines
        try:
            prn = int(first[1:3])
            date = [int(first[4:8])] + [int(first[9 + 3 * j:11 + 3 * j]) for j in range(5)]
        except ValueError:
            raise InputError("bad epoch line of a GPS record (expected Gnn yyyy mm dd hh mm "
                             "ss)", path=path, line=k + 1) from None
        start, orbit_start = 23, 4
    else:
        try:
            prn = int(first[0:2])
            yy = int(first[3:5])
            date = [yy + (2000 if yy < 80 else 1900)] + [int(first[6 + 3 * j:8 + 3 * j])
                                                        for j in range(4)]
            date.append(float(first[17:22]))
        except ValueError:
            raise InputError("bad epoch line of a GPS record (expected PRN yy mm dd hh mm "
                             "ss.s)", path=path, line=k + 1) from None
        start, orbit_start = 22, 3
    if k + 8 > len(lines):
        raise InputError("truncated GPS record (expected 8 lines)", path=path, line=k + 1)
    values = _numbers(first, start, 3, path, k + 1)
    for j in range(1, 8):
        values += _numbers(lines[k + j].ljust(orbit_start + 76), orbit_start, 4, path,
                           k + j + 1)
    v = dict(zip(_FIELDS, values))
    toc_week, toc = gps_week_sow(*date)
    eph = GpsEphemeris(
        prn=prn, week=int(v["week"]), toc=toc, toc_week=toc_week,
        af0=v["af0"], af1=v["af1"], af2=v["af2"], iode=int(v["iode"]), crs=v["crs"],
        delta_n=v["delta_n"], m0=v["m0"], cuc=v["cuc"], e=v["e"], cus=v["cus"],
        sqrt_a=v["sqrt_a"], toe=v["toe"], cic=v["cic"], omega0=v["omega0"], cis=v["cis"],
        i0=v["i0"], crc=v["crc"], omega=v["omega"], omega_dot=v["omega_dot"],
        idot=v["idot"], sv_accuracy=v["sv_accuracy"], health=int(v["health"]),
        tgd=v["tgd"], iodc=int(v["iodc"]), fit_interval=v["fit_interval"])
    if not (1 <= prn <= 32) or eph.sqrt_a < 1000.0:
        raise InputError(f"implausible GPS record (PRN {prn}, sqrt(A) {eph.sqrt_a} sqrt(m))",
                         path=path, line=k + 1)
    return eph, k + 8


def read_gps_nav(path):
    """Read the GPS ephemerides and the Klobuchar coefficients of a RINEX nav file.

    Parameters
    ----------
    path : str or os.PathLike
        RINEX 2.x GPS (``.yyn``) or 3.x navigation file.

    Returns
    -------
    NavData

    Raises
    ------
    InputError
        Missing file, not a navigation file, a malformed record (naming the line).
    """
    path = str(path)
    try:
        with open(path, encoding="ascii", errors="replace") as f:
            lines = f.read().splitlines()
    except OSError as exc:
        raise InputError(f"cannot read the RINEX navigation file ({exc.strerror})",
                         path=path) from None
    version, alpha, beta, leap, k = _header(lines, path)
    ephs = []
    while k < len(lines):
        if not lines[k].strip():
            k += 1
            continue
        eph, k = _record(lines, k, version, path)
        if eph is not None:
            ephs.append(eph)
    if not ephs:
        raise InputError("no GPS ephemeris in the navigation file", path=path)
    return NavData(tuple(ephs), alpha, beta, leap, version, path)


def span_text(path, week, t_first, t_last, margin_s=7200.0):
    """Header and the GPS records of a RINEX 2/3 nav file whose ``toc`` lies within
    ``margin_s`` of ``[t_first, t_last]`` (GPS s of week ``week``), verbatim.

    Returns
    -------
    str
        The text of the shortened navigation file (same version and header).
    """
    path = str(path)
    with open(path, encoding="ascii", errors="replace") as f:
        lines = f.read().splitlines()
    version, _, _, _, k = _header(lines, path)
    out = lines[:k]
    while k < len(lines):
        if not lines[k].strip():
            k += 1
            continue
        eph, k_next = _record(lines, k, version, path)
        if eph is not None:
            t = (eph.toc_week - week) * SECONDS_PER_WEEK + eph.toc
            if t_first - margin_s <= t <= t_last + margin_s:
                out.extend(lines[k:k_next])
        k = k_next
    return "\n".join(out) + "\n"
