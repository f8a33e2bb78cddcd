"""RINEX 3.04 observation files (GPS): the writer of simulated raw observations.

:func:`write_rinex3_obs` writes a header (version, program, marker, receiver and antenna
lines, ``APPROX POSITION XYZ`` in ECEF m, ``SYS / # / OBS TYPES``, ``INTERVAL``, ``TIME OF
FIRST OBS`` in GPS time, ``SYS / PHASE SHIFT``, ``GLONASS COD/PHS/BIS``, ``LEAP SECONDS``)
and one epoch record per epoch (``> yyyy mm dd hh mm ss.sssssss  0 n``, then one line per
satellite ``Gnn`` with F14.3 values each followed by the loss-of-lock indicator LLI and the
signal-strength indicator SSI, one digit each, blank when 0).  Units are those of RINEX:
pseudorange m, carrier phase cycles, Doppler Hz, signal strength dB-Hz.  Epochs are the
receiver's clock times (RINEX: "epoch in receiver time").

The file is written atomically (:func:`ins.common.fileio.atomic_open`).
"""
import math

import numpy as np

from ins.common.fileio import atomic_open
from ins.io.rinex_nav import SECONDS_PER_WEEK

__all__ = ["write_rinex3_obs", "gps_calendar", "LLI_SLIP"]

#: LLI bit 0: lost lock between the previous and this observation (cycle slip possible).
LLI_SLIP = 1
_MAX_VALUE = 9999999999.999


def gps_calendar(week, sow):
    """Calendar date (year, month, day, hour, minute, seconds float) of GPS week + s."""
    import datetime as dt
    total = week * SECONDS_PER_WEEK + sow
    whole = math.floor(total)
    d = dt.datetime(1980, 1, 6) + dt.timedelta(seconds=int(whole))
    return d.year, d.month, d.day, d.hour, d.minute, d.second + (total - whole)


def _hline(text, label):
    return f"{text:<60.60s}{label:<20s}\n"


def header_start(file_type, calendar, marker, comments, program="ins simulate",
                 observer=("simulator", "insphoto"), receiver="SIMULATED",
                 antenna="SIMULATED", approx_xyz_m=(0.0, 0.0, 0.0)):
    """The lines of a RINEX 3.04 observation header from RINEX VERSION / TYPE to
    ANTENNA: DELTA H/E/N (a list of 81-character strings with the newline): ``file_type``
    the satellite-system field (``"G"``, ``"M"``, ``"M (MIXED)"``), ``calendar`` the first
    epoch's (year, month, day, hour, minute, s) in GPS time (:func:`gps_calendar`),
    ``observer`` (observer, agency), ``approx_xyz_m`` the ECEF approximate position (m);
    every field cut to its RINEX width."""
    y, mo, d, h, mi, s = calendar
    return [_hline(f"{3.04:9.2f}{'':11s}{'OBSERVATION DATA':<20s}{file_type:<20s}",
                   "RINEX VERSION / TYPE"),
            _hline(f"{program:<20.20s}{'insphoto':<20s}{y:04d}{mo:02d}{d:02d} "
                   f"{h:02d}{mi:02d}{int(s):02d} GPS", "PGM / RUN BY / DATE"),
            *[_hline(c, "COMMENT") for c in comments],
            _hline(marker, "MARKER NAME"), _hline("NON_GEODETIC", "MARKER TYPE"),
            _hline(f"{observer[0]:<20.20s}{observer[1]:<40.40s}", "OBSERVER / AGENCY"),
            _hline(f"{'0':<20s}{receiver:<20.20s}", "REC # / TYPE / VERS"),
            _hline(f"{'0':<20s}{antenna:<20.20s}", "ANT # / TYPE"),
            _hline("".join(f"{v:14.4f}" for v in approx_xyz_m), "APPROX POSITION XYZ"),
            _hline(f"{0.0:14.4f}{0.0:14.4f}{0.0:14.4f}", "ANTENNA: DELTA H/E/N")]


