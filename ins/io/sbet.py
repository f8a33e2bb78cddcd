"""Applanix SBET trajectories and their SMRMSG accuracy files (POSPac's binary outputs).

SBET (``sbet_*.out``; PDAL ``readers.sbet``/``writers.sbet``, LAStools, orthority, ...):
records of 17 little-endian float64 (136 bytes), in this order (PDAL's
``SbetCommon.hpp``, Applanix POSPac):

====  ==========================  ==================================================
 #    field                       unit and meaning
====  ==========================  ==================================================
 0    time                        s, GPS seconds of week
 1    latitude                    rad, WGS84
 2    longitude                   rad
 3    altitude                    m, ellipsoidal height
 4-6  x, y, z velocity            m/s, in the wander-azimuth frame
 7    roll                        rad
 8    pitch                       rad
 9    platform heading            rad, true heading + wander angle (see Frames)
 10   wander angle                rad
 11   x, y, z body acceleration   m/s^2 (fields 11-13)
 14   x, y, z body angular rate   rad/s (fields 14-16)
====  ==========================  ==================================================

Frames.  The wander-azimuth frame is Applanix's local-level frame turned about the
vertical by the wander angle ``alpha``; true heading = platform heading - alpha (as
J. Skaloud's POSPac decoder reads it).  The velocity axes are taken, as in that decoder,
as ``v_north = vx cos(alpha) - vy sin(alpha)``, ``v_east = -vx sin(alpha) - vy
cos(alpha)``, and ``z`` up (the right-handed north-west-up frame of Savage's wander
frame, which Applanix follows; the decoder's own ``v_down = vz`` makes the frame
left-handed, so the vertical sign is the one published statement we do not follow).
Published decoders disagree on these axes (another MATLAB reader labels x east-west and
y north-south; an exporter of another vendor writes body axes), and PDAL passes the
three values through unnamed: the velocity of an SBET from elsewhere is the field to
check before use; position, attitude and time are unambiguous.
Roll, pitch, heading are the ZYX Euler angles of ``C_nb`` (``C_nb = Rz(heading)
Ry(pitch) Rx(roll)``, body forward-right-down), as in the ``.nav`` files.

The writer (:func:`write_sbet`) writes our local-level NED solution with a wander angle
of 0 (so x = north, y = west, z = up and the platform heading is the true heading in
[0, 2 pi)), and zero body accelerations and angular rates (not carried by a
:class:`~ins.nav.trajectory.Trajectory`; tools that georeference point clouds use time,
position and attitude only).  The reader (:func:`read_sbet`) takes any wander angle.

SMRMSG (``smrmsg_*.out``; PDAL ``readers.smrmsg``): records of 10 little-endian
float64 (80 bytes): time (s), north, east, down position RMS (m), north, east, down
velocity RMS (m/s), roll, pitch, heading RMS in ARC MINUTES (Applanix's unit).

Errors name the file and the 1-based record.
"""
import os
from typing import NamedTuple

import numpy as np

from ins.common import limits, textrows
from ins.common.errors import InputError
from ins.common.fileio import atomic_open
from ins.nav.imu import MAX_ANGULAR_RATE, MAX_SPECIFIC_FORCE, MAX_TIME_S

__all__ = ["SBET_FIELDS", "SMRMSG_FIELDS", "SBET_RECORD_BYTES", "SMRMSG_RECORD_BYTES",
           "write_sbet", "read_sbet", "sbet_rows", "write_smrmsg", "read_smrmsg", "Smrmsg",
           "is_sbet"]

#: The 17 fields of an SBET record, in file order.
SBET_FIELDS = ("time", "latitude", "longitude", "altitude", "x_velocity", "y_velocity",
               "z_velocity", "roll", "pitch", "platform_heading", "wander_angle",
               "x_body_accel", "y_body_accel", "z_body_accel", "x_body_ang_rate",
               "y_body_ang_rate", "z_body_ang_rate")
#: The 10 fields of an SMRMSG record, in file order.
SMRMSG_FIELDS = ("time", "north_pos_rms", "east_pos_rms", "down_pos_rms", "north_vel_rms",
                 "east_vel_rms", "down_vel_rms", "roll_rms", "pitch_rms", "heading_rms")
SBET_RECORD_BYTES = 8 * len(SBET_FIELDS)
SMRMSG_RECORD_BYTES = 8 * len(SMRMSG_FIELDS)
_ARCMIN = np.pi / (180.0 * 60.0)       # rad per arc minute


