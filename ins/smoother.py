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
``xs-_{j+1}`` (:func:`ins._filter_kernels.correct_between_nodes`).  Over a 1 s node
interval the error departs from a straight line by about ``a dt^2 / 8`` with ``a`` the
rate of change of the velocity error (1e-4 m/s^2 for 10 arcsec of tilt): 0.01 mm.

filterpy's ``rts_smoother`` is not used: it assumes ``x-_{j+1} = F x+_j`` for the
stored estimates, which does not hold across the closed-loop resets (the estimates live
in a different reference trajectory at every node); the recursion above is its
algebra with the resets accounted for.
"""
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from . import _filter_kernels


@dataclass
class SmoothedResult:
    """Smoothed solution.

    Attributes
    ----------
    time : ndarray, shape (n,)
    states : ndarray, shape (n, 10)
        Smoothed navigation states (``ins._kernels`` layout).
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


def rts_errors(fwd):
    """The backward recursion: smoothed errors ``xs+`` (m, 21) and covariances (m, 21, 21)."""
    m, n = len(fwd.node_rows), fwd.P_post.shape[-1]     # n = N_STATES for the INS filter
    xs = np.zeros((m, n))
    Ps = np.empty((m, n, n))
    Ps[-1] = fwd.P_post[-1]
    for j in range(m - 2, -1, -1):
        # A = P+_j Phi^T (P-)^-1  <=>  A^T = (P-)^-1 Phi P+_j  (P- symmetric positive)
        cf = cho_factor(fwd.P_prior[j + 1])
        A = cho_solve(cf, fwd.Phi[j + 1] @ fwd.P_post[j]).T
        xs[j] = A @ (fwd.dx[j + 1] + xs[j + 1])
        Pj = fwd.P_post[j] + A @ (Ps[j + 1] - fwd.P_prior[j + 1]) @ A.T
        Ps[j] = 0.5 * (Pj + Pj.T)
    return xs, Ps


def smooth(fwd, *, in_place=False):
    """Smoothed trajectory at every IMU epoch from a :class:`ins.filter.ForwardResult`.

    With ``in_place=True`` the forward states are overwritten (saves one copy of the
    trajectory); otherwise they are left as they are.
    """
    xs, Ps = rts_errors(fwd)
    states = fwd.states if in_place else fwd.states.copy()
    x_before = fwd.dx + xs
    _filter_kernels.correct_between_nodes(states, fwd.time, fwd.node_rows, xs, x_before)
    return SmoothedResult(time=fwd.time, states=states, node_rows=fwd.node_rows, x_after=xs,
                          P=Ps, sensors=fwd.sensors + xs[:, 9:21])
