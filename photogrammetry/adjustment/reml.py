"""GLS with REML variance components for a block's covariance kept as an operator.

The assessment's model (:mod:`photogrammetry.adjustment.assessment`) is ``y = A x + e`` with
``V = lambda C + sum_a s_a G_a``, ``C = S^-1 K S^-1`` the block's covariance
(:class:`photogrammetry.adjustment.block_covariance.BandedCovariance`) and ``G_a`` the diagonal
indicator of angle ``a`` (times `scale`).  Without forming ``V``:

    V^-1 = S (lambda K + S D S)^-1 S,     D = sum_a s_a G_a

(``lambda K + S D S`` is sparse, banded in the normal matrix's order: one banded Cholesky
per iterate).  The components are estimated by average-information REML (Gilmour,
Thompson and Cullis 1995): the score ``u_a = (Py' G_a Py - tr(P G_a)) / 2`` with the
traces of the diagonal components by Hutchinson's estimator (fixed Rademacher probes:
deterministic), the trace of ``P C`` from ``tr(P V) = n - p``, and the
average-information matrix ``AI_ab = Py' G_a P G_b Py / 2`` (exact, no trace).  The
REML solution is that of the dense :func:`photogrammetry.adjustment.assessment.gls_variance_components`
up to the Hutchinson error of the traces (``tests/test_assessment.py`` states it).
"""
import numpy as np
from scipy import sparse
from scipy.linalg import cho_factor, cho_solve
from scipy.sparse.linalg import splu

from ins.common.errors import InputError
from photogrammetry.adjustment.banded import BandedSPD, SparseSPD, rcm_order
from photogrammetry.adjustment.block_covariance import DENSE_MAX_ANGLES

__all__ = ["BandedV", "DenseV", "banded_v", "gls_reml_banded", "PROBES",
           "DENSE_V_MAX_ANGLES"]

#: Hutchinson probes of the traces (Rademacher, seed 0).
PROBES = 64
#: A bordered block (relative, base-free) of at most this many angles is assessed on
#: its covariance as a dense matrix (:class:`DenseV`), a larger one on the sparse
#: augmented system (:class:`BandedV`): the bound up to which the block keeps it
#: (:data:`photogrammetry.adjustment.block_covariance.DENSE_MAX_ANGLES`).
DENSE_V_MAX_ANGLES = DENSE_MAX_ANGLES
#: Smallest INS variance (relative to the largest adjustment variance) for the
#: Woodbury form of ``V^-1``.
WOODBURY_MIN = 1e-6
#: The REML iteration has also converged when every estimated component's step is
#: below this fraction of its own sigma (from the average information) and has stopped
#: shrinking (at least half the last one, in sigmas): the iterates have reached the noise
#: of the solves.  Before the augmented system was factored in the interleaved order
#: (:func:`_interleaved_order`) those were accurate to 1e-5 relative near a bound and
#: ``tol`` alone ran to ``max_iter`` (a 470-image base-free block: 60 iterations of each
#: fit); iterates that still converge (linearly, at a rate below one half, or faster)
#: stop at ``tol`` as before.  The same fraction as the boresight fit's increments
#: (:func:`photogrammetry.adjustment.assessment._small`).
STEP_SIGMA = 1e-3
#: Steps clipped toward zero in a row after which a component's bound is tried at once
#: (the clipped steps divide it by e^1.5 each: about 16 of them to reach the bound).
BOUND_TRY = 2
#: Largest rate of a linear convergence that is extrapolated.  The average information
#: is not the Hessian of the restricted likelihood, so the scoring converges linearly
#: (a 470-image base-free block: each step about 0.35 of the last, lambda and the INS
#: variance along one direction); when two successive steps (log theta) are parallel
#: within 10 % with a ratio ``r`` below this, the step is taken as the sum of its
#: geometric series, ``step / (1 - r)``, and the iteration goes on from there (its stop
#: is the same).
EXTRAPOLATE_RATE = 0.8
#: How parallel two steps must be for the extrapolation: ``|s_k - r s_(k-1)|`` at most
#: this fraction of ``max |s_k|`` in every component.
EXTRAPOLATE_PARALLEL = 0.1
#: Steps not parallel but each component's own ratio in (0, EXTRAPOLATE_RATE):
#: each extrapolated with its own ratio.
EXTRAPOLATE_EACH = True


