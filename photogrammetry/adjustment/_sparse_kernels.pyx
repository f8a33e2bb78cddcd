"""Compiled kernels of :mod:`photogrammetry.adjustment.banded` (private; Cython): the
selected inverse of a sparse ``L D L^T`` factor and the check that its pattern is closed,
and the entries of a banded factor's inverse within the band."""
import numpy as np

#: Index arrays of a scipy sparse matrix: int32 or int64.
ctypedef fused index_t:
    int
    long long


def pattern_is_closed(const index_t[:] indptr, const index_t[:] indices, Py_ssize_t n):
    """True when the strictly lower pattern of ``L`` (CSC, sorted rows) is that of a
    Cholesky factor: every column's rows, less its first (the elimination-tree parent
    ``p``), are rows of column ``p``.  By induction along the parents, then, any two rows
    ``k > l`` of a column have ``(k, l)`` in the pattern (what the selected inversion
    reads)."""
    cdef Py_ssize_t j, a, b, p, u, t
    if indptr.shape[0] < n + 1:
        raise ValueError(f"pattern_is_closed: indptr must hold n + 1 = {n + 1} values")
    mark_arr = np.full(n, -1, np.int64)
    cdef long long[:] mark = mark_arr
    for j in range(n):
        a, b = indptr[j], indptr[j + 1]
        if b - a < 2:
            continue
        p = indices[a]
        for u in range(indptr[p], indptr[p + 1]):
            mark[indices[u]] = j
        for t in range(a + 1, b):
            if mark[indices[t]] != j:
                return False
    return True


def selected_inverse(const index_t[:] indptr, const index_t[:] indices, const double[:] Lx,
                     const double[:] d):
    """Entries of ``Z = (L D L^T)^-1`` on the pattern of ``L`` (Takahashi, sparse).

    ``L`` unit lower triangular given by its strictly lower part (CSC ``indptr``,
    ``indices`` sorted within columns, values ``Lx``), ``d`` the diagonal of ``D``.  For
    each column ``j`` from the last, with ``I`` its rows and ``x = L[I, j]``:
    ``Z[I, j] = -Z[I, I] x`` and ``Z[j, j] = 1 / d_j - x' Z[I, j]``; ``Z[I, I]`` lies on
    the pattern when it is closed (:func:`pattern_is_closed`).  Cost: for every column,
    the rows of the columns of ``I``.

    Returns
    -------
    zd : ndarray (n,)
        The diagonal of ``Z``.
    zx : ndarray like `Lx`
        ``Z[k, j]`` at the position of ``L[k, j]``.
    """
    cdef Py_ssize_t n = d.shape[0], j, a, b, t, lrow, u, q
    cdef double xl, acc, z, s
    if indptr.shape[0] < n + 1 or indices.shape[0] < Lx.shape[0]:
        raise ValueError("selected_inverse: indptr (n + 1,), indices as long as Lx")
    zx_arr = np.zeros(Lx.shape[0])
    zd_arr = np.zeros(n)
    pos_arr = np.full(n, -1, np.int64)
    y_arr = np.zeros(n)
    cdef double[:] zx = zx_arr, zd = zd_arr, y = y_arr
    cdef long long[:] pos = pos_arr
    with nogil:
        for j in range(n - 1, -1, -1):
            a, b = indptr[j], indptr[j + 1]
            for t in range(a, b):
                pos[indices[t]] = t - a
                y[t - a] = 0.0
            for t in range(a, b):
                lrow = indices[t]
                xl = Lx[t]
                acc = zd[lrow] * xl
                for u in range(indptr[lrow], indptr[lrow + 1]):
                    q = pos[indices[u]]
                    if q >= 0:                       # Z[k, l] with k, l both in I, k > l
                        z = zx[u]
                        y[q] += z * xl
                        acc += z * Lx[a + q]
                y[t - a] += acc
            s = 0.0
            for t in range(a, b):
                zx[t] = -y[t - a]
                s += Lx[t] * y[t - a]
            zd[j] = 1.0 / d[j] + s
            for t in range(a, b):
                pos[indices[t]] = -1
    return zd_arr, zx_arr


def band_inverse(const double[:, :] cb, Py_ssize_t b):
    """Entries of ``A^-1`` within the band from the banded Cholesky factor ``cb``
    (lower form: ``cb[d, j] = L[j + d, j]``); returns ``zt`` with ``zt[i, d] = Z[i, i + d]``.

    Takahashi: ``Z = A^-1`` satisfies ``L^T Z = L^-1`` (lower triangular with the
    diagonal ``1 / L_ii``), so for ``j >= i``:
    ``Z_ij = (delta_ij / L_ii - sum_{k > i} L_ki Z_kj) / L_ii`` with ``k <= i + b``.
    Row by row from the last, each row's sums accumulated over the factor's non-zero
    ``L_ki`` (a bordered normal matrix has many zeros inside its band), the stored row
    ``zt[k]`` read contiguously."""
    cdef Py_ssize_t n = cb.shape[1], i, top, w, t, k, j
    cdef double lii, lki, dd
    if cb.shape[0] < b + 1:
        raise ValueError(f"band_inverse: cb must have b + 1 = {b + 1} rows")
    zt_arr = np.zeros((n, b + 1))
    s_arr = np.zeros(b + 1)
    cdef double[:, :] zt = zt_arr
    cdef double[:] s = s_arr
    with nogil:
        for i in range(n - 1, -1, -1):
            lii = cb[0, i]
            top = min(i + b, n - 1)
            w = top - i
            for t in range(w + 1):
                s[t] = 0.0
            for k in range(i + 1, top + 1):
                lki = cb[k - i, i]
                if lki == 0.0:
                    continue
                for j in range(i + 1, k):            # Z_kj = Z_jk, j < k
                    s[j - i] += lki * zt[j, k - j]
                for j in range(k, top + 1):          # Z_kj, j >= k: row k, contiguous
                    s[j - i] += lki * zt[k, j - k]
            dd = 1.0 / lii
            for j in range(i + 1, top + 1):
                zt[i, j - i] = -s[j - i] / lii
                dd -= cb[j - i, i] * zt[i, j - i]
            zt[i, 0] = dd / lii
    return zt_arr
