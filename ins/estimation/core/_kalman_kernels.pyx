"""Compiled covariance kernels of the GNSS/INS filter and smoother (private).

The run's per-node linear algebra on ``n x n`` covariances (``n`` the number of error
states of the layout: 21, 27, 33 ...), as C loops, so that a node costs a few tens of
microseconds instead of the Python call overhead of a dozen small numpy operations:

- :func:`predict`: ``Phi = I + A + A^2/2 + A^3/6``, ``Q_d = (Phi GQG Phi^T + GQG) dt/2``
  (:func:`ins.estimation.core.error_model.discretize`) and ``P- = Phi P Phi^T + Q_d``
  (filterpy's ``predict``, the tests' reference);
- :func:`joseph_update`: the Kalman update by one Cholesky factorization of
  ``S = H P H^T + R``, innovation test, Joseph-form posterior
  (:func:`ins.estimation.core.measurements.kalman_update`; filterpy's ``update`` is the
  tests' reference);
- :func:`rts_step`: one step of the closed-loop RTS recursion
  (:func:`ins.estimation.core.smoother.rts_errors`);
- :func:`fill_navigation` and :func:`fill_interval`: the error model's system matrix
  integrated over an interval, the one source of those formulas
  (:mod:`ins.estimation.core.error_model` calls them from Python).

Every matrix argument is a C-contiguous float64 array (read-only ones are accepted);
results are new arrays.  Compiled by Cython at install (``setup.py``), as every kernel of the
package: nothing is compiled at run time (memory and start-up time, issues 26 and 35).
"""
import numpy as np

from libc.math cimport cos, isfinite, sin, sqrt
from libc.stdlib cimport free, malloc

from ins.nav._earth cimport OMEGA_IE, earth_rate, gravity, radii, transport_rate


# ---------------------------------------------------------------------------------------
# small dense products on row-major buffers (i-k-j order: the inner loop vectorizes)

cdef inline void _mm(const double *X, const double *Y, double *Z, Py_ssize_t n,
                     Py_ssize_t k, Py_ssize_t m) noexcept nogil:
    """``Z (n x m) = X (n x k) @ Y (k x m)``."""
    cdef Py_ssize_t i, j, p
    cdef double x
    for i in range(n * m):
        Z[i] = 0.0
    for i in range(n):
        for p in range(k):
            x = X[i * k + p]
            if x != 0.0:
                for j in range(m):
                    Z[i * m + j] += x * Y[p * m + j]


cdef inline void _transpose(const double *X, double *Y, Py_ssize_t n,
                            Py_ssize_t m) noexcept nogil:
    """``Y (m x n) = X^T`` with ``X`` (n x m)."""
    cdef Py_ssize_t i, j
    for i in range(n):
        for j in range(m):
            Y[j * n + i] = X[i * m + j]


cdef inline void _sandwich(const double *T, const double *M, double *Z, double *w1,
                           double *w2, Py_ssize_t n) noexcept nogil:
    """``Z = T M T^T`` (all n x n), as ``((T (T M)^T))^T`` so that both products skip the
    zeros of ``T`` (a transition or ``I - K H``: mostly zeros); w1, w2: work buffers."""
    _mm(T, M, w1, n, n, n)
    _transpose(w1, w2, n, n)
    _mm(T, w2, w1, n, n, n)
    _transpose(w1, Z, n, n)


cdef inline bint _cholesky(const double *S, double *L, Py_ssize_t m) noexcept nogil:
    """Lower Cholesky factor of ``S`` (m x m) into ``L``; False when ``S`` is not positive
    definite (or not finite)."""
    cdef Py_ssize_t i, j, k
    cdef double d, s
    for i in range(m * m):
        L[i] = 0.0
    for j in range(m):
        d = S[j * m + j]
        for k in range(j):
            d -= L[j * m + k] * L[j * m + k]
        if not d > 0.0 or not isfinite(d):
            return False
        d = sqrt(d)
        L[j * m + j] = d
        for i in range(j + 1, m):
            s = S[i * m + j]
            for k in range(j):
                s -= L[i * m + k] * L[j * m + k]
            L[i * m + j] = s / d
    return True


