"""LiDAR georeferencing: analytic cases (pymap3d as the geodesy oracle, rotations written
by hand or through scipy), the propagated sigmas against a Monte Carlo of the inputs."""
import numpy as np
import pymap3d
import pytest
from scipy.spatial.transform import Rotation

from ins.lidar.georeference import TrajectoryStd, georeference, read_trajectory_std
from ins.lidar.scanner import Scanner, scanner_rays
from ins.nav.trajectory import Trajectory

LAT, LON, H = 30.5, 114.3, 1200.0


def _static(rpy_deg, n=11):
    """A trajectory at rest (exact interpolation) with a fixed attitude."""
    q = Rotation.from_euler("ZYX", np.deg2rad(rpy_deg[::-1])).as_quat()
    return Trajectory(time=np.arange(n, dtype=float),
                      lla=np.tile([np.deg2rad(LAT), np.deg2rad(LON), H], (n, 1)),
                      v_n=np.zeros((n, 3)), q_nb=np.tile(q, (n, 1)))


def _lla_deg(points):
    lla = points.lla()
    return np.column_stack([np.rad2deg(lla[:, :2]), lla[:, 2]])


def _expected(ned):
    ned = np.atleast_2d(ned)
    return np.column_stack(pymap3d.ned2geodetic(ned[:, 0], ned[:, 1], ned[:, 2], LAT, LON, H))


def _close(got, exp, tol_m=1e-6):
    d = np.array(pymap3d.geodetic2ned(got[:, 0], got[:, 1], got[:, 2],
                                      exp[:, 0], exp[:, 1], exp[:, 2])).T
    assert np.abs(d).max() < tol_m, np.abs(d).max()


def test_nadir_ray_level():
    """Level flight, nadir ray: the point is the position minus range times up."""
    traj = _static([0.0, 0.0, 37.0])
    rho = np.array([100.0, 1000.0, 1500.0])
    pts = georeference(traj, [1.0, 2.5, 9.9], scanner_rays(rho, np.zeros(3)), Scanner())
    _close(_lla_deg(pts), _expected(np.column_stack([0 * rho, 0 * rho, rho])))
    assert np.allclose(_lla_deg(pts)[:, 2], H - rho, atol=1e-6)   # straight down


@pytest.mark.parametrize("roll_deg", [-12.0, 5.0, 20.0])
def test_roll_tilts_the_ray(roll_deg):
    """Heading north, roll phi: the nadir ray of the body points phi to the LEFT (west);
    a scan angle equal to the roll points straight down (hand-written Rx)."""
    traj = _static([roll_deg, 0.0, 0.0])
    rho, phi = 800.0, np.deg2rad(roll_deg)
    pts = georeference(traj, [3.0, 3.0], scanner_rays([rho, rho], [0.0, phi]), Scanner())
    exp = _expected([[0.0, -rho * np.sin(phi), rho * np.cos(phi)], [0.0, 0.0, rho]])
    _close(_lla_deg(pts), exp)


def test_lever_arm_and_boresight_heading_east():
    """Heading 90 deg: body forward = east; lever arm and boresight rx tilt (by hand)."""
    traj = _static([0.0, 0.0, 90.0])
    eps = np.deg2rad(0.5)
    sc = Scanner(lever_arm_m=[2.0, 0.5, -0.3], boresight_rad=[eps, 0.0, 0.0])
    rho = 500.0
    pts = georeference(traj, [4.0], scanner_rays([rho], [0.0]), sc)
    # in b: l + Rx(eps) (0, 0, rho) = (2, 0.5 - rho sin eps, -0.3 + rho cos eps);
    # b -> NED for yaw 90: N = -y_b, E = x_b, D = z_b
    yb, zb = 0.5 - rho * np.sin(eps), -0.3 + rho * np.cos(eps)
    _close(_lla_deg(pts), _expected([-yb, 2.0, zb]))


def test_outside_span_dropped():
    traj = _static([0.0, 0.0, 0.0])
    pts = georeference(traj, [-1.0, 5.0, 10.0, 10.5], scanner_rays(np.full(4, 10.0),
                                                                  np.zeros(4)), Scanner())
    assert list(pts.index) == [1, 2]


