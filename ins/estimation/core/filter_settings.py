"""Settings of the forward GNSS/INS filter (:class:`FilterSettings`): IMU noise, lever arm,
initial standard deviations and sensor estimates, measurement options, node interval."""
from dataclasses import dataclass, field

import numpy as np

from ins.common.errors import InputError
from ins.estimation.core.error_model import KFGINS, ImuNoise, StateLayout
from ins.estimation.core.lever_arm import LeverArm

DEG = np.pi / 180.0
ARCSEC = DEG / 3600.0

#: Default non-orthogonality prior per scale-factor prior: arcsec per ppm (see
#: :func:`default_misalignment_std_arcsec`).
MISALIGNMENT_ARCSEC_PER_PPM = 1.0
#: Smallest default non-orthogonality prior, arcsec (as a flight manifest's).
MIN_MISALIGNMENT_STD_ARCSEC = 1.0


def default_misalignment_std_arcsec(noise):
    """Prior sigmas of the gyro and accelerometer non-orthogonality when the config does
    not give them: tied to the IMU's grade through its scale-factor sigma.

    Rule: ``misalignment sigma (arcsec) = scale-factor sigma (ppm)`` per sensor and axis
    (:data:`MISALIGNMENT_ARCSEC_PER_PPM`), at least :data:`MIN_MISALIGNMENT_STD_ARCSEC`.
    Scale factor and non-orthogonality are the diagonal and the off-diagonal of the
    same calibration matrix and come with the same calibration; 1 arcsec (4.85e-6) per
    ppm puts the prior at or above the simulator's grades (off-diagonal 0.9 to 4.8 times
    the diagonal: navigation 5 ppm / 5 arcsec gyro, 50 ppm / 10 arcsec accelerometer;
    tactical 150 ppm / 50 arcsec, 300 ppm / 100 arcsec; mems 1000 ppm / 180 arcsec),
    so the filter is not overconfident on them.  The ``tactical`` preset (100 ppm)
    gets 100 arcsec, ``mems`` and ``land`` (1000 ppm) 1000 arcsec; a KF-GINS-like
    config (1 ppm, a calibrated IMU) 1 arcsec, where the survey layout then matches the
    21 states (``bench/bench_process.py --layout survey``; a flat 100 arcsec cost 80 %
    in forward tilt there: weakly observable pitch against ``m_y`` on yaw-only motion).

    Parameters
    ----------
    noise : ins.estimation.core.error_model.ImuNoise

    Returns
    -------
    gyro, accel : ndarray, shape (3,)
        Prior sigmas, arcsec (x, y, z).
    """
    return tuple(np.maximum(np.asarray(ppm, float) * MISALIGNMENT_ARCSEC_PER_PPM,
                            MIN_MISALIGNMENT_STD_ARCSEC)
                 for ppm in (noise.gyro_scale_std_ppm, noise.accel_scale_std_ppm))


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
    layout : ins.estimation.core.error_model.StateLayout
        The error states (default: the 21 KF-GINS states).
    gyro_misalignment_std_arcsec, accel_misalignment_std_arcsec : float or (3,), optional
        Prior sigma of the non-orthogonality states, arcsec; ``None`` (default): from
        the scale-factor sigma of ``noise`` (:func:`default_misalignment_std_arcsec`,
        1 arcsec per ppm, at least 1 arcsec).
    lever_arm_std_m : float or (3,)
        Prior sigma of the lever-arm correction, m (b frame).
    time_offset_std_ms : float
        Prior sigma of the IMU-GNSS time offset, ms.
    zupt : bool
        Zero-velocity updates at the nodes where the IMU is found at rest (the spread of
        the specific-force norm below ``zupt_accel_std_mps2`` and every angular rate
        below ``zupt_gyro_dps`` over the rows since the last node, with the filter's
        speed below ``ins.estimation.core.filter.ZUPT_MAX_SPEED_MPS``) or that fall in one of
        ``zupt_windows_s`` (GPS s); sigma ``zupt_sigma_mps``.  The windows apply with
        ``zupt`` false too (only the detector is off then): a rest known beforehand,
        such as the IMU's rest before the first GNSS fix that a run starts with.
    nhc : bool
        Non-holonomic constraint at every node (lateral and vertical velocity 0 in the
        vehicle axes, sigma ``nhc_sigma_mps``): for land vehicles.
    nhc_C_vb : array_like, shape (3, 3), optional
        The IMU's mounting in the vehicle, ``v_v = C_vb v_b`` (``[vehicle]
        mounting_rpy_deg``, :mod:`ins.estimation.tools.vehicle`); ``None``: the IMU's axes are the vehicle's.
    heading : sequence of ins.estimation.core.measurements.DualAntennaHeading, optional
        Dual-antenna headings, processed at the node of their time.
    recover : bool
        Recover from a run of rejected position fixes by inflating the navigation
        states' covariance (:data:`ins.estimation.core.updates.RECOVER_AFTER_S`); False keeps
        rejecting them.
    isb_std_m : float
        Prior sigma of the inter-system biases (layout group ``isb``), m.
    clock_bias_std_m, clock_drift_std_mps : float
        Prior sigma of the receiver clock states (layout group ``clock``), m and m/s.
    clock_psd : (float, float)
        Spectral densities of the clock's bias and drift noise, m^2/s and m^2/s^3
        (:func:`ins.estimation.core.error_model.noise_matrix`; default: a TCXO, h0 = 2e-19,
        h-2 = 2e-20).
    updater : callable, optional
        ``updater(settings, gnss)`` makes the object that processes the GNSS update
        events (default :class:`ins.estimation.core.updates.Updater`; tight coupling:
        :class:`ins.estimation.coupling.pseudorange.TightUpdater`).
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
    layout: StateLayout = KFGINS
    gyro_misalignment_std_arcsec: object = None
    accel_misalignment_std_arcsec: object = None
    lever_arm_std_m: object = 0.05
    time_offset_std_ms: float = 5.0
    zupt: bool = False
    zupt_sigma_mps: float = 0.005
    zupt_accel_std_mps2: float = 0.05
    zupt_gyro_dps: float = 0.5
    zupt_windows_s: tuple = ()
    nhc: bool = False
    nhc_sigma_mps: float = 0.1
    nhc_C_vb: object = None
    heading: tuple = ()
    recover: bool = True
    clock_bias_std_m: float = 30.0
    clock_drift_std_mps: float = 1.0
    isb_std_m: float = 300.0
    clock_psd: tuple = (0.5 * 299792458.0 ** 2 * 2e-19,
                        2.0 * np.pi ** 2 * 299792458.0 ** 2 * 2e-20)
    updater: object = None

    def prior_std(self):
        """Prior standard deviations of the optional groups of :attr:`layout`, SI."""
        gyro, accel = self.misalignment_std_arcsec()
        edge = {"gyro_misalignment": (gyro, ARCSEC, 3),
                "accel_misalignment": (accel, ARCSEC, 3),
                "lever_arm": (self.lever_arm_std_m, 1.0, 3),
                "time_offset": (self.time_offset_std_ms, 1e-3, 1),
                "clock": ((self.clock_bias_std_m, self.clock_drift_std_mps), 1.0, 2),
                "isb": (self.isb_std_m, 1.0, 4)}
        return np.concatenate([[]] + [np.broadcast_to(np.asarray(edge[g][0], float), edge[g][2])
                                      * edge[g][1] for g in self.layout.groups])

    def misalignment_std_arcsec(self):
        """The gyro and accelerometer non-orthogonality priors in use, arcsec (3,) each:
        the given ones, else :func:`default_misalignment_std_arcsec`."""
        derived = default_misalignment_std_arcsec(self.noise)
        return tuple(np.broadcast_to(np.asarray(d if v is None else v, float), 3)
                     for v, d in zip((self.gyro_misalignment_std_arcsec,
                                      self.accel_misalignment_std_arcsec), derived))

    def initial_covariance(self):
        std = np.concatenate([np.broadcast_to(np.asarray(self.pos_std_ned_m, float), 3),
                              np.broadcast_to(np.asarray(self.vel_std_ned_mps, float), 3),
                              np.broadcast_to(np.asarray(self.att_std_deg, float), 3) * DEG,
                              self.noise.sensor_std, self.prior_std(),
                              # unused ambiguity slots: 1 cycle, uncorrelated (the
                              # updater sets a slot when a satellite takes it)
                              np.ones(self.layout.n_ambiguities)])
        if np.any(~np.isfinite(std)) or np.any(std <= 0):
            raise InputError(f"initial standard deviations must be > 0, got "
                             f"{dict(zip(self.layout.names, std))}")
        return np.diag(std ** 2)
