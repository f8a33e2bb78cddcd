"""Compiled robust start of the coplanarity adjustment: minimal samples + MSAC (Cython).

Per pair, hypotheses are drawn from minimal samples of the tie points (3 points when the
base is known, 5 otherwise: three angles of image 2 and two base-direction parameters)
and solved exactly by Newton's method on the coplanarity conditions
``g = b . (R1 u1 x R2 u2) = 0`` of the sample, started from the prior.  Every hypothesis
is scored by MSAC: ``sum min(g^2 / var, t^2)`` over all points of the pair, with
``var`` the condition's variance propagated from the photo coordinates.  The number of
hypotheses adapts to the best inlier ratio (confidence `conf`).

Independence of the prior: a sample of inliers has one solution near the truth, and
Newton converges to it from any start in its basin (a prior within a few tenths of a
degree), so the set of hypotheses, the winner and its inliers do not depend on the
prior; the random samples come from a generator re-seeded with the same seed for every
pair (no dependence on the order or batching of the pairs either).

The generator is a Mersenne Twister seeded and drawn as numba's ``np.random.seed`` /
``np.random.randint`` (the kernels this module replaced): the same samples, hypotheses
and results, bit for bit.  The condition terms are the inline C of ``_coplanarity.pxd``.
"""
import numpy as np

from libc.math cimport INFINITY, fabs, isfinite, log, sqrt

from photogrammetry.adjustment cimport _coplanarity as cp

#: Status of :func:`msac_pairs`: a hypothesis was found / none (every sample singular
#: or diverging: the prior is kept) / too few points (fewer than twice the sample: the
#: robust start is skipped, a wrong exact root of 5 of 7 points would win).
MSAC_OK, MSAC_NONE, MSAC_TOO_FEW = 0, 1, 2

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


# ---------------------------------------------------------------------------------------
# the generator: MT19937, seeded by an integer (Knuth's initialization of the reference
# implementation); randint(n) takes the low bits of 32-bit draws (numpy's rule) and
# rejects values >= n

cdef enum:
    MT_N = 624
    MT_M = 397

cdef struct Twister:
    int index
    unsigned int mt[MT_N]


cdef void _mt_seed(Twister *st, unsigned int seed) noexcept nogil:
    cdef unsigned int pos
    for pos in range(MT_N):
        st.mt[pos] = seed
        seed = 1812433253U * (seed ^ (seed >> 30)) + pos + 1
    st.index = MT_N


cdef void _mt_shuffle(Twister *st) noexcept nogil:
    cdef int i
    cdef unsigned int y
    for i in range(MT_N - MT_M):
        y = (st.mt[i] & 0x80000000U) | (st.mt[i + 1] & 0x7fffffffU)
        st.mt[i] = st.mt[i + MT_M] ^ (y >> 1) ^ (0x9908b0dfU if y & 1 else 0U)
    for i in range(MT_N - MT_M, MT_N - 1):
        y = (st.mt[i] & 0x80000000U) | (st.mt[i + 1] & 0x7fffffffU)
        st.mt[i] = st.mt[i + MT_M - MT_N] ^ (y >> 1) ^ (0x9908b0dfU if y & 1 else 0U)
    y = (st.mt[MT_N - 1] & 0x80000000U) | (st.mt[0] & 0x7fffffffU)
    st.mt[MT_N - 1] = st.mt[MT_M - 1] ^ (y >> 1) ^ (0x9908b0dfU if y & 1 else 0U)


cdef unsigned int _mt_next(Twister *st) noexcept nogil:
    cdef unsigned int y
    if st.index >= MT_N:
        _mt_shuffle(st)
        st.index = 0
    y = st.mt[st.index]
    st.index += 1
    y ^= y >> 11
    y ^= (y << 7) & 0x9d2c5680U
    y ^= (y << 15) & 0xefc60000U
    y ^= y >> 18
    return y


