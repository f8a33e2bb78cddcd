"""Scalar formulas shared by Python and the numba kernels, registered with numba on demand.

A function decorated :func:`jitable` is plain Python (numpy) until a module of numba
kernels calls :func:`register_pending` at its import; from then on numba compiles it into
the kernels that call it (``numba.extending.register_jitable``).  So the modules that hold
such formulas (:mod:`ins.nav.earth`) do not import numba: ``ins process`` runs on compiled
(Cython) kernels and never loads it (its import alone holds about 90 MiB).
"""
import threading

_PENDING = []
_LOCK = threading.Lock()


def jitable(fn):
    """Mark ``fn`` for numba's ``register_jitable`` (done by :func:`register_pending`);
    returns ``fn`` unchanged."""
    with _LOCK:
        _PENDING.append(fn)
    return fn


def register_pending():
    """Register every :func:`jitable` function with numba (imports numba); idempotent.

    Call it at the import of a module whose numba kernels call such functions, before any
    of its kernels is compiled or loaded from numba's cache."""
    from numba.extending import register_jitable
    with _LOCK:
        while _PENDING:
            register_jitable(_PENDING.pop())
