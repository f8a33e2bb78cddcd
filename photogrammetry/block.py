"""Block adjustment of exposure angles from the coplanarity of every overlapping pair.

Unknowns: the three angles of every image (rad, in the named system; ``R = C_mc``), and,
for the ``relative``/``base-free`` methods, the base direction of every pair (two
nuisance parameters each, eliminated pair by pair).  One condition per tie point and
pair, ``det[b, R_i u_i, R_j u_j] = 0``, weighted by its variance propagated from the
four photo coordinates.  Points seen in three or more images enter several pairs; the
correlation between those conditions is neglected.

Datum (the coplanarity conditions fix the angles only up to a common rotation unless the
bases are known): ``"first"`` holds the first image's angles at their prior (the paper's
transfer to the geodetic frame through one known image); ``"ins"`` adds every image's
prior angles as weighted observations (sigma from the EO file or a default);
``"none"`` adds nothing (only with ``known-base``, where the GNSS bases orient the block).
The results are in the mapping frame of the priors with the full covariance matrix.
"""
import warnings
from dataclasses import dataclass, field

import numpy as np

from ins.errors import InputError, InputWarning

from . import _coplanarity_kernels as K
from .coplanarity import STATUS_TEXT, STATUS_ZERO_BASE, adjust_pairs
from .rotation import check_system

__all__ = ["BlockResult", "adjust_block", "pad_pairs", "DATUMS"]

DATUMS = ("first", "ins", "none")


@dataclass
class BlockResult:
    """Adjusted angles of a block.

    Attributes
    ----------
    angles : ndarray (m, 3)
        Rad, system order, mapping frame; the prior for images that were not adjusted.
    cov : ndarray (3m, 3m)
        A-posteriori covariance of all angles (image-major), rad^2.
    sigma : ndarray (m, 3)
        Per-angle standard deviations, rad (0 for the datum image of ``"first"``).
    sigma0 : float
        A-posteriori standard deviation of unit weight (1 = the a-priori photo sigma).
    redundancy : int
    iterations : int
    converged : bool
    adjusted : ndarray of bool (m,)
        Images that took part (connected to the block by at least one good pair).
    pair_status : ndarray of int (P,)
        Per pair, see :data:`photogrammetry.coplanarity.STATUS_TEXT`.
    rejected : ndarray of bool (P, n)
        Tie points rejected by data snooping (pair-wise, before the block adjustment).
    residuals : ndarray (P, n)
        Normalized misclosures ``g / sqrt(var)`` at the solution (0 where not used).
    """
    angles: np.ndarray
    cov: np.ndarray
    sigma: np.ndarray
    sigma0: float
    redundancy: int
    iterations: int
    converged: bool
    adjusted: np.ndarray
    pair_status: np.ndarray
    rejected: np.ndarray
    residuals: np.ndarray
    mask: np.ndarray = field(repr=False, default=None)

    def correlation(self):
        """Correlation matrix of all angles (3m, 3m); 0 rows for fixed images."""
        s = np.sqrt(np.diag(self.cov))
        inv = np.where(s > 0, 1.0 / np.where(s > 0, s, 1.0), 0.0)
        return self.cov * inv[:, None] * inv[None, :]


def pad_pairs(pair_points):
    """Stack per-pair point lists into padded arrays.

    Parameters
    ----------
    pair_points : sequence of (xy_i, xy_j)
        Photo coordinates (n_k, 2) mm of the common points in the two images.

    Returns
    -------
    xy_i, xy_j : ndarray (P, n_max, 2); mask : ndarray of bool (P, n_max)
    """
    n_max = max([len(a) for a, _ in pair_points] + [1])
    P = len(pair_points)
    xy_i, xy_j = np.zeros((P, n_max, 2)), np.zeros((P, n_max, 2))
    mask = np.zeros((P, n_max), bool)
    for k, (a, b) in enumerate(pair_points):
        xy_i[k, :len(a)], xy_j[k, :len(b)], mask[k, :len(a)] = a, b, True
    return xy_i, xy_j, mask


