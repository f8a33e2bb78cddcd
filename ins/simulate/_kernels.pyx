"""Compiled loops of the simulator (private; Cython): recursions that cannot be vectorized
and the per-sample attitude/rate formulas of the truth (one pass, no temporaries).

The Earth model is that of ``ins/nav/_earth.pxd`` (the formulas of :mod:`ins.nav.earth`,
``tests/test_native_earth.py`` holds the two equal).  Every product and sum is evaluated
in the order written (``-ffp-contract=off``, setup.py), so the results are those of the
numba kernels this module replaced, bit for bit.
"""
import numpy as np

from libc.math cimport atan, atan2, copysign, cos, cosh, exp, fabs, hypot, rint, sin, sqrt, tan, tanh

from ins.nav._earth cimport OMEGA_IE, gravity, transport_rate


def gauss_markov_add(double[:, :] y, const double[:] dt, const double[:, :] white,
                     const double[:] sigma, double corr_time, const double[:] state):
    """Add ``g_k dt_k`` of a first-order Gauss-Markov process to the rows of ``y``.

    ``g_k = e^{-dt_k/T} g_{k-1} + sigma sqrt(1 - e^{-2 dt_k/T}) white_k`` (exact
    discretization, steady-state standard deviation ``sigma``).  ``state`` is
    ``g`` before the first row; the new state is returned.
    """
    cdef double g[3]
    cdef double phi, s
    cdef Py_ssize_t k, i
    if y.shape[1] < 3 or white.shape[0] < y.shape[0] or white.shape[1] < 3 \
            or dt.shape[0] < y.shape[0] or sigma.shape[0] < 3 or state.shape[0] < 3:
        raise ValueError("gauss_markov_add: y, white (n, 3), dt (n,), sigma, state (3,)")
    for i in range(3):
        g[i] = state[i]
    with nogil:
        for k in range(y.shape[0]):
            phi = exp(-dt[k] / corr_time)
            s = sqrt(max(1.0 - phi * phi, 0.0))
            for i in range(3):
                g[i] = phi * g[i] + sigma[i] * s * white[k, i]
                y[k, i] += g[i] * dt[k]
    return np.array([g[0], g[1], g[2]])


def quantize(double[:, :] y, double q, const double[:] carry):
    """Quantize the rows of ``y`` in place to multiples of ``q``, carrying the residue.

    Equivalent to ``Y_k = q round(S_k / q)``, ``y_k = Y_k - Y_{k-1}`` on the running sum
    ``S_k`` (rounding half to even); ``carry`` is the residue before the first row, the
    new one is returned.
    """
    cdef double c[3]
    cdef double s, v
    cdef Py_ssize_t k, i
    if y.shape[1] < 3 or carry.shape[0] < 3:
        raise ValueError("quantize: y (n, 3), carry (3,)")
    for i in range(3):
        c[i] = carry[i]
    with nogil:
        for k in range(y.shape[0]):
            for i in range(3):
                s = c[i] + y[k, i]
                v = q * rint(s / q)
                c[i] = s - v
                y[k, i] = v
    return np.array([c[0], c[1], c[2]])


# ---------------------------------------------------------------------------------------
# truth: attitude, mount and rates of the platform (one pass per sample, no temporaries)

def euler_rates_to_body(r, p, dr, dp, dy):
    """Body angular rate of ``C = Rz(yaw) Ry(pitch) Rx(roll)`` from the Euler rates
    (numpy: scalars or arrays)."""
    sr, cr, sp, cp = np.sin(r), np.cos(r), np.sin(p), np.cos(p)
    return dr - dy * sp, dp * cr + dy * sr * cp, -dp * sr + dy * cr * cp


def body_to_euler_rates(r, p, wx, wy, wz):
    """Euler rates (roll, pitch, yaw) from the body rate; inverse of the above (numpy)."""
    sr, cr = np.sin(r), np.cos(r)
    a = wy * sr + wz * cr
    return wx + a * np.tan(p), wy * cr - wz * sr, a / np.cos(p)


cdef inline void _euler_rates_to_body(double r, double p, double dr, double dp, double dy,
                                      double *w) noexcept nogil:
    """:func:`euler_rates_to_body` of one sample into ``w[0:3]``."""
    cdef double sr = sin(r), cr = cos(r), sp = sin(p), cp = cos(p)
    w[0] = dr - dy * sp
    w[1] = dp * cr + dy * sr * cp
    w[2] = -dp * sr + dy * cr * cp


