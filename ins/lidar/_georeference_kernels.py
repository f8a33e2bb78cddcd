"""Numba loop of the LiDAR direct georeferencing (private; :mod:`ins.lidar.georeference`).

Per return k: ``d_n = C_nb (l_b + C_bs r_s)``, the point in ECEF
``r_e = r_imu_e + C_en d_n``, and the first-order NED variance of the point from the
independent input sigmas (see :func:`ins.lidar.georeference.georeference`).
"""
import math

import numba as nb
import numpy as np

from ins.nav.earth import E2, A


@nb.njit(cache=True, inline="always")
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@nb.njit(cache=True, inline="always")
def _mv(M, x0, x1, x2):
    return (M[0, 0] * x0 + M[0, 1] * x1 + M[0, 2] * x2,
            M[1, 0] * x0 + M[1, 1] * x1 + M[1, 2] * x2,
            M[2, 0] * x0 + M[2, 1] * x1 + M[2, 2] * x2)


@nb.njit(cache=True, inline="always")
def _pv(P, k, use_P, x0, x1, x2):
    """``P[k] @ x`` with ``use_P``, else x."""
    if use_P:
        return (P[k, 0, 0] * x0 + P[k, 0, 1] * x1 + P[k, 0, 2] * x2,
                P[k, 1, 0] * x0 + P[k, 1, 1] * x1 + P[k, 1, 2] * x2,
                P[k, 2, 0] * x0 + P[k, 2, 1] * x1 + P[k, 2, 2] * x2)
    return x0, x1, x2