def _pair_normals(u_i, u_j, mask, R_i, M_i, R_j, M_j, b, mode, sigma_mm):
    """Per pair: reduced normal matrix (6, 6) and gradient (6,) for (theta_i, theta_j)."""
    r_i = np.einsum("pab,pnb->pna", R_i, u_i)
    r_j = np.einsum("pab,pnb->pna", R_j, u_j)
    if mode == "free":
        g, var, N, _ = K.condition_terms(r_i, r_j, b, R_i, R_j, sigma_mm)
        b = K.smallest_direction(N, np.where(mask, 1.0 / np.where(var > 0, var, 1), 0))
    g, var, N, A_j = K.condition_terms(r_i, r_j, b, R_i, R_j, sigma_mm)
    A_i = np.cross(r_i, np.cross(r_j, b[:, None, :]))
    w = np.where(mask, 1.0 / np.where(var > 0, var, 1.0), 0.0)
    J = np.concatenate([np.einsum("pna,pak->pnk", A_i, M_i),
                        np.einsum("pna,pak->pnk", A_j, M_j)], axis=2)
    E = None
    if mode != "known":
        E = K.tangent_basis(b)
        J = np.concatenate([J, np.einsum("pna,pak->pnk", N, E)], axis=2)
    H = np.einsum("pn,pna,pnb->pab", w, J, J)
    grad = np.einsum("pn,pna,pn->pa", w, J, g)
    HbbInv_Hba = None
    if mode != "known":          # eliminate the base direction of each pair
        Hbb = H[:, 6:, 6:] + 1e-30 * np.eye(2)
        HbbInv_Hba = np.linalg.solve(Hbb, H[:, 6:, :6])
        HbbInv_gb = np.linalg.solve(Hbb, grad[:, 6:, None])[..., 0]
        grad = grad[:, :6] - np.einsum("pba,pb->pa", H[:, 6:, :6], HbbInv_gb)
        H = H[:, :6, :6] - H[:, :6, 6:] @ HbbInv_Hba
        HbbInv_Hba = (HbbInv_Hba, HbbInv_gb, E)
    vtpv = np.einsum("pn,pn,pn->p", w, g, g)
    return H, grad, vtpv, b, HbbInv_Hba, g * np.sqrt(w)


def _position_propagation(u_i, u_j, mask, R_i, M_i, R_j, M_j, b, sigma_mm, pairs, use, idx,
                          n_unk, position_sigma):
    """Covariance of the angles due to the errors of the EO positions (known-base).

    The estimate solves ``grad(theta, X) = 0``; to first order
    ``d theta = -H^-1 H_tX dX`` with ``H_tX = sum w J^T dg/dX`` and ``dg/dX_j = N = -dg/dX_i``
    (``g = (X_j - X_i) . N``), so the added covariance is ``H^-1 H_tX S_X H_Xt H^-1``.
    Returns ``H_tX S_X H_Xt`` (n_unk, n_unk), to be sandwiched by ``H^-1``.
    """
    r_i = np.einsum("pab,pnb->pna", R_i, u_i)
    r_j = np.einsum("pab,pnb->pna", R_j, u_j)
    _, var, N, A_j = K.condition_terms(r_i, r_j, b, R_i, R_j, sigma_mm)
    A_i = np.cross(r_i, np.cross(r_j, b[:, None, :]))
    w = np.where(mask, 1.0 / np.where(var > 0, var, 1.0), 0.0)
    J = np.concatenate([np.einsum("pna,pak->pnk", A_i, M_i),
                        np.einsum("pna,pak->pnk", A_j, M_j)], axis=2)
    H_tX = np.einsum("pn,pna,pnb->pab", w, J, N)          # (P, 6, 3): d grad / d X_j
    m = len(position_sigma)
    T = np.zeros((n_unk, 3 * m))
    for k in range(len(pairs)):
        sel = use[k]
        ii = idx[k][sel]
        for sign, img in ((-1.0, pairs[k, 0]), (1.0, pairs[k, 1])):
            T[ii, 3 * img:3 * img + 3] += sign * H_tX[k][sel]
    return (T * (position_sigma.ravel() ** 2)[None, :]) @ T.T


