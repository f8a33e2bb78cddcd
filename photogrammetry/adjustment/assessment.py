"""Accuracy of a block adjustment and assessment of the INS angles against it.

Per image ``i`` the INS-minus-adjusted angle differences ``d_i`` (rad, system order).
With the INS attitude ``R_ins = R_true @ B^T`` (``B = Rx(rx) Ry(ry) Rz(rz)`` the boresight
misalignment of the camera file, ``C_bc = axes @ B``) plus white noise, to first order

    d = -J beta + e_ins + e_adj,   cov(e_adj) = C_adj,   cov(e_ins) = S = diag(s_a^2)

with ``beta = (rx, ry, rz)``, ``J_i = M_i^-1 R_i`` (``M_i`` the model-frame axes of the
angles), ``C_adj`` the adjustment's FULL covariance of the compared images (the adjusted
angles of a strip are strongly correlated: the relative orientations chain along it) and
``s_a`` the INS noise of angle ``a`` (one variance component per angle).  The boresight
is the generalized least-squares estimate ``(A^T W A)^-1 A^T W d`` with
``W = (C_adj + S)^-1`` and covariance ``(A^T W A)^-1``; the variance components are
estimated by REML (Fisher scoring, equivalent to iterated Helmert/MINQUE), which is the
correlated-data form of ``sqrt(mean(d^2) - sigma_adj^2)``.  For a single-heading block
``beta`` is essentially the (GLS) mean of ``d``; for strips flown back and forth the
mean of phi and omega cancels, the fit does not.

The model is linear in ``beta`` only to first order: a boresight of 0.2 deg makes
second-order terms of about one arcsec, as large as the estimate's sigma on a good block.
So the fit is iterated (Gauss-Newton): with the current estimate ``B_k`` the INS attitude
is corrected exactly, ``R_c = P_k^T R_ins B_k`` (``P_k`` the datum's common rotation when
it is estimated), its differences with the adjusted angles give the increment, until it
is below 1e-12 rad.  The reported differences (``diff``, ``mean``, ``rms``) are those of
the uncorrected INS angles.

A variance component whose estimate is negative (the data show less scatter than the
adjustment's own covariance predicts) is not estimable: it is held at 0 inside the fit
(the constrained REML estimate) and reported as NaN with ``ins_noise_negative`` set,
never as a noise of 0; ``ins_noise_var`` keeps the signed estimate.

The boresight is only observable when the block's orientation does not come from the
INS (``known-base`` with GNSS bases); with datum ``first`` or ``ins`` it is absorbed by
the datum and the report says so; the fit then also takes out a common model-frame
rotation of the block (the datum's own INS error), so the noise estimate stays valid.
(With datum ``ins`` the adjusted angles depend on the INS angles themselves; the
dependence is mostly the common rotation, which the fit removes; the rest is neglected.)
"""
from dataclasses import dataclass

import numpy as np

from ins.nav.rotation import rotvec_to_dcm, wrap_to_pi
from photogrammetry.adjustment import _coplanarity_kernels as K
from photogrammetry.adjustment.reml import banded_v, gls_reml_banded
from photogrammetry.orientation.rotation import angles_to_matrix, matrix_to_angles

__all__ = ["Assessment", "assess", "gls_variance_components", "LAMBDA_MAX_REL",
           "MAX_ROUNDS"]