def test_moving_trajectory_matches_interpolated_position():
    """Constant velocity east: the point under a nadir ray follows the Hermite position."""
    n = 21
    t = np.arange(n) * 0.5
    ned = np.column_stack([np.zeros(n), 60.0 * t, np.zeros(n)])
    lat, lon, h = pymap3d.ned2geodetic(ned[:, 0], ned[:, 1], ned[:, 2], LAT, LON, H)
    lla = np.column_stack([np.deg2rad(lat), np.deg2rad(lon), h])
    q = Rotation.from_euler("ZYX", [np.pi / 2, 0, 0]).as_quat()
    v = np.tile([0.0, 60.0, 0.0], (n, 1))
    traj = Trajectory(t, lla, v, np.tile(q, (n, 1)))
    tq = np.array([2.25, 7.6])
    pts = georeference(traj, tq, scanner_rays([300.0, 300.0], [0.0, 0.0]), Scanner())
    got = _lla_deg(pts)
    # 300 m straight down from the IMU position at tq (the path is 60 t east)
    imu = np.column_stack(pymap3d.ned2geodetic(0 * tq, 60.0 * tq, 0 * tq, LAT, LON, H))
    d = np.array(pymap3d.geodetic2ned(got[:, 0], got[:, 1], got[:, 2], imu[:, 0], imu[:, 1],
                                      imu[:, 2])).T
    assert np.allclose(d, [[0, 0, 300.0]] * 2, atol=0.01), d


def _mc_points(rng, m, base, sc, std, rho, theta):
    """Independent forward model (scipy Rotation, flat NED at the IMU) with perturbed
    inputs: position, roll/pitch/yaw, lever arm, boresight, range, scan angle."""
    rpy = np.deg2rad(base) + rng.normal(0, 1, (m, 3)) * std[3:6]
    C_nb = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix()
    bore = sc.boresight_rad + rng.normal(0, 1, (m, 3)) * sc.boresight_sigma_rad
    C_bs = sc.axes @ Rotation.from_euler("XYZ", bore).as_matrix()      # intrinsic x, y, z
    lever = sc.lever_arm_m + rng.normal(0, 1, (m, 3)) * sc.lever_arm_sigma_m
    r = rho + rng.normal(0, sc.range_sigma_m, m)
    th = theta + rng.normal(0, sc.scan_angle_sigma_rad, m)
    r_s = scanner_rays(r, th, sc.forward_tilt_rad)
    v_b = lever + np.einsum("mij,mj->mi", C_bs, r_s)
    return rng.normal(0, 1, (m, 3)) * std[:3] + np.einsum("mij,mj->mi", C_nb, v_b)


@pytest.mark.parametrize("base, theta_deg, tilt_deg", [
    ([3.0, -2.0, 40.0], 25.0, 0.0), ([-8.0, 4.0, 200.0], -33.0, 8.0)])
def test_sigma_against_monte_carlo(base, theta_deg, tilt_deg):
    rng = np.random.default_rng(7)
    sc = Scanner(forward_tilt_rad=np.deg2rad(tilt_deg), range_sigma_m=0.05,
                 scan_angle_sigma_rad=np.deg2rad(0.004), lever_arm_m=[0.3, -0.2, 0.4],
                 boresight_rad=np.deg2rad([0.1, -0.05, 0.2]),
                 axes=Rotation.from_euler("z", 0.3).as_matrix(),
                 lever_arm_sigma_m=[0.01, 0.02, 0.03],
                 boresight_sigma_rad=np.deg2rad([0.005, 0.008, 0.01]))
    std = np.array([0.03, 0.04, 0.06, np.deg2rad(0.005), np.deg2rad(0.006), np.deg2rad(0.02)])
    rho, theta = 900.0, np.deg2rad(theta_deg)
    traj = _static(base)
    pts = georeference(traj, [5.0], scanner_rays([rho], [theta], sc.forward_tilt_rad), sc,
                       std=TrajectoryStd(np.array([0.0, 10.0]), np.tile(std, (2, 1))))
    mc = _mc_points(rng, 40000, base, sc, std, rho, theta)
    var_mc = mc.var(axis=0)
    # 40000 samples: the variance's relative sigma is sqrt(2/40000) = 0.7 %
    assert np.allclose(pts.var_ned_m2[0], var_mc, rtol=0.04), (pts.var_ned_m2[0], var_mc)
    # the nominal point (no noise) agrees with the independent forward model
    nominal = _mc_points(np.random.default_rng(0), 1, base,
                         Scanner(**{**{k: getattr(sc, k) for k in sc.__dataclass_fields__},
                                    "range_sigma_m": 0.0, "scan_angle_sigma_rad": 0.0,
                                    "lever_arm_sigma_m": [0, 0, 0],
                                    "boresight_sigma_rad": [0, 0, 0]}),
                         np.zeros(6), rho, theta)
    _close(_lla_deg(pts), _expected(nominal), tol_m=1e-6)


