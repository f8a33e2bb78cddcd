"""Strip-overlap check of georeferenced LiDAR points: the height differences of
overlapping strips and a least-squares estimate of the scanner boresight from them.

For a point i of strip a, the surface of strip b is fitted locally by a plane through its
``k`` nearest points (horizontal distance below ``radius_m``):
``z_b(x) = c0 + g . (x - x_i)``; the height difference is ``dz_i = z_a,i - c0``.  With
the points computed with the boresight ``b0`` and the scanner's true boresight ``b``,
each point moves by ``J (b0 - b)`` (``J``: its derivative with respect to the boresight,
:func:`ins.lidar.georeference.boresight_jacobian`, here in ENU), so to first order::

    dz_i = [(J_U - g_E J_E - g_N J_N)_a,i - (J_U - g_E J_E - g_N J_N)_b] (b0 - b)

(the vertical shift of each strip less the part its horizontal shift explains on the
slope; ``J_b`` the mean of the neighbours').  Least squares over all pairs gives
``delta = b0 - b`` with the covariance ``sigma0^2 (A^T A)^-1``, ``sigma0`` the residuals'
RMS; differences beyond 4 robust sigmas (MAD) of the first fit are left out once.  The
boresight to use is ``b0 - delta``.  Opposite-direction strips see ``rx`` (the
roll-like angle) on any terrain; ``ry`` and ``rz`` only through terrain slopes: on flat
ground they are not estimable (flagged by a sigma above :data:`MAX_SIGMA_RAD`).
Trajectory errors correlated in time make ``sigma0`` and the sigmas optimistic.
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError

__all__ = ["PairDifferences", "BoresightEstimate", "pair_differences", "estimate_boresight",
           "overlapping_pairs", "boresight_from_strips",
           "MAX_SIGMA_RAD"]

#: A boresight angle whose sigma exceeds this (0.1 deg) is flagged as not estimable.
MAX_SIGMA_RAD = np.deg2rad(0.1)


@dataclass(frozen=True)
class PairDifferences:
    """Height differences of strip ``a`` against the surface of strip ``b``.

    Attributes
    ----------
    a, b : int
        Strip ids.
    dz_m : ndarray (m,)
        ``z_a - z_b`` at the points of a, m (up).
    rows_a, rows_b : ndarray (m, k)
        ``J_U - g_E J_E - g_N J_N`` of the point of a and of b's neighbours, per
        parameter of the Jacobians given (m/rad); the boresight's row of ``dz`` is
        ``rows_a - rows_b``.
    xy_m : ndarray (m, 2)
        East, north of the points (m, local frame).
    """

    a: int
    b: int
    dz_m: np.ndarray
    rows_a: np.ndarray
    rows_b: np.ndarray
    xy_m: np.ndarray

    @property
    def rows(self):
        """Rows of ``dz`` for a parameter common to both strips (the boresight)."""
        return self.rows_a - self.rows_b

    @property
    def mean_m(self):
        return float(np.mean(self.dz_m)) if len(self.dz_m) else float("nan")

    @property
    def rms_m(self):
        return float(np.sqrt(np.mean(self.dz_m ** 2))) if len(self.dz_m) else float("nan")


def _rows(J_enu, g):
    """``J_U - g_E J_E - g_N J_N`` for (m, 3, 3) Jacobians (rows E, N, U) and slopes g."""
    return J_enu[:, 2, :] - g[:, 0:1] * J_enu[:, 0, :] - g[:, 1:2] * J_enu[:, 1, :]


def pair_differences(enu_m, J_enu, strip, a, b, radius_m=3.0, k=8, max_points=20000,
                     max_plane_rms_m=0.5, rng=None):
    """Height differences of strip ``a``'s points against strip ``b``'s local planes.

    Parameters
    ----------
    enu_m : ndarray (n, 3)
        Points in a local east, north, up frame, m.
    J_enu : ndarray (n, 3, k)
        Their derivatives with respect to k parameters (rows E, N, U), m/rad (the
        boresight, then possibly the trajectory's roll, pitch, yaw).
    strip : ndarray (n,)
    a, b : int
    radius_m : float
        The k neighbours in b must lie within this horizontal distance, m.
    max_points : int
        At most this many points of a (a random subset).
    max_plane_rms_m : float
        Planes whose fit residual RMS exceeds this (edges, vegetation) are left out.

    Returns
    -------
    PairDifferences
    """
    from scipy.spatial import cKDTree
    rng = np.random.default_rng(0) if rng is None else rng
    ia = np.flatnonzero(strip == a)
    ib = np.flatnonzero(strip == b)
    npar = J_enu.shape[2]
    empty = PairDifferences(a, b, np.zeros(0), np.zeros((0, npar)), np.zeros((0, npar)),
                            np.zeros((0, 2)))
    if len(ia) == 0 or len(ib) < k:
        return empty
    pb = enu_m[ib]
    tree = cKDTree(pb[:, :2])
    # only the points of a inside b's area can overlap: query them all cheaply first
    dist, _ = tree.query(enu_m[ia, :2], k=1, distance_upper_bound=radius_m)
    ia = ia[np.isfinite(dist)]
    if len(ia) > max_points:
        ia = np.sort(rng.choice(ia, max_points, replace=False))
    if len(ia) == 0:
        return empty
    pa = enu_m[ia]
    dist, nb = tree.query(pa[:, :2], k=k, distance_upper_bound=radius_m)
    ok = np.all(np.isfinite(dist), axis=1)
    pa, ia, nb = pa[ok], ia[ok], nb[ok]
    if len(ia) == 0:
        return empty
    q = pb[nb]                                           # (m, k, 3)
    dx = q[:, :, 0] - pa[:, None, 0]
    dy = q[:, :, 1] - pa[:, None, 1]
    G = np.stack([np.ones_like(dx), dx, dy], axis=2)     # (m, k, 3)
    N = np.einsum("mki,mkj->mij", G, G)
    rhs = np.einsum("mki,mk->mi", G, q[:, :, 2])
    good = np.linalg.cond(N) < 1e8
    c = np.zeros((len(ia), 3))
    c[good] = np.linalg.solve(N[good], rhs[good][..., None])[..., 0]
    res = q[:, :, 2] - np.einsum("mki,mi->mk", G, c)
    plane_rms = np.sqrt(np.mean(res ** 2, axis=1))
    good &= plane_rms < max_plane_rms_m
    c, pa, ia, nb = c[good], pa[good], ia[good], nb[good]
    g = c[:, 1:3]
    J_b = J_enu[ib][nb].mean(axis=1)
    return PairDifferences(a, b, pa[:, 2] - c[:, 0], _rows(J_enu[ia], g), _rows(J_b, g),
                           pa[:, :2].copy())


@dataclass(frozen=True)
class BoresightEstimate:
    """Least-squares boresight from strip differences.

    Attributes
    ----------
    delta_rad : ndarray (3,)
        ``b0 - b`` (rx, ry, rz), rad: subtract from the boresight used.
    sigma_rad : ndarray (3,)
    cov_rad2 : ndarray (3, 3)
    sigma0_m : float
        RMS of the residual height differences, m.
    n_used, n_rejected : int
    estimable : ndarray (3,) of bool
        sigma below :data:`MAX_SIGMA_RAD`.
    pairs : list of PairDifferences
    """

    delta_rad: np.ndarray
    sigma_rad: np.ndarray
    cov_rad2: np.ndarray
    sigma0_m: float
    n_used: int
    n_rejected: int
    estimable: np.ndarray
    pairs: list


def estimate_boresight(pairs, attitude_var=None, reject_sigmas=4.0):
    """Least-squares ``b0 - b`` from the pairs' height differences (module notes).

    Parameters
    ----------
    pairs : list of PairDifferences
        Their first 3 row columns are the boresight's; with ``attitude_var`` columns 3..5
        are the trajectory's roll, pitch, yaw.
    attitude_var : dict {strip: ndarray (3,)}, optional
        Variance (rad^2) of an attitude error taken as constant over each strip: added to
        the covariance of the estimate, ``H B_s Var_s B_s^T H^T`` summed over the strips
        (``H = (A^T A)^-1 A^T``, ``B_s`` the rows of dz with respect to strip s's error).

    Raises
    ------
    InputError
        Fewer than 10 differences (strips that do not overlap).
    """
    dz = np.concatenate([p.dz_m for p in pairs]) if pairs else np.zeros(0)
    if len(dz) < 10:
        raise InputError(f"only {len(dz)} height differences between strips: the strips "
                         "do not overlap (or the points are too sparse for the radius)")
    A = np.concatenate([p.rows[:, :3] for p in pairs])
    keep = np.ones(len(dz), bool)
    for it in range(2):
        x, *_ = np.linalg.lstsq(A[keep], dz[keep], rcond=None)
        if it == 0:
            r = dz - A @ x
            mad = 1.4826 * np.median(np.abs(r - np.median(r)))
            keep = np.abs(r - np.median(r)) <= reject_sigmas * max(mad, 1e-12)
    r = dz[keep] - A[keep] @ x
    m = int(keep.sum())
    sigma0 = float(np.sqrt(r @ r / max(m - 3, 1)))
    Ninv = np.linalg.pinv(A[keep].T @ A[keep])
    cov = sigma0 ** 2 * Ninv
    if attitude_var:
        H = Ninv @ A[keep].T                                   # (3, m)
        offsets = np.cumsum([0] + [len(p.dz_m) for p in pairs])
        for s_id, var in attitude_var.items():
            B = np.zeros((len(dz), 3))
            for p, o in zip(pairs, offsets):
                if p.a == s_id:
                    B[o:o + len(p.dz_m)] += p.rows_a[:, 3:6]
                if p.b == s_id:
                    B[o:o + len(p.dz_m)] -= p.rows_b[:, 3:6]
            HB = H @ B[keep]
            cov = cov + HB @ np.diag(var) @ HB.T
    sig = np.sqrt(np.clip(np.diag(cov), 0, None))
    return BoresightEstimate(x, sig, cov, sigma0, m, int(len(dz) - m), sig < MAX_SIGMA_RAD,
                             list(pairs))


def overlapping_pairs(strip):
    """Strip pairs (a, b), a < b, of the strip ids present (every pair is tried; pairs that
    do not overlap give no difference)."""
    ids = np.unique(strip)
    return [(int(a), int(b)) for i, a in enumerate(ids) for b in ids[i + 1:]]


def boresight_from_strips(traj, time, r_s, strip, scanner, std=None, origin_lla=None,
                          iterations=5, radius_m=3.0, k=8, max_points=20000, seed=0):
    """Boresight of ``scanner`` from the strip overlaps, iterated (Gauss-Newton).

    The points are georeferenced with the current boresight, differenced
    (:func:`pair_differences`, every pair a < b of :func:`overlapping_pairs`), the
    correction estimated (:func:`estimate_boresight`) and applied, until it falls below
    0.05 of its sigma (at most ``iterations`` times; the Jacobians of the first iteration
    are kept).  The first-order model alone leaves a bias of several sigmas for a
    boresight of 0.1 deg.

    Parameters
    ----------
    traj : ins.nav.trajectory.Trajectory
    time : ndarray (n,)
    r_s : ndarray (n, 3)
        Returns in the scanner frame (m), inside the trajectory.
    strip : ndarray (n,) of int
    scanner : ins.lidar.scanner.Scanner
        Its boresight is the start ``b0``.
    std : ins.lidar.georeference.TrajectoryStd, optional
        The trajectory's sigmas: their strip-mean roll, pitch, yaw variances enter the
        estimate's covariance (an attitude error constant over each strip).
    origin_lla : (lat rad, lon rad, h m), optional
        Origin of the local ENU frame (default: the first point).

    Returns
    -------
    boresight_rad : ndarray (3,)
        The estimated boresight (rx, ry, rz), rad.
    estimate : BoresightEstimate
        Of the last iteration (its pairs' differences are those left by the estimated
        boresight; ``sigma_rad`` the boresight's sigmas).
    first : BoresightEstimate
        Of the first iteration (the differences with the starting boresight).
    """
    import pymap3d

    from ins.lidar.georeference import attitude_jacobian, boresight_jacobian, georeference
    strip = np.asarray(strip)
    b = np.array(scanner.boresight_rad, dtype=float)
    pairs_ab = overlapping_pairs(strip)
    att_var = None
    if std is not None:
        s = std.at(time)[:, 3:6] ** 2
        att_var = {int(i): s[strip == i].mean(axis=0) for i in np.unique(strip)}
    first = est = None
    for _ in range(max(1, iterations)):
        sc = scanner.with_boresight(b)
        pts = georeference(traj, time, r_s, sc)
        if len(pts.index) != len(time):
            raise InputError(f"{len(time) - len(pts.index)} returns lie outside the "
                             "trajectory")
        if origin_lla is None:
            origin_lla = tuple(pts.lla()[0])
        if first is None:       # the Jacobians of the start (a fixed-slope iteration)
            J = np.concatenate([boresight_jacobian(traj, time, r_s, sc),
                                attitude_jacobian(traj, time, r_s, sc)], axis=2)
            J_enu = J[:, [1, 0, 2], :] * np.array([1.0, 1.0, -1.0])[None, :, None]
            del J
        lat0, lon0, h0 = np.rad2deg(origin_lla[0]), np.rad2deg(origin_lla[1]), origin_lla[2]
        enu = np.column_stack(pymap3d.ecef2enu(*pts.xyz_ecef_m.T, lat0, lon0, h0))
        rng = np.random.default_rng(seed)
        pairs = [pair_differences(enu, J_enu, strip, a, bb, radius_m, k, max_points, rng=rng)
                 for a, bb in pairs_ab]
        est = estimate_boresight(pairs, att_var)
        first = first or est
        b = b - est.delta_rad
        if np.all(np.abs(est.delta_rad) < 0.05 * np.maximum(est.sigma_rad, 1e-12)):
            break
    return b, est, first
