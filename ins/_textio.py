"""Fast, exact reading and writing of numeric text tables (private; numba kernels).

Reading
-------
:func:`parse_table` turns the bytes of a text file into a float64 table.  Lines end with
``\\n`` (``\\r\\n`` works: ``\\r`` counts as blank space); fields are separated by blanks
(spaces, tabs) and/or one comma; blank lines and lines whose first non-blank character
is ``#`` or ``%`` are skipped, and a ``#`` or ``%`` after a blank ends a data line
(trailing comment).  The first data line fixes the table's width; every later data line
must have the same number of fields.  A field must be a whole decimal number
(``[+-]digits[.digits][e[+-]digits]``, also ``.5`` and ``5.``) or ``inf``,
``infinity``, ``nan`` (any case): ``1.2.3``, ``abc``, ``1e``, hexadecimal floats and
empty fields (``1,,2``) are errors.  NaN and inf are returned as numbers; the caller
decides about them, naming the line through the row-to-line map.

Numbers are converted exactly (bit-identical to ``float()``, ``np.loadtxt`` and glibc's
correctly rounded ``strtod``) inside a numba kernel: decimals of at most 18 significant
digits by Clinger's exact fast path or a double-double product with a certified
rounding; everything else (more digits, inf, nan, and the rare roundings the
double-double product cannot decide, such as exact ties) by the C library's ``strtod``
called from the kernel.  About 0.10 s for the 302 k-line, 7-column, 48 MB benchmark log
(glibc ``strtod`` alone: 0.23 s; ``np.loadtxt``: 0.65 s).  Where ``strtod`` cannot be
linked, or the process's numeric locale does not use ``.`` as the decimal point, a
pure-Python fallback with the same outputs (about 20x slower) is used.

Writing
-------
:func:`format_fixed` writes a float64 table in fixed-point notation with a number of
decimals per column (as ``'%.{d}f' % x``, digit for digit: the product ``x * 10**d``
is formed exactly with Dekker's two-product and rounded to nearest, ties to even,
which is what Python does).  :func:`format_table` also accepts ``-1`` decimals for a
column written as ``'%.17e'`` (scientific, 18 significant digits), which reads back to
the same float64.  :func:`roundtrip_decimals` finds the fewest decimals with which a
column reads back exactly, if any.  This module does not write files.
"""
import functools
import locale
import os
import re
from typing import NamedTuple

import numba
import numpy as np
from numba import types

from .errors import InputError

__all__ = [
    "ParsedTable", "parse_table", "file_buffer", "read_table", "table_error_message",
    "is_number", "read_text", "read_toml", "iter_table",
    "format_fixed", "format_table", "roundtrip_decimals",
    "OK", "NO_DATA", "TOO_FEW_COLUMNS", "TOO_MANY_COLUMNS", "COLUMN_COUNT", "BAD_NUMBER",
    "EMPTY_FIELD",
]

# ---------------------------------------------------------------------------------------
# status codes of parse_table
OK = 0
NO_DATA = 1            #: no data line at all
TOO_FEW_COLUMNS = 2    #: the first data line has fewer than ncols_min fields
TOO_MANY_COLUMNS = 3   #: the first data line has more than ncols_max fields
COLUMN_COUNT = 4       #: a later data line has another number of fields than the first
BAD_NUMBER = 5         #: a field is not a whole number (text, 1.2.3, 1e, 0x1p3, ...)
EMPTY_FIELD = 6        #: an empty field between commas or after a trailing comma

_NL, _CR, _SP, _TAB, _COMMA, _HASH, _PCT = 10, 13, 32, 9, 44, 35, 37

_strtod = types.ExternalFunction("strtod", types.float64(types.voidptr, types.voidptr))


def _strtod_available():
    """True when numba can link the C library's ``strtod`` in this process."""
    try:
        import llvmlite.binding as llvm
        if llvm.address_of_symbol("strtod"):
            return True
        import ctypes.util
        name = ctypes.util.find_library("c")
        if name:
            llvm.load_library_permanently(name)
        return bool(llvm.address_of_symbol("strtod"))
    except Exception:   # pragma: no cover - exotic platform
        return False


_HAVE_STRTOD = _strtod_available()


# ---------------------------------------------------------------------------------------
# exact arithmetic helpers

_TWO52 = 4503599627370496.0
_MAX_FIXED = 9e18
_SCI_LO, _SCI_HI = 1e-280, 1e280      # scientific kernel domain (else Python fallback)
_P10_MIN, _P10_MAX = -270, 300


@functools.lru_cache(maxsize=1)
def _pow10_table():
    """Powers of ten 10**p, p in [_P10_MIN, _P10_MAX], as double-double (hi, lo).

    ``hi`` is 10**p correctly rounded, ``lo`` the remainder 10**p - hi correctly
    rounded (Python's int / int division and int-to-float conversion are exact-rounded).
    """
    p = np.arange(_P10_MIN, _P10_MAX + 1)
    hi = np.empty(p.size)
    lo = np.empty(p.size)
    for k, e in enumerate(p.tolist()):
        if e >= 0:
            big = 10 ** e
            h = float(big)
            hi[k] = h
            lo[k] = float(big - int(h))
        else:
            big = 10 ** (-e)
            h = 1 / big
            num, den = h.as_integer_ratio()          # h = num / den exactly
            hi[k] = h
            lo[k] = (den - num * big) / (big * den)  # 1/big - h
    return hi, lo