def sbet_rows(traj):
    """The (n, 17) SBET records of a :class:`~ins.nav.trajectory.Trajectory` (wander angle 0,
    heading in [0, 2 pi), zero body accelerations and rates)."""
    n = len(traj)
    rows = np.zeros((n, 17))
    rows[:, 0] = traj.time
    rows[:, 1:4] = traj.lla
    rows[:, 4] = traj.v_n[:, 0]                 # x: north
    rows[:, 5] = -traj.v_n[:, 1]                # y: west
    rows[:, 6] = -traj.v_n[:, 2]                # z: up
    rpy = traj.rpy()
    rows[:, 7:9] = rpy[:, :2]
    yaw = np.mod(rpy[:, 2], 2 * np.pi)
    yaw[yaw >= 2 * np.pi] = 0.0
    rows[:, 9] = yaw
    return rows


def write_sbet(path, pieces):
    """Write trajectory pieces (a Trajectory or an iterable of them, in time order) as an
    SBET file, atomically.  Returns the number of records."""
    from ins.nav.trajectory import Trajectory
    if isinstance(pieces, Trajectory):
        pieces = [pieces]
    n = 0
    with atomic_open(path, "wb") as f:
        for piece in pieces:
            rows = sbet_rows(piece)
            if not np.all(np.isfinite(rows)):
                k = int(np.flatnonzero(~np.all(np.isfinite(rows), axis=1))[0])
                raise ValueError(f"trajectory epoch {n + k} holds a non-finite value; "
                                 f"not written")
            f.write(np.ascontiguousarray(rows, dtype="<f8").tobytes())
            n += len(rows)
    return n


def _records(path, width, what):
    path_s = os.fspath(path)
    size = os.path.getsize(path_s)
    nbytes = 8 * width
    if size == 0:
        raise InputError(f"empty file (no {what} records)", path=path_s)
    if size % nbytes:
        k = size // nbytes
        hint = ""
        other = SMRMSG_RECORD_BYTES if nbytes == SBET_RECORD_BYTES else SBET_RECORD_BYTES
        if size % other == 0:
            hint = (" (its size is a multiple of {} bytes: an {} file?)"
                    .format(other, "SMRMSG accuracy" if other == SMRMSG_RECORD_BYTES
                            else "SBET trajectory"))
        raise InputError(f"file size {size} bytes is not a multiple of {nbytes} ({width} "
                         f"little-endian float64 a {what} record): record {k + 1} has only "
                         f"{size - k * nbytes} bytes{hint}", path=path_s, record=k + 1)
    data = np.fromfile(path_s, dtype="<f8")
    if data.size * 8 != size:
        raise InputError(f"read {data.size * 8} bytes of {size}", path=path_s)
    rows = data.astype(np.float64, copy=False).reshape(-1, width)
    bad = np.flatnonzero(~np.all(np.isfinite(rows), axis=1))
    if bad.size:
        raise InputError(f"non-finite value in a {what} record", path=path_s,
                         record=int(bad[0]) + 1)
    back = np.flatnonzero(np.diff(rows[:, 0]) <= 0)
    if back.size:
        k = int(back[0]) + 1
        which = "duplicated epoch" if rows[k, 0] == rows[k - 1, 0] else "time not increasing"
        raise InputError(f"{which}: t = {float(rows[k, 0])!r} s after {float(rows[k - 1, 0])!r} s",
                         path=path_s, record=k + 1)
    return rows


def read_sbet(path):
    """Read an SBET file into a :class:`~ins.nav.trajectory.Trajectory` (module notes).

    Raises
    ------
    InputError
        Naming the file and the 1-based record: a size that is not a multiple of 136
        bytes, a non-finite value, time not strictly increasing, a latitude beyond
        +-pi/2 rad or a longitude beyond +-2 pi rad (not an SBET file, or degrees).
    """
    from ins.nav.rotation import euler_to_quat
    from ins.nav.trajectory import Trajectory
    path_s = os.fspath(path)
    rows = _records(path_s, 17, "SBET")
    lat, lon = rows[:, 1], rows[:, 2]
    bad = np.flatnonzero((np.abs(lat) > np.pi / 2) | (np.abs(lon) > 2 * np.pi))
    if bad.size:
        k = int(bad[0])
        raise InputError(f"latitude {float(lat[k])!r}, longitude {float(lon[k])!r} rad out of "
                         f"range (an SBET holds radians)", path=path_s, record=k + 1)
    L, F = limits, SBET_FIELDS
    textrows.check_ranges(rows, None, path_s, [
        (0, -MAX_TIME_S, MAX_TIME_S, "time", "s"),
        (3, L.MIN_HEIGHT_M, L.MAX_HEIGHT_M, "altitude", "m")]
        + [(j, -L.MAX_SPEED_MPS, L.MAX_SPEED_MPS, F[j], "m/s") for j in (4, 5, 6)]
        + [(j, -4 * np.pi, 4 * np.pi, F[j], "rad") for j in (7, 8, 9, 10)]
        + [(j, -MAX_SPECIFIC_FORCE, MAX_SPECIFIC_FORCE, F[j], "m/s^2") for j in (11, 12, 13)]
        + [(j, -MAX_ANGULAR_RATE, MAX_ANGULAR_RATE, F[j], "rad/s") for j in (14, 15, 16)])
    a = rows[:, 10]
    vx, vy, vz = rows[:, 4], rows[:, 5], rows[:, 6]
    ca, sa = np.cos(a), np.sin(a)
    v_n = np.column_stack([vx * ca - vy * sa, -vx * sa - vy * ca, -vz])
    rpy = np.column_stack([rows[:, 7], rows[:, 8], rows[:, 9] - a])
    return Trajectory(time=rows[:, 0].copy(), lla=rows[:, 1:4].copy(), v_n=v_n,
                      q_nb=euler_to_quat(rpy))