@nb.njit(cache=True)
def georeference_kernel(lla, q_nb, r_s, C_bs, l_b, M_x, M_xy, P, use_P, l_bp, std,
                        lever_sig, bore_sig, range_sig, angle_sig, line_scanner, xyz_e,
                        var_ned):
    """Fill ``xyz_e`` (n, 3) ECEF points (m) and ``var_ned`` (n, 3) NED variances (m^2).

    ``lla`` (n, 3) IMU lat, lon (rad), h (m); ``q_nb`` (n, 4) scalar last; ``r_s`` (n, 3)
    m; ``C_bs`` = ``axes @ Rx @ Ry @ Rz`` with ``M_x`` = ``axes @ Rx``, ``M_xy`` =
    ``axes @ Rx @ Ry`` (for the boresight Jacobian); ``std`` (n, 6): position N, E, D (m), roll, pitch, yaw (rad);
    ``lever_sig``, ``bore_sig`` (3,); ``range_sig`` m, ``angle_sig`` rad; with
    ``line_scanner`` the scan-angle derivative of r_s is ``r_s x e_x``.  With ``use_P``
    (a scanner on the aircraft) every vector of the scanner's mounting frame is taken
    into b by ``P[k]`` (``C_ba(t)``, (n, 3, 3)) and the arm is ``l_bp + P[k] l_b``.
    """
    n = lla.shape[0]
    C = np.empty((3, 3))
    for k in range(n):
        # C_nb from the quaternion
        x, y, z, w = q_nb[k, 0], q_nb[k, 1], q_nb[k, 2], q_nb[k, 3]
        s = 1.0 / (x * x + y * y + z * z + w * w)
        C[0, 0] = 1 - 2 * s * (y * y + z * z)
        C[0, 1] = 2 * s * (x * y - z * w)
        C[0, 2] = 2 * s * (x * z + y * w)
        C[1, 0] = 2 * s * (x * y + z * w)
        C[1, 1] = 1 - 2 * s * (x * x + z * z)
        C[1, 2] = 2 * s * (y * z - x * w)
        C[2, 0] = 2 * s * (x * z - y * w)
        C[2, 1] = 2 * s * (y * z + x * w)
        C[2, 2] = 1 - 2 * s * (x * x + y * y)
        rx, ry, rz = r_s[k, 0], r_s[k, 1], r_s[k, 2]
        sx, sy, sz = _mv(C_bs, rx, ry, rz)
        px, py, pz = _pv(P, k, use_P, sx, sy, sz)
        la0, la1, la2 = _pv(P, k, use_P, l_b[0], l_b[1], l_b[2])
        if use_P:
            la0, la1, la2 = la0 + l_bp[0], la1 + l_bp[1], la2 + l_bp[2]
        vb0, vb1, vb2 = la0 + px, la1 + py, la2 + pz
        d0, d1, d2 = _mv(C, vb0, vb1, vb2)
        lat, lon, h = lla[k, 0], lla[k, 1], lla[k, 2]
        sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
        rn = A / math.sqrt(1.0 - E2 * sl * sl)
        # C_en columns: north, east, down in ECEF
        xyz_e[k, 0] = (rn + h) * cl * co - sl * co * d0 - so * d1 - cl * co * d2
        xyz_e[k, 1] = (rn + h) * cl * so - sl * so * d0 + co * d1 - cl * so * d2
        xyz_e[k, 2] = (rn * (1.0 - E2) + h) * sl + cl * d0 - sl * d2
        # variances (NED), independent sources
        v0 = std[k, 0] ** 2
        v1 = std[k, 1] ** 2
        v2 = std[k, 2] ** 2
        # attitude: roll axis C[:, 0] (= Rz Ry e_x), pitch axis Rz(yaw) e_y, yaw axis e_z
        cpy, cps = C[0, 0], C[1, 0]
        nrm = math.sqrt(cpy * cpy + cps * cps)
        cy, sy_ = (cpy / nrm, cps / nrm) if nrm > 0 else (1.0, 0.0)
        j0, j1, j2 = _cross(C[0, 0], C[1, 0], C[2, 0], d0, d1, d2)
        sr = std[k, 3] ** 2
        v0 += j0 * j0 * sr
        v1 += j1 * j1 * sr
        v2 += j2 * j2 * sr
        j0, j1, j2 = _cross(-sy_, cy, 0.0, d0, d1, d2)
        sp = std[k, 4] ** 2
        v0 += j0 * j0 * sp
        v1 += j1 * j1 * sp
        v2 += j2 * j2 * sp
        j0, j1, j2 = _cross(0.0, 0.0, 1.0, d0, d1, d2)
        sw = std[k, 5] ** 2
        v0 += j0 * j0 * sw
        v1 += j1 * j1 * sw
        v2 += j2 * j2 * sw
        # lever arm: C_nb P e_i
        for i in range(3):
            li = lever_sig[i] ** 2
            e0, e1, e2 = _pv(P, k, use_P, 1.0 * (i == 0), 1.0 * (i == 1), 1.0 * (i == 2))
            j0, j1, j2 = _mv(C, e0, e1, e2)
            v0 += j0 * j0 * li
            v1 += j1 * j1 * li
            v2 += j2 * j2 * li
        # boresight: d(C_bs r)/d(rx) = A Rx (e_x x (Ry Rz r)), ... (signs do not matter)
        # with u = Ry Rz r = (A Rx)^T C_bs r and w = Rz r = (A Rx Ry)^T C_bs r
        for i in range(3):
            bi = bore_sig[i] ** 2
            if bi == 0.0:
                continue
            if i == 0:
                M = M_x
            elif i == 1:
                M = M_xy
            else:
                M = C_bs
            # u = M^T (C_bs r)
            u0 = M[0, 0] * sx + M[1, 0] * sy + M[2, 0] * sz
            u1 = M[0, 1] * sx + M[1, 1] * sy + M[2, 1] * sz
            u2 = M[0, 2] * sx + M[1, 2] * sy + M[2, 2] * sz
            if i == 0:
                c0, c1, c2 = _cross(1.0, 0.0, 0.0, u0, u1, u2)
            elif i == 1:
                c0, c1, c2 = _cross(0.0, 1.0, 0.0, u0, u1, u2)
            else:
                c0, c1, c2 = _cross(0.0, 0.0, 1.0, u0, u1, u2)
            b0, b1, b2 = _mv(M, c0, c1, c2)
            b0, b1, b2 = _pv(P, k, use_P, b0, b1, b2)
            j0, j1, j2 = _mv(C, b0, b1, b2)
            v0 += j0 * j0 * bi
            v1 += j1 * j1 * bi
            v2 += j2 * j2 * bi
        # range: along the ray; scan angle: r_s x e_x (line scanners)
        rho = math.sqrt(rx * rx + ry * ry + rz * rz)
        if rho > 0 and range_sig > 0:
            b0, b1, b2 = _mv(C_bs, rx / rho, ry / rho, rz / rho)
            b0, b1, b2 = _pv(P, k, use_P, b0, b1, b2)
            j0, j1, j2 = _mv(C, b0, b1, b2)
            rr = range_sig * range_sig
            v0 += j0 * j0 * rr
            v1 += j1 * j1 * rr
            v2 += j2 * j2 * rr
        if line_scanner and angle_sig > 0:
            c0, c1, c2 = _cross(rx, ry, rz, 1.0, 0.0, 0.0)
            b0, b1, b2 = _mv(C_bs, c0, c1, c2)
            b0, b1, b2 = _pv(P, k, use_P, b0, b1, b2)
            j0, j1, j2 = _mv(C, b0, b1, b2)
            aa = angle_sig * angle_sig
            v0 += j0 * j0 * aa
            v1 += j1 * j1 * aa
            v2 += j2 * j2 * aa
        var_ned[k, 0] = v0
        var_ned[k, 1] = v1
        var_ned[k, 2] = v2