class BandedV:
    """``V = lambda C + diag(d)`` with ``C = S^-1 K S^-1``: products and solves.

    Two exact forms: ``V^-1 = S (lambda K + S D S)^-1 S`` (any ``d >= 0``; bandwidth
    twice the normal matrix's) and, without the position term (``K = sigma0^2 S``) and
    when every ``d`` is at least :data:`WOODBURY_MIN` of the largest diagonal of ``C``,
    ``V^-1 = D^-1 - D^-1 (S / (lambda sigma0^2) + D^-1)^-1 D^-1`` (Woodbury: the normal
    matrix's bandwidth, about four times cheaper; the cancellation costs at most
    ``1 / WOODBURY_MIN`` times the rounding error).

    Bordered operator (relative methods: ``S^-1 = (H^-1)_aa`` with ``H`` the normal
    matrix of the angles and the bases): Woodbury with the bordered
    ``H / (lambda sigma0^2) + diag(D^-1, 0)`` (sparse LU), whose Schur complement of the bases is
    ``S / (lambda sigma0^2) + D^-1``; else the quasi-definite augmented system
    ``[[H / (lambda sigma0^2), E], [E', -D]] [z; x] = [0; -v]`` (``E`` selects the
    angles; sparse L D L' in the order of :func:`_interleaved_order`) gives
    ``x = V^-1 v``; ``lambda = 0``: ``V = D``."""

    def __init__(self, op, lam, d, perm=None):
        self.op, self.lam, self.d = op, float(lam), np.asarray(d, float)
        S = op.S
        cmax = op.sigma0 ** 2 * np.max(np.einsum("kaa->ka", op.blocks)) if op.blocks.size else 0
        self.woodbury = (op.TX is None and lam > 0 and len(self.d)
                         and np.min(self.d) >= WOODBURY_MIN * max(lam * cmax, 1e-300))
        self.n = n = len(self.d)
        self.lu = None
        if getattr(op, "bordered", False):
            nb = S.shape[0] - n
            if self.woodbury:
                M = S / (lam * op.sigma0 ** 2) + sparse.diags(
                    np.concatenate([1.0 / self.d, np.zeros(nb)]))
                self.f = SparseSPD(M, what="assessment covariance")
            elif lam > 0:
                self.lu = _AugmentedLDL(op, n, lam * op.sigma0 ** 2, self.d)
            return
        if self.woodbury:
            M = S / (lam * op.sigma0 ** 2) + sparse.diags(1.0 / self.d)
        else:
            M = lam * op.K() + S @ sparse.diags(self.d) @ S
        self.f = BandedSPD(M, perm=perm, what="assessment covariance")

    def _solve_woodbury_inner(self, w):
        if not getattr(self.op, "bordered", False):
            return self.f.solve(w)
        pad = np.zeros((self.op.S.shape[0],) + w.shape[1:])
        pad[:self.n] = w
        return self.f.solve(pad)[:self.n]

    def solve(self, v):
        """``V^-1 v``."""
        v = np.asarray(v, dtype=float)
        Di = 1.0 / (self.d if v.ndim == 1 else self.d[:, None])
        if self.woodbury:
            return Di * v - Di * self._solve_woodbury_inner(Di * v)
        if getattr(self.op, "bordered", False):
            if self.lu is None:                      # lambda = 0: V = D
                return Di * v
            N = self.op.S.shape[0]
            rhs = np.zeros((N + self.n,) + v.shape[1:])
            rhs[N:] = -v
            return self.lu.solve(rhs)[N:]
        return self.op.S @ self.f.solve(self.op.S @ v)

    def dot(self, v):
        """``V v``."""
        dv = self.d * v if v.ndim == 1 else self.d[:, None] * v
        return self.lam * self.op.apply(v) + dv


    def apply_c(self, v):
        """``C v``."""
        return self.op.apply(v)


