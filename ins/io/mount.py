"""Mount-angle log of a gyro-stabilized mount: reader and interpolation.

Layout (``docs/interfaces.md``): an optional header comment, then one epoch a line::

    # time_s roll_deg pitch_deg yaw_deg  (platform p relative to aircraft a:
    #                                      C_ap = Rz(yaw) Ry(pitch) Rx(roll))

Time in s on the IMU's time scale; angles in deg.
"""
from dataclasses import dataclass

import numpy as np

from ins.common import textfiles, textrows
from ins.common.errors import InputError
from ins.nav.rotation import euler_to_dcm, wrap_to_pi

_HINT = "mount log: time_s roll_deg pitch_deg yaw_deg"


@dataclass(frozen=True)
class MountLog:
    """Mount angles over time.

    Attributes
    ----------
    time : ndarray, shape (n,)
        s, strictly increasing.
    rpy : ndarray, shape (n, 3)
        Roll, pitch, yaw of the platform relative to the aircraft, rad
        (``C_ap = Rz(yaw) Ry(pitch) Rx(roll)``).
    max_gap_s : float
        Interpolation is refused (``valid`` False) across an interval longer than this.
    """

    time: np.ndarray
    rpy: np.ndarray
    max_gap_s: float = None

    def __post_init__(self):
        if self.max_gap_s is None:
            d = np.diff(self.time)
            gap = 3.0 * float(np.median(d)) if d.size else 1.0
            object.__setattr__(self, "max_gap_s", gap)

    def __len__(self):
        return len(self.time)

    def angles(self, t):
        """Interpolated angles at ``t`` (rad, shape (m, 3)) and a validity mask.

        Each angle is interpolated linearly along the shorter arc between the two
        bracketing epochs (an angle logged as 179 then -179 deg passes +-180 deg, not 0)
        and returned in (-pi, pi].  ``valid`` is False outside the log and inside gaps
        longer than ``max_gap_s``; the angles there are zero (mount at its reference
        position).
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        k = np.searchsorted(self.time, t, side="right")
        inside = (k > 0) & (k < len(self.time)) | (t == self.time[-1])
        k = np.clip(k, 1, len(self.time) - 1)
        gap = self.time[k] - self.time[k - 1]
        valid = inside & (gap <= self.max_gap_s)
        w = np.clip((t - self.time[k - 1]) / gap, 0.0, 1.0)[:, None]
        # the short way round: a yaw from 179 to -179 deg passes 180, not 0
        step = wrap_to_pi(self.rpy[k] - self.rpy[k - 1])
        rpy = wrap_to_pi(self.rpy[k - 1] + w * step)
        rpy[~valid] = 0.0
        return rpy, valid

    def C_ap(self, t):
        """``C_ap(t)`` (shape (m, 3, 3)) and the validity mask of :meth:`angles`."""
        rpy, valid = self.angles(t)
        return euler_to_dcm(rpy), valid


def read_mount(path):
    """Read a mount-angle log (4 columns: time_s roll_deg pitch_deg yaw_deg).

    Raises
    ------
    InputError
        Naming the file and line: column count, text or non-finite value, time not
        strictly increasing, an angle beyond +-180 deg.
    """
    path_s = str(path)
    rows, row_line = textfiles.read_table(path, ncols_min=4, ncols_max=4, hint=_HINT)
    textrows.check_rows(rows, row_line, path_s, name_duplicates=False)
    big = np.flatnonzero(np.any(np.abs(rows[:, 1:]) > 180.0, axis=1))
    if big.size:
        raise InputError("mount angle beyond +-180 deg (expected deg)", path=path_s,
                         line=int(row_line[big[0]]))
    if len(rows) < 2:
        raise InputError("a mount log needs at least 2 epochs", path=path_s)
    return MountLog(rows[:, 0].copy(), np.deg2rad(rows[:, 1:4]))