@dataclass
class Assessment:
    """INS assessment of a block (all angles rad, system order unless stated).

    Attributes
    ----------
    names : tuple of str
        Angle names in system order.
    used : ndarray of bool (m,)
        Images compared (adjusted, not the datum image).
    diff : ndarray (m, 3)
        INS minus adjusted angles (0 where not used).
    mean, mean_sigma : ndarray (3,)
        Arithmetic mean of ``d`` per angle over the used images, and its sigma
        ``sqrt(1^T (C_adj + S) 1) / k`` with the full covariance.
    gls_mean, gls_mean_sigma : ndarray (3,)
        Generalized least-squares (best linear unbiased) common offset per angle.
    rms : ndarray (3,)
    boresight : ndarray (3,)
        Estimated misalignment (rx, ry, rz), rad, as ``boresight_deg`` of the camera file.
    boresight_sigma : ndarray (3,)
    boresight_observable : bool
    ins_noise, ins_noise_sigma : ndarray (3,)
        Per-angle INS noise (REML variance component, the adjustment's own covariance
        removed; NaN where the estimate is negative, see ``ins_noise_negative``) and its
        sigma (from the REML Fisher information; where the noise is NaN, the square root
        of the sigma of the variance: the scale the data could have detected).
    ins_noise_var : ndarray (3,)
        Signed estimate of the noise variance, rad^2 (one unconstrained scoring step at
        the constrained REML solution; negative: not estimable).
    ins_noise_negative : ndarray of bool (3,)
        The variance component came out negative: ``ins_noise`` is NaN (not 0).
    residual_rms : ndarray (3,)
        RMS of the differences after removing the boresight (and datum rotation).
    adj_sigma_rms : ndarray (3,)
        RMS of the adjustment's own per-angle sigma over the used images.
    chi2, dof : float, int
        ``r^T V^-1 r`` of the GLS residuals and its degrees of freedom.
    cov_factor, cov_factor_sigma : float
        REML factor ``lambda`` of the adjustment's covariance in ``V = lambda C_adj + S``
        (1 when the data cannot tell it: relative sigma above :data:`LAMBDA_MAX_REL`).
    correlations : ndarray (m, 3, 3)
        Correlation of each image's three adjusted angles.
    """
    names: tuple
    used: np.ndarray
    diff: np.ndarray
    mean: np.ndarray
    mean_sigma: np.ndarray
    gls_mean: np.ndarray
    gls_mean_sigma: np.ndarray
    rms: np.ndarray
    boresight: np.ndarray
    boresight_sigma: np.ndarray
    boresight_observable: bool
    ins_noise: np.ndarray
    ins_noise_sigma: np.ndarray
    residual_rms: np.ndarray
    adj_sigma_rms: np.ndarray
    chi2: float
    dof: int
    cov_factor: float
    cov_factor_sigma: float
    correlations: np.ndarray
    ins_noise_var: np.ndarray = None
    ins_noise_negative: np.ndarray = None
    boresight_iterations: int = 0


def _image_correlations(blocks):
    s = np.sqrt(np.einsum("mii->mi", blocks))
    inv = np.where(s > 0, 1.0 / np.where(s > 0, s, 1.0), 0.0)
    return blocks * inv[:, :, None] * inv[:, None, :]


def _inv_spd(V):
    L = np.linalg.cholesky(V)
    Li = np.linalg.solve(L, np.eye(len(V)))
    return Li.T @ Li


def gls_variance_components(y, A, G, fixed=None, max_iter=100, tol=1e-7):
    """Generalized least squares with REML variance components.

    Model ``y = A x + e``, ``cov(e) = V = sum_a theta_a G_a`` (``theta_a >= 0``).  Fisher
    scoring of the restricted likelihood: ``theta <- I^-1 u`` with
    ``I_ab = tr(P G_a P G_b) / 2``, ``u_a = y^T P G_a P y / 2`` and
    ``P = V^-1 - V^-1 A (A^T V^-1 A)^-1 A^T V^-1`` (iterated Helmert / MINQUE).

    Parameters
    ----------
    y : ndarray (n,)
    A : ndarray (n, p)
        Design matrix (full column rank).
    G : sequence of q ndarrays (n, n)
        Covariance structures (symmetric, positive semi-definite).
    fixed : sequence of q floats or None, optional
        Components held at the given value (None: estimated).

    Returns
    -------
    x : ndarray (p,)
    cov_x : ndarray (p, p)
        ``(A^T V^-1 A)^-1`` at the estimated components.
    theta : ndarray (q,)
        Constrained estimate (``>= 0``; a component whose estimate is negative is held
        at 0, see `negative`).
    sigma_theta : ndarray (q,)
        From the inverse Fisher information of the estimated components (0 if fixed, NaN
        if the information matrix is not positive definite).
    residual : ndarray (n,)
    chi2 : float
        ``r^T V^-1 r``.
    theta_signed : ndarray (q,)
        One unconstrained scoring step from the constrained solution (the MINQUE
        estimate there): equal to `theta` for components inside the bound, negative for
        those that are not estimable.
    negative : ndarray of bool (q,)
        Estimated components whose unconstrained estimate is negative (not estimable:
        reported as such, never as a variance of 0).
    """
    q, n = len(G), len(y)
    fixed = [None] * q if fixed is None else list(fixed)
    est = np.array([f is None for f in fixed])
    theta = np.array([1.0 if f is None else f for f in fixed])
    floor = 1e-12 * max(np.trace(g) / n for g in G)

    def terms(theta):
        V = sum(t * g for t, g in zip(theta, G)) + floor * np.eye(n)
        Vi = _inv_spd(V)
        ViA = Vi @ A
        cov_x = np.linalg.inv(A.T @ ViA)
        return Vi, cov_x, Vi - ViA @ cov_x @ ViA.T

    def scoring(theta):
        _, _, P = terms(theta)
        PG = [P @ g for g in G]
        Py = P @ y
        info = np.array([[0.5 * np.sum(a * b.T) for b in PG] for a in PG])
        u = np.array([0.5 * Py @ g @ Py for g in G])
        rhs = u[est] - info[np.ix_(est, ~est)] @ theta[~est]
        return info, np.linalg.solve(info[np.ix_(est, est)], rhs)

    for _ in range(max_iter):
        new = theta.copy()
        new[est] = np.maximum(scoring(theta)[1], 0.0)
        done = np.all(np.abs(new - theta) <= tol * np.maximum(np.abs(new), 1e-3 * np.max(new)))
        theta = new
        if done:
            break
    info, step = scoring(theta)
    signed = theta.copy()
    signed[est] = step
    negative = np.zeros(q, bool)
    negative[est] = step < 0
    Vi, cov_x, P = terms(theta)
    sig = np.zeros(q)
    var_theta = np.diag(np.linalg.inv(info[np.ix_(est, est)]))
    sig[est] = np.where(var_theta >= 0, np.sqrt(np.abs(var_theta)), np.nan)
    x = cov_x @ (A.T @ Vi @ y)
    r = y - A @ x
    return x, cov_x, theta, sig, r, float(r @ Vi @ r), signed, negative