class DenseV:
    """``V = lambda C + diag(d)`` with ``C`` the block's covariance as a dense matrix
    (:meth:`photogrammetry.adjustment.block_covariance.BandedCovariance.dense`): LAPACK's
    Cholesky of ``V``, solves and products.  For a bordered block of up to
    :data:`DENSE_V_MAX_ANGLES` angles this is several times cheaper than the sparse
    factor of the augmented system (:class:`BandedV`; 470 base-free images, 1407
    angles: 0.05 s against 0.2 s a factorization, 0.01 s against 0.07 s the solves of
    the probes) and exact for any ``d >= 0`` (no Woodbury cancellation)."""

    def __init__(self, op, C, lam, d):
        self.op, self.C, self.lam, self.d = op, C, float(lam), np.asarray(d, float)
        self.n = len(self.d)
        self.woodbury = False
        V = self.lam * C
        V[np.diag_indices(self.n)] += self.d
        try:
            self.cf = cho_factor(V, lower=True, overwrite_a=True, check_finite=False)
        except np.linalg.LinAlgError:
            raise InputError("the assessment covariance lambda C + D is not positive "
                             f"definite (lambda {lam:g})") from None

    def solve(self, v):
        """``V^-1 v``."""
        return cho_solve(self.cf, np.asarray(v, dtype=float), check_finite=False)

    def dot(self, v):
        """``V v``."""
        dv = self.d * v if v.ndim == 1 else self.d[:, None] * v
        return self.lam * (self.C @ v) + dv

    def apply_c(self, v):
        """``C v``."""
        return self.C @ v


def _dense_c(op, cache):
    """The dense ``C`` of `op` when the assessment works on it (bordered, at most
    :data:`DENSE_V_MAX_ANGLES` angles), kept in `cache` for the next ``V``; else None."""
    if not (getattr(op, "bordered", False) and op.n_angles <= DENSE_V_MAX_ANGLES):
        return None
    if op.C is not None:                    # kept by the block
        return op.C
    kept = None if cache is None else cache.get("C")
    if kept is not None and kept[0] is op:
        return kept[1]
    try:
        C = op.dense()
    except ValueError:                      # no L D L' of the bases' block: sparse
        return None
    if cache is not None:
        cache["C"] = (op, C)
    return C


def _interleaved_order(op, n):
    """Elimination order of the augmented system ``[[H / c, E], [E', -D]]``: the order
    of the block's sparse factor of ``H`` (:class:`photogrammetry.adjustment.banded.SparseSPD`,
    minimum degree), each angle's ``x`` right after its angle.  The angle's pivot is then
    ``H``'s and the ``x``'s about ``-V_ii`` (quasi-definite: diagonal pivots exist in any
    order), where SuperLU's own column order with partial pivoting eliminated an ``x``
    (pivot ``-d``, tiny for a component at its bound) first, and the solves lost 1e-5
    relative on a ``V`` of condition 1e4 (470-image base-free block); in this order they
    are accurate to 1e-11, and the factor has a fifth of the non-zeros.  None when the
    block's solver has no such order (banded)."""
    solver = getattr(op, "solver", None)
    pc = getattr(solver, "perm_c", None)
    if pc is None and getattr(op, "bordered", False):   # a CHOLMOD factor: SuperLU's
        op.solver = SparseSPD(op.S, what="block normal matrix")
        pc = op.solver.perm_c
    N = op.S.shape[0]
    if pc is None or len(pc) != N:
        return None
    key = np.concatenate([2 * np.asarray(pc, float), 2 * np.asarray(pc[:n], float) + 1])
    return np.argsort(key, kind="stable")


class _AugmentedLDL:
    """Sparse ``L D L'`` of the quasi-definite augmented matrix
    ``[[H / c, E], [E', -D]]`` in the order of :func:`_interleaved_order` (diagonal
    pivots), or SuperLU's LU with partial pivoting when there is no order or a pivot
    vanishes.  The permuted pattern is made once per operator (kept on it) and only its
    values are set for each ``(c, d)``: the assembly and permutation were a sixth of a
    factorization (1000 images)."""

    def __init__(self, op, n, c, d):
        self.order = None
        tpl = _augmented_pattern(op, n)
        if tpl is not None:
            A, order, h, xd, xi = tpl
            data = A.data.copy()
            data[h] /= c
            data[xd] = -d[xi]
            try:
                self.lu = splu(sparse.csc_matrix((data, A.indices, A.indptr), shape=A.shape),
                               permc_spec="NATURAL", diag_pivot_thresh=0.0,
                               options=dict(SymmetricMode=True))
                self.order = order
                return
            except RuntimeError:                     # an exactly zero pivot
                pass
        E = sparse.eye(op.S.shape[0], n)
        self.lu = splu(sparse.bmat([[op.S / c, E], [E.T, -sparse.diags(d)]], format="csc"))

    def solve(self, rhs):
        if self.order is None:
            return self.lu.solve(rhs)
        out = np.empty_like(rhs)
        out[self.order] = self.lu.solve(np.ascontiguousarray(rhs[self.order]))
        return out


