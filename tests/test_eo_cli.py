"""``photogrammetry eo`` on a simulated flight folder: the chain reproduces the
simulator's true EO from the true 200 Hz trajectory; explicit inputs, formats, errors."""
import numpy as np
import pytest

from photogrammetry.cli.main import main
from photogrammetry.orientation.exposure import read_eo_applanix, read_eo_csv, read_eo_patb

ARCSEC = np.pi / 180 / 3600
PLAN = __import__("pathlib").Path(__file__).parent / "data" / "flights" / "short.toml"


def angle_err_arcsec(a, b):
    return np.abs(np.angle(np.exp(1j * (a - b)))) / ARCSEC


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    folder_mod = pytest.importorskip("photogrammetry.simulate.folder")
    tmp = tmp_path_factory.mktemp("eo_flight")
    plan = tmp / "plan200.toml"
    text = PLAN.read_text()
    assert "rate_hz = 100.0" in text
    plan.write_text(text.replace("rate_hz = 100.0", "rate_hz = 200.0", 1))   # [imu] 200 Hz
    return folder_mod.simulate_flight(plan, tmp / "flight", seed=5)


@pytest.mark.parametrize("system, truth", [("phi-omega-kappa", "eo_true.csv"),
                                           ("omega-phi-kappa", "eo_true_omega-phi-kappa.csv")])
def test_flight_folder_reproduces_true_eo(flight, tmp_path, system, truth, capsys):
    out = tmp_path / "eo.csv"
    assert main(["eo", str(flight), "--system", system, "-o", str(out)]) == 0
    assert "exposures" in capsys.readouterr().out
    eo, ref = read_eo_csv(out), read_eo_csv(flight / truth)
    assert eo.image_id == ref.image_id and eo.system == ref.system == system
    assert eo.frame == ref.frame
    # truth.nav stores h to 1e-5 m and angles to 1e-9 deg: the floor of this comparison
    assert np.abs(eo.position - ref.position).max() < 2e-5          # sub-millimetre
    assert angle_err_arcsec(eo.angles, ref.angles).max() < 0.01      # under 0.1 arcsec
    assert np.abs(eo.time - ref.time).max() < 1e-6


def test_explicit_inputs_formats_sigma(flight, tmp_path):
    std = tmp_path / "solution_std.txt"
    nav = np.loadtxt(flight / "truth.nav")
    t = nav[::200, 1]
    cols = np.column_stack([t] + [np.full_like(t, v) for v in
                                  (0.02, 0.03, 0.05, 0.01, 0.01, 0.02, 0.002, 0.003, 0.01)])
    np.savetxt(std, cols, fmt="%.6f")
    args = ["eo", "--trajectory", str(flight / "truth.nav"), "--events",
            str(flight / "events.csv"), "--camera", str(flight / "camera.toml"), "-q"]
    out = tmp_path / "utm.csv"
    assert main(args + ["--frame", "utm", "--sigma", str(std), "--system", "omega-phi-kappa",
                        "-o", str(out)]) == 0
    eo = read_eo_csv(out)
    assert eo.frame == "EPSG:32650; heights = ellipsoidal" and eo.has_sigmas
    # the header names the sigma file: refine takes the boresight's INS sigma from it
    from photogrammetry.orientation.exposure import read_eo_header
    assert read_eo_header(out)["trajectory sigma"] == str(std)
    # independent: the ENU result back to lat/lon (pymap3d), then pyproj's UTM 50N
    import pymap3d
    import pyproj
    enu_out = tmp_path / "enu.csv"
    assert main(args + ["--origin", "30.5,114.3,20", "-o", str(enu_out)]) == 0
    enu = read_eo_csv(enu_out)
    lat, lon, h = pymap3d.enu2geodetic(*enu.position.T, 30.5, 114.3, 20.0)
    e, n = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32650",
                                       always_xy=True).transform(lon, lat)
    assert np.abs(eo.position - np.column_stack([e, n, h])).max() < 1e-5
    assert np.all(eo.position_sigma > 0.019) and np.all(eo.position_sigma < 0.051)
    # the same via the Applanix and PATB writers
    for fmt, reader in (("applanix", read_eo_applanix), ("patb", read_eo_patb)):
        p = tmp_path / f"eo.{fmt}"
        assert main(args + ["--frame", "utm", "--format", fmt, "-o", str(p)]) == 0
        other = reader(p)
        assert np.abs(other.matrices() - eo.matrices()).max() < 1e-11
        assert np.abs(other.position - eo.position).max() < 1e-6


def test_errors(flight, tmp_path, capsys):
    out = tmp_path / "eo.csv"
    assert main(["eo", "--trajectory", str(flight / "truth.nav"), "-o", str(out)]) == 2
    assert "--events is required" in capsys.readouterr().err
    ev = tmp_path / "events.csv"
    ev.write_text("image_id,time_s\nlate_image,999999.0\n")
    assert main(["eo", str(flight), "--events", str(ev), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "event late_image at t = 999999.0 s is outside the trajectory" in err
    assert main(["eo", str(tmp_path), "-o", str(out)]) == 2
    assert "no manifest.toml" in capsys.readouterr().err
    assert not out.exists()


def test_orthometric_heights_of_a_geoid_model(flight, tmp_path, capsys):
    """--height orthometric:MODEL: Z = h - N(lat, lon) at each perspective centre, the
    header names the model; refused with --geoid-undulation and in the ENU frame."""
    from ins.io.geoid import load_geoid
    try:
        g = load_geoid("EGM2008")
    except Exception as exc:
        pytest.skip(f"no EGM2008 grid: {exc}")
    base = ["eo", str(flight), "--frame", "utm", "-q"]
    assert main(base + ["-o", str(tmp_path / "e.csv")]) == 0
    assert main(base + ["--height", "orthometric:EGM2008", "-o", str(tmp_path / "o.csv")]) == 0
    e, o = read_eo_csv(tmp_path / "e.csv"), read_eo_csv(tmp_path / "o.csv")
    assert "orthometric (geoid EGM2008, EPSG:3855" in o.frame
    import pyproj
    lon, lat = pyproj.Transformer.from_crs("EPSG:32650", "EPSG:4326", always_xy=True
                                           ).transform(e.position[:, 0], e.position[:, 1])
    N = g.undulation(np.deg2rad(lat), np.deg2rad(lon))
    assert np.abs(e.position[:, 2] - o.position[:, 2] - N).max() < 2e-6   # 6 decimals
    assert np.abs(e.position[:, :2] - o.position[:, :2]).max() == 0
    assert np.abs(e.angles - o.angles).max() == 0
    capsys.readouterr()
    assert main(base + ["--height", "orthometric", "--geoid-undulation", "-10",
                        "-o", str(tmp_path / "x.csv")]) == 2
    assert "not both" in capsys.readouterr().err
    assert main(["eo", str(flight), "--height", "orthometric", "-o",
                 str(tmp_path / "x.csv")]) == 2
    assert "projected frames only" in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()