#: The factor of the adjustment covariance is estimated only when its relative sigma is
#: below this (else held at 1: the INS noise dominates and the factor does not matter).
LAMBDA_MAX_REL = 0.3
#: Rounds of the boresight fit at most (REML fits and GLS steps).
MAX_ROUNDS = 30
#: A banded fit frees ``lambda`` only when the fit with ``lambda = 1`` gives it a relative
#: sigma below this, twice :data:`LAMBDA_MAX_REL`.  The relative sigma falls slowly as
#: ``lambda`` grows (1000-image base-free block of ``bench/bench_block_scale.py``: 0.92 at
#: 1, 0.64 at the free estimate 2.9): above this bound the free estimate would have to be
#: tens of times the held one to pass :data:`LAMBDA_MAX_REL`, and the data, which enter
#: the information, would have shown it.
LAMBDA_TRY_REL = 2 * LAMBDA_MAX_REL


def _fit(y, A, C, groups, start=None, cache=None):
    """GLS + REML of ``y = A x + e``, ``V = lambda C + diag(s^2[groups])``.

    ``lambda`` checks the block's covariance ``C`` (about 1 when the conditions of points
    seen in three or more images are weighted jointly, i.e. with tie-point ids; about 1.4
    without them) and takes up a misfit when the data can tell it from the INS noise.
    ``C`` is a dense matrix, or a block's covariance operator
    (:class:`photogrammetry.adjustment.block_covariance.BandedCovariance`: REML by
    :func:`photogrammetry.adjustment.reml.gls_reml_banded`, started from `start`, a dict that keeps
    the last components (rad^2) for the next call and whether ``lambda`` is held).  A
    banded fit first holds ``lambda = 1``; it frees it only when the held fit's
    information gives ``lambda`` a relative sigma below :data:`LAMBDA_TRY_REL` (else the
    free fit could not pass :data:`LAMBDA_MAX_REL` and would only cost iterations, up to
    runaway ones where ``lambda`` is not separable from the INS noise).
    """
    banded = not isinstance(C, np.ndarray)
    scale = _scale(y, C)
    start = {} if start is None else start

    def solve(fixed, info=None):
        if banded:
            key = "free" if fixed is None else "held"
            t0 = start.get(key)
            t0 = None if t0 is None else np.concatenate([t0[:1], t0[1:] / scale])
            if t0 is not None and fixed is not None:
                t0[0] = fixed[0]
            res = gls_reml_banded(y, A, C, groups, scale, fixed, t0, info=info,
                                  cache=cache)
            if np.all(np.isfinite(res[2])):
                start[key] = np.concatenate([res[2][:1], res[2][1:] * scale])
            return res
        D = [np.diag((groups == a) * scale) for a in range(3)]
        return gls_variance_components(y, A, [C] + D, fixed=fixed)
    held = None
    if start.get("lambda_held"):
        out = held = solve([1.0, None, None, None])
    else:
        if banded and "free" not in start:   # the free lambda starts from the held fit
            info = {}
            held = solve([1.0, None, None, None], info)
            start["free"] = start.get("held")
            if not info["lambda_rel_sigma"] < LAMBDA_TRY_REL:
                start["lambda_held"] = True
        out = held if start.get("lambda_held") else solve(None)
    lam, lam_sigma = out[2][0], out[3][0]
    if not (lam > 0 and lam_sigma < LAMBDA_MAX_REL * lam):
        out = held if held is not None else solve([1.0, None, None, None])
        lam, lam_sigma = 1.0, 0.0
        start["lambda_held"] = True
    x, cov_x, theta, sig, r, chi2, signed, negative = out
    return (x, cov_x, lam, lam_sigma, theta[1:] * scale, sig[1:] * scale, r, chi2,
            signed[1:] * scale, negative[1:])


