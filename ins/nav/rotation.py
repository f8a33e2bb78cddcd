"""Attitude representations: DCM, quaternion, Euler angles, rotation vector.

Conventions (``conventions.md``, "Rotations"):

- ``C_nb`` is the direction-cosine matrix (DCM) taking a vector from frame ``b``
  to frame ``n``: ``v_n = C_nb @ v_b``.
- Quaternions are scalar-last ``[x, y, z, w]`` with the Hamilton product;
  ``q_nb`` corresponds to ``C_nb`` exactly as
  ``scipy.spatial.transform.Rotation.from_quat(q_nb).as_matrix()`` does, and
  ``quat_multiply(q_ab, q_bc) = q_ac`` corresponds to ``C_ab @ C_bc``.
- Euler angles ``rpy = (roll phi, pitch theta, yaw psi)`` in the ZYX sequence:
  ``C_nb = rot_z(psi) @ rot_y(theta) @ rot_x(phi)``, i.e.
  ``Rotation.from_euler('ZYX', [psi, theta, phi])``.  Extracted angles are
  roll in (-pi, pi], pitch in [-pi/2, pi/2], yaw in (-pi, pi].
- A rotation vector ``rv`` is ``angle * unit_axis`` (rad); its quaternion is
  ``[sin(angle/2) * unit_axis, cos(angle/2)]``.

Every function takes one item, shape (3,), (4,) or (3, 3), or a stack of them,
shape (n, 3), (n, 4) or (n, 3, 3); the output has a leading ``n`` axis exactly
when an input had one.  Inputs are never modified.  The conversions and
``quat_normalize`` / ``quat_rotate`` refuse a NaN or infinite element with a
``ValueError`` naming the first offending row of a stack (a NaN quaternion
would otherwise pass the zero-norm test and come out as a NaN rotation); the
algebra (``skew``, ``quat_multiply``, ``quat_conjugate``) and the angle wraps
propagate NaN unchanged.  Quaternions returned by the
conversions (``dcm_to_quat``, ``euler_to_quat``, ``rotvec_to_quat``) have the
canonical sign ``w >= 0``; the algebraic functions (``quat_multiply``,
``quat_conjugate``, ``quat_normalize``) do not change the sign.
"""

import math

import numpy as np

from ins.nav.stacks import _canonical, _check_pair, _normalized, _out, _pm_pi, as_stack

__all__ = [
    "skew",
    "rot_x", "rot_y", "rot_z",
    "quat_multiply", "quat_conjugate", "quat_normalize", "quat_rotate",
    "quat_to_dcm", "quat_to_dcm_one", "dcm_to_quat",
    "euler_to_dcm", "dcm_to_euler", "euler_to_quat", "quat_to_euler",
    "rotvec_to_quat", "quat_to_rotvec", "rotvec_to_dcm", "dcm_to_rotvec",
    "wrap_to_pi", "wrap_to_2pi",
]

# Below this rotation angle (rad) the small-angle series are used.
_SMALL_ANGLE = 1e-4
# Gimbal lock is declared when cos(pitch) = hypot(C32, C33) is below this value;
# there the roll/yaw split is pure rounding noise.
_GIMBAL_TOL = 1e-14


# --------------------------------------------------------------------------
def skew(v):
    """Cross-product (skew-symmetric) matrix.

    Parameters
    ----------
    v : array_like, shape (3,) or (n, 3)
        Vector(s), any unit, any frame.

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
        ``S`` with ``S @ b == np.cross(v, b)`` for every 3-vector ``b``.
    """
    v, single = as_stack(v, "v", (3,))
    x, y, z = v.T
    S = np.zeros((len(v), 3, 3))
    S[:, 0, 1], S[:, 0, 2] = -z, y
    S[:, 1, 0], S[:, 1, 2] = z, -x
    S[:, 2, 0], S[:, 2, 1] = -y, x
    return _out(S, single)


def _elementary(angle, i, j):
    a = np.asarray(angle, dtype=float)
    if a.ndim > 1:
        raise ValueError(f"angle must be a scalar or have shape (n,), got {a.shape}")
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    R[..., 3 - i - j, 3 - i - j] = 1.0
    R[..., i, i], R[..., i, j] = c, -s
    R[..., j, i], R[..., j, j] = s, c
    return R


def rot_x(angle):
    """Elementary rotation about x (active): ``[[1, 0, 0], [0, c, -s], [0, s, c]]``.

    Parameters
    ----------
    angle : float or array_like, shape (n,)
        Rotation angle(s), rad.

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
    """
    return _elementary(angle, 1, 2)


