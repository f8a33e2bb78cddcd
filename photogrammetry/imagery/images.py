"""Image files in bounded memory: a grey level of an image at a reduced scale.

Feature detection works on one level of a pyramid whose longer side is at most
``max_side_px`` (a DMC frame of 7680 x 13824 px is read at 1/4.6 by default), so the
memory does not grow with the frame:

- JPEG and other pillow formats: pillow's ``draft`` decodes JPEG at 1/2, 1/4 or 1/8
  directly; the rest is an area-average resize (OpenCV ``INTER_AREA``).
- TIFF and GeoTIFF (tifffile): the smallest stored pyramid level (overview) that is
  not smaller than the target; a level above :data:`BANDED_PIXELS` is decoded tile by
  tile (or strip by strip), each band of rows reduced across as soon as it is complete
  and the reduced rows then down (the area average is separable): one band and a
  ``height x target width`` float array in memory, never the frame.  A compression
  tifffile cannot decode without the optional imagecodecs package (JPEG-in-TIFF, as
  DJI/ODM write) falls back to pillow (libtiff), in memory.

Pixel coordinates follow ``docs/interfaces.md``: centres at integers, ``(0, 0)`` the
centre of the top-left pixel.  A level pixel ``(u_l, v_l)`` is the full-frame pixel
``u = (u_l + 0.5) * sx - 0.5``, ``v = (v_l + 0.5) * sy - 0.5`` (:meth:`GreyLevel.to_full`).
"""
import os
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError

__all__ = ["GreyLevel", "read_grey", "image_size", "BANDED_PIXELS", "TIFF_SUFFIXES"]

#: Frames with more pixels than this are decoded segment by segment, band by band.
BANDED_PIXELS = 40_000_000
#: Suffixes read with tifffile.
TIFF_SUFFIXES = (".tif", ".tiff", ".gtif")
_READ_BUFFER = 4 << 20          # compressed bytes tifffile reads at a time


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


def _grey(a, path, size=None):
    """uint8 grey of an (h, w), (h, w, c) array (first three channels averaged), reduced
    to ``size = (w, h)`` by area averages first; 8-bit data keep their levels, other
    data are stretched between the 0.5 and 99.5 percentiles of the reduced image."""
    a = np.asarray(a)
    eight_bit = a.dtype == np.uint8
    if a.ndim == 3:
        a = a[..., :3].mean(axis=-1, dtype=np.float32) if a.shape[-1] >= 3 else a[..., 0]
    if a.ndim != 2:
        raise InputError(f"not a single-frame image (array of shape {a.shape})", path=path)
    a = np.asarray(a, dtype=np.float32)
    if size is not None:
        a = _resize(a, size)
    if not eight_bit:
        lo, hi = np.nanpercentile(a, [0.5, 99.5]) if a.size else (0.0, 1.0)
        a = (a - lo) * (255.0 / max(hi - lo, 1e-12))
    return np.ascontiguousarray(np.clip(np.round(a), 0, 255), dtype=np.uint8)


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


def _reduce_segments(page, path, width, height, tw, th):
    """Decode a TIFF page segment by segment (tiles or strips, in row order); each band
    of rows, once complete, is reduced across (to ``tw`` columns), then the stack of
    reduced rows down (to ``th``).  The area average is separable, so this is the
    whole-frame reduction; memory: one band of the frame and ``height x tw`` floats
    (92 MB for a 13824-row DMC frame at 1667 columns), not the frame."""
    import cv2
    rows = np.zeros((height, tw), np.float32)
    bands = {}                  # y -> [rows, columns filled]: complete ones are reduced

    for seg, idx, shape in page.segments(maxworkers=1, buffersize=_READ_BUFFER):
        _, _, y, x, _ = idx
        h, w = min(shape[1], height - y), min(shape[2], width - x)
        if y not in bands:
            bands[y] = [np.zeros((h, width), np.float32), 0]
        a = np.asarray(seg).reshape(shape)[0]
        a = a[..., :3].mean(axis=-1, dtype=np.float32) if a.shape[-1] >= 3 else a[..., 0]
        band = bands[y]
        band[0][:, x:x + w] = a[:h, :w]
        band[1] += w
        if band[1] >= width:
            rows[y:y + h] = cv2.resize(band[0], (tw, h), interpolation=cv2.INTER_AREA)
            del bands[y]
    if bands:
        raise InputError("TIFF segments do not cover the frame", path=path)
    out = cv2.resize(rows, (tw, th), interpolation=cv2.INTER_AREA)
    if page.dtype == np.uint8:
        return np.clip(np.round(out), 0, 255).astype(np.uint8)
    return _grey(out.astype(np.float64), path)


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
        page = level.pages[0] if hasattr(level, "pages") else None
        if lw * lh <= BANDED_PIXELS or page is None or len(level.pages) != 1 \
                or page.planarconfig != 1:
            return width, height, _grey(_tiff_array(level.asarray(), level.axes), path,
                                        (tw, th))
        return width, height, _reduce_segments(page, path, lw, lh, tw, th)


def _read_pillow(path, max_side_px):
    import warnings

    from PIL import Image
    with warnings.catch_warnings():     # aerial frames are large by nature (a DMC frame
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)   # is 106 Mpx)
        with Image.open(path) as im:
            width, height = im.size
            tw, th = _target(width, height, max_side_px)
            if (tw, th) != (width, height):
                im.draft("L", (tw, th))   # JPEG: decode at 1/2, 1/4, 1/8 (not below target)
            a = np.asarray(im.convert("L"))
    return width, height, _grey(a, path, (tw, th))


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
