"""WGS84 Earth model in the local-level NED frame ``n``.

Geodetic position is ``(lat, lon, h)``: latitude and longitude in rad, ellipsoidal
height in m.  Velocities are NED in m/s.  Every function takes scalars or arrays that
broadcast against each other; vector results have a trailing axis of length 3.

The private ``_`` functions are the scalar formulas (numpy: scalars or arrays).  The
compiled kernels (Cython: mechanization, filter, simulator, LiDAR georeferencing) use the
same formulas in ``ins/nav/_earth.pxd``, held equal to these by tests/test_native_earth.py.
"""
import numpy as np

#: Semi-major axis of WGS84, m.
A = 6378137.0
#: Flattening of WGS84.
F = 1.0 / 298.257223563
#: First eccentricity squared.
E2 = F * (2.0 - F)
#: Earth rotation rate of WGS84, rad/s.
OMEGA_IE = 7.292115e-5
#: Normal-gravity coefficients a1..a6 of the INS paper (Schwarz and Wei), SI units:
#: g = a1 (1 + a2 sin^2 lat + a3 sin^4 lat) + (a4 + a5 sin^2 lat) h + a6 h^2.
GRAVITY_COEFFS = (9.7803267715, 0.0052790414, 0.0000232718,
                  -0.0000030876910891, 0.0000000043977311, 0.0000000000007211)

_A1, _A2, _A3, _A4, _A5, _A6 = GRAVITY_COEFFS


def _radii(lat):
    s2 = np.sin(lat) ** 2
    w = 1.0 - E2 * s2
    rn = A / np.sqrt(w)
    rm = rn * (1.0 - E2) / w
    return rm, rn


def _gravity(lat, h):
    s2 = np.sin(lat) ** 2
    return _A1 * (1.0 + _A2 * s2 + _A3 * s2 * s2) + (_A4 + _A5 * s2) * h + _A6 * h * h


def _earth_rate(lat):
    return OMEGA_IE * np.cos(lat), 0.0 * lat, -OMEGA_IE * np.sin(lat)


def _transport_rate(lat, h, v_north, v_east):
    rm, rn = _radii(lat)
    return (v_east / (rn + h), -v_north / (rm + h), -v_east * np.tan(lat) / (rn + h))


def _lla_rate(lat, h, v_north, v_east, v_down):
    rm, rn = _radii(lat)
    return v_north / (rm + h), v_east / ((rn + h) * np.cos(lat)), -v_down


#: Public names of the scalar formulas above, for the one-point paths of other subpackages
#: (the filter's measurements, the lever arm): normal gravity (m/s^2), radii of curvature
#: (M, N, m), Earth rate and transport rate as their north, east, down components (rad/s),
#: rate of the geodetic position (rad/s, rad/s, m/s).
gravity_kernel = _gravity
radii_kernel = _radii
earth_rate_kernel = _earth_rate
transport_rate_kernel = _transport_rate
lla_rate_kernel = _lla_rate


def _as_vector(v, name):
    v = np.asarray(v, dtype=float)
    if v.ndim == 0 or v.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (3,) or (..., 3), got {v.shape}")
    return v


def radii(lat):
    """Meridian and prime-vertical radii of curvature.

    Parameters
    ----------
    lat : array_like
        Geodetic latitude, rad.

    Returns
    -------
    M, N : ndarray
        ``M = a (1 - e^2) / (1 - e^2 sin^2 lat)^1.5`` and
        ``N = a / (1 - e^2 sin^2 lat)^0.5``, m.
    """
    return _radii(np.asarray(lat, dtype=float))


def normal_gravity(lat, h):
    """Magnitude of normal gravity (the INS paper's a1..a6 series), m/s^2.

    Parameters
    ----------
    lat : array_like
        Geodetic latitude, rad.
    h : array_like
        Ellipsoidal height, m.
    """
    return _gravity(np.asarray(lat, dtype=float), np.asarray(h, dtype=float))


def gravity_n(lat, h):
    """Normal gravity vector ``[0, 0, g]`` in the NED frame, m/s^2, shape (..., 3)."""
    g = normal_gravity(lat, h)
    if g.ndim == 0:                                  # one point: no stacking
        return np.array([0.0, 0.0, g])
    return np.stack([np.zeros_like(g), np.zeros_like(g), g], axis=-1)


def earth_rate_n(lat):
    """Earth rotation rate ``w_ie_n = [W cos lat, 0, -W sin lat]``, rad/s, shape (..., 3)."""
    lat = np.asarray(lat, dtype=float)
    if lat.ndim == 0:
        return np.array(_earth_rate(lat))
    return np.stack(_earth_rate(lat), axis=-1)


def transport_rate_n(lat, h, v_n):
    """Transport rate ``w_en_n``: rotation of n relative to e, in n, rad/s.

    ``w_en_n = [vE / (N + h), -vN / (M + h), -vE tan(lat) / (N + h)]``.

    Parameters
    ----------
    lat, h : array_like
        Geodetic latitude (rad) and ellipsoidal height (m).
    v_n : array_like, shape (3,) or (..., 3)
        Velocity relative to the Earth, NED, m/s.
    """
    v_n = _as_vector(v_n, "v_n")
    lat = np.asarray(lat, dtype=float)
    h = np.asarray(h, dtype=float)
    if v_n.ndim == 1 and lat.ndim == 0 and h.ndim == 0:     # one point
        return np.array(_transport_rate(lat, h, v_n[0], v_n[1]))
    return np.stack(np.broadcast_arrays(*_transport_rate(lat, h, v_n[..., 0], v_n[..., 1])),
                    axis=-1)