def test_each_source_alone():
    """Nadir, level, heading north: range sigma -> vertical only; roll sigma ->
    east only, rho sigma_roll; yaw sigma -> nothing on a nadir ray."""
    traj = _static([0.0, 0.0, 0.0])
    rho = 1000.0
    r_s = scanner_rays([rho], [0.0])
    sc = Scanner(range_sigma_m=0.1)
    p = georeference(traj, [1.0], r_s, sc)
    assert np.allclose(p.var_ned_m2, [[0, 0, 0.01]], atol=1e-15)
    std = TrajectoryStd(np.array([0.0, 10.0]), np.tile([0, 0, 0, 1e-4, 0, 1e-3], (2, 1)))
    p = georeference(traj, [1.0], r_s, Scanner(), std=std)
    assert np.allclose(p.var_ned_m2, [[0, (rho * 1e-4) ** 2, 0]], atol=1e-12)
    assert np.isclose(p.sigma_h_m[0], 0.1) and p.sigma_v_m[0] < 1e-9


def test_read_solution_std_and_smrmsg(tmp_path):
    from ins.io.sbet import write_smrmsg
    p = tmp_path / "solution_std.txt"
    p.write_text("# time_s std_n_m ...\n0.0 0.1 0.2 0.3 0 0 0 0.01 0.02 0.03\n"
                 "2.0 0.3 0.4 0.5 0 0 0 0.03 0.04 0.05\n")
    s = read_trajectory_std(p)
    assert np.allclose(s.at([1.0, 5.0]), [[0.2, 0.3, 0.4, *np.deg2rad([0.02, 0.03, 0.04])],
                                          [0.3, 0.4, 0.5, *np.deg2rad([0.03, 0.04, 0.05])]])
    write_smrmsg(tmp_path / "smrmsg_x.out", [0.0, 1.0], [[1, 2, 3], [1, 2, 3]],
                 np.zeros((2, 3)), np.deg2rad([[0.1, 0.2, 0.3], [0.1, 0.2, 0.3]]))
    s = read_trajectory_std(tmp_path / "smrmsg_x.out")
    assert np.allclose(s.std[0], [1, 2, 3, *np.deg2rad([0.1, 0.2, 0.3])])
    p.write_text("0.0 0.1 -0.2 0.3 0 0 0 0.01 0.02 0.03\n")
    from ins.common.errors import InputError
    with pytest.raises(InputError, match="solution_std.txt:1"):
        read_trajectory_std(p)


# ---------------------------------------------------------------------------------------
# ins georeference (CLI): CSV in, LAS/LAZ out, read back with laspy, CRS by pyproj

def _run(argv, capsys):
    from ins.cli import main as cli
    try:
        code = cli.main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def static_flight(tmp_path):
    from ins.io.navfiles import write_nav
    traj = _static([2.0, -1.0, 30.0], n=11)
    write_nav(tmp_path / "t.nav", traj)
    (tmp_path / "std.txt").write_text("# time_s ...\n0 0.02 0.03 0.05 0 0 0 0.01 0.01 0.02\n"
                                      "10 0.02 0.03 0.05 0 0 0 0.01 0.01 0.02\n")
    (tmp_path / "s.toml").write_text('[scanner]\nmodel = "polygon"\nrange_sigma_m = 0.02\n'
                                     '[mounting]\nlever_arm_m = [0.2, 0.1, 0.3]\n'
                                     'boresight_deg = [0.01, -0.02, 0.03]\n')
    rows = ["time_s,range_m,scan_angle_deg,intensity,return_number,strip"]
    rng = np.random.default_rng(1)
    t = np.round(np.sort(rng.uniform(-0.5, 10.5, 500)), 6)
    rho = np.round(rng.uniform(900, 1300, 500), 4)
    ang = np.round(rng.uniform(-30, 30, 500), 5)
    for k in range(500):
        rows.append(f"{t[k]:.6f},{rho[k]:.4f},{ang[k]:.5f},{k % 300},{1 + k % 3},{k % 2}")
    (tmp_path / "returns.csv").write_text("\n".join(rows) + "\n")
    return tmp_path, traj, t, rho, ang


