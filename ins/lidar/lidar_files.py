"""LiDAR returns in (CSV or LAS/LAZ in the scanner frame) and georeferenced points out
(LAS/LAZ through laspy, the optional extra ``lidar``).

Returns CSV (``docs/interfaces.md``): a header line naming the columns, then one return
a line, commas or blanks between the numbers, ``#`` comments allowed::

    time_s,range_m,scan_angle_deg[,intensity][,return_number][,number_of_returns][,strip]
    time_s,x_s_m,y_s_m,z_s_m[,intensity][,return_number][,number_of_returns][,strip]

(line scanners; model "points").  Without ``number_of_returns``, the returns of one pulse
are the consecutive lines of equal ``time_s`` (and strip): their number of returns is
the largest return number among them (a block never splits such a group).

Returns LAS/LAZ: points in the scanner frame (x, y, z in m), GPS time in s on the
trajectory's time scale, intensity, return number, number of returns and point source id
(the strip) kept.

Points LAS/LAZ out: LAS 1.4, point format 6 (GPS time, intensity, return number and
number of returns, scan angle in 0.006 deg, point source id = strip), extra dimensions
``sigma_e_m``, ``sigma_n_m``, ``sigma_u_m`` (each axis's own sigma, east, north, up of
the local level at the point), ``sigma_h_m`` (``sqrt(var_N + var_E)``) and ``sigma_v_m``
(``= sigma_u_m``), float32; the CRS as a WKT VLR; z is the ellipsoidal height (WGS84)
whatever the horizontal CRS.  One horizontal sigma cannot serve both axes: an attitude
error moves the points along or across the flight line by very different amounts.
"""
import os
from dataclasses import dataclass

import numpy as np

from ins.common import textfiles
from ins.common.errors import InputError

__all__ = ["ReturnsBlock", "count_returns", "iter_returns", "LasPointWriter", "utm_crs",
           "import_laspy"]

_LINE_COLS = ("time_s", "range_m", "scan_angle_deg")
_POINT_COLS = ("time_s", "x_s_m", "y_s_m", "z_s_m")
_OPTIONAL = ("intensity", "return_number", "number_of_returns", "strip")
LIDAR_EXTRA = "pip install 'insphoto[lidar]'"


def import_laspy():
    """laspy with its LAZ backend, or an :class:`InputError` naming the extra."""
    try:
        import laspy
    except ImportError:
        raise InputError(f"LAS/LAZ files need laspy: {LIDAR_EXTRA}") from None
    return laspy


@dataclass
class ReturnsBlock:
    """A block of returns.

    Attributes
    ----------
    time : ndarray (n,)
        s.
    range_m, scan_angle_rad : ndarray (n,) or None
        Line scanners.
    xyz_s_m : ndarray (n, 3) or None
        Model "points".
    intensity, return_number, strip : ndarray (n,) of int
        Zeros / ones when not given.
    number_of_returns : ndarray (n,) of int
        Returns of the pulse (given, or from the pulse's lines: see the module).
    """

    time: np.ndarray
    range_m: np.ndarray = None
    scan_angle_rad: np.ndarray = None
    xyz_s_m: np.ndarray = None
    intensity: np.ndarray = None
    return_number: np.ndarray = None
    strip: np.ndarray = None
    number_of_returns: np.ndarray = None

    def __len__(self):
        return len(self.time)


def _is_las(path):
    if os.fspath(path).lower().endswith((".las", ".laz")):
        return True
    with open(path, "rb") as f:
        return f.read(4) == b"LASF"


def _csv_header(path):
    """Column names and the number of lines up to and including the header line."""
    with open(path, "rb") as f:
        for i, raw in enumerate(f, start=1):
            line = raw.decode("utf-8", "replace").strip()
            if not line or line.startswith("#"):
                continue
            names = [c.strip() for c in line.replace(",", " ").split()]
            return names, i
    raise InputError("no header line (expected time_s,range_m,scan_angle_deg or "
                     "time_s,x_s_m,y_s_m,z_s_m)", path=os.fspath(path))


