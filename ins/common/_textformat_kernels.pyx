"""Compiled kernels of :mod:`ins.common.textformat` (Cython; private).

:func:`_format_kernel` writes a float64 table as text, each column fixed point
(``'%.{d}f'``, digit for digit: ``|x| * 10**d`` is formed exactly with Dekker's
two-product and rounded to nearest, ties to even) or ``'%.17e'``; it runs without the
GIL but for the allocation of the output.  :func:`_roundtrip_kernel` is the exact test of
:func:`ins.common.textformat.roundtrip_decimals`.
"""
import numpy as np

from libc.math cimport fabs, floor, isfinite
from libc.stdint cimport int64_t, uint8_t, uint64_t

from ins.common._exactdecimal cimport P10_MIN, two_prod

cdef enum:
    _NL = 10

cdef extern from *:
    """
    #define INS_TWO52 4503599627370496.0
    #define INS_MAX_FIXED 9e18
    #define INS_SCI_LO 1e-280
    #define INS_SCI_HI 1e280
    """
    const double _TWO52 "INS_TWO52"
    const double _MAX_FIXED "INS_MAX_FIXED"
    # the scientific kernel's domain (else the Python fallback)
    const double _SCI_LO "INS_SCI_LO"
    const double _SCI_HI "INS_SCI_HI"


cdef inline int64_t _round_big(double p, double e) noexcept nogil:
    """Nearest integer (ties to even) to p + e, p an integer-valued double, |e| small."""
    cdef double fe = floor(e)
    cdef double g = e - fe
    cdef int64_t r = <int64_t>p + <int64_t>fe
    if g > 0.5 or (g == 0.5 and (r & 1) == 1):
        r += 1
    return r


cdef inline int64_t _round_scaled(double a, double scale) noexcept nogil:
    """Nearest integer (ties to even) to the exact product a * scale, a >= 0.

    ``scale`` must be an exact power of ten (<= 1e22).  Returns -1 when the product is
    not finite or >= 9e18.
    """
    cdef double p = a * scale, e, fp, d1
    cdef int64_t r
    if not (p < _MAX_FIXED):
        return -1
    if p < 0.5:
        return 0
    two_prod(a, scale, &p, &e)
    if p >= _TWO52:
        return _round_big(p, e)
    r = <int64_t>p               # floor(p): 0.5 <= p < 2**52 (one cvttsd2si, no libm call)
    fp = <double>r
    d1 = (p - fp) - 0.5          # exact for p >= 0.5
    if d1 > -e or (d1 == -e and (r & 1) == 1):
        r += 1
    return r


cdef inline void _sci_digits(double a, int64_t bits, const double *p10hi,
                             const double *p10lo, int64_t *N_out,
                             int64_t *E_out) noexcept nogil:
    """N, E with N the 18-digit integer nearest to a * 10**(17 - E), 1e17 <= N < 1e18.

    ``bits`` is the IEEE bit pattern of ``a`` (for a first guess of E without log10).
    """
    cdef int64_t ex = <int64_t>((<uint64_t>bits >> 52) & 0x7FF) - 1023
    # floor(ex * log10(2)); E is then off by at most one (>> of a negative int64 is an
    # arithmetic shift, i.e. a floor, with gcc and clang)
    cdef int64_t E = (ex * 78913) >> 18
    cdef int64_t N = 0, k
    cdef double p, e
    cdef int it
    for it in range(6):
        k = 17 - E - P10_MIN
        two_prod(a, p10hi[k], &p, &e)
        e += a * p10lo[k]
        if p >= 2e18:               # guards for the int64 conversion only
            E += 1
            continue
        if p < 5e16:
            E -= 1
            continue
        N = _round_big(p, e)
        if N >= 1000000000000000000LL:
            E += 1
            continue
        if N < 100000000000000000LL:
            E -= 1
            continue
        break
    N_out[0] = N
    E_out[0] = E


cdef inline void _put_digits(uint8_t *out, Py_ssize_t end, int64_t x, Py_ssize_t count,
                             const uint8_t *pairs) noexcept nogil:
    """Write the ``count`` low decimal digits of ``x`` (>= 0) to out[end - count:end]."""
    cdef uint64_t u = <uint64_t>x     # unsigned: division by a constant without sign fix-ups
    cdef uint64_t q
    cdef Py_ssize_t r
    while count >= 2:
        q = u // 100
        r = <Py_ssize_t>(u - q * 100) * 2
        out[end - 2] = pairs[r]
        out[end - 1] = pairs[r + 1]
        end -= 2
        count -= 2
        u = q
    if count == 1:
        out[end - 1] = 48 + <Py_ssize_t>(u % 10)


