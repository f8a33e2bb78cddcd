"""Matching guided by the exterior-orientation prior: overlapping pairs, epipolar bands,
geometric verification and multi-image tracks.

Geometry (``conventions.md``): a keypoint's ideal photo coordinates ``(x, y)`` (mm) give
the camera ray ``(x, y, -f)``, in the mapping frame ``C_mc @ (x, y, -f)`` from the
perspective centre ``X0``.  The ground lies between the heights ``Z = z_low`` and
``Z = z_high`` of the mapping frame (a ground height and its relief, or a DEM's range),
so the point seen in image i lies, in image j, on the segment of the epipolar line
between the projections of the ray's points at those two heights.  A candidate in j is
kept when its ideal photo coordinates lie within a band of half-width ``tol`` around
that segment, with (:func:`band_tolerance_mm`)

    tol = n_sigma * sqrt(2 (f + r^2 / f)^2 s_ang^2 + 2 (f s_pos / D)^2) + loc

``s_ang`` the RMS of the prior's angle sigmas (rad; an angle error moves a point at the
image radius r by up to ``(f + r^2/f) s_ang``), ``s_pos`` the RMS position sigma (m),
``D`` the distance to the ground (m) and ``loc`` the keypoints' localisation (three level
pixels).  Among the candidates of the band, the nearest descriptor must beat the second
by the ratio test (a lone candidate in the band against the second-nearest of the whole
image) and be the nearest for its partner too (mutual).  The matches are then
verified with an essential matrix (OpenCV ``USAC_MAGSAC`` on the ideal coordinates, so
the camera's distortion is out), and the pairs' matches joined into tracks (connected
components of the match graph, i.e. union-find); a track that holds two keypoints of one
image is dropped whole.
"""
from dataclasses import dataclass

import numpy as np

__all__ = ["PriorView", "ideal_photo_mm", "ground_points", "project_mm", "select_pairs",
           "band_tolerance_mm",
           "guided_matches", "verify_pair", "build_tracks", "PairMatches"]

_CHUNK = 512


@dataclass(frozen=True)
class PriorView:
    """The prior exterior orientation of one image.

    Attributes
    ----------
    X0_m : ndarray (3,)
        Perspective centre in the mapping frame, m.
    C_mc : ndarray (3, 3)
        Camera frame to mapping frame.
    sigma_angle_rad : float
        RMS of the three angle sigmas, rad.
    sigma_position_m : float
        RMS of the three position sigmas, m.
    """
    X0_m: np.ndarray
    C_mc: np.ndarray
    sigma_angle_rad: float
    sigma_position_m: float


@dataclass(frozen=True)
class PairMatches:
    """Verified matches of one pair (keypoint indices) and the counts of the stages."""
    i: int
    j: int
    idx_i: np.ndarray
    idx_j: np.ndarray
    n_candidates: int
    n_guided: int
    sampson_mm: np.ndarray


def ideal_photo_mm(camera, uv_px):
    """Ideal (undistorted) photo coordinates (mm) of observed pixels; NaN where the
    distortion cannot be inverted (beyond the fold of the polynomial)."""
    xy = camera.pixel_to_photo(np.asarray(uv_px, float).reshape(-1, 2))
    try:
        return camera.undistort(xy)
    except ValueError:
        out = np.full_like(xy, np.nan)
        for k in range(len(xy)):
            try:
                out[k] = camera.undistort(xy[k])
            except ValueError:
                pass
        return out


def _rays_m(view, xy_mm, f_mm):
    rays = np.column_stack([xy_mm, np.full(len(xy_mm), -f_mm)])
    return rays @ np.asarray(view.C_mc).T


def ground_points(view, xy_mm, f_mm, z_m):
    """Points of the rays of ``xy_mm`` (ideal, mm) at the height ``Z = z_m`` of the
    mapping frame, (k, 3) m; NaN for rays that do not reach that height forwards."""
    d = _rays_m(view, xy_mm, f_mm)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z_m - view.X0_m[2]) / d[:, 2]
    t = np.where(t > 0, t, np.nan)
    return view.X0_m + t[:, None] * d