@numba.njit(cache=True)
def _two_prod(a, b):
    """p, e with p = fl(a*b) and p + e = a*b exactly (Dekker, no FMA needed)."""
    p = a * b
    c = 134217729.0 * a
    ah = c - (c - a)
    al = a - ah
    c = 134217729.0 * b
    bh = c - (c - b)
    bl = b - bh
    e = ((ah * bh - p) + ah * bl + al * bh) + al * bl
    return p, e


# ---------------------------------------------------------------------------------------
# numba parser

@numba.njit(cache=True, inline="always")
def _is_blank(c):
    return c == _SP or c == _TAB or c == _CR


@numba.njit(cache=True, inline="always")
def _is_number_start(c):
    # digits, sign, point, and the first letters of inf / infinity / nan
    return ((48 <= c <= 57) or c == 43 or c == 45 or c == 46
            or c == 105 or c == 73 or c == 110 or c == 78)


@numba.njit(cache=True, inline="always")
def _fast_decimal(w, q, p10hi, p10lo):
    """Correctly rounded float64 of w * 10**q (0 < w < 1e18), or ok=False when unsure.

    Exact (Clinger) when w < 2**53 and |q| <= 22.  Otherwise w * 10**q is formed in
    double-double arithmetic (relative error < 2**-102.8) and its rounding to float64 is
    accepted only when the whole interval of +- 2**-100 relative around it rounds to the
    same float64; the rare other cases (and results outside 1e-270..1e290) return
    ok=False for strtod to decide.
    """
    if w < 9007199254740992 and -22 <= q <= 22:
        if q >= 0:
            return np.float64(w) * p10hi[q - _P10_MIN], True
        return np.float64(w) / p10hi[-q - _P10_MIN], True
    if q < _P10_MIN or q > _P10_MAX:
        return 0.0, False
    wh = np.float64(w)
    wl = np.float64(w - np.int64(wh))
    H = p10hi[q - _P10_MIN]
    L = p10lo[q - _P10_MIN]
    p, e = _two_prod(wh, H)
    t = e + (wh * L + wl * H)
    r = p + t
    bb = r - p
    s = (p - (r - bb)) + (t - bb)          # r + s == p + t exactly
    if not (1e-270 < r < 1e290):
        return 0.0, False
    # the exact value lies within r + s +- bnd; accept r when both ends round to r
    bnd = r * 7.888609052210118e-31        # r * 2**-100 (exact scaling)
    if r + (s + bnd) == r and r + (s - bnd) == r:
        return r, True
    return 0.0, False


@numba.njit(cache=True)
def _scan_number(buf, i, n, end, base, p10hi, p10lo):
    """Value of the number at buf[i] and the offset just after it (== i: none).

    Decimal numbers of at most 18 significant digits are converted here; the others
    (more digits, inf, nan, unsure roundings) by strtod.
    """
    k = i
    c = buf[k]
    neg = False
    if c == 45 or c == 43:
        neg = c == 45
        k += 1
    w = np.int64(0)
    nd = 0
    dexp = 0
    many = False
    anyd = False
    c = buf[k]
    while 48 <= c <= 57:
        anyd = True
        if w > 0 or c != 48:
            if nd < 18:
                w = w * 10 + (c - 48)
                nd += 1
            else:
                many = True
                dexp += 1
        k += 1
        c = buf[k]
    if c == 46:
        k += 1
        c = buf[k]
        while 48 <= c <= 57:
            anyd = True
            if w > 0 or c != 48:
                if nd < 18:
                    w = w * 10 + (c - 48)
                    nd += 1
                    dexp -= 1
                else:
                    many = True
            else:
                dexp -= 1
            k += 1
            c = buf[k]
    if not anyd:
        # inf, nan, or no number at all
        v = _strtod(buf[i:].ctypes, end.ctypes)
        return v, end[0] - base
    if c == 101 or c == 69:
        k2 = k + 1
        eneg = False
        c2 = buf[k2]
        if c2 == 45 or c2 == 43:
            eneg = c2 == 45
            k2 += 1
            c2 = buf[k2]
        if 48 <= c2 <= 57:
            e10 = 0
            while 48 <= c2 <= 57:
                if e10 < 100000:
                    e10 = e10 * 10 + (c2 - 48)
                k2 += 1
                c2 = buf[k2]
            dexp += -e10 if eneg else e10
            k = k2
    if many:
        v = _strtod(buf[i:].ctypes, end.ctypes)
        return v, end[0] - base
    if w == 0:
        return -0.0 if neg else 0.0, k
    v, ok = _fast_decimal(w, dexp, p10hi, p10lo)
    if not ok:
        v = _strtod(buf[i:].ctypes, end.ctypes)
        return v, end[0] - base
    return -v if neg else v, k


