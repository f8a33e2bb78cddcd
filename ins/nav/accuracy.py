"""Errors of a trajectory against a reference (truth) on their common epochs."""
from dataclasses import dataclass

import numpy as np

from ins.nav import earth
from ins.nav.rotation import quat_conjugate, quat_multiply, quat_to_rotvec

#: Epochs of two files match when their times agree to this tolerance, s.
TIME_TOLERANCE_S = 1e-6
ARCSEC = np.pi / 180.0 / 3600.0


@dataclass(frozen=True)
class TrajectoryErrors:
    """Estimate minus reference on common epochs.

    Attributes
    ----------
    time : ndarray, shape (n,)
        Common epochs, s.
    pos_n : ndarray, shape (n, 3)
        Position error NED, m (estimate relative to the reference, in the reference's n).
    v_n : ndarray, shape (n, 3)
        Velocity error NED, m/s.
    att_n : ndarray, shape (n, 3)
        Attitude error as a small rotation of the estimated n frame: the rotation vector
        of ``C_nb_est C_nb_ref^T`` (north, east, down tilt and heading), rad.
    """

    time: np.ndarray
    pos_n: np.ndarray
    v_n: np.ndarray
    att_n: np.ndarray

    @property
    def horizontal(self):
        """Horizontal position error, m."""
        return np.hypot(self.pos_n[:, 0], self.pos_n[:, 1])

    def summary(self):
        """Dictionary of final, RMS and max figures (m, m/s, arcsec)."""
        out = {"n_epochs": len(self.time), "t_from": float(self.time[0]),
               "t_to": float(self.time[-1])}
        series = {"horizontal_m": self.horizontal, "down_m": self.pos_n[:, 2],
                  "north_m": self.pos_n[:, 0], "east_m": self.pos_n[:, 1],
                  "vel_3d_mps": np.linalg.norm(self.v_n, axis=1),
                  "tilt_n_arcsec": self.att_n[:, 0] / ARCSEC,
                  "tilt_e_arcsec": self.att_n[:, 1] / ARCSEC,
                  "heading_arcsec": self.att_n[:, 2] / ARCSEC}
        for name, x in series.items():
            out[name] = {"final": float(x[-1]), "rms": float(np.sqrt(np.mean(x ** 2))),
                         "max": float(np.max(np.abs(x)))}
        return out


def compare(estimate, reference):
    """Errors of ``estimate`` against ``reference`` (both :class:`~ins.nav.trajectory.Trajectory`)
    on the epochs they share (times equal within ``TIME_TOLERANCE_S``)."""
    i, j = _common_epochs(estimate.time, reference.time)
    if len(i) == 0:
        raise ValueError("the trajectories share no epoch (times must match within 1 us)")
    pos = earth.ned_offset(reference.lla[j], estimate.lla[i])
    vel = estimate.v_n[i] - reference.v_n[j]
    dq = quat_multiply(estimate.q_nb[i], quat_conjugate(reference.q_nb[j]))
    return TrajectoryErrors(time=reference.time[j], pos_n=pos, v_n=vel,
                            att_n=quat_to_rotvec(dq))


def _common_epochs(t_a, t_b):
    k = np.searchsorted(t_b, t_a)
    k = np.clip(k, 1, max(len(t_b) - 1, 1))
    left = np.abs(t_b[k - 1] - t_a)
    right = np.abs(t_b[np.minimum(k, len(t_b) - 1)] - t_a)
    jb = np.where(left <= right, k - 1, np.minimum(k, len(t_b) - 1))
    ok = np.abs(t_b[jb] - t_a) <= TIME_TOLERANCE_S
    return np.flatnonzero(ok), jb[ok]

