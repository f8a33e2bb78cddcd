"""Compiled kernels of the Moon-centre extraction (Cython): block maxima of a frame; the
limb model's phased disks (four basis laws) with their derivatives, blur and binning.

Private to `moon_centre` and `_limb_model`.  All kernels release the GIL while they loop,
so that images can be processed in a thread pool.
"""
import numpy as np

from libc.math cimport sqrt

EPS = 1e-9

#: Basis laws of the limb model, in the order of the rows of ``disk_jac``'s output:
#: flat (1 on the lit part), Lambert (``mu0``), Lommel-Seeliger (``mu0 / (mu0 + mu)``),
#: Hapke's multiple scattering (``mu0 / (mu0 + mu) (H(mu0) H(mu) - 1)``, isotropic, with
#: Hapke's approximation ``H(x) = (1 + 2 x) / (1 + 2 gamma x)``, ``gamma = sqrt(1 - w)``,
#: single-scattering albedo ``w = HAPKE_W``).
LAWS = ("flat", "lambert", "lommel-seeliger", "hapke-multiple")

#: Single-scattering albedo of the Hapke multiple-scattering basis term (lunar: 0.2-0.3).
HAPKE_W = 0.25
_GAMMA = np.sqrt(1.0 - HAPKE_W)

cdef double C_EPS = EPS
cdef double C_GAMMA = _GAMMA

#: Pixel types of the frames :func:`block_max` reads in their own type.
ctypedef fused pixel_t:
    unsigned char
    signed char
    unsigned short
    short
    unsigned int
    int
    long long
    unsigned long long
    float
    double


cdef inline double _fmin2(double a, double b) noexcept nogil:
    """min(a, b) as Python evaluates it: b if b < a else a."""
    return b if b < a else a


cdef inline double _fmax2(double a, double b) noexcept nogil:
    """max(a, b) as Python evaluates it: b if b > a else a."""
    return b if b > a else a


