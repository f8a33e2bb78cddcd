"""Compiled kernels of :mod:`photogrammetry.adjustment.banded`: the selected inverse of a sparse
``L D L^T`` factor and the check that its pattern is closed (private)."""
import numpy as np
from numba import njit


@njit(cache=True)
def pattern_is_closed(indptr, indices, n):
    """True when the strictly lower pattern of ``L`` (CSC, sorted rows) is that of a
    Cholesky factor: every column's rows, less its first (the elimination-tree parent
    ``p``), are rows of column ``p``.  By induction along the parents, then, any two rows
    ``k > l`` of a column have ``(k, l)`` in the pattern (what the selected inversion
    reads)."""
    mark = np.full(n, -1, np.int64)
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


@njit(cache=True)
def selected_inverse(indptr, indices, Lx, d):
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
    n = len(d)
    zx = np.zeros(len(Lx))
    zd = np.zeros(n)
    pos = np.full(n, -1, np.int64)
    y = np.zeros(n)
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
    return zd, zx
