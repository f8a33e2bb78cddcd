# WGS84 scalar formulas for the compiled kernels (C inline functions; private).
#
# The same formulas as ins/nav/earth.py (_radii, _gravity, _earth_rate, _transport_rate),
# which stays the source for Python; every compiled kernel cimports these;
# tests/test_native_earth.py holds the two equal to the last bits.
# Units: lat rad, h m, velocities m/s, rates rad/s (north, east, down), gravity m/s^2.
from libc.math cimport cos, sin, sqrt, tan

cdef extern from *:
    """
    #define INS_WGS84_A 6378137.0
    #define INS_WGS84_F (1.0 / 298.257223563)
    #define INS_WGS84_E2 (INS_WGS84_F * (2.0 - INS_WGS84_F))
    #define INS_OMEGA_IE 7.292115e-5
    """
    const double WGS84_A "INS_WGS84_A"
    const double WGS84_E2 "INS_WGS84_E2"
    const double OMEGA_IE "INS_OMEGA_IE"

cdef inline void radii(double lat, double *rm, double *rn) noexcept nogil:
    """Meridian (rm) and prime-vertical (rn) radii of curvature, m."""
    cdef double s = sin(lat)
    cdef double w = 1.0 - WGS84_E2 * (s * s)
    rn[0] = WGS84_A / sqrt(w)
    rm[0] = rn[0] * (1.0 - WGS84_E2) / w


cdef inline double gravity(double lat, double h) noexcept nogil:
    """Normal gravity magnitude, m/s^2 (coefficients a1..a6 of ins.nav.earth.GRAVITY_COEFFS)."""
    cdef double s = sin(lat)
    cdef double s2 = s * s
    return (9.7803267715 * (1.0 + 0.0052790414 * s2 + 0.0000232718 * s2 * s2)
            + (-0.0000030876910891 + 0.0000000043977311 * s2) * h
            + 0.0000000000007211 * h * h)


cdef inline void earth_rate(double lat, double *wn, double *wd) noexcept nogil:
    """North and down components of the Earth rate in n (east is 0), rad/s."""
    wn[0] = OMEGA_IE * cos(lat)
    wd[0] = -OMEGA_IE * sin(lat)


cdef inline void transport_rate(double lat, double h, double vn, double ve,
                                double *tn, double *te, double *td) noexcept nogil:
    """Transport rate w_en_n (north, east, down), rad/s."""
    cdef double rm, rn
    radii(lat, &rm, &rn)
    tn[0] = ve / (rn + h)
    te[0] = -vn / (rm + h)
    td[0] = -ve * tan(lat) / (rn + h)
