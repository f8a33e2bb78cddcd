"""Numba loops of the simulator (private): recursions that cannot be vectorized and the
per-sample attitude/rate formulas of the truth (one pass, no temporaries)."""
import math

import numba as nb
import numpy as np
from numba.extending import register_jitable

from ins.common.jitable import register_pending
from ins.nav.earth import earth_rate_kernel, gravity_kernel, transport_rate_kernel

register_pending()     # the Earth formulas of ins.nav.earth, compiled into these kernels


@nb.njit(cache=True)
def gauss_markov_add(y, dt, white, sigma, corr_time, state):
    """Add ``g_k dt_k`` of a first-order Gauss-Markov process to the rows of ``y``.

    ``g_k = e^{-dt_k/T} g_{k-1} + sigma sqrt(1 - e^{-2 dt_k/T}) white_k`` (exact
    discretization, steady-state standard deviation ``sigma``).  ``state`` is
    ``g`` before the first row; the new state is returned.
    """
    g = state.copy()
    for k in range(y.shape[0]):
        phi = math.exp(-dt[k] / corr_time)
        s = math.sqrt(max(1.0 - phi * phi, 0.0))
        for i in range(3):
            g[i] = phi * g[i] + sigma[i] * s * white[k, i]
            y[k, i] += g[i] * dt[k]
    return g


@nb.njit(cache=True)
def quantize(y, q, carry):
    """Quantize the rows of ``y`` in place to multiples of ``q``, carrying the residue.

    Equivalent to ``Y_k = q round(S_k / q)``, ``y_k = Y_k - Y_{k-1}`` on the running sum
    ``S_k``; ``carry`` is the residue before the first row, the new one is returned.
    """
    c = carry.copy()
    for k in range(y.shape[0]):
        for i in range(3):
            s = c[i] + y[k, i]
            v = q * np.round(s / q)
            c[i] = s - v
            y[k, i] = v
    return c


# ---------------------------------------------------------------------------------------
# truth: attitude, mount and rates of the platform (one pass per sample, no temporaries)

@register_jitable
def euler_rates_to_body(r, p, dr, dp, dy):
    """Body angular rate of ``C = Rz(yaw) Ry(pitch) Rx(roll)`` from the Euler rates."""
    sr, cr, sp, cp = np.sin(r), np.cos(r), np.sin(p), np.cos(p)
    return dr - dy * sp, dp * cr + dy * sr * cp, -dp * sr + dy * cr * cp


@register_jitable
def body_to_euler_rates(r, p, wx, wy, wz):
    """Euler rates (roll, pitch, yaw) from the body rate; inverse of the above."""
    sr, cr = np.sin(r), np.cos(r)
    a = wy * sr + wz * cr
    return wx + a * np.tan(p), wy * cr - wz * sr, a / np.cos(p)


@nb.njit(cache=True, inline="always")
def _zyx(C, r, p, y):
    """C = Rz(y) Ry(p) Rx(r), in place."""
    sr, cr, sp, cp, sy, cy = math.sin(r), math.cos(r), math.sin(p), math.cos(p), \
        math.sin(y), math.cos(y)
    C[0, 0], C[0, 1], C[0, 2] = cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy
    C[1, 0], C[1, 1], C[1, 2] = cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy
    C[2, 0], C[2, 1], C[2, 2] = -sp, sr * cp, cr * cp


@nb.njit(cache=True, inline="always")
def _soft_limit(x, dx, limit, knee):
    """C4 saturation: identity below ``k = knee * limit``, then ``k + span g(u)``,
    ``u = (|x| - k) / span``, ``span = limit - k``, ``g(u) = tanh(u + u^3 / 3) = u + O(u^5)``
    (g'(0) = 1, its 2nd, 3rd and 4th derivatives vanish at the knee: the angular rate
    through the knee is C3, which 2-node Gauss-Legendre increments integrate well; with
    a plain tanh knee (C2) the jerk jumps there and GL2 leaves ~2e-9 rad per crossing)."""
    k = knee * limit
    ax = abs(x)
    if ax <= k:
        return x, dx
    span = limit - k
    u = (ax - k) / span
    v = u + u * u * u / 3.0
    return math.copysign(k + span * math.tanh(v), x), dx * (1.0 + u * u) / math.cosh(v) ** 2