def _format_kernel(const double[:, ::1] values, const int64_t[:, ::1] bits,
                   const int64_t[::1] decimals, int sep, const double[::1] p10hi,
                   const double[::1] p10lo, const uint8_t[::1] pairs,
                   const int64_t[::1] pow10_int):
    """Text of ``values``: returns (uint8 text, status, bad row, bad column).

    Parameters
    ----------
    values : ndarray of float64, shape (n, m), C-contiguous (read-only is fine)
        The table.
    bits : ndarray of int64, shape (n, m)
        ``values.view(np.int64)`` (IEEE bit patterns: sign and exponent).
    decimals : ndarray of int64, shape (m,)
        Decimals per column, 0..22, or -1 for ``'%.17e'``.
    sep : int
        Byte of the field separator.
    p10hi, p10lo : ndarray of float64
        The powers of ten of :func:`ins.common.exactdecimal.pow10_table`.
    pairs : ndarray of uint8, shape (200,)
        The ASCII digits of 00..99.
    pow10_int : ndarray of int64, shape (19,)
        10**k, k = 0..18.

    Returns
    -------
    tuple
        ``(text, status, row, column)``; status 0: ok; 1: non-finite value; 2:
        ``|value * 10**d| >= 9e18``; 3: a value outside the scientific kernel's range
        (the caller falls back to Python); row and column (0-based) of the bad value.
    """
    cdef Py_ssize_t n = values.shape[0], m = values.shape[1]
    out_a = np.empty(n * m * 27 + 1, np.uint8)
    pow10_a = np.empty(m, np.float64)
    cdef uint8_t[::1] out_v = out_a
    cdef double[::1] pow10_v = pow10_a
    cdef uint8_t *out = &out_v[0]
    cdef double *pow10 = &pow10_v[0] if m > 0 else NULL
    cdef const double *vals = &values[0, 0] if n * m > 0 else NULL
    cdef const int64_t *bts = &bits[0, 0] if n * m > 0 else NULL
    cdef const int64_t *dec = &decimals[0] if m > 0 else NULL
    cdef const double *hi = &p10hi[0]
    cdef const double *lo = &p10lo[0]
    cdef const uint8_t *prs = &pairs[0]
    cdef const int64_t *p10i = &pow10_int[0]
    cdef Py_ssize_t pos = 0, r, j, nint, bad_r = 0, bad_j = 0
    cdef int status = 0
    cdef double v, a
    cdef int64_t b, d, N, E, ip, frac, lead
    cdef uint8_t sepb = <uint8_t>sep
    with nogil:
        for j in range(m):
            pow10[j] = hi[dec[j] - P10_MIN] if dec[j] >= 0 else 1.0
        for r in range(n):
            for j in range(m):
                v = vals[r * m + j]
                if not isfinite(v):
                    status = 1
                    break
                b = bts[r * m + j]
                a = fabs(v)
                d = dec[j]
                if b < 0:                   # sign bit: also for -0.0, as '%f' does
                    out[pos] = 45
                    pos += 1
                if d >= 0:
                    N = _round_scaled(a, pow10[j])
                    if N < 0:
                        status = 2
                        break
                    # integer part: trunc(a), plus one when the rounding carried into it
                    # (cheaper than an integer division by 10**d)
                    if d <= 18:
                        ip = <int64_t>a
                        frac = N - ip * p10i[d]
                        if frac >= p10i[d]:
                            ip += 1
                            frac -= p10i[d]
                    else:
                        # |x| < 9e18 / 10**d < 1 and N < 9e18 < 10**d: no integer part and
                        # no carry (10**d is beyond int64 and pow10_int)
                        ip = 0
                        frac = N
                    nint = 1
                    while nint < 19 and ip >= p10i[nint]:
                        nint += 1
                    _put_digits(out, pos + nint, ip, nint, prs)
                    pos += nint
                    if d > 0:
                        out[pos] = 46
                        _put_digits(out, pos + 1 + d, frac, d, prs)
                        pos += 1 + d
                else:
                    if a == 0.0:
                        N = 0
                        E = 0
                    else:
                        if a < _SCI_LO or a > _SCI_HI:
                            status = 3
                            break
                        _sci_digits(a, b, hi, lo, &N, &E)
                    lead = N // 100000000000000000LL
                    out[pos] = <uint8_t>(48 + lead)
                    out[pos + 1] = 46
                    _put_digits(out, pos + 19, N - lead * 100000000000000000LL, 17, prs)
                    pos += 19
                    out[pos] = 101
                    out[pos + 1] = 45 if E < 0 else 43
                    pos += 2
                    if E < 0:
                        E = -E
                    if E >= 100:
                        out[pos] = <uint8_t>(48 + E // 100)
                        pos += 1
                        E = E % 100
                    out[pos] = <uint8_t>(48 + E // 10)
                    out[pos + 1] = <uint8_t>(48 + E % 10)
                    pos += 2
                out[pos] = sepb if j < m - 1 else _NL
                pos += 1
            if status != 0:
                bad_r = r
                bad_j = j
                break
    if status != 0:
        return out_a[:0], status, bad_r, bad_j
    return out_a[:pos], 0, 0, 0


def _roundtrip_kernel(const double[::1] x, Py_ssize_t min_decimals, Py_ssize_t max_decimals,
                      const double[::1] p10hi):
    """Fewest decimals d in min_decimals..max_decimals (0..22) with which every ``|x|``
    reads back exactly from its ``'%.{d}f'`` text, or -1.

    With ``N`` the rounded ``|x| * 10**d`` (below 2**53), the text reads back as the
    correctly rounded ``N / 10**d``, a single IEEE division.
    """
    cdef Py_ssize_t d, i, nx = x.shape[0]
    cdef const double *xp = &x[0] if nx > 0 else NULL
    cdef double scale, a
    cdef int64_t N
    cdef bint ok
    for d in range(min_decimals, max_decimals + 1):
        scale = p10hi[d - P10_MIN]
        ok = True
        for i in range(nx):
            a = fabs(xp[i])
            N = _round_scaled(a, scale)
            if N < 0 or N >= 9007199254740992LL or <double>N / scale != a:
                ok = False
                break
        if ok:
            return d
    return -1


def two_prod_checked(double a, double b):
    """``(p, e)`` of :func:`two_prod` of ``_exactdecimal.pxd`` (the kernels' exact product),
    for :func:`ins.common.exactdecimal.two_prod` and its test."""
    cdef double p, e
    two_prod(a, b, &p, &e)
    return p, e