def _augmented_pattern(op, n):
    """The augmented matrix with ``c = 1, d = 1`` in the interleaved order (CSC), the
    order, and where its values go: the mask of the ``H`` entries, the positions of the
    ``-d`` diagonal and their angle indices; kept on `op`.  None without an order."""
    kept = op.__dict__.get("_augmented")
    if kept is not None and kept[0] == n:
        return kept[1]
    order = _interleaved_order(op, n)
    tpl = None
    if order is not None:
        N = op.S.shape[0]
        E = sparse.eye(N, n)
        aug = sparse.bmat([[op.S, E], [E.T, -sparse.eye(n)]], format="csc")
        A = aug[order][:, order].tocsc()
        A.sort_indices()
        r = order[A.indices]
        c = order[np.repeat(np.arange(A.shape[0]), np.diff(A.indptr))]
        xd = np.flatnonzero((r >= N) & (r == c))
        tpl = (A, order, (r < N) & (c < N), xd, r[xd] - N)
    op.__dict__["_augmented"] = (n, tpl)            # the operator's private cache
    return tpl


def banded_v(op, lam, d, perm=None, cache=None):
    """:class:`BandedV` of ``(op, lam, d)``, or the last one made with `cache` when it had
    the same operator, ``lambda`` and ``d`` (to 1e-12 relative; the assessment asks for one ``V`` several
    times in a row: the REML fit's last iterate, the GLS rounds held at it, the next
    fit's start, the means; each is a factorization of the block's size).

    Parameters
    ----------
    cache : dict, optional
        Holds the last ``V`` (the caller's, for the duration of one assessment), and
        the dense ``C`` of a bordered block of up to :data:`DENSE_V_MAX_ANGLES` angles
        (:class:`DenseV`; without a cache it is formed for every ``V``).
    """
    d = np.asarray(d, float)
    last = None if cache is None else cache.get("V")
    # equal to 1e-12 relative: the next fit starts from the last components through a
    # change of scale and back (a rounding apart); or apart by at most 1e-9 of the
    # largest d: the floor (1e-12 of a scale that follows the data) of a component at
    # its bound, which moves with every round of the boresight fit (V changes by 1e-9
    # relative at most; a new factorization each round cost a fifth of the assessment)
    if (last is not None and last.op is op and last.lam == float(lam)
            and last.d.shape == d.shape
            and np.allclose(last.d, d, rtol=1e-12, atol=1e-9 * np.max(np.abs(d), initial=0))):
        return last
    C = _dense_c(op, cache)
    if cache is not None:
        cache["V"] = None                   # the previous factor freed first
    Vs = BandedV(op, lam, d, perm) if C is None else DenseV(op, C, lam, d)
    if cache is not None:
        cache["V"] = Vs
    return Vs


def _projector(Vs, A, also=None):
    """``P v = V^-1 v - V^-1 A (A' V^-1 A)^-1 A' V^-1 v`` and ``(A' V^-1 A)^-1``; with
    `also` (n, k), ``P also`` too, its ``V^-1`` solved with ``A``'s (one pass through
    the factor instead of two)."""
    if also is None:
        ViA = Vs.solve(A)
    else:
        X = Vs.solve(np.column_stack([A, also]))
        ViA, Vi_also = X[:, :A.shape[1]], X[:, A.shape[1]:]
    cov_x = np.linalg.inv(A.T @ ViA)

    def P(v, Viv=None):
        Viv = Vs.solve(v) if Viv is None else Viv
        return Viv - ViA @ (cov_x @ (A.T @ Viv))
    if also is None:
        return P, cov_x
    return P, cov_x, P(also, Vi_also)


