"""Compiled loops of the LiDAR direct georeferencing (private; Cython;
:mod:`ins.lidar.georeference`).

Per return k: ``d_n = C_nb (l_b + C_bs r_s)``, the point in ECEF
``r_e = r_imu_e + C_en d_n``, and the first-order NED variance of the point from the
independent input sigmas (see :func:`ins.lidar.georeference.georeference`).  WGS84 from
``ins/nav/_earth.pxd``.  Both kernels release the GIL while they run.
"""
from libc.math cimport cos, sin, sqrt

from ins.nav._earth cimport WGS84_A, WGS84_E2


cdef inline void _cross(double a0, double a1, double a2, double b0, double b1, double b2,
                        double *o) noexcept nogil:
    o[0] = a1 * b2 - a2 * b1
    o[1] = a2 * b0 - a0 * b2
    o[2] = a0 * b1 - a1 * b0


cdef inline void _mv(const double[:, :] M, double x0, double x1, double x2,
                     double *o) noexcept nogil:
    """``M @ x`` (M 3x3)."""
    o[0] = M[0, 0] * x0 + M[0, 1] * x1 + M[0, 2] * x2
    o[1] = M[1, 0] * x0 + M[1, 1] * x1 + M[1, 2] * x2
    o[2] = M[2, 0] * x0 + M[2, 1] * x1 + M[2, 2] * x2


cdef inline void _mv9(const double *C, double x0, double x1, double x2,
                      double *o) noexcept nogil:
    """``C @ x`` (C 3x3 row by row)."""
    o[0] = C[0] * x0 + C[1] * x1 + C[2] * x2
    o[1] = C[3] * x0 + C[4] * x1 + C[5] * x2
    o[2] = C[6] * x0 + C[7] * x1 + C[8] * x2


cdef inline void _pv(const double[:, :, :] P, Py_ssize_t k, bint use_P, double x0,
                     double x1, double x2, double *o) noexcept nogil:
    """``P[k] @ x`` with ``use_P``, else x."""
    if use_P:
        o[0] = P[k, 0, 0] * x0 + P[k, 0, 1] * x1 + P[k, 0, 2] * x2
        o[1] = P[k, 1, 0] * x0 + P[k, 1, 1] * x1 + P[k, 1, 2] * x2
        o[2] = P[k, 2, 0] * x0 + P[k, 2, 1] * x1 + P[k, 2, 2] * x2
    else:
        o[0] = x0
        o[1] = x1
        o[2] = x2


cdef inline void _add_var(double *v, const double *j, double s) noexcept nogil:
    """``v += j**2 s`` per axis."""
    v[0] += j[0] * j[0] * s
    v[1] += j[1] * j[1] * s
    v[2] += j[2] * j[2] * s