cdef inline void _cho_solve_cols(const double *L, double *B, Py_ssize_t m,
                                 Py_ssize_t c) noexcept nogil:
    """``B <- S^-1 B`` in place (``S = L L^T``, m x m; ``B`` m x c, each column one
    right-hand side), row by row so that the inner loop runs along the columns."""
    cdef Py_ssize_t i, k, j
    cdef double a, d
    for i in range(m):                          # L Y = B
        for k in range(i):
            a = L[i * m + k]
            for j in range(c):
                B[i * c + j] -= a * B[k * c + j]
        d = L[i * m + i]
        for j in range(c):
            B[i * c + j] /= d
    for i in range(m - 1, -1, -1):              # L^T X = Y
        for k in range(i + 1, m):
            a = L[k * m + i]
            for j in range(c):
                B[i * c + j] -= a * B[k * c + j]
        d = L[i * m + i]
        for j in range(c):
            B[i * c + j] /= d


cdef double *_alloc(Py_ssize_t count) except NULL:
    cdef double *p = <double *> malloc(max(count, 1) * sizeof(double))
    if p == NULL:
        raise MemoryError()
    return p


def _square(name, a):
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise ValueError(f"{name} must be square (n, n), got shape {a.shape}")


# ---------------------------------------------------------------------------------------
# the error model's transition over an interval

cdef void _fill_navigation(double *F, Py_ssize_t n, double lat, double h, double vn,
                           double ve, double vd, double fn, double fe, double fd,
                           double dt) noexcept nogil:
    """Navigation block (9 x 9) of F times dt into the row-major n x n buffer F."""
    cdef double rm, rn, rmh, rnh, w, s, c, t, sec2, g
    cdef double wn, wd, tn, te, td, xn, xe, xd
    cdef Py_ssize_t i
    radii(lat, &rm, &rn)
    rmh = rm + h
    rnh = rn + h
    w = OMEGA_IE
    s = sin(lat)
    c = cos(lat)
    t = s / c
    sec2 = 1.0 / (c * c)
    g = gravity(lat, h)
    F[0 * n + 0] = -vd / rmh * dt
    F[0 * n + 2] = vn / rmh * dt
    F[1 * n + 0] = ve * t / rnh * dt
    F[1 * n + 1] = -(vd + vn * t) / rnh * dt
    F[1 * n + 2] = ve / rnh * dt
    for i in range(3):
        F[i * n + 3 + i] = dt
    F[3 * n + 0] = (-2 * ve * w * c / rmh - ve * ve * sec2 / (rmh * rnh)) * dt
    F[3 * n + 2] = (vn * vd / (rmh * rmh) - ve * ve * t / (rnh * rnh)) * dt
    F[4 * n + 0] = (2 * w * (vn * c - vd * s) / rmh + vn * ve * sec2 / (rmh * rnh)) * dt
    F[4 * n + 2] = ((ve * vd + vn * ve * t) / (rnh * rnh)) * dt
    F[5 * n + 0] = (2 * w * ve * s / rmh) * dt
    F[5 * n + 2] = (-ve * ve / (rnh * rnh) - vn * vn / (rmh * rmh)
                    + 2 * g / (sqrt(rm * rn) + h)) * dt
    F[3 * n + 3] = vd / rmh * dt
    F[3 * n + 4] = -2 * (w * s + ve * t / rnh) * dt
    F[3 * n + 5] = vn / rmh * dt
    F[4 * n + 3] = (2 * w * s + ve * t / rnh) * dt
    F[4 * n + 4] = (vd + vn * t) / rnh * dt
    F[4 * n + 5] = (2 * w * c + ve / rnh) * dt
    F[5 * n + 3] = -2 * vn / rmh * dt
    F[5 * n + 4] = -2 * (w * c + ve / rnh) * dt
    F[3 * n + 7] = -fd * dt                            # [f_n x]
    F[3 * n + 8] = fe * dt
    F[4 * n + 6] = fd * dt
    F[4 * n + 8] = -fn * dt
    F[5 * n + 6] = -fe * dt
    F[5 * n + 7] = fn * dt
    F[6 * n + 0] = -w * s / rmh * dt
    F[6 * n + 2] = ve / (rnh * rnh) * dt
    F[7 * n + 2] = -vn / (rmh * rmh) * dt
    F[8 * n + 0] = (-w * c / rmh - ve * sec2 / (rmh * rnh)) * dt
    F[8 * n + 2] = -ve * t / (rnh * rnh) * dt
    F[6 * n + 4] = 1.0 / rnh * dt
    F[7 * n + 3] = -1.0 / rmh * dt
    F[8 * n + 4] = -t / rnh * dt
    earth_rate(lat, &wn, &wd)                          # -[w_in_n x]
    transport_rate(lat, h, vn, ve, &tn, &te, &td)
    xn = wn + tn
    xe = te
    xd = wd + td
    F[6 * n + 7] = xd * dt
    F[6 * n + 8] = -xe * dt
    F[7 * n + 6] = -xd * dt
    F[7 * n + 8] = xn * dt
    F[8 * n + 6] = xe * dt
    F[8 * n + 7] = -xn * dt


