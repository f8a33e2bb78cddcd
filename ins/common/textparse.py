"""Exact parsing of numeric text tables into float64 (compiled kernel inside).

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
correctly rounded ``strtod``) inside a compiled kernel (Cython,
``ins/common/_textparse_kernels.pyx``, without the GIL): decimals of at most 18
significant digits by Clinger's exact fast path or a double-double product with a
certified rounding; everything else (more digits, inf, nan, and the rare roundings the
double-double product cannot decide, such as exact ties) by the C library's ``strtod``
called from the kernel.  About 0.09 s for the 302 k-line, 7-column, 48 MB benchmark log
(the numba kernel it replaced: 0.10 s; glibc ``strtod`` alone: 0.23 s; ``np.loadtxt``: 0.65 s; the comparison with pandas and
pyarrow is in ``bench/bench_textio.py``).  Where the process's numeric locale does not
use ``.`` as the decimal point (``strtod`` follows it), a pure-Python fallback with the
same outputs (about 20x slower) is used.  Files: :mod:`ins.common.textfiles`.
"""
import locale
import re
from typing import NamedTuple

import numpy as np

# _fast_decimal: the kernel's exact conversion, callable from Python (tests/test_textio.py)
from ins.common._textparse_kernels import _fast_decimal, _parse_kernel  # noqa: F401
from ins.common.exactdecimal import pow10_table, readonly

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
    """Pure-Python twin of :func:`_parse_kernel` (used where the numeric locale's decimal
    point is not ``.``).

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


def _use_compiled():
    """True when the compiled kernel applies: ``strtod`` reads ``.`` as the decimal point."""
    return locale.localeconv().get("decimal_point", ".") == "."


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
    engine : {None, "compiled", "python"}
        Force a parser (for tests); ``None`` picks the compiled kernel unless the numeric
        locale's decimal point is not ``.``.  ``"numba"`` (the kernel's former
        implementation) is accepted as another name of ``"compiled"``.

    Returns
    -------
    ParsedTable
        ``(values, status, err_line, err_col, row_line, err_pos, width, first_line)``.
    """
    buf = readonly(np.ascontiguousarray(buf, dtype=np.uint8))
    if buf.size == 0 or buf[-1] != 0:
        raise ValueError("buf must end with a NUL byte (use file_buffer or append 0)")
    if engine is None:
        engine = "compiled" if _use_compiled() else "python"
    if engine in ("compiled", "numba"):
        hi, lo = pow10_table()
        res = _parse_kernel(buf, int(ncols_min), int(ncols_max), int(skip_header_lines), hi, lo)
    elif engine == "python":
        res = _parse_py(buf, int(ncols_min), int(ncols_max), int(skip_header_lines))
    else:
        raise ValueError(f"engine must be None, 'compiled' or 'python', got {engine!r}")
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
