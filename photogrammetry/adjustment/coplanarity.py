"""Coplanarity adjustment of the angles of a stereo pair (one pair or thousands at once).

The model frame is the mapping frame ``m``; ``R = C_mc`` of each image takes a photo ray
``(x, y, -f)`` (mm, ideal = undistorted photo coordinates) into it.  Image 1's angles are
held fixed (the "known" image of the coplanarity paper); image 2's three angles are
adjusted.  Methods:

``"known-base"``
    ``det[b, R1 u1, R2 u2] = 0`` per point with the base ``b = X2 - X1`` from the exposure
    positions (GNSS): 3 unknowns, at least 3 points.
``"relative"``
    the same condition with the base direction adjusted too (dependent relative
    orientation): 5 unknowns, at least 5 points.
``"base-free"``
    the angles alone: the base direction is eliminated (it is the unit null vector of the
    stack of the epipolar-plane normals ``N_i = R1 u1_i x R2 u2_i``), the correct form of
    the paper's eqs. (8)-(12) (``conventions.md``, erratum 1).  Reaches the bound of
    ``"relative"``; needs no base at all.  At least 5 points (n - 2 >= 3 conditions).
``"paper"``
    the paper's literal F1/F2 on the triples (1, 2, k) with the pencil coefficient fixed
    to one.  Biased (erratum 1); kept only to show it.

Each condition is weighted by the inverse of its variance propagated from the four photo
coordinates (sigma ``sigma_mm`` each; a condition whose variance is zero or not finite is
refused, InputError naming the pair and point); Gauss-Newton with analytic derivatives;
outliers by Baarda's data snooping on the conditions' normalized residuals.

Failures are stated, never hidden: a pair that failed (too few points, singular normal
equations, zero base) keeps its prior angles with a NaN covariance and its reason; a
pair that did not converge is marked ``converged = False``; with zero redundancy the
variance factor cannot be estimated: ``sigma0`` is NaN and the covariance is the
a-priori one (``sigma0 = 1``), marked by ``sigma0_estimated = False``.

The covariance is the a-priori one scaled by ``max(sigma0, 1)^2``: a sigma0 above 1
says the photo sigma was stated too small, one below 1 is mostly the scatter of its
own estimate at a low redundancy (relative sigma ``1 / sqrt(2 r)``), and scaling by it
made the sigmas of few-point pairs optimistic (cross-strip pairs of 22 points, one
mismatch, base-free: 4.0 % of the true errors beyond the 99 % chi-square point of their
covariance, 1.7 % with the floor; ``tests/test_refine_cli.py``, NGI-like pairs).
"""
import warnings
from dataclasses import dataclass, field

import numpy as np

from ins.common.errors import InputError, QualityWarning
from ins.nav.rotation import skew
from photogrammetry.adjustment import _coplanarity_kernels as K
from photogrammetry.adjustment.robust_start import robust_start
from photogrammetry.orientation.rotation import angles_to_matrix, check_system

__all__ = ["METHODS", "PairResult", "adjust_pair", "adjust_pairs", "paper_adjust",
           "pencil_determinants", "STATUS_TEXT"]

METHODS = ("known-base", "relative", "base-free", "paper")
_MODE = {"known-base": "known", "relative": "relative", "base-free": "free"}
_MIN_POINTS = {"known-base": 3, "relative": 5, "base-free": 5, "paper": 4}
STATUS_ZERO_BASE = 4
STATUS_TEXT = {K.STATUS_OK: "ok", K.STATUS_NOT_CONVERGED: "not converged",
               K.STATUS_SINGULAR: "singular normal equations (collinear or too few points)",
               K.STATUS_TOO_FEW: "too few tie points", STATUS_ZERO_BASE: "zero base"}
#: Critical value of Baarda's w-test (alpha = 0.001, two-sided).
W_CRITICAL = 3.29
#: MSAC threshold of the robust start: |misclosure| / its sigma (a point beyond it is an
#: outlier of a hypothesis; generous, since a minimal-sample hypothesis is noisier than
#: the adjusted solution and data snooping follows on the converged one).
MSAC_THRESHOLD = 5.0
#: A minimal-sample hypothesis farther than this from the prior (rad, any angle) is
#: discarded (5 deg: beyond any plausible INS error; the trust rule flags far less).
MAX_CHANGE = np.deg2rad(5.0)


