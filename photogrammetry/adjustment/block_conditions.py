"""The coplanarity conditions of a block, their weights and Jacobian (:mod:`photogrammetry.adjustment.block`).

One condition per tie point and pair, ``det[b, R_i u_i, R_j u_j] = 0``; the conditions of
one tie point seen in k >= 3 images share its photo coordinates and are weighted
together by the pseudo-inverse of their joint covariance (the block's docstring says why).
"""
import warnings
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse.linalg import splu

from ins.common.errors import InputError, InputWarning
from photogrammetry.adjustment import _coplanarity_kernels as K
from photogrammetry.adjustment._pair_kernels import block_condition_terms

__all__ = ["pad_pairs"]


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


def _condition_index(pairs, mask, point_ids, m):
    """The conditions (used tie points of the good pairs) grouped by tie point.

    Returns
    -------
    p, s : ndarray of int (C,)
        Pair and slot (point index in the pair) of every condition.
    obs : ndarray of int (C, 2)
        Ids of the two observations (image, point) of every condition; equal ids are the
        same photo coordinates (shared by the conditions of a point seen in 3+ images).
    buckets : list of ndarray of int (T, c)
        Condition indices, one row per tie point with c conditions (one array per c).
    """
    p, s = np.nonzero(mask)
    C = len(p)
    if point_ids is None:                     # every condition on its own (no ids given)
        group, obs = np.arange(C), np.arange(2 * C).reshape(C, 2)
    else:
        codes = {}
        group = np.fromiter((codes.setdefault(point_ids[a][b], len(codes))
                             for a, b in zip(p, s)), dtype=np.int64, count=C)
        obs = group[:, None] * m + pairs[p]
    order = np.argsort(group, kind="stable")
    _, start, size = np.unique(group[order], return_index=True, return_counts=True)
    buckets = [order[start[size == c][:, None] + np.arange(c)] for c in np.unique(size)]
    return p, s, obs, buckets


def _csr_pattern(rows, cols, shape, kept):
    """CSR structure of the entries ``(rows, cols)`` (no two equal) and where each
    entry's value goes, made once and kept in the dict `kept` (the conditions' cache:
    the same pattern at every Gauss-Newton iteration); the values set by
    ``data = vals[src]`` are those of ``csr_matrix((vals, (rows, cols)))``."""
    if "src" not in kept:
        P = sparse.csr_matrix((np.arange(len(rows), dtype=float), (rows, cols)), shape=shape)
        kept.update(src=P.data.astype(np.int64), indices=P.indices, indptr=P.indptr,
                    shape=shape)
    return kept


def _csr(vals, kept):
    return sparse.csr_matrix((vals[kept["src"]], kept["indices"].copy(), kept["indptr"].copy()),
                             shape=kept["shape"])


def _joint_weights(buckets, obs, d, s2, n_cond, tol, pattern=None):
    """Weight matrix of the conditions: per tie point the pseudo-inverse of the joint
    covariance of its conditions.

    ``Sigma_ab = s2 * sum over the observations o shared by conditions a and b of
    d_a,o . d_b,o``; the pseudo-inverse is taken of the correlation matrix (scale-free),
    dropping eigenvalues below `tol` times the largest (combinations of the conditions
    that the observations do not move: repeated conditions).

    Parameters
    ----------
    d : ndarray (C, 2, 2)
        Derivative of every condition by the (x, y) of its two observations.
    s2 : float
        Variance of one photo coordinate, mm^2.

    pattern : dict, optional
        Kept for the next call with the same `buckets` (the CSR structure of ``W``).

    Returns
    -------
    W : scipy.sparse.csr_matrix (C, C); rank : int (independent conditions);
    var : ndarray (C,) variance of each condition.
    """
    var = s2 * np.einsum("cij,cij->c", d, d)
    rows, cols, vals, rank = [], [], [], 0
    obs = np.ascontiguousarray(obs, dtype=np.int64)
    d = np.ascontiguousarray(d, dtype=float)
    for idx in buckets:
        c = idx.shape[1]
        if c == 1:                          # a condition on its own: 1 / its variance
            v = var[idx[:, 0]]
            keep = v > 0
            rank += int(keep.sum())
            vals.append(np.where(keep, 1.0 / np.where(keep, v, 1.0), 0.0))
        else:                               # compiled: per tie point a c x c eigh
            Wt, r = K.joint_weight_blocks(np.ascontiguousarray(idx, dtype=np.int64), obs, d,
                                          float(s2), float(tol))
            rank += int(r)
            vals.append(Wt.ravel())
        if pattern is None or "src" not in pattern:
            rows.append(np.repeat(idx, c, axis=1).ravel())
            cols.append(np.tile(idx, (1, c)).ravel())
    vals = np.concatenate(vals)
    if pattern is None:
        W = sparse.csr_matrix((vals, (np.concatenate(rows), np.concatenate(cols))),
                              shape=(n_cond, n_cond))
    else:
        if "src" not in pattern:
            _csr_pattern(np.concatenate(rows), np.concatenate(cols), (n_cond, n_cond),
                         pattern)
        W = _csr(vals, pattern)
    return W, rank, var


