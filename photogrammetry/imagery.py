"""Image files in bounded memory: a grey level of an image at a reduced scale.

Feature detection works on one level of a pyramid whose longer side is at most
``max_side_px`` (a DMC frame of 7680 x 13824 px is read at 1/4.6 by default), so the
memory does not grow with the frame:

- JPEG and other pillow formats: pillow's ``draft`` decodes JPEG at 1/2, 1/4 or 1/8
  directly; the rest is an area-average resize (OpenCV ``INTER_AREA``).
- TIFF and GeoTIFF (tifffile): the smallest stored pyramid level (overview) that is
  not smaller than the target, else the full page decoded into a temporary memory-mapped
  file (on disk, not in RAM) for frames above :data:`MEMMAP_PIXELS`, reduced in bands
  of rows.  A compression tifffile cannot decode without the optional imagecodecs
  package (JPEG-in-TIFF, as DJI/ODM write) falls back to pillow (libtiff), in memory.

Pixel coordinates follow ``docs/interfaces.md``: centres at integers, ``(0, 0)`` the
centre of the top-left pixel.  A level pixel ``(u_l, v_l)`` is the full-frame pixel
``u = (u_l + 0.5) * sx - 0.5``, ``v = (v_l + 0.5) * sy - 0.5`` (:meth:`GreyLevel.to_full`).
"""
import os
import tempfile
from dataclasses import dataclass

import numpy as np

from ins.errors import InputError

__all__ = ["GreyLevel", "read_grey", "image_size", "MEMMAP_PIXELS", "TIFF_SUFFIXES"]

#: Frames with more pixels than this are decoded through a memory-mapped temporary file.
MEMMAP_PIXELS = 40_000_000
#: Suffixes read with tifffile.
TIFF_SUFFIXES = (".tif", ".tiff", ".gtif")
_BAND_ROWS = 1024


@dataclass(frozen=True)
class GreyLevel:
    """One grey level of an image.

    Attributes
    ----------
    pixels : ndarray (h, w) uint8
    width_px, height_px : int
        Size of the full frame, px.
    """
    pixels: np.ndarray
    width_px: int
    height_px: int

    @property
    def scale(self):
        """Full-frame pixels per level pixel ``(sx, sy)``."""
        h, w = self.pixels.shape
        return self.width_px / w, self.height_px / h

    def to_full(self, uv_level):
        """Level pixel coordinates (..., 2) to full-frame pixel coordinates."""
        sx, sy = self.scale
        uv = np.asarray(uv_level, dtype=float)
        return np.stack([(uv[..., 0] + 0.5) * sx - 0.5, (uv[..., 1] + 0.5) * sy - 0.5],
                        axis=-1)


def _grey(a, path):
    """uint8 grey of an (h, w), (h, w, c) array (first three channels averaged)."""
    a = np.asarray(a)
    if a.ndim == 3:
        a = a[..., :3].mean(axis=-1) if a.shape[-1] >= 3 else a[..., 0]
    if a.ndim != 2:
        raise InputError(f"not a single-frame image (array of shape {a.shape})", path=path)
    if a.dtype != np.uint8:
        a = np.asarray(a, dtype=float)
        lo, hi = np.nanpercentile(a, [0.5, 99.5]) if a.size else (0.0, 1.0)
        a = np.clip((a - lo) * (255.0 / max(hi - lo, 1e-12)), 0, 255)
    return np.ascontiguousarray(a, dtype=np.uint8)


def _target(width, height, max_side_px):
    if max_side_px is None or max(width, height) <= max_side_px:
        return width, height
    s = max_side_px / max(width, height)
    return max(1, round(width * s)), max(1, round(height * s))


def _resize(a, size):
    import cv2
    if (a.shape[1], a.shape[0]) == tuple(size):
        return a
    return cv2.resize(a, size, interpolation=cv2.INTER_AREA)