cdef long long _randint(Twister *st, long long n) noexcept nogil:
    """A uniform integer in [0, n), n >= 1."""
    cdef unsigned long long v = n - 1, r, high
    cdef int nbits = 0
    if n <= 1:
        return 0
    while v:
        nbits += 1
        v >>= 1
    while True:
        if nbits <= 32:
            r = _mt_next(st) & (0xffffffffU >> (32 - nbits))
        else:
            high = _mt_next(st) & (0xffffffffU >> (64 - nbits))
            r = _mt_next(st) + (high << 32)
        if <long long>r < n:
            return <long long>r


# ---------------------------------------------------------------------------------------

cdef int _gauss_solve(double *A, double *rhs, int k) noexcept nogil:
    """Solve the k x k system in place (partial pivoting); 0 when a pivot is below
    1e-12 of the largest element (a degenerate sample).  The solution is in ``rhs``."""
    cdef double amax = 0.0, f, v, tmp
    cdef int i, j, c, piv
    for i in range(k):
        for j in range(k):
            amax = cp.fmax2(amax, fabs(A[k * i + j]))
    if not amax > 0 or not isfinite(amax):
        return 0
    for c in range(k):
        piv = c
        for i in range(c + 1, k):
            if fabs(A[k * i + c]) > fabs(A[k * piv + c]):
                piv = i
        if not fabs(A[k * piv + c]) > 1e-12 * amax:
            return 0
        if piv != c:
            for j in range(k):
                tmp = A[k * c + j]
                A[k * c + j] = A[k * piv + j]
                A[k * piv + j] = tmp
            tmp = rhs[c]
            rhs[c] = rhs[piv]
            rhs[piv] = tmp
        for i in range(c + 1, k):
            f = A[k * i + c] / A[k * c + c]
            for j in range(c, k):
                A[k * i + j] -= f * A[k * c + j]
            rhs[i] -= f * rhs[c]
    for c in range(k - 1, -1, -1):
        v = rhs[c]
        for j in range(c + 1, k):
            v -= A[k * c + j] * rhs[j]
        rhs[c] = v / A[k * c + c]
    return 1


cdef struct Pair:
    # one pair's data and scratch
    int k                     # unknowns of a sample: 3 (known base) or 5
    const double *r1          # (n, 3) image 1's rays in the model frame
    const double *u2          # (n, 3) image 2's camera rays
    double R1[9]
    double R2[9]
    double M2[9]
    double E[6]
    double Ji[5]
    double N[3]
    double A[25]
    double rhs[5]


cdef int _sample_base(Pair *w, const long long *idx, double *b) except -1:
    """Base direction of a sample at the current rotation: the null vector of its
    epipolar-plane normals (3x3 eigenproblem), into b."""
    cdef double S[9]
    cdef double ev[3]
    cdef double V[9]
    cdef double var
    cdef int s, a, c
    for a in range(9):
        S[a] = 0.0
    for s in range(w.k):
        cp.terms(&w.r1[3 * idx[s]], &w.u2[3 * idx[s]], w.R1, w.R2, w.M2, b, w.E, 0.0, 3,
                 w.Ji, w.N, &var)
        for a in range(3):
            for c in range(3):
                S[3 * a + c] += w.N[a] * w.N[c]
    _check(cp.eigh(3, S, ev, V))
    for a in range(3):
        b[a] = V[3 * a]
    return 0


cdef int _newton_sample(Pair *w, const long long *idx, const double *prior, const double *b0,
                        const int *order, const double *sign, double s2, double max_change,
                        double *ang, double *b) except -1:
    """Exact solution of the k conditions of a sample by Newton from the prior.

    Fills ``ang`` (3,) and ``b`` (3,); returns 1 when converged (step below 1e-10
    rad) within `max_change` rad of the prior, else 0."""
    cdef int k = w.k, it, s, c, a
    cdef double g, var, step, nrm
    for a in range(3):
        ang[a] = prior[a]
        b[a] = b0[a]
    if k == 5:
        cp.rotation(ang, order, sign, w.R2, w.M2)
        _sample_base(w, idx, b)
    for it in range(10):
        cp.rotation(ang, order, sign, w.R2, w.M2)
        if k == 5:
            cp.tangent(b, w.E)
        for s in range(k):
            g = cp.terms(&w.r1[3 * idx[s]], &w.u2[3 * idx[s]], w.R1, w.R2, w.M2, b, w.E, s2,
                         k, w.Ji, w.N, &var)
            for c in range(k):
                w.A[k * s + c] = w.Ji[c]
            w.rhs[s] = -g
        if not _gauss_solve(w.A, w.rhs, k):
            return 0
        step = 0.0
        for c in range(3):
            ang[c] += w.rhs[c]
            step = cp.fmax2(step, fabs(w.rhs[c]))
            if not fabs(ang[c] - prior[c]) < max_change:
                return 0
        if k == 5:
            for a in range(3):
                b[a] += w.E[2 * a] * w.rhs[3] + w.E[2 * a + 1] * w.rhs[4]
            nrm = sqrt(cp.dot(3, b, b))
            for a in range(3):
                b[a] = b[a] / nrm
            step = cp.fmax2(cp.fmax2(step, fabs(w.rhs[3])), fabs(w.rhs[4]))
        if step < 1e-10:
            return 1
    return 0


