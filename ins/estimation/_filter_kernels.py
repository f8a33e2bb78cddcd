"""Numba loops of the GNSS/INS filter (private): mechanization of the IMU rows between
two filter nodes with the current sensor-error estimates removed, accumulating the
integrals the covariance step needs, and the application of error-state corrections.

State layout of the navigation vector: that of :mod:`ins.nav._kernels`
(lat, lon, h, vN, vE, vD, qx, qy, qz, qw), named in :data:`ins.estimation.error_model.NAV`; the 12
sensor estimates in the order of :data:`ins.estimation.error_model.SENSORS`; error states in that of
:data:`ins.estimation.error_model.STATE` (the loops below index them element by element).
"""
import math

import numba as nb
import numpy as np

from ins.nav import _kernels


@nb.njit(cache=True, inline="always")
def _compensate(raw, k, bias, scale, dt, out):
    for i in range(3):
        out[i] = (raw[k, i] - bias[i] * dt) / (1.0 + scale[i])


@nb.njit(cache=True, inline="always")
def _unskew(th, m):
    """``th <- th - N(m) th`` (first-order removal of the non-orthogonality ``m``)."""
    a = th[0] - (m[2] * th[1] + m[1] * th[2])
    b = th[1] - (m[2] * th[0] + m[0] * th[2])
    c = th[2] - (m[1] * th[0] + m[0] * th[1])
    th[0], th[1], th[2] = a, b, c


@nb.njit(cache=True, inline="always")
def _propagate(time, dtheta_b, dvel_b, k0, k1, state, sensors, out, acc, mis, use_mis):
    c = np.empty(9)
    th_p = np.empty(3)
    dv_p = np.empty(3)
    th = np.empty(3)
    dv = np.empty(3)
    bg, ba, sg, sa = sensors[0:3], sensors[3:6], sensors[6:9], sensors[9:12]
    mg, ma = mis[0:3], mis[3:6]
    for k in range(k0, k1):
        dt = time[k] - time[k - 1]
        dt_p = time[k - 1] - time[k - 2] if k >= 2 else dt
        _compensate(dtheta_b, k - 1, bg, sg, dt_p, th_p)
        _compensate(dvel_b, k - 1, ba, sa, dt_p, dv_p)
        _compensate(dtheta_b, k, bg, sg, dt, th)
        _compensate(dvel_b, k, ba, sa, dt, dv)
        if use_mis:
            _unskew(th_p, mg)
            _unskew(dv_p, ma)
            _unskew(th, mg)
            _unskew(dv, ma)
        qx, qy, qz, qw = state[6], state[7], state[8], state[9]
        _kernels.quat_to_dcm_rows(qx, qy, qz, qw, c)
        for i in range(3):
            for j in range(3):
                cij = c[3 * i + j]
                acc[i, j] += cij * dt
                acc[3 + i, j] += cij * th[j]
                acc[6 + i, j] += cij * dv[j]
                acc[9, i] += cij * dv[j]
        if use_mis:
            # C N(v): column j of N(v) is (v_z, 0, v_x)... (N symmetric, zero diagonal)
            for i in range(3):
                c0, c1, c2 = c[3 * i], c[3 * i + 1], c[3 * i + 2]
                acc[10 + i, 0] += c1 * th[2] + c2 * th[1]
                acc[10 + i, 1] += c0 * th[2] + c2 * th[0]
                acc[10 + i, 2] += c0 * th[1] + c1 * th[0]
                acc[13 + i, 0] += c1 * dv[2] + c2 * dv[1]
                acc[13 + i, 1] += c0 * dv[2] + c2 * dv[0]
                acc[13 + i, 2] += c0 * dv[1] + c1 * dv[0]
        _kernels._step(state, c, th_p, dv_p, th, dv, dt)
        for i in range(_kernels.N_STATE):
            out[k - k0, i] = state[i]