cdef inline void _body_to_euler_rates(double r, double p, double wx, double wy, double wz,
                                      double *e) noexcept nogil:
    """:func:`body_to_euler_rates` of one sample into ``e[0:3]``."""
    cdef double sr = sin(r), cr = cos(r)
    cdef double a = wy * sr + wz * cr
    e[0] = wx + a * tan(p)
    e[1] = wy * cr - wz * sr
    e[2] = a / cos(p)


cdef inline void _zyx(double *C, double r, double p, double y) noexcept nogil:
    """C = Rz(y) Ry(p) Rx(r), row by row (``C[3 i + j]``)."""
    cdef double sr = sin(r), cr = cos(r), sp = sin(p), cp = cos(p), sy = sin(y), cy = cos(y)
    C[0] = cp * cy
    C[1] = sr * sp * cy - cr * sy
    C[2] = cr * sp * cy + sr * sy
    C[3] = cp * sy
    C[4] = sr * sp * sy + cr * cy
    C[5] = cr * sp * sy - sr * cy
    C[6] = -sp
    C[7] = sr * cp
    C[8] = cr * cp


cdef inline void _soft_limit(double *x, double *dx, double limit, double knee) noexcept nogil:
    """C4 saturation of ``x`` (and its rate ``dx``), in place: identity below
    ``k = knee * limit``, then ``k + span g(u)``, ``u = (|x| - k) / span``,
    ``span = limit - k``, ``g(u) = tanh(u + u^3 / 3) = u + O(u^5)`` (g'(0) = 1, its 2nd,
    3rd and 4th derivatives vanish at the knee: the angular rate through the knee is C3,
    which 2-node Gauss-Legendre increments integrate well; with a plain tanh knee (C2)
    the jerk jumps there and GL2 leaves ~2e-9 rad per crossing)."""
    cdef double k = knee * limit
    cdef double ax = fabs(x[0])
    cdef double span, u, v, ch
    if ax <= k:
        return
    span = limit - k
    u = (ax - k) / span
    v = u + u * u * u / 3.0
    ch = cosh(v)
    x[0] = copysign(k + span * tanh(v), x[0])
    dx[0] = dx[0] * (1.0 + u * u) / (ch * ch)


def sum_of_sines(const double[:] t, const double[:] amp, const double[:] omega,
                 const double[:] phase, const double[:] lag_cos, const double[:] lag_sin,
                 double[:, :] out):
    """``sum A sin(w t + phase)``: value, first and second derivative, and the response
    of a first-order lag ``A g sin(w t + phase - phi)`` (``lag_cos = g cos phi``,
    ``lag_sin = g sin phi``) with its derivative; ``out`` (n, 5) filled in place."""
    cdef Py_ssize_t k, j, m = amp.shape[0]
    cdef double v, dv, ddv, lv, dlv, a, w, s, c
    if out.shape[0] < t.shape[0] or out.shape[1] < 5 or omega.shape[0] < m \
            or phase.shape[0] < m or lag_cos.shape[0] < m or lag_sin.shape[0] < m:
        raise ValueError("sum_of_sines: out (n, 5) and five coefficient arrays of one length")
    with nogil:
        for k in range(t.shape[0]):
            v = dv = ddv = lv = dlv = 0.0
            for j in range(m):
                a = amp[j]
                w = omega[j]
                s = sin(w * t[k] + phase[j])
                c = cos(w * t[k] + phase[j])
                v += a * s
                dv += a * w * c
                ddv -= a * w * w * s
                lv += a * (s * lag_cos[j] - c * lag_sin[j])
                dlv += a * w * (c * lag_cos[j] + s * lag_sin[j])
            out[k, 0] = v
            out[k, 1] = dv
            out[k, 2] = ddv
            out[k, 3] = lv
            out[k, 4] = dlv


