"""The robust start of the coplanarity adjustment of a pair
(:func:`photogrammetry.adjustment.coplanarity.adjust_pairs`): MSAC on minimal samples
solved from the prior (:mod:`photogrammetry.adjustment._msac_kernels`), the five-point
essential matrix's pose as a start that does not depend on the prior
(:mod:`photogrammetry.adjustment.essential`), whichever scores better on the MSAC cost,
then Gauss-Newton on the inliers and re-classification of all points until the set is
stable (:func:`robust_start`).
"""
import numpy as np

from ins.nav.rotation import wrap_to_pi
from photogrammetry.adjustment import _coplanarity_kernels as K
from photogrammetry.adjustment import _msac_kernels as MK
from photogrammetry.orientation.rotation import angles_to_matrix

__all__ = ["robust_start", "ESSENTIAL_BELOW"]

#: Least points of a solution per mode, its unknowns (a re-classified set needs one more).
_MIN_MODE = {"known": 3, "relative": 5, "free": 5}
#: The essential-matrix start is tried for the pairs whose MSAC winner from the prior
#: holds less than this share of their points (or that have no winner): the pairs with
#: outliers or a doubtful winner; a pair whose winner holds nearly all has nothing to
#: gain (and the pairs whose Gauss-Newton from the winner failed are tried afterwards:
#: a weak pair's winner 6000 arcsec off that held all its 26 clean points).
ESSENTIAL_BELOW = 0.9


def _msac_cost(u1, u2, mask, R1, angles2, base, system, sigma_mm, threshold):
    """MSAC cost ``sum min(g^2 / var, t^2)`` over the masked points and the inliers
    (``g^2 / var < t^2``) of the hypotheses ``angles2`` (P, 3), ``base`` (P, 3) unit."""
    R2 = angles_to_matrix(angles2, system)
    r1 = np.einsum("pij,pnj->pni", R1, u1)
    r2 = np.einsum("pij,pnj->pni", R2, u2)
    g, var = K.condition_terms(r1, r2, base, R1, R2, sigma_mm)[:2]
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.where(var > 0, g * g / np.where(var > 0, var, 1.0), np.inf)
    t2 = float(threshold) ** 2
    inl = mask & (e < t2)
    return np.sum(np.where(mask, np.minimum(e, t2), 0.0), axis=1), inl


def _unit(b):
    return b / np.linalg.norm(b, axis=1, keepdims=True)


def _essential_candidate(u1, u2, mask, R1, prior2, base, mode, system, sigma_mm, threshold,
                         seed, max_change, ang, b, inl, st, todo, force=False):
    """The prior-free start (:func:`photogrammetry.adjustment.essential.essential_starts`)
    of the pairs ``todo`` (bool (P,)) against the MSAC winner from the prior, in place:
    per pair, the essential matrix's pose replaces the winner (``ang``, ``b``, ``inl``,
    ``st``) when its MSAC cost on all points is lower (or MSAC found no hypothesis, or
    `force`: the winner's Gauss-Newton runs all failed) and it lies within `max_change`
    of the prior (the farther of a near-planar scene's two poses, or a wrong one, does
    not).  With a known base only its rotation is used, scored with the given base.
    Returns the pairs whose start was replaced (bool (P,))."""
    from photogrammetry.adjustment.essential import essential_starts
    taken = np.zeros(len(st), bool)
    todo = np.flatnonzero(todo)
    if len(todo) == 0:
        return taken
    f = -u1[todo, 0, 2]
    e_ang, e_b, e_ok = essential_starts(u1[todo, :, :2], u2[todo, :, :2], mask[todo], f,
                                        R1[todo], system, threshold * sigma_mm, seed=seed)
    near = e_ok & np.all(np.abs(wrap_to_pi(np.nan_to_num(e_ang) - prior2[todo]))
                         < max_change, axis=1)
    todo, e_ang, e_b = todo[near], e_ang[near], e_b[near]
    if len(todo) == 0:
        return taken
    if mode == "known":
        e_b = _unit(base[todo])
    u1t, u2t, mt, R1t = u1[todo], u2[todo], mask[todo], R1[todo]
    cost_e, inl_e = _msac_cost(u1t, u2t, mt, R1t, e_ang, e_b, system, sigma_mm, threshold)
    cost_m, _ = _msac_cost(u1t, u2t, mt, R1t, ang[todo], _unit(b[todo]), system, sigma_mm,
                           threshold)
    take = force | (st[todo] != MK.MSAC_OK) | (cost_e < cost_m)
    take &= inl_e.sum(axis=1) > _MIN_MODE[mode]
    idx = todo[take]
    ang[idx], b[idx], inl[idx], st[idx] = e_ang[take], e_b[take], inl_e[take], MK.MSAC_OK
    taken[idx] = True
    return taken


