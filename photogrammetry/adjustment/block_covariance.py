"""Covariance of a large block's angles without the dense inverse (block scale).

For ``known-base`` blocks above :data:`photogrammetry.adjustment.block.BANDED_MIN_ANGLES` unknowns
the normal matrix ``S`` of the free images' angles (sparse: an image is coupled only
with the images it shares tie points with) is factored as a banded matrix
(:class:`photogrammetry.adjustment.banded.BandedSPD`), and the covariance

    C = sigma0^2 S^-1 + S^-1 T Sx T^T S^-1 = S^-1 K S^-1,   K = sigma0^2 S + T Sx T^T

(``T = J^T W G_X`` the sensitivity to the EO positions, ``Sx`` their variances; no
second term without position sigmas) is kept as an operator: its 3x3 block per image
(the Takahashi entries of ``S^-1`` inside the band, plus the position term by banded
solves), its product with vectors, and the sparse ``S`` and ``K`` for the assessment's
``V^-1 = S (lambda K + S D S)^-1 S``.

Relative and base-free blocks (bordered): the unknowns are the angles and two
base-direction parameters per pair; the angles' normal matrix is the Schur complement
``S = H_aa - H_ab H_bb^-1 H_ba`` of the bases, which is dense (the bases of pairs that
share tie points are coupled through the joint weights, so ``H_bb^-1`` fills in).  The
full normal matrix ``H`` (angles first, then bases) is sparse (a base touches two
images), so it is ``H`` that is factored:
``S^-1 = (H^-1)_aa``, the angles' covariance blocks are entries of ``H^-1`` on the
pattern of its sparse ``L D L'`` factor (minimum-degree order; selected inversion, the
Takahashi recurrence on a sparse pattern, :class:`photogrammetry.adjustment.banded.SparseSPD`) and
``C v = sigma0^2 (H^-1 [v; 0])_a``.  ``n_angles`` < ``H.shape[0]`` marks this form
(no position term: the bases are unknowns).
"""
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.linalg import lapack

from ins.common.errors import InputError
from photogrammetry.adjustment.banded import BandedSPD, SparseSPD, bordered_order

__all__ = ["BandedCovariance", "banded_covariance", "DENSE_MAX_ANGLES"]

#: A bordered block (relative, base-free) of at most this many angles keeps its
#: covariance as a dense matrix too (``BandedCovariance.C``, ``8 n^2`` bytes: 70 MB at
#: 1000 images, 104 MB at this bound, 1200 images): its sigmas are its diagonal
#: (instead of the selected inverse of the sparse factor) and the INS assessment works
#: on it (:class:`photogrammetry.adjustment.reml.DenseV`: a dense Cholesky of ``n^3 / 3``
#: flops per REML evaluation; 987 images: 0.3 s, three times cheaper than the sparse
#: augmented system, whose cost grows more slowly).  Forming it and the assessment
#: hold two such matrices at a time; the bound keeps them within a fifth of the 1 GB
#: that a block of that size may use (``bench/bench_block_scale.py``).
DENSE_MAX_ANGLES = 3600


