"""Sparse symmetric positive-definite systems as banded ones (block scale).

The normal matrix of a block couples an image only with its neighbours (the images it
shares tie points with), so after a reverse Cuthill-McKee ordering it is banded: a few
strips' worth of unknowns wide.  :class:`BandedSPD` factors it with LAPACK's banded
Cholesky (``scipy.linalg.cholesky_banded``: cost ``n b^2``, memory ``n b`` for ``n``
unknowns and half-bandwidth ``b``), solves with it, and gives the entries of the inverse
inside the band by the Takahashi recurrence (compiled, the same ``n b^2``): the 3x3
covariance block of every image without the dense inverse.

A relative block's normal matrix also holds two base-direction unknowns per pair, which
the joint weights of a tie point couple across its pairs: banded, it is about four times
wider.  :class:`SparseSPD` factors it as ``L D L'`` in minimum-degree order (SuperLU with
diagonal pivots) and gives the entries of the inverse on the factor's own pattern by the
same recurrence run over the sparse pattern (selected inversion): cost the sum, over the
columns, of the rows of the columns they touch, instead of ``n b^2``.
"""
import numpy as np
from scipy import sparse
from scipy.linalg import cho_solve_banded, cholesky_banded
from scipy.sparse.csgraph import reverse_cuthill_mckee
from scipy.sparse.linalg import splu

from ins.common.errors import InputError
from photogrammetry.adjustment._sparse_kernels import (band_inverse, gram_rows,
                                                        lower_solve_sparse, pattern_is_closed,
                                                        selected_inverse)

__all__ = ["BandedSPD", "SparseSPD", "rcm_order", "bordered_order", "DENSE_ROW"]

#: :meth:`SparseSPD.inverse_form`: rows of ``Y`` with more than this fraction of their
#: entries non-zero are multiplied densely (BLAS); 470 base-free images: the last 600 of
#: 5432 rows, the product 0.07 s where the compiled sparse one alone took 0.25 s.
DENSE_ROW = 0.3


def rcm_order(A):
    """Reverse Cuthill-McKee permutation of a sparse symmetric matrix."""
    return reverse_cuthill_mckee(sparse.csr_matrix(A), symmetric_mode=True)


