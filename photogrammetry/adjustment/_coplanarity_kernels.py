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
from numba import njit

from ins.common.errors import InputError
from ins.nav.rotation import rot_x, rot_y, rot_z

# axis index of the primary, secondary, tertiary rotation for each angle system, and the
# sign of the angle in it: phi-omega-kappa is Ry(-phi) Rx(omega) Rz(kappa) (conventions.md)
_AXES = {"phi-omega-kappa": (1, 0, 2), "omega-phi-kappa": (0, 1, 2)}
_SIGNS = {"phi-omega-kappa": (-1.0, 1.0, 1.0), "omega-phi-kappa": (1.0, 1.0, 1.0)}
_ROT = (rot_x, rot_y, rot_z)
STATUS_OK, STATUS_NOT_CONVERGED, STATUS_SINGULAR, STATUS_TOO_FEW = 0, 1, 2, 3
#: Internal (numba kernel): a condition with zero or non-finite variance; never returned,
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
                max_iter=30, tol=1e-11, engine="numba"):
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
    engine : {"numba", "numpy"}
        The compiled per-pair kernel (fast) or the vectorized numpy form (reference).

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
    if engine == "numba":
        return _solve_numba(u1, u2, mask, R1, angles, b, mode, system, sigma_xy, max_iter,
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


def _solve_numba(u1, u2, mask, R1, angles, b, mode, system, sigma_xy, max_iter, tol,
                 status, n_used, k):
    P, n = mask.shape
    out = {"Q": np.zeros((P, k, k)), "vtpv": np.zeros(P), "g": np.zeros((P, n)),
           "var": np.zeros((P, n)), "J": np.zeros((P, n, k)), "w": np.zeros((P, n)),
           "iterations": np.zeros(P, dtype=np.int64)}
    bad_point = np.full(P, -1, dtype=np.int64)
    f64 = np.ascontiguousarray
    solve_pairs_numba(f64(u1, dtype=float), f64(u2, dtype=float), f64(mask, dtype=np.bool_),
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
# numba kernel: the same Gauss-Newton, one pair at a time (no temporaries)
_ORDER = {s: np.array(a) for s, a in _AXES.items()}
_SIGN = {s: np.array(a) for s, a in _SIGNS.items()}
_MODE_ID = {"known": 0, "relative": 1, "free": 2}


@njit(cache=True)
def _nb_rotation(a, order, sign, R, M):
    """``R`` (3, 3) and the axes ``M`` of one angle triplet, as :func:`rotation_and_axes`."""
    for i in range(3):
        for j in range(3):
            R[i, j] = 1.0 if i == j else 0.0
    T = np.empty((3, 3))
    for k in range(3):
        ax = order[k]
        for i in range(3):
            M[i, k] = sign[k] * R[i, ax]
        c, s = np.cos(sign[k] * a[k]), np.sin(sign[k] * a[k])
        i1, i2 = (ax + 1) % 3, (ax + 2) % 3
        for i in range(3):                       # R <- R @ elementary(ax, a[k])
            T[i, ax] = R[i, ax]
            T[i, i1] = c * R[i, i1] + s * R[i, i2]
            T[i, i2] = -s * R[i, i1] + c * R[i, i2]
        R[:, :] = T


@njit(cache=True)
def _nb_cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=True)
def _nb_terms(r1, u2, R1, R2, M2, b, E, s2, k, Ji, N, t):
    """One point: fills Ji (k,) and N (3,) (t: (2, 3) scratch); returns (g, var)."""
    r2x = R2[0, 0] * u2[0] + R2[0, 1] * u2[1] + R2[0, 2] * u2[2]
    r2y = R2[1, 0] * u2[0] + R2[1, 1] * u2[1] + R2[1, 2] * u2[2]
    r2z = R2[2, 0] * u2[0] + R2[2, 1] * u2[1] + R2[2, 2] * u2[2]
    N[0] = r1[1] * r2z - r1[2] * r2y
    N[1] = r1[2] * r2x - r1[0] * r2z
    N[2] = r1[0] * r2y - r1[1] * r2x
    g = N[0] * b[0] + N[1] * b[1] + N[2] * b[2]
    t0, t1, t2 = r2y * b[2] - r2z * b[1], r2z * b[0] - r2x * b[2], r2x * b[1] - r2y * b[0]
    d1x = R1[0, 0] * t0 + R1[1, 0] * t1 + R1[2, 0] * t2
    d1y = R1[0, 1] * t0 + R1[1, 1] * t1 + R1[2, 1] * t2
    c0 = b[1] * r1[2] - b[2] * r1[1]                # b x r1
    c1 = b[2] * r1[0] - b[0] * r1[2]
    c2 = b[0] * r1[1] - b[1] * r1[0]
    d2x = R2[0, 0] * c0 + R2[1, 0] * c1 + R2[2, 0] * c2
    d2y = R2[0, 1] * c0 + R2[1, 1] * c1 + R2[2, 1] * c2
    var = s2 * (d1x * d1x + d1y * d1y + d2x * d2x + d2y * d2y)
    a0, a1, a2 = r2y * c2 - r2z * c1, r2z * c0 - r2x * c2, r2x * c1 - r2y * c0   # dg/dtheta2
    for j in range(3):
        Ji[j] = a0 * M2[0, j] + a1 * M2[1, j] + a2 * M2[2, j]
    if k == 5:
        for j in range(2):
            Ji[3 + j] = N[0] * E[0, j] + N[1] * E[1, j] + N[2] * E[2, j]
    return g, var


@njit(cache=True)
def _nb_tangent(b, E):
    h = np.array([1.0, 0.0, 0.0]) if abs(b[0]) < 0.8 else np.array([0.0, 1.0, 0.0])
    e1, e2 = np.empty(3), np.empty(3)
    _nb_cross(b, h, e1)
    e1 /= np.sqrt(e1 @ e1)
    _nb_cross(b, e1, e2)
    E[:, 0] = e1
    E[:, 1] = e2


@njit(cache=True)
def _nb_profile(r1, u2, mask, R1, R2, M2, b, s2, use_weights, N, Ji, scratch, E):
    """Base direction minimizing sum w (b . N)^2 (weights from the current b)."""
    S = np.zeros((3, 3))
    for i in range(len(u2)):
        if not mask[i]:
            continue
        g, var = _nb_terms(r1[i], u2[i], R1, R2, M2, b, E, s2, 3, Ji, N, scratch)
        w = 1.0
        if use_weights:
            w = 1.0 / var if var > 0 else 0.0
        for a in range(3):
            for c in range(3):
                S[a, c] += w * N[a] * N[c]
    _, vecs = np.linalg.eigh(S)
    return vecs[:, 0].copy()


@njit(cache=True)
def solve_pairs_numba(u1, u2, mask, R1, angles, base, mode, order, sign, s2, max_iter, tol,
                      status, iterations, Q, vtpv, g_out, var_out, J_out, w_out, bad_point):
    """In-place per-pair Gauss-Newton (see :func:`solve_pairs`); angles and base updated.

    A condition whose variance is not > 0 stops its pair with status
    :data:`STATUS_ZERO_VARIANCE` and its point index in ``bad_point`` (the caller
    refuses it)."""
    P, n = mask.shape
    k = 3 if mode == 0 else 5
    R2, M2, E = np.empty((3, 3)), np.empty((3, 3)), np.zeros((3, 2))
    Ji, N, scratch = np.empty(k), np.empty(3), np.empty((2, 3))
    H, grad, r1 = np.empty((k, k)), np.empty(k), np.empty((n, 3))
    for p in range(P):
        if status[p] != 1:
            continue
        for i in range(n):
            for a in range(3):
                r1[i, a] = R1[p, a, 0] * u1[p, i, 0] + R1[p, a, 1] * u1[p, i, 1] \
                    + R1[p, a, 2] * u1[p, i, 2]
        b = base[p] / np.sqrt(base[p] @ base[p])
        ang = angles[p]
        if mode == 2:
            _nb_rotation(ang, order, sign, R2, M2)
            b = _nb_profile(r1, u2[p], mask[p], R1[p], R2, M2, b, s2, False, N, Ji, scratch, E)
        done = False
        for it in range(max_iter + 1):
            _nb_rotation(ang, order, sign, R2, M2)
            if mode == 2:
                b = _nb_profile(r1, u2[p], mask[p], R1[p], R2, M2, b, s2, True, N, Ji, scratch,
                                E)
            if k == 5:
                _nb_tangent(b, E)
            H[:, :] = 0.0
            grad[:] = 0.0
            v = 0.0
            for i in range(n):
                if not mask[p, i]:
                    g_out[p, i] = 0.0
                    w_out[p, i] = 0.0
                    continue
                g, var = _nb_terms(r1[i], u2[p, i], R1[p], R2, M2, b, E, s2, k, Ji, N,
                                   scratch)
                if not var > 0:
                    status[p] = 5
                    bad_point[p] = i
                    var_out[p, i] = var
                    break
                w = 1.0 / var
                for a in range(k):
                    wa = w * Ji[a]
                    grad[a] += wa * g
                    for c in range(a, k):
                        H[a, c] += wa * Ji[c]
                v += w * g * g
                g_out[p, i], var_out[p, i], w_out[p, i] = g, var, w
                for a in range(k):
                    J_out[p, i, a] = Ji[a]
            if status[p] == 5:
                break
            for a in range(k):
                for c in range(a):
                    H[a, c] = H[c, a]
            vtpv[p] = v
            d = np.sqrt(np.abs(np.diag(H))) + 1e-300
            Hs = H / np.outer(d, d)
            if not np.all(np.isfinite(Hs)) or np.min(np.diag(H)) <= 0.0:
                status[p] = 2
                break
            ev = np.linalg.eigvalsh(Hs)
            if not (ev[0] > 1e-13 * ev[-1]):
                status[p] = 2
                break
            if done:
                status[p] = 0
                break
            if it == max_iter:
                break
            step = -np.linalg.solve(Hs, grad / d) / d
            ang += step[:3]
            if k == 5 and mode == 1:
                b = b + E @ step[3:]
                b /= np.sqrt(b @ b)
            iterations[p] += 1
            done = np.max(np.abs(step)) < tol
        if status[p] <= 1:
            Q[p] = np.linalg.inv(H)
        base[p] = b


@njit(cache=True)
def joint_weight_blocks(idx, obs, d, s2, tol):
    """Per tie point, the pseudo-inverse of the joint covariance of its conditions (see
    :func:`photogrammetry.adjustment.block_conditions._joint_weights`), compiled.

    Parameters
    ----------
    idx : ndarray of int (T, c)
        Conditions of each of T tie points with c conditions.
    obs : ndarray of int (C, 2); d : ndarray (C, 2, 2); s2 : float; tol : float

    Returns
    -------
    vals : ndarray (T, c, c)
        The weight blocks.
    rank : int
        Eigenvalues kept (independent conditions).
    """
    T, c = idx.shape
    vals = np.zeros((T, c, c))
    rank = 0
    S = np.empty((c, c))
    inv = np.empty(c)
    for t in range(T):
        for a in range(c):
            ca = idx[t, a]
            for b in range(c):
                cb = idx[t, b]
                acc = 0.0
                for s in range(2):
                    for r in range(2):
                        if obs[ca, s] == obs[cb, r]:
                            acc += d[ca, s, 0] * d[cb, r, 0] + d[ca, s, 1] * d[cb, r, 1]
                S[a, b] = s2 * acc
        for a in range(c):
            inv[a] = 1.0 / np.sqrt(S[a, a]) if S[a, a] > 0 else 0.0
        for a in range(c):
            for b in range(c):
                S[a, b] *= inv[a] * inv[b]
        lam, U = np.linalg.eigh(S)
        top = lam[c - 1]
        for k in range(c):
            if lam[k] > tol * top:
                rank += 1
                w = 1.0 / lam[k]
                for a in range(c):
                    for b in range(c):
                        vals[t, a, b] += U[a, k] * w * U[b, k]
        for a in range(c):
            for b in range(c):
                vals[t, a, b] *= inv[a] * inv[b]
    return vals, rank
