"""The IMU's mounting in a land vehicle: the rotation ``C_vb`` from the IMU body axes ``b``
to the vehicle axes ``v`` that the non-holonomic constraint
(:class:`ins.estimation.core.measurements.NonHolonomic`) holds in, and its estimate from a solution.

Frames and convention
---------------------
``v``: forward, right, down of the vehicle (forward = its direction of travel on a
straight road).  ``C_vb`` takes a body vector into ``v`` (``v_v = C_vb v_b``).  The
config gives it as the IMU's roll, pitch and yaw in the vehicle frame,
``[vehicle] mounting_rpy_deg = [roll, pitch, yaw]``, with the Euler convention of
``C_nb`` (the INS angles of the conventions): ``C_vb = Rz(yaw) Ry(pitch) Rx(roll)``.  A positive
pitch is the IMU's nose up against the vehicle's: the forward velocity then shows in the
IMU's axes with a downward component, ``v_b = u (cos p cos y, -sin y, sin p cos y)``
(roll 0).  What the constraint needs is the vehicle's forward axis seen from the IMU
(two angles); a rotation about that axis turns the lateral and vertical axes into each
other, both held at zero, and cannot be seen in the velocity.  In this parameterization
the roll turns about the IMU's own x axis, so a roll goes with its own pitch and yaw:
give the three angles of one estimate together (the estimate fixes the roll, 0 by
default, and finds the pitch and yaw that put the forward axis where the velocity is).

Estimate (:func:`estimate_mounting`)
------------------------------------
From a solution without the constraint (a trajectory: time, ``v_n``, ``q_nb``): at the
epochs faster than ``min_speed_mps`` and turning slower than ``max_turn_dps`` (in turns
the IMU's offset from the vehicle's rear axle and the tyres' slip give a lateral
velocity), the direction of the body-frame velocity ``C_nb^T v_n``; its mean direction
gives pitch and yaw.  The sigma is the scatter of the means over ``block_s`` blocks
divided by the square root of their number (the epochs are correlated over seconds:
one block, one independent sample).  It does not hold the first solution's own attitude
error, common to all epochs (on the simulated car of ``tests/test_vehicle.py``, MEMS
IMU: pitch 3.915 +- 0.008 deg estimated against 3.873 true, tilt error 0.05 deg RMS;
over 5 seeds of ``bench/bench_land.py`` the yaw scatters by 0.062 deg against a stated
0.018): take the sigma as a lower bound.  Units: rad inside, deg at the edges.
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError

__all__ = ["mounting_dcm", "Mounting", "estimate_mounting", "MIN_SPEED_MPS", "MAX_TURN_DPS",
           "BLOCK_S"]

#: Default: epochs slower than this (m/s) are not used by the estimate.
MIN_SPEED_MPS = 5.0
#: Default: epochs turning faster than this (deg/s) are not used by the estimate.
MAX_TURN_DPS = 1.0
#: Default length of the blocks whose means give the sigma, s.
BLOCK_S = 5.0


def mounting_dcm(rpy_deg, where="mounting_rpy_deg"):
    """``C_vb`` (3 x 3) of the IMU's roll, pitch, yaw in the vehicle frame (deg):
    ``Rz(yaw) Ry(pitch) Rx(roll)`` (module notes).

    Raises
    ------
    InputError
        Not three finite numbers (``where`` names the key).
    """
    from scipy.spatial.transform import Rotation
    try:
        rpy = np.array(rpy_deg, dtype=float)
    except (TypeError, ValueError):
        rpy = None
    if rpy is None or rpy.shape != (3,) or not np.all(np.isfinite(rpy)):
        raise InputError(f"{where}: expected [roll, pitch, yaw] in deg (3 finite numbers: "
                         f"the IMU's attitude in the vehicle's forward-right-down axes), got "
                         f"{rpy_deg!r}")
    return Rotation.from_euler("ZYX", rpy[::-1], degrees=True).as_matrix()


@dataclass(frozen=True)
class Mounting:
    """An estimated mounting (:func:`estimate_mounting`).

    Attributes
    ----------
    rpy_deg : ndarray, shape (3,)
        Roll (the given value: not observable), pitch, yaw of the IMU in the vehicle
        frame, deg.
    sigma_deg : ndarray, shape (2,)
        1-sigma of pitch and yaw, deg.
    n_epochs, n_blocks : int
        Epochs used and blocks of ``block_s`` they fall in.
    scatter_deg : ndarray, shape (2,)
        Standard deviation of the per-epoch pitch and yaw of the velocity, deg.
    """

    rpy_deg: np.ndarray
    sigma_deg: np.ndarray
    n_epochs: int
    n_blocks: int
    scatter_deg: np.ndarray

    @property
    def C_vb(self):
        return mounting_dcm(self.rpy_deg)

    def toml(self):
        """The config line of this estimate (``[vehicle]`` table)."""
        r, p, y = self.rpy_deg
        return (f"[vehicle]\nmounting_rpy_deg = [{r:.3f}, {p:.3f}, {y:.3f}]   # sigma pitch "
                f"{self.sigma_deg[0]:.3f}, yaw {self.sigma_deg[1]:.3f} deg\n")


def _pitch_yaw(d_b, roll_rad):
    """Pitch and yaw (rad) of unit forward directions ``d_b`` (n, 3) in b, given roll."""
    c, s = np.cos(roll_rad), np.sin(roll_rad)
    d = np.column_stack([d_b[:, 0], c * d_b[:, 1] - s * d_b[:, 2],
                         s * d_b[:, 1] + c * d_b[:, 2]])           # Rx(roll) d_b
    return np.arctan2(d[:, 2], d[:, 0]), np.arctan2(-d[:, 1], np.hypot(d[:, 0], d[:, 2]))


def estimate_mounting(traj, min_speed_mps=MIN_SPEED_MPS, max_turn_dps=MAX_TURN_DPS,
                      block_s=BLOCK_S, roll_deg=0.0):
    """Pitch and yaw of the IMU against the vehicle's direction of travel (module notes).

    Parameters
    ----------
    traj : ins.nav.trajectory.Trajectory
        A solution without the non-holonomic constraint (time s, ``v_n`` m/s NED,
        ``q_nb``), e.g. ``solution.nav`` of ``ins process --preset mems``.
    min_speed_mps, max_turn_dps, block_s : float
        Slowest speed (m/s) and fastest turn (deg/s, the heading's rate) used; block
        length of the sigma (s).
    roll_deg : float
        The IMU's roll in the vehicle frame when known otherwise (deg); 0 by default.

    Returns
    -------
    Mounting

    Raises
    ------
    InputError
        Fewer than two blocks of straight driving at speed.
    """
    from scipy.spatial.transform import Rotation
    t = np.asarray(traj.time, dtype=float)
    if not (min_speed_mps > 0 and max_turn_dps > 0 and block_s > 0):
        raise InputError(f"min speed {min_speed_mps!r} m/s, max turn {max_turn_dps!r} deg/s, "
                         f"block {block_s!r} s: expected numbers > 0")
    R = Rotation.from_quat(traj.q_nb)
    v_b = R.inv().apply(traj.v_n)
    speed = np.linalg.norm(v_b, axis=1)
    heading = np.unwrap(R.as_euler("ZYX")[:, 0])
    turn = np.abs(np.gradient(heading, t)) if len(t) > 1 else np.zeros(len(t))
    use = (speed > min_speed_mps) & (turn < np.deg2rad(max_turn_dps))
    blocks = np.floor((t[use] - t[0]) / block_s).astype(int)
    ids = np.unique(blocks)
    if len(ids) < 2:
        raise InputError(f"{int(use.sum())} epochs faster than {min_speed_mps:g} m/s and "
                         f"turning slower than {max_turn_dps:g} deg/s, in {len(ids)} block(s) "
                         f"of {block_s:g} s: at least two blocks of straight driving are "
                         f"needed for the mounting")
    d = v_b[use] / speed[use, None]
    roll = np.deg2rad(roll_deg)
    mean = d.mean(axis=0)
    p, y = (float(a[0]) for a in _pitch_yaw((mean / np.linalg.norm(mean))[None], roll))
    per = np.column_stack(_pitch_yaw(d, roll))
    block_means = np.array([per[blocks == b].mean(axis=0) for b in ids])
    sigma = block_means.std(axis=0, ddof=1) / np.sqrt(len(ids))
    return Mounting(rpy_deg=np.array([float(roll_deg), np.rad2deg(p), np.rad2deg(y)]),
                    sigma_deg=np.rad2deg(sigma), n_epochs=int(use.sum()), n_blocks=len(ids),
                    scatter_deg=np.rad2deg(per.std(axis=0)))
