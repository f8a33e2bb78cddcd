"""The GNSS log of the antenna: positions (and velocities) with their standard
deviations, whatever file they came from (readers: :mod:`ins.io.gnss`, :mod:`ins.io.rtklib`,
:mod:`ins.io.rosbag`)."""
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GnssLog:
    """Antenna positions (and velocities) with their standard deviations.

    Attributes
    ----------
    time : ndarray, shape (n,)
        s.
    lla : ndarray, shape (n, 3)
        Latitude, longitude (rad), ellipsoidal height (m).
    sigma_ned_m : ndarray, shape (n, 3)
        Position standard deviations N, E, D, m.
    v_n : ndarray, shape (n, 3) or None
        Antenna velocity NED, m/s.
    sigma_vel_ned_mps : ndarray, shape (n, 3) or None
        Velocity standard deviations, m/s.
    line : ndarray, shape (n,) of int
        1-based line of each record in the file (0 when not from a file).
    path : str or None
        The file read.
    cov_ned_m2 : ndarray, shape (n, 3, 3) or None
        Full position covariance in the n frame (north, east, down), m^2, when the
        source gives one (RTKLIB's sdne/sdeu/sdun); its diagonal is ``sigma_ned_m**2``.
    quality : ndarray, shape (n,) of int or None
        Solution quality flag of the source (RTKLIB Q: 1 fix, 2 float, 3 SBAS, 4 DGPS,
        5 single, 6 PPP), ``None`` when the source has none.
    vel_time : ndarray, shape (n,) or None
        Epochs of the velocities, s, when they differ from those of the positions (a
        receiver whose Doppler velocities are stamped differently from its positions:
        :meth:`shifted` with a separate velocity shift); ``None``: ``time``.
    screen : ins.io.pos_screen.CovarianceScreen or None
        What the reader's covariance screen repaired and dropped (RTKLIB ``.pos``),
        ``None`` when not screened.
    """

    time: np.ndarray
    lla: np.ndarray
    sigma_ned_m: np.ndarray
    v_n: np.ndarray = None
    sigma_vel_ned_mps: np.ndarray = None
    line: np.ndarray = None
    path: str = None
    cov_ned_m2: np.ndarray = None
    quality: np.ndarray = None
    vel_time: np.ndarray = None
    screen: object = None

    def __len__(self):
        return len(self.time)

    @property
    def has_velocity(self):
        return self.v_n is not None

    @property
    def velocity_time(self):
        """Epochs of the velocities, s (``vel_time``, else the positions' ``time``)."""
        return self.time if self.vel_time is None else self.vel_time

    def select(self, keep):
        """The records where the boolean mask or index array ``keep`` selects."""
        def take(a):
            return None if a is None else a[keep]
        return GnssLog(self.time[keep], self.lla[keep], self.sigma_ned_m[keep], take(self.v_n),
                       take(self.sigma_vel_ned_mps), take(self.line), self.path,
                       take(self.cov_ned_m2), take(self.quality), take(self.vel_time),
                       self.screen)

    def shifted(self, time_shift_s, velocity_time_shift_s=None):
        """The same log with ``time_shift_s`` (s) added to every epoch (a clock offset
        between the GNSS time base and the IMU's; 0 gives the log itself).

        ``velocity_time_shift_s`` (s), when given and different, is added to the
        velocities' epochs instead: they then get their own epochs (``vel_time``), the
        position's plus the difference of the two shifts.  ``None`` (default): the
        velocities keep the positions' epochs (one shift for both).
        """
        shift = float(time_shift_s or 0.0)
        v_shift = shift if velocity_time_shift_s is None else float(velocity_time_shift_s)
        if shift == 0.0 and v_shift == 0.0:
            return self
        from dataclasses import replace
        vel_time = None
        if self.has_velocity and (self.vel_time is not None or v_shift != shift):
            vel_time = self.velocity_time + v_shift
        return replace(self, time=self.time + shift, vel_time=vel_time)

    def update_events(self, use_velocity=True):
        """The filter's GNSS updates in time order: ``(time, record, kind)`` arrays with
        ``kind`` 3 for a record's position and velocity at one epoch, 1 a position
        alone, 2 a velocity alone (at ``vel_time``; a position before a velocity of
        the same time).  Without ``vel_time`` (or without velocities used) one event a
        record, at ``time``."""
        n = len(self.time)
        record = np.arange(n)
        if self.vel_time is None or not (use_velocity and self.has_velocity):
            kind = np.full(n, 3 if use_velocity and self.has_velocity else 1, dtype=np.int64)
            return np.asarray(self.time, dtype=float), record, kind
        time = np.concatenate([self.time, self.vel_time])
        order = np.argsort(time, kind="stable")
        kind = np.concatenate([np.ones(n, np.int64), np.full(n, 2, np.int64)])
        return time[order], np.concatenate([record, record])[order], kind[order]