@dataclass
class BandedCovariance:
    """Covariance of the free images' angles (image-major, rad^2), as an operator.

    Attributes
    ----------
    S : scipy.sparse.csr_matrix (N, N)
        Normal matrix of the free angles (a-priori weights); bordered (relative
        methods): of the angles and then the base-direction parameters (``N > n``).
    factor : photogrammetry.adjustment.banded.BandedSPD or SparseSPD
        The factor whose inverse entries gave the covariance blocks (Takahashi): banded
        Cholesky (known-base), sparse ``L D L'`` (bordered).
    sigma0 : float
    TX : scipy.sparse.csr_matrix (n, 3m) or None
        ``T Sx^(1/2)``: the EO-position term (known-base with position sigmas).
    free : ndarray of bool (m,)
        The images of the unknowns (in order).
    blocks : ndarray (k, 3, 3)
        Covariance block of each free image.
    n_angles : int
        ``n``, the angle unknowns (the first ``n`` of ``S``).
    solver : photogrammetry.adjustment.banded.SparseSPD or BandedSPD
        Solves with ``S`` (bordered: the sparse LU, cheaper than the band; else
        `factor`).
    C : ndarray (n, n) or None
        The covariance as a dense matrix, when it was formed (:meth:`dense`; bordered
        blocks of up to :data:`DENSE_MAX_ANGLES` angles: their blocks are its diagonal).
    """
    S: object
    factor: object
    sigma0: float
    TX: object
    free: np.ndarray
    blocks: np.ndarray
    n_angles: int = None
    solver: object = None
    C: object = None

    def __post_init__(self):
        if self.n_angles is None:
            self.n_angles = self.S.shape[0]
        if self.solver is None:
            self.solver = self.factor

    @property
    def bordered(self):
        """True when ``S`` holds base-direction unknowns after the angles."""
        return self.n_angles < self.S.shape[0]

    def solve_angles(self, v):
        """``(S_full^-1 [v; 0])_a``: the inverse of the angles' (reduced) normal matrix
        times `v` (n,) or (n, k)."""
        v = np.asarray(v, dtype=float)
        if not self.bordered:
            return self.factor.solve(v)
        pad = np.zeros((self.S.shape[0],) + v.shape[1:])
        pad[:self.n_angles] = v
        return self.solver.solve(pad)[:self.n_angles]

    def apply(self, v):
        """``C v`` for a vector (n,) or matrix (n, k)."""
        x = self.solve_angles(v)
        out = self.sigma0 ** 2 * x
        if self.TX is not None:
            out = out + self.factor.solve(self.TX @ (self.TX.T @ x))
        return out

    def dense(self):
        """``C`` as a dense matrix (n, n), rad^2 (`C` when it was kept).  Bordered:
        ``sigma0^2 S^-1`` with the reduced normal matrix ``S = H_aa - H_ab H_bb^-1 H_ba``
        formed through the sparse factor of the bases' block ``H_bb``
        (:meth:`photogrammetry.adjustment.banded.SparseSPD.inverse_form`) and inverted by
        LAPACK's Cholesky (470 base-free images: 0.4 s, where the solves of ``H`` with
        the angles' unit vectors took 3 s); ValueError when SuperLU's factor of
        ``H_bb`` is not ``L D L'`` of one ordering.  Else ``C`` applied to the identity.
        Memory ``8 n^2`` bytes (with the temporaries, three times that)."""
        if self.C is not None:
            return self.C
        n = self.n_angles
        if not self.bordered:
            return self.apply(np.eye(n))
        H = sparse.csr_matrix(self.S)
        Hbb = SparseSPD(H[n:, n:], what="block normal matrix of the bases")
        S = Hbb.inverse_form(H[n:, :n])
        S *= -1.0
        S += H[:n, :n].toarray()
        C = _inv_spd(S.T, "the block's reduced normal matrix")   # (in place: F order)
        C *= self.sigma0 ** 2
        return C

    def K(self):
        """``K = sigma0^2 S + T Sx T^T`` (sparse), so that ``C = S^-1 K S^-1`` (not
        bordered only)."""
        if self.bordered:
            raise ValueError("a bordered block's reduced normal matrix is not sparse")
        K = self.sigma0 ** 2 * self.S
        if self.TX is not None:
            K = K + self.TX @ self.TX.T
        return sparse.csr_matrix(K)