@pytest.mark.parametrize("ext, crs", [(".laz", None), (".las", "EPSG:4326")])
def test_cli_csv_to_las(static_flight, capsys, ext, crs):
    import laspy
    from pyproj import CRS
    tmp, traj, t, rho, ang = static_flight
    out = tmp / f"points{ext}"
    argv = ["georeference", "--trajectory", tmp / "t.nav", "--trajectory-std", tmp / "std.txt",
            "--scanner", tmp / "s.toml", tmp / "returns.csv", "-o", out, "-q"]
    if crs:
        argv += ["--crs", crs]
    code, stdout, err = _run(argv, capsys)
    assert code == 0, err
    inside = (t >= 0) & (t <= 10)
    assert f"{(~inside).sum()} returns outside" in stdout
    las = laspy.read(out)
    assert len(las.points) == inside.sum()
    assert np.allclose(las.gps_time, t[inside])
    assert np.array_equal(las.intensity, (np.arange(500) % 300)[inside])
    assert np.array_equal(las.point_source_id, (np.arange(500) % 2)[inside])
    assert np.allclose(las.scan_angle * 0.006, ang[inside], atol=0.0031)
    las_crs = las.header.parse_crs()
    expected_crs = CRS.from_user_input(crs) if crs else CRS.from_epsg(32650)  # 114.3 E: 50N
    assert las_crs.equals(expected_crs)
    # independent: the library's ECEF points through pyproj, versus the file
    sc = Scanner(range_sigma_m=0.02, lever_arm_m=[0.2, 0.1, 0.3],
                 boresight_rad=np.deg2rad([0.01, -0.02, 0.03]))
    pts = georeference(traj, t[inside], scanner_rays(rho[inside], np.deg2rad(ang[inside])), sc)
    lla = _lla_deg(pts)
    if crs:
        assert np.allclose(las.x, lla[:, 1], atol=2e-8) and np.allclose(las.y, lla[:, 0],
                                                                        atol=2e-8)
    else:
        from pyproj import Transformer
        e, n = Transformer.from_crs(4326, 32650, always_xy=True).transform(lla[:, 1], lla[:, 0])
        assert np.allclose(las.x, e, atol=1e-3) and np.allclose(las.y, n, atol=1e-3)
    assert np.allclose(las.z, lla[:, 2], atol=1e-3)
    assert np.all(las.sigma_v_m > 0.02) and np.all(las.sigma_h_m > 0.03)


def test_cli_no_return_inside(static_flight, capsys):
    tmp = static_flight[0]
    (tmp / "late.csv").write_text("time_s,range_m,scan_angle_deg\n100,500,0\n")
    code, _, err = _run(["georeference", "--trajectory", tmp / "t.nav", "--scanner",
                         tmp / "s.toml", tmp / "late.csv", "-o", tmp / "p.las"], capsys)
    assert code == 2 and "none of the 1 returns" in err and "late.csv" in err
    assert not (tmp / "p.las").exists()


def test_cli_bad_header(static_flight, capsys):
    tmp = static_flight[0]
    (tmp / "bad.csv").write_text("time,range_m,scan_angle_deg\n1,500,0\n")
    code, _, err = _run(["georeference", "--trajectory", tmp / "t.nav", "--scanner",
                         tmp / "s.toml", tmp / "bad.csv", "-o", tmp / "p.las"], capsys)
    assert code == 2 and "bad.csv:1" in err and "time_s,range_m,scan_angle_deg" in err


