"""Trajectory: time, geodetic position, NED velocity and attitude at a series of epochs.

Its rows follow the KF-GINS ``.nav`` layout (:meth:`Trajectory.nav_rows`), one epoch a
line (the files themselves: :mod:`ins.io.navfiles`)::

    week  t  lat  lon  h  vN  vE  vD  roll  pitch  yaw

with t in s, lat/lon in deg, h in m (ellipsoidal), velocity NED in m/s, roll/pitch/yaw in
deg (yaw in [0, 360)).  Written with 12 decimals in lat/lon (1e-12 deg = 0.1 um),
5 in h, 6 in velocity and 9 in the angles (4e-6 arcsec): finer than 0.1 mm.

A trajectory knows no file format: :mod:`ins.io.navfiles` reads and writes ``.nav`` files
and tells them from an Applanix SBET (:mod:`ins.io.sbet`).
"""
from dataclasses import dataclass

import numpy as np

from ins.nav.rotation import euler_to_quat, quat_to_euler


@dataclass(frozen=True)
class Trajectory:
    """Navigation solution at a series of epochs.

    Attributes
    ----------
    time : ndarray, shape (n,)
        Time, s.
    lla : ndarray, shape (n, 3)
        Latitude (rad), longitude (rad), ellipsoidal height (m).
    v_n : ndarray, shape (n, 3)
        Velocity NED, m/s.
    q_nb : ndarray, shape (n, 4)
        Attitude quaternion taking b to n (scalar last).
    """

    time: np.ndarray
    lla: np.ndarray
    v_n: np.ndarray
    q_nb: np.ndarray

    def __post_init__(self):
        n = np.shape(self.time)[0] if np.ndim(self.time) == 1 else None
        if n is None:
            raise ValueError(f"time must have shape (n,), got {np.shape(self.time)}")
        for name, width in (("lla", 3), ("v_n", 3), ("q_nb", 4)):
            if np.shape(getattr(self, name)) != (n, width):
                raise ValueError(f"{name} must have shape ({n}, {width}), "
                                 f"got {np.shape(getattr(self, name))}")

    def __len__(self):
        return len(self.time)

    def rpy(self, degrees=False):
        """Roll, pitch, yaw (ZYX), shape (n, 3); yaw in (-pi, pi]."""
        return quat_to_euler(self.q_nb, degrees=degrees)

    @classmethod
    def concatenate(cls, pieces):
        """One trajectory from consecutive pieces."""
        pieces = list(pieces)
        if not pieces:
            raise ValueError("no trajectory pieces to concatenate")
        return cls(*(np.concatenate([getattr(p, f) for p in pieces])
                     for f in ("time", "lla", "v_n", "q_nb")))

    @classmethod
    def from_nav_rows(cls, rows):
        """From rows of the 11 ``.nav`` columns (deg, m, m/s)."""
        rows = np.asarray(rows, dtype=float)
        return cls(time=rows[:, 1].copy(),
                   lla=np.column_stack([np.deg2rad(rows[:, 2:4]), rows[:, 4]]),
                   v_n=rows[:, 5:8].copy(),
                   q_nb=euler_to_quat(rows[:, 8:11], degrees=True))

    def nav_rows(self, week=0):
        """The 11 ``.nav`` columns, shape (n, 11), yaw in [0, 360)."""
        rpy = self.rpy(degrees=True)
        rpy[:, 2] = np.mod(rpy[:, 2], 360.0)
        rpy[:, 2][rpy[:, 2] >= 360.0] = 0.0   # mod of a tiny negative number
        return np.column_stack([np.full(len(self), float(week)), self.time,
                                np.rad2deg(self.lla[:, :2]), self.lla[:, 2], self.v_n, rpy])
