"""Exact parsing of numeric text tables into float64 (numba kernels inside).

:func:`parse_table` turns the bytes of a text file into a float64 table.  Lines end with
``\\n`` (``\\r\\n`` works: ``\\r`` counts as blank space); fields are separated by blanks
(spaces, tabs) and/or one comma; blank lines and lines whose first non-blank character
is ``#`` or ``%`` are skipped, and a ``#`` or ``%`` after a blank ends a data line
(trailing comment).  The first data line fixes the table's width; every later data line
must have the same number of fields.  A field must be a whole decimal number
(``[+-]digits[.digits][e[+-]digits]``, also ``.5`` and ``5.``) or ``inf``,
``infinity``, ``nan`` (any case): ``1.2.3``, ``abc``, ``1e``, hexadecimal floats and
empty fields (``1,,2``) are errors.  NaN and inf are returned as numbers; the caller
decides about them, naming the line through the row-to-line map
(:func:`ins.common.textrows.check_rows`).  :func:`table_error_message` describes a failed parse.

Numbers are converted exactly (bit-identical to ``float()``, ``np.loadtxt`` and glibc's
correctly rounded ``strtod``) inside a numba kernel: decimals of at most 18 significant
digits by Clinger's exact fast path or a double-double product with a certified
rounding; everything else (more digits, inf, nan, and the rare roundings the
double-double product cannot decide, such as exact ties) by the C library's ``strtod``
called from the kernel.  About 0.10 s for the 302 k-line, 7-column, 48 MB benchmark log
(glibc ``strtod`` alone: 0.23 s; ``np.loadtxt``: 0.65 s; the comparison with pandas and
pyarrow is in ``bench/bench_textio.py``).  Where ``strtod`` cannot be linked, or the
process's numeric locale does not use ``.`` as the decimal point, a pure-Python fallback
with the same outputs (about 20x slower) is used.  Files: :mod:`ins.common.textfiles`.
"""
import locale
import re
from typing import NamedTuple

import numba
import numpy as np
from numba import types

from ins.common.exactdecimal import P10_MAX, P10_MIN, pow10_table, readonly, two_prod

__all__ = [
    "ParsedTable", "parse_table", "table_error_message", "is_number",
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
            return np.float64(w) * p10hi[q - P10_MIN], True
        return np.float64(w) / p10hi[-q - P10_MIN], True
    if q < P10_MIN or q > P10_MAX:
        return 0.0, False
    wh = np.float64(w)
    wl = np.float64(w - np.int64(wh))
    H = p10hi[q - P10_MIN]
    L = p10lo[q - P10_MIN]
    p, e = two_prod(wh, H)
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
    buf = readonly(np.ascontiguousarray(buf, dtype=np.uint8))
    if buf.size == 0 or buf[-1] != 0:
        raise ValueError("buf must end with a NUL byte (use file_buffer or append 0)")
    if engine is None:
        engine = "numba" if _use_numba() else "python"
    if engine == "numba":
        hi, lo = pow10_table()
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