@numba.njit(cache=True)
def _parse_line(buf, i, n, out, off, cap, end, base, p10hi, p10lo):
    """Parse the data line starting at ``buf[i]`` (a non-blank, non-comment character).

    Stores up to ``cap`` values in ``out[off:off + cap]`` and keeps counting beyond.
    Returns (status, position after the line's ``\\n``, field count, bad field index
    (1-based), byte offset of the bad field).
    """
    col = 0
    while True:
        c = buf[i]
        if c == _COMMA or c == _NL or i >= n:
            # an empty field: after a comma or at the start of the line
            return EMPTY_FIELD, i, col, col + 1, i
        if not _is_number_start(c):
            return BAD_NUMBER, i, col, col + 1, i
        v, j = _scan_number(buf, i, n, end, base, p10hi, p10lo)
        if j <= i:
            return BAD_NUMBER, i, col, col + 1, i
        d = buf[j]
        if not (d == _SP or d == _TAB or d == _CR or d == _COMMA or d == _NL or j >= n):
            return BAD_NUMBER, i, col, col + 1, i
        # refuse what strtod accepts beyond decimal numbers: hexadecimal, nan(...)
        k = i + 1 if (c == 43 or c == 45) else i
        if buf[k] == 48 and k + 1 < j and (buf[k + 1] == 120 or buf[k + 1] == 88):
            return BAD_NUMBER, i, col, col + 1, i
        if buf[j - 1] == 41:
            return BAD_NUMBER, i, col, col + 1, i
        if col < cap:
            out[off + col] = v
        col += 1
        i = j
        while _is_blank(buf[i]) and i < n:
            i += 1
        c = buf[i]
        if c == _COMMA:
            i += 1
            while _is_blank(buf[i]) and i < n:
                i += 1
            c = buf[i]
            if c == _NL or i >= n or c == _HASH or c == _PCT or c == _COMMA:
                return EMPTY_FIELD, i, col, col + 1, i
            continue
        if c == _NL or i >= n:
            return OK, i + 1, col, 0, 0
        if c == _HASH or c == _PCT:
            while i < n and buf[i] != _NL:
                i += 1
            return OK, i + 1, col, 0, 0
        # otherwise blanks were skipped and a new field starts at i


@numba.njit(cache=True, nogil=True)   # releases the GIL: reader/writer threads
def _parse_kernel(buf, ncols_min, ncols_max, skip_header_lines, p10hi, p10lo):
    """numba kernel of :func:`parse_table`; ``buf`` ends with a NUL byte."""
    n = buf.size - 1
    end = np.zeros(1, np.int64)
    base = buf.ctypes.data
    nlines = 1
    for i in range(n):
        if buf[i] == _NL:
            nlines += 1
    pos = 0
    line = 0
    # header lines, skipped whatever they hold
    while line < skip_header_lines and pos < n:
        while pos < n and buf[pos] != _NL:
            pos += 1
        pos += 1
        line += 1
    width = -1
    first_line = 0
    nrows = 0
    values = np.empty((0, 1), np.float64)
    flat = values.reshape(-1)
    row_line = np.empty(0, np.int64)
    while pos < n:
        line += 1
        i = pos
        while _is_blank(buf[i]) and i < n:
            i += 1
        c = buf[i]
        if c == _NL or i >= n:
            pos = i + 1
            continue
        if c == _HASH or c == _PCT:
            while i < n and buf[i] != _NL:
                i += 1
            pos = i + 1
            continue
        if width < 0:
            # first data line: count its fields into a scratch row
            j = i
            while j < n and buf[j] != _NL:
                j += 1
            cap = (j - i + 2) // 2 + 1
            tmp = np.empty(cap, np.float64)
            status, pos, ncol, ecol, epos = _parse_line(buf, i, n, tmp, 0, cap, end, base,
                                                        p10hi, p10lo)
            if status != OK:
                return values[:0], row_line[:0], status, line, ecol, epos, ncol, line
            if ncol < ncols_min:
                return values[:0], row_line[:0], TOO_FEW_COLUMNS, line, ncol, i, ncol, line
            if ncol > ncols_max:
                return values[:0], row_line[:0], TOO_MANY_COLUMNS, line, ncol, i, ncol, line
            width = ncol
            first_line = line
            maxrows = nlines - line + 1
            values = np.empty((maxrows, width), np.float64)
            row_line = np.empty(maxrows, np.int64)
            flat = values.reshape(-1)
            for k in range(width):
                values[0, k] = tmp[k]
            row_line[0] = line
            nrows = 1
            continue
        status, pos, ncol, ecol, epos = _parse_line(buf, i, n, flat, nrows * width, width,
                                                    end, base, p10hi, p10lo)
        if status != OK:
            return values[:0], row_line[:0], status, line, ecol, epos, width, first_line
        if ncol != width:
            return values[:0], row_line[:0], COLUMN_COUNT, line, ncol, i, width, first_line
        row_line[nrows] = line
        nrows += 1
    if width < 0:
        return values[:0], row_line[:0], NO_DATA, 0, 0, 0, 0, 0
    return values[:nrows], row_line[:nrows], OK, 0, 0, 0, width, first_line


# ---------------------------------------------------------------------------------------
# pure-Python fallback (same outputs)

_NUMBER_RE = re.compile(rb"[+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
                        rb"|[iI][nN][fF](?:[iI][nN][iI][tT][yY])?|[nN][aA][nN])")
_FIELD_RE = re.compile(rb"[^ \t\r,\n]*")
_BLANKS_RE = re.compile(rb"[ \t\r]*")


def is_number(text):
    """True when ``text`` (str or bytes) is one field that :func:`parse_table` accepts."""
    if isinstance(text, str):
        text = text.encode("utf-8", errors="replace")
    return _NUMBER_RE.fullmatch(text) is not None


