"""RINEX 3.04 mixed observation and navigation files of the multi-GNSS simulator.

:func:`write_mixed_obs` writes ``M (MIXED)`` observations: per system its
``SYS / # / OBS TYPES`` (:func:`ins.simulate.gnss_signals.obs_types`), ``SYS / PHASE
SHIFT`` (0), ``GLONASS SLOT / FRQ #`` (slot and channel ``k`` of every GLONASS
satellite), ``GLONASS COD/PHS/BIS`` (0), time system GPS; epoch records as
:mod:`ins.io.rinex_obs` (``F14.3`` values with LLI and SSI digits).

:func:`write_mixed_nav` writes ``N: GNSS NAV DATA / M: MIXED`` records (RINEX 3.04 table
A6-A14): GPS (LNAV, epoch in GPS time), Galileo (I/NAV, data sources 517, epoch in GST =
GPS time, GAL week = GPS week), BeiDou (D1/D2, epoch and ``toe`` in BDT, BDT week),
GLONASS (epoch ``t_b`` in UTC, ``-tau_n``, ``+gamma_n``, message frame time in s of the UTC
week, position, velocity, acceleration in km, km/s, km/s^2, health, channel ``k``, age),
with the header's Klobuchar ``GPSA``/``GPSB`` and ``LEAP SECONDS``.  Both files are
written atomically.
"""
import datetime as _dt

import numpy as np

from ins.common.fileio import atomic_open
from ins.io.rinex_nav import SECONDS_PER_WEEK
from ins.io.rinex_obs import gps_calendar, header_start
from ins.simulate.gnss_signals import SIGNALS, obs_types
from ins.simulate.kepler_orbit import BDT_WEEK0_GPS

__all__ = ["write_mixed_obs", "write_mixed_nav"]
_MAX_VALUE = 9999999999.999
_NAMES = {"G": "GPS", "R": "GLONASS", "E": "GALILEO", "C": "BEIDOU"}


def _h(text, label):
    return f"{text:<60.60s}{label:<20s}\n"


def _types_lines(system, types):
    out, rest = [], list(types)
    first = True
    while rest or first:
        chunk, rest = rest[:13], rest[13:]
        head = f"{system}  {len(types):3d}" if first else " " * 6
        out.append(_h(head + "".join(f" {t}" for t in chunk), "SYS / # / OBS TYPES"))
        first = False
    return out


def _glonass_lines(slots):
    out = []
    for i in range(0, max(len(slots), 1), 8):
        chunk = slots[i:i + 8]
        head = f"{len(slots):3d} " if i == 0 else "    "
        out.append(_h(head + "".join(f"R{s:02d} {k:2d} " for s, k in chunk),
                      "GLONASS SLOT / FRQ #"))
    return out


def _field(value, lli, ssi):
    if not np.isfinite(value):
        return " " * 16
    if abs(value) > _MAX_VALUE:
        raise ValueError(f"observation {value} does not fit RINEX F14.3")
    return f"{value:14.3f}{(str(lli) if lli else ' ')}{(str(ssi) if ssi else ' ')}"


