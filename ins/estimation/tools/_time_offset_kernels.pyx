"""Compiled loop of ins.estimation.tools.time_offset (private; Cython): the body attitude
integrated from the gyro increments alone (no Earth or transport rate: the slowly varying
errors are fitted out)."""
import numpy as np

from libc.math cimport cos, sin, sqrt


def resolve_increments(const double[:, :] dtheta_b, const double[:, :] dvel_b):
    """Velocity increments resolved in the body frame at the first epoch (frame 0):
    ``C_0b(t_k) dvel_b[k]``, with ``C_0b`` the product of the rotation vectors
    ``dtheta_b`` (the velocity increment taken at the interval's mid attitude).

    Returns dvel_0, shape (n, 3)."""
    cdef Py_ssize_t n = dtheta_b.shape[0], k, stage
    cdef double q[4]
    cdef double half[4]
    cdef double a0, a1, a2, ang, s, x1, y1, z1, w1, x2, y2, z2, w2
    cdef double x, y, z, w, v0, v1, v2, cx, cy, cz, norm
    if dtheta_b.shape[1] < 3 or dvel_b.shape[0] < n or dvel_b.shape[1] < 3:
        raise ValueError("resolve_increments: dtheta_b and dvel_b must be (n, 3)")
    out_arr = np.empty((n, 3))
    cdef double[:, :] out = out_arr
    q[0] = q[1] = q[2] = 0.0      # scalar last
    q[3] = 1.0
    with nogil:
        for k in range(n):
            for stage in range(2):
                # half the increment, then the other half
                a0, a1, a2 = 0.5 * dtheta_b[k, 0], 0.5 * dtheta_b[k, 1], 0.5 * dtheta_b[k, 2]
                ang = sqrt(a0 * a0 + a1 * a1 + a2 * a2)
                s = 0.5 if ang == 0.0 else sin(0.5 * ang) / ang
                x1, y1, z1, w1 = q[0], q[1], q[2], q[3]
                x2, y2, z2, w2 = s * a0, s * a1, s * a2, cos(0.5 * ang)
                q[0] = w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2
                q[1] = w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2
                q[2] = w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2
                q[3] = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
                if stage == 0:
                    half[0], half[1], half[2], half[3] = q[0], q[1], q[2], q[3]
            x, y, z, w = half[0], half[1], half[2], half[3]
            v0, v1, v2 = dvel_b[k, 0], dvel_b[k, 1], dvel_b[k, 2]
            # rotate v by the mid-interval quaternion: v + 2w (u x v) + 2 u x (u x v)
            cx = y * v2 - z * v1
            cy = z * v0 - x * v2
            cz = x * v1 - y * v0
            out[k, 0] = v0 + 2.0 * (w * cx + y * cz - z * cy)
            out[k, 1] = v1 + 2.0 * (w * cy + z * cx - x * cz)
            out[k, 2] = v2 + 2.0 * (w * cz + x * cy - y * cx)
            norm = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
            q[0] = q[0] / norm
            q[1] = q[1] / norm
            q[2] = q[2] / norm
            q[3] = q[3] / norm
    return out_arr
