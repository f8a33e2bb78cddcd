"""Compiled kernels of the coplanarity adjustment (private; Cython): the Gauss-Newton of
:func:`photogrammetry.adjustment._coplanarity_kernels.solve_pairs` one pair at a time (no
temporaries), the joint weight blocks of the block conditions and the block's condition
terms.

The condition terms are the inline C of ``_coplanarity.pxd``; the small eigenproblems,
solves and inverses go to scipy's LAPACK there, as numba's ``np.linalg`` did in the
kernels these replaced (equal bit for bit).
"""
import numpy as np

from libc.math cimport fabs, isnan, sqrt

from photogrammetry.adjustment cimport _coplanarity as cp

_LINALG_MESSAGES = {cp.LINALG_NOT_FINITE: "Array must not contain infs or NaNs.",
                    cp.LINALG_SINGULAR: "Matrix is singular to machine precision.",
                    cp.LINALG_NO_CONVERGENCE: "Eigenvalues did not converge."}


cdef int _check(int code) except -1:
    """Raise numpy.linalg.LinAlgError (MemoryError) for a failed helper of _coplanarity."""
    if code == cp.LINALG_OK:
        return 0
    if code == cp.LINALG_NO_MEMORY:
        raise MemoryError()
    raise np.linalg.LinAlgError(_LINALG_MESSAGES[code])


cdef int _profile(Py_ssize_t n, const double *r1, const double[:, :] u2,
                  const unsigned char[:] mask, const double *R1, const double *R2,
                  const double *M2, double *b, double s2, bint use_weights,
                  const double *E) except -1:
    """Base direction minimizing sum w (b . N)^2 (weights from the current b), into b."""
    cdef double S[9]
    cdef double ev[3]
    cdef double V[9]
    cdef double Ji[5]
    cdef double N[3]
    cdef double u[3]
    cdef double g, var, w
    cdef Py_ssize_t i
    cdef int a, c
    for a in range(9):
        S[a] = 0.0
    for i in range(n):
        if not mask[i]:
            continue
        u[0], u[1], u[2] = u2[i, 0], u2[i, 1], u2[i, 2]
        g = cp.terms(&r1[3 * i], u, R1, R2, M2, b, E, s2, 3, Ji, N, &var)
        w = 1.0
        if use_weights:
            w = 1.0 / var if var > 0 else 0.0
        for a in range(3):
            for c in range(3):
                S[3 * a + c] += w * N[a] * N[c]
    _check(cp.eigh(3, S, ev, V))
    for a in range(3):
        b[a] = V[3 * a]
    return 0