def _diverged(y, A, op, theta):
    """The result of a free-lambda REML that ran away (lambda to 0 or the components
    to infinity: lambda is not separable from the INS noise): infinite sigma of lambda,
    so that the caller holds it (the estimates are not used)."""
    nan = np.full(A.shape[1], np.nan)
    return (nan, np.full((A.shape[1],) * 2, np.nan), theta, np.array([np.inf, 0, 0, 0]),
            np.full(len(y), np.nan), np.nan, theta, np.zeros(4, bool))


def gls_reml_banded(y, A, op, groups, scale, fixed=None, theta0=None, max_iter=60,
                    tol=1e-7, probes=PROBES, info=None, cache=None):
    """GLS + REML of ``y = A x + e``, ``V = theta_0 C + sum_a theta_{a+1} scale G_a``.

    Parameters
    ----------
    y : ndarray (n,); A : ndarray (n, p)
    op : photogrammetry.adjustment.block_covariance.BandedCovariance
        ``C`` (its images in the order of `y`, three angles each).
    groups : ndarray of int (n,)
        Angle of each element (0, 1, 2).
    scale : float
    fixed : sequence of 4 (float or None), optional
        Components held (None: estimated).
    theta0 : array_like (4,), optional
        Start (default ones).
    info : dict, optional
        Filled with ``lambda_rel_sigma``: the relative sigma of ``theta_0`` from the
        average information of all four components at the solution (also when
        ``theta_0`` is held: whether the data could tell it).
    cache : dict, optional
        Reuse of the factor of ``V`` across calls (:func:`banded_v`).

    Returns
    -------
    The tuple of :func:`photogrammetry.adjustment.assessment.gls_variance_components`:
    ``x, cov_x, theta, sigma_theta, residual, chi2, theta_signed, negative``.
    """
    n = len(y)
    cache = {} if cache is None else cache
    fixed = [None] * 4 if fixed is None else list(fixed)
    est = np.array([f is None for f in fixed])
    theta = np.array([1.0] * 4 if theta0 is None else theta0, dtype=float)
    theta[~est] = [f for f in fixed if f is not None]
    Gd = [scale * (groups == a) for a in range(3)]
    floor = 1e-12 * scale
    Z = np.random.default_rng(0).choice([-1.0, 1.0], (n, probes))
    perm = None if getattr(op, "bordered", False) else rcm_order(op.S)

    def stats(theta):
        d = sum(t * g for t, g in zip(theta[1:], Gd)) + floor
        Vs = banded_v(op, max(theta[0], 0.0), d, perm, cache)
        P, cov_x, PyZ = _projector(Vs, A, np.column_stack([y, Z]))
        Py, PZ = PyZ[:, 0], PyZ[:, 1:]
        tr_d = np.array([np.mean(np.sum(Z * PZ * g[:, None], axis=0)) for g in Gd])
        tr_c = (n - A.shape[1] - theta[1:] @ tr_d) / max(theta[0], 1e-300)
        w = np.column_stack([Vs.apply_c(Py)] + [g * Py for g in Gd])
        q = Py @ w
        u = 0.5 * (q - np.concatenate([[tr_c], tr_d]))
        AI = 0.5 * w.T @ P(w)
        return Vs, cov_x, Py, u, AI

    if theta0 is None:                  # moment start: the differences' own scatter
        cdiag = np.einsum("kaa->ka", op.blocks).ravel()
        for a in range(3):
            if est[a + 1]:
                ya, ca = y[groups == a] ** 2, cdiag[groups == a]
                theta[a + 1] = max(np.mean(ya) - np.mean(ca), 0.1 * np.mean(ya)) / scale
    # a variance component that starts at 0 (held at its bound by the last fit) stays
    # there (its log-space step cannot move it), so it is not live from the start:
    # live, its score polluted the first step of the others through the information
    # (the next fit's first lambda 1.76 for 1.25, two evaluations more)
    live = est & ~((theta == 0) & (np.arange(4) > 0))
    last = None
    clipped = np.zeros(4, int)               # steps clipped toward 0 in a row
    prev_l = prev_live = None                # the last step in log(theta)
    prev_sig = None                          # and its largest component in sigmas
    for _ in range(max_iter):
        if last is None:
            last = stats(theta)
        _, _, _, u, AI = last
        AIl = AI[np.ix_(live, live)]
        step = np.linalg.solve(AIl, u[live])
        # damped Newton in log(theta): no component changes by more than e^1.5 per step
        t = theta[live]
        rel = step / np.maximum(t, 1e-300)
        new = theta.copy()
        new[live] = t * np.exp(np.clip(rel, -1.5, 1.5))
        top = np.max(new[1:]) if np.any(new[1:] > 0) else 1.0
        gone = live & (np.arange(4) > 0) & (new < 1e-9 * top)
        new[gone] = 0.0                  # a variance at its bound: held at 0
        with np.errstate(invalid="ignore"):
            sig_live = np.sqrt(np.diag(np.linalg.inv(AIl)))
        in_sig = np.max(np.abs(new[live] - t) / sig_live, initial=0.0)
        stalled = (prev_sig is not None and in_sig <= STEP_SIGMA
                   and in_sig >= 0.5 * prev_sig)
        prev_sig = in_sig
        done = stalled or np.all(np.abs(new - theta) <= tol * np.maximum(np.abs(new),
                                                                         1e-3 * np.max(new)))
        down = np.zeros(4, bool)
        down[np.flatnonzero(live)[rel < -1.5]] = True
        live_before = live.copy()
        live &= ~gone
        if done and not gone.any():
            break               # theta kept: its step is below tol, its terms are `last`
        clipped = np.where(down & live, clipped + 1, 0)
        lstep = np.zeros(4)
        lstep[np.flatnonzero(live_before)] = np.clip(rel, -1.5, 1.5)
        lstep[~live] = 0.0
        if (prev_l is not None and not gone.any() and not down.any()
                and np.array_equal(prev_live, live) and prev_l @ prev_l > 0):
            r = float(lstep @ prev_l) / float(prev_l @ prev_l)
            with np.errstate(divide="ignore", invalid="ignore"):
                ri = lstep[live] / prev_l[live]          # each component's own rate
            if 0 < r < EXTRAPOLATE_RATE and np.all(np.abs(lstep - r * prev_l)
                                                   <= EXTRAPOLATE_PARALLEL * np.max(np.abs(lstep))):
                new[live] = theta[live] * np.exp(np.clip(lstep[live] / (1 - r), -1.5, 1.5))
                lstep = None
            elif EXTRAPOLATE_EACH and np.all((ri > 0) & (ri < EXTRAPOLATE_RATE)):
                new[live] = theta[live] * np.exp(np.clip(lstep[live] / (1 - ri), -1.5, 1.5))
                lstep = None
        prev_l, prev_live = lstep, live.copy()
        theta, last = new, None
        if est[0] and not (1e-8 < theta[0] < 1e8 and np.all(theta[1:] < 1e8)):
            return _diverged(y, A, op, theta)   # lambda not separable from the noise
        try_bound = np.flatnonzero((clipped >= BOUND_TRY) & (np.arange(4) > 0))
        if len(try_bound):
            # the bound of the component heading to 0 (KKT): held there when its score
            # at 0 points below it; else the clipped steps go on (one evaluation lost)
            trial = theta.copy()
            trial[try_bound] = 0.0
            at = stats(trial)
            if np.all(at[3][try_bound] <= 0):
                theta, last = trial, at
                live[try_bound] = False
            clipped[try_bound] = 0
    Vs, cov_x, Py, u, AI = last if last is not None else stats(theta)
    signed = theta.copy()
    signed[est] = theta[est] + np.linalg.solve(AI[np.ix_(est, est)], u[est])
    negative = np.zeros(4, bool)
    negative[est] = signed[est] < 0
    sig = np.zeros(4)
    var_theta = np.diag(np.linalg.inv(AI[np.ix_(est, est)]))
    sig[est] = np.where(var_theta >= 0, np.sqrt(np.abs(var_theta)), np.nan)
    if info is not None:
        try:
            v0 = np.linalg.inv(AI)[0, 0]
        except np.linalg.LinAlgError:
            v0 = np.inf
        info["lambda_rel_sigma"] = (np.sqrt(v0) / theta[0] if v0 >= 0 and theta[0] > 0
                                    else np.inf)
    x = cov_x @ (A.T @ Vs.solve(y))
    r = y - A @ x
    return x, cov_x, theta, sig, r, float(r @ Vs.solve(r)), signed, negative
