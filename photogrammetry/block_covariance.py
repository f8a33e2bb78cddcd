"""Covariance of a large block's angles without the dense inverse (block scale).

For ``known-base`` blocks above :data:`photogrammetry.block.BANDED_MIN_ANGLES` unknowns
the normal matrix ``S`` of the free images' angles (sparse: an image is coupled only
with the images it shares tie points with) is factored as a banded matrix
(:class:`photogrammetry.banded.BandedSPD`), and the covariance

    C = sigma0^2 S^-1 + S^-1 T Sx T^T S^-1 = S^-1 K S^-1,   K = sigma0^2 S + T Sx T^T

(``T = J^T W G_X`` the sensitivity to the EO positions, ``Sx`` their variances; no
second term without position sigmas) is kept as an operator: its 3x3 block per image
(the Takahashi entries of ``S^-1`` inside the band, plus the position term by banded
solves), its product with vectors, and the sparse ``S`` and ``K`` for the assessment's
``V^-1 = S (lambda K + S D S)^-1 S``.
"""
from dataclasses import dataclass

import numpy as np
from scipy import sparse

from .banded import BandedSPD

__all__ = ["BandedCovariance", "banded_covariance"]


@dataclass
class BandedCovariance:
    """Covariance of the free images' angles (image-major, rad^2), as an operator.

    Attributes
    ----------
    S : scipy.sparse.csr_matrix (n, n)
        Normal matrix of the free angles (a-priori weights).
    factor : photogrammetry.banded.BandedSPD
        Its banded Cholesky factor.
    sigma0 : float
    TX : scipy.sparse.csr_matrix (n, 3m) or None
        ``T Sx^(1/2)``: the EO-position term (known-base with position sigmas).
    free : ndarray of bool (m,)
        The images of the unknowns (in order).
    blocks : ndarray (k, 3, 3)
        Covariance block of each free image.
    """
    S: object
    factor: BandedSPD
    sigma0: float
    TX: object
    free: np.ndarray
    blocks: np.ndarray

    def apply(self, v):
        """``C v`` for a vector (n,) or matrix (n, k)."""
        x = self.factor.solve(v)
        out = self.sigma0 ** 2 * x
        if self.TX is not None:
            out = out + self.factor.solve(self.TX @ (self.TX.T @ x))
        return out

    def K(self):
        """``K = sigma0^2 S + T Sx T^T`` (sparse), so that ``C = S^-1 K S^-1``."""
        K = self.sigma0 ** 2 * self.S
        if self.TX is not None:
            K = K + self.TX @ self.TX.T
        return sparse.csr_matrix(K)


def _position_blocks(factor, TX, k, chunk=256):
    """3x3 blocks of ``S^-1 TX TX^T S^-1`` per image, by banded solves of TX's columns."""
    out = np.zeros((k, 3, 3))
    TXc = sparse.csc_matrix(TX)
    for c0 in range(0, TXc.shape[1], chunk):
        Y = factor.solve(TXc[:, c0:c0 + chunk].toarray()).reshape(k, 3, -1)
        out += np.einsum("iac,ibc->iab", Y, Y)
    return out


def banded_covariance(H, sigma0, free, WJ=None, N=None, img=None, position_sigma=None):
    """The covariance operator of a known-base block from its normal matrix.

    Parameters
    ----------
    H : scipy.sparse matrix (n, n)
        Normal matrix of the free angles (with the prior's weights for datum ins).
    sigma0 : float
    free : ndarray of bool (m,)
    WJ, N, img : the block's ``W J`` (C, n), ``dg/db`` (C, 3), images (C, 2) of every
        condition (for the position term).
    position_sigma : ndarray (m, 3), optional
        Sigma of the EO positions, m.

    Returns
    -------
    BandedCovariance
    """
    S = sparse.csr_matrix(H)
    factor = BandedSPD(S, what="block normal matrix")
    k = S.shape[0] // 3
    blocks = sigma0 ** 2 * factor.diagonal_blocks(3)
    TX = None
    if position_sigma is not None and np.any(position_sigma):
        m = len(free)
        C = len(img)
        cols = (3 * img[:, :, None] + np.arange(3)).reshape(C, 6)
        G = sparse.csr_matrix((np.concatenate([-N, N], axis=1).ravel(),
                               (np.repeat(np.arange(C), 6), cols.ravel())), shape=(C, 3 * m))
        TX = sparse.csr_matrix(WJ.T @ G @ sparse.diags(np.ravel(position_sigma)))
        blocks = blocks + _position_blocks(factor, TX, k)
    return BandedCovariance(S, factor, float(sigma0), TX, free, blocks)