def disk_jac(const double[:, :] P, bint flat, double c1, double c2, double R,
             const double[:] e1, const double[:] e2, const double[:, :] de1,
             const double[:, :] de2, const double[:] sun3, const double[:, :] dsun3,
             double sin_r, double cos_r, double f, double scale, double n,
             double[:, :] D, double[:, :, :] dD):
    """Anti-aliased phased disks of the four basis laws (`LAWS`) at sub-pixels, ``D``
    (4, N), and ``dD`` (4, 3, N), their derivatives with respect to ``(c1, c2, R)``
    (analytic chain rule).

    The limb is anti-aliased by a linear coverage ramp one sub-pixel wide; the flat law's
    terminator (a step in ``mu0``) by a ramp one sub-pixel wide across it.

    Flat images: ``P[:, :2]`` are the sub-pixels' ``(u, v)``; ``X = (u - c1) / R``.
    Camera: ``P`` are their unit directions, ``X = P.e1 / sin r``, ``Y = P.e2 / sin r``
    with ``r = R / f``; ``de1, de2, dsun3`` (2, 3) are the derivatives of the frame and of
    the Sun vector with respect to ``c1, c2``.
    """
    cdef Py_ssize_t N = P.shape[0], i
    cdef int j, k
    cdef double s0, s1, s2, sa, X, Y, px, py, pz, rho, cover, sc, Xc, Yc, mu, mu0
    cdef double Xs = 0.0, Ys = 0.0, w = 1.0, F, gF = 1.0, tstep, t, lam, ls
    cdef double q0, q1, h0, h1, g0, g1, ms, drho, dcover, dXc, dYc, dmu, dmu0, dt
    cdef double ds0, ds1, ds2, dsa, dXs, dYs, dl, dI, dms, den
    cdef double dX[3]
    cdef double dY[3]
    cdef bint full, clip, tfull
    if (P.shape[1] < (2 if flat else 3) or e1.shape[0] < 3 or e2.shape[0] < 3
            or de1.shape[0] < 2 or de1.shape[1] < 3 or de2.shape[0] < 2 or de2.shape[1] < 3
            or sun3.shape[0] < 3 or dsun3.shape[0] < 2 or dsun3.shape[1] < 3
            or D.shape[0] < 4 or D.shape[1] < N or dD.shape[0] < 4 or dD.shape[1] < 3
            or dD.shape[2] < N):
        raise ValueError("disk_jac: inconsistent array shapes")
    s0, s1, s2 = sun3[0], sun3[1], sun3[2]
    sa = sqrt(s0 * s0 + s1 * s1)
    with nogil:
        for i in range(N):
            if flat:
                X = (P[i, 0] - c1) / R
                Y = (P[i, 1] - c2) / R
                dX[0], dX[1], dX[2] = -1.0 / R, 0.0, -X / R
                dY[0], dY[1], dY[2] = 0.0, -1.0 / R, -Y / R
            else:
                px, py, pz = P[i, 0], P[i, 1], P[i, 2]
                X = (px * e1[0] + py * e1[1] + pz * e1[2]) / sin_r
                Y = (px * e2[0] + py * e2[1] + pz * e2[2]) / sin_r
                for k in range(2):
                    dX[k] = (px * de1[k, 0] + py * de1[k, 1] + pz * de1[k, 2]) / sin_r
                    dY[k] = (px * de2[k, 0] + py * de2[k, 1] + pz * de2[k, 2]) / sin_r
                dX[2] = -X * cos_r / (f * sin_r)
                dY[2] = -Y * cos_r / (f * sin_r)
            rho = sqrt(X * X + Y * Y)
            cover = 0.5 + (1.0 - rho) * R * scale * n
            if cover <= 0.0:
                for j in range(4):
                    D[j, i] = 0.0
                    for k in range(3):
                        dD[j, k, i] = 0.0
                continue
            full = cover >= 1.0
            if full:
                cover = 1.0
            clip = rho >= 1.0 - C_EPS
            sc = (1.0 - C_EPS) / rho if clip else 1.0
            Xc, Yc = X * sc, Y * sc
            mu = sqrt(_fmax2(1.0 - Xc * Xc - Yc * Yc, 0.0))
            mu0 = Xc * s0 + Yc * s1 + mu * s2
            # the flat law's terminator: the half-ellipse F = Xs + cos(a) sqrt(1 - Ys^2) = 0
            # in the basis (Xs, Ys) along / across the Sun's direction on the sky; a ramp in
            # F one sub-pixel wide (F is smooth but at the horns; its gradient capped there)
            if sa > 1e-9:
                Xs = (Xc * s0 + Yc * s1) / sa
                Ys = (-Xc * s1 + Yc * s0) / sa
                w = sqrt(_fmax2(1.0 - Ys * Ys, 1e-12))
                F = Xs + s2 * w
                t = s2 * Ys / w
                gF = _fmin2(sqrt(1.0 + t * t), 10.0) / (R * scale * n)
                tstep = 0.5 + F / gF
                tfull = tstep >= 1.0 or tstep <= 0.0
                tstep = _fmin2(_fmax2(tstep, 0.0), 1.0)
            else:
                tstep, tfull = 1.0, True
            lam = mu0 if mu0 > 0.0 else 0.0
            ls = mu0 / (mu0 + mu) if mu0 > 0.0 else 0.0
            # Hapke's multiple-scattering factor H(mu0) H(mu) - 1 (>= 0) and its slopes
            q0, q1 = 1.0 + 2.0 * C_GAMMA * lam, 1.0 + 2.0 * C_GAMMA * mu
            h0, h1 = (1.0 + 2.0 * lam) / q0, (1.0 + 2.0 * mu) / q1
            g0, g1 = 2.0 * (1.0 - C_GAMMA) / (q0 * q0), 2.0 * (1.0 - C_GAMMA) / (q1 * q1)
            ms = h0 * h1 - 1.0
            D[0, i] = tstep * cover
            D[1, i] = lam * cover
            D[2, i] = ls * cover
            D[3, i] = ls * ms * cover
            for k in range(3):
                drho = (X * dX[k] + Y * dY[k]) / rho if rho > 1e-12 else 0.0
                dcover = 0.0
                if not full:
                    dcover = -drho * R * scale * n
                    if k == 2:
                        dcover += (1.0 - rho) * scale * n
                if clip:
                    dXc = sc * (dX[k] - X * drho / rho)
                    dYc = sc * (dY[k] - Y * drho / rho)
                    dmu = 0.0
                else:
                    dXc, dYc = dX[k], dY[k]
                    dmu = -(Xc * dXc + Yc * dYc) / mu if mu > 0.0 else 0.0
                dmu0 = dXc * s0 + dYc * s1 + dmu * s2
                if k < 2:
                    dmu0 += Xc * dsun3[k, 0] + Yc * dsun3[k, 1] + mu * dsun3[k, 2]
                dt = 0.0
                if not tfull:
                    ds0 = dsun3[k, 0] if k < 2 else 0.0
                    ds1 = dsun3[k, 1] if k < 2 else 0.0
                    ds2 = dsun3[k, 2] if k < 2 else 0.0
                    dsa = (s0 * ds0 + s1 * ds1) / sa
                    dXs = (dXc * s0 + dYc * s1 + Xc * ds0 + Yc * ds1 - Xs * dsa) / sa
                    dYs = (-dXc * s1 + dYc * s0 - Xc * ds1 + Yc * ds0 - Ys * dsa) / sa
                    dt = (dXs + ds2 * w - s2 * Ys * dYs / w) / gF
                dD[0, k, i] = dt * cover + tstep * dcover
                dl = dmu0 if mu0 > 0.0 else 0.0
                dD[1, k, i] = dl * cover + lam * dcover
                if mu0 > 0.0:
                    den = mu0 + mu
                    dI = (mu * dmu0 - mu0 * dmu) / (den * den)
                else:
                    dI = 0.0
                dD[2, k, i] = dI * cover + ls * dcover
                dms = g0 * dl * h1 + h0 * g1 * dmu
                dD[3, k, i] = (dI * ms + ls * dms) * cover + ls * ms * dcover