def project_mm(view, points_m, f_mm):
    """Ideal photo coordinates (mm) of mapping-frame points in a view; NaN behind it."""
    d = (np.asarray(points_m, float) - view.X0_m) @ np.asarray(view.C_mc)
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = -f_mm * d[:, :2] / d[:, 2:3]
    xy[~(d[:, 2] < 0)] = np.nan
    return xy


def _frame_grid_mm(camera, n):
    u = np.linspace(-0.5, camera.width_px - 0.5, n)
    v = np.linspace(-0.5, camera.height_px - 0.5, n)
    uu, vv = np.meshgrid(u, v)
    return ideal_photo_mm(camera, np.column_stack([uu.ravel(), vv.ravel()]))


def _inside_mm(camera, xy_mm, r_max_mm):
    """Ideal photo points that land on the frame.  Points beyond the frame's largest
    ideal radius are out even where the distortion polynomial folds them back onto it
    (a strong barrel term does at about 1.5 x the frame's radius)."""
    ok = np.all(np.isfinite(xy_mm), axis=1)
    ok &= np.hypot(xy_mm[:, 0], xy_mm[:, 1]) <= r_max_mm
    uv = camera.photo_to_pixel(np.where(ok[:, None], camera.distort(np.nan_to_num(xy_mm)),
                                        0.0))
    return ok & camera.inside(uv)


def select_pairs(views, camera, z_m, min_overlap=0.1, grid=9):
    """Overlapping pairs from the prior footprints on the ground ``Z = z_m``.

    A grid of ``grid x grid`` pixels of image i is taken to the ground and projected
    into image j; the overlap of (i, j) is the larger of the two fractions that land
    inside the other frame.

    Returns
    -------
    list of (i, j, overlap) with i < j and overlap >= min_overlap
    """
    f = camera.focal_length_mm
    xy = _frame_grid_mm(camera, grid)
    r_max = 1.001 * np.nanmax(np.hypot(xy[:, 0], xy[:, 1]))
    ground = [ground_points(v, xy, f, z_m) for v in views]
    centres = np.array([np.nanmean(g, axis=0) if np.isfinite(g).any() else v.X0_m
                        for g, v in zip(ground, views)])
    reach = np.array([np.nanmax(np.linalg.norm(g - c, axis=1)) if np.isfinite(g).any()
                      else 0.0 for g, c in zip(ground, centres)])
    n = len(views)
    frac = np.zeros((n, n))
    for i in range(n):
        near = np.linalg.norm(centres[:, :2] - centres[i, :2], axis=1) <= reach + reach[i]
        for j in np.flatnonzero(near):
            if j == i:
                continue
            ok = np.all(np.isfinite(ground[i]), axis=1)
            if not ok.any():
                continue
            frac[i, j] = _inside_mm(camera, project_mm(views[j], ground[i][ok], f),
                                    r_max).sum() / len(xy)
    pairs = []
    for i in range(n):
        for j in range(i + 1, n):
            o = max(frac[i, j], frac[j, i])
            if o >= min_overlap:
                pairs.append((i, j, float(o)))
    return pairs


def band_tolerance_mm(camera, vi, vj, depth_m, n_sigma, loc_mm):
    """Half-width of the epipolar band (mm) for the pair (module docstring)."""
    f = camera.focal_length_mm
    r = 0.5 * np.hypot(camera.width_px, camera.height_px) * camera.pixel_size_mm
    s_ang2 = vi.sigma_angle_rad ** 2 + vj.sigma_angle_rad ** 2
    s_pos2 = vi.sigma_position_m ** 2 + vj.sigma_position_m ** 2
    return float(n_sigma * np.sqrt((f + r * r / f) ** 2 * s_ang2
                                   + (f / max(depth_m, 1e-3)) ** 2 * s_pos2) + loc_mm)


