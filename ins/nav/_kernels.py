"""Numba loops of the strapdown mechanization (private; hot paths only).

The Earth-model formulas are those of :mod:`ins.nav.earth` (``register_jitable`` there).
numba's on-disk cache keys on THIS file only (its timestamp): after editing
``ins/nav/earth.py`` touch this file (or delete ``ins/__pycache__/*.nbi``) so the kernels
recompile.  The test suite does not depend on that: ``tests/conftest.py`` points
``NUMBA_CACHE_DIR`` at a folder keyed on a hash of every source of ``ins/`` and
``photogrammetry/``.

State vector layout (float64[10]): lat, lon (rad), h (m), vN, vE, vD (m/s),
q_nb = qx, qy, qz, qw (scalar last).
"""
import math

import numba as nb
import numpy as np

from ins.common.jitable import register_pending
from ins.nav import earth

register_pending()     # the Earth formulas of ins.nav.earth, compiled into these kernels

_radii = earth._radii

N_STATE = 10


@nb.njit(cache=True, inline="always")
def _rates(lat, h, vn, ve):
    """Earth rate and transport rate in n (rad/s) and gravity (m/s^2) at (lat, h, v)."""
    wie_n, _, wie_d = earth._earth_rate(lat)
    wen_n, wen_e, wen_d = earth._transport_rate(lat, h, vn, ve)
    return wie_n, wie_d, wen_n, wen_e, wen_d, earth._gravity(lat, h)


@nb.njit(cache=True, inline="always")
def quat_to_dcm_rows(qx, qy, qz, qw, c):
    """``C`` of the unit quaternion ``[qx, qy, qz, qw]`` (scalar last) into ``c[0:9]``,
    row by row (``c[3 i + j] = C[i, j]``; the same as :func:`ins.nav.rotation.quat_to_dcm`)."""
    c[0] = 1.0 - 2.0 * (qy * qy + qz * qz)
    c[1] = 2.0 * (qx * qy - qz * qw)
    c[2] = 2.0 * (qx * qz + qy * qw)
    c[3] = 2.0 * (qx * qy + qz * qw)
    c[4] = 1.0 - 2.0 * (qx * qx + qz * qz)
    c[5] = 2.0 * (qy * qz - qx * qw)
    c[6] = 2.0 * (qx * qz - qy * qw)
    c[7] = 2.0 * (qy * qz + qx * qw)
    c[8] = 1.0 - 2.0 * (qx * qx + qy * qy)


@nb.njit(cache=True, inline="always")
def _rotvec_to_quat(x, y, z):
    """Quaternion (x, y, z, w) of a rotation vector (rad); series below 0.01 rad."""
    a2 = x * x + y * y + z * z
    if a2 < 1e-4:
        s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0 - a2 * a2 * a2 / 645120.0
        c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0 - a2 * a2 * a2 / 46080.0
    else:
        a = math.sqrt(a2)
        s = math.sin(0.5 * a) / a
        c = math.cos(0.5 * a)
    return x * s, y * s, z * s, c


@nb.njit(cache=True, inline="always")
def _quat_mul(px, py, pz, pw, qx, qy, qz, qw):
    """Hamilton product p * q, scalar last (C(p * q) = C(p) C(q))."""
    return (pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
            pw * qw - px * qx - py * qy - pz * qz)


@nb.njit(cache=True, inline="always")
def _specific_force_n(c, zn, ze, zd, fx, fy, fz):
    """(I - 0.5 [zeta x]) C_nb f_b: body increment into n at mid-interval."""
    gx = c[0] * fx + c[1] * fy + c[2] * fz
    gy = c[3] * fx + c[4] * fy + c[5] * fz
    gz = c[6] * fx + c[7] * fy + c[8] * fz
    return (gx - 0.5 * (ze * gz - zd * gy),
            gy - 0.5 * (zd * gx - zn * gz),
            gz - 0.5 * (zn * gy - ze * gx))


@nb.njit(cache=True, inline="always")
def _gravity_coriolis(wie_n, wie_d, wen_n, wen_e, wen_d, g, vn, ve, vd, dt):
    """(g_n - (2 w_ie_n + w_en_n) x v_n) dt, m/s."""
    an = 2.0 * wie_n + wen_n
    ae = wen_e
    ad = 2.0 * wie_d + wen_d
    return (-(ae * vd - ad * ve) * dt,
            -(ad * vn - an * vd) * dt,
            (g - (an * ve - ae * vn)) * dt)


