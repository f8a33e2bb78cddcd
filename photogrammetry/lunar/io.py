"""Inputs of the lunar heading: exposure times, measured centres, Moon images.

TIMES.csv (``#`` comments allowed)::

    image_id,utc                        # ISO 8601 UTC, e.g. 2017-05-12T15:00:00.250Z
    image_id,gps_week,gps_time_s        # or GPS time (GPS = UTC + 18 s since 2017)

CENTRES.csv::

    image_id,u_px,v_px[,sigma_px]       # or sigma_u_px,sigma_v_px; default sigma 0.1 px

Images: ``<image_id>.png|.tif|.tiff|.fits|.fit`` in a folder (grayscale; colour is
averaged).  FITS needs astropy (a test/bench extra).
"""
import csv
import os

import numpy as np

from ins import textfiles
from ins.errors import InputError
from ins.fileio import atomic_open

__all__ = ["read_times", "write_times", "read_centres", "load_image", "find_images",
           "GPS_EPOCH", "GPS_MINUS_UTC_S"]

GPS_EPOCH = np.datetime64("1980-01-06T00:00:00", "ns")
GPS_MINUS_UTC_S = 18          # leap seconds since 2017-01-01 (conventions.md)
IMAGE_EXTENSIONS = (".png", ".tif", ".tiff", ".fits", ".fit")
#: Accepted span of exposure times (UTC) and the last accepted GPS week (year 2200).
_FIRST_UTC = np.datetime64("1980-01-06")
_LAST_UTC = np.datetime64("2200-01-01")
MAX_GPS_WEEK = 11427


def _rows(path):
    """(header, [(line number, fields)]) of a CSV file with ``#`` comments."""
    text = textfiles.read_text(path, "a CSV file with a header line")
    lines = [(k + 1, line) for k, line in enumerate(text.splitlines())
             if line.strip() and not line.lstrip().startswith("#")]
    if not lines:
        raise InputError("empty file (expected a header line and rows)", path)
    rows = list(csv.reader([line for _, line in lines], skipinitialspace=True))
    header = [h.strip() for h in rows[0]]
    body = []
    for (num, _), fields in zip(lines[1:], rows[1:]):
        if len(fields) != len(header):
            raise InputError(f"expected {len(header)} fields ({','.join(header)}), "
                             f"got {len(fields)}", path, num)
        body.append((num, dict(zip(header, (x.strip() for x in fields)))))
    return header, body


def _number(text, path, line, name):
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{name}: expected a number, got {text!r}", path, line) from None
    if not np.isfinite(value):
        raise InputError(f"{name}: expected a finite number, got {text!r}", path, line)
    return value


def read_times(path):
    """Exposure times.

    Returns
    -------
    ids : list of str
    utc : ndarray of datetime64[ns], shape (n,)

    Raises
    ------
    InputError
        Bad fields, duplicate ids, or times not strictly increasing (file:line).
    """
    header, body = _rows(path)
    if "image_id" not in header or not ("utc" in header or {"gps_week", "gps_time_s"} <= set(header)):
        raise InputError("header must be image_id,utc or image_id,gps_week,gps_time_s, got "
                         + ",".join(header), path, 1)
    ids, times = [], []
    for line, row in body:
        if "utc" in row:
            text = row["utc"].rstrip("Z").replace(" ", "T")
            try:
                t = np.datetime64(text)          # its own unit: no silent ns overflow
            except ValueError:
                t = None
            if t is None or np.isnat(t) or not _FIRST_UTC <= t < _LAST_UTC:
                raise InputError(f"utc: expected ISO 8601 UTC between 1980 and 2200 "
                                 f"(2017-05-12T15:00:00.25Z), got {row['utc']!r}",
                                 path, line)
            t = t.astype("datetime64[ns]")
        else:
            week = _number(row["gps_week"], path, line, "gps_week")
            sec = _number(row["gps_time_s"], path, line, "gps_time_s")
            if week != int(week) or not 0 <= week <= MAX_GPS_WEEK:
                raise InputError(f"gps_week: expected an integer week 0 .. {MAX_GPS_WEEK} "
                                 f"(continuous, since 1980-01-06), got {row['gps_week']!r}",
                                 path, line)
            if not 0 <= sec <= 604800:
                raise InputError(f"gps_time_s: expected seconds of the week 0 .. 604800, "
                                 f"got {row['gps_time_s']!r}", path, line)
            ns = int(round((week * 604800 + sec - GPS_MINUS_UTC_S) * 1e9))
            t = GPS_EPOCH + np.timedelta64(ns, "ns")
        if ids and t <= times[-1]:
            raise InputError(f"times out of order: {t} is not after the previous {times[-1]}",
                             path, line)
        if row["image_id"] in ids:
            raise InputError(f"duplicate image_id {row['image_id']!r}", path, line)
        ids.append(row["image_id"])
        times.append(t)
    return ids, np.array(times, dtype="datetime64[ns]")