cdef double _score(Pair *w, const long long *used, Py_ssize_t m, const double *ang,
                   const double *b, const int *order, const double *sign, double s2,
                   double t2, double best, long long *inl_out) noexcept nogil:
    """MSAC cost ``sum min(g^2/var, t2)`` and the inlier count of a hypothesis (the sum
    stops once above `best`: such a hypothesis cannot win)."""
    cdef double cost = 0.0, g, var, e
    cdef long long inl = 0
    cdef Py_ssize_t j, i
    cp.rotation(ang, order, sign, w.R2, w.M2)
    for j in range(m):
        i = used[j]
        g = cp.terms(&w.r1[3 * i], &w.u2[3 * i], w.R1, w.R2, w.M2, b, w.E, s2, 3, w.Ji,
                     w.N, &var)
        e = g * g / var if var > 0 else INFINITY
        if e < t2:
            cost += e
            inl += 1
        else:
            cost += t2
        if cost >= best:
            inl_out[0] = inl
            return INFINITY
    inl_out[0] = inl
    return cost


cdef double _ipow(double a, long long e) noexcept nogil:
    """a ** e for an integer e >= 0 by binary powering (numba's float ** int)."""
    cdef double r = 1.0
    while e != 0:
        if e & 1:
            r *= a
        e >>= 1
        a *= a
    return r


