"""Single-or-stack array arguments: one item of shape ``tail`` or a stack ``(n, *tail)``.

The shape and finiteness checks of the rotation functions (:mod:`ins.nav.rotation`,
``photogrammetry.orientation.rotation``), in the manner of ``scipy.spatial.transform.Rotation``: the
output has a leading ``n`` axis exactly when an input had one; errors name the argument
and the first offending row.
"""
import numpy as np

__all__ = ["as_stack"]


def as_stack(x, name, tail, finite=False):
    """Return ``(a, single)``: `x` as a float ``(n, *tail)`` array and whether it was one item.

    The shape check of every function here that takes one item or a stack (shared with
    ``photogrammetry.orientation.rotation``); ``name`` is the argument's name in the message.

    With ``finite=True`` a NaN or infinite element is refused (ValueError naming the
    first offending row of a stack).
    """
    a = np.asarray(x, dtype=float)
    if a.shape == tail:
        a, single = a[np.newaxis], True
    elif a.ndim == len(tail) + 1 and a.shape[1:] == tail:
        single = False
    else:
        one = "(" + ", ".join(map(str, tail)) + ("," if len(tail) == 1 else "") + ")"
        many = "(n, " + ", ".join(map(str, tail)) + ")"
        raise ValueError(f"{name} must have shape {one} or {many}, got {a.shape}")
    if finite and not np.isfinite(a).all():
        bad = np.flatnonzero(~np.isfinite(a.reshape(len(a), -1)).all(axis=1))
        value = np.array2string(a[bad[0]], separator=", ").replace("\n", "")
        where = "" if single else f" (row {int(bad[0])} of {len(a)}; {bad.size} such)"
        raise ValueError(f"{name} must be finite, got {value}{where}")
    return a, single


def _out(a, single):
    return a[0] if single else a


def _check_pair(a, a_single, b, b_single, names):
    if not (a_single or b_single) and len(a) != len(b):
        raise ValueError(f"{names[0]} and {names[1]} must be single or stacks of equal "
                         f"length, got {len(a)} and {len(b)} rows")


def _normalized(q, name="q"):
    """Unit quaternions of the (n, 4) stack `q`: refuses a zero, NaN or infinite norm
    (a NaN quaternion would pass a bare ``norm == 0`` test and come out as NaN)."""
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    bad = np.flatnonzero(~(np.isfinite(norm[:, 0]) & (norm[:, 0] > 0)))
    if bad.size:
        i = int(bad[0])
        what = "nonzero norm" if norm[i, 0] == 0 else "finite elements"
        where = f" (row {i} of {len(q)}; {bad.size} such)" if len(q) > 1 else ""
        raise ValueError(f"{name} must have {what}, got "
                         f"{np.array2string(q[i], separator=', ')}{where}")
    return q / norm


def _canonical(q):
    """Flip quaternions to w > 0 (ties broken by the first nonzero of x, y, z being > 0)."""
    x, y, z, w = q.T
    flip = (w < 0) | ((w == 0) & ((x < 0) | ((x == 0) & ((y < 0) | ((y == 0) & (z < 0))))))
    return np.where(flip[:, np.newaxis], -q, q)


def _pm_pi(a):
    """Map atan2 output from [-pi, pi] to (-pi, pi]."""
    return np.where(a == -np.pi, np.pi, a)