class Smrmsg(NamedTuple):
    """An SMRMSG accuracy file in SI units.

    Attributes
    ----------
    time : ndarray, shape (n,)
        s.
    sigma_pos_ned_m : ndarray, shape (n, 3)
    sigma_vel_ned_mps : ndarray, shape (n, 3)
    sigma_rpy_rad : ndarray, shape (n, 3)
        Roll, pitch, heading RMS, rad (arc minutes in the file).
    """

    time: np.ndarray
    sigma_pos_ned_m: np.ndarray
    sigma_vel_ned_mps: np.ndarray
    sigma_rpy_rad: np.ndarray


def write_smrmsg(path, time, sigma_pos_ned_m, sigma_vel_ned_mps, sigma_rpy_rad):
    """Write an SMRMSG accuracy file (angles converted to arc minutes), atomically.
    Returns the number of records."""
    rows = np.column_stack([np.asarray(time, float), np.asarray(sigma_pos_ned_m, float),
                            np.asarray(sigma_vel_ned_mps, float),
                            np.asarray(sigma_rpy_rad, float) / _ARCMIN])
    if rows.shape[1] != 10:
        raise ValueError(f"expected time (n,) and three (n, 3) sigma arrays, got {rows.shape}")
    if not np.all(np.isfinite(rows)):
        raise ValueError("SMRMSG values hold a non-finite value; not written")
    with atomic_open(path, "wb") as f:
        f.write(np.ascontiguousarray(rows, dtype="<f8").tobytes())
    return len(rows)


def read_smrmsg(path):
    """Read an SMRMSG accuracy file (:class:`Smrmsg`, SI units).

    Raises
    ------
    InputError
        Naming the file and record: a size that is not a multiple of 80 bytes, a
        non-finite value, time not increasing, a negative RMS.
    """
    path_s = os.fspath(path)
    rows = _records(path_s, 10, "SMRMSG")
    neg = np.argwhere(rows[:, 1:] < 0)
    if neg.size:
        k, j = neg[0]
        raise InputError(f"{SMRMSG_FIELDS[j + 1]} = {float(rows[k, j + 1])!r}: an RMS must be "
                         f">= 0", path=path_s, record=int(k) + 1)
    textrows.check_ranges(rows, None, path_s, [
        (0, -MAX_TIME_S, MAX_TIME_S, "time", "s")]
        + [(j, 0.0, limits.MAX_SIGMA_M, SMRMSG_FIELDS[j], "m") for j in (1, 2, 3)]
        + [(j, 0.0, limits.MAX_SPEED_MPS, SMRMSG_FIELDS[j], "m/s") for j in (4, 5, 6)]
        + [(j, 0.0, 180.0 * 60.0, SMRMSG_FIELDS[j], "arcmin") for j in (7, 8, 9)])
    return Smrmsg(rows[:, 0].copy(), rows[:, 1:4].copy(), rows[:, 4:7].copy(),
                  rows[:, 7:10] * _ARCMIN)


def is_sbet(path):
    """True when ``path`` looks like an SBET file: a size that is a multiple of 136
    bytes, and a first record with a finite time, a latitude within +-pi/2 and a
    longitude within +-2 pi rad, not text."""
    try:
        size = os.path.getsize(path)
        if size == 0 or size % SBET_RECORD_BYTES:
            return False
        with open(path, "rb") as f:
            head = f.read(SBET_RECORD_BYTES)
    except OSError:
        return False
    if all(b in b"\t\n\r " or 32 <= b < 127 for b in head):
        return False                     # printable text (a .nav of that size)
    rec = np.frombuffer(head, dtype="<f8")
    return bool(np.all(np.isfinite(rec)) and abs(rec[1]) <= np.pi / 2
                and abs(rec[2]) <= 2 * np.pi)