def _segment_distance(p0, p1, q):
    """Distances (c, m) of points q (m, 2) to segments p0-p1 (c, 2)."""
    d = p1 - p0
    L2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-30)
    t = ((q[None, :, 0] - p0[:, None, 0]) * d[:, None, 0]
         + (q[None, :, 1] - p0[:, None, 1]) * d[:, None, 1]) / L2[:, None]
    t = np.clip(t, 0.0, 1.0)
    ex = q[None, :, 0] - (p0[:, None, 0] + t * d[:, None, 0])
    ey = q[None, :, 1] - (p0[:, None, 1] + t * d[:, None, 1])
    return np.hypot(ex, ey)


def guided_matches(desc_i, desc_j, xy_i, xy_j, vi, vj, f_mm, z_range_m, tol_mm,
                   ratio=0.8):
    """Descriptor matches of a pair restricted to the epipolar bands of the prior.

    Parameters
    ----------
    desc_i, desc_j : ndarray (n_i, d), (n_j, d)
        Descriptors (unit norm).
    xy_i, xy_j : ndarray (n_i, 2), (n_j, 2)
        Ideal photo coordinates, mm (NaN: unusable keypoint).
    vi, vj : PriorView
    f_mm : float
    z_range_m : (float, float)
        Lowest and highest ground height, mapping frame, m.
    tol_mm : float
        Half-width of the band, mm.
    ratio : float
        Lowe's ratio of the nearest to the second-nearest descriptor distance.

    Returns
    -------
    idx_i, idx_j : ndarray of int
        Mutual nearest neighbours within the band that pass the ratio test.
    n_candidates : int
        Keypoints of i with at least one candidate in the band.
    """
    z0, z1 = z_range_m
    p0 = project_mm(vj, ground_points(vi, xy_i, f_mm, z0), f_mm)
    p1 = project_mm(vj, ground_points(vi, xy_i, f_mm, z1), f_mm)
    # a ray that misses one of the heights: use the one it reaches
    p0 = np.where(np.isfinite(p0), p0, p1)
    p1 = np.where(np.isfinite(p1), p1, p0)
    usable_j = np.all(np.isfinite(xy_j), axis=1)
    qj = np.where(usable_j[:, None], xy_j, 1e30)
    dj = np.asarray(desc_j, np.float32)
    n_i, n_j = len(xy_i), len(xy_j)
    best_i = np.full(n_i, -1)
    best_col = np.full(n_j, np.inf)
    arg_col = np.full(n_j, -1)
    n_cand = 0
    rows = np.flatnonzero(np.all(np.isfinite(p0), axis=1))
    for s in range(0, len(rows), _CHUNK):
        r = rows[s:s + _CHUNK]
        band = _segment_distance(p0[r], p1[r], qj) <= tol_mm
        full = np.maximum(2.0 - 2.0 * (np.asarray(desc_i[r], np.float32) @ dj.T), 0.0)
        dist2 = np.where(band, full, np.inf)
        n_cand += int(band.any(axis=1).sum())
        am = np.argmin(dist2, axis=1)
        if n_j >= 2:
            d1, d2 = np.sqrt(np.partition(dist2, 1, axis=1)[:, :2]).T
            # a lone candidate in the band: the second-nearest of the whole image
            # stands in for the second of the band (else any lone candidate would pass)
            f2 = np.partition(full, 1, axis=1)[:, :2]
            am_full = np.argmin(full, axis=1)
            alt = np.sqrt(np.where(am_full == am, f2[:, 1], f2[:, 0]))
            d2 = np.where(np.isfinite(d2), d2, alt)
        else:
            d1, d2 = np.sqrt(dist2[:, 0]), np.full(len(r), np.inf)
        good = np.isfinite(d1) & (d1 < ratio * d2)
        best_i[r[good]] = am[good]
        cm = np.argmin(dist2, axis=0)
        cv = dist2[cm, np.arange(n_j)]
        better = cv < best_col
        best_col[better] = cv[better]
        arg_col[better] = r[cm[better]]
    ii = np.flatnonzero(best_i >= 0)
    jj = best_i[ii]
    mutual = arg_col[jj] == ii
    return ii[mutual], jj[mutual], n_cand


