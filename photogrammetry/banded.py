"""Sparse symmetric positive-definite systems as banded ones (block scale).

The normal matrix of a block couples an image only with its neighbours (the images it
shares tie points with), so after a reverse Cuthill-McKee ordering it is banded: a few
strips' worth of unknowns wide.  :class:`BandedSPD` factors it with LAPACK's banded
Cholesky (``scipy.linalg.cholesky_banded``: cost ``n b^2``, memory ``n b`` for ``n``
unknowns and half-bandwidth ``b``), solves with it, and gives the entries of the inverse
inside the band by the Takahashi recurrence (compiled, the same ``n b^2``): the 3x3
covariance block of every image without the dense inverse.
"""
import numpy as np
from numba import njit
from scipy import sparse
from scipy.linalg import cho_solve_banded, cholesky_banded
from scipy.sparse.csgraph import reverse_cuthill_mckee

from ins.errors import InputError

__all__ = ["BandedSPD", "rcm_order"]


def rcm_order(A):
    """Reverse Cuthill-McKee permutation of a sparse symmetric matrix."""
    return reverse_cuthill_mckee(sparse.csr_matrix(A), symmetric_mode=True)


def _bandwidth(A):
    coo = A.tocoo()
    return int(np.max(np.abs(coo.row - coo.col))) if coo.nnz else 0


@njit(cache=True)
def _band_inverse(cb, b):
    """Entries of ``A^-1`` within the band from the banded Cholesky factor ``cb``
    (lower form: ``cb[d, j] = L[j + d, j]``); returns ``zb`` in the same layout.

    Takahashi: ``Z = A^-1`` satisfies ``L^T Z = L^-1`` (lower triangular with the
    diagonal ``1 / L_ii``), so for ``j >= i``:
    ``Z_ij = (delta_ij / L_ii - sum_{k > i} L_ki Z_kj) / L_ii`` with ``k <= i + b``."""
    n = cb.shape[1]
    zb = np.zeros((b + 1, n))
    for i in range(n - 1, -1, -1):
        lii = cb[0, i]
        top = min(i + b, n - 1)
        for j in range(top, i - 1, -1):
            s = 0.0
            for k in range(i + 1, top + 1):
                lki = cb[k - i, i]
                if lki == 0.0:
                    continue
                # Z_kj with both k, j in (i, i + b]: symmetric, inside the band
                if k >= j:
                    s += lki * zb[k - j, j]
                else:
                    s += lki * zb[j - k, k]
            if j == i:
                zb[0, i] = (1.0 / lii - s) / lii
            else:
                zb[j - i, i] = -s / lii
    return zb


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
            self._zb = _band_inverse(self.cb, self.b)
        r, c = self.iperm[np.asarray(rows)], self.iperm[np.asarray(cols)]
        lo, hi = np.minimum(r, c), np.maximum(r, c)
        d = hi - lo
        if np.any(d > self.b):
            raise ValueError("entry outside the band of the factor")
        return self._zb[d, lo]

    def diagonal_blocks(self, k=3):
        """The ``k x k`` diagonal blocks of ``A^-1`` (n // k, k, k), original order."""
        m = self.n // k
        i = (k * np.arange(m)[:, None, None] + np.arange(k)[None, :, None])
        j = (k * np.arange(m)[:, None, None] + np.arange(k)[None, None, :])
        i, j = np.broadcast_arrays(i, j)
        return self.inverse_entries(i.ravel(), j.ravel()).reshape(m, k, k)
