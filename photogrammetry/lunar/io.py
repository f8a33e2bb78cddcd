"""Inputs of the lunar heading: exposure times, measured centres, Moon images.

TIMES.csv (``#`` comments allowed)::

    image_id,utc                        # ISO 8601 UTC, e.g. 2017-05-12T15:00:00.250Z
    image_id,gps_week,gps_time_s        # or GPS time (GPS = UTC + 18 s since 2017)

CENTRES.csv::

    image_id,u_px,v_px[,sigma_px]       # or sigma_u_px,sigma_v_px; default sigma 0.1 px

Images: ``<image_id>.png|.tif|.tiff|.fits|.fit`` in a folder (grayscale; colour is
averaged).  FITS needs astropy (the extra ``fits``); its header gives the exposure time
(`fits_time`) and the clipping level (`fits_saturation`).
"""
import csv
import os
import re

import numpy as np

from ins.common import textfiles
from ins.common.errors import InputError
from ins.common.fileio import atomic_open

__all__ = ["read_times", "write_times", "read_centres", "load_image", "load_image_meta",
           "find_images", "fits_time", "fits_header_time", "fits_saturation", "parse_time_zone", "GPS_EPOCH",
           "GPS_MINUS_UTC_S"]

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


_ZONE = re.compile(r"^(UTC|Z)?([+-])(\d\d):?(\d\d)$")


def parse_time_zone(text, option="--time-zone"):
    """A time-zone offset ``+08:00`` / ``-0530`` / ``UTC`` / ``Z`` as numpy timedelta64[ns]
    (local time = UTC + offset)."""
    t = str(text).strip().upper()
    if t in ("UTC", "Z", "+00:00", "00:00"):
        return np.timedelta64(0, "ns")
    m = _ZONE.match(t)
    if not m or int(m.group(3)) > 14 or int(m.group(4)) >= 60:
        raise InputError(f"{option}: expected an offset from UTC as +HH:MM or -HH:MM "
                         f"(+08:00 for China), or UTC, got {text!r}")
    minutes = int(m.group(3)) * 60 + int(m.group(4))
    return np.timedelta64((1 if m.group(2) == "+" else -1) * minutes * 60_000_000_000, "ns")


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


def _read_fits(path):
    """(data, header) of the first HDU with an image."""
    try:
        from astropy.io import fits
    except ImportError:
        raise InputError("reading FITS needs astropy: pip install 'insphoto[fits]' (or "
                         "convert the image to PNG/TIFF)", path) from None
    try:
        with fits.open(path) as hdul:
            for h in hdul:
                if getattr(h, "data", None) is not None and np.ndim(h.data) >= 2:
                    return np.asarray(h.data), h.header
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read the FITS file: {exc}", path) from None
    raise InputError("no image data in the FITS file", path)


_DMY = re.compile(r"^(\d\d)/(\d\d)/(\d\d)$")        # the pre-1999 DATE-OBS form dd/mm/yy
FITS_TIMESYS = ("UTC", "UT")


def _fits_datetime(text, path, key):
    """An ISO 8601 date-time (or date) of a FITS header value as datetime64[ns]."""
    text = str(text).strip().rstrip("Z")
    m = _DMY.match(text)
    if m:
        text = f"19{m.group(3)}-{m.group(2)}-{m.group(1)}"
    try:
        t = np.datetime64(text, "ns")
    except ValueError:
        t = None
    if t is None or np.isnat(t):
        raise InputError(f"{key}: expected an ISO 8601 date-time (2017-05-12T15:00:00.25), "
                         f"got {text!r}", path)
    return t