def georeference_kernel(const double[:, :] lla, const double[:, :] q_nb,
                        const double[:, :] r_s, const double[:, :] C_bs,
                        const double[:] l_b, const double[:, :] M_x,
                        const double[:, :] M_xy, const double[:, :, :] P, bint use_P,
                        const double[:] l_bp, const double[:, :] std,
                        const double[:] lever_sig, const double[:] bore_sig,
                        double range_sig, double angle_sig, bint line_scanner,
                        double[:, :] xyz_e, double[:, :] var_ned):
    """Fill ``xyz_e`` (n, 3) ECEF points (m) and ``var_ned`` (n, 3) NED variances (m^2).

    ``lla`` (n, 3) IMU lat, lon (rad), h (m); ``q_nb`` (n, 4) scalar last; ``r_s`` (n, 3)
    m; ``C_bs`` = ``axes @ Rx @ Ry @ Rz`` with ``M_x`` = ``axes @ Rx``, ``M_xy`` =
    ``axes @ Rx @ Ry`` (for the boresight Jacobian); ``std`` (n, 6): position N, E, D (m), roll, pitch, yaw (rad);
    ``lever_sig``, ``bore_sig`` (3,); ``range_sig`` m, ``angle_sig`` rad; with
    ``line_scanner`` the scan-angle derivative of r_s is ``r_s x e_x``.  With ``use_P``
    (a scanner on the aircraft) every vector of the scanner's mounting frame is taken
    into b by ``P[k]`` (``C_ba(t)``, (n, 3, 3)) and the arm is ``l_bp + P[k] l_b``.
    """
    cdef Py_ssize_t n = lla.shape[0], k, i
    cdef double C[9]
    cdef double sv[3]
    cdef double pv[3]
    cdef double la[3]
    cdef double d[3]
    cdef double j[3]
    cdef double e[3]
    cdef double c[3]
    cdef double bv[3]
    cdef double v[3]
    cdef double x, y, z, w, s, rx, ry, rz, lat, lon, h, sl, cl, so, co, rn
    cdef double cpy, cps, nrm, cy, sy_, sr, sp, sw, li, bi, u0, u1, u2, rho, rr, aa
    cdef const double[:, :] M
    if (lla.shape[1] < 3 or q_nb.shape[0] < n or q_nb.shape[1] < 4 or r_s.shape[0] < n
            or r_s.shape[1] < 3 or C_bs.shape[0] < 3 or C_bs.shape[1] < 3 or l_b.shape[0] < 3
            or M_x.shape[0] < 3 or M_x.shape[1] < 3 or M_xy.shape[0] < 3
            or M_xy.shape[1] < 3 or (use_P and (P.shape[0] < n or P.shape[1] < 3
                                                or P.shape[2] < 3))
            or l_bp.shape[0] < 3 or std.shape[0] < n or std.shape[1] < 6
            or lever_sig.shape[0] < 3 or bore_sig.shape[0] < 3 or xyz_e.shape[0] < n
            or xyz_e.shape[1] < 3 or var_ned.shape[0] < n or var_ned.shape[1] < 3):
        raise ValueError("georeference_kernel: inconsistent array shapes")
    with nogil:
        for k in range(n):
            # C_nb from the quaternion
            x, y, z, w = q_nb[k, 0], q_nb[k, 1], q_nb[k, 2], q_nb[k, 3]
            s = 1.0 / (x * x + y * y + z * z + w * w)
            C[0] = 1 - 2 * s * (y * y + z * z)
            C[1] = 2 * s * (x * y - z * w)
            C[2] = 2 * s * (x * z + y * w)
            C[3] = 2 * s * (x * y + z * w)
            C[4] = 1 - 2 * s * (x * x + z * z)
            C[5] = 2 * s * (y * z - x * w)
            C[6] = 2 * s * (x * z - y * w)
            C[7] = 2 * s * (y * z + x * w)
            C[8] = 1 - 2 * s * (x * x + y * y)
            rx, ry, rz = r_s[k, 0], r_s[k, 1], r_s[k, 2]
            _mv(C_bs, rx, ry, rz, sv)
            _pv(P, k, use_P, sv[0], sv[1], sv[2], pv)
            _pv(P, k, use_P, l_b[0], l_b[1], l_b[2], la)
            if use_P:
                la[0], la[1], la[2] = la[0] + l_bp[0], la[1] + l_bp[1], la[2] + l_bp[2]
            _mv9(C, la[0] + pv[0], la[1] + pv[1], la[2] + pv[2], d)
            lat, lon, h = lla[k, 0], lla[k, 1], lla[k, 2]
            sl, cl, so, co = sin(lat), cos(lat), sin(lon), cos(lon)
            rn = WGS84_A / sqrt(1.0 - WGS84_E2 * sl * sl)
            # C_en columns: north, east, down in ECEF
            xyz_e[k, 0] = (rn + h) * cl * co - sl * co * d[0] - so * d[1] - cl * co * d[2]
            xyz_e[k, 1] = (rn + h) * cl * so - sl * so * d[0] + co * d[1] - cl * so * d[2]
            xyz_e[k, 2] = (rn * (1.0 - WGS84_E2) + h) * sl + cl * d[0] - sl * d[2]
            # variances (NED), independent sources
            v[0] = std[k, 0] * std[k, 0]
            v[1] = std[k, 1] * std[k, 1]
            v[2] = std[k, 2] * std[k, 2]
            # attitude: roll axis C[:, 0] (= Rz Ry e_x), pitch axis Rz(yaw) e_y, yaw axis e_z
            cpy, cps = C[0], C[3]
            nrm = sqrt(cpy * cpy + cps * cps)
            if nrm > 0:
                cy, sy_ = cpy / nrm, cps / nrm
            else:
                cy, sy_ = 1.0, 0.0
            _cross(C[0], C[3], C[6], d[0], d[1], d[2], j)
            sr = std[k, 3] * std[k, 3]
            _add_var(v, j, sr)
            _cross(-sy_, cy, 0.0, d[0], d[1], d[2], j)
            sp = std[k, 4] * std[k, 4]
            _add_var(v, j, sp)
            _cross(0.0, 0.0, 1.0, d[0], d[1], d[2], j)
            sw = std[k, 5] * std[k, 5]
            _add_var(v, j, sw)
            # lever arm: C_nb P e_i
            for i in range(3):
                li = lever_sig[i] * lever_sig[i]
                _pv(P, k, use_P, 1.0 * (i == 0), 1.0 * (i == 1), 1.0 * (i == 2), e)
                _mv9(C, e[0], e[1], e[2], j)
                _add_var(v, j, li)
            # boresight: d(C_bs r)/d(rx) = A Rx (e_x x (Ry Rz r)), ... (signs do not matter)
            # with u = Ry Rz r = (A Rx)^T C_bs r and w = Rz r = (A Rx Ry)^T C_bs r
            for i in range(3):
                bi = bore_sig[i] * bore_sig[i]
                if bi == 0.0:
                    continue
                if i == 0:
                    M = M_x
                elif i == 1:
                    M = M_xy
                else:
                    M = C_bs
                # u = M^T (C_bs r)
                u0 = M[0, 0] * sv[0] + M[1, 0] * sv[1] + M[2, 0] * sv[2]
                u1 = M[0, 1] * sv[0] + M[1, 1] * sv[1] + M[2, 1] * sv[2]
                u2 = M[0, 2] * sv[0] + M[1, 2] * sv[1] + M[2, 2] * sv[2]
                if i == 0:
                    _cross(1.0, 0.0, 0.0, u0, u1, u2, c)
                elif i == 1:
                    _cross(0.0, 1.0, 0.0, u0, u1, u2, c)
                else:
                    _cross(0.0, 0.0, 1.0, u0, u1, u2, c)
                _mv(M, c[0], c[1], c[2], bv)
                _pv(P, k, use_P, bv[0], bv[1], bv[2], e)
                _mv9(C, e[0], e[1], e[2], j)
                _add_var(v, j, bi)
            # range: along the ray; scan angle: r_s x e_x (line scanners)
            rho = sqrt(rx * rx + ry * ry + rz * rz)
            if rho > 0 and range_sig > 0:
                _mv(C_bs, rx / rho, ry / rho, rz / rho, bv)
                _pv(P, k, use_P, bv[0], bv[1], bv[2], e)
                _mv9(C, e[0], e[1], e[2], j)
                rr = range_sig * range_sig
                _add_var(v, j, rr)
            if line_scanner and angle_sig > 0:
                _cross(rx, ry, rz, 1.0, 0.0, 0.0, c)
                _mv(C_bs, c[0], c[1], c[2], bv)
                _pv(P, k, use_P, bv[0], bv[1], bv[2], e)
                _mv9(C, e[0], e[1], e[2], j)
                aa = angle_sig * angle_sig
                _add_var(v, j, aa)
            var_ned[k, 0] = v[0]
            var_ned[k, 1] = v[1]
            var_ned[k, 2] = v[2]


