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
``xs-_{j+1}`` (:func:`ins.estimation.core._filter_kernels.correct_rows`).  The recursion needs
only the node matrices (read backwards from :class:`ins.estimation.core.filter_stores.NodeStore`,
in memory or a temporary file); the corrections are then applied in a forward sweep over the stored
forward trajectory, piece by piece (:func:`iter_smoothed`), so that the smoothed
solution is written in time order with bounded memory.  Over a 1 s node
interval the error departs from a straight line by about ``a dt^2 / 8`` with ``a`` the
rate of change of the velocity error (1e-4 m/s^2 for 10 arcsec of tilt): 0.01 mm.

filterpy's ``rts_smoother`` is not used: it assumes ``x-_{j+1} = F x+_j`` for the
stored estimates, which does not hold across the closed-loop resets (the estimates live
in a different reference trajectory at every node); the recursion above is its
algebra with the resets accounted for.  Each backward step is one compiled kernel
(:func:`ins.estimation.core._kalman_kernels.rts_step`).
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import QualityError
from ins.estimation.core import _filter_kernels
from ins.estimation.core import _kalman_kernels
from ins.estimation.core.error_model import (ATT_CROSS, ATT_STOP, STATE_NAMES, VARIANCE_RTOL,
                                             checked_std)
from ins.estimation.core.filter_stores import PIECE_ROWS, Table, read_rows


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


def rts_errors(fwd, full=True, workdir=None, att_cross=False):
    """The backward recursion: smoothed errors ``xs+`` (m, 21) and covariances.

    ``fwd`` has ``dx`` and either ``nodes`` (:class:`ins.estimation.core.filter_stores.NodeStore`, read
    backwards block by block) or the sequences ``P_prior``, ``P_post``, ``Phi``.
    Returns ``(xs, Ps)`` with ``Ps`` (m, 21, 21), or with ``full=False`` ``(xs, std)``
    with the smoothed standard deviations (m, 21) only (bounded memory), and with
    ``att_cross=True`` (and ``full=False``) ``(xs, std, cross)`` with also the smoothed
    attitude cross covariances ``Ps[ATT_CROSS]`` (m, 3) (rad^2: N-E, N-D, E-D of the phi
    angles; :data:`ins.estimation.core.error_model.ATT_CROSS`), which with ``std`` give
    the whole attitude block.  With ``workdir`` (and ``full=False``) the tables are
    :class:`ins.estimation.core.filter_stores.Table` s in temporary files there, written
    backwards block by block: memory does not grow with the number of nodes.

    Raises
    ------
    ins.common.errors.QualityError
        When a forward prior covariance is not positive definite (its Cholesky factor
        fails) or a smoothed variance is negative beyond rounding (relative to the
        forward posterior variance of the same state): the message names the node time
        (``fwd.node_time`` when present, else the node index) and the state.
    """
    stores = getattr(fwd, "stores", None)
    dx_src = stores["dx"] if stores is not None else np.asarray(fwd.dx, dtype=float)
    t_src = (stores["node_time"] if stores is not None
             else getattr(fwd, "node_time", None))
    when = ((lambda j: f"t = {float(t_src[j]):.3f} s") if t_src is not None
            else (lambda j: f"node {j}"))
    m = len(dx_src)
    n = read_rows(dx_src, 0, 1).shape[1]
    disk = workdir is not None and not full
    xs_tab, std_tab = Table(m, n, workdir if disk else None), Table(m, n, workdir if disk else None)
    att_tab = Table(m, len(ATT_CROSS[0]), workdir if disk else None)
    Ps = np.empty((m, n, n)) if full else None
    names = _names(fwd, n)
    blk = _BLOCK
    xs_blk, std_blk, hi = np.zeros((blk, n)), np.empty((blk, n)), m   # rows lo .. hi-1
    att_blk = np.empty((blk, len(ATT_CROSS[0])))
    lo = max(hi - blk, 0)
    dx_blk = read_rows(dx_src, lo, hi + 1)              # dx of nodes lo .. hi
    t_blk = None if t_src is None else read_rows(t_src, lo, hi)
    x_next = None                                       # xs of node j + 1
    nxt = None                                          # (P_prior, Phi, Ps) of node j + 1
    for j, P_prior, P_post, Phi in _backward_nodes(fwd):
        if j < lo:                                      # the next block back
            xs_tab.put(lo, xs_blk[:hi - lo])
            std_tab.put(lo, std_blk[:hi - lo])
            att_tab.put(lo, att_blk[:hi - lo])
            hi, lo = lo, max(lo - blk, 0)
            dx_blk = read_rows(dx_src, lo, hi + 1)
            t_blk = None if t_src is None else read_rows(t_src, lo, hi)
        i = j - lo
        P_post = np.ascontiguousarray(P_post, dtype=float)
        if nxt is None:
            Pj = np.array(P_post)
            xs_blk[i] = 0.0
        else:
            # A = P+_j Phi^T (P-)^-1  <=>  A^T = (P-)^-1 Phi P+_j  (P- symmetric positive)
            ok, xs_blk[i], Pj = _kalman_kernels.rts_step(nxt[0], nxt[1], P_post, nxt[2],
                                                         dx_blk[i + 1] + x_next)
            if not ok:
                raise QualityError(_not_positive(nxt[0], when(j + 1),
                                                 "its Cholesky factorization failed"))
        if full:
            Ps[j] = Pj
        var, scale = Pj.diagonal(), P_post.diagonal()
        if (var >= -VARIANCE_RTOL * np.abs(scale)).all():      # the usual case: fast
            np.sqrt(np.maximum(var, 0.0), out=std_blk[i])
        else:                                                   # NaN, or negative
            std_blk[i] = checked_std(var, scale, None if t_blk is None else t_blk[i],
                                     names=names, what="smoothed covariance")
        att_blk[i] = Pj[ATT_CROSS] if n > ATT_STOP else np.nan   # NaN: no attitude
        x_next = xs_blk[i].copy()
        nxt = (np.ascontiguousarray(P_prior, dtype=float),
               np.ascontiguousarray(Phi, dtype=float), Pj)
    if m:
        xs_tab.put(lo, xs_blk[:hi - lo])
        std_tab.put(lo, std_blk[:hi - lo])
        att_tab.put(lo, att_blk[:hi - lo])
    if full:
        return xs_tab.array(), Ps
    out = (xs_tab, std_tab, att_tab) if disk else (xs_tab.array(), std_tab.array(),
                                                   att_tab.array())
    return out if att_cross else out[:2]


