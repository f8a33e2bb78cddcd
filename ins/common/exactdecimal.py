"""Exact decimal arithmetic shared by the text parser and the fixed-point formatter.

Powers of ten as double-double numbers (:func:`pow10_table`), Dekker's exact product
(:func:`two_prod`) and read-only views (:func:`readonly`).  The compiled kernels of
:mod:`ins.common.textparse` and :mod:`ins.common.textformat` use :func:`two_prod` and
``P10_MIN``/``P10_MAX`` from ``ins/common/_exactdecimal.pxd`` (C, built without fused
multiply-add) and take the table of :func:`pow10_table` as arguments.
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
    """p, e with p = fl(a*b) and p + e = a*b exactly (Dekker, no FMA needed): the
    kernels' own C function (``_exactdecimal.pxd``), so that its test tests them.

    Parameters
    ----------
    a, b : float

    Returns
    -------
    p, e : float
        The rounded product and its exact rounding error.
    """
    from ins.common._textformat_kernels import two_prod_checked
    return two_prod_checked(float(a), float(b))


def readonly(a):
    """A read-only view of ``a`` (the kernels declare their inputs ``const``: they never
    write to them)."""
    v = a.view()
    v.flags.writeable = False
    return v
