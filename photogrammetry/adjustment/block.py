"""Block adjustment of exposure angles from the coplanarity of every overlapping pair.

Unknowns: the three angles of every image (rad, in the named system; ``R = C_mc``), and,
for the ``relative``/``base-free`` methods, the base direction of every pair (two
nuisance parameters each, eliminated by the Schur complement; the two methods give the
same estimate in a block).  One condition per tie point and pair,
``det[b, R_i u_i, R_j u_j] = 0``.

Weights: a point seen in k >= 3 images enters k(k-1)/2 pairs whose conditions share its
photo coordinates, so they are correlated; along a strip the centres are nearly in line
and the conditions of (i, j), (j, k), (i, k) nearly repeat each other (three epipolar
planes through one line of centres coincide).  With the tie-point ids the conditions of
one point are weighted together by the pseudo-inverse of their joint covariance,
propagated from the shared photo coordinates (``sigma_mm`` each); combinations of them
that the observations hardly move (eigenvalue of the correlation matrix below
:data:`RANK_TOL` times the largest) are dropped as repetitions and the redundancy counts
the independent conditions.  This keeps all pairs (no choice of k - 1 pairs per point,
which would leave the pairs (i, i+2) of a strip without conditions) and is consistent
for any threshold (``W Sigma W = W``, so the covariance ``(J^T W J)^-1`` is that of the
estimate); the threshold (per method, see :data:`RANK_TOL`) trades efficiency for
robustness against the nonlinear, geometry-made combinations.  The bases of the relative
methods start from each pair's screening (image i at its INS angles): the iterations
weight the conditions one by one until the steps are small, then jointly.  Without ids
each condition is weighted on its own (the covariance is then optimistic by about 1.2x
in sigma on the blocks of ``tests/scenario.py``: chi-square per angle 1.3-1.6).

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
from scipy import sparse

from ins.common.errors import InputError, InputWarning, QualityWarning
from ins.nav.rotation import wrap_to_pi
from photogrammetry.adjustment import _coplanarity_kernels as K
from photogrammetry.adjustment import cholmod
from photogrammetry.adjustment.banded import BandedSPD, SparseSPD
from photogrammetry.adjustment.block_conditions import (
    _check_variance,
    _condition_terms,
    _conditions,
    _free_images,
    _jacobian,
    _joint_weights,
    _reduced_normals,
    pad_pairs,
)
from photogrammetry.adjustment.block_covariance import _position_cov, banded_covariance
from photogrammetry.adjustment.coplanarity import (
    MAX_CHANGE,
    STATUS_TEXT,
    STATUS_ZERO_BASE,
    adjust_pairs,
)
from photogrammetry.adjustment.quality import block_quality, unadjusted_quality
from photogrammetry.orientation.rotation import check_system

__all__ = ["BlockResult", "adjust_block", "pad_pairs", "DATUMS"]

DATUMS = ("first", "ins", "none")
#: Relative eigenvalue (of a tie point's condition correlation matrix) below which a
#: combination of its conditions counts as a repetition and is dropped, per method.  With
#: known bases the nearly repeated combination of a strip triple is the transfer of scale
#: along the strip: weak in the observations and in the angles alike (the centres' offset
#: from a line, squared, ~1e-4 here), informative (pitch) and well behaved down to ~1e-8;
#: 1e-4 keeps most of it.  With a base-direction nuisance per pair it ties the nuisances
#: of the triple together at full strength: nonlinear, Gauss-Newton diverges below ~1e-4.
RANK_TOL = {"known": 1e-4, "relative": 1e-2, "free": 1e-2}
#: Critical value of the block's data snooping on ``|g| / sigma_g`` (alpha = 6e-5 per
#: condition): the second line after each pair's own (robust start and w-test at
#: :data:`photogrammetry.adjustment.coplanarity.W_CRITICAL`), for the outliers a pair cannot see
#: alone (too few points of its own); the block tests hundreds of conditions per round.
BLOCK_W_CRITICAL = 4.0
#: ``algebra="auto"``: blocks with at least this many free angles are solved with the
#: sparse normal matrix (banded Cholesky; relative methods: the bordered matrix of angles
#: and bases, sparse LU) and keep their covariance as an operator
#: (:mod:`photogrammetry.adjustment.block_covariance`; ``cov`` is then None), smaller ones with the
#: dense reduced normal matrix.
BANDED_MIN_ANGLES = 300
ALGEBRAS = ("auto", "dense", "banded")
#: Internal screening status: the pair's screening moved image j beyond MAX_CHANGE
#: (reported as "not converged" in ``pair_status``, flagged by the quality rule).
STATUS_STRAYED = 7


@dataclass
class BlockResult:
    """Adjusted angles of a block.

    Attributes
    ----------
    angles : ndarray (m, 3)
        Rad, system order, mapping frame; the prior for images that were not adjusted.
    cov : ndarray (3m, 3m) or None
        A-posteriori covariance of all angles (image-major), rad^2, scaled by
        ``max(sigma0, 1)^2``; None for a block solved with the banded algebra (see
        `cov_op` and :meth:`cov_blocks`).
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
        Per pair, see :data:`photogrammetry.adjustment.coplanarity.STATUS_TEXT`; every pair not
        ``0`` ("ok", including "not converged" in the pair-wise screening) was left out
        with a warning.
    rejected : ndarray of bool (P, n)
        Tie points rejected by data snooping (pair-wise, before the block adjustment).
    residuals : ndarray (P, n)
        Normalized misclosures ``g / sqrt(var)`` at the solution (0 where not used).
    quality : photogrammetry.adjustment.quality.Quality
        Trust flags: pairs and images whose sigma0 or angle change is implausible
        (the rule in :mod:`photogrammetry.adjustment.quality`).
    cov_op : photogrammetry.adjustment.block_covariance.BandedCovariance or None
        The free images' covariance as an operator (banded algebra only).
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
    quality: object = None
    cov_op: object = field(repr=False, default=None)

    def cov_blocks(self):
        """The 3x3 covariance block of every image (m, 3, 3), rad^2 (0 for the datum
        image, the prior's for images left out)."""
        m = len(self.angles)
        if self.cov is not None:
            return np.stack([self.cov[3 * i:3 * i + 3, 3 * i:3 * i + 3] for i in range(m)])
        out = np.zeros((m, 3, 3))
        out[self.cov_op.free] = self.cov_op.blocks
        idx = np.flatnonzero(~self.adjusted)
        out[idx] = np.einsum("ia,ab->iab", self.sigma[idx] ** 2, np.eye(3))
        return out

    def correlation(self):
        """Correlation matrix of all angles (3m, 3m); 0 rows for fixed images (dense
        covariance only: see :meth:`cov_blocks` for a banded block)."""
        if self.cov is None:
            raise ValueError("the block's covariance is kept as an operator (banded "
                             "algebra): use cov_blocks() or cov_op")
        s = np.sqrt(np.diag(self.cov))
        inv = np.where(s > 0, 1.0 / np.where(s > 0, s, 1.0), 0.0)
        return self.cov * inv[:, None] * inv[None, :]