def test_cli_las_in_scanner_frame(static_flight, capsys):
    """Model "points": a LAS of points in the scanner frame (written by hand with laspy)
    gives the same points as range/angle returns of the same geometry."""
    import laspy
    tmp, traj, t, rho, ang = static_flight
    inside = (t >= 0) & (t <= 10)
    t, rho, ang = t[inside], rho[inside], ang[inside]
    r_s = scanner_rays(rho, np.deg2rad(ang))
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales = [1e-4, 1e-4, 1e-4]
    header.offsets = [0.0, 0.0, 0.0]
    las = laspy.LasData(header)
    las.x, las.y, las.z = r_s[:, 0], r_s[:, 1], r_s[:, 2]
    las.gps_time = t
    las.intensity = np.arange(len(t)) % 1000
    las.point_source_id = np.full(len(t), 7)
    las.write(tmp / "scanner_frame.las")
    (tmp / "p.toml").write_text('[scanner]\nmodel = "points"\n[mounting]\n'
                                'lever_arm_m = [0.2, 0.1, 0.3]\n'
                                'boresight_deg = [0.01, -0.02, 0.03]\n')
    code, out, err = _run(["georeference", "--trajectory", tmp / "t.nav", "--scanner",
                           tmp / "p.toml", tmp / "scanner_frame.las", "-o", tmp / "p.las",
                           "--crs", "EPSG:4979", "-q"], capsys)
    assert code == 0, err
    got = laspy.read(tmp / "p.las")
    sc = Scanner(lever_arm_m=[0.2, 0.1, 0.3], boresight_rad=np.deg2rad([0.01, -0.02, 0.03]))
    lla = _lla_deg(georeference(traj, t, scanner_rays(rho, np.deg2rad(ang)), sc))
    assert np.allclose(got.y, lla[:, 0], atol=2e-8) and np.allclose(got.x, lla[:, 1], atol=2e-8)
    assert np.allclose(got.z, lla[:, 2], atol=2e-3)      # the input's 0.1 mm grid
    assert np.all(got.point_source_id == 7)
    assert np.allclose(got.scan_angle * 0.006, ang, atol=0.0031)
    # a line scanner cannot read scanner-frame points
    code, _, err = _run(["georeference", "--trajectory", tmp / "t.nav", "--scanner",
                         tmp / "s.toml", tmp / "scanner_frame.las", "-o", tmp / "q.las"],
                        capsys)
    assert code == 2 and '"points"' in err