@nb.njit(cache=True)
def sum_of_sines(t, amp, omega, phase, lag_cos, lag_sin, out):
    """``sum A sin(w t + phase)``: value, first and second derivative, and the response
    of a first-order lag ``A g sin(w t + phase - phi)`` (``lag_cos = g cos phi``,
    ``lag_sin = g sin phi``) with its derivative; ``out`` (n, 5) filled in place."""
    for k in range(t.shape[0]):
        v = dv = ddv = lv = dlv = 0.0
        for j in range(amp.shape[0]):
            a, w = amp[j], omega[j]
            s, c = math.sin(w * t[k] + phase[j]), math.cos(w * t[k] + phase[j])
            v += a * s
            dv += a * w * c
            ddv -= a * w * w * s
            lv += a * (s * lag_cos[j] - c * lag_sin[j])
            dlv += a * w * (c * lag_cos[j] + s * lag_sin[j])
        out[k, 0], out[k, 1], out[k, 2], out[k, 3], out[k, 4] = v, dv, ddv, lv, dlv


@nb.njit(cache=True, inline="always")
def _aircraft(prof, turb, k, wind_n, wind_e, g):
    """Aircraft roll, pitch, d = yaw - track and their rates at sample k.

    ``prof[k]`` = psi, psi_dot, psi_ddot, V, V_dot, up, up_dot, s, s_dot (airborne weight);
    ``turb[k]`` = roll, d roll, pitch, d pitch, yaw, d yaw of the turbulence.  Roll
    ``atan(V psi_dot / g) + s roll_t`` (coordinated turn), pitch ``atan2(up, V) + s
    pitch_t`` (flight-path angle), ``d = s (crab + yaw_t)`` with the crab of the wind
    triangle ``atan2(B, A)``, ``A = V - w.along``, ``B = -w.right``.
    """
    psi, psi_dot, psi_ddot, V, V_dot = prof[k, 0], prof[k, 1], prof[k, 2], prof[k, 3], \
        prof[k, 4]
    up, up_dot, s, ds = prof[k, 5], prof[k, 6], prof[k, 7], prof[k, 8]
    x = V * psi_dot / g
    dx = (V_dot * psi_dot + V * psi_ddot) / g
    roll = math.atan(x) + s * turb[k, 0]
    droll = dx / (1.0 + x * x) + ds * turb[k, 0] + s * turb[k, 1]
    den = V * V + up * up
    pitch = math.atan2(up, V) + s * turb[k, 2]
    dpitch = ds * turb[k, 2] + s * turb[k, 3]
    if den > 0.0:
        dpitch += (V * up_dot - up * V_dot) / den
    sp, cp = math.sin(psi), math.cos(psi)
    A = V - (wind_n * cp + wind_e * sp)
    B = wind_n * sp - wind_e * cp
    crab = dcrab = 0.0
    if wind_n != 0.0 or wind_e != 0.0:
        den = A * A + B * B
        crab = math.atan2(B, A)
        # d/dt: dA = (wind_n sp - wind_e cp) psi_dot + V_dot, dB = (wind_n cp + wind_e sp) psi_dot
        dcrab = (A * (wind_n * cp + wind_e * sp) * psi_dot
                 - B * (B * psi_dot + V_dot)) / den
    d = s * (crab + turb[k, 4])
    dd = ds * (crab + turb[k, 4]) + s * (dcrab + turb[k, 5])
    return roll, pitch, d, droll, dpitch, dd


