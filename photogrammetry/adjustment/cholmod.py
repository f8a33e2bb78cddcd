"""Optional supernodal sparse Cholesky for the Gauss-Newton steps of a bordered block.

A relative or base-free block's normal matrix (angles and base directions, a few
thousand unknowns per hundred images) is factored at every Gauss-Newton iteration.
SuperLU (:class:`photogrammetry.adjustment.banded.SparseSPD`, scipy's) computes an
``L U`` with a column-by-column panel kernel; CHOLMOD (SuiteSparse's supernodal
``L L'``, with AMD ordering) does the same factorization several times faster: on the
470-image simulated block of ``bench/bench_block_scale.py`` (6839 unknowns, 0.9 M
non-zeros in the factor) 0.04 s against 0.11 s, conversion and analysis included.
It comes with cvxopt (``pip install insphoto[fast]``: manylinux wheels with SuiteSparse
built in; scikit-sparse has none); without it, or with :data:`USE_CHOLMOD` False,
SuperLU is used.  Only the steps are solved with it: the selected inverse and the
ordering that the assessment's augmented system reuses need SuperLU's ``L D L'``
(made on demand).  The steps agree with SuperLU's to the rounding of the solves
(the refined angles within 1e-12 rad on that block).
"""
import numpy as np
from scipy import sparse

from ins.common.errors import InputError

__all__ = ["CholmodSPD", "available", "USE_CHOLMOD"]

#: Factor the block's Gauss-Newton normal matrices with CHOLMOD when cvxopt is installed.
USE_CHOLMOD = True


def _cholmod():
    try:
        import cvxopt
        from cvxopt import cholmod
    except ImportError:
        return None, None
    return cvxopt, cholmod


def available():
    """True when :class:`CholmodSPD` can be used (cvxopt importable and
    :data:`USE_CHOLMOD`)."""
    return bool(USE_CHOLMOD) and _cholmod()[1] is not None


class CholmodSPD:
    """Supernodal Cholesky factor ``P A P' = L L'`` of a sparse SPD matrix (CHOLMOD
    through cvxopt, AMD ordering; the lower triangle of `A` is read): solves.

    Parameters
    ----------
    A : scipy.sparse matrix (n, n)
        Symmetric positive definite.
    what : str
        Names the matrix in the error message.

    Raises
    ------
    InputError
        ``A`` is not positive definite (singular normal equations).
    ImportError
        cvxopt is not installed.
    """

    def __init__(self, A, what="normal matrix"):
        cvxopt, cholmod = _cholmod()
        if cholmod is None:
            raise ImportError("CholmodSPD needs cvxopt (pip install insphoto[fast])")
        L = sparse.tril(A, format="csc")
        L.sum_duplicates()
        self.n = n = L.shape[0]
        cols = np.repeat(np.arange(n, dtype=np.int64), np.diff(L.indptr))
        M = cvxopt.spmatrix(cvxopt.matrix(np.asarray(L.data, float)),
                            cvxopt.matrix(L.indices.astype(np.int64)), cvxopt.matrix(cols),
                            (n, n))
        self._cvxopt, self._cholmod = cvxopt, cholmod
        old = cholmod.options.get("supernodal")
        cholmod.options["supernodal"] = 2                # L L', supernodal
        try:
            self.F = cholmod.symbolic(M, uplo="L")
            cholmod.numeric(M, self.F)
        except ArithmeticError:
            raise InputError(f"{what} is singular or not positive definite (part of the "
                             "block not connected to the datum, or degenerate geometry)"
                             ) from None
        finally:
            if old is None:
                cholmod.options.pop("supernodal", None)
            else:
                cholmod.options["supernodal"] = old

    def solve(self, rhs):
        """``A^-1 rhs`` for a vector (n,) or a matrix (n, k)."""
        rhs = np.asarray(rhs, dtype=float)
        B = self._cvxopt.matrix(rhs.reshape(self.n, -1))
        self._cholmod.solve(self.F, B)
        return np.array(B).reshape(rhs.shape)