def row_pass(const double[:, :, :] S, const double[:] kern, Py_ssize_t n, Py_ssize_t off,
             Py_ssize_t cols_out):
    """``T[a, y, X] = sum_i kern[i] S[a, y, n X + i - off]`` (zeros outside)."""
    cdef Py_ssize_t A = S.shape[0], H = S.shape[1], W = S.shape[2], a, y, X, i, x, base
    cdef Py_ssize_t m = kern.shape[0]
    cdef double acc
    T_arr = np.zeros((A, H, cols_out))
    cdef double[:, :, ::1] T = T_arr
    with nogil:
        for a in range(A):
            for y in range(H):
                for X in range(cols_out):
                    acc = 0.0
                    base = n * X - off
                    for i in range(m):
                        x = base + i
                        if 0 <= x < W:
                            acc += kern[i] * S[a, y, x]
                    T[a, y, X] = acc
    return T_arr


def col_pass(const double[:, :, :] T, const double[:] kern, Py_ssize_t n, Py_ssize_t off,
             Py_ssize_t rows_out):
    """``O[a, Y, x] = sum_i kern[i] T[a, n Y + i - off, x]`` (zeros outside)."""
    cdef Py_ssize_t A = T.shape[0], H = T.shape[1], W = T.shape[2], a, Y, i, y, x, base
    cdef Py_ssize_t m = kern.shape[0]
    cdef double w
    O_arr = np.zeros((A, rows_out, W))
    cdef double[:, :, ::1] O = O_arr
    with nogil:
        for a in range(A):
            for Y in range(rows_out):
                base = n * Y - off
                for i in range(m):
                    y = base + i
                    if 0 <= y < H:
                        w = kern[i]
                        for x in range(W):
                            O[a, Y, x] += w * T[a, y, x]
    return O_arr


def block_max(const pixel_t[:, :] img, Py_ssize_t b):
    """Maxima of the ``b x b`` blocks of a 2-D image (any numeric type), as float."""
    cdef Py_ssize_t rows = img.shape[0] // b, cols = img.shape[1] // b, R, C, i, j
    cdef double m
    out_arr = np.empty((rows, cols))
    cdef double[:, ::1] out = out_arr
    with nogil:
        for R in range(rows):
            for C in range(cols):
                out[R, C] = img[R * b, C * b]
            for i in range(R * b, R * b + b):
                for C in range(cols):
                    m = out[R, C]
                    for j in range(C * b, C * b + b):
                        if img[i, j] > m:
                            m = img[i, j]
                    out[R, C] = m
    return out_arr


def cross3(const double[:] a, const double[:] b):
    """Cross product of two 3-vectors."""
    if a.shape[0] != 3 or b.shape[0] != 3:
        raise ValueError("cross3: two 3-vectors")
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])