cdef inline void _aircraft(const double[:, :] prof, const double[:, :] turb, Py_ssize_t k,
                           double wind_n, double wind_e, double g, double *o) noexcept nogil:
    """Aircraft roll, pitch, d = yaw - track and their rates at sample k, into ``o[0:6]``
    (roll, pitch, d, droll, dpitch, dd).

    ``prof[k]`` = psi, psi_dot, psi_ddot, V, V_dot, up, up_dot, s, s_dot (airborne weight);
    ``turb[k]`` = roll, d roll, pitch, d pitch, yaw, d yaw of the turbulence.  Roll
    ``atan(V psi_dot / g) + s roll_t`` (coordinated turn), pitch ``atan2(up, V) + s
    pitch_t`` (flight-path angle), ``d = s (crab + yaw_t)`` with the crab of the wind
    triangle ``atan2(B, A)``, ``A = V - w.along``, ``B = -w.right``.
    """
    cdef double psi = prof[k, 0], psi_dot = prof[k, 1], psi_ddot = prof[k, 2]
    cdef double V = prof[k, 3], V_dot = prof[k, 4]
    cdef double up = prof[k, 5], up_dot = prof[k, 6], s = prof[k, 7], ds = prof[k, 8]
    cdef double x = V * psi_dot / g
    cdef double dx = (V_dot * psi_dot + V * psi_ddot) / g
    cdef double den = V * V + up * up
    cdef double sp, cp, A, B, crab = 0.0, dcrab = 0.0
    o[0] = atan(x) + s * turb[k, 0]
    o[3] = dx / (1.0 + x * x) + ds * turb[k, 0] + s * turb[k, 1]
    o[1] = atan2(up, V) + s * turb[k, 2]
    o[4] = ds * turb[k, 2] + s * turb[k, 3]
    if den > 0.0:
        o[4] += (V * up_dot - up * V_dot) / den
    sp = sin(psi)
    cp = cos(psi)
    A = V - (wind_n * cp + wind_e * sp)
    B = wind_n * sp - wind_e * cp
    if wind_n != 0.0 or wind_e != 0.0:
        den = A * A + B * B
        crab = atan2(B, A)
        # d/dt: dA = (wind_n sp - wind_e cp) psi_dot + V_dot, dB = (wind_n cp + wind_e sp) psi_dot
        dcrab = (A * (wind_n * cp + wind_e * sp) * psi_dot
                 - B * (B * psi_dot + V_dot)) / den
    o[2] = s * (crab + turb[k, 4])
    o[5] = ds * (crab + turb[k, 4]) + s * (dcrab + turb[k, 5])


