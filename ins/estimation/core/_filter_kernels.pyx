"""Compiled loops of the GNSS/INS filter (private; Cython): mechanization of the IMU rows
between two filter nodes with the current sensor-error estimates removed, accumulating
the integrals the covariance step needs, and the application of error-state corrections.

State layout of the navigation vector: that of :mod:`ins.nav._kernels`
(lat, lon, h, vN, vE, vD, qx, qy, qz, qw), named in :data:`ins.estimation.core.error_model.NAV`;
the 12 sensor estimates in the order of :data:`ins.estimation.core.error_model.SENSORS`; error
states in that of :data:`ins.estimation.core.error_model.STATE` (the loops below index them
element by element).  The mechanization step is the C inline code of
``ins/nav/_strapdown.pxd``, the one of :func:`ins.nav._kernels.mechanize_rows`.
"""
import numpy as np

from libc.math cimport cos, sqrt
from libc.stdint cimport int64_t

from ins.nav._earth cimport radii
from ins.nav cimport _strapdown as sd


cdef inline void _compensate(const double *raw, const double *bias, const double *scale,
                             double dt, double *out) noexcept nogil:
    """out = (raw - bias dt) / (1 + scale), per axis."""
    cdef int i
    for i in range(3):
        out[i] = (raw[i] - bias[i] * dt) / (1.0 + scale[i])


cdef inline void _unskew(double *th, const double *m) noexcept nogil:
    """th <- th - N(m) th (first-order removal of the non-orthogonality m)."""
    cdef double a = th[0] - (m[2] * th[1] + m[1] * th[2])
    cdef double b = th[1] - (m[2] * th[0] + m[0] * th[2])
    cdef double c = th[2] - (m[1] * th[0] + m[0] * th[1])
    th[0] = a
    th[1] = b
    th[2] = c


cdef _propagate(const double[:] time, const double[:, :] dtheta_b, const double[:, :] dvel_b,
                Py_ssize_t k0, Py_ssize_t k1, double[:] state, const double[:] sensors,
                double[:, :] out, double[:, :] acc, const double[:] mis, bint use_mis):
    cdef double s[10]
    cdef double sens[12]
    cdef double m[6]
    cdef double a[16][3]
    cdef double raw[4][3]
    cdef double c[9]
    cdef double th_p[3]
    cdef double dv_p[3]
    cdef double th[3]
    cdef double dv[3]
    cdef double dt, dt_p, cij, c0, c1, c2
    cdef Py_ssize_t k, i, j, n_acc = 16 if use_mis else 10
    cdef Py_ssize_t n = time.shape[0]
    if dtheta_b.shape[0] != n or dvel_b.shape[0] != n or dtheta_b.shape[1] < 3 \
            or dvel_b.shape[1] < 3:
        raise ValueError("time, dtheta_b (n, 3) and dvel_b (n, 3) must have the same rows")
    if k1 > k0 and (k0 < 1 or k1 > n):
        raise ValueError(f"rows {k0} .. {k1 - 1} outside 1 .. {n - 1}")
    if state.shape[0] < sd.N_STATE or sensors.shape[0] < 12 or mis.shape[0] < 6:
        raise ValueError("state must hold 10 values, sensors 12 and mis 6")
    if acc.shape[0] < n_acc or acc.shape[1] < 3:
        raise ValueError(f"acc must have shape ({n_acc}, 3), got "
                         f"({acc.shape[0]}, {acc.shape[1]})")
    if k1 > k0 and (out.shape[0] < k1 - k0 or out.shape[1] < sd.N_STATE):
        raise ValueError(f"out must have shape ({k1 - k0}, 10)")
    with nogil:
        for i in range(sd.N_STATE):
            s[i] = state[i]
        for i in range(12):
            sens[i] = sensors[i]
        for i in range(6):
            m[i] = mis[i]
        for i in range(n_acc):
            for j in range(3):
                a[i][j] = acc[i, j]
        for k in range(k0, k1):
            dt = time[k] - time[k - 1]
            dt_p = time[k - 1] - time[k - 2] if k >= 2 else dt
            # gyro bias (rad/s), accel bias (m/s^2), gyro scale, accel scale
            for i in range(3):
                raw[0][i] = dtheta_b[k - 1, i]
                raw[1][i] = dvel_b[k - 1, i]
                raw[2][i] = dtheta_b[k, i]
                raw[3][i] = dvel_b[k, i]
            _compensate(raw[0], &sens[0], &sens[6], dt_p, th_p)
            _compensate(raw[1], &sens[3], &sens[9], dt_p, dv_p)
            _compensate(raw[2], &sens[0], &sens[6], dt, th)
            _compensate(raw[3], &sens[3], &sens[9], dt, dv)
            if use_mis:
                _unskew(th_p, &m[0])
                _unskew(dv_p, &m[3])
                _unskew(th, &m[0])
                _unskew(dv, &m[3])
            sd.quat_to_dcm_rows(s[6], s[7], s[8], s[9], c)
            for i in range(3):
                for j in range(3):
                    cij = c[3 * i + j]
                    a[i][j] += cij * dt
                    a[3 + i][j] += cij * th[j]
                    a[6 + i][j] += cij * dv[j]
                    a[9][i] += cij * dv[j]
            if use_mis:
                # C N(v): column j of N(v) is (v_z, 0, v_x)... (N symmetric, zero diagonal)
                for i in range(3):
                    c0 = c[3 * i]
                    c1 = c[3 * i + 1]
                    c2 = c[3 * i + 2]
                    a[10 + i][0] += c1 * th[2] + c2 * th[1]
                    a[10 + i][1] += c0 * th[2] + c2 * th[0]
                    a[10 + i][2] += c0 * th[1] + c1 * th[0]
                    a[13 + i][0] += c1 * dv[2] + c2 * dv[1]
                    a[13 + i][1] += c0 * dv[2] + c2 * dv[0]
                    a[13 + i][2] += c0 * dv[1] + c1 * dv[0]
            sd.step(s, c, th_p, dv_p, th, dv, dt)
            for i in range(sd.N_STATE):
                out[k - k0, i] = s[i]
        for i in range(sd.N_STATE):
            state[i] = s[i]
        for i in range(n_acc):
            for j in range(3):
                acc[i, j] = a[i][j]


