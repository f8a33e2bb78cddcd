"""Photogrammetric rotation matrices and the two named angle systems.

``R = C_mc`` takes a camera-frame vector into the mapping frame ``m``: an image ray
``(x, y, -f)`` (mm) points along ``C_mc @ (x, y, -f)`` in ``m``, so the collinearity
condition is ``X_m - X_0 = lambda * R @ (x, y, -f)``.

Two angle systems, always named, never implicit (``conventions.md``, "Rotations"):

==================== ======= ============================================ =======================
system               primary matrix                                       array order
==================== ======= ============================================ =======================
``phi-omega-kappa``  Y       ``R = Ry(-phi) @ Rx(omega) @ Rz(kappa)``     ``(phi, omega, kappa)``
``omega-phi-kappa``  X       ``R = Rx(omega) @ Ry(phi) @ Rz(kappa)``      ``(omega, phi, kappa)``
==================== ======= ============================================ =======================

``Rx``, ``Ry``, ``Rz`` are the ACTIVE elementary rotations of :mod:`ins.nav.rotation`
(``rot_x(a) = [[1, 0, 0], [0, cos a, -sin a], [0, sin a, cos a]]``, and cyclically): a
positive angle turns a vector counter-clockwise about the axis seen from its tip.

``phi-omega-kappa`` carries the sign of phi of the Russian/Vietnamese/Chinese textbooks
and programs whose name it has: ``R_phi = Ry(-phi) = [[cos phi, 0, -sin phi], [0, 1, 0],
[sin phi, 0, cos phi]]`` and the nine elements (rows a, b, c of ``R``)

    a1 = cos phi cos kappa - sin phi sin omega sin kappa
    a2 = -cos phi sin kappa - sin phi sin omega cos kappa
    a3 = -sin phi cos omega
    b1 = cos omega sin kappa,  b2 = cos omega cos kappa,  b3 = -sin omega
    c1 = sin phi cos kappa + cos phi sin omega sin kappa
    c2 = -sin phi sin kappa + cos phi sin omega cos kappa
    c3 = cos phi cos omega

with ``phi = atan2(-a3, c3)``, ``omega = asin(-b3)``, ``kappa = atan2(b1, b2)``.
``omega-phi-kappa`` is the Western (PATB, Applanix) system; its transpose is the
object-to-image matrix ``M`` of Wolf/Dewitt/Mikhail.  Near nadir with the mapping x axis
to the east the two phi differ in sign (``phi_W ~ -phi_CN``) and omega agrees to first
order.  In scipy's terms (intrinsic sequences) ``phi-omega-kappa`` is
``Rotation.from_euler('YXZ', [-phi, omega, kappa])`` and ``omega-phi-kappa`` is
``Rotation.from_euler('XYZ', [omega, phi, kappa])``.

Extracted angles: the primary angle and kappa in (-pi, pi], the middle (secondary)
angle in [-pi/2, pi/2].  At gimbal lock (middle angle +-90 deg, cosine below 1e-14)
only the sum or difference of primary and kappa is defined: kappa is set to 0 and the
primary angle carries the whole rotation about the vertical.  The primary angle is
recovered from ``D = R @ Rz(kappa).T`` (the rotation by the primary and middle angles
alone), which equals the atan2 of the textbook elements away from the lock and keeps the
matrix round trip exact to rounding at and near it.

INS attitude to camera attitude: ``C_mc = C_mn @ C_nb @ C_bc`` (:func:`camera_attitude`);
for the ENU mapping frame ``C_mn`` is :func:`dcm_mn_enu`.  The computer-vision (OpenCV,
COLMAP) convention is reached only through :func:`to_cv_rotation`/:func:`from_cv_rotation`.
"""
import numpy as np

from ins.nav.earth import dcm_en
from ins.nav.rotation import rot_x, rot_y, rot_z
from ins.nav.stacks import as_stack

__all__ = ["SYSTEMS", "angles_to_matrix", "matrix_to_angles", "check_system",
           "convert_angles", "dcm_mn_enu", "boresight_matrix", "camera_attitude",
           "to_cv_rotation", "from_cv_rotation", "P_NED_ENU", "C_CV_C"]