def studentized_misclosures(const double[:, :, :] u1, const double[:, :, :] u2, mask_in,
                            keep_in, const double[:, :, :] R1, const double[:, :] angles,
                            const double[:, :] base, const double[:, :, :] Q, order,
                            const double[:] sign, double s2, double[:, :] out):
    """Studentized misclosures of every masked point at an adjusted solution, into
    ``out`` (P, n) (0 for the others).

    ``Q`` (P, k, k) is the cofactor matrix of the solution (k = 3 with a known base, 5
    with the base direction, tangent basis of ``_coplanarity_kernels.tangent_basis``).  A
    point that took part (``keep``) is divided by the sigma of its residual,
    ``sqrt(var - J Q J^T)`` (the w-test); one that did not by the sigma of its prediction
    error, ``sqrt(var + J Q J^T)``: both are N(0, 1) for a good point, so the decision
    does not depend on which set the solution came from (an influential point of a weak
    pair has a large misclosure at a solution without it, and a small one with it)."""
    cdef const unsigned char[:, :] mask = np.asarray(mask_in, dtype=np.bool_).view(np.uint8)
    cdef const unsigned char[:, :] keep = np.asarray(keep_in, dtype=np.bool_).view(np.uint8)
    cdef Py_ssize_t P = mask.shape[0], n = mask.shape[1], p, i
    cdef int k = Q.shape[1], a, c, order_c[3]
    cdef double R1c[9]
    cdef double R2[9]
    cdef double M2[9]
    cdef double E[6]
    cdef double Ji[5]
    cdef double N[3]
    cdef double r1[3]
    cdef double u[3]
    cdef double b[3]
    cdef double ang[3]
    cdef double Qp[25]
    cdef double JQ[5]
    cdef double g, var, h, v, nrm
    if (k not in (3, 5) or Q.shape[2] != k or Q.shape[0] < P or keep.shape[0] < P
            or keep.shape[1] < n or u1.shape[0] < P or u1.shape[1] < n or u1.shape[2] < 3
            or u2.shape[0] < P or u2.shape[1] < n or u2.shape[2] < 3 or R1.shape[0] < P
            or angles.shape[0] < P or base.shape[0] < P or out.shape[0] < P
            or out.shape[1] < n or len(order) < 3 or sign.shape[0] < 3):
        raise ValueError("studentized_misclosures: inconsistent array shapes")
    for a in range(3):
        order_c[a] = int(order[a])
    for a in range(6):
        E[a] = 0.0
    for p in range(P):
        for a in range(3):
            ang[a] = angles[p, a]
            b[a] = base[p, a]
            for c in range(3):
                R1c[3 * a + c] = R1[p, a, c]
        cp.rotation(ang, order_c, &sign[0], R2, M2)
        nrm = sqrt(cp.dot(3, b, b))
        for a in range(3):
            b[a] = b[a] / nrm
        if k == 5:
            cp.tangent(b, E)
        for a in range(k):
            for c in range(k):
                Qp[k * a + c] = Q[p, a, c]
        for i in range(n):
            out[p, i] = 0.0
            if not mask[p, i]:
                continue
            for a in range(3):
                r1[a] = R1[p, a, 0] * u1[p, i, 0] + R1[p, a, 1] * u1[p, i, 1] \
                    + R1[p, a, 2] * u1[p, i, 2]
                u[a] = u2[p, i, a]
            g = cp.terms(r1, u, R1c, R2, M2, b, E, s2, k, Ji, N, &var)
            cp.vecmat(k, Ji, Qp, JQ)
            h = cp.dot(k, JQ, Ji)
            v = var - h if keep[p, i] else var + h
            out[p, i] = g / sqrt(v) if v > 1e-3 * var else INFINITY