def write_mixed_obs(path, obs, glonass_channels, approx_xyz_m, interval_s, marker,
                    leap_seconds=None, comments=()):
    """Write :class:`ins.simulate.gnss_multi.MultiObservations` as RINEX 3.04.

    Parameters
    ----------
    path : str or os.PathLike
    obs : ins.simulate.gnss_multi.MultiObservations
    glonass_channels : dict
        GLONASS slot -> channel ``k``.
    approx_xyz_m : sequence of 3 float
        ECEF, m.
    interval_s : float
    marker : str
    leap_seconds : int, optional
    comments : sequence of str

    Returns
    -------
    int
        Epochs written.
    """
    systems = list(obs.signals)
    types = {sy: obs_types(sy, [i for i, (nm, _, _) in enumerate(SIGNALS[sy])
                                if nm in obs.signals[sy]]) for sy in systems}
    present = obs.observed
    first = int(np.argmax(present.any(axis=1))) if present.any() else 0
    y, mo, d, hh, mi, s = gps_calendar(obs.week, obs.time_rx[first])
    head = header_start("M (MIXED)", (y, mo, d, hh, mi, s), marker, comments,
                        approx_xyz_m=approx_xyz_m)
    for sy in systems:
        head += _types_lines(sy, types[sy])
    head += [_h(f"{interval_s:10.3f}", "INTERVAL"),
             _h(f"{y:6d}{mo:6d}{d:6d}{hh:6d}{mi:6d}{s:13.7f}     GPS", "TIME OF FIRST OBS")]
    for sy in systems:
        head += [_h(f"{sy} {t}", "SYS / PHASE SHIFT") for t in types[sy] if t[0] == "L"]
    if "R" in systems:
        head += _glonass_lines(sorted(glonass_channels.items()))
    head.append(_h(" C1C    0.000 C1P    0.000 C2C    0.000 C2P    0.000",
                   "GLONASS COD/PHS/BIS"))
    if leap_seconds is not None:
        head.append(_h(f"{int(leap_seconds):6d}", "LEAP SECONDS"))
    head.append(_h("", "END OF HEADER"))
    ssi = np.where(np.isfinite(obs.snr),
                   np.clip(np.floor(np.nan_to_num(obs.snr) / 6.0), 1, 9), 0).astype(int)
    written = 0
    with atomic_open(path, "w") as f:
        f.write("".join(head))
        for i in range(len(obs.time_rx)):
            cols = np.flatnonzero(present[i])
            if len(cols) == 0:
                continue
            y, mo, d, hh, mi, s = gps_calendar(obs.week, obs.time_rx[i])
            lines = [f"> {y:04d} {mo:02d} {d:02d} {hh:02d} {mi:02d}{s:11.7f}  0{len(cols):3d}\n"]
            for j in cols:
                sat = obs.sats[j]
                body = []
                for q in range(len(obs.signals[sat[0]])):
                    vals = (obs.code[i, j, q], obs.phase[i, j, q], obs.doppler[i, j, q],
                            obs.snr[i, j, q])
                    flags = ((0, ssi[i, j, q]), (obs.lli[i, j, q], ssi[i, j, q]), (0, 0), (0, 0))
                    body += [_field(v, a, b) for v, (a, b) in zip(vals, flags)]
                lines.append(f"{sat}{''.join(body).rstrip()}\n")
            f.write("".join(lines))
            written += 1
    return written


def _d19(value):
    value = float(value)
    text = f"{value if np.isfinite(value) else 0.0:19.12E}"
    if len(text) != 19:
        raise ValueError(f"{value} does not fit RINEX D19.12")
    return text


def _epoch(sat, cal, clock):
    y, mo, d, hh, mi, s = cal
    if abs(s - round(s)) > 1e-6:
        raise ValueError(f"{sat}: the epoch {cal} is not a whole second")
    return (f"{sat} {y:04d} {mo:02d} {d:02d} {hh:02d} {mi:02d} {int(round(s)):02d}"
            + "".join(_d19(v) for v in clock) + "\n")


def _rows(rows):
    return "".join("    " + "".join(_d19(v) for v in row) + "\n" for row in rows)


def _gps(e):
    t_tx = (e.toe - 7200.0) % SECONDS_PER_WEEK
    return (_epoch(f"G{e.prn:02d}", gps_calendar(e.toc_week, e.toc), (e.af0, e.af1, e.af2))
            + _rows([(e.iode, e.crs, e.delta_n, e.m0), (e.cuc, e.e, e.cus, e.sqrt_a),
                     (e.toe, e.cic, e.omega0, e.cis), (e.i0, e.crc, e.omega, e.omega_dot),
                     (e.idot, 0.0, e.week, 0.0), (e.sv_accuracy, e.health, e.tgd, e.iodc),
                     (t_tx, e.fit_interval)]))


