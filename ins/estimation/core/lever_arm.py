"""GNSS antenna lever arm, fixed or varying with a gyro-stabilized mount.

Geometry (``conventions.md`` item 4; the lever-arm paper, whose formula images are lost):
the IMU sits on the stabilized platform (``C_bp = I``), the antenna on the aircraft.
With ``l_bp`` the IMU-to-platform-centre arm in ``b`` and ``l_ap`` the
platform-centre-to-antenna arm in ``a`` (m), and ``C_ap(t)`` from the mount angles, ::

    l_b(t) = l_bp + C_bp C_pa(t) l_ap,        C_pa = C_ap^T.

Antenna position and velocity (n frame, NED)::

    r_ant = r_imu + C_nb l_b                           (lat/lon/h through D^-1)
    v_ant = v_imu + C_nb (w_ib_b x l_b) - w_in_n x (C_nb l_b) + C_nb dl_b/dt

Jacobians with respect to the error state of :mod:`ins.estimation.core.error_model`
(``C_nb_est = (I - [phi x]) C_nb``, sensor errors truth minus estimate)::

    d r_ant = dr + [(C_nb l_b) x] phi
    d v_ant = dv + [(C_nb (w_ib_b x l_b + dl_b/dt)) x] phi
              - [w_in_n x][(C_nb l_b) x] phi - C_nb [l_b x] (d b_g + diag(w_ib_b) d s_g)

The mount angles are taken as exact (no error state): a mount-angle error enters as a
lever-arm error (0.1 deg on a 1 m arm is 1.7 mm).
"""
import numpy as np

from ins.estimation.core.error_model import ATT, BG, N_STATES, POS, SG, VEL
from ins.nav import earth
from ins.nav.rotation import skew

#: Half-width of the central difference of l_b(t), s.
RATE_STEP_S = 0.01


class LeverArm:
    """Antenna lever arm in ``b``, fixed or following the mount.

    Parameters
    ----------
    l_bp : array_like, shape (3,)
        IMU to platform centre (or, without mount, IMU to antenna), in ``b``, m.
    l_ap : array_like, shape (3,), optional
        Platform centre to antenna, in the aircraft frame ``a``, m.
    mount : ins.io.mount.MountLog, optional
        The mount angles; without it (or where it has no data) the mount is taken at its
        zero position: ``l_b = l_bp + l_ap``.
    """

    def __init__(self, l_bp, l_ap=(0.0, 0.0, 0.0), mount=None):
        self.l_bp = np.array(l_bp, dtype=float).reshape(3)
        self.l_ap = np.array(l_ap, dtype=float).reshape(3)
        if not (np.all(np.isfinite(self.l_bp)) and np.all(np.isfinite(self.l_ap))):
            raise ValueError("lever arms must be finite")
        self.mount = mount

    @property
    def static_b(self):
        """The arm with the mount at zero, ``l_bp + l_ap``, m."""
        return self.l_bp + self.l_ap

    @property
    def varying(self):
        return self.mount is not None

    def at(self, t):
        """Arm ``l_b`` (m), its rate ``dl_b/dt`` (m/s) and whether mount data covered ``t``.

        Parameters
        ----------
        t : float or array_like, shape (m,)

        Returns
        -------
        l_b, dl_b : ndarray, shape (m, 3)
        valid : ndarray of bool, shape (m,)
            False where the mount log has no data: the static arm is returned there.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.mount is None:
            return (np.tile(self.static_b, (len(t), 1)), np.zeros((len(t), 3)),
                    np.ones(len(t), bool))
        C_ap, valid = self.mount.C_ap(t)
        l_b = self.l_bp + np.einsum("mji,j->mi", C_ap, self.l_ap)
        C_p, ok_p = self.mount.C_ap(t + RATE_STEP_S)
        C_m, ok_m = self.mount.C_ap(t - RATE_STEP_S)
        dl_b = np.einsum("mji,j->mi", C_p - C_m, self.l_ap) / (2 * RATE_STEP_S)
        dl_b[~(ok_p & ok_m & valid)] = 0.0
        l_b[~valid] = self.static_b
        return l_b, dl_b, valid


    def at_one(self, t):
        """:meth:`at` of one epoch ``t`` (s): ``(l_b, dl_b, valid)``, shapes (3,), (3,)
        and a bool (without a mount: the static arm, no stacking)."""
        if self.mount is None:
            return self.l_bp + self.l_ap, np.zeros(3), True
        l_b, dl_b, valid = self.at(t)
        return l_b[0], dl_b[0], bool(valid[0])


def antenna_lla(lla, C_nb, l_b):
    """Antenna position (lat, lon rad, h m) from the IMU's ``lla``, ``C_nb`` and ``l_b``.

    The offset ``C_nb l_b`` (m, NED) is converted through ``D^-1`` at the IMU position
    (the error of this linearization is below 1e-6 m for arms of a few metres).
    """
    return lla + earth.lla_rate(lla[0], lla[2], C_nb @ l_b)


def antenna_lla_one(lla, arm_n):
    """:func:`antenna_lla` of one epoch with the arm already in n (``C_nb l_b``, m NED):
    the filter's per-epoch path, through the scalar formula of ``earth.lla_rate``."""
    return lla + np.array(earth.lla_rate_kernel(lla[0], lla[2], *arm_n.tolist()))


def antenna_velocity(v_n, C_nb, w_ib_b, w_in_n, l_b, dl_b):
    """Antenna velocity NED (m/s) (module notes); rates in rad/s, arms in m.

    ``v_n + C_nb (w_ib_b x l_b + dl_b/dt) - w_in_n x (C_nb l_b)``; one epoch, or stacks
    with a leading dimension n (``C_nb`` (n, 3, 3), the vectors (n, 3)).
    """
    arm_n = np.einsum("...ij,...j->...i", C_nb, l_b)
    return (v_n + np.einsum("...ij,...j->...i", C_nb, np.cross(w_ib_b, l_b) + dl_b)
            - np.cross(w_in_n, arm_n))


def position_jacobian(C_nb, l_b):
    """H (3 x 21) of the antenna position error (NED, m)."""
    H = np.zeros((3, N_STATES))
    H[:, POS] = np.eye(3)
    H[:, ATT] = skew(C_nb @ l_b)
    return H


def velocity_jacobian(C_nb, w_ib_b, w_in_n, l_b, dl_b):
    """H (3 x 21) of the antenna velocity error (NED, m/s)."""
    H = np.zeros((3, N_STATES))
    H[:, VEL] = np.eye(3)
    H[:, ATT] = (skew(C_nb @ (np.cross(w_ib_b, l_b) + dl_b))
                 - skew(w_in_n) @ skew(C_nb @ l_b))
    H[:, BG] = -C_nb @ skew(l_b)
    H[:, SG] = -C_nb @ skew(l_b) @ np.diag(w_ib_b)
    return H