def msac_pairs(const double[:, :, :] u1, const double[:, :, :] u2, mask_in,
               const double[:, :, :] R1, const double[:, :] prior, const double[:, :] base,
               bint known, order, const double[:] sign, double s2, double t2, double conf,
               long long min_hyp, long long max_hyp, double max_change, long long seed,
               double[:, :] angles_out, double[:, :] base_out, inlier_in,
               long long[:] status_out, long long[:] hyp_out):
    """Robust start of every pair (see the module docstring).

    Parameters
    ----------
    u1, u2 : (P, n, 3) camera rays, mm; mask : (P, n) bool; R1 : (P, 3, 3) image 1's
    ``C_mc``; prior : (P, 3) image 2's prior angles, rad; base : (P, 3) the base (used
    only when `known`); t2 : squared MSAC threshold of the normalized misclosure;
    conf : confidence of the adaptive stop; min_hyp, max_hyp : bounds of the number of
    hypotheses; max_change : rad, a hypothesis farther from the prior is discarded.

    Outputs (filled): angles_out (P, 3), base_out (P, 3) unit, inlier_out (P, n) bool,
    status_out (P,) (:data:`MSAC_OK` ...), hyp_out (P,) hypotheses drawn.
    """
    cdef const unsigned char[:, :] mask = np.asarray(mask_in, dtype=np.bool_).view(np.uint8)
    if not (isinstance(inlier_in, np.ndarray) and inlier_in.dtype == np.bool_):
        raise TypeError("msac_pairs: inlier_out must be a bool array")
    cdef unsigned char[:, :] inlier_out = inlier_in.view(np.uint8)
    cdef Py_ssize_t P = mask.shape[0], n = mask.shape[1], p, i, m, s, j, h, tmp_i
    cdef int k = 3 if known else 5, a, c, order_c[3]
    cdef Pair w
    cdef Twister rng
    cdef double ang[3]
    cdef double b[3]
    cdef double b0[3]
    cdef double pr[3]
    cdef double best, cost, eps, nrm, g, var
    cdef long long best_inl, inl, need
    if (u1.shape[0] < P or u1.shape[1] < n or u1.shape[2] < 3 or u2.shape[0] < P
            or u2.shape[1] < n or u2.shape[2] < 3 or R1.shape[0] < P or prior.shape[0] < P
            or base.shape[0] < P or angles_out.shape[0] < P or base_out.shape[0] < P
            or inlier_out.shape[0] < P or inlier_out.shape[1] < n or status_out.shape[0] < P
            or hyp_out.shape[0] < P or len(order) < 3 or sign.shape[0] < 3):
        raise ValueError("msac_pairs: inconsistent array shapes")
    for a in range(3):
        order_c[a] = int(order[a])
    w.k = k
    for a in range(6):
        w.E[a] = 0.0
    r1_arr = np.empty((n, 3))
    u2_arr = np.empty((n, 3))
    used_arr = np.empty(n, np.int64)
    pool_arr = np.empty(n, np.int64)
    cdef double[:, ::1] r1 = r1_arr, u2p = u2_arr
    cdef long long[::1] used = used_arr, pool = pool_arr
    w.r1 = &r1[0, 0] if n > 0 else NULL
    w.u2 = &u2p[0, 0] if n > 0 else NULL
    for p in range(P):
        _mt_seed(&rng, <unsigned int>seed)
        m = 0
        for i in range(n):
            if mask[p, i]:
                used[m] = i
                m += 1
        for a in range(3):
            angles_out[p, a] = prior[p, a]
            pr[a] = prior[p, a]
            b[a] = base[p, a]
        nrm = cp.fmax2(sqrt(cp.dot(3, b, b)), 1e-300)
        for a in range(3):
            base_out[p, a] = b[a] / nrm
            b0[a] = base_out[p, a]
        for i in range(n):
            inlier_out[p, i] = mask[p, i]
        hyp_out[p] = 0
        if m < 2 * k:             # too few to out-vote anything: Gauss-Newton from the
            status_out[p] = MSAC_TOO_FEW      # prior on all points, then snooping
            continue
        for a in range(3):
            for c in range(3):
                w.R1[3 * a + c] = R1[p, a, c]
        for i in range(n):
            for a in range(3):
                r1[i, a] = R1[p, a, 0] * u1[p, i, 0] + R1[p, a, 1] * u1[p, i, 1] \
                    + R1[p, a, 2] * u1[p, i, 2]
                u2p[i, a] = u2[p, i, a]
        for i in range(m):
            pool[i] = used[i]
        best, best_inl, need = INFINITY, 0, max_hyp
        h = 0
        while h < need and h < max_hyp:
            h += 1
            for s in range(k):                   # partial Fisher-Yates: k distinct points
                j = s + _randint(&rng, m - s)
                tmp_i = pool[s]
                pool[s] = pool[j]
                pool[j] = tmp_i
            if not _newton_sample(&w, &pool[0], pr, b0, order_c, &sign[0], s2, max_change,
                                  ang, b):
                continue
            cost = _score(&w, &used[0], m, ang, b, order_c, &sign[0], s2, t2, best, &inl)
            if cost < best:
                best, best_inl = cost, inl
                for a in range(3):
                    angles_out[p, a] = ang[a]
                    base_out[p, a] = b[a]
                eps = <double>inl / <double>m
                if eps >= 1.0:
                    need = min_hyp
                else:
                    need = <long long>(log(1.0 - conf) / log(1.0 - _ipow(eps, k))) + 1
                    need = max(min_hyp, min(need, max_hyp))
        hyp_out[p] = h
        if best_inl == 0:
            status_out[p] = MSAC_NONE
            for a in range(3):
                angles_out[p, a] = prior[p, a]
            continue
        status_out[p] = MSAC_OK
        for a in range(3):
            ang[a] = angles_out[p, a]
            b[a] = base_out[p, a]
        cp.rotation(ang, order_c, &sign[0], w.R2, w.M2)
        for i in range(n):
            inlier_out[p, i] = False
            if mask[p, i]:
                g = cp.terms(&w.r1[3 * i], &w.u2[3 * i], w.R1, w.R2, w.M2, b, w.E, s2, 3,
                             w.Ji, w.N, &var)
                inlier_out[p, i] = var > 0 and g * g / var < t2