def _kepler(e):
    sat = f"{e.system}{e.prn:02d}"
    if e.system == "E":
        cal = gps_calendar(e.week, e.toc)
        rows = [(e.iode, e.crs, e.delta_n, e.m0), (e.cuc, e.e, e.cus, e.sqrt_a),
                (e.toe, e.cic, e.omega0, e.cis), (e.i0, e.crc, e.omega, e.omega_dot),
                (e.idot, 517.0, e.week, 0.0), (3.12, e.health, e.tgd, e.tgd),
                ((e.toe - 600.0) % SECONDS_PER_WEEK, 0.0, 0.0, 0.0)]
    else:
        cal = gps_calendar(e.week + BDT_WEEK0_GPS, e.toc)      # BDT calendar: same epoch form
        rows = [(e.iode, e.crs, e.delta_n, e.m0), (e.cuc, e.e, e.cus, e.sqrt_a),
                (e.toe, e.cic, e.omega0, e.cis), (e.i0, e.crc, e.omega, e.omega_dot),
                (e.idot, 0.0, e.week, 0.0), (2.0, e.health, e.tgd, e.tgd),
                ((e.toe - 600.0) % SECONDS_PER_WEEK, e.iode)]
    return _epoch(sat, cal, (e.af0, e.af1, e.af2)) + _rows(rows)


def _glonass(e):
    u = e.tb_utc
    sunday = _dt.datetime(u.year, u.month, u.day) - _dt.timedelta(days=(u.weekday() + 1) % 7)
    tk = (u - sunday).total_seconds() - 900.0
    km = [x / 1e3 for x in (*e.pos, *e.vel, *e.acc)]
    return (_epoch(f"R{e.slot:02d}", (u.year, u.month, u.day, u.hour, u.minute, u.second),
                   (-e.tau_n, e.gamma_n, tk % SECONDS_PER_WEEK))
            + _rows([(km[0], km[3], km[6], e.health), (km[1], km[4], km[7], e.k),
                     (km[2], km[5], km[8], 0.0)]))


def write_mixed_nav(path, gps=(), kepler=(), glonass=(), ion_alpha=None, ion_beta=None,
                    leap_seconds=None, comments=()):
    """Write broadcast ephemerides of several systems as a RINEX 3.04 mixed file.

    Parameters
    ----------
    path : str or os.PathLike
    gps : sequence of ins.io.rinex_nav.GpsEphemeris
    kepler : sequence of ins.simulate.kepler_orbit.KeplerEphemeris
        Galileo and BeiDou.
    glonass : sequence of ins.simulate.glonass_orbit.GlonassEphemeris
    ion_alpha, ion_beta : sequence of 4 float, optional
        Klobuchar coefficients.
    leap_seconds : int, optional
        GPS - UTC, s.
    comments : sequence of str

    Returns
    -------
    int
        Records written.
    """
    head = [_h(f"{3.04:9.2f}{'':11s}{'N: GNSS NAV DATA':<20s}{'M: MIXED':<20s}",
               "RINEX VERSION / TYPE"),
            _h(f"{'ins simulate':<20s}{'insphoto':<20s}", "PGM / RUN BY / DATE")]
    head += [_h(c, "COMMENT") for c in comments]
    for name, coeffs in (("GPSA", ion_alpha), ("GPSB", ion_beta)):
        if coeffs is not None:
            head.append(_h(f"{name} " + "".join(f"{float(c):12.4E}" for c in coeffs),
                           "IONOSPHERIC CORR"))
    if leap_seconds is not None:
        head.append(_h(f"{int(leap_seconds):6d}", "LEAP SECONDS"))
    head.append(_h("", "END OF HEADER"))
    body = [_gps(e) for e in gps] + [_glonass(e) for e in glonass] + [_kepler(e) for e in kepler]
    with atomic_open(path, "w") as f:
        f.write("".join(head) + "".join(body))
    return len(body)