def _check_options(system, method, datum):
    """The internal mode of `method` ("known", "relative", "free"), the options checked."""
    check_system(system)
    mode = {"known-base": "known", "relative": "relative", "base-free": "free"}.get(method)
    if mode is None:
        raise InputError(f"--method {method!r}: expected known-base, relative or base-free")
    if datum not in DATUMS:
        raise InputError(f"--datum {datum!r}: expected one of {', '.join(DATUMS)}")
    if datum == "none" and mode != "known":
        raise InputError("--datum none needs --method known-base (the bases orient the block)")
    return mode


def _screen_pairs(xy_i, xy_j, mask, prior, pairs, base, f_mm, system, mode, sigma_mm,
                  snooping, max_iter):
    """Pair-wise screening (image i held at its prior): outliers and failed pairs.

    Base-free, so the INS errors of image i and the GNSS base do not enter the tests.  A
    pair whose screening did not converge has no valid outlier tests (and, for the
    relative methods, no starting base direction): it is left out, with a warning.

    Returns
    -------
    screen : dict (from :func:`photogrammetry.adjustment.coplanarity.adjust_pairs`)
    status : ndarray of int (P,); good : ndarray of bool (P,)
    mask : ndarray of bool (P, n)
        The points kept (not rejected, of a good pair).
    """
    screen = adjust_pairs(xy_i, xy_j, f_mm, prior[pairs[:, 0]], prior[pairs[:, 1]], system,
                          "base-free", mask=mask, sigma_mm=sigma_mm, snooping=snooping,
                          max_iter=max_iter)
    status = screen["status"]
    if mode == "known":     # 3 or 4 points: no base-free screening, the known base suffices
        few = (status == K.STATUS_TOO_FEW) & (mask.sum(axis=1) >= 3)
        status = np.where(few, K.STATUS_OK, status)
        norm = np.linalg.norm(base, axis=1)
        status = np.where(norm < 1e-9, STATUS_ZERO_BASE, status)
    # a screening with a redundancy of 5 or more that went farther than any sample may
    # go from the prior, and farther than 5 of its own sigmas, has no valid outlier
    # tests either (a weak pair of 5-9 points wanders anywhere: it stays, as it was)
    change = np.abs(wrap_to_pi(screen["angles"] - prior[pairs[:, 1]]))
    strayed = (status == K.STATUS_OK) & (screen["redundancy"] >= 5) & np.any(
        change > np.maximum(MAX_CHANGE, 5 * np.nan_to_num(screen["sigma"], nan=np.inf)),
        axis=1)
    status = np.where(strayed, STATUS_STRAYED, status)
    good = status == K.STATUS_OK
    for k in np.flatnonzero(~good):
        what = ("its pair-wise screening did not converge"
                if status[k] == K.STATUS_NOT_CONVERGED else STATUS_TEXT.get(status[k], ""))
        if strayed[k]:
            what = (f"its pair-wise screening moved image {pairs[k, 1]} more than "
                    f"{np.rad2deg(MAX_CHANGE):g} deg and 5 of its sigmas from its prior")
        warnings.warn(f"pair {pairs[k, 0]}-{pairs[k, 1]} left out: {what}",
                      QualityWarning if status[k] in (K.STATUS_NOT_CONVERGED, STATUS_STRAYED)
                      else InputWarning,
                      stacklevel=3)
    return screen, status, good, screen["mask"] & good[:, None]


