"""Standard deviations of a trajectory: ``solution_std.txt`` of ``ins process`` or an
Applanix SMRMSG file (:func:`read_trajectory_std`), interpolated in time
(:class:`TrajectoryStd`); used by the LiDAR georeferencing, the strip check and
``ins export``."""
import os
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError

__all__ = ["TrajectoryStd", "read_trajectory_std"]


@dataclass(frozen=True)
class TrajectoryStd:
    """Standard deviations of a trajectory.

    Attributes
    ----------
    time : ndarray, shape (k,)
        s, increasing.
    std : ndarray, shape (k, 6)
        N, E, D position (m), roll, pitch, yaw (rad).
    """

    time: np.ndarray
    std: np.ndarray

    def at(self, t):
        """Linear interpolation at ``t`` (s), held constant beyond the ends; (m, 6)."""
        t = np.asarray(t, dtype=float)
        return np.column_stack([np.interp(t, self.time, self.std[:, j]) for j in range(6)])


def read_trajectory_std(path):
    """Read trajectory sigmas: ``solution_std.txt`` of ``ins process`` (text: time_s,
    std N E D m, std vN vE vD m/s, std roll pitch yaw deg) or an Applanix SMRMSG file
    (binary; detected by the extension ``.out`` or a name starting with ``smrmsg``).

    Returns
    -------
    TrajectoryStd

    Raises
    ------
    InputError
        Naming the file and line/record: a negative or non-finite sigma, time not
        increasing, a wrong column count.
    """
    name = os.path.basename(os.fspath(path)).lower()
    if name.startswith("smrmsg") or name.endswith(".out"):
        from ins.io.sbet import read_smrmsg
        s = read_smrmsg(path)
        return TrajectoryStd(s.time, np.column_stack([s.sigma_pos_ned_m, s.sigma_rpy_rad]))
    from ins.common import textfiles
    rows, row_line = textfiles.read_table(
        path, ncols_min=10, ncols_max=64,
        hint="solution_std.txt: time_s std_n_m std_e_m std_d_m std_vn_mps std_ve_mps "
             "std_vd_mps std_roll_deg std_pitch_deg std_yaw_deg")
    rows = np.array(rows[:, :10], dtype=float)
    bad = np.flatnonzero(~np.all(np.isfinite(rows), axis=1) | np.any(rows[:, 1:] < 0, axis=1))
    if bad.size:
        raise InputError("standard deviations must be finite and >= 0 (m, m/s, deg)",
                         path=str(path), line=int(row_line[bad[0]]))
    if np.any(np.diff(rows[:, 0]) <= 0):
        k = int(np.flatnonzero(np.diff(rows[:, 0]) <= 0)[0]) + 1
        raise InputError("time not increasing", path=str(path), line=int(row_line[k]))
    return TrajectoryStd(rows[:, 0].copy(),
                         np.column_stack([rows[:, 1:4], np.deg2rad(rows[:, 7:10])]))