@dataclass
class PairResult:
    """Adjusted angles of image 2 of one pair.

    Attributes
    ----------
    angles : ndarray (3,)
        Image 2's angles (rad, system order).
    cov : ndarray (3, 3)
        A-posteriori covariance of the angles, rad^2 (``max(sigma0, 1)^2 Q``; ``Q``
        alone, the a-priori covariance, when ``sigma0_estimated`` is False).
    sigma : ndarray (3,)
        Per-angle standard deviations, rad.
    base : ndarray (3,) or None
        Unit base direction in the model frame (the given one for known-base).
    sigma0 : float
        A-posteriori standard deviation of unit weight (1 = the a-priori sigma); NaN
        when the redundancy is zero (not estimable).
    redundancy : int
    iterations : int
    status : str
        ``"ok"`` or ``"not converged"`` (a failed pair raises, see :func:`adjust_pair`).
    rejected : ndarray of int
        Indices of the points rejected as outliers.
    converged : bool
    sigma0_estimated : bool
        False when the redundancy is zero: ``cov`` is then the a-priori covariance.
    """
    angles: np.ndarray
    cov: np.ndarray
    sigma: np.ndarray
    base: np.ndarray
    sigma0: float
    redundancy: int
    iterations: int
    status: str
    rejected: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    converged: bool = True
    sigma0_estimated: bool = True


def _stack_rays(xy, f_mm, name):
    xy = np.asarray(xy, dtype=float)
    if xy.ndim != 3 or xy.shape[2] != 2:
        raise InputError(f"{name}: photo coordinates must have shape (pairs, points, 2) mm, "
                         f"got {xy.shape}")
    f = np.broadcast_to(np.asarray(f_mm, dtype=float).reshape(-1, 1, 1), xy.shape[:2] + (1,))
    return np.concatenate([xy, -f], axis=2)


def _normalized_residuals(out):
    """Baarda's w (a-priori sigma) of every condition, 0 where not used."""
    J, Q, w, g, var = out["J"], out["Q"], out["w"], out["g"], out["var"]
    h = w * np.einsum("pni,pij,pnj->pn", J, Q, J)          # hat-matrix diagonal
    r = 1.0 - h
    ok = (w > 0) & (r > 1e-3)
    wt = np.zeros_like(g)
    wt[ok] = np.abs(g[ok]) / np.sqrt(var[ok] * r[ok])
    return wt


