"""``ins process`` with the formats of issue 15: the GNSS log as an RTKLIB .pos (written
in RTKLIB's llh layout from the flight's KF-GINS GNSS file) on a shifted clock undone by
--gnss-time-shift-s gives the same solution as the KF-GINS file; --format nav,sbet writes
the SBET and SMRMSG beside solution.nav with the same numbers."""
import numpy as np
import pytest
import tomllib

from ins.cli.main import main
from ins.io.gnss import read_gnss
from ins.io.navfiles import read_nav
from ins.io.sbet import read_sbet, read_smrmsg


@pytest.fixture(scope="module")
def flight():
    from test_filter import short_flight
    return short_flight()


def config(flight, tmp_path):
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
[filter]
end_s = {man['flight']['start_time_s'] + 200.0}
""")
    return cfg


def write_pos(path, gnss, shift_s, week=2300):
    """The GNSS log in RTKLIB's llh layout (GPST week/tow; more decimals than RTKLIB
    prints so that the two files carry the same numbers)."""
    lines = ["% program   : RTKPOST ver.2.4.3 b34",
             "% (lat/lon/height=WGS84/ellipsoidal,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,"
             "ns=# of satellites)",
             "%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   "
             "sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio"]
    lat, lon = np.rad2deg(gnss.lla[:, 0]), np.rad2deg(gnss.lla[:, 1])
    for k in range(len(gnss)):
        s = gnss.sigma_ned_m[k]
        lines.append(f"{week} {gnss.time[k] + shift_s:.6f} {lat[k]:.12f} {lon[k]:.12f} "
                     f"{gnss.lla[k, 2]:.5f}   1  10 {s[0]:.6f} {s[1]:.6f} {s[2]:.6f} "
                     f"0.0000 0.0000 0.0000 0.00 99.9")
    path.write_text("\n".join(lines) + "\n")


def test_rtklib_input_time_shift_and_sbet_output(flight, tmp_path):
    cfg = config(flight, tmp_path)
    gnss = read_gnss(flight / "gnss.txt")
    pos = tmp_path / "rover.pos"
    write_pos(pos, gnss, shift_s=0.5)
    common = ["--imu", str(flight / "imu.txt"), "--mount", str(flight / "mount.txt"),
              "--config", str(cfg), "--no-plots", "-q"]
    assert main(["process", "--gnss", str(flight / "gnss.txt"), *common,
                 "-o", str(tmp_path / "base")]) == 0
    assert main(["process", "--gnss", str(pos), "--gnss-time-shift-s", "-0.5",
                 "--format", "nav,sbet", *common, "-o", str(tmp_path / "rtk")]) == 0
    base = read_nav(tmp_path / "base" / "solution.nav")
    rtk = read_nav(tmp_path / "rtk" / "solution.nav")
    np.testing.assert_allclose(rtk.time, base.time)
    dpos = (rtk.lla[:, :2] - base.lla[:, :2]) * 6.4e6
    assert np.max(np.abs(dpos)) < 1e-4 and np.max(np.abs(rtk.lla[:, 2] - base.lla[:, 2])) < 1e-4
    # the SBET holds the same trajectory (the .nav is rounded to 1e-12 deg)
    sb = read_sbet(tmp_path / "rtk" / "sbet_solution.out")
    np.testing.assert_array_equal(sb.time, rtk.time)
    np.testing.assert_allclose(sb.lla[:, :2], rtk.lla[:, :2], rtol=0, atol=1e-13)
    np.testing.assert_allclose(sb.v_n, rtk.v_n, rtol=0, atol=1e-6)
    std = np.loadtxt(tmp_path / "rtk" / "solution_std.txt")
    acc = read_smrmsg(tmp_path / "rtk" / "smrmsg_solution.out")
    np.testing.assert_allclose(acc.time, std[:, 0], atol=1e-6)
    np.testing.assert_allclose(acc.sigma_pos_ned_m, std[:, 1:4], atol=1e-6)
    np.testing.assert_allclose(np.rad2deg(acc.sigma_rpy_rad), std[:, 7:10], atol=1e-8)


def test_bad_input_options(flight, tmp_path, capsys):
    cfg = config(flight, tmp_path)
    args = ["process", "--imu", str(flight / "imu.txt"), "--gnss", str(flight / "gnss.txt"),
            "--config", str(cfg), "-q", "-o", str(tmp_path / "o")]
    assert main(args + ["--format", "las"]) == 2
    assert "--format 'las'" in capsys.readouterr().err
    assert main(args + ["--gnss-quality", "fix"]) == 2
    assert "only RTKLIB" in capsys.readouterr().err
    assert main(args + ["--gnss-quality-scale", "float3"]) == 2
    assert "name=factor" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text(cfg.read_text() + "[gnss]\ntime_shift_s = \"x\"\n")
    args[args.index(str(cfg))] = str(bad)
    assert main(args) == 2
    assert "[gnss] time_shift_s" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_config_keys_and_imu_shift(tmp_path):
    from ins.estimation.pipeline.config import load_config
    from ins.io.imu_files import shift_time, shifted_blocks
    from ins.nav.imu import ImuLog
    p = tmp_path / "c.toml"
    p.write_text('[files]\nimu = "i.txt"\ngnss = "g.pos"\n[imu]\ntime_shift_s = 0.25\n'
                 '[gnss]\nformat = "rtklib"\ntime_shift_s = -0.2\nquality = "fix,float"\n'
                 'quality_scale = "float=3"\n')
    cfg = load_config(p)
    assert cfg.imu_time_shift_s == 0.25 and cfg.gnss_time_shift_s == -0.2
    assert cfg.gnss_format == "rtklib" and cfg.gnss_quality == {1, 2}
    assert cfg.gnss_quality_scale == {2: 3.0}
    log = ImuLog(np.array([1.0, 1.01, 1.02]), np.zeros((3, 3)), np.ones((3, 3)))
    moved = shift_time(log, 0.25)
    np.testing.assert_array_equal(moved.time, [1.25, 1.26, 1.27])
    np.testing.assert_array_equal(moved.dvel_b, log.dvel_b)
    assert [b.time[0] for b in shifted_blocks(iter([log, log]), -1.0)] == [0.0, 0.0]
    assert shift_time(log, 0.0) is log
    p.write_text('[files]\nimu = "i.txt"\ngnss = "g.pos"\n[gnss]\nquality = "fixed"\n')
    from ins.common.errors import InputError
    with pytest.raises(InputError, match=r"\[gnss\] quality: unknown quality 'fixed'"):
        load_config(p)