@nb.njit(cache=True)
def interpolate_kernel(t, slot, t0, t1, y0, y1, d0, d1, tj, rvj, q0, lla_out, q_out):
    """The EO interpolation (:func:`ins.nav.interpolation.interpolate_trajectory`, "cubic")
    evaluated per return from per-interval data.

    For return i in interval ``slot[i]``: Hermite of (lat, lon, h) between ``y0``, ``y1``
    with slopes ``d0``, ``d1`` over ``[t0, t1]``; attitude ``q0 * exp(sum_j L_j(t)
    rv_j)`` with the Lagrange basis over the stencil times ``tj`` (slot, 4) of the
    rotation vectors ``rvj`` (slot, 4, 3) of ``q0^-1 q_j``.
    """
    for i in range(t.shape[0]):
        s_ = slot[i]
        h = t1[s_] - t0[s_]
        s = (t[i] - t0[s_]) / h
        s2 = s * s
        s3 = s2 * s
        h00 = 2 * s3 - 3 * s2 + 1
        h10 = s3 - 2 * s2 + s
        h01 = -2 * s3 + 3 * s2
        h11 = s3 - s2
        for c in range(3):
            lla_out[i, c] = (h00 * y0[s_, c] + h10 * h * d0[s_, c] + h01 * y1[s_, c]
                             + h11 * h * d1[s_, c])
        r0 = 0.0
        r1 = 0.0
        r2 = 0.0
        m = 4
        for j in range(m):
            w = 1.0
            for jj in range(m):
                if jj != j:
                    w *= (t[i] - tj[s_, jj]) / (tj[s_, j] - tj[s_, jj])
            r0 += w * rvj[s_, j, 0]
            r1 += w * rvj[s_, j, 1]
            r2 += w * rvj[s_, j, 2]
        angle = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        if angle < 1e-4:
            a2 = angle * angle
            k = 0.5 - a2 / 48 + a2 * a2 / 3840
        else:
            k = math.sin(0.5 * angle) / angle
        px, py, pz, pw = q0[s_, 0], q0[s_, 1], q0[s_, 2], q0[s_, 3]
        qx, qy, qz, qw = r0 * k, r1 * k, r2 * k, math.cos(0.5 * angle)
        q_out[i, 0] = pw * qx + qw * px + py * qz - pz * qy
        q_out[i, 1] = pw * qy + qw * py + pz * qx - px * qz
        q_out[i, 2] = pw * qz + qw * pz + px * qy - py * qx
        q_out[i, 3] = pw * qw - px * qx - py * qy - pz * qz
