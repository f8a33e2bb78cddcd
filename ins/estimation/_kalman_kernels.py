"""Compiled covariance kernels of the GNSS/INS filter and smoother (private).

The run's per-node linear algebra on ``n x n`` covariances (``n`` the number of error
states of the layout: 21, 27, 33 ...), as numba loops, so that a node costs a few tens
of microseconds instead of the Python and scipy call overhead of a dozen small numpy
operations:

- :func:`predict`: ``Phi = I + A + A^2/2 + A^3/6``, ``Q_d = (Phi GQG Phi^T + GQG) dt/2``
  (:func:`ins.estimation.error_model.discretize`) and ``P- = Phi P Phi^T + Q_d``
  (filterpy's ``predict``, the tests' reference);
- :func:`joseph_update`: the Kalman update by one Cholesky factorization of
  ``S = H P H^T + R``, innovation test, Joseph-form posterior
  (:func:`ins.estimation.measurements.kalman_update`; filterpy's ``update`` is the
  tests' reference);
- :func:`rts_step`: one step of the closed-loop RTS recursion
  (:func:`ins.estimation.smoother.rts_errors`).

The matrix products go to BLAS (numba's ``@``, through scipy's BLAS: 3-5 times faster
than plain loops at n = 21..33); the Cholesky factorizations and triangular solves are
loops.  Every function takes C-contiguous float64 arrays.
"""
import math

import numba as nb
import numpy as np

from ins.estimation.error_model import fill_interval


@nb.njit(cache=True)
def predict(A, GQG, dt, P):
    """Transition, process noise and prior covariance of one node interval.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        ``int F dt`` over the interval (:func:`ins.estimation.error_model.interval_matrix`).
    GQG : ndarray, shape (n, n)
        Continuous ``G Q G^T``.
    dt : float
        Interval, s.
    P : ndarray, shape (n, n)
        Covariance at the start of the interval.

    Returns
    -------
    Phi, Qd, P_prior : ndarray, shape (n, n)
    """
    n = A.shape[0]
    A2 = A @ A
    Phi = np.eye(n) + A + 0.5 * A2 + (A2 @ A) / 6.0
    PhiT = np.ascontiguousarray(Phi.T)
    Qd = 0.5 * dt * ((Phi @ GQG) @ PhiT + GQG)
    return Phi, Qd, (Phi @ P) @ PhiT + Qd


@nb.njit(cache=True)
def interval(lat, h, v_n, acc, dt, decay_s, n, gyro_mis, accel_mis, clock):
    """``A = int F dt`` over a node interval (n x n), as
    :func:`ins.estimation.error_model.interval_matrix` (its reference) from the
    integrals ``acc`` of :func:`ins.estimation._filter_kernels.propagate_rows` (rows 0-2
    ``S_C``, 3-5 ``S_Cw``, 6-8 ``S_Cf``, 9 ``sum C_nb dvel``, 10-12 ``S_CNw``, 13-15
    ``S_CNf``); ``gyro_mis``, ``accel_mis``, ``clock``: first index of those groups,
    or -1."""
    A = np.zeros((n, n))
    fill_interval(A, lat, h, v_n[0], v_n[1], v_n[2], acc[9, 0] / dt, acc[9, 1] / dt,
                  acc[9, 2] / dt, acc, dt, decay_s, gyro_mis, accel_mis, clock)
    return A


@nb.njit(cache=True)
def node_predict(lat, h, v_n, acc, dt, decay_s, gyro_mis, accel_mis, clock, GQG, P):
    """:func:`interval` then :func:`predict`: ``(Phi, Qd, P_prior)`` of a node."""
    A = interval(lat, h, v_n, acc, dt, decay_s, P.shape[0], gyro_mis, accel_mis, clock)
    return predict(A, GQG, dt, P)


