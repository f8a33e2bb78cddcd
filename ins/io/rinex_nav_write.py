"""RINEX 3.04 GPS navigation files: the writer of broadcast ephemerides.

:func:`write_gps_nav` writes :class:`ins.io.rinex_nav.GpsEphemeris` records (IS-GPS-200
units: s, s/s, s/s^2, m, rad, rad/s, sqrt(m)) as a RINEX 3.04 ``N`` file of system ``G``:
the header (version, program, optional ``IONOSPHERIC CORR`` ``GPSA``/``GPSB`` and
``LEAP SECONDS``) and per record the epoch line (``Gnn yyyy mm dd hh mm ss`` of ``toc``
in GPS time, ``af0 af1 af2``) and seven broadcast-orbit lines of four ``D19.12``
numbers in the order of the RINEX specification (the order
:func:`ins.io.rinex_nav.read_gps_nav` reads).  The GPS week written is the record's
continuous week (RINEX 3: not modulo 1024).  Fields :class:`GpsEphemeris` does not keep
(codes on L2, L2 P data flag) are written as 0; the transmission time of the message
is the caller's or, by default, ``toe - 7200`` s (two hours before the reference
time, the usual upload; RTKLIB aligns its week with ``toe``).

The file is written atomically (:func:`ins.common.fileio.atomic_open`).
"""
import numpy as np

from ins.common.fileio import atomic_open
from ins.io.rinex_nav import SECONDS_PER_WEEK

__all__ = ["write_gps_nav"]


def _hline(text, label):
    return f"{text:<60.60s}{label:<20s}\n"


def _d19(value):
    value = float(value)
    if not np.isfinite(value):
        value = 0.0
    text = f"{value:19.12E}"
    if len(text) != 19:
        raise ValueError(f"{value} does not fit RINEX D19.12")
    return text


def _calendar(week, sow):
    from ins.io.rinex_obs import gps_calendar
    y, mo, d, h, mi, s = gps_calendar(week, sow)
    if abs(s - round(s)) > 1e-6:
        raise ValueError(f"toc {sow} s of week {week} is not a whole second")
    return y, mo, d, h, mi, int(round(s))


def _record(eph, t_tx):
    y, mo, d, h, mi, s = _calendar(eph.toc_week, eph.toc)
    rows = [(eph.iode, eph.crs, eph.delta_n, eph.m0),
            (eph.cuc, eph.e, eph.cus, eph.sqrt_a),
            (eph.toe, eph.cic, eph.omega0, eph.cis),
            (eph.i0, eph.crc, eph.omega, eph.omega_dot),
            (eph.idot, 0.0, eph.week, 0.0),
            (eph.sv_accuracy, eph.health, eph.tgd, eph.iodc),
            (t_tx, eph.fit_interval)]
    out = [f"G{eph.prn:02d} {y:04d} {mo:02d} {d:02d} {h:02d} {mi:02d} {s:02d}"
           + "".join(_d19(v) for v in (eph.af0, eph.af1, eph.af2)) + "\n"]
    out += ["    " + "".join(_d19(v) for v in row) + "\n" for row in rows]
    return "".join(out)


def write_gps_nav(path, ephemerides, transmission_time_s=None, ion_alpha=None,
                  ion_beta=None, leap_seconds=None, comments=()):
    """Write GPS broadcast ephemerides as a RINEX 3.04 navigation file.

    Parameters
    ----------
    path : str or os.PathLike
    ephemerides : sequence of ins.io.rinex_nav.GpsEphemeris
        ``toc`` must be a whole second (RINEX's epoch line has no fraction).
    transmission_time_s : sequence of float, optional
        Transmission time of each message, GPS s of the record's week (default
        ``toe - 7200`` wrapped into the week).
    ion_alpha, ion_beta : sequence of 4 float, optional
        Klobuchar coefficients (s, s/semicircle, s/semicircle^2, s/semicircle^3);
        none written when absent (RTKLIB then uses its default model).
    leap_seconds : int, optional
        GPS - UTC, s.
    comments : sequence of str
        ``COMMENT`` lines (60 characters each at most).

    Returns
    -------
    int
        Number of records written.
    """
    ephemerides = list(ephemerides)
    if transmission_time_s is None:
        transmission_time_s = [(e.toe - 7200.0) % SECONDS_PER_WEEK for e in ephemerides]
    if len(transmission_time_s) != len(ephemerides):
        raise ValueError("one transmission time per ephemeris")
    head = [_hline(f"{3.04:9.2f}{'':11s}{'N: GNSS NAV DATA':<20s}{'G: GPS':<20s}",
                   "RINEX VERSION / TYPE"),
            _hline(f"{'insphoto':<20s}{'insphoto':<20s}{'':<20s}", "PGM / RUN BY / DATE")]
    head += [_hline(c, "COMMENT") for c in comments]
    for name, coeffs in (("GPSA", ion_alpha), ("GPSB", ion_beta)):
        if coeffs is not None:
            head.append(_hline(f"{name} " + "".join(f"{float(c):12.4E}" for c in coeffs),
                               "IONOSPHERIC CORR"))
    if leap_seconds is not None:
        head.append(_hline(f"{int(leap_seconds):6d}", "LEAP SECONDS"))
    head.append(_hline("", "END OF HEADER"))
    with atomic_open(path, "w") as f:
        f.write("".join(head))
        for eph, t_tx in zip(ephemerides, transmission_time_s):
            f.write(_record(eph, t_tx))
    return len(ephemerides)
