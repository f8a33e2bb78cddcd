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

What the estimate absorbs, and the split of the error it leaves.  The points move with
a boresight error as with an attitude error fixed in the body frame (the same rotation
of ``C_bs r_s``, but for the lever arm), so with the trajectory's attitude error
``e(t) = c + v(t)`` (``c`` its part common to the strips in the body frame, ``v`` what
differs between and within them) the estimate is ``b_hat = b - c - G v + n``: the
common part whole, a weighted mean ``G v`` of the rest, and the adjustment's error
``n`` (``sigma0^2 (A^T A)^-1``).  In the points of the same flight the error is then
``J (e(t) + b_hat - b) = J (v(t) - G v + n)``: ``c`` is gone.  Its variance is in the
total sigma (``cov_rad2``: the adjustment's plus ``H B_s Var_s B_s^T H^T``), which is
the right one for the boresight on ANOTHER flight, but counting it and the
trajectory's whole attitude sigma in this flight's points counts ``c`` twice (mean z^2
0.03-0.08 horizontally on the simulated flights).  The right sigma for this flight's
points is that of ``v(t) - G v + n``, the rotation left, which the strips' height
differences measure where they see it (:func:`strip_attitude`, per segment of each
strip: the posterior of ``e_s + U (b_hat - b)``, ``U`` the body axes of the
boresight angles (:func:`boresight_axes`), so ``n`` is in it and is not added again;
written by ``ins strip-check
--scanner-out`` as the scanner file's ``[calibration]``,
:class:`ins.lidar.scanner.BoresightCalibration`, and used by
:func:`ins.lidar.georeference.georeference`).
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.nav.rotation import rot_x, rot_y

__all__ = ["PairDifferences", "BoresightEstimate", "StripAttitude", "strip_attitude",
           "boresight_axes",
           "pair_differences", "estimate_boresight",
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
    seg_a, seg_b : ndarray (m,) of int, optional
        Segment label (``label`` of :func:`pair_differences`) of the point of a and of
        b's nearest neighbour.
    """

    a: int
    b: int
    dz_m: np.ndarray
    rows_a: np.ndarray
    rows_b: np.ndarray
    xy_m: np.ndarray
    seg_a: np.ndarray = None
    seg_b: np.ndarray = None

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
                     max_plane_rms_m=0.5, rng=None, label=None):
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
    label : ndarray (n,) of int, optional
        A segment label per point (kept as ``seg_a``, ``seg_b``).

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
    seg_a = seg_b = None
    if label is not None:
        seg_a, seg_b = np.asarray(label)[ia], np.asarray(label)[ib][nb[:, 0]]
    return PairDifferences(a, b, pa[:, 2] - c[:, 0], _rows(J_enu[ia], g), _rows(J_b, g),
                           pa[:, :2].copy(), seg_a, seg_b)


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
    cov_adjustment_rad2 : ndarray (3, 3)
        ``sigma0^2 (A^T A)^-1`` alone (the strips' noise; ``cov_rad2`` adds the
        trajectory's attitude error when its variances were given).
    keep : ndarray of bool
        Which differences (the pairs' concatenated) were used.
    """

    delta_rad: np.ndarray
    sigma_rad: np.ndarray
    cov_rad2: np.ndarray
    sigma0_m: float
    n_used: int
    n_rejected: int
    estimable: np.ndarray
    pairs: list
    cov_adjustment_rad2: np.ndarray = None
    keep: np.ndarray = None


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
    cov = cov_adj = sigma0 ** 2 * Ninv
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
                             list(pairs), cov_adj, keep)


@dataclass(frozen=True)
class StripAttitude:
    """The trajectory's attitude error left in each strip after a boresight calibration.

    Attributes
    ----------
    strips : ndarray (k,) of int
    error_rad : ndarray (k, 3)
        Roll, pitch, yaw error of each strip's points (the Euler axes of
        :func:`ins.lidar.georeference.attitude_jacobian`), rad, relative to the
        calibrated boresight: their part common to the strips is in the boresight.
    sigma_rad : ndarray (k, 3)
        Their estimation sigmas, rad.
    sigma0_m : float
        RMS of the height differences left after them, m.
    """

    strips: np.ndarray
    error_rad: np.ndarray
    sigma_rad: np.ndarray
    sigma0_m: float

    def left_sigma_rad(self, weights=None):
        """The attitude sigma left in the points (roll, pitch, yaw; rad, (3,)): the
        root of the (weighted) mean over the strips of ``error^2 + sigma^2``, the
        expected square of each strip's error given its estimate."""
        w = np.ones(len(self.strips)) if weights is None else np.asarray(weights, float)
        ms = (self.error_rad ** 2 + self.sigma_rad ** 2) * w[:, None]
        return np.sqrt(ms.sum(axis=0) / max(w.sum(), 1e-300))


#: The trajectory's attitude axes whose strip-to-strip part the strip check estimates
#: (roll, yaw); pitch's is held at zero (:func:`strip_attitude`).
STRIP_AXES = (0, 2)


def strip_attitude(est, attitude_var, axes=STRIP_AXES, height_var=None, boresight_axes=None):
    """The trajectory's attitude error left in each strip's points after the boresight
    of ``est`` (its pairs' rows must hold the trajectory's roll, pitch, yaw columns
    3..5): the posterior given the strips' height differences.

    Model, over the differences ``est`` used (after its boresight)::

        dz = A eps + sum_s B_s e_s + noise

    with ``eps = b_hat - b`` the calibrated boresight's error (flat prior), ``e_s`` the
    trajectory's attitude error over strip s (prior ``N(0, attitude_var[s])``, the
    strips independent: the model of :func:`estimate_boresight`), ``B_s`` the rows of
    strip s's error (``+rows_a`` for strip a, ``-rows_b`` for b), noise of variance
    ``sigma0^2``.  A boresight and an attitude error fixed in the body frame move the
    points alike, so what the points of strip s keep is ``r_s = e_s + U eps`` (``U``
    the body axes of the boresight's rotations, ``boresight_axes``: ``eps`` turns the
    scanner about ITS axes, ``e_s`` the body about roll, pitch, yaw, so a scanner mounted
    turned, e.g. backwards, has ``U != I``): the part of the trajectory's error common to
    the strips cancels against the boresight that absorbed it, what differs from strip
    to strip stays.  The data fix ``r_s`` where
    the geometry shows it (the common part, roll differences through the strips'
    separation, yaw differences through the slopes); where it does not (a pitch error
    fixed in the navigation frame shifts all strips alike) its prior would remain.
    Only the axes ``axes`` are estimated per strip (default roll and yaw); the others'
    strip-to-strip part is held at zero.  Pitch is held so by default: its strip-to-strip
    part is seen only through along-track slopes, where it trades off against yaw's
    (the estimate wanders by hundreds of arcsec on the simulated flights), and the tilt
    error of a GNSS/INS solution is mostly fixed in the body frame (accelerometer bias
    and misalignment over g: the simulated flights' pitch errors differ by 2-12 arcsec
    between strips), so its common part, absorbed by the boresight, is nearly all of it.
    ``E[r_s^2] = r_hat_s^2 + Var(r_s)`` per axis is returned; ``sigma0`` is re-estimated
    once from the residuals of the posterior.

    Parameters
    ----------
    est : BoresightEstimate
    attitude_var : dict {strip or segment: ndarray (3,)}
        Prior variance of each strip's (or, when the pairs carry segment labels, each
        segment's) roll, pitch, yaw error (rad^2).
    height_var : dict {strip or segment: float}, optional
        Prior variance of each one's vertical position error (m^2): a height offset
        per strip or segment is then estimated beside the attitude (``+1`` for a, ``-1``
        for b), so that a height difference between the strips is not taken for a roll
        error.
    boresight_axes : ndarray (3, 3), optional
        ``U``: its column i is the body-frame axis of the boresight angle i's rotation
        (``axes Rx e_x``, ``axes Rx Ry e_y``, ``C_bs e_z``; :func:`boresight_axes`),
        which for a level IMU is the Euler axis it moves; default the identity (a
        scanner with ``axes`` = I).

    Returns
    -------
    StripAttitude
    """
    pairs = est.pairs
    if not pairs or pairs[0].rows_a.shape[1] < 6:
        raise ValueError("the pairs carry no attitude columns (3..5)")
    segs = pairs[0].seg_a is not None
    la = [p.seg_a if segs else np.full(len(p.dz_m), p.a) for p in pairs]
    lb = [p.seg_b if segs else np.full(len(p.dz_m), p.b) for p in pairs]
    ids = np.unique(np.concatenate(la + lb).astype(np.int64))
    col = {int(s): 3 * i for i, s in enumerate(ids)}
    dz = np.concatenate([p.dz_m for p in pairs])
    A = np.concatenate([p.rows[:, :3] for p in pairs])
    M = np.zeros((len(dz), 3 * len(ids)))
    o = 0
    for p, ga, gb in zip(pairs, la, lb):
        m = len(p.dz_m)
        r = np.arange(o, o + m)
        ca = np.array([col[int(v)] for v in ga])
        cb = np.array([col[int(v)] for v in gb])
        for j in range(3):
            np.add.at(M, (r, ca + j), p.rows_a[:, 3 + j])
            np.add.at(M, (r, cb + j), -p.rows_b[:, 3 + j])
        o += m
    keep = np.ones(len(dz), bool) if est.keep is None else est.keep
    nk = M.shape[1]
    H = np.zeros((len(dz), len(ids) if height_var is not None else 0))
    if height_var is not None:
        o = 0
        for ga, gb in zip(la, lb):
            r = np.arange(o, o + len(ga))
            np.add.at(H, (r, np.array([col[int(v)] // 3 for v in ga])), 1.0)
            np.add.at(H, (r, np.array([col[int(v)] // 3 for v in gb])), -1.0)
            o += len(ga)
    dz, X = dz[keep], np.hstack([A[keep], M[keep], H[keep]])
    prior = np.zeros(X.shape[1])
    for s_id, c in col.items():
        v = np.asarray(attitude_var.get(s_id, np.zeros(3)), float)
        prior[3 + c:3 + c + 3] = 1.0 / np.maximum(v, 1e-30)
        if height_var is not None:
            prior[3 + nk + c // 3] = 1.0 / max(float(height_var.get(s_id, 0.0)), 1e-30)
    use = np.ones(X.shape[1], bool)   # the strips' axes not estimated: held at zero
    use[3:3 + nk] = np.tile(np.isin(np.arange(3), axes), len(ids))
    N0, b0 = X[:, use].T @ X[:, use], X[:, use].T @ dz
    sigma0 = est.sigma0_m
    th, cov = np.zeros(X.shape[1]), np.zeros((X.shape[1], X.shape[1]))
    for _ in range(2):
        Nn = N0 / sigma0 ** 2 + np.diag(prior[use])
        cov[np.ix_(use, use)] = np.linalg.pinv(Nn)
        th[use] = cov[np.ix_(use, use)] @ (b0 / sigma0 ** 2)
        r = dz - X @ th
        sigma0 = float(np.sqrt(r @ r / max(len(dz) - 3, 1)))
    U = np.eye(3) if boresight_axes is None else np.asarray(boresight_axes, float)
    T = np.zeros((len(ids), 3, X.shape[1]))
    for i in range(len(ids)):
        T[i, :, :3] = U
        T[i, :, 3 + 3 * i:3 + 3 * i + 3] = np.eye(3)
    e = np.einsum("sij,j->si", T, th)
    var = np.clip(np.einsum("sij,jk,sik->si", T, cov, T), 0, None)
    return StripAttitude(ids, e, np.sqrt(var), sigma0)


def boresight_axes(scanner, boresight_rad):
    """Body-frame axes of the rotations of the boresight angles ``(rx, ry, rz)`` of
    ``scanner`` at ``boresight_rad``: columns ``axes Rx e_x``, ``axes Rx Ry e_y``,
    ``C_bs e_z`` (``d(C_bs r)/d b_i = u_i x (C_bs r)``), shape (3, 3)."""
    from ins.nav.rotation import rot_z
    b = np.asarray(boresight_rad, float)
    Mx = scanner.axes @ rot_x(b[0])
    Mxy = Mx @ rot_y(b[1])
    return np.column_stack([Mx[:, 0], Mxy[:, 1], (Mxy @ rot_z(b[2]))[:, 2]])


def overlapping_pairs(strip):
    """Strip pairs (a, b), a < b, of the strip ids present (every pair is tried; pairs that
    do not overlap give no difference)."""
    ids = np.unique(strip)
    return [(int(a), int(b)) for i, a in enumerate(ids) for b in ids[i + 1:]]


def boresight_from_strips(traj, time, r_s, strip, scanner, std=None, origin_lla=None,
                          iterations=5, radius_m=3.0, k=8, max_points=20000, seed=0,
                          segment_s=6.0):
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
    segment_s : float
        With ``std``: the attitude error left after the calibration is estimated per
        segment of this length along each strip (:func:`strip_attitude`), s.

    Returns
    -------
    (boresight_rad, estimate, first, calibration)
    boresight_rad : ndarray (3,)
        The estimated boresight (rx, ry, rz), rad.
    calibration : ins.lidar.scanner.BoresightCalibration or None
        With ``std``: the split of the estimate's error for the points of this flight
        (the adjustment's sigma, and the attitude error left: :func:`strip_attitude`
        per ``segment_s`` segment weighted by the points, pitch's taken at least as
        roll's); None without ``std``.
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
    att_var = label = None
    if std is not None:
        s = std.at(time)[:, 3:6] ** 2
        att_var = {int(i): s[strip == i].mean(axis=0) for i in np.unique(strip)}
        # segments of segment_s along each strip: the attitude error left per segment
        label = np.zeros(len(time), np.int64)
        for i in np.unique(strip):
            m = strip == i
            label[m] = int(i) * 100_000 + np.floor(
                (time[m] - time[m].min()) / segment_s).astype(np.int64)
        seg_var = {int(g): s[label == g].mean(axis=0) for g in np.unique(label)}
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
        pairs = [pair_differences(enu, J_enu, strip, a, bb, radius_m, k, max_points, rng=rng,
                                  label=label)
                 for a, bb in pairs_ab]
        est = estimate_boresight(pairs, att_var)
        first = first or est
        b = b - est.delta_rad
        if np.all(np.abs(est.delta_rad) < 0.05 * np.maximum(est.sigma_rad, 1e-12)):
            break
    calibration = None
    if att_var is not None:
        from ins.lidar.scanner import BoresightCalibration
        sa = strip_attitude(est, seg_var, boresight_axes=boresight_axes(scanner, b))
        w = [np.count_nonzero(label == s_id) for s_id in sa.strips]
        left = sa.left_sigma_rad(w)
        # pitch's strip-to-strip part is not seen (strip_attitude): taken as roll's, the
        # tilt errors of a GNSS/INS sharing their causes (accelerometer bias and
        # misalignment over g, the same in both axes)
        left[1] = max(left[1], left[0])
        calibration = BoresightCalibration(
            [float(np.min(time)), float(np.max(time))],
            np.sqrt(np.clip(np.diag(est.cov_adjustment_rad2), 0, None)), left)
    return b, est, first, calibration