def adjust_pairs(xy1_mm, xy2_mm, f_mm, angles1, angles2, system, method="base-free",
                 base=None, mask=None, sigma_mm=0.005, snooping=True,
                 w_critical=W_CRITICAL, max_reject=0.3, max_iter=30, robust=True,
                 msac_threshold=MSAC_THRESHOLD, seed=0, max_change=MAX_CHANGE, essential=True):
    """Adjust image 2's angles of many pairs at once (vectorized).

    Parameters
    ----------
    xy1_mm, xy2_mm : array_like, shape (P, n, 2)
        Ideal (undistorted) photo coordinates of the tie points in image 1 and 2, mm;
        pairs with fewer points are padded and ``mask`` marks the real ones.
    f_mm : float or array_like (P,)
        Principal distance, mm.
    angles1, angles2 : array_like, shape (P, 3)
        Image 1's (fixed) and image 2's (prior) angles, rad, in `system`'s order.
    system : {"phi-omega-kappa", "omega-phi-kappa"}
    method : {"known-base", "relative", "base-free", "paper"}
    base : array_like, shape (P, 3), optional
        ``X2 - X1`` in the mapping frame, m; required for known-base, the initial
        direction for relative (default: the base-free estimate).
    mask : array_like of bool, shape (P, n), optional
    sigma_mm : float
        A-priori sigma of one photo coordinate, mm.
    snooping : bool
        Reject outliers by data snooping (one per pair and round, largest w first, while
        w > `w_critical`, at most `max_reject` of a pair's points).
    robust : bool
        Robust start (default): minimal samples solved exactly from the prior and scored
        by MSAC (:mod:`photogrammetry.adjustment._msac_kernels`; normalized misclosure threshold
        `msac_threshold`, random samples seeded by `seed`), Gauss-Newton from the winner
        on its inliers, every point re-classified at that solution (``|g| / sigma_g <
        msac_threshold``), Gauss-Newton again, THEN data snooping.  The result and the
        rejected set then do not depend on the prior within its basin (a few tenths of a
        degree).  ``False``: Gauss-Newton from the prior on all points, then snooping
        (also what a pair with fewer than twice the sample's points gets: 10, or 6 with
        a known base).
    max_change : float
        Rad; a minimal-sample hypothesis farther than this from the prior is discarded.
    essential : bool
        With the robust start, also a start that does not depend on the prior: the
        five-point essential matrix by RANSAC (USAC_MAGSAC) on the normalized image
        coordinates and its pose (:mod:`photogrammetry.adjustment.essential`), tried
        where the MSAC winner holds less than
        :data:`photogrammetry.adjustment.robust_start.ESSENTIAL_BELOW` of the points (or
        MSAC found nothing); it replaces the winner when its MSAC cost is lower and it
        lies within `max_change` of the prior.  Pairs that have fewer inliers than
        their unknowns are still refused (status "too few tie points").

    Returns
    -------
    dict of arrays: ``angles`` (P, 3), ``cov`` (P, 3, 3) rad^2, ``sigma`` (P, 3),
    ``base`` (P, 3) unit, ``sigma0`` (P,), ``redundancy``, ``iterations``, ``status``
    (ints, see :data:`STATUS_TEXT`), ``reason`` (P,) its text, ``converged`` (P,) bool,
    ``failed`` (P,) bool (status above "not converged": the prior angles are returned,
    with NaN ``cov``, ``sigma`` and ``sigma0``, never a zero covariance),
    ``sigma0_estimated`` (P,) bool (False at zero redundancy: ``sigma0`` NaN and ``cov``
    the a-priori ``Q``), ``rejected`` (P, n) bool, ``mask`` (P, n) final, ``vtpv`` (P,),
    ``robust_rejected`` (P, n) bool (rejected by the robust start, a subset of
    ``rejected``), ``hypotheses`` (P,) drawn by MSAC (0 without the robust start).

    Raises
    ------
    InputError
        Unknown method, ``sigma_mm`` not > 0, a missing base for known-base, or a
        condition with zero or non-finite variance (names the pair and point).
    """
    check_system(system)
    if not (np.isfinite(sigma_mm) and sigma_mm > 0):
        raise InputError(f"sigma_mm: the photo-coordinate sigma must be > 0 mm, got {sigma_mm}")
    if method not in METHODS:
        raise InputError(f"method {method!r}: expected one of {', '.join(METHODS)}")
    u1, u2 = _stack_rays(xy1_mm, f_mm, "xy1_mm"), _stack_rays(xy2_mm, f_mm, "xy2_mm")
    P, n = u1.shape[:2]
    mask_in = mask
    mask = np.ones((P, n), bool) if mask is None else np.array(mask, dtype=bool, copy=True)
    angles1 = np.asarray(angles1, dtype=float).reshape(P, 3)
    angles2 = np.asarray(angles2, dtype=float).reshape(P, 3)
    prior_in = angles2
    R1 = angles_to_matrix(angles1, system)
    if method == "paper":
        return paper_adjust(u1, u2, mask, R1, angles2, system, sigma_mm, max_iter)
    mode = _MODE[method]
    if base is None:
        if mode == "known":
            raise InputError("known-base needs the base vectors (exposure positions)")
        base = np.tile([1.0, 0.0, 0.0], (P, 1))
        if mode == "relative":
            base = _base_free_direction(u1, u2, mask, R1, angles2, system)
    base = np.asarray(base, dtype=float).reshape(P, 3)
    zero = np.linalg.norm(base, axis=1) < 1e-9 if mode != "free" else np.zeros(P, bool)
    rejected = np.zeros((P, n), bool)
    hypotheses = np.zeros(P, dtype=int)
    if robust:
        angles2, base, mask, hypotheses = robust_start(
            u1, u2, mask, R1, angles2, np.where(zero[:, None], 1.0, base), mode, system,
            sigma_mm, msac_threshold, seed, max_change, max_iter, essential)
        rejected = ~mask & _stack_mask(xy1_mm, mask_in)
    robust_rejected = rejected.copy()
    n_snooped = np.zeros(P, dtype=int)
    todo = np.arange(P)
    out = None
    while True:
        part = K.solve_pairs(u1[todo], u2[todo], mask[todo], R1[todo], angles2[todo],
                             np.where(zero[todo, None], 1.0, base[todo]), mode, system,
                             sigma_mm, max_iter)
        out = part if out is None else _merge(out, part, todo)
        if not snooping:
            break
        wt = _normalized_residuals(part)
        worst = np.argmax(wt, axis=1)
        n_used = mask[todo].sum(axis=1)
        cap = np.floor(max_reject * (n_used + n_snooped[todo]))
        flag = ((wt[np.arange(len(todo)), worst] > w_critical) & (part["status"] <= 1)
                & (n_used - 1 > _MIN_POINTS[method]) & (n_snooped[todo] < cap))
        if not flag.any():
            break
        todo, worst = todo[flag], worst[flag]
        mask[todo, worst] = False
        rejected[todo, worst] = True
        n_snooped[todo] += 1
    status = np.where(zero, STATUS_ZERO_BASE, out["status"])
    res = _finish(out, status, prior_in, mask, rejected)
    res["robust_rejected"] = robust_rejected
    res["hypotheses"] = hypotheses
    return res


