"""Compiled kernels of :mod:`ins.common.textparse` (Cython; private).

:func:`_parse_kernel` parses a NUL-terminated text buffer into a float64 table with the
rules of :func:`ins.common.textparse.parse_table`, which calls it.  Numbers of at most 18
significant digits are converted here (Clinger's exact fast path, or a double-double
product with a certified rounding: :func:`_fast_decimal`); the others (more digits, inf,
nan, and the roundings the double-double product cannot decide) by the C library's
``strtod`` (glibc's is correctly rounded).  The whole parse runs without the GIL except
for the allocation of the output arrays (the IMU reader thread of ``ins process`` runs
beside the filter).
"""
import numpy as np

from libc.stdint cimport int64_t
from libc.stdlib cimport free, malloc, strtod

from ins.common._exactdecimal cimport P10_MAX, P10_MIN, two_prod

# status codes: the same values as ins.common.textparse's OK ... EMPTY_FIELD
cdef enum:
    OK = 0
    TOO_FEW_COLUMNS = 2
    TOO_MANY_COLUMNS = 3
    COLUMN_COUNT = 4
    BAD_NUMBER = 5
    EMPTY_FIELD = 6
    NO_DATA = 1

cdef enum:
    _NL = 10
    _CR = 13
    _SP = 32
    _TAB = 9
    _COMMA = 44
    _HASH = 35
    _PCT = 37


cdef inline bint _is_blank(unsigned char c) noexcept nogil:
    return c == _SP or c == _TAB or c == _CR


cdef inline bint _is_number_start(unsigned char c) noexcept nogil:
    # digits, sign, point, and the first letters of inf / infinity / nan
    return ((48 <= c <= 57) or c == 43 or c == 45 or c == 46
            or c == 105 or c == 73 or c == 110 or c == 78)


cdef inline bint _fast_decimal_c(int64_t w, int64_t q, const double *p10hi, const double *p10lo,
                                 double *out) noexcept nogil:
    """Correctly rounded float64 of w * 10**q into ``out[0]`` (0 < w < 1e18), or False.

    See :func:`_fast_decimal`.
    """
    cdef double wh, wl, H, L, p, e, t, r, bb, s, bnd
    if w < 9007199254740992LL and -22 <= q <= 22:
        if q >= 0:
            out[0] = <double>w * p10hi[q - P10_MIN]
        else:
            out[0] = <double>w / p10hi[-q - P10_MIN]
        return True
    if q < P10_MIN or q > P10_MAX:
        return False
    wh = <double>w
    wl = <double>(w - <int64_t>wh)
    H = p10hi[q - P10_MIN]
    L = p10lo[q - P10_MIN]
    two_prod(wh, H, &p, &e)
    t = e + (wh * L + wl * H)
    r = p + t
    bb = r - p
    s = (p - (r - bb)) + (t - bb)          # r + s == p + t exactly
    if not (1e-270 < r < 1e290):
        return False
    # the exact value lies within r + s +- bnd; accept r when both ends round to r
    bnd = r * 7.888609052210118e-31        # r * 2**-100 (exact scaling)
    if r + (s + bnd) == r and r + (s - bnd) == r:
        out[0] = r
        return True
    return False


def _fast_decimal(w, q, const double[::1] p10hi, const double[::1] p10lo):
    """Correctly rounded float64 of w * 10**q (0 < w < 1e18), or ok=False when unsure.

    Exact (Clinger) when w < 2**53 and |q| <= 22.  Otherwise w * 10**q is formed in
    double-double arithmetic (relative error < 2**-102.8) and its rounding to float64 is
    accepted only when the whole interval of +- 2**-100 relative around it rounds to the
    same float64; the rare other cases (and results outside 1e-270..1e290) return
    ok=False for strtod to decide.

    Parameters
    ----------
    w : int
        Decimal significand, 0 < w < 1e18.
    q : int
        Decimal exponent.
    p10hi, p10lo : ndarray of float64
        The powers of ten of :func:`ins.common.exactdecimal.pow10_table`.

    Returns
    -------
    v : float
        The value (0.0 when ``ok`` is False).
    ok : bool
        True when ``v`` is the correctly rounded value.
    """
    cdef double v = 0.0
    cdef bint ok = _fast_decimal_c(<int64_t>w, <int64_t>q, &p10hi[0], &p10lo[0], &v)
    return (v if ok else 0.0), bool(ok)


cdef inline double _strtod_at(const unsigned char *buf, Py_ssize_t i,
                              Py_ssize_t *j) noexcept nogil:
    """strtod of the text at buf[i]; ``j[0]`` = offset just after the number."""
    cdef char *endp
    cdef double v = strtod(<const char *>(buf + i), &endp)
    j[0] = <Py_ssize_t>(<const unsigned char *>endp - buf)
    return v