@dataclass
class _Linearized:
    """The block linearized at the current angles and bases (one iteration)."""
    g: np.ndarray           # (C,) misclosures
    var: np.ndarray         # (C,) variance of each condition
    rank: int               # independent conditions
    N: np.ndarray           # (C, 3) dg/db
    E: np.ndarray           # (P, 3, 2) tangent basis of the bases (None for known-base)
    WJ: object              # W @ J (sparse)
    grad: np.ndarray        # J^T W g + the prior's gradient
    H: object               # normal matrix with the prior's weights (sparse)
    vtpv: float             # weighted sum of squares (conditions and prior)


def _linearize(angles, prior, free, b, cond, joint, col, n_ang, n_base, bslot, prior_w,
               system, mode, sigma_mm, point_ids):
    """Misclosures, weights, Jacobian and normal equations at `angles` and bases `b`."""
    R, M = K.rotation_and_axes(angles, system)
    g, d, J_ang, N = _condition_terms(cond.U, cond.img, cond.p, R, M, b)
    W, rank, var = _joint_weights(cond.buckets if joint else cond.buckets_1,
                                  cond.obs if joint else cond.obs_1,
                                  d, sigma_mm ** 2, len(g), RANK_TOL[mode],
                                  cond.kept.setdefault("W" if joint else "W1", {}))
    _check_variance(var, cond, point_ids, sigma_mm)
    E = None if mode == "known" else K.tangent_basis(b)
    NE = None if E is None else np.einsum("ca,cak->ck", N, E[cond.p])
    J = _jacobian(J_ang, NE, cond.img, bslot[cond.p], col, n_ang, n_ang + n_base,
                  cond.kept.setdefault("J", {}))
    WJ = W @ J
    Wg = W @ g
    # J' as CSR times W J (CSR): the same sums as (J.T @ WJ).tocsr(), whose CSC J.T made
    # scipy convert W J (four times J's non-zeros) to CSC and the product back
    H = J.T.tocsr() @ WJ
    grad = J.T @ Wg
    dl = (angles[free] - prior[free]).ravel()
    vtpv = float(g @ Wg + np.sum(prior_w * dl ** 2))
    grad[:n_ang] += prior_w * dl
    H = H + sparse.diags(np.concatenate([prior_w, np.zeros(n_base)]))
    return _Linearized(g, var, rank, N, E, WJ, grad, H, vtpv)