def solve_pairs_kernel(const double[:, :, :] u1, const double[:, :, :] u2, mask_in,
                       const double[:, :, :] R1, double[:, :] angles, double[:, :] base,
                       int mode, order, const double[:] sign, double s2,
                       int max_iter, double tol, long long[:] status,
                       long long[:] iterations, double[:, :, :] Q, double[:] vtpv,
                       double[:, :] g_out, double[:, :] var_out, double[:, :, :] J_out,
                       double[:, :] w_out, long long[:] bad_point):
    """In-place per-pair Gauss-Newton (see ``_coplanarity_kernels.solve_pairs``); angles
    and base updated.  ``mode``: 0 known base, 1 relative, 2 free; ``mask_in`` (P, n)
    bool.

    A condition whose variance is not > 0 stops its pair with status 5
    (``STATUS_ZERO_VARIANCE``) and its point index in ``bad_point`` (the caller refuses
    it)."""
    cdef const unsigned char[:, :] mask = np.asarray(mask_in, dtype=np.bool_).view(np.uint8)
    cdef Py_ssize_t P = mask.shape[0], n = mask.shape[1], p, i
    cdef int k = 3 if mode == 0 else 5
    cdef int it, a, c, order_c[3]
    cdef double R1c[9]
    cdef double R2[9]
    cdef double M2[9]
    cdef double E[6]
    cdef double Ji[5]
    cdef double N[3]
    cdef double u[3]
    cdef double b[3]
    cdef double ang[3]
    cdef double H[25]
    cdef double Hs[25]
    cdef double grad[5]
    cdef double d[5]
    cdef double x[5]
    cdef double step[5]
    cdef double ev[5]
    cdef double Hinv[25]
    cdef double db[3]
    cdef double g, var, w, wa, v, nrm, dmin, smax
    cdef bint done, finite
    if (u1.shape[0] < P or u1.shape[1] < n or u1.shape[2] < 3 or u2.shape[0] < P
            or u2.shape[1] < n or u2.shape[2] < 3 or R1.shape[0] < P or angles.shape[0] < P
            or angles.shape[1] < 3 or base.shape[0] < P or base.shape[1] < 3
            or len(order) < 3 or sign.shape[0] < 3 or status.shape[0] < P
            or iterations.shape[0] < P or Q.shape[0] < P or Q.shape[1] < k
            or Q.shape[2] < k or vtpv.shape[0] < P or g_out.shape[0] < P
            or g_out.shape[1] < n or var_out.shape[0] < P or var_out.shape[1] < n
            or J_out.shape[0] < P or J_out.shape[1] < n or J_out.shape[2] < k
            or w_out.shape[0] < P or w_out.shape[1] < n or bad_point.shape[0] < P):
        raise ValueError("solve_pairs_kernel: inconsistent array shapes")
    for a in range(3):
        order_c[a] = int(order[a])
    for a in range(6):
        E[a] = 0.0
    r1_arr = np.empty((n, 3))
    cdef double[:, ::1] r1 = r1_arr
    for p in range(P):
        if status[p] != 1:
            continue
        for a in range(3):
            for c in range(3):
                R1c[3 * a + c] = R1[p, a, c]
        for i in range(n):
            for a in range(3):
                r1[i, a] = R1[p, a, 0] * u1[p, i, 0] + R1[p, a, 1] * u1[p, i, 1] \
                    + R1[p, a, 2] * u1[p, i, 2]
        b[0], b[1], b[2] = base[p, 0], base[p, 1], base[p, 2]
        nrm = sqrt(cp.dot(3, b, b))
        b[0], b[1], b[2] = b[0] / nrm, b[1] / nrm, b[2] / nrm
        ang[0], ang[1], ang[2] = angles[p, 0], angles[p, 1], angles[p, 2]
        if mode == 2:
            cp.rotation(ang, order_c, &sign[0], R2, M2)
            _profile(n, &r1[0, 0], u2[p], mask[p], R1c, R2, M2, b, s2, False, E)
        done = False
        for it in range(max_iter + 1):
            cp.rotation(ang, order_c, &sign[0], R2, M2)
            if mode == 2:
                _profile(n, &r1[0, 0], u2[p], mask[p], R1c, R2, M2, b, s2, True, E)
            if k == 5:
                cp.tangent(b, E)
            for a in range(k * k):
                H[a] = 0.0
            for a in range(k):
                grad[a] = 0.0
            v = 0.0
            for i in range(n):
                if not mask[p, i]:
                    g_out[p, i] = 0.0
                    w_out[p, i] = 0.0
                    continue
                u[0], u[1], u[2] = u2[p, i, 0], u2[p, i, 1], u2[p, i, 2]
                g = cp.terms(&r1[i, 0], u, R1c, R2, M2, b, E, s2, k, Ji, N, &var)
                if not var > 0:
                    status[p] = 5
                    bad_point[p] = i
                    var_out[p, i] = var
                    break
                w = 1.0 / var
                for a in range(k):
                    wa = w * Ji[a]
                    grad[a] += wa * g
                    for c in range(a, k):
                        H[k * a + c] += wa * Ji[c]
                v += w * g * g
                g_out[p, i], var_out[p, i], w_out[p, i] = g, var, w
                for a in range(k):
                    J_out[p, i, a] = Ji[a]
            if status[p] == 5:
                break
            for a in range(k):
                for c in range(a):
                    H[k * a + c] = H[k * c + a]
            vtpv[p] = v
            for a in range(k):
                d[a] = sqrt(fabs(H[k * a + a])) + 1e-300
            finite = True
            dmin = H[0]
            for a in range(k):
                for c in range(k):
                    Hs[k * a + c] = H[k * a + c] / (d[a] * d[c])
                finite = finite and cp.all_finite(k, &Hs[k * a])
                if H[k * a + a] < dmin:
                    dmin = H[k * a + a]
            if not finite or dmin <= 0.0:
                status[p] = 2
                break
            _check(cp.eigh(k, Hs, ev, NULL))
            if not (ev[0] > 1e-13 * ev[k - 1]):
                status[p] = 2
                break
            if done:
                status[p] = 0
                break
            if it == max_iter:
                break
            for a in range(k):
                x[a] = grad[a] / d[a]
            _check(cp.solve(k, Hs, x))
            for a in range(k):
                step[a] = -x[a] / d[a]
            for a in range(3):
                ang[a] += step[a]
            if k == 5 and mode == 1:
                cp.matvec_32(E, &step[3], db)
                b[0], b[1], b[2] = b[0] + db[0], b[1] + db[1], b[2] + db[2]
                nrm = sqrt(cp.dot(3, b, b))
                b[0], b[1], b[2] = b[0] / nrm, b[1] / nrm, b[2] / nrm
            iterations[p] += 1
            # np.max(np.abs(step)) < tol, a NaN propagating as in numpy
            smax = fabs(step[0])
            for a in range(1, k):
                if isnan(fabs(step[a])) or fabs(step[a]) > smax:
                    smax = fabs(step[a])
                if isnan(smax):
                    break
            done = smax < tol
        angles[p, 0], angles[p, 1], angles[p, 2] = ang[0], ang[1], ang[2]
        if status[p] <= 1:
            _check(cp.inverse(k, H, Hinv))
            for a in range(k):
                for c in range(k):
                    Q[p, a, c] = Hinv[k * a + c]
        base[p, 0], base[p, 1], base[p, 2] = b[0], b[1], b[2]