cdef double _scan_number(const unsigned char *buf, Py_ssize_t i, const double *p10hi,
                         const double *p10lo, Py_ssize_t *j) noexcept nogil:
    """Value of the number at buf[i]; ``j[0]`` = the offset just after it (== i: none).

    Decimal numbers of at most 18 significant digits are converted here; the others
    (more digits, inf, nan, unsure roundings) by strtod.
    """
    cdef Py_ssize_t k = i, k2
    cdef unsigned char c = buf[k], c2
    cdef bint neg = False, many = False, anyd = False, eneg
    cdef int64_t w = 0
    cdef int nd = 0, e10
    cdef int64_t dexp = 0
    cdef double v
    if c == 45 or c == 43:
        neg = c == 45
        k += 1
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
        return _strtod_at(buf, i, j)
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
        return _strtod_at(buf, i, j)
    j[0] = k
    if w == 0:
        return -0.0 if neg else 0.0
    if not _fast_decimal_c(w, dexp, p10hi, p10lo, &v):
        return _strtod_at(buf, i, j)
    return -v if neg else v


cdef inline Py_ssize_t _data_line(const unsigned char *b, Py_ssize_t *pos, Py_ssize_t n,
                                  Py_ssize_t *line) noexcept nogil:
    """Index of the first character of the next line holding data, from ``pos[0]`` on:
    blank and comment (``#``, ``%``) lines are skipped, every line visited counted in
    ``line[0]``; -1 at the end of the buffer (``pos[0]`` then at or past ``n``)."""
    cdef Py_ssize_t i
    cdef unsigned char c
    while pos[0] < n:
        line[0] += 1
        i = pos[0]
        while _is_blank(b[i]) and i < n:
            i += 1
        c = b[i]
        if c == _NL or i >= n:
            pos[0] = i + 1
            continue
        if c == _HASH or c == _PCT:
            while i < n and b[i] != _NL:
                i += 1
            pos[0] = i + 1
            continue
        return i
    return -1


cdef int _parse_line(const unsigned char *buf, Py_ssize_t i, Py_ssize_t n, double *out,
                     Py_ssize_t cap, const double *p10hi, const double *p10lo,
                     Py_ssize_t *pos, Py_ssize_t *ncol, Py_ssize_t *ecol,
                     Py_ssize_t *epos) noexcept nogil:
    """Parse the data line starting at ``buf[i]`` (a non-blank, non-comment character).

    Stores up to ``cap`` values in ``out[:cap]`` and keeps counting beyond.  Returns the
    status; ``pos`` = position after the line's ``\\n``, ``ncol`` = field count, ``ecol``
    = bad field index (1-based), ``epos`` = byte offset of the bad field.
    """
    cdef Py_ssize_t col = 0, j, k
    cdef unsigned char c, d
    cdef double v
    cdef int status = OK
    while True:
        c = buf[i]
        if c == _COMMA or c == _NL or i >= n:
            # an empty field: after a comma or at the start of the line
            status = EMPTY_FIELD
            break
        if not _is_number_start(c):
            status = BAD_NUMBER
            break
        v = _scan_number(buf, i, p10hi, p10lo, &j)
        if j <= i:
            status = BAD_NUMBER
            break
        d = buf[j]
        if not (d == _SP or d == _TAB or d == _CR or d == _COMMA or d == _NL or j >= n):
            status = BAD_NUMBER
            break
        # refuse what strtod accepts beyond decimal numbers: hexadecimal, nan(...)
        k = i + 1 if (c == 43 or c == 45) else i
        if buf[k] == 48 and k + 1 < j and (buf[k + 1] == 120 or buf[k + 1] == 88):
            status = BAD_NUMBER
            break
        if buf[j - 1] == 41:
            status = BAD_NUMBER
            break
        if col < cap:
            out[col] = v
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
                status = EMPTY_FIELD
                break
            continue
        if c == _NL or i >= n:
            pos[0] = i + 1
            ncol[0] = col
            ecol[0] = 0
            epos[0] = 0
            return OK
        if c == _HASH or c == _PCT:
            while i < n and buf[i] != _NL:
                i += 1
            pos[0] = i + 1
            ncol[0] = col
            ecol[0] = 0
            epos[0] = 0
            return OK
        # otherwise blanks were skipped and a new field starts at i
    pos[0] = i
    ncol[0] = col
    ecol[0] = col + 1
    epos[0] = i
    return status