def _parse_py(buf, ncols_min, ncols_max, skip_header_lines):
    """Pure-Python twin of :func:`_parse_kernel` (used where strtod is unavailable).

    A tokenizer with the kernel's rules and ``float()`` (correctly rounded, like the
    kernel) for the conversion; ``np.loadtxt`` cannot mix blank and comma separators
    nor locate a bad field, hence not used.
    """
    data = bytes(buf[:-1]) if buf.size else b""
    n = len(data)
    starts = [0] + [m.end() for m in re.finditer(rb"\n", data)]
    rows, lines = [], []
    width, first_line = -1, 0

    def fail(status, line, col, pos, ncol):
        return (np.empty((0, max(width, 1) if width > 0 else 1)), np.empty(0, np.int64),
                status, line, col, pos, ncol, line if width < 0 else first_line)

    for idx, start in enumerate(starts):
        line = idx + 1
        if start >= n and idx > 0:
            break
        if line <= skip_header_lines:
            continue
        stop = data.find(b"\n", start)
        stop = n if stop < 0 else stop
        i = _BLANKS_RE.match(data, start, stop).end()
        if i >= stop or data[i] in b"#%":
            continue
        fields = []
        status = OK
        ecol = epos = 0
        while True:
            if i >= stop or data[i] == _COMMA:
                status, ecol, epos = EMPTY_FIELD, len(fields) + 1, i
                break
            j = _FIELD_RE.match(data, i, stop).end()
            tok = data[i:j]
            if not _NUMBER_RE.fullmatch(tok):
                status, ecol, epos = BAD_NUMBER, len(fields) + 1, i
                break
            fields.append(float(tok))
            i = _BLANKS_RE.match(data, j, stop).end()
            if i < stop and data[i] == _COMMA:
                i = _BLANKS_RE.match(data, i + 1, stop).end()
                if i >= stop or data[i] in b"#%,":
                    status, ecol, epos = EMPTY_FIELD, len(fields) + 1, i
                    break
                continue
            if i >= stop or data[i] in b"#%":
                break
        if status != OK:
            return fail(status, line, ecol, epos, len(fields) if width < 0 else width)
        if width < 0:
            first = _start_of(data, start)
            if len(fields) < ncols_min:
                return fail(TOO_FEW_COLUMNS, line, len(fields), first, len(fields))
            if len(fields) > ncols_max:
                return fail(TOO_MANY_COLUMNS, line, len(fields), first, len(fields))
            width, first_line = len(fields), line
        elif len(fields) != width:
            return fail(COLUMN_COUNT, line, len(fields), _start_of(data, start), width)
        rows.append(fields)
        lines.append(line)
    if width < 0:
        return np.empty((0, 1)), np.empty(0, np.int64), NO_DATA, 0, 0, 0, 0, 0
    return (np.array(rows, dtype=np.float64).reshape(len(rows), width),
            np.array(lines, dtype=np.int64), OK, 0, 0, 0, width, first_line)


def _start_of(data, start):
    """Offset of the first non-blank byte of the line starting at ``start``."""
    return _BLANKS_RE.match(data, start).end()


# ---------------------------------------------------------------------------------------
# public reading API

class ParsedTable(NamedTuple):
    """Result of :func:`parse_table`.

    Attributes
    ----------
    values : ndarray, shape (nrows, width), float64
        The data rows (empty when ``status != OK``).
    status : int
        ``OK`` (0) or one of the error codes of this module.
    err_line : int
        1-based line of the error (0 when none).
    err_col : int
        For ``BAD_NUMBER`` / ``EMPTY_FIELD``: the 1-based field index; for the column
        count errors: the number of fields found on that line.
    row_line : ndarray, shape (nrows,), int64
        1-based line number of each row.
    err_pos : int
        Byte offset of the bad field (or of the line's first field).
    width : int
        Number of columns (fields of the first data line; -1/0 when unknown).
    first_line : int
        Line of the first data line (the one that fixed the width).
    """

    values: np.ndarray
    status: int
    err_line: int
    err_col: int
    row_line: np.ndarray
    err_pos: int
    width: int
    first_line: int


def _readonly(a):
    """A read-only view of ``a``: the kernels then see one array type (one compilation)."""
    v = a.view()
    v.flags.writeable = False
    return v


def _use_numba():
    return _HAVE_STRTOD and locale.localeconv().get("decimal_point", ".") == "."


def parse_table(buf, ncols_min=1, ncols_max=1 << 30, skip_header_lines=0, engine=None):
    """Parse numeric text into a float64 table.

    Parameters
    ----------
    buf : ndarray of uint8, shape (nbytes + 1,)
        The text followed by one NUL byte (see :func:`file_buffer`).  Not modified.
    ncols_min, ncols_max : int
        Accepted width of the table (fields of the first data line).
    skip_header_lines : int
        Number of physical lines skipped before parsing, whatever they hold.
    engine : {None, "numba", "python"}
        Force a parser (for tests); ``None`` picks numba when ``strtod`` is available.

    Returns
    -------
    ParsedTable
        ``(values, status, err_line, err_col, row_line, err_pos, width, first_line)``.
    """
    buf = _readonly(np.ascontiguousarray(buf, dtype=np.uint8))
    if buf.size == 0 or buf[-1] != 0:
        raise ValueError("buf must end with a NUL byte (use file_buffer or append 0)")
    if engine is None:
        engine = "numba" if _use_numba() else "python"
    if engine == "numba":
        hi, lo = _pow10_table()
        res = _parse_kernel(buf, int(ncols_min), int(ncols_max), int(skip_header_lines), hi, lo)
    elif engine == "python":
        res = _parse_py(buf, int(ncols_min), int(ncols_max), int(skip_header_lines))
    else:
        raise ValueError(f"engine must be None, 'numba' or 'python', got {engine!r}")
    values, row_line, status, eline, ecol, epos, width, first = res
    values = values.reshape(-1, max(int(width), 1)) if status == OK else values[:0]
    if values.base is not None and values.size and values.base.size > 1.25 * values.size:
        values = values.copy()
        row_line = row_line.copy()
    return ParsedTable(values, int(status), int(eline), int(ecol), row_line, int(epos),
                       int(width), int(first))