#: The accepted angle systems.
SYSTEMS = ("phi-omega-kappa", "omega-phi-kappa")
#: NED <-> ENU axis swap (its own inverse).
P_NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: Photogrammetric camera frame (x right, y up on the image, z backwards) to the
#: computer-vision camera frame (x right, y down, z forward): ``v_cv = C_CV_C @ v_c``.
C_CV_C = np.diag([1.0, -1.0, -1.0])

_GIMBAL_TOL = 1e-14


def check_system(system):
    """Return `system` if it is one of :data:`SYSTEMS`, else raise ValueError naming them."""
    if system not in SYSTEMS:
        raise ValueError(f"unknown angle system {system!r}; accepted: "
                         + ", ".join(repr(s) for s in SYSTEMS))
    return system


def _pm_pi(a):
    return np.where(a == -np.pi, np.pi, a) + 0.0   # (-pi, pi], no -0.0


def _pok_matrix(phi, omega, kappa):
    """Ry(-phi) Rx(omega) Rz(kappa), element by element (the textbooks' a1..c3)."""
    sp, so, sk = np.sin(phi), np.sin(omega), np.sin(kappa)
    cp, co, ck = np.cos(phi), np.cos(omega), np.cos(kappa)
    R = np.empty(phi.shape + (3, 3))
    R[:, 0, 0] = cp * ck - sp * so * sk          # a1
    R[:, 0, 1] = -cp * sk - sp * so * ck         # a2
    R[:, 0, 2] = -sp * co                        # a3
    R[:, 1, 0] = co * sk                         # b1
    R[:, 1, 1] = co * ck                         # b2
    R[:, 1, 2] = -so                             # b3
    R[:, 2, 0] = sp * ck + cp * so * sk          # c1
    R[:, 2, 1] = -sp * sk + cp * so * ck         # c2
    R[:, 2, 2] = cp * co                         # c3
    return R


def _opk_matrix(omega, phi, kappa):
    """Rx(omega) Ry(phi) Rz(kappa), element by element."""
    sp, so, sk = np.sin(phi), np.sin(omega), np.sin(kappa)
    cp, co, ck = np.cos(phi), np.cos(omega), np.cos(kappa)
    R = np.empty(phi.shape + (3, 3))
    R[:, 0, 0] = cp * ck
    R[:, 0, 1] = -cp * sk
    R[:, 0, 2] = sp
    R[:, 1, 0] = so * sp * ck + co * sk
    R[:, 1, 1] = -so * sp * sk + co * ck
    R[:, 1, 2] = -so * cp
    R[:, 2, 0] = -co * sp * ck + so * sk
    R[:, 2, 1] = co * sp * sk + so * ck
    R[:, 2, 2] = co * cp
    return R


def _pok_angles(R):
    # middle: b3 = -sin(omega); kappa: b1 = cos(omega) sin(kappa), b2 = cos(omega) cos(kappa)
    r10, r11 = R[:, 1, 0], R[:, 1, 1]
    cos_mid = np.hypot(r10, r11)
    omega = np.arctan2(-R[:, 1, 2], cos_mid)
    kappa = np.where(cos_mid < _GIMBAL_TOL, 0.0, np.arctan2(r10, r11))
    # D = R Rz(kappa)^T = Ry(-phi) Rx(omega): D00 = cos(phi), D20 = sin(phi)
    # (away from the lock the same as phi = atan2(-a3, c3))
    sk, ck = np.sin(kappa), np.cos(kappa)
    phi = np.arctan2(R[:, 2, 0] * ck - R[:, 2, 1] * sk, R[:, 0, 0] * ck - R[:, 0, 1] * sk)
    return np.stack([_pm_pi(phi), omega + 0.0, _pm_pi(kappa)], axis=-1)


