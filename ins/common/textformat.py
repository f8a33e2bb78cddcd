"""Fixed-point text of float64 tables, digit for digit as Python's ``'%.{d}f'`` (compiled).

:func:`format_fixed` writes a float64 table in fixed-point notation with a number of
decimals per column (as ``'%.{d}f' % x``, digit for digit: the product ``x * 10**d``
is formed exactly with Dekker's two-product and rounded to nearest, ties to even,
which is what Python does).  :func:`format_table` also accepts ``-1`` decimals for a
column written as ``'%.17e'`` (scientific, 18 significant digits), which reads back to
the same float64.  :func:`roundtrip_decimals` finds the fewest decimals with which a
column reads back exactly, if any.  This module does not write files (see
:func:`ins.common.fileio.atomic_open`).  The kernels are compiled (Cython,
``ins/common/_textformat_kernels.pyx``; the formatting runs without the GIL).  About
0.06 s for the 48 MB benchmark IMU log (the numba kernel it replaced: 0.09 s;
``numpy.savetxt`` 0.83 s, pandas ``to_csv`` 2.7 s: ``bench/bench_textio.py``).
"""
import numpy as np

from ins.common._textformat_kernels import _format_kernel, _roundtrip_kernel
from ins.common.exactdecimal import pow10_table, readonly

__all__ = ["format_fixed", "format_table", "roundtrip_decimals"]


_PAIRS = np.frombuffer("".join(f"{k:02d}" for k in range(100)).encode(), np.uint8).copy()
_POW10_INT = np.array([10 ** k for k in range(19)], dtype=np.int64)


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