def rot_y(angle):
    """Elementary rotation about y (active): ``[[c, 0, s], [0, 1, 0], [-s, 0, c]]``.

    Parameters
    ----------
    angle : float or array_like, shape (n,)
        Rotation angle(s), rad.

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
    """
    return _elementary(angle, 2, 0)


def rot_z(angle):
    """Elementary rotation about z (active): ``[[c, -s, 0], [s, c, 0], [0, 0, 1]]``.

    Parameters
    ----------
    angle : float or array_like, shape (n,)
        Rotation angle(s), rad.

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
    """
    return _elementary(angle, 0, 1)


# --------------------------------------------------------------------------
# quaternion algebra
def quat_multiply(p, q):
    """Hamilton product ``p * q`` of scalar-last quaternions.

    ``quat_multiply(q_ab, q_bc) = q_ac``, matching ``C_ab @ C_bc`` and scipy's
    ``Rotation * Rotation``.  The sign is not canonicalised.

    Parameters
    ----------
    p, q : array_like, shape (4,) or (n, 4)
        Quaternions ``[x, y, z, w]``; a single one is paired with every row of
        a stack.

    Returns
    -------
    ndarray, shape (4,) or (n, 4)
    """
    p, ps = as_stack(p, "p", (4,))
    q, qs = as_stack(q, "q", (4,))
    _check_pair(p, ps, q, qs, ("p", "q"))
    pv, pw = p[:, :3], p[:, 3:]
    qv, qw = q[:, :3], q[:, 3:]
    v = pw * qv + qw * pv + np.cross(pv, qv)
    w = pw * qw - np.sum(pv * qv, axis=1, keepdims=True)
    return _out(np.concatenate([v, w], axis=1), ps and qs)


def quat_conjugate(q):
    """Conjugate ``[-x, -y, -z, w]``; the inverse of a unit quaternion (``q_ba`` from ``q_ab``).

    Parameters
    ----------
    q : array_like, shape (4,) or (n, 4)

    Returns
    -------
    ndarray, shape (4,) or (n, 4)
    """
    q, single = as_stack(q, "q", (4,))
    return _out(q * np.array([-1.0, -1.0, -1.0, 1.0]), single)


def quat_normalize(q):
    """Scale quaternion(s) to unit norm (sign unchanged).

    Parameters
    ----------
    q : array_like, shape (4,) or (n, 4)

    Returns
    -------
    ndarray, shape (4,) or (n, 4)

    Raises
    ------
    ValueError
        If a quaternion has zero norm or a NaN / infinite element.
    """
    q, single = as_stack(q, "q", (4,), finite=True)
    return _out(_normalized(q), single)


def quat_rotate(q, v):
    """Rotate vector(s): ``C(q) @ v``, e.g. ``v_n = quat_rotate(q_nb, v_b)``.

    Parameters
    ----------
    q : array_like, shape (4,) or (n, 4)
        Quaternion(s) ``[x, y, z, w]``; normalised internally.
    v : array_like, shape (3,) or (n, 3)
        Vector(s) in the source frame; a single item is paired with every row of
        the other argument's stack.

    Returns
    -------
    ndarray, shape (3,) or (n, 3)
        Vector(s) in the target frame, same unit as `v`.
    """
    q, qs = as_stack(q, "q", (4,), finite=True)
    v, vs = as_stack(v, "v", (3,), finite=True)
    _check_pair(q, qs, v, vs, ("q", "v"))
    C = _q2c(_normalized(q))
    return _out((C @ v[:, :, np.newaxis])[:, :, 0], qs and vs)


