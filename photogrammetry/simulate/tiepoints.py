"""Simulated tie points: ground points on the terrain seen in two or more images.

Ground points are a jittered grid over the block in the mapping frame (ENU at the block
origin, m) on the terrain surface, with a spacing that gives about ``per_image`` points
in one image footprint.  Each is projected into every exposure with the TRUE exterior
orientation by the collinearity equations (the camera ray is ``(x, y, -f)``,
``X - X0 = lambda C_mc (x, y, -f)``), kept where its DISTORTED image position lies
inside the format with a margin, and kept as a tie point when at least two images see
it.  The observed photo coordinates (mm, origin at the principal point, ``x`` along the
image columns, ``y`` against the rows) are the distorted ones (Brown model of the camera
file) plus white Gaussian noise of ``sigma_px * pixel_size_mm`` in x and y.
"""
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

__all__ = ["TiePoints", "ground_grid", "project", "simulate_tiepoints"]


@dataclass(frozen=True)
class TiePoints:
    """Tie-point observations and their ground truth.

    Attributes
    ----------
    image_index : ndarray of int, shape (m,)
        Exposure of each observation (row of the
        :class:`~photogrammetry.simulate.exposures.TrueExposures`).
    point_id : ndarray of int, shape (m,)
        Ground point of each observation (1-based ids).
    xy_mm : ndarray, shape (m, 2)
        Observed photo coordinates (distorted, with noise), mm.
    ground_id : ndarray of int, shape (k,)
        Ids of the ground points (those seen in >= 2 images), increasing.
    ground_m : ndarray, shape (k, 3)
        Their mapping-frame coordinates X, Y, Z, m.
    sigma_px : float
        Standard deviation of the image noise, pixels (per coordinate).
    """

    image_index: np.ndarray
    point_id: np.ndarray
    xy_mm: np.ndarray
    ground_id: np.ndarray
    ground_m: np.ndarray
    sigma_px: float

    def __len__(self):
        return len(self.point_id)