def fits_time(header, path):
    """Mid-exposure time of a FITS header in the header's own time zone, datetime64[ns].

    Rule: ``DATE-AVG`` (mid-exposure) when present; else ``DATE-OBS`` (the start: a full
    date-time, or a date with ``TIME-OBS``/``UT``) plus half of ``EXPTIME``
    (or ``EXPOSURE``), s, when present.  ``TIMESYS`` must be absent, UTC or UT (the
    time zone of local-time headers is the caller's option).  None without a date.
    """
    sys_ = str(header.get("TIMESYS", "UTC")).strip().upper()
    if sys_ not in FITS_TIMESYS:
        raise InputError(f"TIMESYS = {sys_!r}: only UTC header times are read (convert "
                         "them, or give --times)", path)
    if "DATE-AVG" in header:
        return _fits_datetime(header["DATE-AVG"], path, "DATE-AVG")
    if "DATE-OBS" not in header:
        return None
    date = str(header["DATE-OBS"]).strip()
    if "T" not in date:
        clock = header.get("TIME-OBS", header.get("UT"))
        if clock is not None:
            date = f"{_fits_datetime(date, path, 'DATE-OBS').astype('datetime64[D]')}" \
                   f"T{str(clock).strip()}"
    t = _fits_datetime(date, path, "DATE-OBS")
    exptime = header.get("EXPTIME", header.get("EXPOSURE"))
    if exptime is not None:
        try:
            half = float(exptime) / 2
        except (TypeError, ValueError):
            raise InputError(f"EXPTIME: expected seconds, got {exptime!r}", path) from None
        if not (np.isfinite(half) and half >= 0):
            raise InputError(f"EXPTIME: expected seconds >= 0, got {exptime!r}", path)
        t = t + np.timedelta64(int(round(half * 1e9)), "ns")
    return t


def fits_header_time(path):
    """`fits_time` of the first image HDU of a FITS file (its header only), or None."""
    try:
        from astropy.io import fits
    except ImportError:
        raise InputError("reading FITS needs astropy: pip install 'insphoto[fits]'",
                         path) from None
    try:
        with fits.open(path) as hdul:
            for h in hdul:
                if int(h.header.get("NAXIS", 0)) >= 2:
                    return fits_time(h.header, str(path))
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read the FITS file: {exc}", path) from None
    raise InputError("no image data in the FITS file", path)


def fits_saturation(header):
    """The clipping level of a FITS header: ``SATURATE``, else ``DATAMAX``; None."""
    for key in ("SATURATE", "DATAMAX"):
        v = header.get(key)
        if v is not None:
            try:
                v = float(v)
            except (TypeError, ValueError):
                continue
            if np.isfinite(v) and v > 0:
                return v
    return None


def load_image_meta(path, dtype=None):
    """`load_image` and what the file tells about the exposure: ``{"saturation": counts
    or None, "time": datetime64[ns] or None (FITS: `fits_time`, in the header's zone)}``."""
    ext = os.path.splitext(str(path))[1].lower()
    if ext in (".fits", ".fit"):
        data, header = _read_fits(str(path))
        img = _gray(np.asarray(data), path)
        meta = {"saturation": fits_saturation(header), "time": fits_time(header, str(path))}
        return (img if dtype is None else img.astype(dtype, copy=False)), meta
    return load_image(path, dtype), {"saturation": None, "time": None}


def _gray(img, path):
    if img.ndim == 3:
        img = img[..., :3].mean(axis=-1) if img.shape[-1] in (3, 4) else img[0]
    if img.ndim != 2:
        raise InputError(f"expected a grayscale image, got shape {img.shape}", path)
    if img.dtype.byteorder not in ("=", "|"):          # FITS is big-endian
        img = img.astype(img.dtype.newbyteorder("="))
    return img


def load_image(path, dtype=float):
    """A grayscale image as an array (rows, columns); colour channels are averaged.

    ``dtype=None`` keeps the file's type for grayscale images (e.g. uint16 of a 16-bit
    PNG: no float copy of the whole frame); otherwise the array is converted to ``dtype``.
    FITS needs astropy (the extra ``fits``).
    """
    path = str(path)
    ext = os.path.splitext(path)[1].lower()
    if ext in (".fits", ".fit"):
        img = _read_fits(path)[0]
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
    img = _gray(img, path)
    return img if dtype is None else img.astype(dtype, copy=False)