@nb.njit(cache=True, inline="always")
def _cholesky(S, L):
    """Lower Cholesky factor of ``S`` into ``L``; False when ``S`` is not positive
    definite (or not finite)."""
    m = S.shape[0]
    for i in range(m):
        for j in range(m):
            L[i, j] = 0.0
    for j in range(m):
        d = S[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0 or not math.isfinite(d):
            return False
        d = math.sqrt(d)
        L[j, j] = d
        for i in range(j + 1, m):
            s = S[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
    return True


@nb.njit(cache=True, inline="always")
def _cho_solve_cols(L, B):
    """``B <- S^-1 B`` in place (``S = L L^T``), column by column."""
    m = L.shape[0]
    for c in range(B.shape[1]):
        for i in range(m):                      # L y = b
            s = B[i, c]
            for k in range(i):
                s -= L[i, k] * B[k, c]
            B[i, c] = s / L[i, i]
        for i in range(m - 1, -1, -1):          # L^T x = y
            s = B[i, c]
            for k in range(i + 1, m):
                s -= L[k, i] * B[k, c]
            B[i, c] = s / L[i, i]


@nb.njit(cache=True)
def joseph_update(P, H, R, z, threshold):
    """Kalman update of ``P`` by the measurement ``(H, R)`` with innovation ``z``
    (predicted minus measured).

    Returns
    -------
    status : int
        0 accepted, 1 rejected by the test ``z^T S^-1 z <= threshold``, 2 ``S`` not
        positive definite (or not finite).
    dx : ndarray, shape (n,)
        Error-state estimate ``K z`` (zeros unless accepted).
    P_post : ndarray, shape (n, n)
        ``(I - K H) P (I - K H)^T + K R K^T`` (a copy of ``P`` unless accepted).
    nis : float
        ``z^T S^-1 z`` (NaN when ``S`` is not positive definite).
    S : ndarray, shape (m, m)
        Innovation covariance ``H P H^T + R`` (symmetrized).
    """
    m, n = H.shape
    PHt = P @ np.ascontiguousarray(H.T)
    S = H @ PHt + R
    for i in range(m):
        for j in range(i):
            s = 0.5 * (S[i, j] + S[j, i])
            S[i, j] = s
            S[j, i] = s
    dx = np.zeros(n)
    L = np.empty((m, m))
    if not _cholesky(S, L):
        return 2, dx, P.copy(), np.nan, S
    nis = 0.0
    w = np.empty(m)
    for i in range(m):
        s = z[i]
        for k in range(i):
            s -= L[i, k] * w[k]
        w[i] = s / L[i, i]
        nis += w[i] * w[i]
    if not nis <= threshold:
        return 1, dx, P.copy(), nis, S
    Kt = np.ascontiguousarray(PHt.T)            # K^T = S^-1 (P H^T)^T
    _cho_solve_cols(L, Kt)
    K = np.ascontiguousarray(Kt.T)
    dx = K @ np.ascontiguousarray(z)
    IKH = np.eye(n) - K @ H
    Pn = (IKH @ P) @ np.ascontiguousarray(IKH.T) + (K @ R) @ Kt
    return 0, dx, Pn, nis, S


@nb.njit(cache=True)
def rts_step(P_prior_next, Phi_next, P_post, Ps_next, v):
    """One backward step of the closed-loop RTS recursion
    (:mod:`ins.estimation.smoother`): ``A = P+_j Phi^T (P-_{j+1})^-1``,
    ``xs = A v`` (``v = dx_{j+1} + xs+_{j+1}``) and
    ``Ps_j = P+_j + A (Ps_{j+1} - P-_{j+1}) A^T`` (symmetrized).

    Returns ``(ok, xs, Ps_j)``; ``ok`` False when ``P-_{j+1}`` is not positive definite.
    """
    n = P_post.shape[0]
    L = np.empty((n, n))
    xs = np.zeros(n)
    if not _cholesky(P_prior_next, L):
        return False, xs, P_post.copy()
    At = Phi_next @ P_post                      # A^T = (P-)^-1 Phi P+
    _cho_solve_cols(L, At)
    A = np.ascontiguousarray(At.T)
    xs = A @ np.ascontiguousarray(v)
    Pj = (A @ (Ps_next - P_prior_next)) @ At
    for i in range(n):
        for j in range(i + 1):
            s = P_post[i, j] + 0.5 * (Pj[i, j] + Pj[j, i])
            Pj[i, j] = s
            Pj[j, i] = s
    return True, xs, Pj