def _stack_mask(xy, mask_in):
    """The caller's mask (all points when None) as a (P, n) bool array."""
    shape = np.shape(xy)[:2]
    return np.ones(shape, bool) if mask_in is None else np.asarray(mask_in, bool)


def _merge(out, part, idx):
    for key, value in part.items():
        out[key][idx] = value
    return out


def _finish(out, status, prior2, mask, rejected):
    good = status <= K.STATUS_NOT_CONVERGED
    r = out["redundancy"] * good
    estimated = good & (r > 0)
    # zero redundancy: no variance factor; the covariance is the a-priori one (s0 = 1)
    s0sq = np.where(estimated, out["vtpv"] / np.maximum(r, 1), 1.0)
    # the covariance is scaled by max(sigma0, 1)^2: a sigma0 below 1 is the scatter of
    # its estimate (redundancy 16: +-18 %), not a better photo sigma (module docstring)
    cov = np.maximum(s0sq, 1.0)[:, None, None] * out["Q"][:, :3, :3]
    cov[~good] = np.nan                     # failed: no estimate, no covariance
    angles = np.where(good[:, None], out["angles"], prior2)
    return {"angles": angles, "cov": cov, "sigma": np.sqrt(np.einsum("pii->pi", cov)),
            "base": out["base"], "sigma0": np.where(estimated, np.sqrt(s0sq), np.nan),
            "sigma0_estimated": estimated, "redundancy": r,
            "iterations": out["iterations"], "status": status,
            "reason": np.array([STATUS_TEXT[int(k)] for k in status], dtype=object),
            "converged": status == K.STATUS_OK, "failed": ~good, "rejected": rejected,
            "mask": mask, "vtpv": out["vtpv"] * good}