def _opk_angles(R):
    # middle: R02 = sin(phi); kappa: R00 = cos(phi) cos(kappa), R01 = -cos(phi) sin(kappa)
    r00, r01 = R[:, 0, 0], R[:, 0, 1]
    cos_mid = np.hypot(r00, r01)
    phi = np.arctan2(R[:, 0, 2], cos_mid)
    kappa = np.where(cos_mid < _GIMBAL_TOL, 0.0, np.arctan2(-r01, r00))
    # D = R Rz(kappa)^T = Rx(omega) Ry(phi): D11 = cos(omega), D21 = sin(omega)
    sk, ck = np.sin(kappa), np.cos(kappa)
    omega = np.arctan2(R[:, 2, 0] * sk + R[:, 2, 1] * ck, R[:, 1, 0] * sk + R[:, 1, 1] * ck)
    return np.stack([_pm_pi(omega), phi + 0.0, _pm_pi(kappa)], axis=-1)


def angles_to_matrix(angles, system, degrees=False):
    """Rotation matrix ``R = C_mc`` of photogrammetric angles.

    Parameters
    ----------
    angles : array_like, shape (3,) or (n, 3)
        Angles in the order of the system's name: ``(phi, omega, kappa)`` for
        ``"phi-omega-kappa"``, ``(omega, phi, kappa)`` for ``"omega-phi-kappa"``;
        rad, or deg with ``degrees=True``.
    system : {"phi-omega-kappa", "omega-phi-kappa"}
        ``R = Ry(-phi) Rx(omega) Rz(kappa)`` (the textbooks' sign of phi) or
        ``R = Rx(omega) Ry(phi) Rz(kappa)`` (active elementary rotations of
        :mod:`ins.nav.rotation`).
    degrees : bool, default False

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
        ``C_mc``: maps camera-frame vectors (x, y image axes, z opposite to the view)
        into the mapping frame.

    Raises
    ------
    ValueError
        Unknown system or wrong shape.
    """
    check_system(system)
    a, single = as_stack(angles, "angles", (3,))
    if degrees:
        a = np.deg2rad(a)
    maker = _pok_matrix if system == "phi-omega-kappa" else _opk_matrix
    R = maker(a[:, 0], a[:, 1], a[:, 2])
    return R[0] if single else R


def matrix_to_angles(R, system, degrees=False):
    """Angles of a rotation matrix ``R = C_mc`` in a named system (inverse of
    :func:`angles_to_matrix`).

    Parameters
    ----------
    R : array_like, shape (3, 3) or (n, 3, 3)
        Rotation matrix (orthonormal, det +1).
    system : {"phi-omega-kappa", "omega-phi-kappa"}
    degrees : bool, default False
        Return degrees instead of radians.

    Returns
    -------
    ndarray, shape (3,) or (n, 3)
        Angles in the order of the system's name.  Primary angle and kappa in
        (-pi, pi], middle angle in [-pi/2, pi/2] (all from ``atan2``).

    Notes
    -----
    ``phi-omega-kappa``: ``phi = atan2(-a3, c3)``, ``omega = asin(-b3)``,
    ``kappa = atan2(b1, b2)``; ``omega-phi-kappa``: ``omega = atan2(-r23, r33)``,
    ``phi = asin(r13)``, ``kappa = atan2(-r12, r11)`` (1-based element names).
    Gimbal lock (middle angle +-90 deg, its cosine below 1e-14): kappa = 0, the primary
    angle takes the whole rotation about the then common axis.
    """
    check_system(system)
    R, single = as_stack(R, "R", (3, 3))
    a = _pok_angles(R) if system == "phi-omega-kappa" else _opk_angles(R)
    if degrees:
        a = np.rad2deg(a)
    return a[0] if single else a


def convert_angles(angles, from_system, to_system, degrees=False):
    """Angles of one system to the other (same rotation matrix ``R = C_mc``).

    Parameters
    ----------
    angles : array_like, shape (3,) or (n, 3)
        In the order of `from_system`'s name; rad, or deg with ``degrees=True``.
    from_system, to_system : {"phi-omega-kappa", "omega-phi-kappa"}
    degrees : bool, default False

    Returns
    -------
    ndarray, same shape
        In the order of `to_system`'s name, wrapped as :func:`matrix_to_angles`.
        Near nadir with the mapping x axis east, phi changes sign and omega stays to
        first order; reordering the numbers is not a conversion.
    """
    return matrix_to_angles(angles_to_matrix(angles, from_system, degrees), to_system, degrees)