def _columns(path, model):
    names, nhead = _csv_header(path)
    need = _POINT_COLS if model == "points" else _LINE_COLS
    if tuple(names[:len(need)]) != need:
        raise InputError(f"header {','.join(names)!r}: expected {','.join(need)} first "
                         f"(scanner model {model!r}), then optionally "
                         f"{', '.join(_OPTIONAL)}", path=os.fspath(path), line=nhead)
    extra = names[len(need):]
    bad = [n for n in extra if n not in _OPTIONAL]
    if bad or len(set(extra)) != len(extra):
        raise InputError(f"header column {bad[0] if bad else extra!r} unknown or repeated "
                         f"(optional columns: {', '.join(_OPTIONAL)})", path=os.fspath(path),
                         line=nhead)
    return names, nhead


def count_returns(path):
    """Number of returns (LAS: the header's count; CSV: the non-empty lines, bounded
    by a count of newlines, for progress only)."""
    if _is_las(path):
        laspy = import_laspy()
        with laspy.open(os.fspath(path)) as r:
            return int(r.header.point_count)
    n = 0
    with open(path, "rb") as f:
        while True:
            b = f.read(1 << 24)
            if not b:
                break
            n += b.count(b"\n")
    return n


#: Largest range of a return, m (airborne and terrestrial scanners reach some km).
MAX_RANGE_M = 1.0e5


def _ints(a, name, path, lines, lo, hi):
    bad = np.flatnonzero((a != np.round(a)) | (a < lo) | (a > hi))
    if bad.size:
        raise InputError(f"{name} {a[bad[0]].item()!r} must be an integer in [{lo}, {hi}]",
                         path=os.fspath(path), line=int(lines[bad[0]]))
    return a.astype(np.int64)


def iter_returns(path, model, block_size=1_000_000):
    """Read returns block by block (:class:`ReturnsBlock`; bounded memory).

    Raises
    ------
    InputError
        Naming the file and line: header, column count, non-finite value, a range <= 0,
        an integer column out of range.
    """
    if _is_las(path):
        yield from _iter_las(path, model, block_size)
        return
    names, nhead = _columns(path, model)
    pending = []
    npend = 0
    for values, lines in textfiles.iter_table(path, len(names), len(names),
                                              hint=",".join(names),
                                              skip_header_lines=nhead):
        pending.append((values, lines))
        npend += len(values)
        while npend > block_size:
            v = np.concatenate([p[0] for p in pending])
            ln = np.concatenate([p[1] for p in pending])
            cut = _pulse_cut(v, block_size, names)
            yield _csv_block(path, names, model, v[:cut], ln[:cut])
            pending = [(v[cut:], ln[cut:])]
            npend = len(pending[0][0])
    if npend:
        v = np.concatenate([p[0] for p in pending])
        ln = np.concatenate([p[1] for p in pending])
        yield _csv_block(path, names, model, v, ln)


def _pulse_cut(v, block_size, names):
    """Where to end a block of `block_size` lines or fewer without splitting the lines of
    one pulse (equal time and strip); the whole block if one pulse fills it."""
    key = [0] + ([names.index("strip")] if "strip" in names else [])
    cut = block_size
    while cut > 0 and np.array_equal(v[cut, key], v[cut - 1, key]):
        cut -= 1
    return cut if cut > 0 else block_size


def _pulse_counts(time, strip, return_number):
    """Number of returns of each line's pulse: the largest return number among the
    consecutive lines of equal time and strip."""
    if len(time) == 0:
        return return_number.copy()
    new = np.concatenate([[True], (np.diff(time) != 0) | (np.diff(strip) != 0)])
    start = np.flatnonzero(new)
    top = np.maximum.reduceat(return_number, start)
    return np.repeat(top, np.diff(np.append(start, len(time))))


