"""Fixed-point text of float64 tables, digit for digit as Python's ``'%.{d}f'`` (numba).

:func:`format_fixed` writes a float64 table in fixed-point notation with a number of
decimals per column (as ``'%.{d}f' % x``, digit for digit: the product ``x * 10**d``
is formed exactly with Dekker's two-product and rounded to nearest, ties to even,
which is what Python does).  :func:`format_table` also accepts ``-1`` decimals for a
column written as ``'%.17e'`` (scientific, 18 significant digits), which reads back to
the same float64.  :func:`roundtrip_decimals` finds the fewest decimals with which a
column reads back exactly, if any.  This module does not write files (see
:func:`ins.common.fileio.atomic_open`).  About 0.10 s for the 48 MB benchmark IMU log
(``numpy.savetxt`` 0.83 s, pandas ``to_csv`` 2.7 s: ``bench/bench_textio.py``).
"""
import numba
import numpy as np

from ins.common.exactdecimal import P10_MIN, pow10_table, readonly, two_prod

__all__ = ["format_fixed", "format_table", "roundtrip_decimals"]

_NL = 10
_TWO52 = 4503599627370496.0
_MAX_FIXED = 9e18
_SCI_LO, _SCI_HI = 1e-280, 1e280      # scientific kernel domain (else Python fallback)


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
    p, e = two_prod(a, scale)
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
        k = 17 - E - P10_MIN
        p, e = two_prod(a, p10hi[k])
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
        pow10[j] = p10hi[decimals[j] - P10_MIN] if decimals[j] >= 0 else 1.0
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
    hi, lo = pow10_table()
    out, status, r, c = _format_kernel(readonly(values), readonly(values.view(np.int64)),
                                       readonly(decimals), sepb, hi, lo, _PAIRS, _POW10_INT)
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
        scale = p10hi[d - P10_MIN]
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
    hi, _ = pow10_table()
    return int(_roundtrip_kernel(readonly(x), int(min_decimals), min(int(max_decimals), 22),
                                 hi))