def _base_free_direction(u1, u2, mask, R1, angles2, system):
    """Unit base direction from the prior angles (null vector of the N stack, cheirality)."""
    R2 = angles_to_matrix(angles2, system)
    r1 = np.einsum("pij,pnj->pni", R1, u1)
    r2 = np.einsum("pij,pnj->pni", R2, u2)
    b = K.smallest_direction(np.cross(r1, r2), mask.astype(float))
    # cheirality: X = l1 r1 = b + l2 r2 with l1 > 0 for most points
    c = np.einsum("pni,pni->pn", r1, r2)
    a11, a22 = np.einsum("pni,pni->pn", r1, r1), np.einsum("pni,pni->pn", r2, r2)
    l1 = (a22 * np.einsum("pni,pi->pn", r1, b) - c * np.einsum("pni,pi->pn", r2, b))
    l1 /= np.where(a11 * a22 - c * c > 0, a11 * a22 - c * c, 1.0)
    sign = np.where(np.sum(np.sign(l1) * mask, axis=1) < 0, -1.0, 1.0)
    return b * sign[:, None]


def adjust_pair(xy1_mm, xy2_mm, f_mm, angles1, angles2, system, method="base-free",
                base=None, sigma_mm=0.005, snooping=True, **options):
    """Adjust image 2's angles of one pair; see :func:`adjust_pairs`.

    Parameters
    ----------
    xy1_mm, xy2_mm : array_like, shape (n, 2)
        Ideal photo coordinates, mm.
    angles1, angles2 : array_like, shape (3,)
        Rad, `system` order.
    base : array_like (3,), optional
        ``X2 - X1``, m.

    Returns
    -------
    PairResult

    Raises
    ------
    InputError
        Too few points for the method, a zero base, or singular geometry (collinear
        points), a condition with zero variance.

    Warns
    -----
    ins.common.errors.QualityWarning
        Not converged (``converged`` False: the last iterate), or no redundancy
        (``sigma0`` NaN, ``sigma0_estimated`` False: the covariance is the a-priori one).
    """
    xy1, xy2 = np.asarray(xy1_mm, float), np.asarray(xy2_mm, float)
    if xy1.ndim != 2 or xy1.shape != xy2.shape or xy1.shape[1] != 2:
        raise InputError(f"photo coordinates must be two (n, 2) arrays in mm, got "
                         f"{xy1.shape} and {xy2.shape}")
    if len(xy1) < _MIN_POINTS.get(method, 0):
        raise InputError(f"{method} needs at least {_MIN_POINTS[method]} tie points, "
                         f"got {len(xy1)}")
    res = adjust_pairs(xy1[None], xy2[None], f_mm, np.reshape(angles1, (1, 3)),
                       np.reshape(angles2, (1, 3)), system, method,
                       None if base is None else np.reshape(base, (1, 3)),
                       sigma_mm=sigma_mm, snooping=snooping, **options)
    status = int(res["status"][0])
    if status >= K.STATUS_SINGULAR:
        raise InputError(f"pair adjustment failed: {STATUS_TEXT[status]}")
    if status == K.STATUS_NOT_CONVERGED:
        warnings.warn("pair adjustment did not converge: the angles are the last iterate "
                      "and their covariance is not to be trusted", QualityWarning,
                      stacklevel=2)
    estimated = bool(res["sigma0_estimated"][0])
    if not estimated:
        warnings.warn("pair adjustment has no redundancy: sigma0 is not estimable (NaN); "
                      "the covariance is the a-priori one (sigma0 = 1)", QualityWarning,
                      stacklevel=2)
    return PairResult(res["angles"][0], res["cov"][0], res["sigma"][0], res["base"][0],
                      float(res["sigma0"][0]), int(res["redundancy"][0]),
                      int(res["iterations"][0]), STATUS_TEXT[status],
                      np.flatnonzero(res["rejected"][0]), status == K.STATUS_OK, estimated)


def pencil_determinants(r1, r2, triples):
    """``det[N_i, N_j, N_k]`` of the epipolar-plane normals (zero for a correct orientation).

    Parameters
    ----------
    r1, r2 : ndarray, shape (n, 3)
        Model-frame rays of the tie points in image 1 and 2.
    triples : array_like of int, shape (m, 3)

    Returns
    -------
    ndarray (m,), normalized by the product of the normals' lengths (a sine-like number).
    """
    N = np.cross(r1, r2)
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    t = np.asarray(triples)
    return np.linalg.det(np.stack([N[t[:, 0]], N[t[:, 1]], N[t[:, 2]]], axis=1))


