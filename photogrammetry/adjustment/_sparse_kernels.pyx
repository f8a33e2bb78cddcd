"""Compiled kernels of :mod:`photogrammetry.adjustment.banded` (private; Cython): the
selected inverse of a sparse ``L D L^T`` factor and the check that its pattern is closed,
the entries of a banded factor's inverse within the band, and the solve of a unit lower
triangular sparse factor with a sparse right-hand side (sparse result)."""
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


def lower_solve_sparse(const index_t[:] indptr, const index_t[:] indices, const double[:] Lx,
                       const index_t[:] bptr, const index_t[:] bind, const double[:] bx,
                       Py_ssize_t n):
    """``Y = L^-1 B`` for a unit lower triangular ``L`` and a sparse ``B``, both CSC.

    ``L`` by its strictly lower part (``indptr``, ``indices``, ``Lx``; rows need not be
    sorted), ``B`` (n, k) by ``bptr``, ``bind``, ``bx``.  Column by column: ``B``'s column
    scattered into a dense work vector, then for every row ``r`` from the column's first
    non-zero on, ``x[L rows of r] -= L[., r] x[r]`` where ``x[r]`` is non-zero (cost: the
    rows below the first non-zero, plus the flops of the non-zeros reached); the
    non-zeros of ``x`` are ``Y``'s column (an entry cancelled to exactly 0 is left out).

    Returns
    -------
    yptr : ndarray of int64 (k + 1,); yind : ndarray of int64; yx : ndarray of float
        ``Y`` in CSC, rows sorted.
    """
    cdef Py_ssize_t k = bptr.shape[0] - 1, j, t, r, u, lo, cap, nnz = 0
    cdef double xr
    if indptr.shape[0] < n + 1:
        raise ValueError(f"lower_solve_sparse: indptr must hold n + 1 = {n + 1} values")
    x_arr = np.zeros(n)
    cdef double[:] x = x_arr
    yptr_arr = np.zeros(k + 1, np.int64)
    cdef long long[:] yptr = yptr_arr
    cap = max(16, 4 * bind.shape[0])
    yind_arr = np.empty(cap, np.int64)
    yx_arr = np.empty(cap)
    cdef long long[:] yind = yind_arr
    cdef double[:] yx = yx_arr
    for j in range(k):
        lo = n
        for t in range(bptr[j], bptr[j + 1]):
            x[bind[t]] += bx[t]
            if bind[t] < lo:
                lo = bind[t]
        if nnz + n - lo > cap:                     # room for the whole tail
            cap = max(2 * cap, nnz + n - lo)
            yind_arr = np.resize(yind_arr, cap)
            yx_arr = np.resize(yx_arr, cap)
            yind = yind_arr
            yx = yx_arr
        with nogil:
            for r in range(lo, n):
                xr = x[r]
                if xr == 0.0:
                    continue
                for u in range(indptr[r], indptr[r + 1]):
                    x[indices[u]] -= Lx[u] * xr
                yind[nnz] = r
                yx[nnz] = xr
                nnz += 1
                x[r] = 0.0
        yptr[j + 1] = nnz
    return yptr_arr, yind_arr[:nnz].copy(), yx_arr[:nnz].copy()


def gram_rows(const index_t[:] indptr, const index_t[:] indices, const double[:] yx,
              const double[:] w, Py_ssize_t k, Py_ssize_t panel=32):
    """``G = Y' diag(w) Y`` (dense k x k) of a sparse ``Y`` (m, k) given by rows (CSR:
    ``indptr``, ``indices`` sorted within rows, ``yx``).  By panels of `panel` columns
    ``b`` of ``G``: for every row of ``Y``, its entries ``b`` in the panel times its
    entries ``a <= b`` added to ``G[a, b]`` (the panel, ``k * panel`` values, stays in
    cache: the rows' outer products scattered into the whole ``G`` missed it on every
    entry, ten times slower); then the upper triangle mirrored.  Cost: the sum over the
    rows of half their non-zeros squared."""
    cdef Py_ssize_t m = w.shape[0], r, s, t, a, b, c0, c1, e
    cdef double yb
    if indptr.shape[0] < m + 1:
        raise ValueError(f"gram_rows: indptr must hold m + 1 = {m + 1} values")
    if panel < 1:
        raise ValueError("gram_rows: panel must be positive")
    g_arr = np.zeros((k, k))
    gp_arr = np.zeros((panel, k))
    cur_arr = np.zeros(m, np.int64)
    cdef double[:, :] g = g_arr, gp = gp_arr
    cdef long long[:] cur = cur_arr
    with nogil:
        for r in range(m):
            cur[r] = indptr[r]
        c0 = 0
        while c0 < k:
            c1 = min(c0 + panel, k)
            for r in range(m):
                e = indptr[r + 1]
                s = cur[r]
                while s < e and indices[s] < c1:
                    b = indices[s]
                    yb = yx[s] * w[r]
                    for t in range(indptr[r], s + 1):       # a <= b: sorted rows
                        gp[b - c0, indices[t]] += yb * yx[t]
                    s += 1
                cur[r] = s
            for b in range(c0, c1):
                for a in range(b + 1):
                    g[a, b] = gp[b - c0, a]
                    g[b, a] = gp[b - c0, a]
                    gp[b - c0, a] = 0.0
            c0 = c1
    return g_arr
