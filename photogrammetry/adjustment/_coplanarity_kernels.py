"""Vectorized Gauss-Newton kernels of the coplanarity adjustment (many pairs at once).

Every array has a leading pair axis ``P`` and, for tie points, a point axis ``n``
(padded; ``mask`` says which entries are real).  Rays are camera-frame photo rays
``u = (x, y, -f)`` in mm; ``R = C_mc`` takes them into the model (mapping) frame.

The condition of a tie point is the coplanarity of the base and the two rays,
``g = det[b, R1 u1, R2 u2] = b . N`` with ``N = r1 x r2``; its variance is propagated
from the four photo coordinates (each with sigma ``sigma_xy`` mm), which makes the
weighted least squares on ``g`` the first-order Gauss-Helmert (Sampson) solution.

Modes (the unknowns): ``"known"`` the 3 angles of image 2, base fixed; ``"relative"``
3 angles + 2 base-direction parameters (tangent plane of the unit sphere);
``"free"`` the 3 angles with the base direction eliminated at every iterate: the base is
the unit null vector of the weighted stack of the N_i (variable projection; no base is
needed as input), and the angle step is the Schur complement of the full normal
equations (identical to solving them and dropping the base step).  Q and J are those of
the full problem (angles first, then the two base-direction nuisances).
"""
import numpy as np

from ins.common.errors import InputError
from ins.nav.rotation import rot_x, rot_y, rot_z
from photogrammetry.adjustment._pair_kernels import (  # noqa: F401 (joint_weight_blocks: block_conditions)
    joint_weight_blocks, solve_pairs_kernel)

# axis index of the primary, secondary, tertiary rotation for each angle system, and the
# sign of the angle in it: phi-omega-kappa is Ry(-phi) Rx(omega) Rz(kappa) (conventions.md)
_AXES = {"phi-omega-kappa": (1, 0, 2), "omega-phi-kappa": (0, 1, 2)}
_SIGNS = {"phi-omega-kappa": (-1.0, 1.0, 1.0), "omega-phi-kappa": (1.0, 1.0, 1.0)}
_ROT = (rot_x, rot_y, rot_z)
STATUS_OK, STATUS_NOT_CONVERGED, STATUS_SINGULAR, STATUS_TOO_FEW = 0, 1, 2, 3
#: Internal (compiled kernel): a condition with zero or non-finite variance; never returned,
#: :func:`solve_pairs` raises InputError naming the observation.
STATUS_ZERO_VARIANCE = 5


def _refuse_zero_variance(pair, point, var, sigma_xy):
    raise InputError(
        f"pair {pair}, tie point {point}: the coplanarity condition has variance {var!r} "
        f"(photo-coordinate sigma {sigma_xy!r} mm); a zero or non-finite variance has no "
        "weight (expected sigma > 0 mm and a point off the base line, finite coordinates)")


def rotation_and_axes(angles, system):
    """``R = C_mc`` of angle triplets and the model-frame axes of their partial rotations.

    Parameters
    ----------
    angles : ndarray, shape (P, 3)
        Angles in the order of the system's name, rad.
    system : str
        ``"phi-omega-kappa"`` or ``"omega-phi-kappa"``.

    Returns
    -------
    R : ndarray, shape (P, 3, 3)
    M : ndarray, shape (P, 3, 3)
        Column k is the model-frame axis of angle k, so that ``dR = skew(M @ d_angles) R``
        (for phi-omega-kappa the axis of phi is ``-y``: ``R = Ry(-phi) Rx(omega) Rz(kappa)``).
    """
    order, signs = _AXES[system], _SIGNS[system]
    angles = np.asarray(angles, dtype=float).reshape(-1, 3)
    E = np.eye(3)
    R = np.broadcast_to(E, (len(angles), 3, 3)).copy()
    M = np.empty((len(angles), 3, 3))
    for k, (axis, sign) in enumerate(zip(order, signs)):
        M[:, :, k] = sign * R[:, :, axis]    # axis of rotation k, rotated by the earlier ones
        R = R @ _ROT[axis](sign * angles[:, k])
    return R, M


