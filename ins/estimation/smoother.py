"""Backward Rauch-Tung-Striebel pass over the closed-loop forward filter.

Formulation
-----------
After each feedback the forward filter's error estimate is zero: at node ``j`` the
posterior error relative to the corrected (post-update) trajectory is 0 with covariance
``P+_j``; mechanizing on to node ``j + 1`` gives the pre-update trajectory there, whose
prior error is 0 with covariance ``P-_{j+1} = Phi_{j+1} P+_j Phi_{j+1}^T + Q``.  The
update then fed back ``dx_{j+1}``, so an error ``e`` relative to the post-update state is
``dx_{j+1} + e`` relative to the pre-update one (to first order; exact for the sensor
states).  The RTS recursion on these error states, each relative to the forward
trajectory, reads

    A_j      = P+_j Phi_{j+1}^T (P-_{j+1})^-1
    xs+_j    = A_j (dx_{j+1} + xs+_{j+1})             (the forward estimate is 0)
    Ps_j     = P+_j + A_j (Ps_{j+1} - P-_{j+1}) A_j^T

starting from ``xs+ = 0``, ``Ps = P+`` at the last node.  ``xs+_j`` is the smoothed
error of the forward state after the update at node ``j``; ``xs-_j = dx_j + xs+_j``
the error just before it.

Between two nodes the forward trajectory is one continuous mechanization, so its error
varies smoothly: every IMU epoch gets the linear interpolation in time of ``xs+_j`` and
``xs-_{j+1}`` (:func:`ins.estimation._filter_kernels.correct_rows`).  The recursion needs only
the node matrices (read backwards from :class:`ins.estimation.filter_stores.NodeStore`, in memory or a
temporary file); the corrections are then applied in a forward sweep over the stored
forward trajectory, piece by piece (:func:`iter_smoothed`), so that the smoothed
solution is written in time order with bounded memory.  Over a 1 s node
interval the error departs from a straight line by about ``a dt^2 / 8`` with ``a`` the
rate of change of the velocity error (1e-4 m/s^2 for 10 arcsec of tilt): 0.01 mm.

filterpy's ``rts_smoother`` is not used: it assumes ``x-_{j+1} = F x+_j`` for the
stored estimates, which does not hold across the closed-loop resets (the estimates live
in a different reference trajectory at every node); the recursion above is its
algebra with the resets accounted for.  Each backward step is one compiled kernel
(:func:`ins.estimation._kalman_kernels.rts_step`).
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import QualityError
from ins.estimation import _filter_kernels, _kalman_kernels
from ins.estimation.error_model import STATE_NAMES, checked_std


def _backward_nodes(fwd):
    """``(j, P_prior_j, P_post_j, Phi_j)`` from the last node to the first."""
    nodes = getattr(fwd, "nodes", None)
    if nodes is None:                                   # plain sequences
        for j in range(len(fwd.P_post) - 1, -1, -1):
            yield j, fwd.P_prior[j], fwd.P_post[j], fwd.Phi[j]
        return
    for j0, block in nodes.blocks_reversed():
        for i in range(len(block) - 1, -1, -1):
            yield j0 + i, block[i, 0], block[i, 1], block[i, 2]


def rts_errors(fwd, full=True):
    """The backward recursion: smoothed errors ``xs+`` (m, 21) and covariances.

    ``fwd`` has ``dx`` and either ``nodes`` (:class:`ins.estimation.filter_stores.NodeStore`, read
    backwards block by block) or the sequences ``P_prior``, ``P_post``, ``Phi``.
    Returns ``(xs, Ps)`` with ``Ps`` (m, 21, 21), or with ``full=False`` ``(xs, std)``
    with the smoothed standard deviations (m, 21) only (bounded memory).

    Raises
    ------
    ins.common.errors.QualityError
        When a forward prior covariance is not positive definite (its Cholesky factor
        fails) or a smoothed variance is negative beyond rounding (relative to the
        forward posterior variance of the same state): the message names the node time
        (``fwd.node_time`` when present, else the node index) and the state.
    """
    dx = np.asarray(fwd.dx, dtype=float)
    node_time = getattr(fwd, "node_time", None)
    when = ((lambda j: f"t = {float(node_time[j]):.3f} s") if node_time is not None
            else (lambda j: f"node {j}"))
    m, n = dx.shape
    xs = np.zeros((m, n))
    Ps = np.empty((m, n, n)) if full else None
    std = np.empty((m, n))
    nxt = None                                          # (P_prior, Phi, Ps) of node j + 1
    for j, P_prior, P_post, Phi in _backward_nodes(fwd):
        P_post = np.ascontiguousarray(P_post, dtype=float)
        if nxt is None:
            Pj = np.array(P_post)
        else:
            # A = P+_j Phi^T (P-)^-1  <=>  A^T = (P-)^-1 Phi P+_j  (P- symmetric positive)
            ok, xs[j], Pj = _kalman_kernels.rts_step(nxt[0], nxt[1], P_post, nxt[2],
                                                     dx[j + 1] + xs[j + 1])
            if not ok:
                raise QualityError(_not_positive(nxt[0], when(j + 1),
                                                 "its Cholesky factorization failed"))
        if full:
            Ps[j] = Pj
        std[j] = checked_std(np.diag(Pj), np.diag(P_post),
                             None if node_time is None else node_time[j], names=_names(fwd, n),
                             what="smoothed covariance")
        nxt = (np.ascontiguousarray(P_prior, dtype=float),
               np.ascontiguousarray(Phi, dtype=float), Pj)
    return xs, (Ps if full else std)


def _names(fwd, n):
    """State names of a forward result (its layout), else of the 21-state layout."""
    layout = getattr(fwd, "layout", None)
    if layout is not None and layout.n == n:
        return layout.names
    return STATE_NAMES if n == len(STATE_NAMES) else tuple(f"state_{k}" for k in range(n))


def _not_positive(P, when, exc):
    """Message for a prior covariance whose Cholesky factorization failed."""
    d = np.diag(P)
    if not np.all(np.isfinite(P)):
        detail = "it holds non-finite values"
    elif np.any(d <= 0):
        k = int(np.argmin(d))
        names = _names(None, len(d))
        detail = f"variance {d[k]:.3e} for state {names[k]}"
    else:
        w = np.linalg.eigvalsh(P / np.sqrt(np.outer(d, d)))
        detail = f"smallest eigenvalue of its correlation matrix {w[0]:.3e}"
    return (f"smoother: the forward filter's prior covariance at {when} is not positive "
            f"definite ({detail}; {exc}); the forward solution is numerically unreliable "
            f"there (implausible noise settings or initial sigmas?)")


@dataclass
class SmoothedResult:
    """Smoothed solution.

    Attributes
    ----------
    time : ndarray, shape (n,)
    states : ndarray, shape (n, 10)
        Smoothed navigation states (``ins.nav._kernels`` layout).
    node_rows : ndarray, shape (m,)
    x_after : ndarray, shape (m, 21)
        Smoothed error of the forward post-update state at each node.
    P : ndarray, shape (m, 21, 21)
        Smoothed covariance at the nodes.
    sensors : ndarray, shape (m, 12)
        Smoothed sensor errors (gyro bias rad/s, accel bias m/s^2, scales).
    """

    time: np.ndarray
    states: np.ndarray
    node_rows: np.ndarray
    x_after: np.ndarray
    P: np.ndarray
    sensors: np.ndarray


def iter_smoothed(fwd, xs, rows=1 << 16):
    """The smoothed trajectory in time order, ``(time, states)`` pieces: the forward
    pieces (read back from ``fwd.trajectory``) corrected by the smoothed errors ``xs``
    of :func:`rts_errors` (bounded memory: one piece at a time)."""
    x_before = fwd.dx + xs
    for row0, time, states in fwd.trajectory.chunks(rows):
        _filter_kernels.correct_rows(states, time, row0, fwd.node_rows, fwd.node_time, xs,
                                     x_before)
        yield time, states


def smooth(fwd):
    """Smoothed trajectory at every IMU epoch from a :class:`ins.estimation.filter.ForwardResult`
    (in memory; :func:`iter_smoothed` streams it)."""
    xs, Ps = rts_errors(fwd)
    parts = list(iter_smoothed(fwd, xs))
    return SmoothedResult(time=np.concatenate([p[0] for p in parts]),
                          states=np.concatenate([p[1] for p in parts]),
                          node_rows=fwd.node_rows, x_after=xs, P=Ps,
                          sensors=fwd.sensors + xs[:, 9:])