def _csv_block(path, names, model, v, lines):
    bad = np.flatnonzero(~np.all(np.isfinite(v), axis=1))
    if bad.size:
        raise InputError("non-finite value", path=os.fspath(path), line=int(lines[bad[0]]))
    col = {n: v[:, i] for i, n in enumerate(names)}
    n = len(v)
    blk = ReturnsBlock(time=col["time_s"].copy())
    if model == "points":
        far = np.flatnonzero(np.any(np.abs(v[:, 1:4]) > MAX_RANGE_M, axis=1))
        if far.size:
            raise InputError(f"point {', '.join(f'{x:g}' for x in v[far[0], 1:4])} m is "
                             f"farther than {MAX_RANGE_M:g} m from the scanner",
                             path=os.fspath(path), line=int(lines[far[0]]))
        blk.xyz_s_m = v[:, 1:4].copy()
    else:
        bad = np.flatnonzero((col["range_m"] <= 0) | (col["range_m"] > MAX_RANGE_M))
        if bad.size:
            raise InputError(f"range_m {float(col['range_m'][bad[0]]):g} must be in "
                             f"(0, {MAX_RANGE_M:g}] m",
                             path=os.fspath(path), line=int(lines[bad[0]]))
        big = np.flatnonzero(np.abs(col["scan_angle_deg"]) >= 90)
        if big.size:
            raise InputError(f"scan_angle_deg {float(col['scan_angle_deg'][big[0]])!r} must be "
                             "within +-90 deg", path=os.fspath(path), line=int(lines[big[0]]))
        blk.range_m = col["range_m"].copy()
        blk.scan_angle_rad = np.deg2rad(col["scan_angle_deg"])
    blk.intensity = (_ints(col["intensity"], "intensity", path, lines, 0, 65535)
                     if "intensity" in col else np.zeros(n, np.int64))
    blk.return_number = (_ints(col["return_number"], "return_number", path, lines, 1, 15)
                         if "return_number" in col else np.ones(n, np.int64))
    blk.strip = (_ints(col["strip"], "strip", path, lines, 0, 65535)
                 if "strip" in col else np.zeros(n, np.int64))
    if "number_of_returns" in col:
        blk.number_of_returns = _ints(col["number_of_returns"], "number_of_returns", path,
                                      lines, 1, 15)
        bad = np.flatnonzero(blk.return_number > blk.number_of_returns)
        if bad.size:
            raise InputError(f"return_number {int(blk.return_number[bad[0]])} above "
                             f"number_of_returns {int(blk.number_of_returns[bad[0]])}",
                             path=os.fspath(path), line=int(lines[bad[0]]))
    else:
        blk.number_of_returns = _pulse_counts(blk.time, blk.strip, blk.return_number)
    return blk


def _iter_las(path, model, block_size):
    if model != "points":
        raise InputError(f"a LAS/LAZ input holds points in the scanner frame: the scanner "
                         f"model must be \"points\", not {model!r}", path=os.fspath(path))
    laspy = import_laspy()
    try:
        reader = laspy.open(os.fspath(path))
    except Exception as exc:       # laspy raises its own LaspyException and OSError
        raise InputError(f"not a readable LAS/LAZ file: {exc}", path=os.fspath(path)) from None
    with reader:
        if "gps_time" not in reader.header.point_format.dimension_names:
            raise InputError(f"point format {reader.header.point_format.id} has no GPS time "
                             "(needed to interpolate the trajectory)", path=os.fspath(path))
        for chunk in reader.chunk_iterator(block_size):
            yield ReturnsBlock(time=np.asarray(chunk.gps_time, dtype=float),
                               xyz_s_m=np.column_stack([np.asarray(chunk.x, float),
                                                        np.asarray(chunk.y, float),
                                                        np.asarray(chunk.z, float)]),
                               intensity=np.asarray(chunk.intensity, np.int64),
                               return_number=np.asarray(chunk.return_number, np.int64),
                               strip=np.asarray(chunk.point_source_id, np.int64),
                               number_of_returns=np.maximum(
                                   np.asarray(chunk.number_of_returns, np.int64),
                                   np.asarray(chunk.return_number, np.int64)))


def utm_crs(lat_deg, lon_deg):
    """The WGS84 / UTM zone CRS (EPSG 326zz north, 327zz south) of a position."""
    from pyproj import CRS
    zone = int(np.floor((lon_deg + 180.0) / 6.0)) % 60 + 1
    return CRS.from_epsg((32600 if lat_deg >= 0 else 32700) + zone)