def propagate_rows(const double[:] time, const double[:, :] dtheta_b,
                   const double[:, :] dvel_b, Py_ssize_t k0, Py_ssize_t k1, double[:] state,
                   const double[:] sensors, double[:, :] out, double[:, :] acc):
    """Mechanize rows ``k0 .. k1-1`` (in place on ``state``, the state at ``time[k0-1]``),
    with the sensor-error estimates removed.  Releases the GIL while it runs.

    Parameters
    ----------
    time : ndarray of float64, shape (n,)
        Epochs of the increments, s.
    dtheta_b, dvel_b : ndarray of float64, shape (n, 3)
        Raw angle (rad) and velocity (m/s) increments in the body frame ``b``.
    k0, k1 : int
        First and one-past-last row; ``1 <= k0``, ``k1 <= n``.
    state : ndarray of float64, shape (10,), writable
        Navigation state (:mod:`ins.nav._kernels` layout), updated in place.
    sensors : ndarray of float64, shape (12,)
        Gyro bias (rad/s), accel bias (m/s^2), gyro scale, accel scale (estimates),
        removed from the increments: ``dtheta = (dtheta_raw - b_g dt) / (1 + s_g)``, the
        same for ``dvel``.
    out : ndarray of float64, shape (>= k1 - k0, 10), writable
        ``out[k - k0]`` receives the state at ``time[k]``.
    acc : ndarray of float64, shape (10, 3), writable
        Receives (added to what it holds) ``S_C = sum C_nb dt`` (rows 0-2, s),
        ``S_Cw = sum C_nb diag(dtheta)`` (rows 3-5, rad), ``S_Cf = sum C_nb diag(dvel)``
        (rows 6-8, m/s) and the sum of ``C_nb dvel`` (row 9, m/s), with ``C_nb`` at the
        start of each row's interval.
    """
    _propagate(time, dtheta_b, dvel_b, k0, k1, state, sensors, out, acc, np.zeros(6), False)


def propagate_rows_mis(const double[:] time, const double[:, :] dtheta_b,
                       const double[:, :] dvel_b, Py_ssize_t k0, Py_ssize_t k1,
                       double[:] state, const double[:] sensors, const double[:] mis,
                       double[:, :] out, double[:, :] acc):
    """:func:`propagate_rows` with the non-orthogonality also removed, after the bias and
    scale.  Releases the GIL while it runs.

    Parameters
    ----------
    mis : ndarray of float64, shape (6,)
        Gyro m_x, m_y, m_z, accel m_x, m_y, m_z (rad):
        ``dtheta <- dtheta - N(m_g) dtheta`` (``N`` of
        :func:`ins.estimation.core.error_model.sym_matrix`), the same for ``dvel`` with ``m_a``.
    acc : ndarray of float64, shape (16, 3), writable
        Rows 0-9 as in :func:`propagate_rows`; also receives ``S_CNw = sum C_nb N(dtheta)``
        (rows 10-12, rad) and ``S_CNf = sum C_nb N(dvel)`` (rows 13-15, m/s).

    The other parameters are those of :func:`propagate_rows`.
    """
    _propagate(time, dtheta_b, dvel_b, k0, k1, state, sensors, out, acc, mis, True)