def _header(obs_types, approx_xyz_m, week, first_sow, interval_s, marker, receiver,
            antenna, leap_seconds, comments, program="ins simulate"):
    y, mo, d, h, mi, s = gps_calendar(week, first_sow)
    out = header_start("G", (y, mo, d, h, mi, s), marker, comments, program=program,
                       receiver=receiver, antenna=antenna, approx_xyz_m=approx_xyz_m)
    out += [_hline(f"G{len(obs_types):5d}" + "".join(f" {t}" for t in obs_types),
                   "SYS / # / OBS TYPES"),
            _hline(f"{interval_s:10.3f}", "INTERVAL"),
            _hline(f"{y:6d}{mo:6d}{d:6d}{h:6d}{mi:6d}{s:13.7f}     GPS",
                   "TIME OF FIRST OBS")]
    out += [_hline(f"G {t}", "SYS / PHASE SHIFT") for t in obs_types if t.startswith("L")]
    out.append(_hline(" C1C    0.000 C1P    0.000 C2C    0.000 C2P    0.000",
                      "GLONASS COD/PHS/BIS"))
    if leap_seconds is not None:
        out.append(_hline(f"{int(leap_seconds):6d}", "LEAP SECONDS"))
    out.append(_hline("", "END OF HEADER"))
    return "".join(out)


def _field(value, lli, ssi):
    if not np.isfinite(value):
        return " " * 16
    if abs(value) > _MAX_VALUE:
        raise ValueError(f"observation {value} does not fit RINEX F14.3")
    return f"{value:14.3f}{(str(lli) if lli else ' ')}{(str(ssi) if ssi else ' ')}"


def write_rinex3_obs(path, week, time_s, prns, values, obs_types=("C1C", "L1C", "D1C", "S1C"),
                     lli=None, ssi=None, approx_xyz_m=(0.0, 0.0, 0.0), interval_s=None,
                     marker="SIM", receiver="SIMULATED", antenna="SIMULATED",
                     leap_seconds=None, comments=(), program="ins simulate"):
    """Write GPS observations as a RINEX 3.04 observation file.

    Parameters
    ----------
    path : str or os.PathLike
    week : int
        GPS week of ``time_s``.
    time_s : array_like, shape (n,)
        Epochs (receiver clock time), GPS s of week ``week`` (may exceed 604800 across a
        week boundary).
    prns : sequence of int, length m
        GPS PRNs of the columns of ``values``.
    values : array_like, shape (n, m, k)
        Observations in the order of ``obs_types`` (m, cycles, Hz, dB-Hz); NaN: not
        observed (a satellite with every value NaN is left out of the epoch).
    obs_types : sequence of str, length k
        RINEX 3 observation codes.
    lli : array_like of int, shape (n, m, k), optional
        Loss-of-lock indicators (bit 0 :data:`LLI_SLIP`), 0 = blank.
    ssi : array_like of int, shape (n, m, k), optional
        Signal-strength indicators 1-9, 0 = blank.
    approx_xyz_m : sequence of 3 float
        Approximate antenna position, ECEF m.
    interval_s : float, optional
        Observation interval, s (default: the median epoch spacing).
    leap_seconds : int, optional
        GPS - UTC, s.
    comments : sequence of str
        ``COMMENT`` lines (60 characters each at most).
    program : str
        The program named in ``PGM / RUN BY / DATE`` (20 characters at most; default
        the simulator's).

    Returns
    -------
    int
        Number of epochs written (epochs without any satellite are skipped).
    """
    time_s = np.asarray(time_s, dtype=float)
    values = np.asarray(values, dtype=float)
    n, m = len(time_s), len(prns)
    if values.shape != (n, m, len(obs_types)):
        raise ValueError(f"values must have shape {(n, m, len(obs_types))}, got {values.shape}")
    lli = np.zeros(values.shape, int) if lli is None else np.asarray(lli, int)
    ssi = np.zeros(values.shape, int) if ssi is None else np.asarray(ssi, int)
    if interval_s is None:
        interval_s = float(np.median(np.diff(time_s))) if n > 1 else 1.0
    present = np.any(np.isfinite(values), axis=2)
    first = int(np.argmax(present.any(axis=1))) if present.any() else 0
    written = 0
    with atomic_open(path, "w") as f:
        f.write(_header(tuple(obs_types), approx_xyz_m, week, time_s[first] if n else 0.0,
                        interval_s, marker, receiver, antenna, leap_seconds, comments,
                        program))
        for i in range(n):
            cols = np.flatnonzero(present[i])
            if len(cols) == 0:
                continue
            y, mo, d, h, mi, s = gps_calendar(week, time_s[i])
            lines = [f"> {y:04d} {mo:02d} {d:02d} {h:02d} {mi:02d}{s:11.7f}  0{len(cols):3d}\n"]
            for j in cols:
                body = "".join(_field(values[i, j, k], lli[i, j, k], ssi[i, j, k])
                               for k in range(len(obs_types)))
                lines.append(f"G{int(prns[j]):02d}{body.rstrip()}\n")
            f.write("".join(lines))
            written += 1
    return written
