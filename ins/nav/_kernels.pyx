"""Compiled loops of the strapdown mechanization (private; hot paths only; Cython).

The step itself is C inline code in ``ins/nav/_strapdown.pxd`` (shared with
:mod:`ins.estimation.core._filter_kernels`), the Earth model that of ``ins/nav/_earth.pxd``
(the formulas of :mod:`ins.nav.earth`; ``tests/test_native_earth.py`` holds the two
equal through :func:`earth_terms`).

State vector layout (float64[10]): lat, lon (rad), h (m), vN, vE, vD (m/s),
q_nb = qx, qy, qz, qw (scalar last).
"""
from ins.nav._earth cimport earth_rate, gravity, radii, transport_rate
from ins.nav cimport _strapdown as sd

#: Length of the navigation state vector (layout above).
N_STATE = sd.N_STATE


def quat_to_dcm_rows(double qx, double qy, double qz, double qw, double[:] c):
    """Direction-cosine matrix of a unit quaternion, row by row.

    Parameters
    ----------
    qx, qy, qz, qw : float
        Unit quaternion ``q_nb``, scalar last.
    c : ndarray of float64, shape (>= 9,), writable
        Receives ``C_nb`` row by row: ``c[3 i + j] = C[i, j]`` (the same as
        :func:`ins.nav.rotation.quat_to_dcm`).
    """
    cdef double m[9]
    cdef Py_ssize_t i
    if c.shape[0] < 9:
        raise ValueError(f"c must hold 9 values, got {c.shape[0]}")
    sd.quat_to_dcm_rows(qx, qy, qz, qw, m)
    for i in range(9):
        c[i] = m[i]


def mechanize_rows(const double[:] time, const double[:, :] dtheta_b,
                   const double[:, :] dvel_b, Py_ssize_t k0, Py_ssize_t k1,
                   double[:] state, double[:, :] out):
    """Integrate IMU rows ``k0 .. k1-1`` in place on ``state``; row k spans (t[k-1], t[k]].

    Releases the GIL while it runs.

    Parameters
    ----------
    time : ndarray of float64, shape (n,)
        Epochs of the increments, s (each stamped at the end of its interval).
    dtheta_b, dvel_b : ndarray of float64, shape (n, 3)
        Angle (rad) and velocity (m/s) increments in the body frame ``b``; strided or
        read-only arrays are accepted.
    k0, k1 : int
        First and one-past-last row integrated; ``1 <= k0``, ``k1 <= n``.  The previous
        increment of row ``k0`` is row ``k0 - 1``.
    state : ndarray of float64, shape (10,), writable
        Navigation state at ``time[k0 - 1]`` (layout above); receives the state at
        ``time[k1 - 1]``.
    out : ndarray of float64, shape (>= k1 - k0, 10), writable
        ``out[k - k0]`` receives the state at ``time[k]``.
    """
    cdef double s[10]
    cdef double c[9]
    cdef double th_p[3]
    cdef double dv_p[3]
    cdef double th[3]
    cdef double dv[3]
    cdef Py_ssize_t k, i
    _check_rows(time, dtheta_b, dvel_b, k0, k1)
    if state.shape[0] < N_STATE or (k1 > k0 and (out.shape[0] < k1 - k0
                                                   or out.shape[1] < N_STATE)):
        raise ValueError("state must hold 10 values and out (k1 - k0, 10)")
    with nogil:
        for i in range(sd.N_STATE):
            s[i] = state[i]
        for k in range(k0, k1):
            for i in range(3):
                th_p[i] = dtheta_b[k - 1, i]
                dv_p[i] = dvel_b[k - 1, i]
                th[i] = dtheta_b[k, i]
                dv[i] = dvel_b[k, i]
            sd.step(s, c, th_p, dv_p, th, dv, time[k] - time[k - 1])
            for i in range(sd.N_STATE):
                out[k - k0, i] = s[i]
        for i in range(sd.N_STATE):
            state[i] = s[i]


cdef _check_rows(const double[:] time, const double[:, :] dtheta_b,
                 const double[:, :] dvel_b, Py_ssize_t k0, Py_ssize_t k1):
    """ValueError unless rows k0-1 .. k1-1 exist in the three arrays (3 columns)."""
    cdef Py_ssize_t n = time.shape[0]
    if dtheta_b.shape[0] != n or dvel_b.shape[0] != n:
        raise ValueError(f"time, dtheta_b and dvel_b must have the same number of rows, got "
                         f"{n}, {dtheta_b.shape[0]} and {dvel_b.shape[0]}")
    if dtheta_b.shape[1] < 3 or dvel_b.shape[1] < 3:
        raise ValueError("dtheta_b and dvel_b must have 3 columns")
    if k1 > k0 and (k0 < 1 or k1 > n):
        raise ValueError(f"rows {k0} .. {k1 - 1} outside 1 .. {n - 1}")


def earth_terms(const double[:] lat, const double[:] h, const double[:] v_north,
                const double[:] v_east, double[:, :] out):
    """The Earth-model C functions of ``ins/nav/_earth.pxd`` at many points (for tests).

    Parameters
    ----------
    lat, h, v_north, v_east : ndarray of float64, shape (n,)
        Latitude (rad), ellipsoidal height (m), north and east velocity (m/s).
    out : ndarray of float64, shape (n, 8), writable
        Receives per point: meridian and prime-vertical radii (m), normal gravity (m/s^2),
        Earth rate north and down (rad/s, east is 0), transport rate ``w_en_n``
        north, east, down (rad/s).
    """
    cdef Py_ssize_t i, n = lat.shape[0]
    if h.shape[0] != n or v_north.shape[0] != n or v_east.shape[0] != n \
            or out.shape[0] != n or out.shape[1] < 8:
        raise ValueError("lat, h, v_north, v_east must have the same length n and out (n, 8)")
    cdef double rm, rn, wn, wd, tn, te, td
    with nogil:
        for i in range(n):
            radii(lat[i], &rm, &rn)
            earth_rate(lat[i], &wn, &wd)
            transport_rate(lat[i], h[i], v_north[i], v_east[i], &tn, &te, &td)
            out[i, 0] = rm
            out[i, 1] = rn
            out[i, 2] = gravity(lat[i], h[i])
            out[i, 3] = wn
            out[i, 4] = wd
            out[i, 5] = tn
            out[i, 6] = te
            out[i, 7] = td
