"""The Earth model of the compiled kernels (``ins/nav/_earth.pxd``, C) against its Python
source (``ins.nav.earth``'s ``_radii``, ``_gravity``, ``_earth_rate``, ``_transport_rate``).

earth.py's own code is run with the C library's sin/cos/tan/sqrt (those the compiled
kernels and the numba kernels call) and must give the same numbers to the last bit.  Run
with numpy's ufuncs it differs only where numpy's tan rounds differently from the C
library's (1 ulp of tan; a few ulps of the transport rate's down component)."""
import math
import types

import numpy as np
import pytest

from ins.nav import _kernels, earth

#: earth.py's functions with ``np`` bound to the C library's scalar functions.
_LIBM = types.SimpleNamespace(sin=math.sin, cos=math.cos, tan=math.tan, sqrt=math.sqrt)


def _with_libm(fn):
    glb = dict(vars(earth))
    glb["np"] = _LIBM
    f = types.FunctionType(fn.__code__, glb, fn.__name__)
    glb[fn.__name__] = f
    return f


_radii, _gravity, _earth_rate, _transport_rate = (
    _with_libm(f) for f in (earth._radii, earth._gravity, earth._earth_rate,
                            earth._transport_rate))


def _points():
    """Latitudes from pole to pole (with the equator, +-45 deg and values near the
    poles), heights from -500 m to 30 km, velocities up to 300 m/s, both signs."""
    rng = np.random.default_rng(26)
    lat = np.concatenate([np.deg2rad(np.linspace(-89.9, 89.9, 3599)),
                          [0.0, np.pi / 4, -np.pi / 4, np.deg2rad(89.999), np.deg2rad(-89.999)],
                          rng.uniform(-1.5, 1.5, 2000)])
    n = len(lat)
    h = np.concatenate([np.linspace(-500.0, 30000.0, n - 2000), rng.uniform(-100, 12000, 2000)])
    v_north = rng.uniform(-300.0, 300.0, n)
    v_east = rng.uniform(-300.0, 300.0, n)
    v_north[:10] = 0.0
    v_east[10:20] = 0.0
    return lat, h, v_north, v_east


def _python_terms(lat, h, vn, ve):
    """The eight columns of :func:`ins.nav._kernels.earth_terms` from earth.py's code,
    point by point with the C library's functions, and vectorized with numpy's."""
    rows = []
    for a, b, c, d in zip(lat.tolist(), h.tolist(), vn.tolist(), ve.tolist()):
        rm, rn = _radii(a)
        wn, _, wd = _earth_rate(a)
        tn, te, td = _transport_rate(a, b, c, d)
        rows.append((rm, rn, _gravity(a, b), wn, wd, tn, te, td))
    libm = np.array(rows, dtype=float)
    rm, rn = earth._radii(lat)
    wn, _, wd = earth._earth_rate(lat)
    tn, te, td = earth._transport_rate(lat, h, vn, ve)
    numpy = np.column_stack([rm, rn, earth._gravity(lat, h), wn, wd, tn, te, td])
    return libm, numpy


def _ulps(a, b):
    """Distance in units of the last place of ``a`` (0 where equal)."""
    diff = np.abs(a - b)
    return np.where(diff == 0.0, 0.0, diff / np.spacing(np.abs(a)))


def test_native_earth_equals_python_formulas():
    lat, h, vn, ve = _points()
    out = np.empty((len(lat), 8))
    _kernels.earth_terms(lat, h, vn, ve, out)
    libm, numpy = _python_terms(lat, h, vn, ve)
    assert np.array_equal(libm, out)                  # the same formulas, bit for bit
    ulps = _ulps(numpy, out)
    assert np.array_equal(numpy[:, :7], out[:, :7])   # no tan in these
    assert np.max(ulps[:, 7]) <= 4.0


def test_comparison_resolves_one_ulp():
    """The bit-for-bit comparison can fail: among the points are some where numpy's tan
    and the C library's differ by an ulp, and there the compiled value follows the C
    library's (earth.py's code under the shim), not numpy's."""
    lat, h, vn, ve = _points()
    out = np.empty((len(lat), 8))
    _kernels.earth_terms(lat, h, vn, ve, out)
    libm, numpy = _python_terms(lat, h, vn, ve)
    differ = np.tan(lat) != np.array([math.tan(x) for x in lat.tolist()])
    assert np.count_nonzero(differ) >= 5
    moved = numpy[:, 7] != out[:, 7]
    assert np.any(moved & differ)
    assert np.array_equal(libm[moved, 7], out[moved, 7])


def test_native_earth_values_are_the_model():
    """An independent check of the shared model: the radii and gravity at the equator and
    the pole from the WGS84 constants of the conventions page."""
    lat = np.array([0.0, np.pi / 2])
    z = np.zeros(2)
    out = np.empty((2, 8))
    _kernels.earth_terms(lat, z, z, z, out)
    a, f = 6378137.0, 1 / 298.257223563
    e2 = f * (2 - f)
    assert out[0, 1] == pytest.approx(a, rel=1e-15)                     # N at the equator
    assert out[0, 0] == pytest.approx(a * (1 - e2), rel=1e-15)          # M at the equator
    assert out[1, 0] == pytest.approx(a / np.sqrt(1 - e2), rel=1e-15)   # M = N at the pole
    assert out[1, 1] == pytest.approx(out[1, 0], rel=1e-15)
    assert out[0, 2] == pytest.approx(9.7803267715, rel=1e-15)
    assert out[1, 2] == pytest.approx(9.7803267715 * (1 + 0.0052790414 + 0.0000232718),
                                      rel=1e-15)
    assert out[0, 3] == 7.292115e-5 and out[0, 4] == 0.0


def test_earth_terms_checks_shapes():
    with pytest.raises(ValueError, match="same length"):
        _kernels.earth_terms(np.zeros(3), np.zeros(2), np.zeros(3), np.zeros(3),
                             np.empty((3, 8)))
