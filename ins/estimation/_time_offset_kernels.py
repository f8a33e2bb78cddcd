"""Numba loop of ins.estimation.time_offset: the body attitude integrated from the gyro increments
alone (no Earth or transport rate: the slowly varying errors are fitted out)."""
import numpy as np
from numba import njit


@njit(cache=True)
def resolve_increments(dtheta_b, dvel_b):
    """Velocity increments resolved in the body frame at the first epoch (frame 0):
    ``C_0b(t_k) dvel_b[k]``, with ``C_0b`` the product of the rotation vectors
    ``dtheta_b`` (the velocity increment taken at the interval's mid attitude).

    Returns dvel_0, shape (n, 3)."""
    n = dtheta_b.shape[0]
    out = np.empty((n, 3))
    q = np.array([0.0, 0.0, 0.0, 1.0])      # scalar last
    for k in range(n):
        half = np.empty(4)
        for stage in range(2):
            a = 0.5 * dtheta_b[k]            # half the increment, then the other half
            ang = np.sqrt(a[0] ** 2 + a[1] ** 2 + a[2] ** 2)
            s = 0.5 if ang == 0.0 else np.sin(0.5 * ang) / ang
            dq = np.array([s * a[0], s * a[1], s * a[2], np.cos(0.5 * ang)])
            x1, y1, z1, w1 = q[0], q[1], q[2], q[3]
            x2, y2, z2, w2 = dq[0], dq[1], dq[2], dq[3]
            q = np.array([w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                          w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                          w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
                          w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2])
            if stage == 0:
                half[:] = q
        x, y, z, w = half[0], half[1], half[2], half[3]
        v = dvel_b[k]
        # rotate v by the mid-interval quaternion: v + 2w (u x v) + 2 u x (u x v)
        cx = y * v[2] - z * v[1]
        cy = z * v[0] - x * v[2]
        cz = x * v[1] - y * v[0]
        out[k, 0] = v[0] + 2.0 * (w * cx + y * cz - z * cy)
        out[k, 1] = v[1] + 2.0 * (w * cy + z * cx - x * cz)
        out[k, 2] = v[2] + 2.0 * (w * cz + x * cy - y * cx)
        norm = np.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
        q = q / norm
    return out