def _parse_kernel(const unsigned char[::1] buf, Py_ssize_t ncols_min, Py_ssize_t ncols_max,
                  Py_ssize_t skip_header_lines, const double[::1] p10hi,
                  const double[::1] p10lo):
    """Kernel of :func:`ins.common.textparse.parse_table`; ``buf`` ends with a NUL byte.

    Parameters
    ----------
    buf : ndarray of uint8, shape (nbytes + 1,)
        The text followed by one NUL byte (contiguous; read-only is fine).
    ncols_min, ncols_max : int
        Accepted width of the table.
    skip_header_lines : int
        Physical lines skipped first.
    p10hi, p10lo : ndarray of float64
        The powers of ten of :func:`ins.common.exactdecimal.pow10_table`.

    Returns
    -------
    tuple
        ``(values (nrows, width) float64, row_line (nrows,) int64, status, err_line,
        err_col, err_pos, width, first_line)`` as the fields of
        :class:`ins.common.textparse.ParsedTable`.  Runs without the GIL but for the
        allocation of the outputs.
    """
    cdef const unsigned char *b = &buf[0]
    cdef const double *hi = &p10hi[0]
    cdef const double *lo = &p10lo[0]
    cdef Py_ssize_t n = buf.shape[0] - 1
    cdef Py_ssize_t nlines = 1, i, j, pos = 0, line = 0, width = -1, first_line = 0
    cdef Py_ssize_t nrows = 0, maxrows = 0, cap, ncol = 0, ecol = 0, epos = 0, k
    cdef Py_ssize_t r_line = 0, r_col = 0, r_pos = 0, r_ncol = 0, r_first = 0
    cdef int status = OK, result = -1
    cdef unsigned char c
    cdef double *tmp = NULL
    cdef double *flat = NULL
    cdef int64_t *rows = NULL
    values = np.empty((0, 1), np.float64)
    row_line = np.empty(0, np.int64)
    with nogil:
        for i in range(n):
            if b[i] == _NL:
                nlines += 1
        # header lines, skipped whatever they hold
        while line < skip_header_lines and pos < n:
            while pos < n and b[pos] != _NL:
                pos += 1
            pos += 1
            line += 1
        # the first data line: count its fields into a scratch row
        while True:
            i = _data_line(b, &pos, n, &line)
            if i < 0:
                break
            j = i
            while j < n and b[j] != _NL:
                j += 1
            cap = (j - i + 2) // 2 + 1
            tmp = <double *>malloc(cap * sizeof(double))
            if tmp == NULL:
                result = -2
                break
            status = _parse_line(b, i, n, tmp, cap, hi, lo, &pos, &ncol, &ecol, &epos)
            if status != OK:
                result = status
                r_line, r_col, r_pos, r_ncol, r_first = line, ecol, epos, ncol, line
            elif ncol < ncols_min:
                result = TOO_FEW_COLUMNS
                r_line, r_col, r_pos, r_ncol, r_first = line, ncol, i, ncol, line
            elif ncol > ncols_max:
                result = TOO_MANY_COLUMNS
                r_line, r_col, r_pos, r_ncol, r_first = line, ncol, i, ncol, line
            else:
                width = ncol
                first_line = line
                maxrows = nlines - line + 1
            break
    if result == -2:
        raise MemoryError()
    if result >= 0:
        free(tmp)
        return values[:0], row_line[:0], result, r_line, r_col, r_pos, r_ncol, r_first
    if width < 0:
        return values[:0], row_line[:0], NO_DATA, 0, 0, 0, 0, 0
    values = np.empty((maxrows, width), np.float64)
    row_line = np.empty(maxrows, np.int64)
    cdef double[:, ::1] values_v = values
    cdef int64_t[::1] rows_v = row_line
    flat = &values_v[0, 0]
    rows = &rows_v[0]
    with nogil:
        for k in range(width):
            flat[k] = tmp[k]
        free(tmp)
        rows[0] = first_line
        nrows = 1
        while True:
            i = _data_line(b, &pos, n, &line)
            if i < 0:
                break
            status = _parse_line(b, i, n, flat + nrows * width, width, hi, lo,
                                 &pos, &ncol, &ecol, &epos)
            if status != OK:
                result = status
                r_line, r_col, r_pos = line, ecol, epos
                break
            if ncol != width:
                result = COLUMN_COUNT
                r_line, r_col, r_pos = line, ncol, i
                break
            rows[nrows] = line
            nrows += 1
    if result >= 0:
        return values[:0], row_line[:0], result, r_line, r_col, r_pos, width, first_line
    return values[:nrows], row_line[:nrows], OK, 0, 0, 0, width, first_line