def _solve_step(lin, n_ang, banded=False):
    """Gauss-Newton step: ``(step, S, d_b)``, the free angles' step, S the reduced
    normal matrix (dense) or the banded factor of the sparse normal matrix, and the
    base-direction parameters' step (None for known-base).  Banded: the whole normal
    matrix (angles, then bases: bordered) is factored, no Schur complement formed."""
    if banded:
        if lin.H.shape[0] == n_ang:
            factor = BandedSPD(lin.H, what="block normal matrix")
        elif cholmod.available():                 # optional, several times faster
            factor = cholmod.CholmodSPD(lin.H, what="block normal matrix")
        else:
            factor = SparseSPD(lin.H, what="block normal matrix")
        full = factor.solve(-lin.grad)
        return full[:n_ang], factor, (full[n_ang:] if len(full) > n_ang else None)
    S, rhs, back = _reduced_normals(lin.H.tocsr(), lin.grad, n_ang)
    step, ok = K._solve(S[None], rhs[None])
    if not ok[0]:
        raise InputError("block normal equations are singular: part of the block is not "
                         "connected to the datum image, or the geometry is degenerate "
                         "(try --datum ins)")
    d_b = None if back is None else -(back[1] + back[0] @ step[0])
    return step[0], S, d_b


def _covariance(S, lin, cond, m, free, adjusted, sigma0, mode, n_ang, prior_sigma,
                position_sigma):
    """A-posteriori covariance of all angles (3m, 3m): ``sigma0^2 S^-1`` for the free
    images, plus the EO position errors (known-base with `position_sigma`), the prior for
    the images left out, 0 for the datum image."""
    cov = np.zeros((3 * m, 3 * m))
    if n_ang:
        fidx = (3 * np.flatnonzero(free)[:, None] + np.arange(3)).ravel()
        Hi = np.linalg.inv(S)
        cov[np.ix_(fidx, fidx)] = sigma0 ** 2 * Hi
        if mode == "known" and position_sigma is not None and np.any(position_sigma):
            ps = np.broadcast_to(np.asarray(position_sigma, float), (m, 3))
            Sx = _position_cov(lin.WJ, lin.N, cond.img, m, n_ang, ps)
            cov[np.ix_(fidx, fidx)] += Hi @ Sx @ Hi
    for i in np.flatnonzero(~adjusted):
        cov[3 * i:3 * i + 3, 3 * i:3 * i + 3] = np.diag(prior_sigma[i] ** 2)
    return cov


@dataclass
class _State:
    """Where a Gauss-Newton run ended."""
    angles: np.ndarray
    b: np.ndarray
    lin: _Linearized
    S: np.ndarray
    converged: bool
    iterations: int


