"""Simulated GNSS antenna log: the varying lever arm of a stabilized mount, noise, outages.

Geometry (``conventions.md`` item 4, ``docs/interfaces.md``): the IMU sits on the mount
platform (``b = p``), the antenna on the aircraft ``a``.  With ``l_bp`` the constant
IMU-to-platform-centre arm in ``b`` and ``l_ap`` the constant platform-centre-to-antenna
arm in ``a``, and ``C_pa(t)`` from the mount angles (``C_ap = Rz(yaw) Ry(pitch) Rx(roll)``,
platform relative to aircraft)::

    l_b(t)  = l_bp + C_pa(t) l_ap                       (C_bp = I)
    r_ant   = r_imu + C_nb l_b                          (exact, through ECEF)
    v_ant   = v_imu + C_nb (w_ib_b x l_b) - w_in_n x (C_nb l_b) + C_nb dl_b/dt

The velocity is the usual first-order form (KF-GINS, the lever-arm paper): it neglects the
transport-rate term ``w_en_n x (C_nb l_b)`` and the rotation between the n frames of the
IMU and of the antenna, both about ``|v| |l_b| / R`` (1e-5 m/s for 60 m/s and 1 m).

The log is an :class:`ins.io.gnss_log.GnssLog`, written with :func:`ins.io.gnss.write_gnss` (the
KF-GINS GNSS text of ``docs/interfaces.md``).
"""
import numpy as np

from ins.estimation.core.lever_arm import antenna_velocity
from ins.io.gnss_log import GnssLog
from ins.nav.earth import earth_rate_n, lla_rate, offset_ecef, offset_lla, transport_rate_n
from ins.nav.rotation import quat_to_dcm, rot_x, rot_y, rot_z, skew

__all__ = ["lever_arm_b", "antenna_state", "offset_ecef", "offset_lla", "gnss_times",
           "simulate_gnss"]

#: Smallest standard deviation written to the log, m and m/s.
STD_FLOOR = 1e-3

_E_X, _E_Y, _E_Z = skew(np.eye(3))


def lever_arm_b(mount_rpy, mount_rate, l_bp, l_ap):
    """IMU-to-antenna arm in the body frame and its time derivative.

    Parameters
    ----------
    mount_rpy : array_like, shape (n, 3)
        Mount angles roll, pitch, yaw of the platform relative to the aircraft, rad
        (``C_ap = Rz(yaw) Ry(pitch) Rx(roll)``).
    mount_rate : array_like, shape (n, 3)
        Their time derivatives, rad/s.
    l_bp : array_like, shape (3,)
        IMU to platform centre, in ``b`` (FRD), m.
    l_ap : array_like, shape (3,)
        Platform centre to antenna, in ``a`` (FRD), m.

    Returns
    -------
    l_b : ndarray, shape (n, 3)
        ``l_bp + C_pa l_ap``, m.
    dl_b : ndarray, shape (n, 3)
        ``d l_b / dt = (dC_ap/dt)^T l_ap``, m/s, with ``dC_ap/dt`` from the chain rule
        on the three elementary rotations.
    """
    rpy = np.atleast_2d(np.asarray(mount_rpy, dtype=float))
    rate = np.atleast_2d(np.asarray(mount_rate, dtype=float))
    l_bp = np.asarray(l_bp, dtype=float)
    l_ap = np.asarray(l_ap, dtype=float)
    Rx, Ry, Rz = rot_x(rpy[:, 0]), rot_y(rpy[:, 1]), rot_z(rpy[:, 2])
    C_ap = Rz @ Ry @ Rx
    dC_ap = (rate[:, 2, None, None] * (Rz @ _E_Z @ Ry @ Rx)
             + rate[:, 1, None, None] * (Rz @ Ry @ _E_Y @ Rx)
             + rate[:, 0, None, None] * (C_ap @ _E_X))
    l_b = l_bp + np.einsum("nji,j->ni", C_ap, l_ap)
    dl_b = np.einsum("nji,j->ni", dC_ap, l_ap)
    return l_b, dl_b


def antenna_state(sample, l_bp, l_ap):
    """True antenna position and velocity from a truth sample.

    Parameters
    ----------
    sample : ins.simulate.truth.TruthSample
        Uses ``lla``, ``v_n``, ``q_nb``, ``w_ib_b``, ``mount_rpy``, ``mount_rate``.
    l_bp, l_ap : array_like, shape (3,)
        The constant arms (m), see :func:`lever_arm_b`.

    Returns
    -------
    lla_ant : ndarray, shape (n, 3)
        Antenna latitude, longitude (rad), ellipsoidal height (m); exact through ECEF.
    v_ant_n : ndarray, shape (n, 3)
        Antenna velocity NED, m/s (first-order form of the module docstring).
    """
    lla = np.atleast_2d(sample.lla)
    C_nb = quat_to_dcm(np.atleast_2d(sample.q_nb))
    l_b, dl_b = lever_arm_b(sample.mount_rpy, sample.mount_rate, l_bp, l_ap)
    arm_n = np.einsum("nij,nj->ni", C_nb, l_b)
    lla_ant = offset_lla(lla, arm_n)
    w_in_n = earth_rate_n(lla[:, 0]) + transport_rate_n(lla[:, 0], lla[:, 2], sample.v_n)
    v_ant = antenna_velocity(np.atleast_2d(sample.v_n), C_nb, np.atleast_2d(sample.w_ib_b),
                             w_in_n, l_b, dl_b)
    return lla_ant, v_ant


