"""Compiled robust start of the coplanarity adjustment: minimal samples + MSAC (numba).

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
"""
import numpy as np
from numba import njit

from photogrammetry.adjustment._coplanarity_kernels import _nb_rotation, _nb_tangent, _nb_terms

#: Status of :func:`msac_pairs`: a hypothesis was found / none (every sample singular
#: or diverging: the prior is kept) / too few points (fewer than twice the sample: the
#: robust start is skipped, a wrong exact root of 5 of 7 points would win).
MSAC_OK, MSAC_NONE, MSAC_TOO_FEW = 0, 1, 2


@njit(cache=True)
def _sample_base(r1, u2, idx, R1, R2, M2, b, s2, Ji, N, scratch, E):
    """Base direction of a sample at the current rotation: the null vector of its
    epipolar-plane normals (3x3 eigenproblem)."""
    S = np.zeros((3, 3))
    for i in idx:
        _nb_terms(r1[i], u2[i], R1, R2, M2, b, E, s2, 3, Ji, N, scratch)
        for a in range(3):
            for c in range(3):
                S[a, c] += N[a] * N[c]
    _, vecs = np.linalg.eigh(S)
    return vecs[:, 0].copy()


@njit(cache=True)
def _gauss_solve(A, rhs, k):
    """Solve the k x k system in place (partial pivoting); False when a pivot is below
    1e-12 of the largest element (a degenerate sample).  The solution is in ``rhs``."""
    amax = 0.0
    for i in range(k):
        for j in range(k):
            amax = max(amax, abs(A[i, j]))
    if not amax > 0 or not np.isfinite(amax):
        return False
    for c in range(k):
        piv = c
        for i in range(c + 1, k):
            if abs(A[i, c]) > abs(A[piv, c]):
                piv = i
        if not abs(A[piv, c]) > 1e-12 * amax:
            return False
        if piv != c:
            for j in range(k):
                A[c, j], A[piv, j] = A[piv, j], A[c, j]
            rhs[c], rhs[piv] = rhs[piv], rhs[c]
        for i in range(c + 1, k):
            f = A[i, c] / A[c, c]
            for j in range(c, k):
                A[i, j] -= f * A[c, j]
            rhs[i] -= f * rhs[c]
    for c in range(k - 1, -1, -1):
        v = rhs[c]
        for j in range(c + 1, k):
            v -= A[c, j] * rhs[j]
        rhs[c] = v / A[c, c]
    return True


@njit(cache=True)
def _newton_sample(r1, u2, idx, R1, prior, b0, k, order, sign, s2, max_change, ang, b, W):
    """Exact solution of the k conditions of a sample by Newton from the prior.

    Fills ``ang`` (3,) and ``b`` (3,); returns True when converged (step below 1e-10
    rad) within `max_change` rad of the prior.  ``W``: scratch arrays."""
    R2, M2, E, Ji, N, scratch, A, rhs = W
    ang[:] = prior
    b[:] = b0
    if k == 5:
        _nb_rotation(ang, order, sign, R2, M2)
        b[:] = _sample_base(r1, u2, idx, R1, R2, M2, b, s2, Ji, N, scratch, E)
    for it in range(10):
        _nb_rotation(ang, order, sign, R2, M2)
        if k == 5:
            _nb_tangent(b, E)
        for s in range(k):
            g, var = _nb_terms(r1[idx[s]], u2[idx[s]], R1, R2, M2, b, E, s2, k, Ji, N,
                               scratch)
            for c in range(k):
                A[s, c] = Ji[c]
            rhs[s] = -g
        if not _gauss_solve(A, rhs, k):
            return False
        step = 0.0
        for c in range(3):
            ang[c] += rhs[c]
            step = max(step, abs(rhs[c]))
            if not abs(ang[c] - prior[c]) < max_change:
                return False
        if k == 5:
            for a in range(3):
                b[a] += E[a, 0] * rhs[3] + E[a, 1] * rhs[4]
            b /= np.sqrt(b @ b)
            step = max(step, abs(rhs[3]), abs(rhs[4]))
        if step < 1e-10:
            return True
    return False


@njit(cache=True)
def _score(r1, u2, used, R1, ang, b, order, sign, s2, t2, best, W):
    """MSAC cost ``sum min(g^2/var, t2)`` and the inlier count of a hypothesis (the sum
    stops once above `best`: such a hypothesis cannot win)."""
    R2, M2, E, Ji, N, scratch, _, _ = W
    _nb_rotation(ang, order, sign, R2, M2)
    cost, inl = 0.0, 0
    for i in used:
        g, var = _nb_terms(r1[i], u2[i], R1, R2, M2, b, E, s2, 3, Ji, N, scratch)
        e = g * g / var if var > 0 else np.inf
        if e < t2:
            cost += e
            inl += 1
        else:
            cost += t2
        if cost >= best:
            return np.inf, inl
    return cost, inl