def joint_weight_blocks(const long long[:, :] idx, const long long[:, :] obs,
                        const double[:, :, :] d, double s2, double tol):
    """Per tie point, the pseudo-inverse of the joint covariance of its conditions (see
    :func:`photogrammetry.adjustment.block_conditions._joint_weights`), compiled.

    Parameters
    ----------
    idx : ndarray of int (T, c)
        Conditions of each of T tie points with c conditions.
    obs : ndarray of int (C, 2); d : ndarray (C, 2, 2); s2 : float; tol : float

    Returns
    -------
    vals : ndarray (T, c, c)
        The weight blocks.
    rank : int
        Eigenvalues kept (independent conditions).
    """
    cdef Py_ssize_t T = idx.shape[0], c = idx.shape[1], t, a, b, kk, ca, cb
    cdef int s, r
    cdef long long rank = 0
    cdef double acc, top, w
    vals_arr = np.zeros((T, c, c))
    S_arr = np.empty((c, c))
    inv_arr = np.empty(c)
    lam_arr = np.empty(c)
    U_arr = np.empty((c, c))
    cdef double[:, :, ::1] vals = vals_arr
    cdef double[:, ::1] S = S_arr, U = U_arr
    cdef double[::1] inv = inv_arr, lam = lam_arr
    for t in range(T):
        for a in range(c):
            if not 0 <= idx[t, a] < obs.shape[0]:
                raise IndexError(f"joint_weight_blocks: condition {idx[t, a]} out of range")
    if obs.shape[1] < 2 or d.shape[0] < obs.shape[0] or d.shape[1] < 2 or d.shape[2] < 2:
        raise ValueError("joint_weight_blocks: obs (C, 2) and d (C, 2, 2)")
    if c == 0:
        return vals_arr, 0
    for t in range(T):
        for a in range(c):
            ca = idx[t, a]
            for b in range(c):
                cb = idx[t, b]
                acc = 0.0
                for s in range(2):
                    for r in range(2):
                        if obs[ca, s] == obs[cb, r]:
                            acc += d[ca, s, 0] * d[cb, r, 0] + d[ca, s, 1] * d[cb, r, 1]
                S[a, b] = s2 * acc
        for a in range(c):
            inv[a] = 1.0 / sqrt(S[a, a]) if S[a, a] > 0 else 0.0
        for a in range(c):
            for b in range(c):
                S[a, b] *= inv[a] * inv[b]
        _check(cp.eigh(<int>c, &S[0, 0], &lam[0], &U[0, 0]))
        top = lam[c - 1]
        for kk in range(c):
            if lam[kk] > tol * top:
                rank += 1
                w = 1.0 / lam[kk]
                for a in range(c):
                    for b in range(c):
                        vals[t, a, b] += U[a, kk] * w * U[b, kk]
        for a in range(c):
            for b in range(c):
                vals[t, a, b] *= inv[a] * inv[b]
    return vals_arr, rank


cdef inline double _sum3(double x0, double x1, double x2) noexcept nogil:
    """``x0 + x1 + x2`` as numpy's einsum adds three terms: ``(x0 + x2) + x1``."""
    return (x0 + x2) + x1