def project(ground_m, X0_m, C_mc, focal_length_mm):
    """Ideal (undistorted) photo coordinates of ground points in one image.

    Parameters
    ----------
    ground_m : array_like, shape (k, 3)
        Points in the mapping frame, m.
    X0_m : array_like, shape (3,)
        Perspective centre, m.
    C_mc : array_like, shape (3, 3)
        Camera frame to mapping frame.
    focal_length_mm : float

    Returns
    -------
    xy_mm : ndarray, shape (k, 2)
        ``x = -f d_x / d_z``, ``y = -f d_y / d_z`` with ``d_c = C_mc^T (X - X0)``, mm
        (NaN for points behind the camera, ``d_z >= 0``).
    """
    d_c = (np.asarray(ground_m, float) - np.asarray(X0_m, float)) @ np.asarray(C_mc, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = -focal_length_mm * d_c[:, :2] / d_c[:, 2:3]
    xy[d_c[:, 2] >= 0] = np.nan
    return xy


def _footprint_half_m(camera, height_m):
    """Half sizes of the image footprint (m) at ``height_m`` above the ground, (across
    the columns, across the rows)."""
    scale = height_m * camera.pixel_size_mm / camera.focal_length_mm
    return 0.5 * camera.width_px * scale, 0.5 * camera.height_px * scale


def ground_grid(exposures, camera, terrain, per_image, rng):
    """Jittered grid of ground points over the block, on the terrain.

    The spacing is ``sqrt(footprint area / per_image)`` at the median flying height
    above ``Z = 0``; each node is moved by a uniform offset of up to 0.35 spacing in X
    and Y.  The grid covers the perspective centres' bounding box grown by the larger
    footprint half size.

    Returns
    -------
    ndarray, shape (k, 3)
        X, Y, Z in the mapping frame, m.
    """
    height = float(np.median(exposures.X_m[:, 2]))
    half_u, half_v = _footprint_half_m(camera, height)
    spacing = np.sqrt(4.0 * half_u * half_v / per_image)
    grow = max(half_u, half_v)
    lo = exposures.X_m[:, :2].min(axis=0) - grow
    hi = exposures.X_m[:, :2].max(axis=0) + grow
    gx = np.arange(lo[0] + 0.5 * spacing, hi[0], spacing)
    gy = np.arange(lo[1] + 0.5 * spacing, hi[1], spacing)
    X, Y = (a.ravel() for a in np.meshgrid(gx, gy))
    X = X + rng.uniform(-0.35, 0.35, X.size) * spacing
    Y = Y + rng.uniform(-0.35, 0.35, Y.size) * spacing
    return np.column_stack([X, Y, terrain.height(X, Y)])


def _visible(ground_m, tree, X0_m, C_mc, camera, margin_px, reach_m):
    """Indices and distorted photo coordinates (mm) of the points inside one image."""
    near = np.sort(np.asarray(tree.query_ball_point(X0_m[:2], reach_m), dtype=np.int64))
    xy = camera.distort(project(ground_m[near], X0_m, C_mc, camera.focal_length_mm))
    inside = camera.inside(camera.photo_to_pixel(xy), margin_px) & np.isfinite(xy[:, 0])
    return near[inside], xy[inside]


def simulate_tiepoints(exposures, camera, terrain, per_image, sigma_px, rng, margin_px=20.0,
                       progress=None):
    """Tie-point observations of a simulated block.

    Parameters
    ----------
    exposures : photogrammetry.simulate.exposures.TrueExposures
        True EO (mapping frame).
    camera : photogrammetry.orientation.camera.FrameCamera
        Focal length, pixel size, format, principal point, distortion.
    terrain : photogrammetry.simulate.terrain.Terrain
    per_image : int
        Target number of ground points per image footprint.
    sigma_px : float
        Image noise per coordinate, pixels.
    rng : numpy.random.Generator
        Grid jitter and image noise.
    margin_px : float
        Points closer than this to the format's edge are not observed, pixels.
    progress : callable, optional
        ``progress(done, total)`` over the exposures.

    Returns
    -------
    TiePoints
    """
    if per_image <= 0 or len(exposures) == 0:
        empty = np.empty(0, dtype=np.int64)
        return TiePoints(empty, empty, np.empty((0, 2)), empty, np.empty((0, 3)),
                         float(sigma_px))
    ground = ground_grid(exposures, camera, terrain, per_image, rng)
    tree = cKDTree(ground[:, :2])
    top = float(np.max(exposures.X_m[:, 2])) + terrain.relief_m
    half_u, half_v = _footprint_half_m(camera, top)
    reach = 1.2 * np.hypot(half_u, half_v) + 0.2 * top   # + tilt of a few degrees
    obs_img, obs_pt, obs_xy = [], [], []
    for i in range(len(exposures)):
        idx, xy = _visible(ground, tree, exposures.X_m[i], exposures.C_mc[i], camera,
                           margin_px, reach)
        obs_img.append(np.full(len(idx), i))
        obs_pt.append(idx)
        obs_xy.append(xy)
        if progress is not None:
            progress(i + 1, len(exposures))
    img = np.concatenate(obs_img)
    pt = np.concatenate(obs_pt)
    xy = np.concatenate(obs_xy).reshape(-1, 2)
    seen = np.bincount(pt, minlength=len(ground))
    keep_point = seen >= 2
    new_id = np.cumsum(keep_point)              # 1-based ids of the kept points
    keep = keep_point[pt]
    xy = xy[keep] + rng.standard_normal((int(keep.sum()), 2)) * sigma_px * camera.pixel_size_mm
    return TiePoints(image_index=img[keep], point_id=new_id[pt[keep]], xy_mm=xy,
                     ground_id=np.arange(1, int(keep_point.sum()) + 1),
                     ground_m=ground[keep_point], sigma_px=float(sigma_px))
