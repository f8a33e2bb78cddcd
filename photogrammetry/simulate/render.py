"""Grey images of a textured, seeded terrain seen from known exterior orientations.

For tests and demonstrations of the image side (tie points from images): every pixel's
observed photo coordinates go through the camera's undistortion to a ray
``C_mc @ (x, y, -f)`` from ``X0`` (``conventions.md``), the ray is intersected with the
terrain ``Z(X, Y)`` (:mod:`photogrammetry.simulate.terrain`) by fixed-point iteration
on the height, and the ground texture (a sum of band-limited random octaves on a grid
of the mapping frame) is sampled there bilinearly.  The truth of every pixel is thus
known: a ray of a true EO hits the ground point whose texture the pixel shows.
"""
from dataclasses import dataclass

import numpy as np

__all__ = ["GroundTexture", "make_texture", "render_view", "ray_ground"]

_HEIGHT_ITER = 8


@dataclass(frozen=True)
class GroundTexture:
    """Grey texture on a grid of the mapping frame: ``values[row, col]`` at
    ``X = x0 + col * cell_m``, ``Y = y0 + row * cell_m``."""
    values: np.ndarray
    x0_m: float
    y0_m: float
    cell_m: float


def make_texture(rng, x_range_m, y_range_m, cell_m, octaves=(4, 8, 16, 32, 64)):
    """A random texture over a rectangle of the mapping frame.

    Parameters
    ----------
    rng : numpy.random.Generator
    x_range_m, y_range_m : (float, float)
    cell_m : float
        Grid spacing, m (about half the ground sample distance of the images).
    octaves : sequence of int
        Feature sizes in cells of the octaves (each a smoothed random field).
    """
    import cv2
    nx = int(np.ceil((x_range_m[1] - x_range_m[0]) / cell_m)) + 1
    ny = int(np.ceil((y_range_m[1] - y_range_m[0]) / cell_m)) + 1
    tex = np.zeros((ny, nx), np.float32)
    for size in octaves:
        small = rng.standard_normal((ny // size + 2, nx // size + 2)).astype(np.float32)
        tex += cv2.resize(small, (nx, ny), interpolation=cv2.INTER_CUBIC)
    tex = cv2.GaussianBlur(tex, (0, 0), 1.0)
    lo, hi = np.percentile(tex, [1, 99])
    tex = np.clip((tex - lo) / (hi - lo) * 235 + 10, 0, 255).astype(np.float32)
    return GroundTexture(tex, float(x_range_m[0]), float(y_range_m[0]), float(cell_m))


def ray_ground(X0_m, rays_m, terrain):
    """Points where rays from ``X0_m`` meet the terrain, (k, 3) m (fixed point on the
    height; rays must point downwards)."""
    d = np.asarray(rays_m, float)
    z = np.zeros(len(d))
    for _ in range(_HEIGHT_ITER):
        t = (z - X0_m[2]) / d[:, 2]
        P = X0_m + t[:, None] * d
        z = terrain.height(P[:, 0], P[:, 1])
    t = (z - X0_m[2]) / d[:, 2]
    return X0_m + t[:, None] * d


def render_view(camera, X0_m, C_mc, terrain, texture):
    """Render one grey image (uint8, height_px x width_px).

    Parameters
    ----------
    camera : photogrammetry.orientation.camera.FrameCamera
    X0_m : array_like (3,)
        Perspective centre, mapping frame, m.
    C_mc : array_like (3, 3)
    terrain : photogrammetry.simulate.terrain.Terrain
    texture : GroundTexture
    """
    import cv2
    X0_m = np.asarray(X0_m, float)
    u, v = np.meshgrid(np.arange(camera.width_px, dtype=float),
                       np.arange(camera.height_px, dtype=float))
    uv = np.column_stack([u.ravel(), v.ravel()])
    xy = camera.undistort(camera.pixel_to_photo(uv))
    rays = camera.rays(xy) @ np.asarray(C_mc, float).T
    P = ray_ground(X0_m, rays, terrain)
    col = ((P[:, 0] - texture.x0_m) / texture.cell_m).astype(np.float32)
    row = ((P[:, 1] - texture.y0_m) / texture.cell_m).astype(np.float32)
    shape = (camera.height_px, camera.width_px)
    img = cv2.remap(texture.values, col.reshape(shape), row.reshape(shape),
                    interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)