def _condition_terms(U, img, bp, R, M, b):
    """Per condition: misclosure g (C,), d (C, 2, 2) by the photo coordinates, the
    Jacobian rows by the angles of the two images (C, 6) and ``N`` (C, 3) = dg/db
    (compiled, one pass: :func:`photogrammetry.adjustment._pair_kernels.block_condition_terms`,
    its sums in the order of the numpy expressions it replaced, equal to them bit for
    bit on the 470-image simulated block)."""
    c = np.ascontiguousarray
    return block_condition_terms(c(U, dtype=float), c(img, dtype=np.int64),
                                 c(bp, dtype=np.int64), c(R, dtype=float),
                                 c(M, dtype=float), c(b, dtype=float))


@dataclass
class _Conditions:
    """The coplanarity conditions (one per used tie point of a good pair) and the two
    groupings of their weights: joint per tie point, and one by one."""
    p: np.ndarray           # (C,) pair of every condition
    s: np.ndarray           # (C,) slot (point index in the pair)
    img: np.ndarray         # (C, 2) the two images
    U: np.ndarray           # (C, 2, 3) rays in the two images, mm
    obs: np.ndarray         # joint grouping (see _condition_index)
    buckets: list
    obs_1: np.ndarray       # one by one
    buckets_1: list
    kept: dict = None       # CSR patterns of the weights and the Jacobian (per iteration)

    def __post_init__(self):
        self.kept = {} if self.kept is None else self.kept


def _conditions(pairs, mask, point_ids, m, xy_i, xy_j, f_mm):
    """Index the conditions of the kept points and build their rays."""
    p_c, s_c, obs, buckets = _condition_index(pairs, mask, point_ids, m)
    obs_1, buckets_1 = _condition_index(pairs, mask, None, m)[2:]
    U = np.stack([np.concatenate([xy[p_c, s_c], np.full((len(p_c), 1), -f_mm)], axis=1)
                  for xy in (xy_i, xy_j)], axis=1)
    return _Conditions(p_c, s_c, pairs[p_c], U, obs, buckets, obs_1, buckets_1)


def _check_variance(var, cond, point_ids, sigma_mm):
    """Refuse a condition of zero or non-finite variance, naming its pair and tie point."""
    if np.all(var > 0):
        return
    c = int(np.flatnonzero(~(var > 0))[0])
    pid = int(cond.s[c]) if point_ids is None else point_ids[cond.p[c]][cond.s[c]]
    pid = pid.item() if isinstance(pid, np.generic) else pid
    raise InputError(f"pair {cond.img[c, 0]}-{cond.img[c, 1]}, tie point {pid!r}: the "
                     f"coplanarity condition has variance {float(var[c])!r} (photo "
                     f"sigma {float(sigma_mm)!r} mm); a zero or non-finite variance "
                     "has no weight")


def _jacobian(J_ang, NE, img, bp, col, n_ang, n_cols, pattern=None):
    """Sparse Jacobian (C, n_cols): angles of the free images, then 2 base parameters
    per pair (``NE``, or none for known-base); `pattern` (dict) keeps its CSR structure
    for the next call with the same conditions."""
    C = len(img)
    cols = (3 * col[img][:, :, None] + np.arange(3)).reshape(C, 6)
    ok = np.repeat(col[img] >= 0, 3, axis=1)
    data = J_ang
    if NE is not None:
        cols = np.concatenate([cols, n_ang + 2 * bp[:, None] + np.arange(2)], axis=1)
        ok = np.concatenate([ok, np.ones((C, 2), bool)], axis=1)
        data = np.concatenate([J_ang, NE], axis=1)
    if pattern is not None and "src" in pattern:
        return _csr(data[ok], pattern)
    rows = np.broadcast_to(np.arange(C)[:, None], cols.shape)
    if pattern is not None:
        return _csr(data[ok], _csr_pattern(rows[ok], cols[ok], (C, n_cols), pattern))
    return sparse.csr_matrix((data[ok], (rows[ok], cols[ok])), shape=(C, n_cols))


def _reduced_normals(H, grad, n_ang):
    """Eliminate the base parameters (Schur complement): returns the angles' normal
    matrix S (dense), right-hand side and the back-substitution ``(X, y)`` with
    ``d_b = -(y + X d_a)`` (None for known-base)."""
    H_aa = H[:n_ang, :n_ang].toarray()
    if H.shape[0] == n_ang:
        return H_aa, -grad, None
    try:
        lu = splu(H[n_ang:, n_ang:].tocsc())
    except RuntimeError:
        raise InputError("block normal equations are singular: a pair's base direction is "
                         "not determined") from None
    H_ab = H[:n_ang, n_ang:].toarray()
    X = lu.solve(np.ascontiguousarray(H_ab.T))
    y = lu.solve(grad[n_ang:])
    return H_aa - H_ab @ X, -(grad[:n_ang] - H_ab @ y), (X, y)


def _free_images(pairs, good, m, datum):
    """Images that take part (`adjusted`: in a good pair) and whose angles are unknowns
    (`free`: adjusted, less the datum image of ``"first"``); warns of the images left out."""
    adjusted = np.zeros(m, bool)
    adjusted[pairs[good].ravel()] = True
    for i in np.flatnonzero(~adjusted):
        warnings.warn(f"image {i} has no usable pair: left at its prior angles",
                      InputWarning, stacklevel=3)
    free = adjusted.copy()
    if datum == "first":
        first = int(np.flatnonzero(adjusted)[0]) if adjusted.any() else 0
        free[first] = False
    return adjusted, free