@dataclass
class _GaussNewton:
    """The block's Gauss-Newton iteration with its fixed settings."""
    prior: np.ndarray
    free: np.ndarray
    col: np.ndarray
    n_ang: int
    n_base: int
    bslot: np.ndarray
    prior_w: np.ndarray
    system: str
    mode: str
    sigma_mm: float
    point_ids: object
    good: np.ndarray
    max_iter: int
    tol: float
    progress: object
    banded: bool = False
    iterations: int = 0

    def run(self, angles, b, cond, joint):
        """Iterate from `angles` and bases `b` (copied) to convergence."""
        angles, b = angles.copy(), b.copy()
        converged, S, free, n_ang = False, None, self.free, self.n_ang
        lin = prev = None
        for it in range(self.max_iter + 1):
            lin = S = None              # the previous iterate's matrices: memory
            lin = _linearize(angles, self.prior, free, b, cond, joint, self.col, n_ang,
                             self.n_base, self.bslot, self.prior_w, self.system, self.mode,
                             self.sigma_mm, self.point_ids)
            if n_ang == 0:
                converged = True
                break
            step, S, d_b = _solve_step(lin, n_ang, self.banded)
            if it == self.max_iter:
                break
            angles[free] += step.reshape(-1, 3)
            big = np.max(np.abs(step))
            if d_b is not None:                 # update the base directions
                good = self.good
                b[good] = b[good] + np.einsum("pab,pb->pa", lin.E[good], d_b.reshape(-1, 2))
                b /= np.linalg.norm(b, axis=1, keepdims=True)
                big = max(big, np.max(np.abs(d_b)))
            self.iterations += 1
            if self.progress is not None:
                self.progress(self.iterations, self.max_iter)
            # converged: this step, or the next one at the rate of the last two (fast,
            # linear), below tol (saves the last of ~4 iterations of 10^6-entry factors)
            if joint and (big < self.tol or prev is not None and big < 0.1 * prev
                          and big * big / prev < self.tol):
                converged = True
                break
            prev = big if joint else None
            joint = joint or big < 1e-6
        return _State(angles, b, lin, S, converged, self.iterations)


def _block_outliers(lin, cond, mask, mode):
    """Conditions to drop after a converged run: per pair the largest normalized
    misclosure ``|g| / sigma_g`` above :data:`BLOCK_W_CRITICAL`, while the pair keeps
    enough points for its unknowns."""
    w = np.abs(lin.g) / np.sqrt(np.where(lin.var > 0, lin.var, np.inf))
    over = np.flatnonzero(w > BLOCK_W_CRITICAL)
    if len(over) == 0:
        return over
    over = over[np.argsort(-w[over], kind="stable")]
    _, first = np.unique(cond.p[over], return_index=True)
    drop = over[first]
    need = 3 if mode == "known" else 5
    return drop[mask[cond.p[drop]].sum(axis=1) > need]


