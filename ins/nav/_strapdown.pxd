# Strapdown mechanization step as C inline functions (private), cimported by
# ins/nav/_kernels.pyx and ins/estimation/core/_filter_kernels.pyx so that the step is inlined
# into both loops (a function cimported from another extension module would be called
# through a pointer).
#
# State vector layout (double[10]): lat, lon (rad), h (m), vN, vE, vD (m/s),
# q_nb = qx, qy, qz, qw (scalar last).  Quaternions are scalar last; C_nb rows are stored
# row by row in double[9] (c[3 i + j] = C[i, j]).
#
# Each expression keeps the operation order of the numba kernels it replaced (no FMA:
# setup.py compiles with -ffp-contract=off), so the results are the same to the bit.
from libc.math cimport cos, sin, sqrt

from ins.nav._earth cimport earth_rate, gravity, radii, transport_rate

cdef enum:
    N_STATE = 10


cdef inline void rates(double lat, double h, double vn, double ve, double *r) noexcept nogil:
    """Earth rate, transport rate in n (rad/s) and gravity (m/s^2) at (lat rad, h m, v m/s):
    r = wie_n, wie_d, wen_n, wen_e, wen_d, g."""
    earth_rate(lat, &r[0], &r[1])
    transport_rate(lat, h, vn, ve, &r[2], &r[3], &r[4])
    r[5] = gravity(lat, h)


cdef inline void quat_to_dcm_rows(double qx, double qy, double qz, double qw,
                                  double *c) noexcept nogil:
    """C of the unit quaternion [qx, qy, qz, qw] (scalar last) into c[0:9], row by row
    (the same as ins.nav.rotation.quat_to_dcm)."""
    c[0] = 1.0 - 2.0 * (qy * qy + qz * qz)
    c[1] = 2.0 * (qx * qy - qz * qw)
    c[2] = 2.0 * (qx * qz + qy * qw)
    c[3] = 2.0 * (qx * qy + qz * qw)
    c[4] = 1.0 - 2.0 * (qx * qx + qz * qz)
    c[5] = 2.0 * (qy * qz - qx * qw)
    c[6] = 2.0 * (qx * qz - qy * qw)
    c[7] = 2.0 * (qy * qz + qx * qw)
    c[8] = 1.0 - 2.0 * (qx * qx + qy * qy)


cdef inline void rotvec_to_quat(double x, double y, double z, double *q) noexcept nogil:
    """Quaternion q = (x, y, z, w) of a rotation vector (rad); series below 0.01 rad."""
    cdef double a2 = x * x + y * y + z * z
    cdef double s, c, a
    if a2 < 1e-4:
        s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0 - a2 * a2 * a2 / 645120.0
        c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0 - a2 * a2 * a2 / 46080.0
    else:
        a = sqrt(a2)
        s = sin(0.5 * a) / a
        c = cos(0.5 * a)
    q[0] = x * s
    q[1] = y * s
    q[2] = z * s
    q[3] = c


cdef inline void quat_mul(double px, double py, double pz, double pw,
                          double qx, double qy, double qz, double qw,
                          double *r) noexcept nogil:
    """Hamilton product r = p * q, scalar last (C(p * q) = C(p) C(q))."""
    r[0] = pw * qx + px * qw + py * qz - pz * qy
    r[1] = pw * qy - px * qz + py * qw + pz * qx
    r[2] = pw * qz + px * qy - py * qx + pz * qw
    r[3] = pw * qw - px * qx - py * qy - pz * qz


cdef inline void normalize_into(double qx, double qy, double qz, double qw,
                                double *s) noexcept nogil:
    """s[0:4] = q / |q|, sign chosen so that qw >= 0."""
    cdef double norm = sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if qw < 0.0:
        norm = -norm
    s[0] = qx / norm
    s[1] = qy / norm
    s[2] = qz / norm
    s[3] = qw / norm


cdef inline void specific_force_n(const double *c, double zn, double ze, double zd,
                                  double fx, double fy, double fz, double *a) noexcept nogil:
    """a = (I - 0.5 [zeta x]) C_nb f_b: body increment (m/s) into n at mid-interval."""
    cdef double gx = c[0] * fx + c[1] * fy + c[2] * fz
    cdef double gy = c[3] * fx + c[4] * fy + c[5] * fz
    cdef double gz = c[6] * fx + c[7] * fy + c[8] * fz
    a[0] = gx - 0.5 * (ze * gz - zd * gy)
    a[1] = gy - 0.5 * (zd * gx - zn * gz)
    a[2] = gz - 0.5 * (zn * gy - ze * gx)


cdef inline void gravity_coriolis(const double *r, double vn, double ve, double vd,
                                  double dt, double *o) noexcept nogil:
    """o = (g_n - (2 w_ie_n + w_en_n) x v_n) dt, m/s; r as filled by rates()."""
    cdef double an = 2.0 * r[0] + r[2]
    cdef double ae = r[3]
    cdef double ad = 2.0 * r[1] + r[4]
    o[0] = -(ae * vd - ad * ve) * dt
    o[1] = -(ad * vn - an * vd) * dt
    o[2] = (r[5] - (an * ve - ae * vn)) * dt