#: Nodes per block of the smoother's reads and writes.
_BLOCK = 512


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


def iter_smoothed(fwd, xs, rows=PIECE_ROWS):
    """The smoothed trajectory in time order, ``(time, states)`` pieces: the forward
    pieces (read back from ``fwd.trajectory``) corrected by the smoothed errors ``xs``
    of :func:`rts_errors` (an array or a :class:`ins.estimation.core.filter_stores.Table`;
    bounded memory: one piece and the nodes around it at a time)."""
    stores = getattr(fwd, "stores", None)
    if stores is None:
        src = {"node_rows": fwd.node_rows, "node_time": fwd.node_time, "dx": fwd.dx}
    else:
        src = {k: stores[k] for k in ("node_rows", "node_time", "dx")}
    m = len(src["node_time"])
    seg = None                       # nodes a .. b-1: rows, time, x_after, x_before
    a = b = 0
    for row0, time, states in fwd.trajectory.chunks(rows):
        row1 = row0 + len(time) - 1
        # the nodes from the last at or before row0 to the first at or after row1
        while b < m and (seg is None or seg[0][-1] < row1):
            b1 = min(b + max(rows // 16, 64), m)
            part = [read_rows(src["node_rows"], b, b1), read_rows(src["node_time"], b, b1)]
            x_after = read_rows(xs, b, b1)
            part += [x_after, read_rows(src["dx"], b, b1) + x_after]
            seg = part if seg is None else [np.concatenate([s, p]) for s, p in zip(seg, part)]
            b = b1
        k = max(int(np.searchsorted(seg[0], row0, side="right")) - 1, 0)
        if k:                        # drop the nodes before it
            seg = [s[k:] for s in seg]
            a += k
        _filter_kernels.correct_rows(states, time, row0, *seg)
        yield time, states


def smooth(fwd):
    """Smoothed trajectory at every IMU epoch from a :class:`ins.estimation.core.filter.ForwardResult`
    (in memory; :func:`iter_smoothed` streams it)."""
    xs, Ps = rts_errors(fwd)
    parts = list(iter_smoothed(fwd, xs))
    return SmoothedResult(time=np.concatenate([p[0] for p in parts]),
                          states=np.concatenate([p[1] for p in parts]),
                          node_rows=fwd.node_rows, x_after=xs, P=Ps,
                          sensors=fwd.sensors + xs[:, 9:])