cdef void _fill_interval(double *A, Py_ssize_t n, double lat, double h, double vn,
                         double ve, double vd, double fn, double fe, double fd,
                         const double *S, double dt, double decay_s, Py_ssize_t gyro_mis,
                         Py_ssize_t accel_mis, Py_ssize_t clock) noexcept nogil:
    """``A = int F dt`` into the zeroed row-major n x n buffer A (S: 16 x 3 row-major)."""
    cdef Py_ssize_t i, j
    _fill_navigation(A, n, lat, h, vn, ve, vd, fn, fe, fd, dt)
    for i in range(3):
        for j in range(3):
            A[(3 + i) * n + 12 + j] = S[i * 3 + j]             # v, b_a: S_C
            A[(3 + i) * n + 18 + j] = S[(6 + i) * 3 + j]       # v, s_a: S_Cf
            A[(6 + i) * n + 9 + j] = -S[i * 3 + j]             # phi, b_g: -S_C
            A[(6 + i) * n + 15 + j] = -S[(3 + i) * 3 + j]      # phi, s_g: -S_Cw
            if gyro_mis >= 0:
                A[(6 + i) * n + gyro_mis + j] = -S[(10 + i) * 3 + j]
            if accel_mis >= 0:
                A[(3 + i) * n + accel_mis + j] = S[(13 + i) * 3 + j]
    for i in range(9, 21):
        A[i * n + i] = -dt / decay_s
    if clock >= 0:                                     # receiver clock: bias' = drift
        A[clock * n + clock + 1] = dt


def fill_navigation(double[:, ::1] F not None, double lat, double h, double vn, double ve,
                    double vd, double fn, double fe, double fd, double dt):
    """Write the navigation block of F (:func:`ins.estimation.core.error_model.navigation_matrix`)
    times ``dt`` into ``F[0:9, 0:9]`` (the other elements of that block are left as they
    are: zeros).

    Parameters
    ----------
    F : ndarray, shape (n, n), n >= 9, C-contiguous float64 (written)
    lat, h : float
        Latitude (rad), ellipsoidal height (m).
    vn, ve, vd : float
        Velocity NED, m/s.
    fn, fe, fd : float
        Specific force in n, m/s^2.
    dt : float
        Interval, s (1: the system matrix itself).
    """
    if F.shape[0] < 9 or F.shape[1] != F.shape[0]:
        raise ValueError(f"F must be square with n >= 9, got shape ({F.shape[0]}, "
                         f"{F.shape[1]})")
    _fill_navigation(&F[0, 0], F.shape[0], lat, h, vn, ve, vd, fn, fe, fd, dt)


def fill_interval(double[:, ::1] A not None, double lat, double h, double vn, double ve,
                  double vd, double fn, double fe, double fd, const double[:, ::1] S not None,
                  double dt, double decay_s, Py_ssize_t gyro_mis, Py_ssize_t accel_mis,
                  Py_ssize_t clock):
    """Write ``A = int F dt`` (:func:`ins.estimation.core.error_model.interval_matrix`) into the
    zeroed ``A`` (n x n, n >= 21).

    ``S`` (16, 3): rows 0-2 ``S_C``, 3-5 ``S_Cw``, 6-8 ``S_Cf``, 10-12 ``S_CNw``, 13-15
    ``S_CNf`` (row 9 unused here); ``gyro_mis``, ``accel_mis``, ``clock``: first index of
    those groups or -1.  ``decay_s``: decay time of the sensor states (s; ``inf``: none).
    """
    cdef Py_ssize_t n = A.shape[0]
    if n < 21 or A.shape[1] != n:
        raise ValueError(f"A must be square with n >= 21, got shape ({n}, {A.shape[1]})")
    if S.shape[0] != 16 or S.shape[1] != 3:
        raise ValueError(f"S must have shape (16, 3), got ({S.shape[0]}, {S.shape[1]})")
    for k, name in ((gyro_mis, "gyro_mis"), (accel_mis, "accel_mis"), (clock, "clock")):
        if k >= 0 and k + 3 - (name == "clock") > n:
            raise ValueError(f"{name} = {k} does not fit n = {n} states")
    _fill_interval(&A[0, 0], n, lat, h, vn, ve, vd, fn, fe, fd, &S[0, 0], dt, decay_s,
                   gyro_mis, accel_mis, clock)