def _tiff_shape(series, path):
    axes, shape = series.axes, series.shape
    if "Y" not in axes or "X" not in axes:
        raise InputError(f"TIFF series without Y/X axes ({axes})", path=path)
    return shape[axes.index("X")], shape[axes.index("Y")]


def _tiff_array(arr, axes):
    """Bring a tifffile array to (Y, X[, S])."""
    keep = [a for a in axes if a in "YXS"]
    for k, a in reversed(list(enumerate(axes))):
        if a not in "YXS":
            arr = np.take(arr, 0, axis=k)
    order = [keep.index(a) for a in "YXS" if a in keep]
    return np.transpose(arr, order)


def _read_tiff(path, max_side_px):
    import tifffile
    with tifffile.TiffFile(path) as tif:
        series = tif.series[0]
        width, height = _tiff_shape(series, path)
        tw, th = _target(width, height, max_side_px)
        level = series
        for lv in series.levels[1:]:
            w, h = _tiff_shape(lv, path)
            if w >= tw and h >= th:
                level = lv
        lw, lh = _tiff_shape(level, path)
        if lw * lh <= MEMMAP_PIXELS:
            return width, height, _resize(_grey(_tiff_array(level.asarray(), level.axes),
                                                path), (tw, th))
        fd, tmp = tempfile.mkstemp(suffix=".raw")
        os.close(fd)
        try:
            mm = level.asarray(out=tmp)
            full = _tiff_array(mm, level.axes)
            bands = []
            for r0 in range(0, lh, _BAND_ROWS):
                band = _grey(full[r0:r0 + _BAND_ROWS], path)
                rows = max(1, round(band.shape[0] * th / lh))
                bands.append(_resize(band, (tw, rows)))
            del mm, full
            out = np.concatenate(bands, axis=0)
            return width, height, _resize(out, (tw, th))
        finally:
            os.unlink(tmp)


def _read_pillow(path, max_side_px):
    from PIL import Image
    with Image.open(path) as im:
        width, height = im.size
        tw, th = _target(width, height, max_side_px)
        if (tw, th) != (width, height):
            im.draft("L", (tw, th))       # JPEG: decode at 1/2, 1/4, 1/8 (not below target)
        a = _grey(np.asarray(im.convert("L")), path)
    return width, height, _resize(a, (tw, th))


def read_grey(path, max_side_px=None):
    """Read an image as grey levels, reduced so that its longer side is at most
    ``max_side_px`` (None: full resolution).

    Parameters
    ----------
    path : str
        JPEG, PNG, TIFF or GeoTIFF (RGB, grey or 16-bit; 16-bit is stretched between
        its 0.5 and 99.5 percentiles).
    max_side_px : int, optional

    Returns
    -------
    GreyLevel

    Raises
    ------
    InputError
        A missing or unreadable file (naming it).
    """
    path = str(path)
    if not os.path.isfile(path):
        raise InputError("image not found", path=path)
    try:
        if path.lower().endswith(TIFF_SUFFIXES):
            try:
                w, h, a = _read_tiff(path, max_side_px)
            except Exception as exc:        # a codec tifffile lacks (JPEG-in-TIFF
                try:                        # without imagecodecs): pillow's libtiff
                    w, h, a = _read_pillow(path, max_side_px)
                except Exception:
                    raise exc from None
        else:
            w, h, a = _read_pillow(path, max_side_px)
    except InputError:
        raise
    except Exception as exc:          # the image libraries raise many kinds
        raise InputError(f"cannot read the image: {exc}", path=path) from None
    return GreyLevel(a, int(w), int(h))


def image_size(path):
    """Full-frame ``(width_px, height_px)`` of an image without decoding its pixels."""
    path = str(path)
    if not os.path.isfile(path):
        raise InputError("image not found", path=path)
    try:
        if path.lower().endswith(TIFF_SUFFIXES):
            import tifffile
            with tifffile.TiffFile(path) as tif:
                return _tiff_shape(tif.series[0], path)
        from PIL import Image
        with Image.open(path) as im:
            return im.size
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"cannot read the image: {exc}", path=path) from None