@nb.njit(cache=True)
def propagate_rows(time, dtheta_b, dvel_b, k0, k1, state, sensors, out, acc):
    """Mechanize rows ``k0 .. k1-1`` (in place on ``state``, the state at ``time[k0-1]``).

    ``sensors`` = gyro bias (rad/s), accel bias (m/s^2), gyro scale, accel scale (12
    values, estimates) are removed from the increments:
    ``dtheta = (dtheta_raw - b_g dt) / (1 + s_g)``, the same for ``dvel``.
    ``out[k - k0]`` receives the state at ``time[k]``.  ``acc`` (shape (10, 3)) receives
    (added to what it holds) ``S_C = sum C_nb dt`` (rows 0-2), ``S_Cw = sum C_nb
    diag(dtheta)`` (rows 3-5), ``S_Cf = sum C_nb diag(dvel)`` (rows 6-8) and the sum of
    ``C_nb dvel`` (row 9), with ``C_nb`` at the start of each row's interval.
    """
    _propagate(time, dtheta_b, dvel_b, k0, k1, state, sensors, out, acc, np.zeros(6), False)


@nb.njit(cache=True)
def propagate_rows_mis(time, dtheta_b, dvel_b, k0, k1, state, sensors, mis, out, acc):
    """:func:`propagate_rows` with the non-orthogonality ``mis`` (gyro m_x, m_y, m_z,
    accel m_x, m_y, m_z, rad) also removed, after the bias and scale:
    ``dtheta <- dtheta - N(m_g) dtheta`` (``N`` of :func:`ins.estimation.error_model.sym_matrix`);
    ``acc`` (16, 3) also receives ``S_CNw = sum C_nb N(dtheta)`` (rows 10-12) and
    ``S_CNf = sum C_nb N(dvel)`` (rows 13-15)."""
    _propagate(time, dtheta_b, dvel_b, k0, k1, state, sensors, out, acc, mis, True)


@nb.njit(cache=True, inline="always")
def _correct(s, dn, de, dd, dvn, dve, dvd, px, py, pz):
    """Remove a navigation error (estimate minus truth: NED m, m/s, phi rad) from ``s``."""
    rm, rn = _kernels._radii(s[0])
    s[0] -= dn / (rm + s[2])
    s[1] -= de / ((rn + s[2]) * math.cos(s[0]))
    s[2] += dd
    s[3] -= dvn
    s[4] -= dve
    s[5] -= dvd
    # C_true = Rot(phi) C_est: q <- q(phi) * q
    ax, ay, az, aw = _kernels._rotvec_to_quat(px, py, pz)
    qx, qy, qz, qw = _kernels._quat_mul(ax, ay, az, aw, s[6], s[7], s[8], s[9])
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if qw < 0.0:
        norm = -norm
    s[6], s[7], s[8], s[9] = qx / norm, qy / norm, qz / norm, qw / norm


@nb.njit(cache=True)
def correct_state(s, d):
    """Apply the navigation part ``d[0:9]`` of an error state to one state, in place."""
    _correct(s, d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7], d[8])


@nb.njit(cache=True, nogil=True)
def correct_rows(traj, time, row0, node_rows, node_time, x_after, x_before):
    """Apply interpolated corrections to the rows ``row0 ..`` of a trajectory piece.

    ``traj[i]`` (at ``time[i]``) is row ``row0 + i`` of the whole trajectory.  Node row
    ``node_rows[j]`` gets ``x_after[j]``; a row strictly between nodes ``j`` and ``j + 1``
    the linear interpolation in time (``node_time``) of ``x_after[j]`` and
    ``x_before[j + 1]`` (the error just before the update at node ``j + 1``).
    """
    d = np.empty(9)
    m = len(node_rows)
    j = max(np.searchsorted(node_rows, row0, side="right") - 1, 0)
    for i in range(len(traj)):
        row = row0 + i
        while j + 1 < m and node_rows[j + 1] <= row:
            j += 1
        if row == node_rows[j] or j + 1 >= m:
            correct_state(traj[i], x_after[j, :9])
            continue
        t0 = node_time[j]
        w = (time[i] - t0) / (node_time[j + 1] - t0)
        for k in range(9):
            d[k] = (1.0 - w) * x_after[j, k] + w * x_before[j + 1, k]
        correct_state(traj[i], d)