# ---------------------------------------------------------------------------------------
# predict

cdef void _predict(const double *A, const double *GQG, double dt, const double *P,
                   double *Phi, double *Qd, double *Pp, double *w1, double *w2,
                   Py_ssize_t n) noexcept nogil:
    """Phi, Qd, P- of an interval; w1, w2: n x n work buffers."""
    cdef Py_ssize_t i
    _mm(A, A, w1, n, n, n)                             # A^2
    _mm(w1, A, w2, n, n, n)                            # A^3
    for i in range(n * n):
        Phi[i] = A[i] + 0.5 * w1[i] + w2[i] / 6.0
    for i in range(n):
        Phi[i * n + i] += 1.0
    _sandwich(Phi, GQG, Qd, w1, w2, n)                 # Phi GQG Phi^T
    for i in range(n * n):
        Qd[i] = 0.5 * dt * (Qd[i] + GQG[i])
    _sandwich(Phi, P, Pp, w1, w2, n)                   # Phi P Phi^T
    for i in range(n * n):
        Pp[i] += Qd[i]


def predict(const double[:, ::1] A not None, const double[:, ::1] GQG not None, double dt,
            const double[:, ::1] P not None):
    """Transition, process noise and prior covariance of one node interval.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        ``int F dt`` over the interval (:func:`ins.estimation.core.error_model.interval_matrix`).
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
    cdef Py_ssize_t n = A.shape[0]
    for name, M in (("A", A), ("GQG", GQG), ("P", P)):
        if M.shape[0] != n or M.shape[1] != n:
            raise ValueError(f"{name} must have shape ({n}, {n}), got "
                             f"({M.shape[0]}, {M.shape[1]})")
    Phi = np.empty((n, n))
    Qd = np.empty((n, n))
    Pp = np.empty((n, n))
    cdef double[:, ::1] phi_v = Phi, qd_v = Qd, pp_v = Pp
    cdef double *work = _alloc(2 * n * n)
    with nogil:
        _predict(&A[0, 0], &GQG[0, 0], dt, &P[0, 0], &phi_v[0, 0], &qd_v[0, 0],
                 &pp_v[0, 0], work, work + n * n, n)
    free(work)
    return Phi, Qd, Pp


def interval(double lat, double h, const double[::1] v_n not None,
             const double[:, ::1] acc not None, double dt, double decay_s, Py_ssize_t n,
             Py_ssize_t gyro_mis, Py_ssize_t accel_mis, Py_ssize_t clock):
    """``A = int F dt`` over a node interval (n x n), as
    :func:`ins.estimation.core.error_model.interval_matrix` (its reference) from the
    integrals ``acc`` of :func:`ins.estimation.core._filter_kernels.propagate_rows` (rows 0-2
    ``S_C``, 3-5 ``S_Cw``, 6-8 ``S_Cf``, 9 ``sum C_nb dvel``, 10-12 ``S_CNw``, 13-15
    ``S_CNf``); ``gyro_mis``, ``accel_mis``, ``clock``: first index of those groups,
    or -1."""
    A = np.zeros((n, n))
    fill_interval(A, lat, h, v_n[0], v_n[1], v_n[2], acc[9, 0] / dt, acc[9, 1] / dt,
                  acc[9, 2] / dt, acc, dt, decay_s, gyro_mis, accel_mis, clock)
    return A


def node_predict(double lat, double h, const double[::1] v_n not None,
                 const double[:, ::1] acc not None, double dt, double decay_s,
                 Py_ssize_t gyro_mis, Py_ssize_t accel_mis, Py_ssize_t clock,
                 const double[:, ::1] GQG not None, const double[:, ::1] P not None):
    """:func:`interval` then :func:`predict`: ``(Phi, Qd, P_prior)`` of a node."""
    return predict(interval(lat, h, v_n, acc, dt, decay_s, P.shape[0], gyro_mis, accel_mis,
                            clock), GQG, dt, P)


# ---------------------------------------------------------------------------------------
# update

def joseph_update(const double[:, ::1] P not None, const double[:, ::1] H not None,
                  const double[:, ::1] R not None, const double[::1] z not None,
                  double threshold):
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
    cdef Py_ssize_t m = H.shape[0], n = H.shape[1], i, j, k
    if P.shape[0] != n or P.shape[1] != n:
        raise ValueError(f"P must have shape ({n}, {n}) for H of shape ({m}, {n}), got "
                         f"({P.shape[0]}, {P.shape[1]})")
    if R.shape[0] != m or R.shape[1] != m or z.shape[0] != m:
        raise ValueError(f"R must have shape ({m}, {m}) and z ({m},), got "
                         f"({R.shape[0]}, {R.shape[1]}) and ({z.shape[0]},)")
    S_arr = np.empty((m, m))
    dx_arr = np.zeros(n)
    cdef double[:, ::1] S = S_arr
    cdef double[::1] dx = dx_arr
    cdef double s, nis
    cdef double *Kt = _alloc(m * n)        # (P H^T)^T = H P^T (m x n), then K^T
    cdef double *Pt = _alloc(n * max(n, m))    # P^T (n x n), then P H^T (n x m)
    cdef double *L = _alloc(m * m)
    cdef double *wv = _alloc(m)
    try:
        _transpose(&P[0, 0], Pt, n, n)
        _mm(&H[0, 0], Pt, Kt, m, n, n)                 # (P H^T)^T = H P^T
        _transpose(Kt, Pt, m, n)                       # P H^T (n x m)
        _mm(&H[0, 0], Pt, &S[0, 0], m, n, m)           # H (P H^T)
        for i in range(m):
            for j in range(m):
                S[i, j] += R[i, j]
        for i in range(m):
            for j in range(i):
                s = 0.5 * (S[i, j] + S[j, i])
                S[i, j] = s
                S[j, i] = s
        if not _cholesky(&S[0, 0], L, m):
            return 2, dx_arr, np.array(P), np.nan, S_arr
        nis = 0.0
        for i in range(m):
            s = z[i]
            for k in range(i):
                s -= L[i * m + k] * wv[k]
            wv[i] = s / L[i * m + i]
            nis += wv[i] * wv[i]
        if not nis <= threshold:
            return 1, dx_arr, np.array(P), nis, S_arr
        Pn = _joseph(P, H, R, z, L, Kt, dx, m, n)
        return 0, dx_arr, Pn, nis, S_arr
    finally:
        free(Kt)
        free(Pt)
        free(L)
        free(wv)


cdef object _joseph(const double[:, ::1] P, const double[:, ::1] H, const double[:, ::1] R,
                    const double[::1] z, const double *L, double *Kt, double[::1] dx,
                    Py_ssize_t m, Py_ssize_t n):
    """K = P H^T S^-1, dx = K z, Joseph posterior (Kt holds (P H^T)^T on entry, K^T on
    return)."""
    cdef Py_ssize_t i, j, k
    Pn_arr = np.empty((n, n))
    cdef double[:, ::1] Pn = Pn_arr
    cdef double *IKH = _alloc(n * n)
    cdef double *W = _alloc(n * n)
    cdef double *W2 = _alloc(n * n)
    cdef double *KR = _alloc(n * m)
    cdef double *K = _alloc(n * m)
    with nogil:
        _cho_solve_cols(L, Kt, m, n)                   # K^T = S^-1 (P H^T)^T
        _transpose(Kt, K, m, n)                        # K (n x m)
        for i in range(n):
            dx[i] = 0.0
            for k in range(m):
                dx[i] += K[i * m + k] * z[k]
        _mm(K, &H[0, 0], IKH, n, m, n)                 # K H
        for i in range(n * n):
            IKH[i] = -IKH[i]
        for i in range(n):
            IKH[i * n + i] += 1.0                      # I - K H
        _sandwich(IKH, &P[0, 0], &Pn[0, 0], W, W2, n)  # (I - K H) P (I - K H)^T
        _mm(K, &R[0, 0], KR, n, m, m)                  # K R
        _mm(KR, Kt, W, n, m, n)                        # K R K^T
        for i in range(n):
            for j in range(n):
                Pn[i, j] += W[i * n + j]
    free(IKH)
    free(W)
    free(W2)
    free(KR)
    free(K)
    return Pn_arr


# ---------------------------------------------------------------------------------------
# smoother

def rts_step(const double[:, ::1] P_prior_next not None, const double[:, ::1] Phi_next not None,
             const double[:, ::1] P_post not None, const double[:, ::1] Ps_next not None,
             const double[::1] v not None):
    """One backward step of the closed-loop RTS recursion
    (:mod:`ins.estimation.core.smoother`): ``A = P+_j Phi^T (P-_{j+1})^-1``,
    ``xs = A v`` (``v = dx_{j+1} + xs+_{j+1}``) and
    ``Ps_j = P+_j + A (Ps_{j+1} - P-_{j+1}) A^T`` (symmetrized).

    Returns ``(ok, xs, Ps_j)``; ``ok`` False when ``P-_{j+1}`` is not positive definite.
    """
    cdef Py_ssize_t n = P_post.shape[0], i, j
    for name, M in (("P_prior_next", P_prior_next), ("Phi_next", Phi_next),
                    ("Ps_next", Ps_next)):
        if M.shape[0] != n or M.shape[1] != n:
            raise ValueError(f"{name} must have shape ({n}, {n}), got "
                             f"({M.shape[0]}, {M.shape[1]})")
    if v.shape[0] != n:
        raise ValueError(f"v must have shape ({n},), got ({v.shape[0]},)")
    xs_arr = np.zeros(n)
    cdef double[::1] xs = xs_arr
    cdef double *L = _alloc(n * n)
    cdef double *At = _alloc(n * n)
    cdef double *D = _alloc(n * n)
    cdef double *W = _alloc(n * n)
    cdef double s
    cdef bint ok
    Pj_arr = np.empty((n, n))
    cdef double[:, ::1] Pj = Pj_arr
    with nogil:
        ok = _cholesky(&P_prior_next[0, 0], L, n)
        if ok:
            _mm(&Phi_next[0, 0], &P_post[0, 0], At, n, n, n)   # A^T = (P-)^-1 Phi P+
            _cho_solve_cols(L, At, n, n)
            _transpose(At, W, n, n)                            # W = A
            for i in range(n):
                s = 0.0
                for j in range(n):
                    s += W[i * n + j] * v[j]
                xs[i] = s
            for i in range(n * n):
                D[i] = Ps_next[i // n, i % n] - P_prior_next[i // n, i % n]
            _mm(W, D, L, n, n, n)                              # A (Ps - P-)
            _mm(L, At, &Pj[0, 0], n, n, n)                     # ... A^T
            for i in range(n):
                for j in range(i + 1):
                    s = P_post[i, j] + 0.5 * (Pj[i, j] + Pj[j, i])
                    Pj[i, j] = s
                    Pj[j, i] = s
    free(L)
    free(At)
    free(D)
    free(W)
    if not ok:
        return False, xs_arr, np.array(P_post)
    return True, xs_arr, Pj_arr


# ---------------------------------------------------------------------------------------
# the forward filter's per-node check of its covariances

def diag_std(const double[:, ::1] P_prior not None, const double[:, ::1] P_post not None,
             double rtol, double[::1] std not None):
    """``std = sqrt(max(diag(P_post), 0))`` when every variance of both covariances is
    at least ``-rtol * max(|prior variance|, |posterior variance|)`` of its state
    (rounding, :data:`ins.estimation.core.error_model.VARIANCE_RTOL`), as numpy computes it
    in :class:`ins.estimation.core.filter_stores.NodeStore`; returns False (``std`` left
    unspecified) when one is below or not finite: the caller then names it
    (:func:`ins.estimation.core.error_model.checked_std`)."""
    cdef Py_ssize_t n = P_post.shape[0], i
    cdef double a, b, floor
    if (P_post.shape[1] != n or P_prior.shape[0] != n or P_prior.shape[1] != n
            or std.shape[0] != n):
        raise ValueError(f"P_prior, P_post must have shape ({n}, {n}) and std ({n},)")
    for i in range(n):
        a = P_prior[i, i]
        b = P_post[i, i]
        floor = (a if a >= 0.0 else -a)
        if not floor >= (b if b >= 0.0 else -b):
            floor = (b if b >= 0.0 else -b)
        floor = floor * -rtol
        if not (a >= floor and b >= floor):
            return False
    for i in range(n):
        b = P_post[i, i]
        std[i] = sqrt(b if b >= 0.0 else 0.0)
    return True