def bordered_order(A, n_first, k=3):
    """Ordering of a normal matrix whose first `n_first` unknowns come in groups of `k`
    (an image's angles) and whose others (nuisances, e.g. a pair's base direction)
    each touch a few groups: the groups in reverse Cuthill-McKee order of their own
    graph, every other unknown right after the last group it is coupled with, or the
    reverse Cuthill-McKee order of the whole matrix if its bandwidth is smaller.  On a
    relative block's normal matrix (two base parameters per pair) the half-bandwidth
    is about 25 % below the whole matrix's reverse Cuthill-McKee order on 1000 images
    (831 against 1119), above it on 24 (173 against 134)."""
    A = sparse.csr_matrix(A)
    n = A.shape[0]
    grp = sparse.csr_matrix((np.ones(n_first), (np.arange(n_first) // k,
                                                np.arange(n_first))))
    G = grp @ abs(A[:n_first, :n_first]) @ grp.T
    rank = np.empty(G.shape[0], dtype=np.int64)
    rank[rcm_order(G)] = np.arange(G.shape[0])
    key = np.empty(n)
    key[:n_first] = rank[np.arange(n_first) // k] + (np.arange(n_first) % k) / (k + 1.0)
    B = sparse.csc_matrix(A[:n_first, n_first:])
    last = np.full(n - n_first, -1.0)
    nz = np.diff(B.indptr) > 0
    if nz.any():
        r = rank[B.indices // k]
        last[nz] = np.maximum.reduceat(r, B.indptr[:-1][nz])
    key[n_first:] = np.where(last >= 0, last + 0.9, G.shape[0])
    perm = np.argsort(key, kind="stable")
    whole = rcm_order(A)
    return perm if _bandwidth(A[perm][:, perm]) <= _bandwidth(A[whole][:, whole]) else whole


def _bandwidth(A):
    coo = A.tocoo()
    return int(np.max(np.abs(coo.row - coo.col))) if coo.nnz else 0


class BandedSPD:
    """Cholesky factor of a sparse SPD matrix in a bandwidth-reducing order.

    Parameters
    ----------
    A : scipy.sparse matrix (n, n)
        Symmetric positive definite.
    perm : ndarray of int (n,), optional
        Ordering (default: reverse Cuthill-McKee of ``A``).
    what : str
        Names the matrix in the error message.

    Raises
    ------
    InputError
        ``A`` is not positive definite (singular normal equations).
    """

    def __init__(self, A, perm=None, what="normal matrix"):
        A = sparse.csr_matrix(A)
        self.n = A.shape[0]
        self.perm = rcm_order(A) if perm is None else np.asarray(perm)
        self.iperm = np.empty_like(self.perm)
        self.iperm[self.perm] = np.arange(self.n)
        P = A[self.perm][:, self.perm].tocoo()
        self.b = _bandwidth(P)
        keep = P.row >= P.col
        ab = np.zeros((self.b + 1, self.n))
        ab[P.row[keep] - P.col[keep], P.col[keep]] = P.data[keep]
        try:
            self.cb = cholesky_banded(ab, lower=True)
        except np.linalg.LinAlgError:
            raise InputError(f"{what} is singular or not positive definite (part of the "
                             "block not connected to the datum, or degenerate geometry)"
                             ) from None
        self._zb = None

    def solve(self, rhs):
        """``A^-1 rhs`` for a vector (n,) or a matrix (n, k)."""
        rhs = np.asarray(rhs, dtype=float)
        x = cho_solve_banded((self.cb, True), rhs[self.perm])
        return x[self.iperm]

    def inverse_entries(self, rows, cols):
        """Entries ``(A^-1)[rows, cols]`` (original order); each pair must lie inside
        the band of the ordered matrix (e.g. unknowns coupled in ``A``)."""
        if self._zb is None:
            self._zb = band_inverse(self.cb, self.b)
        r, c = self.iperm[np.asarray(rows)], self.iperm[np.asarray(cols)]
        lo, hi = np.minimum(r, c), np.maximum(r, c)
        d = hi - lo
        if np.any(d > self.b):
            raise ValueError("entry outside the band of the factor")
        return self._zb[lo, d]

    def diagonal_blocks(self, k=3, m=None):
        """The ``k x k`` diagonal blocks of ``A^-1`` (m, k, k) of the first ``m k``
        unknowns (default all: ``m = n // k``), original order."""
        return _diagonal_blocks(self, k, m)


class SparseSPD:
    """Sparse ``L D L^T`` factor (SuperLU, minimum-degree order of ``A + A'``, diagonal
    pivots) of a sparse SPD matrix: solves, and the entries of the inverse on the
    factor's pattern by the sparse Takahashi recurrence (selected inversion,
    :func:`photogrammetry.adjustment._sparse_kernels.selected_inverse`).  On a relative block's
    bordered normal matrix (angles and bases) its fill is several times below the
    banded factor's (1000 images: 1.7 M non-zeros in ``L`` against 10 M in the band),
    and its selected inverse costs 0.6 s against 3.8 s for the band's.

    Raises
    ------
    InputError
        ``A`` singular or not positive definite (a non-positive pivot).
    """

    def __init__(self, A, what="normal matrix"):
        A = sparse.csc_matrix(A)
        A.sum_duplicates()                       # canonical: sorted, no duplicates
        self.n = A.shape[0]
        bad = InputError(f"{what} is singular or not positive definite (part of the "
                         "block not connected to the datum, or degenerate geometry)")
        key = _pattern_key(A)
        order = _ORDERS.get(key)
        try:
            if order is None:
                lu = splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                          options=dict(SymmetricMode=True))
            else:                                # the same pattern: its ordering again
                lu = splu(A[order][:, order].tocsc(), permc_spec="NATURAL",
                          diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
        except RuntimeError:
            raise bad from None
        self.lu, self.order = lu, order      # order: None if A itself was factored
        if order is None:
            _remember(key, np.argsort(lu.perm_c))   # factor position -> original index
            self.perm_c = lu.perm_c
        else:                                # original index -> position in the factor
            iorder = np.empty_like(order)
            iorder[order] = np.arange(self.n)
            self.perm_c = lu.perm_c[iorder]
        self.d = self.lu.U.diagonal()
        if not np.all(self.d > 0):
            raise bad
        self._sel = None

    @property
    def nnz(self):
        """Non-zeros of the factor's strictly lower part (the fill)."""
        return int(self.lu.L.nnz - self.n)

    def solve(self, rhs):
        """``A^-1 rhs`` for a vector (n,) or a matrix (n, k)."""
        rhs = np.asarray(rhs, dtype=float)
        if self.order is None:
            return self.lu.solve(rhs)
        out = np.empty_like(rhs)
        out[self.order] = self.lu.solve(np.ascontiguousarray(rhs[self.order]))
        return out

    def has_selected_inverse(self):
        """True when the factor is ``L D L^T`` of one symmetric ordering with a closed
        pattern (SuperLU kept the diagonal pivots): :meth:`inverse_entries` is exact."""
        if self._sel is None:
            ok = np.array_equal(self.lu.perm_r, self.lu.perm_c)
            L = sparse.tril(self.lu.L, k=-1, format="csc")
            L.sort_indices()
            ok = ok and pattern_is_closed(L.indptr, L.indices, self.n)
            self._sel = (L, None) if ok else False
        return self._sel is not False

    def inverse_entries(self, rows, cols):
        """Entries ``(A^-1)[rows, cols]`` (original order); each pair must be coupled in
        ``A`` or in the factor's fill (else ValueError)."""
        if not self.has_selected_inverse():
            raise ValueError("the factor has no closed L D L' pattern (off-diagonal pivots)")
        L, Z = self._sel
        if Z is None:
            Z = selected_inverse(L.indptr, L.indices, L.data, self.d)
            self._sel = (L, Z)
        zd, zx = Z
        p = self.perm_c
        r, c = p[np.asarray(rows)], p[np.asarray(cols)]
        lo, hi = np.minimum(r, c), np.maximum(r, c)
        out = zd[lo].copy()
        off = np.flatnonzero(hi > lo)
        if len(off):
            idx, found = _find_entries(L.indptr, L.indices, lo[off], hi[off])
            if not np.all(found):
                raise ValueError("entry outside the pattern of the factor")
            out[off] = zx[idx]
        return out

    def diagonal_blocks(self, k=3, m=None):
        """The ``k x k`` diagonal blocks of ``A^-1`` (m, k, k) of the first ``m k``
        unknowns (default all: ``m = n // k``), original order."""
        return _diagonal_blocks(self, k, m)

    def inverse_form(self, B):
        """``B' A^-1 B`` (dense k x k) for a sparse ``B`` (n, k): with ``A = Q' L D L' Q``,
        ``Y = L^-1 Q B`` by a sparse triangular solve (compiled,
        :func:`photogrammetry.adjustment._sparse_kernels.lower_solve_sparse`) and
        ``Y' D^-1 Y`` as a sparse product.  Cost: the non-zeros that ``L`` spreads ``B``
        to, where the dense solve of ``A`` with ``B``'s columns costs the whole factor per
        column (a 470-image base-free block's Schur complement of the bases: 0.1 s against
        1.7 s); the rows of ``Y`` fuller than :data:`DENSE_ROW` by BLAS.  Needs SuperLU's
        diagonal pivots in one symmetric ordering (ValueError otherwise)."""
        if not np.array_equal(self.lu.perm_r, self.lu.perm_c):
            raise ValueError("the factor is not L D L' of one symmetric ordering")
        iperm = np.empty_like(self.perm_c)
        iperm[self.perm_c] = np.arange(self.n)          # factor position -> original
        QB = sparse.csc_matrix(sparse.csr_matrix(B)[iperm])
        QB.sort_indices()
        L = sparse.tril(self.lu.L, k=-1, format="csc")
        yp, yi, yx = lower_solve_sparse(L.indptr, L.indices, L.data, QB.indptr,
                                        QB.indices, QB.data, self.n)
        Y = sparse.csr_matrix(sparse.csc_matrix((yx, yi, yp), shape=(self.n, QB.shape[1])))
        Y.sort_indices()
        k, w = QB.shape[1], 1.0 / self.d
        # the factor's last rows (the elimination tree's root) are dense: their part by
        # BLAS, the others' by the compiled sparse product
        heavy = np.diff(Y.indptr) > DENSE_ROW * k
        light = Y[~heavy]
        G = gram_rows(light.indptr, light.indices, light.data, w[~heavy], k)
        if heavy.any():
            Yh = Y[heavy].toarray() * np.sqrt(w[heavy])[:, None]
            G += Yh.T @ Yh                        # numpy's syrk: exactly symmetric
        return G


#: Fill-reducing orderings of the last few sparsity patterns factored (a block's
#: Gauss-Newton iterations and the assessment's REML iterates refactor one pattern
#: with new values: the minimum-degree ordering is found once, a fifth of a
#: factorization; the numbers are those of the same elimination order).
_ORDERS = {}
_ORDERS_KEPT = 4


def _pattern_key(A):
    """Hashable key of the sparsity pattern of a canonical CSC matrix (a checksum: two
    patterns that collided would share an ordering, a valid one of more fill)."""
    import zlib
    return (A.shape[0], A.nnz, str(A.indices.dtype),
            zlib.adler32(np.ascontiguousarray(A.indptr)),
            zlib.adler32(np.ascontiguousarray(A.indices)))


def _remember(key, order):
    _ORDERS[key] = order
    while len(_ORDERS) > _ORDERS_KEPT:
        _ORDERS.pop(next(iter(_ORDERS)))


def _find_entries(indptr, indices, cols, rows):
    """Positions of the entries ``(rows, cols)`` in a CSC pattern with sorted rows: one
    search of the keys ``col * n + row``, which a sorted CSC pattern holds in order."""
    cols = np.asarray(cols, dtype=np.int64)
    rows = np.asarray(rows, dtype=np.int64)
    n = max(len(indptr) - 1, int(np.max(rows, initial=0)) + 1)
    counts = np.diff(indptr)
    keys = np.repeat(np.arange(len(counts), dtype=np.int64), counts) * n + indices
    idx = np.searchsorted(keys, cols * n + rows)
    ends = np.asarray(indptr, dtype=np.int64)[cols + 1]
    found = idx < ends
    found[found] = np.asarray(indices)[idx[found]] == rows[found]
    return idx, found


def _diagonal_blocks(factor, k, m):
    m = factor.n // k if m is None else int(m)
    i = (k * np.arange(m)[:, None, None] + np.arange(k)[None, :, None])
    j = (k * np.arange(m)[:, None, None] + np.arange(k)[None, None, :])
    i, j = np.broadcast_arrays(i, j)
    return factor.inverse_entries(i.ravel(), j.ravel()).reshape(m, k, k)