cdef inline void step(double *s, double *c, const double *th_p, const double *dv_p,
                      const double *th, const double *dv, double dt) noexcept nogil:
    """One two-sample strapdown step, in place on the state s (layout above).

    th_p, dv_p: previous row's increments; th, dv: this row's (rad, m/s, body frame);
    dt: the interval, s.  Order: (1) velocity, (2) position, (3) attitude.  The velocity
    update uses the attitude at the start of the interval, compensates the body
    increment for rotation (to third order) and sculling, and rotates it to
    mid-interval; Coriolis and gravity are evaluated at the mid-interval position and
    velocity extrapolated from the start of the interval (pass 1) and then at that mid
    point (pass 2).  The position update integrates D^-1 v with the mean of the old and
    new velocity and the radii at mid-interval.  The attitude update applies the body
    rotation (with coning) on the right and the n-frame rotation (w_ie_n + w_en_n) dt
    of pass 2 on the left.  c receives C_nb at the start of the interval (9 values).
    """
    cdef double lat = s[0], lon = s[1], h = s[2]
    cdef double vn = s[3], ve = s[4], vd = s[5]
    cdef double r[6]
    cdef double a[3]
    cdef double g[3]
    cdef double q[4]
    cdef double n[4]
    cdef double b[4]
    cdef double rx, ry, rz, fx, fy, fz, zn, ze, zd, mvn, mve, mvd, rm, rn, mh, mlat
    cdef double vn1, ve1, vd1, bvn, bve, bvd, px, py, pz

    # --- body velocity increment: rotation compensation to third order,
    # 0.5 th x dv + (1/6) th x (th x dv), and two-sample sculling
    rx = th[1] * dv[2] - th[2] * dv[1]
    ry = th[2] * dv[0] - th[0] * dv[2]
    rz = th[0] * dv[1] - th[1] * dv[0]
    fx = dv[0] + 0.5 * rx + (th[1] * rz - th[2] * ry) / 6.0 + (
        th_p[1] * dv[2] - th_p[2] * dv[1] + dv_p[1] * th[2] - dv_p[2] * th[1]) / 12.0
    fy = dv[1] + 0.5 * ry + (th[2] * rx - th[0] * rz) / 6.0 + (
        th_p[2] * dv[0] - th_p[0] * dv[2] + dv_p[2] * th[0] - dv_p[0] * th[2]) / 12.0
    fz = dv[2] + 0.5 * rz + (th[0] * ry - th[1] * rx) / 6.0 + (
        th_p[0] * dv[1] - th_p[1] * dv[0] + dv_p[0] * th[1] - dv_p[1] * th[0]) / 12.0

    # C_nb at the start of the interval
    quat_to_dcm_rows(s[6], s[7], s[8], s[9], c)

    # --- (1) velocity. Pass 1: rates at t[k-1] to extrapolate v and position to mid.
    rates(lat, h, vn, ve, r)
    zn = (r[0] + r[2]) * dt
    ze = r[3] * dt
    zd = (r[1] + r[4]) * dt
    specific_force_n(c, zn, ze, zd, fx, fy, fz, a)
    gravity_coriolis(r, vn, ve, vd, dt, g)
    mvn = vn + 0.5 * (a[0] + g[0])
    mve = ve + 0.5 * (a[1] + g[1])
    mvd = vd + 0.5 * (a[2] + g[2])
    radii(lat, &rm, &rn)
    mh = h - 0.5 * mvd * dt
    mlat = lat + 0.5 * mvn * dt / (rm + mh)
    # Pass 2: rates at mid-interval.
    rates(mlat, mh, mvn, mve, r)
    zn = (r[0] + r[2]) * dt
    ze = r[3] * dt
    zd = (r[1] + r[4]) * dt
    specific_force_n(c, zn, ze, zd, fx, fy, fz, a)
    gravity_coriolis(r, mvn, mve, mvd, dt, g)
    vn1 = vn + a[0] + g[0]
    ve1 = ve + a[1] + g[1]
    vd1 = vd + a[2] + g[2]

    # --- (2) position: mean velocity, radii at mid-interval
    bvn = 0.5 * (vn + vn1)
    bve = 0.5 * (ve + ve1)
    bvd = 0.5 * (vd + vd1)
    mh = h - 0.5 * bvd * dt
    mlat = lat + 0.5 * bvn * dt / (rm + mh)
    radii(mlat, &rm, &rn)
    s[0] = lat + bvn * dt / (rm + mh)
    s[1] = lon + bve * dt / ((rn + mh) * cos(mlat))
    s[2] = h - bvd * dt
    s[3] = vn1
    s[4] = ve1
    s[5] = vd1

    # --- (3) attitude: q_nb(k) = q(-zeta) * q_nb(k-1) * q(phi), zeta of pass 2
    rotvec_to_quat(-zn, -ze, -zd, n)
    px = th[0] + (th_p[1] * th[2] - th_p[2] * th[1]) / 12.0
    py = th[1] + (th_p[2] * th[0] - th_p[0] * th[2]) / 12.0
    pz = th[2] + (th_p[0] * th[1] - th_p[1] * th[0]) / 12.0
    rotvec_to_quat(px, py, pz, b)
    quat_mul(s[6], s[7], s[8], s[9], b[0], b[1], b[2], b[3], q)
    quat_mul(n[0], n[1], n[2], n[3], q[0], q[1], q[2], q[3], b)
    normalize_into(b[0], b[1], b[2], b[3], &s[6])