def robust_start(u1, u2, mask, R1, prior2, base, mode, system, sigma_mm, threshold, seed,
                  max_change, max_iter, essential=True):
    """MSAC on minimal samples (and the essential matrix's pose, whichever scores better:
    :func:`_essential_candidate`), Gauss-Newton on the inliers, re-classification of all
    points at that solution, Gauss-Newton again (no snooping).

    The essential-matrix pose is tried for the pairs whose MSAC winner holds less than
    :data:`ESSENTIAL_BELOW` of their points (or that have no winner), and afterwards for
    those whose Gauss-Newton runs from the winner all failed (a weak pair's winner far
    off on its weak rotation, all points within the threshold); about 1 ms of CPU per
    pair tried, four times the rest of a clean pair's screening.

    A re-classification keeps the points used whose studentized residual is below the
    threshold and adds the others whose studentized prediction error AND plain
    normalized misclosure are below it; a Gauss-Newton run that fails, or raises the
    MSAC cost on all points, is undone (its set, angles and base back to the last
    accepted ones) and the pair stops there.

    Returns the start angles (P, 3) and bases (P, 3), the points kept (P, n) and the
    number of hypotheses per pair."""
    P, n = mask.shape
    f64 = np.ascontiguousarray
    order, sign, s2 = K._ORDER[system], K._SIGN[system], float(sigma_mm) ** 2
    ang, b = np.empty((P, 3)), np.empty((P, 3))
    inl, st, hyp = np.empty((P, n), bool), np.empty(P, np.int64), np.empty(P, np.int64)
    t2 = float(threshold) ** 2
    MK.msac_pairs(f64(u1, dtype=float), f64(u2, dtype=float), f64(mask, dtype=np.bool_),
                  f64(R1, dtype=float), f64(prior2, dtype=float), f64(base, dtype=float),
                  mode == "known", order, sign, s2, t2, 0.999, 10, 500, float(max_change),
                  int(seed), ang, b, inl, st, hyp)
    if mode == "known":
        b = base.copy()
    tried = np.zeros(P, bool)
    if essential:
        share = inl.sum(axis=1) / np.maximum(mask.sum(axis=1), 1)
        tried = (st != MK.MSAC_TOO_FEW) & ((st != MK.MSAC_OK) | (share < ESSENTIAL_BELOW))
        _essential_candidate(u1, u2, mask, R1, prior2, base, mode, system, sigma_mm,
                             threshold, seed, max_change, ang, b, inl, st, tried)
    ok = st == MK.MSAC_OK
    keep = np.where(ok[:, None], inl, mask)
    args = (u1, u2, mask, R1, mode, system, sigma_mm, threshold, max_iter)
    converged = _consensus(*args, ok, ang, b, keep)
    if essential:
        retry = ok & ~converged & ~tried
        if retry.any():
            again = _essential_candidate(u1, u2, mask, R1, prior2, base, mode, system,
                                         sigma_mm, threshold, seed, max_change, ang, b,
                                         inl, st, retry, force=True)
            keep[again] = inl[again]
            _consensus(*args, again, ang, b, keep)
    return ang, b, keep, hyp


def _consensus(u1, u2, mask, R1, mode, system, sigma_mm, threshold, max_iter, todo, ang,
               b, keep):
    """Gauss-Newton on the kept points of the pairs ``todo`` from ``ang``, ``b``; every
    point re-classified there; repeated until the set is stable (at most 5 runs); in
    place (see :func:`robust_start`).  Returns the pairs of which a run converged."""
    P, n = mask.shape
    f64 = np.ascontiguousarray
    order, sign, s2 = K._ORDER[system], K._SIGN[system], float(sigma_mm) ** 2
    converged = np.zeros(P, bool)
    # the robust objective (the MSAC cost on all points) of the accepted solution: a
    # Gauss-Newton run on a re-classified set that raises it, or that fails, is undone
    # (set, angles and base back to the last accepted: a weak pair's wide prediction
    # sigmas can let wrong matches in, which then pull the solution away)
    cost = np.full(P, np.inf)
    if todo.any():
        cost[todo] = _msac_cost(u1[todo], u2[todo], mask[todo], R1[todo], ang[todo],
                                _unit(b[todo]), system, sigma_mm, threshold)[0]
    accepted = keep.copy()
    todo = todo.copy()
    for _ in range(5):      # GN on the kept points; re-classify all points there; repeat
        idx = np.flatnonzero(todo)          # until the set is stable
        if len(idx) == 0:
            break
        part = K.solve_pairs(u1[idx], u2[idx], keep[idx], R1[idx], ang[idx], b[idx], mode,
                             system, sigma_mm, max_iter)
        good = part["status"] == K.STATUS_OK
        new_b = b[idx] if mode == "known" else part["base"]
        c_new = np.full(len(idx), np.inf)
        if good.any():
            c_new[good] = _msac_cost(u1[idx[good]], u2[idx[good]], mask[idx[good]],
                                     R1[idx[good]], part["angles"][good],
                                     _unit(new_b[good]), system, sigma_mm, threshold)[0]
        converged[idx[good]] = True
        good &= c_new <= cost[idx] * (1.0 + 1e-9)
        back = idx[~good]
        keep[back] = accepted[back]
        idx, c_new = idx[good], c_new[good]
        ang[idx] = part["angles"][good]
        if mode != "known":
            b[idx] = part["base"][good]
        cost[idx] = c_new
        accepted[idx] = keep[idx]
        w = np.empty((len(idx), n))
        MK.studentized_misclosures(f64(u1[idx], dtype=float), f64(u2[idx], dtype=float),
                                   f64(mask[idx], dtype=np.bool_),
                                   f64(keep[idx], dtype=np.bool_), f64(R1[idx], dtype=float),
                                   f64(ang[idx]), f64(b[idx]), f64(part["Q"][good]), order,
                                   sign, s2, w)
        again = mask[idx] & (np.abs(w) < threshold)         # inf (no redundancy): out
        # a point not used enters only when its plain normalized misclosure is below
        # the threshold too (the MSAC inlier test at this solution): the prediction
        # sigma of a weak pair is wide enough to let wrong matches in, which the next
        # Gauss-Newton run then fits by turning about the weak direction
        _, plain = _msac_cost(u1[idx], u2[idx], mask[idx], R1[idx], ang[idx],
                              _unit(b[idx]), system, sigma_mm, threshold)
        again &= keep[idx] | plain
        enough = again.sum(axis=1) >= _MIN_MODE[mode] + 1
        changed = enough & np.any(again != keep[idx], axis=1)
        keep[idx[enough]] = again[enough]
        todo[:] = False
        todo[idx[changed]] = True
    keep[todo] = accepted[todo]         # a re-classification never tried (5 rounds done)
    return converged