def file_buffer(path):
    """Bytes of the file at ``path`` as a uint8 array with a NUL byte appended.

    A UTF-8 byte-order mark at the start is blanked (in the returned copy only).
    The file is opened read-only and never modified.
    """
    with open(path, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        buf = np.empty(size + 1, np.uint8)
        view = memoryview(buf)
        got = 0
        while got < size:
            k = f.readinto(view[got:size])
            if not k:
                break
            got += k
        extra = f.read()          # the file grew while being read
    if extra:
        buf = np.concatenate([buf[:got], np.frombuffer(extra, np.uint8), [0]]).astype(np.uint8)
    else:
        buf = buf[:got + 1]
        buf[got] = 0
    if buf.size >= 4 and buf[0] == 0xEF and buf[1] == 0xBB and buf[2] == 0xBF:
        buf[:3] = _SP
    return buf


def read_text(path, expected="text"):
    """The whole text of a (small) text file, decoded as UTF-8 (a BOM is dropped).

    For the line-oriented readers of CSV and TOML files, which would otherwise stop
    with a ``UnicodeDecodeError`` on a binary file.  Line ends are left as they are.

    Parameters
    ----------
    expected : str
        What the file should hold, for the message (e.g. ``"a TOML camera file"``).

    Raises
    ------
    InputError
        When the bytes are not UTF-8 or hold a NUL byte (binary data), naming the file
        and the line of the first bad byte.
    """
    path_s = os.fspath(path)
    with open(path_s, "rb") as f:
        data = f.read()
    try:
        text = data.decode("utf-8-sig")
        bad = text.find("\x00")
        if bad >= 0:
            raise UnicodeDecodeError("utf-8", data, bad, bad + 1, "NUL byte")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError(f"binary data, not UTF-8 text (byte 0x{data[exc.start]:02x} at "
                         f"offset {exc.start}); expected {expected}", path=path_s,
                         line=line) from None
    return text


def check_rows(rows, row_line, path, time_col=0, name_duplicates=True):
    """Every value finite and the time column strictly increasing, else an
    :class:`InputError` naming the file and line (a duplicated epoch named as such
    unless ``name_duplicates`` is false)."""
    path = os.fspath(path)
    bad = np.flatnonzero(~np.all(np.isfinite(rows), axis=1))
    if bad.size:
        raise InputError("non-finite value", path=path, line=int(row_line[bad[0]]))
    t = rows[:, time_col]
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        k = back[0] + 1
        what = ("duplicated epoch" if name_duplicates and t[k] == t[k - 1]
                else "time not increasing")
        raise InputError(f"{what}: t = {float(t[k])!r} s after {float(t[k - 1])!r} s",
                         path=path, line=int(row_line[k]))


def read_toml(path, expected="a TOML file"):
    """A TOML file as a dict; :class:`InputError` naming the file for binary data or
    invalid TOML (the TOML parser's message gives the line and column)."""
    import tomllib
    text = read_text(path, expected)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}; expected {expected}",
                         path=os.fspath(path)) from None


def _field_bytes(buf, pos, limit=40):
    stop = pos
    n = buf.size - 1
    while stop < n and stop - pos < limit and buf[stop] not in (_SP, _TAB, _CR, _NL, _COMMA):
        stop += 1
    return bytes(buf[pos:stop]), stop - pos >= limit


def _binary_byte(raw):
    """The first byte of ``raw`` that no text file holds (a control character or a
    byte that is not UTF-8), or None."""
    for b in raw:
        if b < 0x20 and b not in (0x09, 0x0D) or b == 0x7F:
            return b
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.reason != "unexpected end of data":        # cut inside a character
            return raw[exc.start]
    return None


def _field_text(buf, pos, limit=40):
    raw, cut = _field_bytes(buf, pos, limit)
    return raw.decode("utf-8", errors="replace") + ("..." if cut else "")


def table_error_message(res, buf, ncols_min, ncols_max, column_names=None):
    """One-line description of a failed :func:`parse_table` (without file and line).

    ``column_names`` (a sequence) names fields in the message where given.
    """
    def name(k):   # k: 1-based field index
        if column_names is not None and 1 <= k <= len(column_names):
            return f"field {k} ({column_names[k - 1]})"
        return f"field {k}"

    def expected():
        if ncols_min == ncols_max:
            return f"{ncols_min}"
        if ncols_max >= 1 << 29:
            return f"at least {ncols_min}"
        return f"{ncols_min} to {ncols_max}"

    s = res.status
    if s == NO_DATA:
        return "no data lines (the file is empty or holds only blank and comment lines)"
    if s in (TOO_FEW_COLUMNS, TOO_MANY_COLUMNS):
        return f"{res.err_col} columns, expected {expected()}"
    if s == COLUMN_COUNT:
        return (f"{res.err_col} columns, expected {res.width} "
                f"as on the first data line (line {res.first_line})")
    if s == BAD_NUMBER:
        bad = _binary_byte(_field_bytes(buf, res.err_pos)[0])
        if bad is not None:
            return (f"binary data, not a text table ({name(res.err_col)} holds byte "
                    f"0x{bad:02x})")
        text = _field_text(buf, res.err_pos)
        if text == "":
            return f"{name(res.err_col)} is not a number (unexpected byte)"
        return f"{name(res.err_col)} is not a number: {text!r}"
    if s == EMPTY_FIELD:
        return f"{name(res.err_col)} is empty (two commas in a row or a trailing comma)"
    return f"parse error {s}"   # pragma: no cover


