# Exact decimal arithmetic for the compiled text kernels (C inline functions; private).
#
# The same formulas as ins/common/exactdecimal.py (two_prod, P10_MIN/P10_MAX), cimported by
# ins/common/_textparse_kernels.pyx and ins/common/_textformat_kernels.pyx so that they are
# inlined.  The powers of ten (exactdecimal.pow10_table) are passed to the kernels as
# arrays.  Every product and sum is rounded as written: setup.py compiles with
# -ffp-contract=off (no fused multiply-add), which Dekker's two-product relies on.

cdef enum:
    P10_MIN = -270      # exponent range of exactdecimal.pow10_table
    P10_MAX = 300


cdef inline void two_prod(double a, double b, double *p, double *e) noexcept nogil:
    """p, e with p = fl(a*b) and p + e = a*b exactly (Dekker, no FMA needed)."""
    cdef double c, ah, al, bh, bl
    p[0] = a * b
    c = 134217729.0 * a
    ah = c - (c - a)
    al = a - ah
    c = 134217729.0 * b
    bh = c - (c - b)
    bl = b - bh
    e[0] = ((ah * bh - p[0]) + ah * bl + al * bh) + al * bl