def tangent_basis(b):
    """Two orthonormal vectors perpendicular to each unit vector ``b`` (P, 3) -> (P, 3, 2)."""
    helper = np.where(np.abs(b[:, :1]) < 0.8, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(b, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(b, e1)
    return np.stack([e1, e2], axis=2)


def condition_terms(r1, r2, b, R1, R2, sigma_xy):
    """Misclosures, their variances and the partial derivatives of ``g = b . (r1 x r2)``.

    Returns ``g`` (P, n), ``var`` (P, n) in mm^2 units of g, ``N`` (P, n, 3) = dg/db and
    ``A`` (P, n, 3) = dg/dtheta2 (small rotation of image 2 in the model frame).
    """
    N = np.cross(r1, r2)
    g = np.einsum("pni,pi->pn", N, b)
    d_u1, d_u2 = obs_derivatives(r1, r2, b, R1, R2)
    var = sigma_xy ** 2 * (np.sum(d_u1 ** 2, axis=2) + np.sum(d_u2 ** 2, axis=2))
    A = np.cross(r2, np.cross(b[:, None, :], r1))
    return g, var, N, A


def obs_derivatives(r1, r2, b, R1, R2):
    """Derivatives of ``g = b . (r1 x r2)`` by the photo coordinates (x, y) of the point in
    image 1 and in image 2: ``R1^T (r2 x b)`` and ``R2^T (b x r1)``, two arrays (P, n, 2)."""
    bb = b[:, None, :]
    d_u1 = np.einsum("pji,pnj->pni", R1, np.cross(r2, bb))[..., :2]
    d_u2 = np.einsum("pji,pnj->pni", R2, np.cross(bb, r1))[..., :2]
    return d_u1, d_u2


def smallest_direction(N, w):
    """Unit vector b minimizing sum w (b . N)^2 per pair (sign: first non-zero b . (1,0,0) >= 0)."""
    S = np.einsum("pn,pni,pnj->pij", w, N, N)
    _, vecs = np.linalg.eigh(S)
    return vecs[:, :, 0]


def _solve(H, rhs):
    """Batched solve with a singularity flag (relative reciprocal condition < 1e-13)."""
    scale = np.sqrt(np.abs(np.einsum("pii->pi", H))) + 1e-300
    Hs = H / scale[:, :, None] / scale[:, None, :]
    ok = np.isfinite(Hs).all(axis=(1, 2))
    ev = np.full(Hs.shape[:2], np.nan)
    ev[ok] = np.linalg.eigvalsh(Hs[ok])
    ok &= ev[:, 0] > 1e-13 * ev[:, -1]
    Hs[~ok] = np.eye(H.shape[1])
    x = np.linalg.solve(Hs, (rhs / scale)[..., None])[..., 0] / scale
    x[~ok] = 0.0
    return x, ok


def solve_pairs(u1, u2, mask, R1, angles2, base, mode, system, sigma_xy=1.0,
                max_iter=30, tol=1e-11, engine="compiled"):
    """Gauss-Newton on many pairs at once.

    Parameters
    ----------
    u1, u2 : ndarray, shape (P, n, 3)
        Camera rays (x, y, -f) in mm of the tie points in image 1 and image 2.
    mask : ndarray of bool, shape (P, n)
        Which points take part.
    R1 : ndarray, shape (P, 3, 3)
        Fixed ``C_mc`` of image 1.
    angles2 : ndarray, shape (P, 3)
        Initial angles of image 2, rad (system order).
    base : ndarray, shape (P, 3)
        Base vector (mode "known", any length) or initial direction ("relative";
        ignored by "free").
    mode : {"known", "relative", "free"}
    sigma_xy : float
        A-priori sigma of one photo coordinate, mm.
    engine : {"compiled", "numpy"}
        The compiled per-pair kernel (fast; ``"numba"``, its former name, is accepted)
        or the vectorized numpy form (reference).

    Returns
    -------
    dict with ``angles`` (P, 3), ``base`` (P, 3) unit, ``Q`` (P, k, k) cofactor matrix of
    the unknowns (angles first), ``vtpv`` (P,), ``redundancy`` (P,), ``iterations`` (P,),
    ``status`` (P,), ``g``, ``var``, ``J`` (the final conditions and their Jacobian,
    for the outlier tests), ``w``.
    """
    P = len(u1)
    k = 3 if mode == "known" else 5
    if not (np.isfinite(sigma_xy) and sigma_xy > 0):
        raise InputError(f"sigma_xy: the photo-coordinate sigma must be > 0 mm (it weighs "
                         f"every condition), got {sigma_xy!r}")
    n_used = mask.sum(axis=1)
    need = {"known": 3, "relative": 5, "free": 5}[mode]
    status = np.where(n_used < need, STATUS_TOO_FEW, STATUS_NOT_CONVERGED)
    angles = np.array(angles2, dtype=float, copy=True)
    b = np.array(base, dtype=float, copy=True)
    b_len = np.linalg.norm(b, axis=1)
    b = b / np.where(b_len > 0, b_len, 1.0)[:, None]
    if engine in ("compiled", "numba"):
        return _solve_compiled(u1, u2, mask, R1, angles, b, mode, system, sigma_xy, max_iter,
                            tol, status, n_used, k)
    r1 = np.einsum("pij,pnj->pni", R1, u1)
    if mode == "free":
        R2, _ = rotation_and_axes(angles, system)
        b = smallest_direction(np.cross(r1, np.einsum("pij,pnj->pni", R2, u2)),
                               mask.astype(float))
    iterations = np.zeros(P, dtype=int)
    active = status == STATUS_NOT_CONVERGED
    Q = np.zeros((P, k, k))
    H = np.zeros((P, k, k))
    for it in range(max_iter + 1):
        R2, M2 = rotation_and_axes(angles, system)
        r2 = np.einsum("pij,pnj->pni", R2, u2)
        g, var, N, A = condition_terms(r1, r2, b, R1, R2, sigma_xy)
        if mode == "free":          # profile the base out with the current weights
            w = np.where(mask & (var > 0), 1.0 / np.where(var > 0, var, 1.0), 0.0)
            b = smallest_direction(N, w)
            g, var, N, A = condition_terms(r1, r2, b, R1, R2, sigma_xy)
        bad = active[:, None] & mask & ~(var > 0)
        if bad.any():
            pp, ii = np.argwhere(bad)[0]
            _refuse_zero_variance(int(pp), int(ii), float(var[pp, ii]), sigma_xy)
        w = np.where(mask, 1.0 / np.where(var > 0, var, 1.0), 0.0)
        J = np.einsum("pni,pij->pnj", A, M2)
        E = None
        if mode != "known":
            E = tangent_basis(b)
            J = np.concatenate([J, np.einsum("pni,pij->pnj", N, E)], axis=2)
        H = np.einsum("pn,pni,pnj->pij", w, J, J)
        grad = np.einsum("pn,pni,pn->pi", w, J, g)
        step, ok = _solve(H, -grad)
        singular = active & ~ok
        status[singular] = STATUS_SINGULAR
        active &= ok
        if it == max_iter or not active.any():
            break
        step[~active] = 0.0
        angles += step[:, :3]
        if mode == "relative":
            b = b + np.einsum("pij,pj->pi", E, step[:, 3:])
            b /= np.linalg.norm(b, axis=1, keepdims=True)
        iterations += active
        done = active & (np.max(np.abs(step), axis=1) < tol)
        status[done] = STATUS_OK
        active &= ~done
    good = status <= STATUS_NOT_CONVERGED
    Q[good] = np.linalg.inv(H[good])
    vtpv = np.einsum("pn,pn,pn->p", w, g, g)
    return {"angles": angles, "base": b, "Q": Q, "vtpv": vtpv,
            "redundancy": np.maximum(n_used - (3 if mode == "known" else 5), 0),
            "iterations": iterations, "status": status, "g": g, "var": var, "J": J, "w": w}


def _solve_compiled(u1, u2, mask, R1, angles, b, mode, system, sigma_xy, max_iter, tol,
                    status, n_used, k):
    P, n = mask.shape
    out = {"Q": np.zeros((P, k, k)), "vtpv": np.zeros(P), "g": np.zeros((P, n)),
           "var": np.zeros((P, n)), "J": np.zeros((P, n, k)), "w": np.zeros((P, n)),
           "iterations": np.zeros(P, dtype=np.int64)}
    bad_point = np.full(P, -1, dtype=np.int64)
    f64 = np.ascontiguousarray
    solve_pairs_kernel(f64(u1, dtype=float), f64(u2, dtype=float), f64(mask, dtype=np.bool_),
                       f64(R1, dtype=float), angles, b, _MODE_ID[mode], _ORDER[system],
                       _SIGN[system], float(sigma_xy) ** 2, int(max_iter), float(tol), status,
                       out["iterations"], out["Q"], out["vtpv"], out["g"], out["var"],
                       out["J"], out["w"], bad_point)
    if np.any(status == STATUS_ZERO_VARIANCE):
        pp = int(np.flatnonzero(status == STATUS_ZERO_VARIANCE)[0])
        ii = int(bad_point[pp])
        _refuse_zero_variance(pp, ii, float(out["var"][pp, ii]), sigma_xy)
    out.update(angles=angles, base=b, status=status,
               redundancy=np.maximum(n_used - (3 if mode == "known" else 5), 0))
    return out


# --------------------------------------------------------------------------
# the compiled kernel (photogrammetry.adjustment._pair_kernels): the same Gauss-Newton,
# one pair at a time (no temporaries); axis order and signs of each system as arrays
_ORDER = {s: np.array(a) for s, a in _AXES.items()}
_SIGN = {s: np.array(a) for s, a in _SIGNS.items()}
_MODE_ID = {"known": 0, "relative": 1, "free": 2}