def _last_newline(buf, total):
    """Index of the last newline byte in ``buf[:total]`` (-1 when none)."""
    stop = total
    while stop > 0:
        start = max(0, stop - 65536)
        hit = np.flatnonzero(buf[start:stop] == _NL)
        if hit.size:
            return start + int(hit[-1])
        stop = start
    return -1


def _count_lines(path, block_bytes):
    """Number of lines in the file (newlines + 1): an upper bound of its data rows."""
    buf = np.empty(max(int(block_bytes), 16), np.uint8)
    count = 1
    with open(path, "rb") as f:
        while True:
            got = f.readinto(memoryview(buf))
            if not got:
                return count
            count += int(np.count_nonzero(buf[:got] == _NL))


#: Bytes read and parsed at a time by :func:`read_table` (bounds its memory).
BLOCK_BYTES = 1 << 24


def read_table(path, ncols_min=1, ncols_max=1 << 30, skip_header_lines=0, column_names=None,
               hint=None, block_bytes=BLOCK_BYTES):
    """Read a numeric text table from a file, in blocks of whole lines.

    Memory: the table plus one block of text (``block_bytes``, 16 MiB by default), not
    the whole file's text.  A first pass counts the lines to size the table.

    Parameters
    ----------
    hint : str, optional
        Appended in parentheses to column-count errors (e.g. the expected layout).

    Returns
    -------
    values : ndarray, shape (nrows, width), float64
    row_line : ndarray, shape (nrows,), int64
        1-based line number of each row in the file.

    Raises
    ------
    InputError
        On any of the :func:`parse_table` errors, naming the file and line.
    """
    max_rows = _count_lines(path, block_bytes)
    table = row_lines = None
    nrows = 0
    for values, lines in iter_table(path, ncols_min, ncols_max, column_names, hint,
                                    block_bytes, skip_header_lines):
        if table is None:
            table = np.empty((max_rows, values.shape[1]))
            row_lines = np.empty(max_rows, np.int64)
        m = len(values)
        if nrows + m > max_rows:                     # the file grew meanwhile
            raise InputError("the file changed while being read", path=os.fspath(path))
        table[nrows:nrows + m] = values
        row_lines[nrows:nrows + m] = lines
        nrows += m
    if table is None:
        raise InputError("no data lines (the file is empty or holds only blank and comment "
                         "lines)", path=os.fspath(path))
    if nrows < 0.8 * max_rows:
        return table[:nrows].copy(), row_lines[:nrows].copy()
    return table[:nrows], row_lines[:nrows]


def iter_table(path, ncols_min=1, ncols_max=1 << 30, column_names=None, hint=None,
               block_bytes=BLOCK_BYTES, skip_header_lines=0):
    """Read a numeric text table block by block (bounded memory: one block of text).

    Same rules and errors as :func:`read_table`, but the
    rows are yielded as they are parsed, so a file of any length is read with the memory
    of one block.  The parsing kernel releases the GIL (a reader thread can run beside
    numerical work).

    Yields
    ------
    values : ndarray, shape (nrows, width), float64
        The rows of one block of whole lines (at least one row).
    row_line : ndarray, shape (nrows,), int64
        1-based line number of each row in the file.
    """
    lo, hi = int(ncols_min), int(ncols_max)
    line_offset = first_line = 0
    skip = int(skip_header_lines)
    buf = np.empty(max(int(block_bytes), 16) + 1, np.uint8)
    have = 0
    first_block = True
    seen = False
    with open(path, "rb") as f:
        while True:
            if have == buf.size - 1:                         # a line longer than buf
                grown = np.empty(2 * buf.size, np.uint8)
                grown[:have] = buf[:have]
                buf = grown
            got = f.readinto(memoryview(buf)[have:buf.size - 1])
            total = have + got
            if total == 0:
                break
            cut = _last_newline(buf, total) + 1 if got else total
            if got and cut == 0:
                have = total
                continue
            if first_block and cut >= 3 and buf[0] == 0xEF and buf[1] == 0xBB and buf[2] == 0xBF:
                buf[:3] = _SP
            first_block = False
            saved = buf[cut]
            buf[cut] = 0
            block = buf[:cut + 1]
            res = parse_table(block, lo, hi, skip)
            nl = int(np.count_nonzero(block[:cut] == _NL))
            skip = max(0, skip - nl)
            if res.status == OK:
                if not seen:
                    first_line = res.first_line + line_offset
                seen = True
                lo = hi = res.width           # later blocks must keep the first width
                yield res.values, res.row_line + line_offset
            elif res.status != NO_DATA:
                msg = table_error_message(res, block, lo, hi, column_names)
                if res.status in (TOO_FEW_COLUMNS, TOO_MANY_COLUMNS) and seen:
                    msg = (f"{res.err_col} columns, expected {lo} as on the first data "
                           f"line (line {first_line})")
                if hint and (res.status in (TOO_FEW_COLUMNS, TOO_MANY_COLUMNS, COLUMN_COUNT)
                             or msg.startswith("binary data")):
                    msg += f" ({hint})"
                raise InputError(msg, path=os.fspath(path),
                                 line=(res.err_line + line_offset) if res.err_line else None)
            buf[cut] = saved
            line_offset += nl
            have = total - cut
            if have:
                buf[:have] = buf[cut:total].copy()
            if not got:
                break
    if not seen:
        raise InputError("no data lines (the file is empty or holds only blank and comment "
                         "lines)", path=os.fspath(path))