def adjust_block(angles_prior, pairs, pair_points, f_mm, system, method="base-free",
                 datum="first", positions=None, prior_sigma=None, sigma_mm=0.005,
                 position_sigma=None, snooping=True, max_iter=30, tol=1e-11, progress=None):
    """Adjust the angles of all images of a block together.

    Parameters
    ----------
    angles_prior : array_like, shape (m, 3)
        INS angles of the images, rad, `system` order, mapping frame.
    pairs : array_like of int, shape (P, 2)
        Image indices (i, j) of the overlapping pairs.
    pair_points : sequence of P tuples (xy_i, xy_j)
        Ideal photo coordinates (n_k, 2) mm of the common tie points of each pair.
    f_mm : float
        Principal distance, mm.
    system : {"phi-omega-kappa", "omega-phi-kappa"}
    method : {"known-base", "relative", "base-free"}
    datum : {"first", "ins", "none"}
    positions : array_like (m, 3), optional
        Exposure positions in the mapping frame, m (required by known-base).
    prior_sigma : array_like (m, 3) or (3,), optional
        Sigma of the INS angles, rad (datum "ins"; default 0.005 rad).
    sigma_mm : float
        A-priori sigma of one photo coordinate, mm.
    position_sigma : array_like (m, 3) or (3,) or float, optional
        Sigma of the EO positions, m (known-base): the bases are still taken as given,
        but their errors are propagated into the angles' covariance (default: exact).
    progress : callable(done, total), optional
        Called after each iteration.

    Returns
    -------
    BlockResult

    Raises
    ------
    InputError
        Unknown method or datum, missing positions, a block whose normal equations are
        singular (a part not connected to the datum).
    """
    check_system(system)
    mode = {"known-base": "known", "relative": "relative", "base-free": "free"}.get(method)
    if mode is None:
        raise InputError(f"--method {method!r}: expected known-base, relative or base-free")
    if datum not in DATUMS:
        raise InputError(f"--datum {datum!r}: expected one of {', '.join(DATUMS)}")
    if datum == "none" and mode != "known":
        raise InputError("--datum none needs --method known-base (the bases orient the block)")
    prior = np.array(angles_prior, dtype=float).reshape(-1, 3)
    m = len(prior)
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    if len(pairs) == 0:
        raise InputError("no overlapping pair with common tie points")
    if len(pair_points) != len(pairs):
        raise ValueError("pair_points must have one entry per pair")
    if mode == "known" and positions is None:
        raise InputError("known-base needs the exposure positions (X_m, Y_m, Z_m)")
    xy_i, xy_j, mask = pad_pairs(pair_points)
    base = None if positions is None else (np.asarray(positions, float)[pairs[:, 1]]
                                           - np.asarray(positions, float)[pairs[:, 0]])
    # pair-wise screening: outliers and failed pairs (image i held at its prior)
    # (base-free: the INS errors of image i and the GNSS base do not enter the tests)
    screen = adjust_pairs(xy_i, xy_j, f_mm, prior[pairs[:, 0]], prior[pairs[:, 1]], system,
                          "base-free", mask=mask, sigma_mm=sigma_mm, snooping=snooping,
                          max_iter=max_iter)
    status = screen["status"]
    if mode == "known":     # 3 or 4 points: no base-free screening, the known base suffices
        few = (status == K.STATUS_TOO_FEW) & (mask.sum(axis=1) >= 3)
        status = np.where(few, K.STATUS_OK, status)
        norm = np.linalg.norm(base, axis=1)
        status = np.where(norm < 1e-9, STATUS_ZERO_BASE, status)
    good = status <= K.STATUS_NOT_CONVERGED
    for k in np.flatnonzero(~good):
        warnings.warn(f"pair {pairs[k, 0]}-{pairs[k, 1]} left out: {STATUS_TEXT[status[k]]}",
                      InputWarning, stacklevel=2)
    mask = screen["mask"] & good[:, None]
    adjusted = np.zeros(m, bool)
    adjusted[pairs[good].ravel()] = True
    for i in np.flatnonzero(~adjusted):
        warnings.warn(f"image {i} has no usable pair: left at its prior angles",
                      InputWarning, stacklevel=2)
    free = adjusted.copy()
    if datum == "first":
        first = int(np.flatnonzero(adjusted)[0]) if adjusted.any() else 0
        free[first] = False
    if prior_sigma is None:
        prior_sigma = np.full((m, 3), 0.005)
    prior_sigma = np.broadcast_to(np.asarray(prior_sigma, float), (m, 3))
    col = -np.ones(m, dtype=int)
    col[free] = np.arange(free.sum())
    n_unk = 3 * int(free.sum())
    angles = prior.copy()
    b = screen["base"].copy() if base is None or mode != "known" else base
    u_i = np.concatenate([xy_i, np.full(xy_i.shape[:2] + (1,), -f_mm)], axis=2)
    u_j = np.concatenate([xy_j, np.full(xy_j.shape[:2] + (1,), -f_mm)], axis=2)
    converged = False
    iterations = 0
    idx = (3 * col[pairs][:, :, None] + np.arange(3)).reshape(-1, 6)       # (P, 6)
    use = (col[pairs] >= 0).repeat(3, axis=1) & good[:, None]
    for it in range(max_iter + 1):
        R, M = K.rotation_and_axes(angles, system)
        H_p, g_p, vtpv, b_new, elim, res = _pair_normals(
            u_i, u_j, mask, R[pairs[:, 0]], M[pairs[:, 0]], R[pairs[:, 1]], M[pairs[:, 1]],
            b, mode, sigma_mm)
        if mode == "free":
            b = b_new
        H = np.zeros((n_unk, n_unk))
        grad = np.zeros(n_unk)
        for k in np.flatnonzero(good):          # assemble (P small blocks, cheap)
            sel = use[k]
            ii = idx[k][sel]
            H[np.ix_(ii, ii)] += H_p[k][np.ix_(sel, sel)]
            grad[ii] += g_p[k][sel]
        vtpv_total = vtpv[good].sum()
        if datum == "ins":
            wgt = 1.0 / prior_sigma[free].ravel() ** 2
            dl = (angles[free] - prior[free]).ravel()
            H[np.diag_indices(n_unk)] += wgt
            grad += wgt * dl
            vtpv_total += np.sum(wgt * dl ** 2)
        if n_unk == 0:
            converged = True
            break
        step, ok = K._solve(H[None], -grad[None])
        if not ok[0]:
            raise InputError("block normal equations are singular: part of the block is not "
                             "connected to the datum image, or the geometry is degenerate "
                             "(try --datum ins)")
        step = step[0]
        if it == max_iter:
            break
        angles[free] += step.reshape(-1, 3)
        if mode == "relative":                  # back-substitute the base directions
            HbbInv_Hba, HbbInv_gb, E = elim
            d_ang = np.append(step, 0.0)[np.where(use, idx, n_unk)]
            d_b = -HbbInv_gb - np.einsum("pab,pb->pa", HbbInv_Hba, d_ang)
            b = b + np.einsum("pab,pb->pa", E, d_b)
            b /= np.linalg.norm(b, axis=1, keepdims=True)
        iterations = it + 1
        if progress is not None:
            progress(iterations, max_iter)
        if np.max(np.abs(step)) < tol:
            converged = True
            break
    n_cond = int(mask.sum())
    n_prior = 3 * int(free.sum()) if datum == "ins" else 0
    redundancy = n_cond + n_prior - n_unk - (0 if mode == "known" else 2 * int(good.sum()))
    if redundancy <= 0:
        raise InputError(f"block has no redundancy ({n_cond} conditions for "
                         f"{n_unk} angles and the base directions)")
    sigma0 = float(np.sqrt(vtpv_total / redundancy))
    cov = np.zeros((3 * m, 3 * m))
    if n_unk:
        fidx = (3 * np.flatnonzero(free)[:, None] + np.arange(3)).ravel()
        Hi = np.linalg.inv(H)
        cov[np.ix_(fidx, fidx)] = sigma0 ** 2 * Hi
        if mode == "known" and position_sigma is not None and np.any(position_sigma):
            ps = np.broadcast_to(np.asarray(position_sigma, float), (m, 3))
            R, M = K.rotation_and_axes(angles, system)
            S = _position_propagation(u_i, u_j, mask, R[pairs[:, 0]], M[pairs[:, 0]],
                                      R[pairs[:, 1]], M[pairs[:, 1]], b, sigma_mm, pairs,
                                      use & good[:, None], idx, n_unk, ps)
            cov[np.ix_(fidx, fidx)] += Hi @ S @ Hi
    for i in np.flatnonzero(~adjusted):
        cov[3 * i:3 * i + 3, 3 * i:3 * i + 3] = np.diag(prior_sigma[i] ** 2)
    if not converged:
        warnings.warn(f"block adjustment did not converge in {max_iter} iterations",
                      InputWarning, stacklevel=2)
    sigma = np.sqrt(np.diag(cov)).reshape(m, 3)
    return BlockResult(angles, cov, sigma, sigma0, int(redundancy), iterations, converged,
                       adjusted, status, screen["rejected"], res * mask, mask)
