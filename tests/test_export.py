"""``ins export``: GeoJSON, KML and CSV read back by libraries other than the writers
(which use the standard library's json and text), against independent values.

- GeoJSON: GDAL's GeoJSON driver (fiona) reads the features; the UTC times against
  astropy's GPS -> UTC; RFC 7946's rules (lon, lat order, ellipsoidal third coordinate,
  no ``crs`` member).
- KML: fastkml parses the file and validates it against the OGC KML 2.2 schema (lxml);
  GDAL's KML driver (fiona) reads the coordinates.
- CSV: UTM coordinates against the ``utm`` package (its own Krueger series), Web Mercator
  against the closed form, lat/lon against the .nav itself.
"""
import csv
import json

import numpy as np
import pytest

from ins.cli.main import main
from ins.io.gnss_log import GnssLog
from ins.io.navfiles import write_nav
from ins.io.rtklib import write_pos
from ins.nav.rotation import euler_to_quat
from ins.nav.trajectory import Trajectory

WEEK = 2300                      # 2024-02-04 .. 2024-02-10
T0 = 345600.0                    # Thursday 00:00 GPS
LAT0, LON0, H0 = 30.5, 114.3, 120.0


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A 200 s turn at 10 Hz (solution.nav), its sigmas at 1 Hz (solution_std.txt) and an
    RTKLIB GNSS solution at 1 Hz (gnss.pos): fix, then float, then single, then none."""
    d = tmp_path_factory.mktemp("export")
    n = 2001
    t = T0 + 0.1 * np.arange(n)
    a = np.deg2rad(0.9 * (t - T0))                       # 180 deg in 200 s
    R = 500.0
    north, east = R * np.sin(a), R * (1 - np.cos(a))
    lat = np.deg2rad(LAT0) + north / 6.36e6
    lon = np.deg2rad(LON0) + east / (6.38e6 * np.cos(np.deg2rad(LAT0)))
    h = H0 + 0.05 * (t - T0)
    yaw = np.mod(np.rad2deg(a), 360.0)
    v = R * np.deg2rad(0.9)
    v_n = np.column_stack([v * np.cos(a), v * np.sin(a), np.zeros(n)])
    rpy = np.column_stack([np.full(n, 5.0), np.full(n, 1.0), yaw])
    traj = Trajectory(t, np.column_stack([lat, lon, h]), v_n, euler_to_quat(rpy, degrees=True))
    write_nav(d / "solution.nav", traj, week=WEEK)
    tn = t[::10]
    sd = np.tile([0.02, 0.03, 0.05, 0.01, 0.01, 0.01, 0.003, 0.003, 0.01], (len(tn), 1))
    sd[120:, :2] = [0.3, 0.4]                            # sigma_h 0.5 m after 120 s
    np.savetxt(d / "solution_std.txt", np.column_stack([tn, sd]), fmt="%.6f",
               header="time_s std_n_m std_e_m std_d_m ...")
    k = np.arange(0, 1800, 10)                           # GNSS for the first 180 s
    q = np.select([k < 800, k < 1200], [1, 2], 5)
    log = GnssLog(t[k], np.column_stack([lat[k], lon[k], h[k]]), np.full((len(k), 3), 0.02),
                  quality=q)
    write_pos(d / "gnss.pos", log, week=WEEK)
    return {"dir": d, "traj": traj, "n": n, "quality_by_index": (np.arange(n) // 10 * 10)}


def _export(run, name, *extra):
    out = run["dir"] / name
    assert main(["export", str(run["dir"] / "solution.nav"), "-o", str(out), "-q",
                 *extra]) == 0
    return out


def _idx(n, every):
    idx = np.arange(0, n, every)
    return idx if idx[-1] == n - 1 else np.r_[idx, n - 1]


def _expected_quality(i):
    """Q at epoch index i (10 Hz) of the fixture: GNSS at every 10th epoch up to 1790."""
    nearest = int(round(i / 10.0)) * 10
    if abs(i - nearest) > 5 or nearest >= 1800:
        return 0
    return 1 if nearest < 800 else 2 if nearest < 1200 else 5


def test_geojson_read_by_gdal(run):
    import fiona
    from astropy.time import Time
    out = _export(run, "track.geojson", "--every", "7")
    doc = json.loads(out.read_text())
    assert doc["type"] == "FeatureCollection" and "crs" not in doc          # RFC 7946
    with fiona.open(out) as src:
        assert src.driver == "GeoJSON"
        feats = list(src)
    lines = [f for f in feats if f["geometry"]["type"] == "LineString"]
    points = [f for f in feats if f["geometry"]["type"] == "Point"]
    idx = _idx(run["n"], 7)
    assert len(lines) == 1 and len(points) == len(idx)
    traj = run["traj"]
    want = np.column_stack([np.rad2deg(traj.lla[idx, 1]), np.rad2deg(traj.lla[idx, 0]),
                            traj.lla[idx, 2]])
    got = np.array(lines[0]["geometry"]["coordinates"])
    np.testing.assert_allclose(got[:, :2], want[:, :2], atol=1e-9)        # lon, lat deg
    np.testing.assert_allclose(got[:, 2], want[:, 2], atol=1e-4)          # ellipsoidal h
    p = [dict(f["properties"]) for f in points]
    gps = Time(np.array([x["gps_week"] * 604800.0 + x["gps_time_s"] for x in p]),
               format="gps")
    from datetime import datetime, timezone
    got_utc = [datetime.fromisoformat(str(x["utc"])).astimezone(timezone.utc) for x in p]
    want_utc = [d.replace(tzinfo=timezone.utc) for d in gps.utc.to_datetime()]
    assert max(abs((a - b).total_seconds()) for a, b in zip(got_utc, want_utc)) < 1e-3
    assert json.loads(out.read_text())["features"][1]["properties"]["utc"].endswith("Z")
    assert [x["gnss_quality"] for x in p] == [_expected_quality(i) for i in idx]
    sig_h = np.array([x["sigma_h_m"] for x in p])
    t = np.array([x["gps_time_s"] for x in p]) - T0
    np.testing.assert_allclose(sig_h[t >= 121], 0.5, atol=1e-4)
    np.testing.assert_allclose(sig_h[t <= 119], np.hypot(0.02, 0.03), atol=1e-4)
    assert all(x["h_ellipsoidal_m"] == pytest.approx(h, abs=1e-4)
               for x, h in zip(p, want[:, 2]))


def test_geojson_orthometric_keeps_rfc_coordinates(run):
    from ins.io.geoid import load_geoid
    try:
        g = load_geoid("EGM2008")
    except Exception as exc:
        pytest.skip(f"no EGM2008 grid: {exc}")
    out = _export(run, "ortho.geojson", "--every", "100", "--height", "orthometric:EGM2008")
    doc = json.loads(out.read_text())
    line = doc["features"][0]
    assert "EGM2008" in line["properties"]["heights"]
    coords = np.array(line["geometry"]["coordinates"])
    pts = [f["properties"] for f in doc["features"][1:]]
    H = np.array([x["H_egm2008_m"] for x in pts])
    N = g.undulation(np.deg2rad(coords[:, 1]), np.deg2rad(coords[:, 0]))
    np.testing.assert_allclose(coords[:, 2], H + N, atol=2e-4)   # third coordinate: h
    assert -20 < N.mean() < -5                                   # central China


def test_kml_schema_valid_and_read_by_gdal(run):
    import fiona
    from fastkml import kml
    out = _export(run, "track.kml", "--every", "5", "--height", "ellipsoidal")
    k = kml.KML.parse(str(out), strict=True, validate=True)      # OGC KML 2.2 XSD
    doc = k.features[0]
    styles = {s.id: s for s in doc.styles}
    assert styles["c1"].styles[2].color == "ff00c800"            # fix: green line
    track_folder, epochs = doc.features
    segments = track_folder.features
    assert [s.name for s in segments] == ["fix", "float", "single", "no GNSS"]
    assert [s.style_url.url for s in segments] == ["#c1", "#c2", "#c5", "#c0"]
    idx = _idx(run["n"], 5)
    assert len(epochs.features) == len(idx)
    first = epochs.features[0]
    assert first.times.timestamp.dt.utcoffset().total_seconds() == 0
    # GPS 2024-02-08T00:00:00 = UTC 2024-02-07T23:59:42; check the stamp against astropy
    from astropy.time import Time
    want = Time(WEEK * 604800.0 + T0, format="gps").utc.isot[:19]
    assert first.times.timestamp.dt.strftime("%Y-%m-%dT%H:%M:%S") == want
    fiona.drvsupport.supported_drivers["KML"] = "r"
    with fiona.open(out, layer="epochs", driver="KML") as src:
        got = np.array([f["geometry"]["coordinates"] for f in src])
    traj = run["traj"]
    np.testing.assert_allclose(got[:, 0], np.rad2deg(traj.lla[idx, 1]), atol=1e-9)
    np.testing.assert_allclose(got[:, 1], np.rad2deg(traj.lla[idx, 0]), atol=1e-9)
    np.testing.assert_allclose(got[:, 2], traj.lla[idx, 2], atol=1e-4)
    with fiona.open(out, layer="track", driver="KML") as src:
        lines = list(src)
    assert sum(len(f["geometry"]["coordinates"]) for f in lines) == len(idx) + 3  # joins


def test_kml_coloured_by_sigma(run):
    from fastkml import kml
    out = _export(run, "sigma.kml", "--every", "10", "--color-by", "sigma",
                  "--height", "ellipsoidal", "--no-points")
    doc = kml.KML.parse(str(out), strict=True, validate=True).features[0]
    segs = doc.features[0].features
    assert [s.style_url.url for s in segs] == ["#c1", "#c3"]     # < 5 cm, then 0.5 m
    assert len(doc.features) == 1                                # --no-points


def _read_csv(path):
    lines = path.read_text().splitlines()
    head = [ln for ln in lines if ln.startswith("#")]
    rows = list(csv.DictReader([ln for ln in lines if not ln.startswith("#")]))
    return head, rows


def test_csv_utm_against_utm_package(run):
    import utm
    out = _export(run, "utm.csv", "--crs", "EPSG:32650", "--min-spacing-m", "25")
    head, rows = _read_csv(out)
    assert any("EPSG:32650" in h and "UTM zone 50N" in h for h in head)
    assert any("ellipsoidal" in h for h in head)
    assert {"easting_m", "northing_m", "h_ellipsoidal_m", "utc", "gnss_quality"} <= set(rows[0])
    e = np.array([float(r["easting_m"]) for r in rows])
    nn = np.array([float(r["northing_m"]) for r in rows])
    t = np.array([float(r["gps_time_s"]) for r in rows])
    traj = run["traj"]
    k = np.searchsorted(traj.time, t)
    lat, lon = np.rad2deg(traj.lla[k, 0]), np.rad2deg(traj.lla[k, 1])
    ue, un, zone, letter = utm.from_latlon(lat, lon, force_zone_number=50)
    np.testing.assert_allclose(e, ue, atol=2e-3)
    np.testing.assert_allclose(nn, un, atol=2e-3)
    # decimation: consecutive points >= 25 m apart along the track, the last one kept
    step = np.hypot(np.diff(e), np.diff(nn))
    assert np.all(step[:-1] >= 25.0 - 0.01) and k[-1] == run["n"] - 1
    arc = np.pi * 500.0                                   # the half circle, m
    assert int(arc / 25) + 1 <= len(rows) <= int(arc / 25) + 2


def test_csv_web_mercator_and_latlon(run):
    out = _export(run, "merc.csv", "--crs", "EPSG:3857", "--every", "200")
    _, rows = _read_csv(out)
    traj = run["traj"]
    idx = _idx(run["n"], 200)
    lat, lon = traj.lla[idx, 0], traj.lla[idx, 1]
    R = 6378137.0
    np.testing.assert_allclose([float(r["easting_m"]) for r in rows], R * lon, atol=1e-3)
    np.testing.assert_allclose([float(r["northing_m"]) for r in rows],
                               R * np.log(np.tan(np.pi / 4 + lat / 2)), atol=1e-3)
    out = _export(run, "ll.csv", "--every", "200")
    head, rows = _read_csv(out)
    assert list(rows[0])[3:5] == ["lat_deg", "lon_deg"]          # EPSG:4326 axis order
    np.testing.assert_allclose([float(r["lat_deg"]) for r in rows], np.rad2deg(lat),
                               atol=1e-9)


def test_week_unknown_no_utc(run, tmp_path):
    from ins.io.navfiles import read_nav
    traj = read_nav(run["dir"] / "solution.nav")
    write_nav(tmp_path / "w0.nav", traj, week=0)
    out = tmp_path / "w0.csv"
    assert main(["export", str(tmp_path / "w0.nav"), "-o", str(out), "-q"]) == 0
    head, rows = _read_csv(out)
    assert "utc" not in rows[0] and "gps_week" not in rows[0]
    assert any("no UTC" in h for h in head)
    assert "sigma_h_m" not in rows[0] and "gnss_quality" not in rows[0]   # none beside


@pytest.mark.parametrize("args, match", [
    (["-o", "{d}/x.shp"], "unknown extension"),
    (["-o", "{d}/x.geojson", "--crs", "EPSG:32650"], "--crs is for CSV"),
    (["-o", "{d}/x.csv", "--crs", "EPSG:32650+3855"], "horizontal CRS"),
    (["-o", "{d}/x.csv", "--crs", "EPSG:99999"], "not a CRS"),
    (["-o", "{d}/x.csv", "--height", "msl"], "--height"),
    (["-o", "{d}/solution.nav", "--format", "csv"], "would overwrite the input"),
    (["-o", "{d}/x.kml", "--height", "ellipsoidal", "--std", "{d}/nothere.txt"],
     "nothere.txt"),
])
def test_bad_options(run, capsys, args, match):
    d = str(run["dir"])
    before = (run["dir"] / "solution.nav").read_bytes()
    argv = ["export", f"{d}/solution.nav"] + [a.format(d=d) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert match in err and len(err.strip().splitlines()) == 1
    assert (run["dir"] / "solution.nav").read_bytes() == before
    assert not list(run["dir"].glob(".*.part"))


def test_bad_solution_line_named(tmp_path, capsys):
    bad = tmp_path / "bad.nav"
    bad.write_text("2300 1.0 30.0 114.0 10.0 0 0 0 0 0 0\n2300 2.0 95.0 114.0 10 0 0 0 0 0 0\n")
    assert main(["export", str(bad), "-o", str(tmp_path / "o.geojson")]) == 2
    assert f"{bad}:2:" in capsys.readouterr().err
    assert not (tmp_path / "o.geojson").exists()


def test_decimate_indices():
    from ins.io.track import Track, decimate_indices
    n = 101
    lla = np.column_stack([np.zeros(n), np.deg2rad(np.linspace(0, 1e-3, n)), np.zeros(n)])
    tr = Track(np.arange(n, dtype=float), lla)
    assert list(decimate_indices(tr, every=30)) == [0, 30, 60, 90, 100]
    step = 6378137.0 * np.deg2rad(1e-5)                  # 1.113 m between epochs
    idx = decimate_indices(tr, min_spacing_m=3 * step - 1e-6)
    assert list(idx) == list(range(0, 100, 3)) + [100]
    rest = Track(np.arange(5.0), np.zeros((5, 3)))
    assert list(decimate_indices(rest, min_spacing_m=1.0)) == [0, 4]


def test_kml_default_height_falls_back_to_egm2008(run, monkeypatch, capsys):
    """KML without --height: EGM96 (Google Earth's sea level); without an EGM96 grid
    EGM2008 with a warning; with neither an error that names both ways out."""
    from ins.io import geoid
    real = geoid.load_geoid

    def no96(name):
        if str(name).upper() == "EGM96":
            raise InputError("geoid model EGM96: no grid found")
        return real(name)

    from ins.common.errors import InputError
    monkeypatch.setattr(geoid, "load_geoid", no96)
    try:
        real("EGM2008")
    except InputError:
        pytest.skip("no EGM2008 grid")
    out = run["dir"] / "fallback.kml"
    assert main(["export", str(run["dir"] / "solution.nav"), "-o", str(out), "-q",
                 "--every", "500"]) == 0
    assert "no EGM96 grid installed, EGM2008" in capsys.readouterr().err
    assert "geoid EGM2008" in out.read_text()
    monkeypatch.setattr(geoid, "load_geoid", lambda name: (_ for _ in ()).throw(
        InputError(f"geoid model {name}: no grid found")))
    assert main(["export", str(run["dir"] / "solution.nav"), "-o",
                 str(run["dir"] / "none.kml"), "-q"]) == 2
    assert "--height ellipsoidal" in capsys.readouterr().err


def test_sbet_input_with_smrmsg(run, tmp_path):
    """An SBET and its SMRMSG beside it (the sigmas found by name)."""
    from ins.io.navfiles import read_nav
    from ins.io.sbet import write_sbet, write_smrmsg
    traj = read_nav(run["dir"] / "solution.nav")
    write_sbet(tmp_path / "sbet_solution.out", traj)
    t = traj.time[::10]
    write_smrmsg(tmp_path / "smrmsg_solution.out", t, np.tile([0.1, 0.2, 0.3], (len(t), 1)),
                 np.full((len(t), 3), 0.01), np.full((len(t), 3), 1e-4))
    out = tmp_path / "s.csv"
    assert main(["export", str(tmp_path / "sbet_solution.out"), "-o", str(out), "-q",
                 "--week", str(WEEK), "--every", "100"]) == 0
    _, rows = _read_csv(out)
    np.testing.assert_allclose([float(r["sigma_h_m"]) for r in rows], np.hypot(0.1, 0.2),
                               atol=1e-4)
    assert rows[0]["utc"].startswith("2024-02-07T23:59:42")