def platform_state(const double[:, :] prof, const double[:, :] prof_lag,
                   const double[:, :] turb, const double[:, :] turb_lag, double wind_n,
                   double wind_e, double g, const double[:] lat, const double[:] h,
                   const double[:, :] v_n, const double[:, :] a_n, const double[:] limits,
                   double knee, bint enabled, double[:, :, :] C_na, double[:, :, :] C_nb,
                   double[:, :] mount, double[:, :] mount_rate, double[:, :] w_ib_b,
                   double[:, :] f_b):
    """Aircraft and platform attitude, mount angles and the IMU's rates, per sample.

    The aircraft angles (``_aircraft``) from ``prof``/``turb`` at t; the angles the
    mount's servos follow from ``prof_lag`` (at t - tau) and ``turb_lag`` (the lag's
    response).  The mount command ``C_ap* = Rx(-roll) Ry(-pitch) Rz(-d)`` (of the lagged
    angles) levels the platform along the track; its ZYX angles are soft-limited.
    Outputs (filled in place): ``C_na``, ``C_nb`` (n, 3, 3), ``mount``, ``mount_rate``,
    ``w_ib_b``, ``f_b`` (n, 3).  Releases the GIL while it runs.
    """
    cdef double Cm[9]
    cdef double Ca[9]
    cdef double o[6]
    cdef double wa[3]
    cdef double wm[3]
    cdef double dm[3]
    cdef double a, b, c, da, db, dc, sa, ca, sb, cb, sc, cc
    cdef double c00, c10, c20, c21, c22, mr, mp, my, ux, uz, wx, wy, wz
    cdef double vn, ve, vd, ie_n, ie_e, ie_d, en_n, en_e, en_d, wn, we, wd, xn, xe, xd
    cdef double fn, fe, fd
    cdef Py_ssize_t n = prof.shape[0], k, i, j
    if (prof.shape[1] < 9 or prof_lag.shape[0] < n or prof_lag.shape[1] < 9
            or turb.shape[0] < n or turb.shape[1] < 6 or turb_lag.shape[0] < n
            or turb_lag.shape[1] < 6 or lat.shape[0] < n or h.shape[0] < n
            or v_n.shape[0] < n or v_n.shape[1] < 3 or a_n.shape[0] < n or a_n.shape[1] < 3
            or limits.shape[0] < 3 or C_na.shape[0] < n or C_na.shape[1] < 3
            or C_na.shape[2] < 3 or C_nb.shape[0] < n or C_nb.shape[1] < 3
            or C_nb.shape[2] < 3 or mount.shape[0] < n or mount.shape[1] < 3
            or mount_rate.shape[0] < n or mount_rate.shape[1] < 3 or w_ib_b.shape[0] < n
            or w_ib_b.shape[1] < 3 or f_b.shape[0] < n or f_b.shape[1] < 3):
        raise ValueError("platform_state: inconsistent array shapes")
    with nogil:
        for k in range(n):
            _aircraft(prof, turb, k, wind_n, wind_e, g, o)
            _zyx(Ca, o[0], o[1], prof[k, 0] + o[2])
            _euler_rates_to_body(o[0], o[1], o[3], o[4], prof[k, 1] + o[5], wa)
            if enabled:
                # command: C = Rx(a) Ry(b) Rz(c), a, b, c = -lagged (roll, pitch, d)
                _aircraft(prof_lag, turb_lag, k, wind_n, wind_e, g, o)
                a, b, c, da, db, dc = -o[0], -o[1], -o[2], -o[3], -o[4], -o[5]
                sa, ca, sb, cb, sc, cc = sin(a), cos(a), sin(b), cos(b), sin(c), cos(c)
                c00, c10 = cb * cc, ca * sc + sa * sb * cc      # column 0 and row 2 of C
                c20, c21, c22 = sa * sc - ca * sb * cc, sa * cc + ca * sb * sc, ca * cb
                mr = atan2(c21, c22)
                mp = atan2(-c20, hypot(c21, c22))
                my = atan2(c10, c00)
                # body rate of C: Rz(c)^T Ry(b)^T (da, 0, 0) + Rz(c)^T (0, db, 0) + (0, 0, dc)
                ux, uz = cb * da, sb * da
                wx = cc * ux + sc * db
                wy = -sc * ux + cc * db
                wz = uz + dc
                _body_to_euler_rates(mr, mp, wx, wy, wz, dm)
                _soft_limit(&mr, &dm[0], limits[0], knee)
                _soft_limit(&mp, &dm[1], limits[1], knee)
                _soft_limit(&my, &dm[2], limits[2], knee)
            else:
                mr = mp = my = 0.0
                dm[0] = dm[1] = dm[2] = 0.0
            _zyx(Cm, mr, mp, my)
            _euler_rates_to_body(mr, mp, dm[0], dm[1], dm[2], wm)
            for i in range(3):
                for j in range(3):
                    C_na[k, i, j] = Ca[3 * i + j]
                    C_nb[k, i, j] = (Ca[3 * i] * Cm[j] + Ca[3 * i + 1] * Cm[3 + j]
                                     + Ca[3 * i + 2] * Cm[6 + j])
            mount[k, 0], mount[k, 1], mount[k, 2] = mr, mp, my
            mount_rate[k, 0], mount_rate[k, 1], mount_rate[k, 2] = dm[0], dm[1], dm[2]
            vn, ve, vd = v_n[k, 0], v_n[k, 1], v_n[k, 2]
            # Earth rate (north, east = 0 * lat as ins.nav.earth writes it, down)
            ie_n = OMEGA_IE * cos(lat[k])
            ie_e = 0.0 * lat[k]
            ie_d = -OMEGA_IE * sin(lat[k])
            transport_rate(lat[k], h[k], vn, ve, &en_n, &en_e, &en_d)
            wn, we, wd = ie_n + en_n, ie_e + en_e, ie_d + en_d
            xn, xe, xd = wn + ie_n, we + ie_e, wd + ie_d       # 2 w_ie + w_en
            fn = a_n[k, 0] + (xe * vd - xd * ve)
            fe = a_n[k, 1] + (xd * vn - xn * vd)
            fd = a_n[k, 2] - gravity(lat[k], h[k]) + (xn * ve - xe * vn)
            for i in range(3):
                # w_nb_b = C_ap^T w_na_a + w_ap_p ; + C_bn w_in_n
                w_ib_b[k, i] = (Cm[i] * wa[0] + Cm[3 + i] * wa[1] + Cm[6 + i] * wa[2] + wm[i]
                                + C_nb[k, 0, i] * wn + C_nb[k, 1, i] * we + C_nb[k, 2, i] * wd)
                f_b[k, i] = C_nb[k, 0, i] * fn + C_nb[k, 1, i] * fe + C_nb[k, 2, i] * fd