cdef inline void _correct(double *s, double dn, double de, double dd, double dvn, double dve,
                          double dvd, double px, double py, double pz) noexcept nogil:
    """Remove a navigation error (estimate minus truth: NED m, m/s, phi rad) from s."""
    cdef double rm, rn
    cdef double q[4]
    cdef double r[4]
    radii(s[0], &rm, &rn)
    s[0] -= dn / (rm + s[2])
    s[1] -= de / ((rn + s[2]) * cos(s[0]))
    s[2] += dd
    s[3] -= dvn
    s[4] -= dve
    s[5] -= dvd
    # C_true = Rot(phi) C_est: q <- q(phi) * q
    sd.rotvec_to_quat(px, py, pz, q)
    sd.quat_mul(q[0], q[1], q[2], q[3], s[6], s[7], s[8], s[9], r)
    sd.normalize_into(r[0], r[1], r[2], r[3], &s[6])


cdef inline void _correct_row(double[:, :] traj, Py_ssize_t r, const double *d) noexcept nogil:
    """_correct on row r of a (possibly strided) array of states, d = the 9 navigation
    errors."""
    cdef double v[10]
    cdef int i
    for i in range(10):
        v[i] = traj[r, i]
    _correct(v, d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7], d[8])
    for i in range(10):
        traj[r, i] = v[i]


def correct_state(double[:] s, const double[:] d):
    """Apply the navigation part of an error state to one state, in place.

    Parameters
    ----------
    s : ndarray of float64, shape (10,), writable
        Navigation state (:mod:`ins.nav._kernels` layout).
    d : ndarray of float64, shape (>= 9,)
        Error state (estimate minus truth) whose first 9 values are used: position
        error north, east, down (m), velocity error NED (m/s), attitude error ``phi`` in
        ``n`` (rad; ``C_nb,true = Rot(phi) C_nb,est``).
    """
    cdef double v[10]
    cdef int i
    if s.shape[0] < 10 or d.shape[0] < 9:
        raise ValueError(f"s must hold 10 values and d 9, got {s.shape[0]} and {d.shape[0]}")
    for i in range(10):
        v[i] = s[i]
    _correct(v, d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7], d[8])
    for i in range(10):
        s[i] = v[i]


def correct_rows(double[:, :] traj, const double[:] time, Py_ssize_t row0, node_rows,
                 const double[:] node_time, const double[:, :] x_after,
                 const double[:, :] x_before):
    """Apply interpolated corrections to the rows ``row0 ..`` of a trajectory piece, in
    place.  Releases the GIL while it runs.

    Parameters
    ----------
    traj : ndarray of float64, shape (n, 10), writable
        ``traj[i]`` (at ``time[i]``) is row ``row0 + i`` of the whole trajectory
        (:mod:`ins.nav._kernels` layout).
    time : ndarray of float64, shape (n,)
        Epochs of the rows, s.
    row0 : int
        Row number of ``traj[0]``.
    node_rows : ndarray of int, shape (m,)
        Rows of the filter nodes, increasing.
    node_time : ndarray of float64, shape (m,)
        Epochs of the nodes, s.
    x_after, x_before : ndarray of float64, shape (m, >= 9)
        Error state after / just before the update at each node (the first 9 values are
        used, as in :func:`correct_state`).

    Notes
    -----
    Node row ``node_rows[j]`` gets ``x_after[j]``; a row strictly between nodes ``j`` and
    ``j + 1`` the linear interpolation in time (``node_time``) of ``x_after[j]`` and
    ``x_before[j + 1]``; a row after the last node the last ``x_after``.
    """
    cdef const int64_t[:] nodes = np.ascontiguousarray(node_rows, dtype=np.int64)
    cdef Py_ssize_t m = nodes.shape[0], n = traj.shape[0]
    cdef Py_ssize_t i, k, row, j, lo, hi, mid
    cdef double d[9]
    cdef double t0, w
    if n == 0:
        return
    if m == 0:
        raise ValueError("correct_rows needs at least one node")
    if time.shape[0] < n or traj.shape[1] < 10 or node_time.shape[0] < m \
            or x_after.shape[0] < m or x_before.shape[0] < m \
            or x_after.shape[1] < 9 or x_before.shape[1] < 9:
        raise ValueError("correct_rows: traj (n, 10), time (n,), node_time (m,), "
                         "x_after and x_before (m, >= 9) expected")
    with nogil:
        # j = the last node at or before row0 (searchsorted side="right" - 1), at least 0
        lo = 0
        hi = m
        while lo < hi:
            mid = (lo + hi) // 2
            if nodes[mid] <= row0:
                lo = mid + 1
            else:
                hi = mid
        j = lo - 1 if lo > 0 else 0
        for i in range(n):
            row = row0 + i
            while j + 1 < m and nodes[j + 1] <= row:
                j += 1
            if row == nodes[j] or j + 1 >= m:
                for k in range(9):
                    d[k] = x_after[j, k]
                _correct_row(traj, i, d)
                continue
            t0 = node_time[j]
            w = (time[i] - t0) / (node_time[j + 1] - t0)
            for k in range(9):
                d[k] = (1.0 - w) * x_after[j, k] + w * x_before[j + 1, k]
            _correct_row(traj, i, d)