cdef inline void _cross(const double *a, const double *b, double *out) noexcept nogil:
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


def block_condition_terms(const double[:, :, ::1] U, const long long[:, ::1] img,
                          const long long[::1] bp, const double[:, :, ::1] R,
                          const double[:, :, ::1] M, const double[:, ::1] b):
    """Per condition ``det[b, R_i u_i, R_j u_j]`` of a block and its derivatives, in one
    pass (:func:`photogrammetry.adjustment.block_conditions._condition_terms`; numpy's
    dozen passes through (C, 3) temporaries were a tenth of an iteration).  The sums in
    the order of those numpy expressions: ``R u`` and ``N . b`` as einsum adds three
    terms (:func:`_sum3`), the others left to right; the crosses as ``np.cross``.

    Parameters
    ----------
    U : ndarray (C, 2, 3)
        Rays in the two images, mm.
    img : ndarray of int (C, 2); bp : ndarray of int (C,)
        The images and the pair (row of `b`) of every condition.
    R, M : ndarray (m, 3, 3)
        Rotation and model-frame axes of the angles of every image.
    b : ndarray (P, 3)
        Base of every pair.

    Returns
    -------
    g : ndarray (C,)
        ``b . (r_i x r_j)``, ``r = R u``.
    d : ndarray (C, 2, 2)
        By the photo coordinates (x, y) in image i (``R_i' (r_j x b)``) and in image j
        (``R_j' (b x r_i)``).
    J : ndarray (C, 6)
        By the angles of image i and of image j: ``(r_i x (r_j x b)) M_i`` and
        ``(r_j x (b x r_i)) M_j``.
    N : ndarray (C, 3)
        ``r_i x r_j = dg/db``.
    """
    cdef Py_ssize_t C = U.shape[0], c, a, k, i, j, p
    cdef double ri[3], rj[3], bb[3], t[3], Ai[3], Aj[3], n3[3]
    if img.shape[0] != C or bp.shape[0] != C or U.shape[1] < 2 or U.shape[2] < 3:
        raise ValueError("block_condition_terms: U (C, 2, 3), img (C, 2), bp (C,)")
    for c in range(C):
        if not (0 <= img[c, 0] < R.shape[0] and 0 <= img[c, 1] < R.shape[0]
                and 0 <= bp[c] < b.shape[0]):
            raise IndexError(f"block_condition_terms: condition {c} out of range")
    g_arr = np.empty(C)
    d_arr = np.empty((C, 2, 2))
    J_arr = np.empty((C, 6))
    N_arr = np.empty((C, 3))
    cdef double[::1] g = g_arr
    cdef double[:, :, ::1] d = d_arr
    cdef double[:, ::1] J = J_arr, N = N_arr
    with nogil:
        for c in range(C):
            i, j, p = img[c, 0], img[c, 1], bp[c]
            for a in range(3):
                ri[a] = _sum3(R[i, a, 0] * U[c, 0, 0], R[i, a, 1] * U[c, 0, 1],
                              R[i, a, 2] * U[c, 0, 2])
                rj[a] = _sum3(R[j, a, 0] * U[c, 1, 0], R[j, a, 1] * U[c, 1, 1],
                              R[j, a, 2] * U[c, 1, 2])
                bb[a] = b[p, a]
            _cross(ri, rj, n3)
            g[c] = _sum3(n3[0] * bb[0], n3[1] * bb[1], n3[2] * bb[2])
            for a in range(3):
                N[c, a] = n3[a]
            _cross(rj, bb, t)                          # r_j x b
            for k in range(2):
                d[c, 0, k] = R[i, 0, k] * t[0] + R[i, 1, k] * t[1] + R[i, 2, k] * t[2]
            _cross(ri, t, Ai)
            _cross(bb, ri, t)                          # b x r_i
            for k in range(2):
                d[c, 1, k] = R[j, 0, k] * t[0] + R[j, 1, k] * t[1] + R[j, 2, k] * t[2]
            _cross(rj, t, Aj)
            for k in range(3):
                J[c, k] = Ai[0] * M[i, 0, k] + Ai[1] * M[i, 1, k] + Ai[2] * M[i, 2, k]
                J[c, 3 + k] = Aj[0] * M[j, 0, k] + Aj[1] * M[j, 1, k] + Aj[2] * M[j, 2, k]
    return g_arr, d_arr, J_arr, N_arr
