"""Layout check of COLMAP's binary model files before pycolmap reads them.

pycolmap reads a ``cameras.bin`` / ``images.bin`` / ``points3D.bin`` that was cut short
without a word (the missing records come out as zeros: a camera of focal length 0), so
the sizes are checked here against the record layout of COLMAP's
``src/colmap/scene/reconstruction_io.cc`` (little-endian):

- ``cameras.bin``: ``uint64 n``, then per camera ``uint32 camera_id, int32 model_id,
  uint64 width, uint64 height, float64 params[p(model)]``;
- ``images.bin``: ``uint64 n``, then per image ``uint32 image_id, float64 qvec[4],
  float64 tvec[3], uint32 camera_id, char name[] (NUL-terminated), uint64 m``, then
  ``m`` times ``float64 x, float64 y, uint64 point3D_id``;
- ``points3D.bin``: ``uint64 n``, then per point ``uint64 point3D_id, float64 xyz[3],
  uint8 rgb[3], float64 error, uint64 track_length``, then ``track_length`` times
  ``uint32 image_id, uint32 point2D_idx``.

A file whose records do not end exactly at its end is an :class:`InputError` naming the
file and the record.
"""
import os
import struct

from ins.common.errors import InputError

__all__ = ["check_binary_model", "PARAM_COUNT"]

#: COLMAP model id -> (name, number of parameters), for the models the reader takes.
PARAM_COUNT = {0: ("SIMPLE_PINHOLE", 3), 1: ("PINHOLE", 4), 2: ("SIMPLE_RADIAL", 4),
               3: ("RADIAL", 5), 4: ("OPENCV", 8), 6: ("FULL_OPENCV", 12)}

#: A count beyond this in a header is not a model this reader can hold in memory.
_MAX_COUNT = 10 ** 9


class _Reader:
    def __init__(self, path):
        self.path = path
        with open(path, "rb") as fh:
            self.buf = fh.read()
        self.pos = 0

    def take(self, fmt, what, record=None):
        size = struct.calcsize(fmt)
        if self.pos + size > len(self.buf):
            raise InputError(f"file cut short in {what} (bytes {self.pos}-"
                             f"{self.pos + size - 1} needed, the file has {len(self.buf)}; "
                             "COLMAP binary layout)", path=self.path, record=record)
        out = struct.unpack_from(fmt, self.buf, self.pos)
        self.pos += size
        return out

    def count(self, what):
        (n,) = self.take("<Q", f"the {what} count")
        if n > _MAX_COUNT:
            raise InputError(f"{what} count {n} is not plausible (a damaged header?)",
                             path=self.path)
        return n

    def end(self, n, what):
        if self.pos != len(self.buf):
            raise InputError(f"{len(self.buf) - self.pos} bytes after the {n} {what} the "
                             "header announces (COLMAP binary layout)", path=self.path)


def _cameras(path):
    r = _Reader(path)
    n = r.count("camera")
    for k in range(1, n + 1):
        _, model = r.take("<Ii", "camera id and model", k)
        if model not in PARAM_COUNT:
            raise InputError(f"camera model id {model} is not read ("
                             + ", ".join(f"{v[0]} = {i}" for i, v in PARAM_COUNT.items())
                             + ")", path=path, record=k)
        r.take("<QQ", "width and height", k)
        r.take(f"<{PARAM_COUNT[model][1]}d", f"the {PARAM_COUNT[model][0]} parameters", k)
    r.end(n, "cameras")


def _images(path):
    r = _Reader(path)
    n = r.count("image")
    for k in range(1, n + 1):
        r.take("<I7dI", "image id, pose and camera id", k)
        end = r.buf.find(b"\0", r.pos)
        if end < 0:
            raise InputError("file cut short in an image name (no NUL terminator)",
                             path=path, record=k)
        r.pos = end + 1
        (m,) = r.take("<Q", "the 2-D point count", k)
        if m > _MAX_COUNT:
            raise InputError(f"2-D point count {m} is not plausible", path=path, record=k)
        r.take(f"<{m * 24}s", f"{m} 2-D points", k)
    r.end(n, "images")


def _points(path):
    r = _Reader(path)
    n = r.count("3-D point")
    for k in range(1, n + 1):
        r.take("<Q3d3Bd", "point id, xyz, colour and error", k)
        (m,) = r.take("<Q", "the track length", k)
        if m > _MAX_COUNT:
            raise InputError(f"track length {m} is not plausible", path=path, record=k)
        r.take(f"<{m * 8}s", f"a track of {m} observations", k)
    r.end(n, "points")


def check_binary_model(folder):
    """Check the record layout of ``cameras.bin``, ``images.bin`` and ``points3D.bin`` in
    `folder` (those present); InputError naming the file and record otherwise."""
    for name, check in (("cameras.bin", _cameras), ("images.bin", _images),
                        ("points3D.bin", _points)):
        p = os.path.join(str(folder), name)
        if os.path.isfile(p):
            check(p)