# --------------------------------------------------------------------------
# stacked kernels: (n, ...) in, (n, ...) out
def _q2c(q):
    """DCM of unit quaternions (n, 4) -> (n, 3, 3)."""
    x, y, z, w = q.T
    C = np.empty((len(q), 3, 3))
    C[:, 0, 0] = 1 - 2 * (y * y + z * z)
    C[:, 0, 1] = 2 * (x * y - z * w)
    C[:, 0, 2] = 2 * (x * z + y * w)  # erratum 2: plus sign
    C[:, 1, 0] = 2 * (x * y + z * w)
    C[:, 1, 1] = 1 - 2 * (x * x + z * z)
    C[:, 1, 2] = 2 * (y * z - x * w)
    C[:, 2, 0] = 2 * (x * z - y * w)
    C[:, 2, 1] = 2 * (y * z + x * w)
    C[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return C


def _c2q(C):
    """Shepperd's method, (n, 3, 3) -> canonical unit (n, 4)."""
    n = len(C)
    c = C.reshape(n, 9).T
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = c
    tr = c00 + c11 + c22
    # Candidate k is 4 * q_k * q: accurate when q_k is the largest component.
    cand = np.stack([
        np.stack([1 + c00 - c11 - c22, c01 + c10, c02 + c20, c21 - c12], axis=-1),
        np.stack([c01 + c10, 1 - c00 + c11 - c22, c12 + c21, c02 - c20], axis=-1),
        np.stack([c02 + c20, c12 + c21, 1 - c00 - c11 + c22, c10 - c01], axis=-1),
        np.stack([c21 - c12, c02 - c20, c10 - c01, 1 + tr], axis=-1),
    ], axis=1)
    choice = np.argmax(np.stack([c00, c11, c22, tr], axis=-1), axis=-1)
    q = cand[np.arange(n), choice]
    return _canonical(q / np.linalg.norm(q, axis=-1, keepdims=True))


def _e2c(rpy):
    sr, sp, sy = np.sin(rpy).T
    cr, cp, cy = np.cos(rpy).T
    C = np.empty((len(rpy), 3, 3))
    C[:, 0, 0] = cp * cy
    C[:, 0, 1] = sr * sp * cy - cr * sy
    C[:, 0, 2] = cr * sp * cy + sr * sy
    C[:, 1, 0] = cp * sy
    C[:, 1, 1] = sr * sp * sy + cr * cy
    C[:, 1, 2] = cr * sp * sy - sr * cy
    C[:, 2, 0] = -sp
    C[:, 2, 1] = sr * cp
    C[:, 2, 2] = cr * cp
    return C


def _c2e(C):
    c32, c33 = C[:, 2, 1], C[:, 2, 2]
    cos_pitch = np.hypot(c32, c33)
    roll = np.where(cos_pitch < _GIMBAL_TOL, 0.0, np.arctan2(c32, c33))
    pitch = np.arctan2(-C[:, 2, 0], cos_pitch)
    # yaw from D = C @ rot_x(roll).T = rot_z(yaw) @ rot_y(pitch): D12 = -sin(yaw),
    # D22 = cos(yaw).  Equal to atan2(C21, C11) away from gimbal lock, and keeps
    # the matrix round trip exact near and at it.
    sr, cr = np.sin(roll), np.cos(roll)
    yaw = np.arctan2(sr * C[:, 0, 2] - cr * C[:, 0, 1], cr * C[:, 1, 1] - sr * C[:, 1, 2])
    return np.stack([_pm_pi(roll), pitch, _pm_pi(yaw)], axis=-1) + 0.0  # no -0.0


def _e2q(rpy):
    sr, sp, sy = np.sin(0.5 * rpy).T
    cr, cp, cy = np.cos(0.5 * rpy).T
    q = np.stack([sr * cp * cy - cr * sp * sy,
                  cr * sp * cy + sr * cp * sy,
                  cr * cp * sy - sr * sp * cy,
                  cr * cp * cy + sr * sp * sy], axis=-1)
    return _canonical(q)


def _rv2q(rv):
    angle = np.linalg.norm(rv, axis=-1)
    small = angle < _SMALL_ANGLE
    a2 = angle * angle
    # sin(angle/2)/angle, with its Taylor series where the quotient would lose accuracy
    k = np.where(small, 0.5 - a2 / 48 + a2 * a2 / 3840,
                 np.sin(0.5 * angle) / np.where(small, 1.0, angle))
    q = np.concatenate([rv * k[:, np.newaxis], np.cos(0.5 * angle)[:, np.newaxis]], axis=-1)
    return _canonical(q)


def _q2rv(q):
    q = _canonical(_normalized(q))
    v, w = q[:, :3], q[:, 3]
    s = np.linalg.norm(v, axis=-1)  # sin(angle/2)
    small = s < _SMALL_ANGLE        # then w = cos(angle/2) ~ 1
    w_safe = np.where(small, w, 1.0)
    r2 = (s / w_safe) ** 2
    # angle / s = 2 atan2(s, w) / s; series of atan for small s / w
    k = np.where(small, 2 / w_safe * (1 - r2 / 3 + r2 * r2 / 5),
                 2 * np.arctan2(s, w) / np.where(small, 1.0, s))
    return v * k[:, np.newaxis]


# --------------------------------------------------------------------------
# public conversions
def quat_to_dcm(q):
    """Quaternion to direction-cosine matrix, ``q_nb -> C_nb``.

    Parameters
    ----------
    q : array_like, shape (4,) or (n, 4)
        Quaternion(s) ``[x, y, z, w]``; normalised internally (as scipy does).

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
        ``C`` with ``C[0, 2] = 2 (q1 q3 + q2 q4)`` (the INS paper prints a minus:
        erratum 2 of ``conventions.md``).

    Raises
    ------
    ValueError
        On a wrong shape, a zero-norm quaternion or a NaN / infinite element (the
        message names the first offending row of a stack).
    """
    a = np.asarray(q, dtype=float)
    if a.shape == (4,) and np.isfinite(a).all():     # one quaternion: scalar arithmetic
        x, y, z, w = a.tolist()
        if ((x * x + y * y) + z * z) + w * w > 0:
            return quat_to_dcm_one(x, y, z, w)
    q, single = as_stack(a, "q", (4,), finite=True)
    return _out(_q2c(_normalized(q)), single)


def quat_to_dcm_one(x, y, z, w):
    """:func:`quat_to_dcm` of one quaternion given as four floats (finite, not all
    zero), without its checks: the filter's per-node fast path.  The norm is summed in
    numpy's order for four elements, so the matrix is the same to the bit."""
    norm = math.sqrt(((x * x + y * y) + z * z) + w * w)
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def dcm_to_quat(C):
    """Direction-cosine matrix to quaternion, ``C_nb -> q_nb``.

    Uses Shepperd's method (the largest quaternion component is found from the
    trace and diagonal, the others from off-diagonal sums and differences), so
    it is accurate for all rotations, including 180 deg where the paper's
    division by ``q4`` fails.

    Parameters
    ----------
    C : array_like, shape (3, 3) or (n, 3, 3)
        Rotation matrix (assumed orthonormal with determinant +1; otherwise the
        result is the normalised quaternion of a nearby rotation).

    Returns
    -------
    ndarray, shape (4,) or (n, 4)
        Unit quaternion ``[x, y, z, w]`` with ``w >= 0``.
    """
    C, single = as_stack(C, "C", (3, 3), finite=True)
    return _out(_c2q(C), single)


def euler_to_dcm(rpy, *, degrees=False):
    """Euler angles (roll, pitch, yaw) to ``C_nb = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)``.

    Parameters
    ----------
    rpy : array_like, shape (3,) or (n, 3)
        Roll phi, pitch theta, yaw psi of ``b`` relative to ``n``; rad, or deg
        with ``degrees=True``.
    degrees : bool, default False
        Whether `rpy` is in degrees.

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
        ``C_nb``; equals ``Rotation.from_euler('ZYX', [yaw, pitch, roll]).as_matrix()``.
    """
    rpy, single = as_stack(rpy, "rpy", (3,), finite=True)
    if degrees:
        rpy = np.deg2rad(rpy)
    return _out(_e2c(rpy), single)


def dcm_to_euler(C, *, degrees=False):
    """Direction-cosine matrix ``C_nb`` to Euler angles (roll, pitch, yaw).

    Parameters
    ----------
    C : array_like, shape (3, 3) or (n, 3, 3)
        Rotation matrix ``C_nb``.
    degrees : bool, default False
        Whether to return degrees instead of radians.

    Returns
    -------
    ndarray, shape (3,) or (n, 3)
        ``[roll, pitch, yaw]``: roll = atan2(C32, C33) in (-pi, pi],
        pitch = atan2(-C31, hypot(C32, C33)) in [-pi/2, pi/2],
        yaw = atan2(C21, C11) in (-pi, pi] (the paper's "omega").

    Notes
    -----
    Yaw is evaluated in the equivalent form ``atan2(-D12, D22)`` with
    ``D = C @ rot_x(roll).T``, which stays well conditioned near gimbal lock, so
    ``euler_to_dcm(dcm_to_euler(C))`` reproduces ``C`` to rounding for every
    rotation.  At gimbal lock (``hypot(C32, C33) < 1e-14``, pitch = +-90 deg to
    within 1e-14 rad) roll and yaw are not separable: roll is set to 0 and yaw
    carries the combined angle (yaw - roll at pitch = +90 deg, yaw + roll at
    pitch = -90 deg).  (scipy's ``as_euler`` makes the opposite choice, yaw = 0.)
    """
    C, single = as_stack(C, "C", (3, 3), finite=True)
    rpy = _c2e(C)
    return _out(np.rad2deg(rpy) if degrees else rpy, single)


def euler_to_quat(rpy, *, degrees=False):
    """Euler angles (roll, pitch, yaw) to quaternion ``q_nb``.

    Parameters
    ----------
    rpy : array_like, shape (3,) or (n, 3)
        Roll, pitch, yaw; rad, or deg with ``degrees=True``.
    degrees : bool, default False
        Whether `rpy` is in degrees.

    Returns
    -------
    ndarray, shape (4,) or (n, 4)
        ``q_z(yaw) * q_y(pitch) * q_x(roll)`` as ``[x, y, z, w]``, with ``w >= 0``.
    """
    rpy, single = as_stack(rpy, "rpy", (3,), finite=True)
    if degrees:
        rpy = np.deg2rad(rpy)
    return _out(_e2q(rpy), single)


def quat_to_euler(q, *, degrees=False):
    """Quaternion ``q_nb`` to Euler angles (roll, pitch, yaw).

    Parameters
    ----------
    q : array_like, shape (4,) or (n, 4)
        Quaternion(s) ``[x, y, z, w]``; normalised internally.
    degrees : bool, default False
        Whether to return degrees instead of radians.

    Returns
    -------
    ndarray, shape (3,) or (n, 3)
        ``[roll, pitch, yaw]`` with the ranges and gimbal-lock rule of
        :func:`dcm_to_euler`.
    """
    q, single = as_stack(q, "q", (4,), finite=True)
    rpy = _c2e(_q2c(_normalized(q)))
    return _out(np.rad2deg(rpy) if degrees else rpy, single)


def rotvec_to_quat(rv):
    """Rotation vector to quaternion: ``[sin(a/2) u, cos(a/2)]`` for ``rv = a u``.

    Parameters
    ----------
    rv : array_like, shape (3,) or (n, 3)
        Rotation vector(s), rad; any norm.

    Returns
    -------
    ndarray, shape (4,) or (n, 4)
        Unit quaternion(s) with ``w >= 0`` (norms above pi give the negated
        exponential, the same rotation).

    Notes
    -----
    Below 1e-4 rad ``sin(a/2)/a`` is replaced by its series ``1/2 - a^2/48 + a^4/3840``,
    so tiny and zero vectors are exact (no 0/0).
    """
    rv, single = as_stack(rv, "rv", (3,), finite=True)
    return _out(_rv2q(rv), single)


def quat_to_rotvec(q):
    """Quaternion to rotation vector with angle in [0, pi].

    Parameters
    ----------
    q : array_like, shape (4,) or (n, 4)
        Quaternion(s) ``[x, y, z, w]``; normalised internally, either sign.

    Returns
    -------
    ndarray, shape (3,) or (n, 3)
        ``angle * axis``, rad, with ``angle = 2 atan2(|v|, |w|)``; accurate for
        tiny angles (series) and near pi (atan2, no arccos).
    """
    q, single = as_stack(q, "q", (4,), finite=True)
    return _out(_q2rv(q), single)


def rotvec_to_dcm(rv):
    """Rotation vector to direction-cosine matrix (Rodrigues, via the quaternion).

    Parameters
    ----------
    rv : array_like, shape (3,) or (n, 3)
        Rotation vector(s), rad.

    Returns
    -------
    ndarray, shape (3, 3) or (n, 3, 3)
    """
    rv, single = as_stack(rv, "rv", (3,), finite=True)
    return _out(_q2c(_rv2q(rv)), single)


def dcm_to_rotvec(C):
    """Direction-cosine matrix to rotation vector with angle in [0, pi].

    Parameters
    ----------
    C : array_like, shape (3, 3) or (n, 3, 3)
        Rotation matrix.

    Returns
    -------
    ndarray, shape (3,) or (n, 3)
        Rotation vector(s), rad (via Shepperd's quaternion, so accurate at 180 deg).
    """
    C, single = as_stack(C, "C", (3, 3), finite=True)
    return _out(_q2rv(_c2q(C)), single)


# --------------------------------------------------------------------------
def wrap_to_pi(a):
    """Wrap angle(s) to (-pi, pi].

    Parameters
    ----------
    a : float or array_like, any shape
        Angle(s), rad.

    Returns
    -------
    float or ndarray, same shape as `a`
        Values already in (-pi, pi] are returned unchanged (bit for bit).
    """
    a = np.asarray(a, dtype=float)
    r = np.remainder(a + np.pi, 2 * np.pi) - np.pi  # [-pi, pi]
    r = np.where(r <= -np.pi, np.pi, r)
    return np.where((a > -np.pi) & (a <= np.pi), a, r)[()]


def wrap_to_2pi(a):
    """Wrap angle(s) to [0, 2 pi), e.g. yaw for files.

    Parameters
    ----------
    a : float or array_like, any shape
        Angle(s), rad.

    Returns
    -------
    float or ndarray, same shape as `a`
        Values already in [0, 2 pi) are returned unchanged (bit for bit).
    """
    a = np.asarray(a, dtype=float)
    r = np.remainder(a, 2 * np.pi)
    r = np.where(r >= 2 * np.pi, 0.0, r)
    return np.where((a >= 0) & (a < 2 * np.pi), a, r)[()]