# ---------------------------------------------------------------------------------------
# formatting

@numba.njit(cache=True)
def _round_big(p, e):
    """Nearest integer (ties to even) to p + e, p an integer-valued double, |e| small."""
    fe = np.floor(e)
    g = e - fe
    r = np.int64(p) + np.int64(fe)
    if g > 0.5 or (g == 0.5 and (r & 1) == 1):
        r += 1
    return r


@numba.njit(cache=True)
def _round_scaled(a, scale):
    """Nearest integer (ties to even) to the exact product a * scale, a >= 0.

    ``scale`` must be an exact power of ten (<= 1e22).  Returns -1 when the product is
    not finite or >= 9e18.
    """
    p = a * scale
    if not (p < _MAX_FIXED):
        return np.int64(-1)
    if p < 0.5:
        return np.int64(0)
    p, e = _two_prod(a, scale)
    if p >= _TWO52:
        return _round_big(p, e)
    fp = np.floor(p)
    d1 = (p - fp) - 0.5          # exact for p >= 0.5
    r = np.int64(fp)
    if d1 > -e or (d1 == -e and (r & 1) == 1):
        r += 1
    return r


@numba.njit(cache=True)
def _sci_digits(a, bits, p10hi, p10lo):
    """(N, E) with N the 18-digit integer nearest to a * 10**(17 - E), 1e17 <= N < 1e18.

    ``bits`` is the IEEE bit pattern of ``a`` (for a first guess of E without log10).
    """
    ex = ((bits >> 52) & 0x7FF) - 1023
    E = (ex * 78913) >> 18          # floor(ex * log10(2)), E is then off by at most one
    N = np.int64(0)
    for _ in range(6):
        k = 17 - E - _P10_MIN
        p, e = _two_prod(a, p10hi[k])
        e += a * p10lo[k]
        if p >= 2e18:               # guards for the int64 conversion only
            E += 1
            continue
        if p < 5e16:
            E -= 1
            continue
        N = _round_big(p, e)
        if N >= 1000000000000000000:
            E += 1
            continue
        if N < 100000000000000000:
            E -= 1
            continue
        break
    return N, E


_PAIRS = np.frombuffer("".join(f"{k:02d}" for k in range(100)).encode(), np.uint8).copy()
_POW10_INT = np.array([10 ** k for k in range(19)], dtype=np.int64)


@numba.njit(cache=True)
def _put_digits(out, end, x, count, pairs):
    """Write the ``count`` low decimal digits of ``x`` (>= 0) to out[end - count:end]."""
    u = np.uint64(x)            # unsigned: division by a constant without sign fix-ups
    c100 = np.uint64(100)
    while count >= 2:
        q = u // c100
        r = np.intp(u - q * c100) * 2
        out[end - 2] = pairs[r]
        out[end - 1] = pairs[r + 1]
        end -= 2
        count -= 2
        u = q
    if count == 1:
        out[end - 1] = 48 + np.intp(u % np.uint64(10))


@numba.njit(cache=True, nogil=True)   # releases the GIL: reader/writer threads
def _format_kernel(values, bits, decimals, sep, p10hi, p10lo, pairs, pow10_int):
    """Text of ``values``: returns (uint8 text, status, bad row, bad column).

    status 0: ok; 1: non-finite value; 2: |value * 10**d| >= 9e18; 3: a value outside
    the scientific kernel's range (the caller falls back to Python).
    """
    n, m = values.shape
    out = np.empty(n * m * 27 + 1, np.uint8)
    pos = 0
    pow10 = np.empty(m, np.float64)
    for j in range(m):
        pow10[j] = p10hi[decimals[j] - _P10_MIN] if decimals[j] >= 0 else 1.0
    for r in range(n):
        for j in range(m):
            v = values[r, j]
            if not np.isfinite(v):
                return out[:0], 1, r, j
            b = bits[r, j]
            a = abs(v)
            d = decimals[j]
            if b < 0:                   # sign bit: also for -0.0, as '%f' does
                out[pos] = 45
                pos += 1
            if d >= 0:
                N = _round_scaled(a, pow10[j])
                if N < 0:
                    return out[:0], 2, r, j
                # integer part: trunc(a), plus one when the rounding carried into it
                # (cheaper than an integer division by 10**d)
                ip = np.int64(a)
                frac = N - ip * pow10_int[d]
                if frac >= pow10_int[d]:
                    ip += 1
                    frac -= pow10_int[d]
                nint = 1
                while nint < 19 and ip >= pow10_int[nint]:
                    nint += 1
                _put_digits(out, pos + nint, ip, nint, pairs)
                pos += nint
                if d > 0:
                    out[pos] = 46
                    _put_digits(out, pos + 1 + d, frac, d, pairs)
                    pos += 1 + d
            else:
                if a == 0.0:
                    N = np.int64(0)
                    E = np.int64(0)
                else:
                    if a < _SCI_LO or a > _SCI_HI:
                        return out[:0], 3, r, j
                    N, E = _sci_digits(a, b, p10hi, p10lo)
                lead = N // 100000000000000000
                out[pos] = 48 + lead
                out[pos + 1] = 46
                _put_digits(out, pos + 19, N - lead * 100000000000000000, 17, pairs)
                pos += 19
                out[pos] = 101
                out[pos + 1] = 45 if E < 0 else 43
                pos += 2
                E = abs(E)
                if E >= 100:
                    out[pos] = 48 + E // 100
                    pos += 1
                    E = E % 100
                out[pos] = 48 + E // 10
                out[pos + 1] = 48 + E % 10
                pos += 2
            out[pos] = sep if j < m - 1 else _NL
            pos += 1
    return out[:pos], 0, 0, 0