def gnss_times(t_start, t_end, rate_hz, outages=()):
    """GNSS epochs: whole multiples of ``1 / rate_hz`` in ``[t_start, t_end]``, minus outages.

    Parameters
    ----------
    t_start, t_end : float
        Flight start and end, GPS s of week.
    rate_hz : float
        Fix rate, Hz.
    outages : sequence of (start_s, duration_s)
        Outages; ``start_s`` from the flight start (``t_start``), s.  Epochs with
        ``t_start + start_s <= t < t_start + start_s + duration_s`` are dropped.

    Returns
    -------
    ndarray, shape (n,)
    """
    k0 = int(np.ceil(t_start * rate_hz - 1e-9))
    k1 = int(np.floor(t_end * rate_hz + 1e-9))
    time = np.arange(k0, k1 + 1) / rate_hz
    keep = np.ones(len(time), dtype=bool)
    for start_s, duration_s in outages:
        t0 = t_start + start_s
        keep &= ~((time >= t0) & (time < t0 + duration_s))
    return time[keep]


def simulate_gnss(truth, time, l_bp, l_ap, sigma_ned_m, rng, velocity=False,
                  sigma_vel_mps=None, time_offset_s=0.0, lever_error_b_m=None,
                  velocity_time_offset_s=None):
    """Noisy antenna fixes at the given epochs.

    Parameters
    ----------
    truth : ins.simulate.truth.FlightTruth
        Evaluated at ``time``.
    time : array_like, shape (n,)
        Epochs (GPS s of week), e.g. from :func:`gnss_times`.
    l_bp, l_ap : array_like, shape (3,)
        Lever arms, m (:func:`lever_arm_b`).
    sigma_ned_m : array_like, shape (3,)
        White position noise north, east, down, m.
    rng : numpy.random.Generator
        Noise source (one generator per product keeps products independent of each other).
    velocity : bool
        Whether to add the antenna velocity (with white noise ``sigma_vel_mps``, m/s).
    time_offset_s : float
        IMU-GNSS time offset to inject, s: the record stamped ``t`` holds the antenna at
        the truth's (IMU) time ``t + time_offset_s`` (the sign of the filter's
        ``time_offset`` state).
    velocity_time_offset_s : float, optional
        The offset of the velocities instead, s, when the receiver stamps them
        differently from its positions (a record stamped ``t`` holds the antenna's
        velocity at IMU time ``t + velocity_time_offset_s``); ``None``:
        ``time_offset_s``.
    lever_error_b_m : array_like, shape (3,), optional
        Lever-arm error to inject, m, b frame: the antenna is at ``l_bp +
        lever_error_b_m + C_pa l_ap`` while the manifest states ``l_bp`` (the filter's
        ``lever_arm`` state estimates it).

    Returns
    -------
    ins.io.gnss_log.GnssLog
        The standard deviations are the noise sigmas, at least :data:`STD_FLOOR` (an
        error-free simulation still states a positive sigma, which the readers require).
    """
    time = np.asarray(time, dtype=float)
    sigma = np.broadcast_to(np.asarray(sigma_ned_m, dtype=float), (3,))
    sample = truth.evaluate(np.clip(time + float(time_offset_s), truth.t_start, truth.t_end))
    if lever_error_b_m is not None:
        l_bp = np.asarray(l_bp, dtype=float) + np.asarray(lever_error_b_m, dtype=float)
    lla, v_n = antenna_state(sample, l_bp, l_ap)
    # small NED offsets to (dlat, dlon, dh): D^-1, the same map as the position rate
    lla = lla + lla_rate(lla[:, 0], lla[:, 2], rng.standard_normal((len(time), 3)) * sigma)
    std = np.tile(np.maximum(sigma, STD_FLOOR), (len(time), 1))
    if not velocity:
        return GnssLog(time, lla, std)
    sigma_v = np.broadcast_to(np.asarray(sigma_vel_mps, dtype=float), (3,))
    if velocity_time_offset_s is not None and velocity_time_offset_s != time_offset_s:
        sample = truth.evaluate(np.clip(time + float(velocity_time_offset_s), truth.t_start,
                                        truth.t_end))
        v_n = antenna_state(sample, l_bp, l_ap)[1]
    v_n = v_n + rng.standard_normal((len(time), 3)) * sigma_v
    return GnssLog(time, lla, std, v_n, np.tile(np.maximum(sigma_v, STD_FLOOR), (len(time), 1)))