def _scale(y, C):
    """The variance scale of the fit: mean variance of ``C`` or of ``y``."""
    trace = np.trace(C) if isinstance(C, np.ndarray) else np.einsum("kaa->", C.blocks)
    return max(trace / len(y), float(np.mean(y ** 2)), 1e-30)


def _gls(y, A, C, groups, lam, s2, cache=None):
    """GLS estimate of ``y = A x + e`` with the variance components held,
    ``V = lam C + diag(s2[groups])`` (one factorization of ``V``): ``x`` and its
    covariance ``(A' V^-1 A)^-1``."""
    d = s2[groups] + 1e-12 * _scale(y, C)
    if isinstance(C, np.ndarray):
        L = np.linalg.cholesky(lam * C + np.diag(d))
        W = np.linalg.solve(L, np.column_stack([A, y]))
        Wa, Wy = W[:, :-1], W[:, -1]
        cov = np.linalg.inv(Wa.T @ Wa)
        return cov @ (Wa.T @ Wy), cov
    Vs = banded_v(C, lam, d, cache=cache)
    ViA = Vs.solve(A)
    cov = np.linalg.inv(A.T @ ViA)
    return cov @ (ViA.T @ y), cov


def _small(v, cov):
    """The Gauss-Newton increment is negligible: below 1e-12 rad, or below 1e-3 of its
    own sigma in every component."""
    sig = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return bool(np.max(np.abs(v)) < 1e-12 or np.all(np.abs(v) <= 1e-3 * sig))


def _means(C, lam, s2, ones, d, k, cache=None):
    """Sigma of the arithmetic mean ``sqrt(1' V 1) / k``, covariance and value of the
    GLS mean, with ``V = lam C + diag(s2)`` (dense C or a banded operator)."""
    if isinstance(C, np.ndarray):
        V = lam * C + np.diag(s2)
        mean_sigma = np.sqrt(np.einsum("na,nm,ma->a", ones, V, ones)) / k
        Vi = _inv_spd(V + 1e-12 * np.trace(V) / len(V) * np.eye(len(V)))
        Vi_ones = Vi @ ones
    else:
        Vs = banded_v(C, lam, s2 + 1e-12 * (lam * np.einsum("kaa->", C.blocks)
                                            + np.sum(s2)) / len(s2), cache=cache)
        mean_sigma = np.sqrt(np.einsum("na,na->a", ones, Vs.dot(ones))) / k
        Vi_ones = Vs.solve(ones)
    cov_mean = np.linalg.inv(ones.T @ Vi_ones)
    return mean_sigma, cov_mean, cov_mean @ (Vi_ones.T @ d)