def _format_py(values, decimals, sep):
    """Python twin of :func:`_format_kernel` (for values outside its range)."""
    fmts = ["%.17e" if d < 0 else f"%.{d}f" for d in decimals]
    s = chr(sep)
    text = "".join(s.join(f % v for f, v in zip(fmts, row)) + "\n" for row in values.tolist())
    return np.frombuffer(text.encode("ascii"), np.uint8).copy()


def _check_table(values, decimals):
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 1:
        values = values[:, None]
    if values.ndim != 2:
        raise ValueError(f"values must have shape (n, m), got {values.shape}")
    decimals = np.asarray(decimals, dtype=np.int64).reshape(-1)
    if decimals.size == 1 and values.shape[1] != 1:
        decimals = np.full(values.shape[1], decimals[0], np.int64)
    if decimals.shape != (values.shape[1],):
        raise ValueError(f"decimals must have shape ({values.shape[1]},) for values of "
                         f"shape {values.shape}, got {decimals.shape}")
    if np.any(decimals > 22) or np.any(decimals < -1):
        raise ValueError(f"decimals must be in 0..22 (or -1 for %.17e), got {decimals}")
    return np.ascontiguousarray(values), np.ascontiguousarray(decimals)


def format_table(values, decimals, sep=" "):
    """Format a table as text, each column fixed-point or ``%.17e``.

    Parameters
    ----------
    values : array_like, shape (n, m)
        Finite numbers.
    decimals : array_like of int, shape (m,) (or a scalar for every column)
        Decimals per column, 0..22 for fixed point (``'%.{d}f'``; 0: an integer
        without a point), -1 for ``'%.17e'`` (18 significant digits: reads back to the
        same float64).
    sep : str
        One-character field separator (``" "`` or ``","``).

    Returns
    -------
    ndarray of uint8
        The text, rows ended by ``\\n``; ``.tobytes()`` gives ``bytes``.

    Raises
    ------
    ValueError
        For a non-finite value, or ``|value| * 10**d >= 9e18`` in a fixed column,
        naming the row and column (0-based).
    """
    values, decimals = _check_table(values, decimals)
    if len(sep) != 1 or sep not in " ,;\t":
        raise ValueError(f"sep must be one of ' ', ',', ';', tab; got {sep!r}")
    sepb = ord(sep)
    if values.size == 0:
        return np.empty(0, np.uint8)
    hi, lo = _pow10_table()
    out, status, r, c = _format_kernel(_readonly(values), _readonly(values.view(np.int64)),
                                       _readonly(decimals), sepb, hi, lo, _PAIRS, _POW10_INT)
    if status == 1:
        raise ValueError(f"cannot format non-finite value {values[r, c]} "
                         f"(row {r}, column {c})")
    if status == 2:
        raise ValueError(f"value {values[r, c]!r} (row {r}, column {c}) is too large for "
                         f"{decimals[c]} decimals (|value * 10**d| >= 9e18)")
    if status == 3:
        return _format_py(values, decimals, sepb)
    return out


def format_fixed(values, decimals, sep=" "):
    """Format a table in fixed-point notation, as ``'%.{d}f'`` per column.

    Parameters
    ----------
    values : array_like, shape (n, m)
        Finite numbers with ``|value * 10**d| < 9e18``.
    decimals : array_like of int, shape (m,)
        Decimals per column, 0..22 (0: an integer, no point).
    sep : str
        Field separator (one character), a space by default.

    Returns
    -------
    ndarray of uint8
        The text: fields separated by ``sep``, rows ended by ``\\n``, negative numbers
        (and negative zero) with ``-``.  Digit for digit what ``'%.{d}f' % x`` gives
        (exact rounding of the binary value, ties to even).

    Raises
    ------
    ValueError
        Non-finite value or too large for its decimals (names row and column).
    """
    values, decimals = _check_table(values, decimals)
    if np.any(decimals < 0):
        raise ValueError(f"decimals must be in 0..22, got {decimals}")
    return format_table(values, decimals, sep)


@numba.njit(cache=True)
def _roundtrip_kernel(x, min_decimals, max_decimals, p10hi):
    for d in range(min_decimals, max_decimals + 1):
        scale = p10hi[d - _P10_MIN]
        ok = True
        for v in x:
            a = abs(v)
            N = _round_scaled(a, scale)
            if N < 0 or N >= 9007199254740992 or np.float64(N) / scale != a:
                ok = False
                break
        if ok:
            return d
    return -1


def roundtrip_decimals(x, max_decimals=9, min_decimals=0):
    """Fewest decimals ``d`` in ``min_decimals..max_decimals`` with which every value of
    ``x`` reads back exactly from ``'%.{d}f'`` text, or -1 when there is none.

    The test is exact: with ``N`` the rounded ``|x| * 10**d`` (below 2**53) the text
    reads back as the correctly rounded ``N / 10**d``, a single IEEE division.
    """
    x = np.ascontiguousarray(x, dtype=np.float64).reshape(-1)
    if x.size == 0:
        return int(min_decimals)
    if not np.all(np.isfinite(x)):
        return -1
    hi, _ = _pow10_table()
    return int(_roundtrip_kernel(_readonly(x), int(min_decimals), min(int(max_decimals), 22),
                                 hi))