@njit(cache=True)
def studentized_misclosures(u1, u2, mask, keep, R1, angles, base, Q, order, sign, s2, out):
    """Studentized misclosures of every masked point at an adjusted solution, into
    ``out`` (P, n) (0 for the others).

    ``Q`` (P, k, k) is the cofactor matrix of the solution (k = 3 with a known base, 5
    with the base direction, tangent basis of :func:`_nb_tangent`).  A point that took
    part (``keep``) is divided by the sigma of its residual, ``sqrt(var - J Q J^T)`` (the
    w-test); one that did not by the sigma of its prediction error,
    ``sqrt(var + J Q J^T)``: both are N(0, 1) for a good point, so the decision does not
    depend on which set the solution came from (an influential point of a weak pair has
    a large misclosure at a solution without it, and a small one with it)."""
    P, n = mask.shape
    k = Q.shape[1]
    R2, M2, E = np.empty((3, 3)), np.empty((3, 3)), np.zeros((3, 2))
    Ji, N, scratch, r1 = np.empty(k), np.empty(3), np.empty((2, 3)), np.empty(3)
    for p in range(P):
        _nb_rotation(angles[p], order, sign, R2, M2)
        b = base[p] / np.sqrt(base[p] @ base[p])
        if k == 5:
            _nb_tangent(b, E)
        for i in range(n):
            out[p, i] = 0.0
            if not mask[p, i]:
                continue
            for a in range(3):
                r1[a] = R1[p, a, 0] * u1[p, i, 0] + R1[p, a, 1] * u1[p, i, 1] \
                    + R1[p, a, 2] * u1[p, i, 2]
            g, var = _nb_terms(r1, u2[p, i], R1[p], R2, M2, b, E, s2, k, Ji, N, scratch)
            h = Ji @ Q[p] @ Ji
            v = var - h if keep[p, i] else var + h
            out[p, i] = g / np.sqrt(v) if v > 1e-3 * var else np.inf


@njit(cache=True)
def msac_pairs(u1, u2, mask, R1, prior, base, known, order, sign, s2, t2, conf, min_hyp,
               max_hyp, max_change, seed, angles_out, base_out, inlier_out, status_out,
               hyp_out):
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
    P, n = mask.shape
    k = 3 if known else 5
    r1 = np.empty((n, 3))
    ang, b = np.empty(3), np.empty(3)
    W = (np.empty((3, 3)), np.empty((3, 3)), np.zeros((3, 2)), np.empty(5), np.empty(3),
         np.empty((2, 3)), np.empty((k, k)), np.empty(k))
    for p in range(P):
        np.random.seed(seed)
        used = np.flatnonzero(mask[p])
        m = len(used)
        angles_out[p] = prior[p]
        base_out[p] = base[p] / max(np.sqrt(base[p] @ base[p]), 1e-300)
        inlier_out[p] = mask[p]
        hyp_out[p] = 0
        if m < 2 * k:             # too few to out-vote anything: Gauss-Newton from the
            status_out[p] = MSAC_TOO_FEW      # prior on all points, then snooping
            continue
        for i in range(n):
            for a in range(3):
                r1[i, a] = R1[p, a, 0] * u1[p, i, 0] + R1[p, a, 1] * u1[p, i, 1] \
                    + R1[p, a, 2] * u1[p, i, 2]
        pool = used.copy()
        best, best_inl, need = np.inf, 0, max_hyp
        b0 = base_out[p].copy()
        h = 0
        while h < need and h < max_hyp:
            h += 1
            for s in range(k):                   # partial Fisher-Yates: k distinct points
                j = s + np.random.randint(m - s)
                pool[s], pool[j] = pool[j], pool[s]
            if not _newton_sample(r1, u2[p], pool[:k], R1[p], prior[p], b0, k, order,
                                  sign, s2, max_change, ang, b, W):
                continue
            cost, inl = _score(r1, u2[p], used, R1[p], ang, b, order, sign, s2, t2, best, W)
            if cost < best:
                best, best_inl = cost, inl
                angles_out[p] = ang
                base_out[p] = b
                eps = inl / m
                if eps >= 1.0:
                    need = min_hyp
                else:
                    need = int(np.log(1.0 - conf) / np.log(1.0 - eps ** k)) + 1
                    need = max(min_hyp, min(need, max_hyp))
        hyp_out[p] = h
        if best_inl == 0:
            status_out[p] = MSAC_NONE
            angles_out[p] = prior[p]
            continue
        status_out[p] = MSAC_OK
        R2, M2, E, Ji, N, scratch, _, _ = W
        _nb_rotation(angles_out[p], order, sign, R2, M2)
        for i in range(n):
            inlier_out[p, i] = False
            if mask[p, i]:
                g, var = _nb_terms(r1[i], u2[p, i], R1[p], R2, M2, base_out[p], E, s2, 3,
                                   Ji, N, scratch)
                inlier_out[p, i] = var > 0 and g * g / var < t2