def _paper_terms(r1, r2, mask):
    """The paper's F1, F2 on triples (0, 1, k) and their derivatives by a small rotation of
    image 2 (model frame)."""
    N = np.cross(r1, r2)                                        # (P, n, 3): (A, B, C)
    dN = -np.einsum("pnij,pnjk->pnik", skew(r1.reshape(-1, 3)).reshape(r1.shape + (3,)),
                    skew(r2.reshape(-1, 3)).reshape(r2.shape + (3,)))
    Na, Nc, Nk = N[:, :1], N[:, 1:2], N[:, 2:]
    dNa, dNc, dNk = dN[:, :1], dN[:, 1:2], dN[:, 2:]
    F, dF = [], []
    for j in (1, 2):                                             # B (F1) and C (F2)
        F.append((Nk[..., 0] - Na[..., 0]) * Nc[..., j] - (Nk[..., j] - Na[..., j]) * Nc[..., 0])
        dF.append((dNk[..., 0, :] - dNa[..., 0, :]) * Nc[..., j, None]
                  + (Nk[..., 0, None] - Na[..., 0, None]) * dNc[..., j, :]
                  - (dNk[..., j, :] - dNa[..., j, :]) * Nc[..., 0, None]
                  - (Nk[..., j, None] - Na[..., j, None]) * dNc[..., 0, :])
    w = np.repeat(mask[:, 2:].astype(float), 2, axis=1)
    return np.concatenate(F, axis=1), np.concatenate(dF, axis=1), w


def paper_adjust(u1, u2, mask, R1, angles2, system, sigma_mm=0.005, max_iter=30, tol=1e-11):
    """The paper's literal eqs. (12)-(15): F1 = F2 = 0 on the triples (1, 2, k).

    Unweighted Gauss-Newton on image 2's angles.  Biased (``conventions.md``, erratum 1):
    kept to demonstrate it.  Same inputs and outputs as :func:`adjust_pairs` (rays); the
    covariance, sigmas and sigma0 are NaN (not estimated).
    """
    P = len(u1)
    angles = np.array(angles2, dtype=float, copy=True)
    r1 = np.einsum("pij,pnj->pni", R1, u1)
    status = np.where(mask.sum(axis=1) < 4, K.STATUS_TOO_FEW, K.STATUS_NOT_CONVERGED)
    active = status == K.STATUS_NOT_CONVERGED
    iterations = np.zeros(P, dtype=int)
    for it in range(max_iter):
        R2, M2 = K.rotation_and_axes(angles, system)
        r2 = np.einsum("pij,pnj->pni", R2, u2)
        F, dF, w = _paper_terms(r1, r2, mask)
        J = np.einsum("pmi,pij->pmj", dF, M2)
        H = np.einsum("pm,pmi,pmj->pij", w, J, J)
        step, ok = K._solve(H, -np.einsum("pm,pmi,pm->pi", w, J, F))
        status[active & ~ok] = K.STATUS_SINGULAR
        active &= ok
        step[~active] = 0.0
        angles += step
        iterations += active
        done = active & (np.max(np.abs(step), axis=1) < tol)
        status[done] = K.STATUS_OK
        active &= ~done
        if not active.any():
            break
    good = status <= K.STATUS_NOT_CONVERGED
    # unweighted and biased: no covariance, no variance factor (NaN, never zero)
    return {"angles": np.where(good[:, None], angles, angles2),
            "cov": np.full((P, 3, 3), np.nan), "sigma": np.full((P, 3), np.nan),
            "base": np.zeros((P, 3)), "sigma0": np.full(P, np.nan),
            "sigma0_estimated": np.zeros(P, bool),
            "redundancy": np.maximum(2 * (mask.sum(axis=1) - 2) - 3, 0), "iterations": iterations,
            "status": status,
            "reason": np.array([STATUS_TEXT[int(k)] for k in status], dtype=object),
            "converged": status == K.STATUS_OK, "failed": ~good,
            "rejected": np.zeros(mask.shape, bool), "mask": mask, "vtpv": np.zeros(P)}
