"""``ins process``: flight folder and config runs, outputs, bad inputs (exit code 2, one
line naming the file/line or key, no output)."""
from pathlib import Path

import numpy as np
import pytest
import tomllib

from ins.cli.main import main
from ins.io.navfiles import read_nav

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def flight():
    from test_filter import short_flight
    return short_flight()


def test_flight_folder_run(flight, tmp_path, capsys):
    """Static alignment on the flight's stationary segment, then filter and smoother."""
    out = tmp_path / "out"
    assert main(["process", str(flight), "-o", str(out), "-q"]) == 0
    names = {p.name for p in out.iterdir()}
    assert {"solution.nav", "solution_std.txt", "imu_errors.txt",
            "sigma.png", "biases.png", "errors.png"} <= names
    assert "forward.nav" not in names                 # only with --forward
    assert not [n for n in names if n.startswith(".process-")]   # temporary files gone
    from ins.nav.accuracy import compare
    truth = read_nav(flight / "truth.nav")
    sol = read_nav(out / "solution.nav")
    e = compare(sol, truth)
    sel = e.time > e.time[0] + 120.0
    assert np.sqrt(np.mean(e.horizontal[sel] ** 2)) < 0.02
    std = np.loadtxt(out / "solution_std.txt")
    assert std.shape[1] == 10 and np.all(std[:, 1:] > 0)
    # the smoothed position error is within 4 sigma almost everywhere
    k = np.searchsorted(e.time, std[:, 0])
    k = k[k < len(e.time)]
    ratio = np.abs(e.pos_n[k]) / std[: len(k), 1:4]
    assert np.mean(ratio > 4) < 0.01
    bias = np.loadtxt(out / "imu_errors.txt")
    assert bias.shape[1] == 13


