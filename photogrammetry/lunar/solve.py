"""Rotation camera -> horizon from Moon directions, and the heading.

Given unit directions ``S_c[i]`` of the Moon's centre in the camera frame (from the
image) and ``S_h[i]`` in the horizon frame (from the ephemeris), find ``C_hc`` with
``S_h = C_hc S_c``.

- `solve_rodrigues`: the lunar paper's eqs. (15)-(20), re-derived.  With the Cayley
  form ``C = (I + Q)(I - Q)^-1``, ``Q = [g x]`` (the paper's ``(a, b, c)`` are
  ``g = (a, -b, c)``), ``(I - Q) S_h = (I + Q) S_c`` gives the linear equations
  ``-[(S_h + S_c) x] g = S_h - S_c`` (rank 2 per image), solved by weighted least
  squares.  ``|g| = tan(angle / 2)`` is infinite at a 180 deg rotation: the solution
  breaks down near it.
- `solve_qmethod`: the same weighted directions, Wahba's problem solved by SVD
  (equivalent to Davenport's q-method); valid for every rotation.
- `refine`: Gauss-Newton on the camera-side residuals with each image's 2x2 covariance
  (maximum likelihood; at convergence its covariance is the Cramer-Rao bound).

Heading (the paper's eq. 14 in this toolkit's frames): the azimuth of the camera x axis
(``C_hc[:, 0]``) in the horizon frame NED, from north, clockwise, in [0, 2 pi).  The
paper's ``xi`` is the same axis's azimuth counted from south (``xi = heading - pi``) in
its own camera frame.  Rotation errors are small rotations ``phi`` in ``h``:
``C_hc_true = (I + [phi x]) C_hc_est``.
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.nav.rotation import rotvec_to_dcm, skew, wrap_to_2pi

__all__ = ["cayley", "solve_rodrigues", "solve_qmethod", "refine", "heading",
           "heading_sigma", "HeadingSolution", "solve_heading", "convergence"]


def cayley(g):
    """Rotation matrix ``(I + [g x])(I - [g x])^-1`` of a Gibbs (Rodrigues) vector ``g``."""
    Q = skew(np.asarray(g, float))
    eye = np.eye(3)
    return (eye + Q) @ np.linalg.inv(eye - Q)


def _weights(n, weights):
    w = np.ones(n) if weights is None else np.asarray(weights, float)
    if w.shape != (n,) or np.any(w < 0) or not np.any(w > 0):
        raise ValueError(f"weights must be non-negative, shape ({n},), not all zero")
    return w


def solve_rodrigues(S_h, S_c, weights=None):
    """The paper's Rodrigues-parameter least squares (eqs. 19-20).

    Parameters
    ----------
    S_h, S_c : array_like, shape (n, 3)
        Unit directions in the horizon and camera frames, n >= 2.
    weights : array_like, shape (n,), optional
        Weight of each image's equations (1 / variance of its direction).

    Returns
    -------
    C_hc : ndarray, shape (3, 3)
    g : ndarray, shape (3,)
        Gibbs vector (``tan(angle/2) * axis``).
    """
    S_h, S_c = np.asarray(S_h, float), np.asarray(S_c, float)
    w = _weights(len(S_h), weights)
    A = -skew(S_h + S_c)                              # (n, 3, 3)
    ell = S_h - S_c
    N = np.einsum("n,nji,njk->ik", w, A, A)
    b = np.einsum("n,nji,nj->i", w, A, ell)
    g = np.linalg.solve(N, b)
    return cayley(g), g


def solve_qmethod(S_h, S_c, weights=None):
    """Weighted Wahba solution by SVD: ``min sum w |S_h - C S_c|^2`` over rotations.

    Returns
    -------
    C_hc : ndarray, shape (3, 3)
    """
    S_h, S_c = np.asarray(S_h, float), np.asarray(S_c, float)
    w = _weights(len(S_h), weights)
    B = np.einsum("n,ni,nj->ij", w, S_h, S_c)
    U, _, Vt = np.linalg.svd(B)
    D = np.diag([1.0, 1.0, np.linalg.det(U) * np.linalg.det(Vt)])
    return U @ D @ Vt


def _tangent_basis(s):
    """Two unit vectors orthogonal to each row of ``s``: shape (n, 3, 2)."""
    a = np.where(np.abs(s[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(s, a)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(s, e1)
    return np.stack([e1, e2], axis=-1)


def refine(C_hc, S_h, S_c, cov_c, iterations=5):
    """Maximum-likelihood rotation with each camera direction's covariance.

    Parameters
    ----------
    C_hc : array_like, shape (3, 3)
        Start (e.g. from `solve_qmethod`).
    S_h, S_c : array_like, shape (n, 3)
        Unit directions, horizon and camera frames.
    cov_c : array_like, shape (n, 3, 3)
        Covariance of each ``S_c`` (rank 2, in its tangent plane), rad^2.

    Returns
    -------
    C_hc : ndarray, shape (3, 3)
    P : ndarray, shape (3, 3)
        Covariance of the rotation error ``phi`` in ``h``, rad^2 (a-priori: from cov_c).
    residuals : ndarray, shape (n, 2)
        Whitened residuals (dimensionless; about N(0, 1) each).
    """
    S_h, S_c = np.asarray(S_h, float), np.asarray(S_c, float)
    T = _tangent_basis(S_c)                            # (n, 3, 2)
    cov2 = np.einsum("nai,nab,nbj->nij", T, np.asarray(cov_c, float), T)
    W = np.linalg.inv(cov2)
    L = np.linalg.cholesky(W)                          # W = L L^T
    C = np.asarray(C_hc, float).copy()
    for _ in range(iterations):
        pred = S_h @ C                                 # rows: C^T S_h
        e = np.einsum("nai,na->ni", T, S_c - pred)
        H = np.einsum("nai,ab,nbc->nic", T, C.T, skew(S_h))
        N = np.einsum("nki,nkl,nlj->ij", H, W, H)
        b = np.einsum("nki,nkl,nl->i", H, W, e)
        phi = np.linalg.solve(N, b)
        C = rotvec_to_dcm(phi) @ C
        if np.linalg.norm(phi) < 1e-13:
            break
    pred = S_h @ C
    e = np.einsum("nai,na->ni", T, S_c - pred)
    H = np.einsum("nai,ab,nbc->nic", T, C.T, skew(S_h))
    N = np.einsum("nki,nkl,nlj->ij", H, W, H)
    return C, np.linalg.inv(N), np.einsum("nij,ni->nj", L, e)


REJECT = 5.0


def _whitened(C, S_h, S_c, cov_c):
    T = _tangent_basis(S_c)
    cov2 = np.einsum("nai,nab,nbj->nij", T, cov_c, T)
    L = np.linalg.cholesky(np.linalg.inv(cov2))
    e = np.einsum("nai,na->ni", T, S_c - S_h @ C)
    return np.einsum("nij,ni->nj", L, e)


def heading(C_hc):
    """Azimuth of the camera x axis in NED (from north, clockwise), rad in [0, 2 pi)."""
    C = np.asarray(C_hc, float)
    return float(wrap_to_2pi(np.arctan2(C[1, 0], C[0, 0])))


def heading_sigma(C_hc, P):
    """Standard deviation of `heading` for a rotation-error covariance ``P`` (rad^2), rad."""
    x = np.asarray(C_hc, float)[:, 0]
    hor2 = x[0] ** 2 + x[1] ** 2
    if hor2 < 1e-12:
        return float("inf")
    grad = np.array([-x[0] * x[2], -x[1] * x[2], hor2]) / hor2
    return float(np.sqrt(grad @ P @ grad))


@dataclass
class HeadingSolution:
    """Result of `solve_heading`.

    Attributes
    ----------
    C_hc : ndarray, shape (3, 3)
        Camera to horizon (NED).
    heading, heading_sigma : float
        Azimuth of the camera x axis and its standard deviation, rad.
    P : ndarray, shape (3, 3)
        Rotation-error covariance in ``h``, rad^2.
    residuals : ndarray, shape (n, 2)
        Whitened residuals per image.
    residuals_rad : ndarray, shape (n,)
        Angle between observed and predicted camera direction, rad.
    variance_factor : float
        Sum of squared whitened residuals / (2 n - 3).
    heading_rodrigues : float
        Heading of the paper's Rodrigues least squares (nan if singular), rad.
    used : ndarray of bool, shape (n,)
        Images kept (gross outliers, whitened residual > 5, are dropped).
    """
    C_hc: np.ndarray
    heading: float
    heading_sigma: float
    P: np.ndarray
    residuals: np.ndarray
    residuals_rad: np.ndarray
    variance_factor: float
    heading_rodrigues: float
    used: np.ndarray = None


def solve_heading(S_h, S_c, cov_c):
    """Heading from n >= 2 Moon directions: q-method start, maximum-likelihood refinement.

    Parameters
    ----------
    S_h : array_like, shape (n, 3)
        The Moon's direction in NED (ephemeris).
    S_c : array_like, shape (n, 3)
        The Moon's direction in the camera frame (images).
    cov_c : array_like, shape (n, 3, 3)
        Covariance of each ``S_c``, rad^2.

    Returns
    -------
    HeadingSolution
    """
    S_h, S_c = np.asarray(S_h, float), np.asarray(S_c, float)
    n = len(S_h)
    if n < 2:
        raise InputError(f"at least 2 usable images are needed, got {n}")
    cov_c = np.asarray(cov_c, float)
    var = np.trace(cov_c, axis1=1, axis2=2) / 2
    w = 1.0 / var
    used = np.ones(n, bool)
    for _ in range(max(n // 5, 1)):     # drop gross outliers (whitened residual > 5), one at a time
        C0 = solve_qmethod(S_h[used], S_c[used], w[used])
        C, P, _ = refine(C0, S_h[used], S_c[used], cov_c[used])
        res = _whitened(C, S_h, S_c, cov_c)
        worst = np.argmax(np.where(used, np.linalg.norm(res, axis=1), -1))
        if np.linalg.norm(res[worst]) <= REJECT or used.sum() <= 3:
            break
        used[worst] = False
    cosang = np.einsum("ni,ni->n", S_h @ C, S_c)
    try:
        with np.errstate(all="ignore"):
            C_r, _ = solve_rodrigues(S_h[used], S_c[used], w[used])
        h_r = heading(C_r) if np.all(np.isfinite(C_r)) else float("nan")
    except np.linalg.LinAlgError:
        h_r = float("nan")
    dof = max(2 * int(used.sum()) - 3, 1)
    return HeadingSolution(C_hc=C, heading=heading(C), heading_sigma=heading_sigma(C, P), P=P,
                           residuals=res, residuals_rad=np.arccos(np.clip(cosang, -1, 1)),
                           variance_factor=float(np.sum(res[used] ** 2) / dof),
                           heading_rodrigues=h_r, used=used)


def convergence(S_h, S_c, cov_c, counts=None):
    """Heading and sigma from the first k images, for each k (the paper's Figure 3).

    Returns
    -------
    counts : ndarray of int
    headings, sigmas : ndarray
        rad.
    """
    n = len(S_h)
    counts = np.arange(2, n + 1) if counts is None else np.asarray(counts, int)
    out = [solve_heading(S_h[:k], S_c[:k], cov_c[:k]) for k in counts]
    return counts, np.array([s.heading for s in out]), np.array([s.heading_sigma for s in out])