def test_fast_interpolation_equals_the_eo_interpolation():
    """interpolate_pose ("cubic", numba) against ins.nav.interpolation.interpolate_trajectory
    on a turning, rolling trajectory crossing 180 deg of longitude."""
    from ins.lidar.georeference import interpolate_pose
    from ins.nav.interpolation import interpolate_trajectory
    from ins.nav.rotation import quat_conjugate, quat_multiply, quat_to_rotvec
    n = 400
    t = 1000.0 + 0.005 * np.arange(n) + 0.001 * np.sin(np.arange(n))
    lat = np.deg2rad(-33.9) + 1e-6 * np.arange(n)
    lon = np.deg2rad(179.9999) + 2e-6 * np.arange(n)
    lon = (lon + np.pi) % (2 * np.pi) - np.pi
    lla = np.column_stack([lat, lon, 500.0 + 0.1 * np.arange(n)])
    v = np.column_stack([40 + np.sin(t), 50 + np.cos(t), -0.3 * np.ones(n)])
    rpy = np.column_stack([0.3 * np.sin(3 * t), 0.1 * np.cos(2 * t), 3.0 + 0.8 * t])
    q = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_quat()
    traj = Trajectory(t, lla, v, q)
    tq = np.sort(np.random.default_rng(0).uniform(t[0], t[-1], 5000))
    tq[0], tq[-1] = t[0], t[-1]
    lla_f, q_f = interpolate_pose(traj, tq)
    ref = interpolate_trajectory(traj, tq)
    d = lla_f - ref.lla
    d[:, 1] = (d[:, 1] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(d[:, :2]).max() < 1e-14 and np.abs(d[:, 2]).max() < 1e-9
    ang = np.linalg.norm(quat_to_rotvec(quat_multiply(quat_conjugate(ref.q_nb), q_f)), axis=1)
    assert ang.max() < 1e-12


def test_scanner_on_the_aircraft_by_hand():
    """IMU level on the platform heading north, the platform rolled +10 deg relative to the
    aircraft (C_ap = Rx(10 deg)): a nadir scanner on the aircraft looks 10 deg to the
    right of the body's nadir; its arm is l_bp + Rx(-10 deg) l_a (written by hand)."""
    from ins.io.mount import MountLog
    traj = _static([0.0, 0.0, 0.0])
    mount = MountLog(np.array([0.0, 10.0]), np.tile(np.deg2rad([10.0, 0.0, 0.0]), (2, 1)))
    l_a, l_bp = np.array([0.5, 0.2, -0.4]), np.array([0.1, -0.05, -0.2])
    sc = Scanner(on="aircraft", lever_arm_m=l_a, imu_to_platform_centre_b_m=l_bp)
    a = np.deg2rad(10.0)
    Rx_m = np.array([[1, 0, 0], [0, np.cos(a), np.sin(a)], [0, -np.sin(a), np.cos(a)]])
    rho = 700.0
    pts = georeference(traj, [2.0], scanner_rays([rho], [0.0]), sc, mount=mount)
    ned = l_bp + Rx_m @ l_a + Rx_m @ np.array([0.0, 0.0, rho])
    assert ned[1] > 100                                     # to the right (east)
    _close(_lla_deg(pts), _expected(ned))
    with pytest.raises(Exception, match="mount"):
        georeference(traj, [2.0], scanner_rays([rho], [0.0]), sc)


def test_cli_number_of_returns_per_pulse(static_flight, capsys):
    """Returns of one pulse share its time: their number of returns is the pulse's
    largest return number, also for pulses that straddle the reader's blocks (block size
    5, pulses of 1-4 returns); a given column is kept and checked."""
    import laspy
    tmp = static_flight[0]
    rng = np.random.default_rng(3)
    rows, expect = ["time_s,range_m,scan_angle_deg,return_number,strip"], []
    t = 0.5
    for pulse in range(60):
        k = int(rng.integers(1, 5))
        for r in range(1, k + 1):
            rows.append(f"{t:.4f},{1000 + 5 * r:.1f},{rng.uniform(-20, 20):.3f},{r},1")
            expect.append(k)
        t += 0.1
    (tmp / "pulses.csv").write_text("\n".join(rows) + "\n")
    code, _, err = _run(["georeference", "--trajectory", tmp / "t.nav", "--scanner",
                         tmp / "s.toml", tmp / "pulses.csv", "-o", tmp / "p.las",
                         "--block-size", "5", "-q"], capsys)
    assert code == 0, err
    las = laspy.read(tmp / "p.las")
    assert np.array_equal(las.number_of_returns, expect)
    assert np.all(np.asarray(las.return_number) <= np.asarray(las.number_of_returns))
    # given: kept as written; a return number above it is refused with its line
    (tmp / "given.csv").write_text(rows[0].replace(",strip", ",number_of_returns,strip")
                                   + "\n" + "\n".join(
        r.rsplit(",", 1)[0] + ",4,1" for r in rows[1:]) + "\n")
    code, _, err = _run(["georeference", "--trajectory", tmp / "t.nav", "--scanner",
                         tmp / "s.toml", tmp / "given.csv", "-o", tmp / "g.las", "-q"], capsys)
    assert code == 0, err
    assert np.all(laspy.read(tmp / "g.las").number_of_returns == 4)
    (tmp / "bad.csv").write_text(rows[0].replace(",strip", ",number_of_returns,strip")
                                 + "\n0.5,1000,0,3,2,1\n")
    code, _, err = _run(["georeference", "--trajectory", tmp / "t.nav", "--scanner",
                         tmp / "s.toml", tmp / "bad.csv", "-o", tmp / "b.las"], capsys)
    assert code == 2 and "bad.csv:2" in err and "above number_of_returns 2" in err
    assert not (tmp / "b.las").exists()


def test_cli_orthometric_heights(static_flight, capsys):
    """--height orthometric: z = h - N (N of the model at each point), the WKT the
    compound CRS with the model's vertical CRS (EGM2008 height, EPSG:3855)."""
    import laspy
    from ins.io.geoid import load_geoid
    try:
        g = load_geoid("EGM2008")
    except Exception as exc:
        pytest.skip(f"no EGM2008 grid: {exc}")
    tmp = static_flight[0]
    base = ["georeference", "--trajectory", tmp / "t.nav", "--scanner", tmp / "s.toml",
            tmp / "returns.csv", "-q"]
    code, _, err = _run(base + ["-o", tmp / "e.las"], capsys)
    assert code == 0, err
    code, out, err = _run(base + ["-o", tmp / "o.las", "--height", "orthometric:EGM2008"],
                          capsys)
    assert code == 0, err
    assert "orthometric EGM2008 (EPSG:3855)" in out
    e, o = laspy.read(tmp / "e.las"), laspy.read(tmp / "o.las")
    crs = o.header.parse_crs()
    assert crs.is_compound and crs.sub_crs_list[1].to_epsg() == 3855
    assert crs.sub_crs_list[0].to_epsg() == 32650
    from pyproj import Transformer
    lon, lat = Transformer.from_crs(32650, 4326, always_xy=True).transform(e.x, e.y)
    N = g.undulation(np.deg2rad(lat), np.deg2rad(lon))
    assert np.allclose(np.asarray(e.z) - np.asarray(o.z), N, atol=1.5e-3)
    assert np.allclose(o.x, e.x) and np.allclose(o.y, e.y)
    code, _, err = _run(base + ["-o", tmp / "x.las", "--height", "geoid"], capsys)
    assert code == 2 and "--height" in err and not (tmp / "x.las").exists()
