"""Settings of the forward GNSS/INS filter (:class:`FilterSettings`): IMU noise, lever arm,
initial standard deviations and sensor estimates, measurement options, node interval."""
from dataclasses import dataclass, field

import numpy as np

from .error_model import STATE, ImuNoise
from .errors import InputError
from .lever_arm import LeverArm

DEG = np.pi / 180.0


@dataclass
class FilterSettings:
    """Settings of the forward filter.

    Parameters
    ----------
    noise : ImuNoise
        IMU noise (also gives the initial sigma of the sensor states).
    lever : LeverArm
        Antenna lever arm.
    pos_std_ned_m, vel_std_ned_mps : array_like, shape (3,)
        Initial position (m) and velocity (m/s) standard deviations, NED.
    att_std_deg : array_like, shape (3,)
        Initial attitude standard deviations (roll, pitch, heading), deg.
    initial_sensors : array_like, shape (12,)
        Initial gyro bias (rad/s), accel bias (m/s^2), gyro and accel scale (1).
    use_velocity : bool
        Use the GNSS velocity columns when the file has them.
    reject_probability : float
        Innovation-test false-rejection probability (chi-square with 3 dof).
    node_interval_s : float
        Longest interval between two covariance steps, s.
    """

    noise: ImuNoise = field(default_factory=ImuNoise)
    lever: LeverArm = field(default_factory=lambda: LeverArm(np.zeros(3)))
    pos_std_ned_m: object = (0.05, 0.05, 0.05)
    vel_std_ned_mps: object = (0.02, 0.02, 0.02)
    att_std_deg: object = (0.01, 0.01, 0.1)
    initial_sensors: object = None
    use_velocity: bool = True
    reject_probability: float = 1e-5
    node_interval_s: float = 1.0

    def initial_covariance(self):
        std = np.concatenate([np.broadcast_to(np.asarray(self.pos_std_ned_m, float), 3),
                              np.broadcast_to(np.asarray(self.vel_std_ned_mps, float), 3),
                              np.broadcast_to(np.asarray(self.att_std_deg, float), 3) * DEG,
                              self.noise.sensor_std])
        if np.any(~np.isfinite(std)) or np.any(std <= 0):
            raise InputError(f"initial standard deviations must be > 0, got {std[STATE.nav]}")
        return np.diag(std ** 2)