def assess(result, angles_ins, system, datum, method, progress=None):
    """Compare the INS angles with a block adjustment.

    Parameters
    ----------
    result : photogrammetry.adjustment.block.BlockResult
    angles_ins : array_like (m, 3)
        INS angles, rad, system order.
    system : str
    datum : {"first", "ins", "none"}
    method : {"known-base", "relative", "base-free"}
    progress : callable(done, total), optional
        Called after each round of the boresight fit (a REML fit or a GLS step: one or
        several factorizations of the block's covariance), with at most
        :data:`MAX_ROUNDS`.

    Returns
    -------
    Assessment
    """
    ins = np.asarray(angles_ins, dtype=float)
    used = result.adjusted & (result.sigma.max(axis=1) > 0)
    diff = np.where(used[:, None], wrap_to_pi(ins - result.angles), 0.0)
    d = diff[used]
    k = len(d)
    negative = np.zeros(3, bool)
    boresight_iterations = 0
    idx = (3 * np.flatnonzero(used)[:, None] + np.arange(3)).ravel()
    if result.cov is None:                  # banded block: its covariance as an operator
        C = result.cov_op
        if not np.array_equal(C.free, used):
            raise ValueError("the compared images must be the block's free images")
    else:
        C = result.cov[np.ix_(idx, idx)]
    groups = np.tile(np.arange(3), k)
    ones = np.zeros((3 * k, 3))
    ones[np.arange(3 * k), groups] = 1.0
    z3 = np.zeros(3)
    observable = method == "known-base" and datum != "first"
    mean, mean_sigma, gls_mean, gls_mean_sigma = d.mean(axis=0) if k else z3, z3, z3, z3
    rms = np.sqrt(np.mean(d ** 2, axis=0)) if k else z3
    beta, beta_sigma, e = z3, z3, d - mean
    theta, theta_sigma, chi2, dof, lam, lam_sigma = z3, z3, 0.0, 0, 1.0, 0.0
    signed = z3
    if k > 6:
        R, M = K.rotation_and_axes(result.angles[used], system)
        J = np.linalg.solve(M, R)               # d_angles = J @ camera-frame rotation
        # regressors: the camera-frame boresight, and (when the datum comes from the INS)
        # a common model-frame rotation of the whole block as well
        X = -J if observable else np.concatenate([-J, np.linalg.inv(M)], axis=2)
        A = X.reshape(3 * k, -1)
        # Gauss-Newton on the exact model R_ins = P R_true B^T: correct the INS attitude
        # by the current B (and P), fit the increment, until it vanishes
        R_ins = angles_to_matrix(ins[used], system)
        B_k, P_k = np.eye(3), np.eye(3)
        d_k = d
        # the REML fit (several factorizations) at the first round, then GLS rounds with
        # its components held (one factorization each) until the increments are
        # negligible, then the REML fit again there (from its last components) until its
        # own increment is negligible
        start, fits, ready = {}, 0, True
        cache = {}               # the last factor of V, asked for again at the same V
        for boresight_iterations in range(1, MAX_ROUNDS + 1):
            final = ready and fits < 4
            if final:
                (v, cov_v, lam, lam_sigma, theta, theta_sigma, r, chi2, signed,
                 negative) = _fit(d_k.ravel(), A, C, groups, start, cache)
                fits += 1
            else:
                v, cov_g = _gls(d_k.ravel(), A, C, groups, lam, theta, cache)
            B_k = B_k @ rotvec_to_dcm(v[:3])
            if not observable:
                P_k = P_k @ rotvec_to_dcm(v[3:6])
            d_k = wrap_to_pi(matrix_to_angles(P_k.T @ R_ins @ B_k, system)
                             - result.angles[used])
            ready = _small(v, cov_v if final else cov_g)
            if progress is not None:
                progress(boresight_iterations, MAX_ROUNDS)
            if final and ready:
                break
        if fits == 0:
            raise RuntimeError("the boresight fit did not converge")   # not reached
        dof = 3 * k - A.shape[1]
        e = r.reshape(k, 3)
        mean_sigma, cov_mean, gls_mean = _means(C, lam, theta[groups], ones, d.ravel(), k,
                                                cache)
        cache.clear()
        gls_mean_sigma = np.sqrt(np.diag(cov_mean))
        if observable:
            beta_sigma = np.sqrt(np.diag(cov_v)[:3])
            beta = matrix_to_angles(B_k, "omega-phi-kappa")             # Rx Ry Rz angles
    # a negative variance component is not estimable: NaN and flagged, never 0
    ins_noise = np.where(negative, np.nan, np.sqrt(theta))
    # sigma of s from that of s^2 (delta method; the bound's half-width at s = 0)
    pos = ins_noise > 0
    ins_noise_sigma = np.where(pos, theta_sigma / (2 * np.where(pos, ins_noise, 1)),
                               np.sqrt(theta_sigma))
    adj_var = np.mean(result.sigma[used] ** 2, axis=0) if k else z3
    names = tuple(system.split("-"))
    return Assessment(names, used, diff, mean, mean_sigma, gls_mean, gls_mean_sigma, rms,
                      beta, beta_sigma, observable, ins_noise, ins_noise_sigma,
                      np.sqrt(np.mean(e ** 2, axis=0)) if k else z3, np.sqrt(adj_var),
                      chi2, dof, lam, lam_sigma, _image_correlations(result.cov_blocks()),
                      np.asarray(signed, float), negative, boresight_iterations)