def adjust_block(angles_prior, pairs, pair_points, f_mm, system, method="base-free",
                 datum="first", positions=None, prior_sigma=None, sigma_mm=0.005,
                 position_sigma=None, point_ids=None, snooping=True, max_iter=30, tol=1e-9,
                 progress=None, image_ids=None, algebra="auto"):
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
    point_ids : sequence of P sequences of hashables, optional
        Tie-point id of every point of `pair_points` (as from
        :meth:`photogrammetry.imagery.tiepoints.TiePoints.pairs`).  With them the conditions of a
        point seen in three or more images are weighted jointly (their correlation
        through the shared photo coordinates); without, each condition on its own
        (optimistic covariance when points are seen in 3+ images).
    max_iter : int
        Gauss-Newton iterations per run (and rounds of data snooping).
    tol : float
        Converged when no step (angles, rad; base-direction parameters), or no next
        step predicted from the last two (at a rate below 0.1), exceeds this
        (default 1e-9 rad: 0.2 milliarcsecond, four orders below the angles' sigmas;
        Gauss-Newton gains about three orders per iteration near the solution).
    progress : callable(done, total), optional
        Called after each iteration.
    image_ids : sequence of str, optional
        Names of the images in the quality messages (default: indices).
    algebra : {"auto", "dense", "banded"}
        Normal equations dense (the reduced normal matrix, its inverse: cost cubic in
        the images) or banded (sparse normal matrix in reverse Cuthill-McKee order,
        banded Cholesky, covariance blocks by the Takahashi recurrence: cost
        ``n b^2``, about linear in the images for strips of a given length; relative
        and base-free: the whole normal matrix of the angles and the base directions
        (bordered), steps and solves by a sparse LU, see
        :mod:`photogrammetry.adjustment.block_covariance`); "auto": banded from
        :data:`BANDED_MIN_ANGLES` free angles.

    Returns
    -------
    BlockResult
        With ``quality`` (:func:`photogrammetry.adjustment.quality.block_quality`): flagged, never
        raised here (the caller decides; ``photogrammetry refine`` exits 3).

    Outliers: every pair's screening starts robustly (minimal samples + MSAC, see
    :func:`photogrammetry.adjustment.coplanarity.adjust_pairs`), then snoops; after the block has
    converged, data snooping on the block's normalized misclosures drops, per pair and
    round, the largest above :data:`BLOCK_W_CRITICAL`, and the block
    is iterated again (``rejected`` holds both).

    Raises
    ------
    InputError
        Unknown method or datum, missing positions, a block whose normal equations are
        singular (a part not connected to the datum), a condition with zero or non-finite
        variance (names the pair and tie point).

    Warns
    -----
    InputWarning
        A pair left out (too few points, singular, zero base), an image without a pair.
    QualityWarning
        A pair left out because its pair-wise screening did not converge; the block
        adjustment itself not converged.
    """
    mode = _check_options(system, method, datum)
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
    if point_ids is not None and [len(q) for q in point_ids] != [len(a) for a, _ in pair_points]:
        raise ValueError("point_ids must give one id per point of every pair")
    base = None if positions is None else (np.asarray(positions, float)[pairs[:, 1]]
                                           - np.asarray(positions, float)[pairs[:, 0]])
    screen, status, good, mask = _screen_pairs(xy_i, xy_j, mask, prior, pairs, base, f_mm,
                                               system, mode, sigma_mm, snooping, max_iter)
    adjusted, free = _free_images(pairs, good, m, datum)
    if prior_sigma is None:
        prior_sigma = np.full((m, 3), 0.005)
    prior_sigma = np.broadcast_to(np.asarray(prior_sigma, float), (m, 3))
    prior_w = np.where(datum == "ins", 1.0 / prior_sigma[free].ravel() ** 2, 0.0)

    if not free.any():
        why = ("no pair of images is left after the pair-wise screening" if not good.any()
               else "no image is left to adjust beside the datum image")
        return _unadjusted(prior, prior_sigma, pairs, status, screen, mask, image_ids, why)

    # unknowns: 3 angles per free image, then 2 base-direction parameters per good pair
    col = -np.ones(m, dtype=int)
    col[free] = np.arange(free.sum())
    n_ang = 3 * int(free.sum())
    n_base = 0 if mode == "known" else 2 * int(good.sum())
    bslot = np.cumsum(good) - 1
    angles = prior.copy()
    # base per pair: the GNSS base (known-base), else the screening's unit direction
    b = base.copy() if mode == "known" else screen["base"].copy()
    b[~good] = (1.0, 0.0, 0.0)                       # not used
    cond = _conditions(pairs, mask, point_ids, m, xy_i, xy_j, f_mm)

    # Gauss-Newton.  The base directions (relative, base-free) start from each pair's
    # own screening, in frames of different INS errors: converge first with the
    # conditions weighted one by one, then jointly (the joint weights depend on the bases
    # through the near-repeated combinations).  Then data snooping on the converged
    # block (one condition per pair and round), Gauss-Newton again from there.
    banded = _use_banded(algebra, mode, n_ang)
    gn = _GaussNewton(prior, free, col, n_ang, n_base, bslot, prior_w, system, mode,
                      sigma_mm, point_ids, good, max_iter, tol, progress, banded)
    state = gn.run(angles, b, cond, joint=mode == "known" or point_ids is None)
    snooped = np.zeros(mask.shape, bool)
    for _ in range(max_iter if snooping and n_ang else 0):
        drop = _block_outliers(state.lin, cond, mask, mode)
        if len(drop) == 0:
            break
        mask[cond.p[drop], cond.s[drop]] = False
        snooped[cond.p[drop], cond.s[drop]] = True
        cond = _conditions(pairs, mask, point_ids, m, xy_i, xy_j, f_mm)
        start, state = (state.angles, state.b), None      # free the last run's factor
        state = gn.run(*start, cond, joint=True)
    angles, lin, S, converged, iterations = (state.angles, state.lin, state.S,
                                             state.converged, state.iterations)

    n_prior = n_ang if datum == "ins" else 0
    redundancy = lin.rank + n_prior - n_ang - n_base
    if redundancy <= 0:
        return _unadjusted(prior, prior_sigma, pairs, status, screen, mask, image_ids,
                           f"the block has no redundancy after the screening ({lin.rank} "
                           f"independent conditions for {n_ang} angles and {n_base} "
                           "base-direction parameters): nothing checks the result",
                           rejected=screen["rejected"] | snooped)
    sigma0 = float(np.sqrt(lin.vtpv / redundancy))
    s_cov = max(sigma0, 1.0)        # covariance scale (photogrammetry.adjustment.coplanarity)
    cov_op = None
    if banded:
        ps = (None if position_sigma is None
              else np.broadcast_to(np.asarray(position_sigma, float), (m, 3)))
        cov_op = banded_covariance(lin.H, s_cov, free, lin.WJ, lin.N, cond.img,
                                   ps if mode == "known" else None, n_angles=n_ang,
                                   factor=S)
        cov = None
        sigma = np.zeros((m, 3))
        sigma[free] = np.sqrt(np.einsum("iaa->ia", cov_op.blocks))
        sigma[~adjusted] = prior_sigma[~adjusted]
    else:
        cov = _covariance(S, lin, cond, m, free, adjusted, s_cov, mode, n_ang, prior_sigma,
                          position_sigma)
        sigma = np.sqrt(np.diag(cov)).reshape(m, 3)
    if not converged:
        warnings.warn(f"block adjustment did not converge in {max_iter} iterations",
                      QualityWarning, stacklevel=2)
    res = np.zeros(mask.shape)
    res[cond.p, cond.s] = lin.g / np.sqrt(np.where(lin.var > 0, lin.var, np.inf))
    ok = status == K.STATUS_OK
    change = np.where(ok[:, None], screen["angles"] - prior[pairs[:, 1]], np.nan)
    strayed = status == STATUS_STRAYED
    status = np.where(strayed, K.STATUS_NOT_CONVERGED, status)
    quality = block_quality(pairs, np.where(ok, screen["sigma0"], np.nan),
                            screen["redundancy"], change, screen["sigma"], sigma0,
                            int(redundancy), angles,
                            prior, prior_sigma, sigma, adjusted, image_ids, system,
                            common_rotation=datum == "none", strayed=strayed,
                            n_rejected=int((screen["rejected"] | snooped).sum()))
    return BlockResult(angles, cov, sigma, sigma0, int(redundancy), iterations, converged,
                       adjusted, status, screen["rejected"] | snooped, res, mask, quality,
                       cov_op)


def _unadjusted(prior, prior_sigma, pairs, status, screen, mask, image_ids, why,
                rejected=None):
    """A block whose conditions vanished in the screening (no good pair, or no
    redundancy): every image at its prior, not adjusted, flagged poor (QualityWarning)."""
    status = np.where(status == STATUS_STRAYED, K.STATUS_NOT_CONVERGED, status)
    quality = unadjusted_quality(pairs, status, screen["mask"], screen["rejected"],
                                 len(prior), image_ids, why, STATUS_TEXT)
    warnings.warn(quality.reasons[0], QualityWarning, stacklevel=3)
    sigma = np.array(prior_sigma, float)
    return BlockResult(prior.copy(), np.diag(sigma.ravel() ** 2), sigma, np.nan, 0, 0,
                       False, np.zeros(len(prior), bool), status,
                       screen["rejected"] if rejected is None else rejected,
                       np.zeros(mask.shape), mask, quality, None)


def _use_banded(algebra, mode, n_ang):
    if algebra not in ALGEBRAS:
        raise InputError(f"algebra {algebra!r}: expected one of {', '.join(ALGEBRAS)}")
    return algebra == "banded" or (algebra == "auto" and n_ang >= BANDED_MIN_ANGLES)