def write_times(path, ids, utc):
    """Write exposure times as ``image_id,utc`` (ISO 8601 UTC with a ``Z``), atomically.

    The times are written to the nanosecond their ``datetime64`` holds (milliseconds when
    they are whole milliseconds), so `read_times` gives them back exactly.

    Parameters
    ----------
    path : str
    ids : sequence of str
        Image ids (no commas, unique).
    utc : array_like of datetime64, shape (n,)
        Strictly increasing, UTC.
    """
    utc = np.asarray(utc, dtype="datetime64[ns]")
    unit = "ms" if np.all(utc.astype("int64") % 1_000_000 == 0) else "ns"
    text = np.datetime_as_string(utc, unit=unit)
    with atomic_open(path, "w") as f:
        f.write("image_id,utc\n")
        f.writelines(f"{k},{t}Z\n" for k, t in zip(ids, text))


def read_centres(path, default_sigma_px=0.1):
    """Measured Moon centres.

    Returns
    -------
    ids : list of str
    uv : ndarray, shape (n, 2)
        Column, row, px.
    cov_uv : ndarray, shape (n, 2, 2)
        px^2.
    """
    header, body = _rows(path)
    if not {"image_id", "u_px", "v_px"} <= set(header):
        raise InputError("header must contain image_id,u_px,v_px, got " + ",".join(header),
                         path, 1)
    ids, uv, cov = [], [], []
    for line, row in body:
        u = _number(row["u_px"], path, line, "u_px")
        v = _number(row["v_px"], path, line, "v_px")
        if "sigma_u_px" in row and "sigma_v_px" in row:
            su = _number(row["sigma_u_px"], path, line, "sigma_u_px")
            sv = _number(row["sigma_v_px"], path, line, "sigma_v_px")
        elif "sigma_px" in row:
            su = sv = _number(row["sigma_px"], path, line, "sigma_px")
        else:
            su = sv = default_sigma_px
        if su <= 0 or sv <= 0:
            raise InputError("sigma: expected a positive value in px", path, line)
        ids.append(row["image_id"])
        uv.append((u, v))
        cov.append(np.diag([su * su, sv * sv]))
    return ids, np.array(uv, float).reshape(-1, 2), np.array(cov, float).reshape(-1, 2, 2)


def find_images(folder):
    """``{image_id: path}`` of the image files in a folder (id = file name without extension)."""
    if not os.path.isdir(folder):
        raise InputError("--images: not a folder", folder)
    out = {}
    for name in sorted(os.listdir(folder)):
        stem, ext = os.path.splitext(name)
        if ext.lower() in IMAGE_EXTENSIONS:
            out[stem] = os.path.join(folder, name)
    return out


def load_image(path, dtype=float):
    """A grayscale image as an array (rows, columns); colour channels are averaged.

    ``dtype=None`` keeps the file's type for grayscale images (e.g. uint16 of a 16-bit
    PNG: no float copy of the whole frame); otherwise the array is converted to ``dtype``.
    """
    ext = os.path.splitext(path)[1].lower()
    if ext in (".fits", ".fit"):
        try:
            from astropy.io import fits
        except ImportError:
            raise InputError("reading FITS needs astropy (pip install astropy), "
                             "or convert the image to PNG/TIFF", path) from None
        with fits.open(path) as hdul:
            data = next((h.data for h in hdul if getattr(h, "data", None) is not None), None)
        if data is None:
            raise InputError("no image data in the FITS file", path)
        img = np.asarray(data)
    elif ext in (".tif", ".tiff"):
        import tifffile
        img = np.asarray(tifffile.imread(path))
    else:
        from PIL import Image
        try:
            with Image.open(path) as im:
                im.load()
                if im.mode == "I;16":      # 16-bit grayscale: its bytes, without a copy
                    img = np.frombuffer(im.tobytes(), "<u2").reshape(im.height, im.width)
                else:
                    img = np.asarray(im)
        except OSError as exc:
            raise InputError(f"cannot read the image: {exc}", path) from None
    if img.ndim == 3:
        img = img[..., :3].mean(axis=-1) if img.shape[-1] in (3, 4) else img[0]
    if img.ndim != 2:
        raise InputError(f"expected a grayscale image, got shape {img.shape}", path)
    return img if dtype is None else img.astype(dtype, copy=False)