def compound_crs(crs, height):
    """``crs`` (horizontal) with the vertical CRS of ``height``'s geoid model."""
    from pyproj import CRS
    from pyproj.crs import CompoundCRS
    vertical = CRS.from_epsg(height.geoid.vertical_epsg)
    return CompoundCRS(f"{crs.name} + {vertical.name}", [crs, vertical])


class LasPointWriter:
    """Write georeferenced points to LAS/LAZ in blocks (LAZ by the ``.laz`` extension).

    Use as a context manager around an open binary file (e.g. from
    :func:`ins.common.fileio.atomic_open`).

    Parameters
    ----------
    f : binary file object (seekable)
    crs : pyproj.CRS
        Horizontal CRS of x, y (geographic: degrees, else metres).
    offset : (float, float, float)
        LAS offsets in the CRS units (near the data).
    compress : bool
        LAZ.
    height : ins.io.geoid.HeightSystem, optional
        z: ellipsoidal (default) or orthometric ``H = h - N`` of a geoid model; the CRS
        written is then the compound of ``crs`` and the model's vertical CRS (EGM2008
        height EPSG:3855, EGM96 height EPSG:5773).
    """

    def __init__(self, f, crs, offset, compress, height=None):
        from pyproj import Transformer
        laspy = import_laspy()
        self.height = height if height is not None and height.orthometric else None
        header = laspy.LasHeader(point_format=6, version="1.4")
        header.add_extra_dims([laspy.ExtraBytesParams(f"sigma_{a}_m", np.float32,
                                                      description=f"{name} sigma m")
                               for a, name in (("e", "east"), ("n", "north"), ("u", "up"))]
                              + [laspy.ExtraBytesParams("sigma_h_m", np.float32,
                                                        description="horizontal sigma m"),
                                 laspy.ExtraBytesParams("sigma_v_m", np.float32,
                                                        description="vertical sigma m")])
        geographic = crs.is_geographic
        header.scales = np.array([1e-8, 1e-8, 1e-3] if geographic else [1e-3] * 3)
        header.offsets = np.asarray(offset, dtype=float)
        header.add_crs(crs if self.height is None else compound_crs(crs, self.height))
        self.header = header
        self.transformer = Transformer.from_crs("EPSG:4978", crs, always_xy=True)
        self._laspy = laspy
        self._writer = laspy.open(f, mode="w", header=header, do_compress=compress,
                                  closefd=False)
        self.count = 0

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._writer.close()
        return False

    def write(self, points, intensity, return_number, scan_angle_deg, strip,
              number_of_returns=None):
        """Append a block (``points``: :class:`ins.lidar.georeference.Points`; the number of
        returns defaults to the return number)."""
        n = len(points.time)
        if n == 0:
            return
        x, y, z = self.transformer.transform(points.xyz_ecef_m[:, 0], points.xyz_ecef_m[:, 1],
                                             points.xyz_ecef_m[:, 2])
        if self.height is not None:
            lla = points.lla()
            z = np.asarray(z) - self.height.undulation(lla[:, 0], lla[:, 1])
        rec = self._laspy.ScaleAwarePointRecord.zeros(n, header=self.header)
        rec.x, rec.y, rec.z = x, y, z
        rec.gps_time = points.time
        rec.intensity = np.clip(intensity, 0, 65535).astype(np.uint16)
        rec.return_number = np.clip(return_number, 1, 15).astype(np.uint8)
        rec.number_of_returns = np.clip(return_number if number_of_returns is None
                                        else number_of_returns, 1, 15).astype(np.uint8)
        rec.scan_angle = np.clip(np.round(np.asarray(scan_angle_deg) / 0.006), -30000,
                                 30000).astype(np.int16)
        rec.point_source_id = np.clip(strip, 0, 65535).astype(np.uint16)
        sig = points.sigma_enu_m.astype(np.float32)
        rec.sigma_e_m, rec.sigma_n_m, rec.sigma_u_m = sig[:, 0], sig[:, 1], sig[:, 2]
        rec.sigma_h_m = points.sigma_h_m.astype(np.float32)
        rec.sigma_v_m = points.sigma_v_m.astype(np.float32)
        self._writer.write_points(rec)
        self.count += n
