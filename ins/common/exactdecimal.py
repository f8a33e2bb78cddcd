"""Exact decimal arithmetic shared by the text parser and the fixed-point formatter.

Powers of ten as double-double numbers (:func:`pow10_table`), Dekker's exact product
(:func:`two_prod`) and read-only views (:func:`readonly`).  The compiled kernels of
:mod:`ins.common.textparse` and :mod:`ins.common.textformat` use the C twin of
:func:`two_prod` and of ``P10_MIN``/``P10_MAX`` in ``ins/common/_exactdecimal.pxd`` (the
same operations in the same order, built without fused multiply-add) and take the table
of :func:`pow10_table` as arguments.
"""
import functools

import numpy as np

__all__ = ["P10_MIN", "P10_MAX", "pow10_table", "two_prod", "readonly"]

#: Exponent range of :func:`pow10_table`.
P10_MIN, P10_MAX = -270, 300


@functools.lru_cache(maxsize=1)
def pow10_table():
    """Powers of ten 10**p, p in [P10_MIN, P10_MAX], as double-double (hi, lo).

    ``hi`` is 10**p correctly rounded, ``lo`` the remainder 10**p - hi correctly
    rounded (Python's int / int division and int-to-float conversion are exact-rounded).
    """
    p = np.arange(P10_MIN, P10_MAX + 1)
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


def two_prod(a, b):
    """p, e with p = fl(a*b) and p + e = a*b exactly (Dekker, no FMA needed).

    Parameters
    ----------
    a, b : float
        Factors (their product and the partial products must not overflow).

    Returns
    -------
    p, e : float
        The rounded product and its exact rounding error.
    """
    a = float(a)
    b = float(b)
    p = a * b
    c = 134217729.0 * a
    ah = c - (c - a)
    al = a - ah
    c = 134217729.0 * b
    bh = c - (c - b)
    bl = b - bh
    e = ((ah * bh - p) + ah * bl + al * bh) + al * bl
    return p, e


def readonly(a):
    """A read-only view of ``a`` (the kernels declare their inputs ``const``: they never
    write to them)."""
    v = a.view()
    v.flags.writeable = False
    return v
