"""SIFT features of one image, spread over the frame (OpenCV).

The detector runs on one reduced grey level (:func:`photogrammetry.imagery.images.read_grey`)
cut into a grid of tiles, each with its share of the features (so texture-poor parts of
the frame still get some); every tile is detected with a margin and keeps only the
keypoints of its core, so none is lost or repeated at the seams.  Descriptors are
RootSIFT (L1-normalised, square-rooted: Arandjelovic and Zisserman 2012), compared with
the Euclidean distance.  Keypoint positions are returned in full-frame pixels.
"""
from dataclasses import dataclass

import numpy as np

__all__ = ["Features", "detect_features"]

_TILE_MARGIN_PX = 24


@dataclass(frozen=True)
class Features:
    """Keypoints of one image.

    Attributes
    ----------
    uv_px : ndarray (n, 2)
        Full-frame pixel coordinates (column, row) of the keypoints (observed, i.e.
        distorted).
    descriptors : ndarray (n, 128) float32
        RootSIFT descriptors (unit L2 norm).
    scale_px : float
        Full-frame pixels per pixel of the level the keypoints were found on.
    """
    uv_px: np.ndarray
    descriptors: np.ndarray
    scale_px: float

    def __len__(self):
        return len(self.uv_px)


def _root_sift(desc):
    desc = np.asarray(desc, dtype=np.float32)
    desc = desc / np.maximum(desc.sum(axis=1, keepdims=True), 1e-12)
    return np.sqrt(desc)


def detect_features(level, max_features=4000, tiles=(3, 3)):
    """SIFT keypoints and RootSIFT descriptors of a grey level.

    Parameters
    ----------
    level : photogrammetry.imagery.images.GreyLevel
    max_features : int
        Upper bound of the keypoints (shared among the tiles).
    tiles : (int, int)
        Tiles across and down the frame.

    Returns
    -------
    Features
    """
    import cv2
    img = level.pixels
    h, w = img.shape
    nx, ny = tiles
    per_tile = max(1, int(max_features) // (nx * ny))
    sift = cv2.SIFT_create(nfeatures=per_tile)
    pts, descs = [], []
    xs = np.linspace(0, w, nx + 1).round().astype(int)
    ys = np.linspace(0, h, ny + 1).round().astype(int)
    for r in range(ny):
        for c in range(nx):
            x0, x1, y0, y1 = xs[c], xs[c + 1], ys[r], ys[r + 1]
            ox0, oy0 = max(0, x0 - _TILE_MARGIN_PX), max(0, y0 - _TILE_MARGIN_PX)
            ox1, oy1 = min(w, x1 + _TILE_MARGIN_PX), min(h, y1 + _TILE_MARGIN_PX)
            kps, d = sift.detectAndCompute(img[oy0:oy1, ox0:ox1], None)
            if d is None or not kps:
                continue
            uv = np.array([k.pt for k in kps], dtype=float) + (ox0, oy0)
            # OpenCV's keypoints, like docs/interfaces.md, put pixel centres at integers
            core = ((uv[:, 0] >= x0 - 0.5) & (uv[:, 0] < x1 - 0.5)
                    & (uv[:, 1] >= y0 - 0.5) & (uv[:, 1] < y1 - 0.5))
            pts.append(uv[core])
            descs.append(d[core])
    if not pts:
        return Features(np.zeros((0, 2)), np.zeros((0, 128), np.float32),
                        float(max(level.scale)))
    uv = np.concatenate(pts)
    desc = _root_sift(np.concatenate(descs))
    # identical positions (a keypoint with two orientations) would tie in matching
    _, first = np.unique(np.round(uv, 3), axis=0, return_index=True)
    first.sort()
    return Features(level.to_full(uv[first]), desc[first], float(max(level.scale)))