@nb.njit(cache=True)
def _step(s, c, th_p, dv_p, th, dv, dt):
    """One two-sample strapdown step, in place on the state ``s`` (layout above).

    Order: (1) velocity, (2) position, (3) attitude.  The velocity update uses the
    attitude at the start of the interval, compensates the body increment for rotation
    (to third order) and sculling, and rotates it to mid-interval; Coriolis and gravity
    are evaluated at the mid-interval position and velocity extrapolated from the start
    of the interval (pass 1) and then at that mid point (pass 2).  The position update
    integrates D^-1 v with the mean of the old and new velocity and the radii at
    mid-interval.  The attitude update applies the body rotation (with coning) on the
    right and the n-frame rotation (w_ie_n + w_en_n) dt of pass 2 on the left.
    ``c`` is scratch for C_nb (9 values).
    """
    lat, lon, h = s[0], s[1], s[2]
    vn, ve, vd = s[3], s[4], s[5]
    qx, qy, qz, qw = s[6], s[7], s[8], s[9]

    # --- body velocity increment: rotation compensation to third order,
    # 0.5 th x dv + (1/6) th x (th x dv), and two-sample sculling
    rx = th[1] * dv[2] - th[2] * dv[1]
    ry = th[2] * dv[0] - th[0] * dv[2]
    rz = th[0] * dv[1] - th[1] * dv[0]
    fx = dv[0] + 0.5 * rx + (th[1] * rz - th[2] * ry) / 6.0 + (
        th_p[1] * dv[2] - th_p[2] * dv[1] + dv_p[1] * th[2] - dv_p[2] * th[1]) / 12.0
    fy = dv[1] + 0.5 * ry + (th[2] * rx - th[0] * rz) / 6.0 + (
        th_p[2] * dv[0] - th_p[0] * dv[2] + dv_p[2] * th[0] - dv_p[0] * th[2]) / 12.0
    fz = dv[2] + 0.5 * rz + (th[0] * ry - th[1] * rx) / 6.0 + (
        th_p[0] * dv[1] - th_p[1] * dv[0] + dv_p[0] * th[1] - dv_p[1] * th[0]) / 12.0

    # C_nb at the start of the interval
    quat_to_dcm_rows(qx, qy, qz, qw, c)

    # --- (1) velocity. Pass 1: rates at t[k-1] to extrapolate v and position to mid.
    wie_n, wie_d, wen_n, wen_e, wen_d, g = _rates(lat, h, vn, ve)
    zn, ze, zd = (wie_n + wen_n) * dt, wen_e * dt, (wie_d + wen_d) * dt
    an, ae, ad = _specific_force_n(c, zn, ze, zd, fx, fy, fz)
    gn, ge, gd = _gravity_coriolis(wie_n, wie_d, wen_n, wen_e, wen_d, g, vn, ve, vd, dt)
    mvn, mve, mvd = vn + 0.5 * (an + gn), ve + 0.5 * (ae + ge), vd + 0.5 * (ad + gd)
    rm, rn = _radii(lat)
    mh = h - 0.5 * mvd * dt
    mlat = lat + 0.5 * mvn * dt / (rm + mh)
    # Pass 2: rates at mid-interval.
    wie_n, wie_d, wen_n, wen_e, wen_d, g = _rates(mlat, mh, mvn, mve)
    zn, ze, zd = (wie_n + wen_n) * dt, wen_e * dt, (wie_d + wen_d) * dt
    an, ae, ad = _specific_force_n(c, zn, ze, zd, fx, fy, fz)
    gn, ge, gd = _gravity_coriolis(wie_n, wie_d, wen_n, wen_e, wen_d, g, mvn, mve, mvd, dt)
    vn1, ve1, vd1 = vn + an + gn, ve + ae + ge, vd + ad + gd

    # --- (2) position: mean velocity, radii at mid-interval
    bvn, bve, bvd = 0.5 * (vn + vn1), 0.5 * (ve + ve1), 0.5 * (vd + vd1)
    mh = h - 0.5 * bvd * dt
    mlat = lat + 0.5 * bvn * dt / (rm + mh)
    rm, rn = _radii(mlat)
    s[0] = lat + bvn * dt / (rm + mh)
    s[1] = lon + bve * dt / ((rn + mh) * math.cos(mlat))
    s[2] = h - bvd * dt
    s[3], s[4], s[5] = vn1, ve1, vd1

    # --- (3) attitude: q_nb(k) = q(-zeta) * q_nb(k-1) * q(phi), zeta of pass 2
    nx, ny, nz, nw = _rotvec_to_quat(-zn, -ze, -zd)
    px = th[0] + (th_p[1] * th[2] - th_p[2] * th[1]) / 12.0
    py = th[1] + (th_p[2] * th[0] - th_p[0] * th[2]) / 12.0
    pz = th[2] + (th_p[0] * th[1] - th_p[1] * th[0]) / 12.0
    bx, by, bz, bw = _rotvec_to_quat(px, py, pz)
    qx, qy, qz, qw = _quat_mul(qx, qy, qz, qw, bx, by, bz, bw)
    qx, qy, qz, qw = _quat_mul(nx, ny, nz, nw, qx, qy, qz, qw)
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if qw < 0.0:
        norm = -norm
    s[6], s[7], s[8], s[9] = qx / norm, qy / norm, qz / norm, qw / norm


@nb.njit(cache=True)
def mechanize_rows(time, dtheta_b, dvel_b, k0, k1, state, out):
    """Integrate rows ``k0 .. k1-1`` in place on ``state``; row k spans (t[k-1], t[k]].

    ``state`` holds the navigation state at ``time[k0 - 1]``; the previous increment of
    row ``k0`` is row ``k0 - 1``.  ``out[k - k0]`` receives the state at ``time[k]``.
    """
    c = np.empty(9)
    for k in range(k0, k1):
        _step(state, c, dtheta_b[k - 1], dvel_b[k - 1], dtheta_b[k], dvel_b[k],
              time[k] - time[k - 1])
        for i in range(N_STATE):
            out[k - k0, i] = state[i]
