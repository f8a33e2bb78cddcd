"""Keypoints and descriptors of many images in bounded memory: one file per image on
disk, a few images in memory.

:func:`photogrammetry.imagery.tiepoints_images.match_images` detects every image once and
stores its keypoints (full-frame px, float64), RootSIFT descriptors (float16) and level
scale in ``<folder>/<image id>.npz``; matching a pair loads its two images through a
least-recently-used set of ``max_images`` images, so the memory held by features is
that of ``max_images`` images (about 1.1 MB each at 4000 keypoints) whatever the block
size.  The folder is a temporary one removed at the end, or the user's (``--cache
DIR``), kept, and reused on the next run for an image whose file (path, size,
modification time) and detection settings are unchanged (the ``key`` stored in the
file).
"""
import os
import shutil
import tempfile
import threading
from collections import OrderedDict

import numpy as np

from ins.common.errors import InputError

__all__ = ["FeatureStore", "feature_key"]

_VERSION = "insphoto-features-1"


def feature_key(path, max_side_px, max_features):
    """The identity of an image's features: its file (absolute path, size, modification
    time, ns) and the detection settings."""
    st = os.stat(path)
    return (f"{_VERSION}|{os.path.abspath(path)}|{st.st_size}|{st.st_mtime_ns}|"
            f"{int(max_side_px)}|{int(max_features)}")


class FeatureStore:
    """Per-image features on disk with an LRU of ``max_images`` in memory.

    Parameters
    ----------
    folder : str, optional
        Where the files go (created if missing, kept); default a temporary folder
        removed by :meth:`close`.
    max_images : int
        Images held in memory at once (>= 2: a pair).
    ideal : callable(uv_px) -> xy_mm, optional
        Ideal photo coordinates of keypoints, computed on loading (not stored: they
        depend on the camera file).
    """

    def __init__(self, folder=None, max_images=4, ideal=None):
        if int(max_images) < 2:
            raise ValueError(f"max_images must be >= 2 (a pair), got {max_images}")
        self.max_images = int(max_images)
        self._ideal = ideal
        self._temporary = folder is None
        if folder is None:
            self.folder = tempfile.mkdtemp(prefix="insphoto-features-")
        else:
            self.folder = os.fspath(folder)
            if os.path.exists(self.folder) and not os.path.isdir(self.folder):
                raise InputError("--cache must be a folder", path=self.folder)
            try:
                os.makedirs(self.folder, exist_ok=True)
            except OSError as exc:
                raise InputError(f"cannot create the cache folder: {exc.strerror}",
                                 path=self.folder) from None
        self._names = {}
        self._lru = OrderedDict()
        self._lock = threading.Lock()
        self.loads = 0

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        """Drop the images in memory; remove the folder if it is a temporary one."""
        self._lru.clear()
        if self._temporary and os.path.isdir(self.folder):
            shutil.rmtree(self.folder, ignore_errors=True)

    def _file(self, name):
        return os.path.join(self.folder, f"{name}.npz")

    def lookup(self, k, name, key):
        """``(n_keypoints, scale_px)`` of image `k` when its file holds `key`, else None."""
        self._names[k] = name
        try:
            with np.load(self._file(name)) as z:
                if str(z["key"]) != key:
                    return None
                return len(z["uv_px"]), float(z["scale_px"])
        except (OSError, KeyError, ValueError):
            return None

    def put(self, k, name, key, uv_px, descriptors, scale_px):
        """Store image `k`'s features (atomically: a partial file is never read)."""
        self._names[k] = name
        path = self._file(name)
        fd, tmp = tempfile.mkstemp(dir=self.folder, prefix=f".{name}.", suffix=".npz")
        try:
            with os.fdopen(fd, "wb") as fh:
                np.savez(fh, key=np.array(key), uv_px=np.asarray(uv_px, float),
                         descriptors=np.asarray(descriptors, np.float16),
                         scale_px=np.array(float(scale_px)))
            os.replace(tmp, path)
        except BaseException:
            if os.path.exists(tmp):
                os.remove(tmp)
            raise
        return len(uv_px), float(scale_px)

    def uv_px(self, k):
        """Keypoints (n, 2) of image `k`, full-frame px (read alone, not kept)."""
        with np.load(self._file(self._names[k])) as z:
            return z["uv_px"]

    def get(self, k):
        """``(uv_px, descriptors, xy_mm, scale_px)`` of image `k`, through the LRU."""
        with self._lock:
            hit = self._lru.get(k)
            if hit is not None:
                self._lru.move_to_end(k)
                return hit
        with np.load(self._file(self._names[k])) as z:
            uv, desc, scale = z["uv_px"], z["descriptors"], float(z["scale_px"])
        xy = self._ideal(uv) if self._ideal is not None else None
        item = (uv, desc, xy, scale)
        with self._lock:
            self.loads += 1
            self._lru[k] = item
            self._lru.move_to_end(k)
            while len(self._lru) > self.max_images:
                self._lru.popitem(last=False)
        return item