def verify_pair(xy_i, xy_j, f_mm, threshold_mm, confidence=0.9999):
    """Essential-matrix verification (OpenCV USAC_MAGSAC) of matched ideal coordinates.

    Returns
    -------
    inliers : ndarray of bool
    sampson_mm : ndarray
        Sampson distances of the inliers to the fitted epipolar geometry, mm (with
        pixel noise sigma per coordinate they scatter with that sigma).
    """
    import cv2
    n = len(xy_i)
    if n < 8:
        return np.zeros(n, bool), np.zeros(0)
    K = np.array([[f_mm, 0, 0], [0, f_mm, 0], [0, 0, 1.0]])
    a, b = np.ascontiguousarray(xy_i, np.float64), np.ascontiguousarray(xy_j, np.float64)
    E, mask = cv2.findEssentialMat(a, b, K, method=cv2.USAC_MAGSAC, prob=confidence,
                                   threshold=float(threshold_mm), maxIters=10000)
    if E is None or mask is None or E.shape != (3, 3):
        return np.zeros(n, bool), np.zeros(0)
    inl = mask.ravel().astype(bool)
    Kinv = np.linalg.inv(K)
    F = Kinv.T @ E @ Kinv
    h1 = np.column_stack([a, np.ones(n)])
    h2 = np.column_stack([b, np.ones(n)])
    Fx1, Ftx2 = h1 @ F.T, h2 @ F
    num = np.einsum("ij,ij->i", h2, Fx1)
    den = np.sqrt(Fx1[:, 0] ** 2 + Fx1[:, 1] ** 2 + Ftx2[:, 0] ** 2 + Ftx2[:, 1] ** 2)
    d = num / np.maximum(den, 1e-300)
    return inl, d[inl]


def build_tracks(n_keypoints, matches):
    """Multi-image tracks from pairwise matches.

    Parameters
    ----------
    n_keypoints : sequence of int
        Keypoints per image.
    matches : iterable of PairMatches

    Returns
    -------
    tracks : list of ndarray (m, 2) of (image index, keypoint index), m >= 2, sorted by
        image; tracks that hold two keypoints of one image are dropped.
    n_conflicting : int
        Dropped tracks.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    offset = np.concatenate([[0], np.cumsum(n_keypoints)]).astype(np.int64)
    a, b = [], []
    for m in matches:
        a.append(offset[m.i] + np.asarray(m.idx_i, np.int64))
        b.append(offset[m.j] + np.asarray(m.idx_j, np.int64))
    total = int(offset[-1])
    if not a or total == 0:
        return [], 0
    a, b = np.concatenate(a), np.concatenate(b)
    g = coo_matrix((np.ones(len(a)), (a, b)), shape=(total, total))
    _, label = connected_components(g, directed=False)
    used = np.unique(np.concatenate([a, b]))
    image = np.searchsorted(offset, used, side="right") - 1
    order = np.lexsort((image, label[used]))
    used, image, lab = used[order], image[order], label[used][order]
    starts = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1]])
    ends = np.r_[starts[1:], len(used)]
    tracks, conflicts = [], 0
    for s, e in zip(starts, ends):
        img = image[s:e]
        if e - s < 2:
            continue
        if np.any(img[1:] == img[:-1]):
            conflicts += 1
            continue
        tracks.append(np.column_stack([img, used[s:e] - offset[img]]))
    return tracks, conflicts
