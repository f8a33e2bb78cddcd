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
    screen: object = None

    def __len__(self):
        return len(self.time)

    @property
    def has_velocity(self):
        return self.v_n is not None

    def select(self, keep):
        """The records where the boolean mask or index array ``keep`` selects."""
        def take(a):
            return None if a is None else a[keep]
        return GnssLog(self.time[keep], self.lla[keep], self.sigma_ned_m[keep], take(self.v_n),
                       take(self.sigma_vel_ned_mps), take(self.line), self.path,
                       take(self.cov_ned_m2), take(self.quality), self.screen)

    def shifted(self, time_shift_s):
        """The same log with ``time_shift_s`` (s) added to every epoch (a clock offset
        between the GNSS time base and the IMU's; 0 gives the log itself)."""
        if not time_shift_s:
            return self
        from dataclasses import replace
        return replace(self, time=self.time + float(time_shift_s))