def test_config_run_and_summary(flight, tmp_path, capsys):
    man = tomllib.loads((flight / "manifest.toml").read_text())
    ini, arm = man["initial"], man["lever_arm"]
    cfg = tmp_path / "c.toml"
    cfg.write_text(f"""
[initial]
time_s = {man['flight']['start_time_s']}
lat_deg = {ini['lat_deg']}
lon_deg = {ini['lon_deg']}
h_m = {ini['h_m']}
vel_ned_mps = {list(ini['vel_ned_mps'])}
rpy_deg = {list(ini['rpy_deg'])}
att_std_deg = [0.05, 0.05, 0.2]
[imu_noise]
arw_deg_sqrth = 0.002
vrw_mps_sqrth = 0.002
gyro_bias_std_dph = 0.01
accel_bias_std_mgal = 40.0
corr_time_h = 1.0
[mount]
imu_to_platform_centre_b_m = {arm['imu_to_platform_centre_b_m']}
platform_centre_to_antenna_a_m = {arm['platform_centre_to_antenna_a_m']}
""")
    out = tmp_path / "o"
    code = main(["process", "--imu", str(flight / "imu.txt"), "--gnss", str(flight / "gnss.txt"),
                 "--mount", str(flight / "mount.txt"), "--config", str(cfg),
                 "--truth", str(flight / "truth.nav"), "--no-plots", "--forward",
                 "-o", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "0 rejected" in text and "smoothed" in text
    assert not list(out.glob("*.png"))
    assert len(read_nav(out / "forward.nav")) == len(read_nav(out / "solution.nav"))


def test_example_config_is_valid():
    from ins.estimation.pipeline.config import load_config
    p = ROOT / "data" / "configs" / "kfgins_like.toml"
    text = "[files]\nimu = 'a'\ngnss = 'b'\n" + p.read_text()
    tmp = ROOT / ".cache"
    tmp.mkdir(exist_ok=True)
    f = tmp / "kfgins_like_test.toml"
    f.write_text(text)
    cfg = load_config(f)
    assert cfg.method == "given" and cfg.noise.corr_time_h == 4.0
    np.testing.assert_array_equal(cfg.lever_bp, [0.8, 0.2, -1.5])
    f.unlink()


def _bad(args, capsys):
    code = main(["process"] + args)
    err = capsys.readouterr().err
    assert code == 2
    return err


def test_bad_inputs(flight, tmp_path, capsys):
    out = tmp_path / "out"
    assert "manifest.toml" in _bad([str(tmp_path), "-o", str(out)], capsys)
    assert "--config" in _bad(["--imu", "a", "--gnss", "b", "-o", str(out)], capsys)
    cfg = tmp_path / "c.toml"
    cfg.write_text("[imu_noise]\narw_deg_sqrt = 0.1\n")
    err = _bad(["--imu", str(flight / "imu.txt"), "--gnss", str(flight / "gnss.txt"),
                "--config", str(cfg), "-o", str(out)], capsys)
    assert "[imu_noise]" in err and "arw_deg_sqrt" in err
    cfg.write_text("[alignment]\nmethod = 'magic'\n")
    err = _bad(["--imu", str(flight / "imu.txt"), "--gnss", str(flight / "gnss.txt"),
                "--config", str(cfg), "-o", str(out)], capsys)
    assert "method" in err and "magic" in err
    # a zero sigma in the GNSS file: the line is named, nothing is written
    lines = (flight / "gnss.txt").read_text().splitlines()
    fields = lines[5].split()
    fields[5] = "0.0"
    lines[5] = " ".join(fields)
    bad = tmp_path / "gnss_bad.txt"
    bad.write_text("\n".join(lines) + "\n")
    cfg.write_text("[initial]\nlat_deg = 30\nlon_deg = 114\nh_m = 0\nvel_ned_mps = [0, 0, 0]\n"
                   "rpy_deg = [0, 0, 0]\n")
    err = _bad(["--imu", str(flight / "imu.txt"), "--gnss", str(bad), "--config", str(cfg),
                "-o", str(out)], capsys)
    assert "gnss_bad.txt:6: std_e_m = 0.0" in err
    assert not out.exists()


def test_help_states_units(capsys):
    with pytest.raises(SystemExit):
        main(["process", "--help"])
    text = capsys.readouterr().out
    assert "deg/sqrt(h)" in text and "north-east-down" in text and "solution.nav" in text


def test_in_air_start_from_gnss_track(flight):
    """Start in the air (no stationary data): heading from the GNSS track, a few deg off
    (crab); the filter converges and the smoother carries the solution back."""
    from test_filter import short_flight  # noqa: F401  (same cached flight)

    from ins.estimation.pipeline.process import process
    from ins.estimation.pipeline.config import config_from_manifest
    man = tomllib.loads((flight / "manifest.toml").read_text())
    cfg = config_from_manifest(str(flight))
    cfg.method = "gnss-heading"
    cfg.start_s = man["flight"]["start_time_s"] + 250.0
    res = process(cfg)
    assert res.alignment.method == "gnss-heading"
    e = res.errors_smoothed
    assert np.sqrt(np.mean(e.horizontal ** 2)) < 0.03
    late = e.time > e.time[0] + 60
    assert np.sqrt(np.mean(e.att_n[late, 2] ** 2)) * 206265 < 30       # heading, arcsec
    assert np.sqrt(np.mean(res.errors_forward.att_n[late, 2] ** 2)) * 206265 < 300


def test_euler_sigmas_against_a_numerical_jacobian():
    """Roll/pitch/yaw sigmas of euler_std_deg against J P J^T with J the central
    difference of scipy's ZYX angles under the phi perturbation C_est = Rot(-phi) C;
    a covariance that is not positive semi-definite raises naming the angle."""
    from scipy.spatial.transform import Rotation

    from ins.common.errors import QualityError
    from ins.estimation.pipeline.outputs import euler_std_deg
    rng = np.random.default_rng(7)
    for rpy in ([3.0, -2.0, 40.0], [-20.0, 35.0, -150.0], [5.0, 70.0, 10.0]):
        R = Rotation.from_euler("ZYX", rpy[::-1], degrees=True)
        L = rng.normal(0, 1e-3, (3, 3))
        P = L @ L.T
        J = np.zeros((3, 3))
        for k in range(3):
            d = np.zeros(3)
            d[k] = 1e-7
            plus = (Rotation.from_rotvec(-d) * R).as_euler("ZYX")[::-1]
            minus = (Rotation.from_rotvec(d) * R).as_euler("ZYX")[::-1]
            J[:, k] = (plus - minus) / 2e-7
        expect = np.rad2deg(np.sqrt(np.diag(J @ P @ J.T)))
        got = euler_std_deg(R.as_quat()[None, :], P[None])[0]
        np.testing.assert_allclose(got, expect, rtol=1e-5)
    bad = np.diag([1e-6, -1e-6, 1e-6])
    with pytest.raises(QualityError, match="attitude .* state pitch"):
        euler_std_deg(np.array([[0.0, 0.0, 0.0, 1.0]]), bad[None])


def test_orthometric_heights_file(flight, tmp_path, capsys):
    """--height orthometric:MODEL: solution_orthometric.txt beside the (ellipsoidal)
    solution.nav, the model in its header, H = h - N at every epoch; a bad --height
    stops before the run with nothing written."""
    from ins.io.geoid import load_geoid
    try:
        g = load_geoid("EGM96")
    except Exception as exc:
        pytest.skip(f"no EGM96 grid: {exc}")
    out = tmp_path / "out"
    assert main(["process", str(flight), "-o", str(out), "-q", "--no-plots",
                 "--height", "orthometric:EGM96"]) == 0
    text = (out / "solution_orthometric.txt").read_text().splitlines()
    assert "geoid EGM96 (EPSG:5773)" in text[0] and "H_egm96_m" in text[1]
    rows = np.loadtxt(out / "solution_orthometric.txt")
    sol = np.loadtxt(out / "solution.nav")
    assert rows.shape == (len(sol), 7)
    np.testing.assert_array_equal(rows[:, :5], sol[:, :5])        # same epochs and h
    N = g.undulation(np.deg2rad(rows[:, 2]), np.deg2rad(rows[:, 3]))
    np.testing.assert_allclose(rows[:, 5], N, atol=1e-5)
    np.testing.assert_allclose(rows[:, 6], rows[:, 4] - rows[:, 5], atol=2e-5)
    capsys.readouterr()
    assert main(["process", str(flight), "-o", str(tmp_path / "o2"), "-q",
                 "--height", "orthometric:XGM"]) == 2
    assert "--height" in capsys.readouterr().err and not (tmp_path / "o2").exists()