def _diagonal_blocks(C):
    """The 3x3 diagonal blocks (k, 3, 3) of a dense (3k, 3k) matrix."""
    i = 3 * np.arange(len(C) // 3)[:, None, None] + np.arange(3)[None, :, None]
    return C[i, i.transpose(0, 2, 1)]


def _inv_spd(M, what):
    """Inverse of a dense SPD matrix (LAPACK potrf + potri on its lower triangle; `M`
    overwritten when it is in Fortran order)."""
    c, info = lapack.dpotrf(M, lower=1, clean=1, overwrite_a=1)
    if info == 0:
        c, info = lapack.dpotri(c, lower=1, overwrite_c=1)
    if info != 0:
        raise InputError(f"{what} is singular or not positive definite (part of the "
                         "block not connected to the datum, or degenerate geometry)")
    for s in range(0, len(c), 512):          # the lower triangle mirrored in place
        e = s + 512
        d = c[s:e, s:e]
        d[...] = np.tril(d) + np.tril(d, -1).T
        c[s:e, e:] = c[e:, s:e].T
    return c


def _position_blocks(factor, TX, k, chunk=256):
    """3x3 blocks of ``S^-1 TX TX^T S^-1`` per image, by banded solves of TX's columns."""
    out = np.zeros((k, 3, 3))
    TXc = sparse.csc_matrix(TX)
    for c0 in range(0, TXc.shape[1], chunk):
        Y = factor.solve(TXc[:, c0:c0 + chunk].toarray()).reshape(k, 3, -1)
        out += np.einsum("iac,ibc->iab", Y, Y)
    return out


def banded_covariance(H, sigma0, free, WJ=None, N=None, img=None, position_sigma=None,
                      n_angles=None, factor=None):
    """The covariance operator of a block from its normal matrix.

    Parameters
    ----------
    H : scipy.sparse matrix (N, N)
        Normal matrix of the free angles (with the prior's weights for datum ins), then
        (relative methods) of the base-direction parameters.
    sigma0 : float
    free : ndarray of bool (m,)
    WJ, N, img : the block's ``W J`` (C, n), ``dg/db`` (C, 3), images (C, 2) of every
        condition (for the position term).
    position_sigma : ndarray (m, 3), optional
        Sigma of the EO positions, m (known-base only).
    n_angles : int, optional
        Angle unknowns (default all of ``H``: known-base).
    factor : photogrammetry.adjustment.banded.SparseSPD, optional
        The sparse factor of `H` if already computed (bordered blocks: the last
        Gauss-Newton step's; a :class:`photogrammetry.adjustment.cholmod.CholmodSPD`
        serves the dense covariance's solves, a SuperLU factor is made otherwise).

    Returns
    -------
    BandedCovariance
    """
    S = sparse.csr_matrix(H)
    n_angles = S.shape[0] if n_angles is None else int(n_angles)
    k = n_angles // 3
    if n_angles < S.shape[0]:           # bordered: selected inverse of the sparse factor
        if n_angles <= DENSE_MAX_ANGLES:    # the dense C, which the assessment uses
            solver = factor if factor is not None else SparseSPD(
                S, what="block normal matrix")   # (any factor that solves)
            op = BandedCovariance(S, solver, float(sigma0), None, free, None, n_angles,
                                  solver)
            try:
                op.C = op.dense()
            except ValueError:              # no L D L' of the bases' block
                op = None
            if op is not None:
                op.blocks = _diagonal_blocks(op.C)
                return op
        solver = factor if isinstance(factor, SparseSPD) else SparseSPD(
            S, what="block normal matrix")
        if solver.has_selected_inverse():
            blocks = sigma0 ** 2 * solver.diagonal_blocks(3, k)
            return BandedCovariance(S, solver, float(sigma0), None, free, blocks,
                                    n_angles, solver)
        band = BandedSPD(S, perm=bordered_order(S, n_angles), what="block normal matrix")
        return BandedCovariance(S, band, float(sigma0), None, free,
                                sigma0 ** 2 * band.diagonal_blocks(3, k), n_angles, solver)
    factor = BandedSPD(S, what="block normal matrix")
    blocks = sigma0 ** 2 * factor.diagonal_blocks(3, k)
    TX = None
    if position_sigma is not None and np.any(position_sigma):
        m = len(free)
        C = len(img)
        cols = (3 * img[:, :, None] + np.arange(3)).reshape(C, 6)
        G = sparse.csr_matrix((np.concatenate([-N, N], axis=1).ravel(),
                               (np.repeat(np.arange(C), 6), cols.ravel())), shape=(C, 3 * m))
        TX = sparse.csr_matrix(WJ.T @ G @ sparse.diags(np.ravel(position_sigma)))
        blocks = blocks + _position_blocks(factor, TX, k)
    return BandedCovariance(S, factor, float(sigma0), TX, free, blocks, n_angles, None)


def _position_cov(WJ, N, img, m, n_ang, position_sigma):
    """Angle-covariance term of the EO position errors (known-base), to be sandwiched by
    ``H^-1``: the estimate solves ``J^T W g(theta, X) = 0``, so to first order
    ``d theta = -H^-1 J^T W G_X dX`` with ``G_X = dg/dX`` (``g = (X_j - X_i) . N``:
    ``+N`` for image j, ``-N`` for image i).  Returns ``T S_X T^T``, ``T = J^T W G_X``."""
    C = len(img)
    cols = (3 * img[:, :, None] + np.arange(3)).reshape(C, 6)
    data = np.concatenate([-N, N], axis=1)
    G = sparse.csr_matrix((data.ravel(), (np.repeat(np.arange(C), 6), cols.ravel())),
                          shape=(C, 3 * m))
    T = (WJ[:, :n_ang].T @ G).toarray()
    return (T * (position_sigma.ravel() ** 2)[None, :]) @ T.T