def dcm_mn_enu(lat, lon, origin_lat, origin_lon):
    """``C_mn`` of the ENU tangent-plane mapping frame at a block origin.

    ``C_mn = P @ C_en(origin)^T @ C_en(lat, lon)`` with ``P`` the NED<->ENU swap: a NED
    vector at (lat, lon) goes to ECEF and then to ENU axes at the origin (exact; the
    flat-Earth swap alone is off by ~32 arcsec per km from the origin).

    Parameters
    ----------
    lat, lon : float or array_like, shape (n,)
        Geodetic position of the vector's n frame, rad.
    origin_lat, origin_lon : float
        Block origin, rad.

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
    """
    C_ne0 = np.swapaxes(dcm_en(origin_lat, origin_lon), -1, -2)
    return P_NED_ENU @ C_ne0 @ dcm_en(lat, lon)


def boresight_matrix(boresight_rad):
    """Boresight misalignment ``Rx(rx) @ Ry(ry) @ Rz(rz)``.

    Parameters
    ----------
    boresight_rad : array_like, shape (3,)
        ``(rx, ry, rz)``, rad: small rotations of the true camera axes relative to the
        nominal ones, ``C_bc = axes @ boresight_matrix(boresight_rad)``.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    b = np.asarray(boresight_rad, dtype=float)
    if b.shape != (3,):
        raise ValueError(f"boresight_rad must have shape (3,), got {b.shape}")
    return rot_x(b[0]) @ rot_y(b[1]) @ rot_z(b[2])


def camera_attitude(C_nb, C_bc, C_mn):
    """Camera attitude in the mapping frame: ``C_mc = C_mn @ C_nb @ C_bc``.

    Parameters
    ----------
    C_nb : array_like, shape (3, 3) or (n, 3, 3)
        IMU body (FRD) to NED.
    C_bc : array_like, shape (3, 3) or (n, 3, 3)
        Camera frame to body (camera axes and boresight, see
        :class:`photogrammetry.orientation.camera.CameraMounting`).
    C_mn : array_like, shape (3, 3) or (n, 3, 3)
        NED to the mapping frame (:func:`dcm_mn_enu`, or a projection's with the
        meridian convergence).

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
    """
    mats = [np.asarray(m, dtype=float) for m in (C_mn, C_nb, C_bc)]
    for name, m in zip(("C_mn", "C_nb", "C_bc"), mats):
        if m.shape[-2:] != (3, 3) or m.ndim > 3:
            raise ValueError(f"{name} must have shape (3, 3) or (n, 3, 3), got {m.shape}")
    return mats[0] @ mats[1] @ mats[2]


def to_cv_rotation(C_mc):
    """Computer-vision rotation ``R_cw`` (OpenCV, COLMAP) of a camera attitude ``C_mc``.

    The computer-vision camera has x right, y down, z forward (along the view); the
    photogrammetric camera frame of this package has x right, y up, z backwards.  So
    ``R_cw = C_CV_C @ C_mc.T`` maps mapping-frame (world) vectors into the CV camera
    frame, and a world point ``X`` projects with ``x_cv = R_cw @ X + t``,
    ``t = -R_cw @ X_0``.

    Parameters
    ----------
    C_mc : array_like, shape (3, 3) or (n, 3, 3)

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
    """
    C, single = as_stack(C_mc, "C_mc", (3, 3))
    R = C_CV_C @ np.swapaxes(C, -1, -2)
    return R[0] if single else R


def from_cv_rotation(R_cw):
    """Inverse of :func:`to_cv_rotation`: ``C_mc = R_cw.T @ C_CV_C``."""
    R, single = as_stack(R_cw, "R_cw", (3, 3))
    C = np.swapaxes(R, -1, -2) @ C_CV_C
    return C[0] if single else C