def lla_rate(lat, h, v_n):
    """Rate of geodetic position, ``D^-1 v_n``: (dlat/dt, dlon/dt, dh/dt) in rad/s, m/s.

    The inverse of the paper's ``v_n = diag(M + h, (N + h) cos lat, -1) d(lat, lon, h)/dt``.
    """
    v_n = _as_vector(v_n, "v_n")
    lat = np.asarray(lat, dtype=float)
    h = np.asarray(h, dtype=float)
    if v_n.ndim == 1 and lat.ndim == 0 and h.ndim == 0:     # one point
        return np.array(_lla_rate(lat, h, v_n[0], v_n[1], v_n[2]))
    return np.stack(np.broadcast_arrays(
        *_lla_rate(lat, h, v_n[..., 0], v_n[..., 1], v_n[..., 2])), axis=-1)


def lla_to_ecef(lat, lon, h):
    """Geodetic position (rad, rad, m) to ECEF (m), shape (..., 3)."""
    lat, lon, h = (np.asarray(x, dtype=float) for x in (lat, lon, h))
    _, rn = _radii(lat)
    cl = np.cos(lat)
    return np.stack([(rn + h) * cl * np.cos(lon), (rn + h) * cl * np.sin(lon),
                     (rn * (1.0 - E2) + h) * np.sin(lat)], axis=-1)


def dcm_en(lat, lon):
    """``C_en``: takes a NED vector at (lat, lon) into ECEF, shape (..., 3, 3)."""
    lat, lon = np.broadcast_arrays(np.asarray(lat, float), np.asarray(lon, float))
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    z = np.zeros_like(lat)
    return np.stack([np.stack([-sl * co, -so, -cl * co], axis=-1),
                     np.stack([-sl * so, co, -cl * so], axis=-1),
                     np.stack([cl, z, -sl], axis=-1)], axis=-2)


def offset_ecef(lla, offset_n):
    """ECEF position (m) of the point ``offset_n`` (NED in the n frame at ``lla``, m) away
    from ``lla`` (rows: lat rad, lon rad, h m); shape (n, 3).  Exact for any offset."""
    lla = np.atleast_2d(np.asarray(lla, dtype=float))
    offset_n = np.atleast_2d(np.asarray(offset_n, dtype=float))
    r_e = lla_to_ecef(lla[:, 0], lla[:, 1], lla[:, 2])
    return r_e + np.einsum("nij,nj->ni", dcm_en(lla[:, 0], lla[:, 1]), offset_n)


def offset_lla(lla, offset_n):
    """Geodetic position (rows: lat rad, lon rad, h m) of ``lla`` moved by ``offset_n``
    (NED at ``lla``, m): exact, through ECEF and back with pymap3d; shape (n, 3).
    The inverse of :func:`ned_offset`."""
    import pymap3d
    r_e = offset_ecef(lla, offset_n)
    lat, lon, h = pymap3d.ecef2geodetic(r_e[:, 0], r_e[:, 1], r_e[:, 2], deg=False)
    return np.column_stack([lat, lon, h])


def ned_offset(lla_from, lla_to):
    """NED offset (m) of ``lla_to`` from ``lla_from`` (rows: lat rad, lon rad, h m).

    Exact for any distance: the ECEF difference rotated into the n frame at ``lla_from``.
    """
    a = np.asarray(lla_from, dtype=float)
    b = np.asarray(lla_to, dtype=float)
    if a.shape == (3,) and b.shape == (3,):          # one pair: the same sums, unstacked
        return _ned_offset_one(a, b)
    d_e = lla_to_ecef(b[..., 0], b[..., 1], b[..., 2]) - lla_to_ecef(a[..., 0], a[..., 1],
                                                                     a[..., 2])
    C_en = dcm_en(a[..., 0], a[..., 1])
    return np.einsum("...ji,...j->...i", C_en, d_e)


def _ecef_one(lat, lon, h):
    _, rn = _radii(lat)
    cl = np.cos(lat)
    return ((rn + h) * cl * np.cos(lon), (rn + h) * cl * np.sin(lon),
            (rn * (1.0 - E2) + h) * np.sin(lat))


def _ned_offset_one(a, b):
    """:func:`ned_offset` of one pair of points (shape (3,) each)."""
    xb, yb, zb = _ecef_one(b[0], b[1], b[2])
    xa, ya, za = _ecef_one(a[0], a[1], a[2])
    dx, dy, dz = xb - xa, yb - ya, zb - za
    sl, cl, so, co = np.sin(a[0]), np.cos(a[0]), np.sin(a[1]), np.cos(a[1])
    return np.array([-sl * co * dx + -sl * so * dy + cl * dz,
                     -so * dx + co * dy + 0.0 * dz,
                     -cl * co * dx + -cl * so * dy + -sl * dz])