def interpolate_kernel(const double[:] t, const long long[:] slot, const double[:] t0,
                       const double[:] t1, const double[:, :] y0, const double[:, :] y1,
                       const double[:, :] d0, const double[:, :] d1, const double[:, :] tj,
                       const double[:, :, :] rvj, const double[:, :] q0,
                       double[:, :] lla_out, double[:, :] q_out):
    """The EO interpolation (:func:`ins.nav.interpolation.interpolate_trajectory`, "cubic")
    evaluated per return from per-interval data.

    For return i in interval ``slot[i]``: Hermite of (lat, lon, h) between ``y0``, ``y1``
    with slopes ``d0``, ``d1`` over ``[t0, t1]``; attitude ``q0 * exp(sum_j L_j(t)
    rv_j)`` with the Lagrange basis over the stencil times ``tj`` (slot, 4) of the
    rotation vectors ``rvj`` (slot, 4, 3) of ``q0^-1 q_j``.
    """
    cdef Py_ssize_t n = t.shape[0], m = t0.shape[0], i, c, j, jj
    cdef long long s_
    cdef double h, s, s2, s3, h00, h10, h01, h11, r0, r1, r2, w, angle, a2, k
    cdef double px, py, pz, pw, qx, qy, qz, qw
    if (slot.shape[0] < n or t1.shape[0] < m or y0.shape[0] < m or y1.shape[0] < m
            or d0.shape[0] < m or d1.shape[0] < m or tj.shape[0] < m or rvj.shape[0] < m
            or q0.shape[0] < m or y0.shape[1] < 3 or y1.shape[1] < 3 or d0.shape[1] < 3
            or d1.shape[1] < 3 or tj.shape[1] < 4 or rvj.shape[1] < 4 or rvj.shape[2] < 3
            or q0.shape[1] < 4 or lla_out.shape[0] < n or lla_out.shape[1] < 3
            or q_out.shape[0] < n or q_out.shape[1] < 4):
        raise ValueError("interpolate_kernel: inconsistent array shapes")
    for i in range(n):
        if not 0 <= slot[i] < m:
            raise IndexError(f"interpolate_kernel: slot {slot[i]} outside 0..{m - 1}")
    with nogil:
        for i in range(n):
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
            for j in range(4):
                w = 1.0
                for jj in range(4):
                    if jj != j:
                        w *= (t[i] - tj[s_, jj]) / (tj[s_, j] - tj[s_, jj])
                r0 += w * rvj[s_, j, 0]
                r1 += w * rvj[s_, j, 1]
                r2 += w * rvj[s_, j, 2]
            angle = sqrt(r0 * r0 + r1 * r1 + r2 * r2)
            if angle < 1e-4:
                a2 = angle * angle
                k = 0.5 - a2 / 48 + a2 * a2 / 3840
            else:
                k = sin(0.5 * angle) / angle
            px, py, pz, pw = q0[s_, 0], q0[s_, 1], q0[s_, 2], q0[s_, 3]
            qx, qy, qz, qw = r0 * k, r1 * k, r2 * k, cos(0.5 * angle)
            q_out[i, 0] = pw * qx + qw * px + py * qz - pz * qy
            q_out[i, 1] = pw * qy + qw * py + pz * qx - px * qz
            q_out[i, 2] = pw * qz + qw * pz + px * qy - py * qx
            q_out[i, 3] = pw * qw - px * qx - py * qy - pz * qz