@nb.njit(cache=True)
def platform_state(prof, prof_lag, turb, turb_lag, wind_n, wind_e, g, lat, h, v_n, a_n,
                   limits, knee, enabled, C_na, C_nb, mount, mount_rate, w_ib_b, f_b):
    """Aircraft and platform attitude, mount angles and the IMU's rates, per sample.

    The aircraft angles (:func:`_aircraft`) from ``prof``/``turb`` at t; the angles the
    mount's servos follow from ``prof_lag`` (at t - tau) and ``turb_lag`` (the lag's
    response).  The mount command ``C_ap* = Rx(-roll) Ry(-pitch) Rz(-d)`` (of the lagged
    angles) levels the platform along the track; its ZYX angles are soft-limited.
    Outputs (filled in place): ``C_na``, ``C_nb`` (n, 3, 3), ``mount``, ``mount_rate``,
    ``w_ib_b``, ``f_b`` (n, 3).
    """
    Cm = np.empty((3, 3))
    Ca = np.empty((3, 3))
    for k in range(prof.shape[0]):
        r, p, d, dr, dp, dd = _aircraft(prof, turb, k, wind_n, wind_e, g)
        _zyx(Ca, r, p, prof[k, 0] + d)
        wa = euler_rates_to_body(r, p, dr, dp, prof[k, 1] + dd)
        if enabled:
            # command: C = Rx(a) Ry(b) Rz(c), a, b, c = -lagged (roll, pitch, d)
            a, b, c, da, db, dc = _aircraft(prof_lag, turb_lag, k, wind_n, wind_e, g)
            a, b, c, da, db, dc = -a, -b, -c, -da, -db, -dc
            sa, ca, sb, cb, sc, cc = math.sin(a), math.cos(a), math.sin(b), math.cos(b), \
                math.sin(c), math.cos(c)
            c00, c10 = cb * cc, ca * sc + sa * sb * cc      # column 0 and row 2 of C
            c20, c21, c22 = sa * sc - ca * sb * cc, sa * cc + ca * sb * sc, ca * cb
            mr = math.atan2(c21, c22)
            mp = math.atan2(-c20, math.hypot(c21, c22))
            my = math.atan2(c10, c00)
            # body rate of C: Rz(c)^T Ry(b)^T (da, 0, 0) + Rz(c)^T (0, db, 0) + (0, 0, dc)
            ux, uz = cb * da, sb * da
            wx = cc * ux + sc * db
            wy = -sc * ux + cc * db
            wz = uz + dc
            dmr, dmp, dmy = body_to_euler_rates(mr, mp, wx, wy, wz)
            mr, dmr = _soft_limit(mr, dmr, limits[0], knee)
            mp, dmp = _soft_limit(mp, dmp, limits[1], knee)
            my, dmy = _soft_limit(my, dmy, limits[2], knee)
        else:
            mr = mp = my = dmr = dmp = dmy = 0.0
        _zyx(Cm, mr, mp, my)
        wm = euler_rates_to_body(mr, mp, dmr, dmp, dmy)
        for i in range(3):
            for j in range(3):
                C_na[k, i, j] = Ca[i, j]
                C_nb[k, i, j] = Ca[i, 0] * Cm[0, j] + Ca[i, 1] * Cm[1, j] + Ca[i, 2] * Cm[2, j]
        mount[k, 0], mount[k, 1], mount[k, 2] = mr, mp, my
        mount_rate[k, 0], mount_rate[k, 1], mount_rate[k, 2] = dmr, dmp, dmy
        vn, ve, vd = v_n[k, 0], v_n[k, 1], v_n[k, 2]
        ie_n, ie_e, ie_d = earth_rate_kernel(lat[k])
        en_n, en_e, en_d = transport_rate_kernel(lat[k], h[k], vn, ve)
        wn, we, wd = ie_n + en_n, ie_e + en_e, ie_d + en_d
        xn, xe, xd = wn + ie_n, we + ie_e, wd + ie_d       # 2 w_ie + w_en
        fn = a_n[k, 0] + (xe * vd - xd * ve)
        fe = a_n[k, 1] + (xd * vn - xn * vd)
        fd = a_n[k, 2] - gravity_kernel(lat[k], h[k]) + (xn * ve - xe * vn)
        for i in range(3):
            # w_nb_b = C_ap^T w_na_a + w_ap_p ; + C_bn w_in_n
            w_ib_b[k, i] = (Cm[0, i] * wa[0] + Cm[1, i] * wa[1] + Cm[2, i] * wa[2] + wm[i]
                            + C_nb[k, 0, i] * wn + C_nb[k, 1, i] * we + C_nb[k, 2, i] * wd)
            f_b[k, i] = C_nb[k, 0, i] * fn + C_nb[k, 1, i] * fe + C_nb[k, 2, i] * fd
