"""The flight plan's ``[scanner]`` table: strict keys in SI, and the LiDAR products of
``ins simulate`` (returns, scanner files, true points) against an independent truth: the
true trajectory through the forward georeferencing formula lands on the true points
within the scanner's noise (the simulator intersects rays with the terrain iteratively)."""
from pathlib import Path

import numpy as np
import pytest
import tomli_w
import tomllib

from ins.common.errors import InputError
from ins.simulate.plan_read import parse_plan

SHORT = Path(__file__).parent / "data" / "flights" / "short.toml"
SCANNER = {"model": "polygon", "pulse_rate_hz": 1500.0, "scan_rate_hz": 25.0,
           "field_of_view_deg": 50.0, "range_sigma_m": 0.03, "scan_angle_sigma_deg": 0.002,
           "lever_arm_m": [0.1, 0.05, 0.2], "boresight_deg": [0.1, -0.08, 0.15],
           "lever_arm_sigma_m": [0.01, 0.01, 0.01], "boresight_sigma_deg": [0.01, 0.01, 0.02]}


def _plan(scanner=None):
    with open(SHORT, "rb") as f:
        data = tomllib.load(f)
    if scanner is not None:
        data["scanner"] = dict(scanner)
    return data


def test_scanner_table_optional_and_in_si():
    assert parse_plan(_plan()).scanner is None
    s = parse_plan(_plan(SCANNER)).scanner
    assert s.model == "polygon" and s.pulse_rate_hz == 1500.0
    assert np.isclose(s.field_of_view, np.deg2rad(50.0))
    assert np.allclose(s.boresight, np.deg2rad([0.1, -0.08, 0.15]))
    assert np.allclose(s.boresight_sigma, np.deg2rad([0.01, 0.01, 0.02]))
    assert np.isclose(s.scan_angle_sigma, np.deg2rad(0.002))
    assert parse_plan(_plan({})).scanner.pulse_rate_hz == 2000.0     # an empty table: defaults


@pytest.mark.parametrize("key, value, words", [
    ("boresight_arcsec", [1, 2, 3], "unknown key"),
    ("lever_arm", [0, 0, 0], "did you mean lever_arm_m"),
    ("pulse_rate_hz", -5.0, "Hz"),
    ("model", "points", "polygon"),
    ("boresight_deg", [10.0, 0.0, 0.0], "beyond"),
    ("range_sigma_m", -0.01, "m in [0, 10]"),
    ("lever_arm_m", [0.1, 0.2], "expected 3 numbers"),
])
def test_bad_scanner_keys_name_the_key(key, value, words):
    with pytest.raises(InputError) as e:
        parse_plan(_plan({**SCANNER, key: value}), source="plan.toml")
    assert "[scanner]" in str(e.value) and key in str(e.value) and words in str(e.value)


@pytest.fixture(scope="module")
def lidar_folder(tmp_path_factory):
    from ins.simulate.folder import simulate_flight
    tmp = tmp_path_factory.mktemp("simlidar")
    plan = tmp / "plan.toml"
    plan.write_bytes(tomli_w.dumps(_plan(SCANNER)).encode())
    return simulate_flight(plan, tmp / "flight", 4)


def test_lidar_products_against_the_truth(lidar_folder):
    from ins.io.navfiles import read_trajectory
    from ins.lidar.georeference import georeference, returns_to_scanner
    from ins.lidar.lidar_files import iter_returns
    from ins.lidar.scanner import Scanner, read_scanner
    from ins.nav.earth import dcm_en
    from ins.simulate.plan_read import load_plan
    from ins.simulate.truth import build_truth
    f = lidar_folder
    with open(f / "manifest.toml", "rb") as fh:
        manifest = tomllib.load(fh)
    for key in ("returns", "scanner", "scanner_true", "points_true"):
        assert (f / manifest["files"][key]).is_file()
    given, true = read_scanner(f / "scanner.toml"), read_scanner(f / "scanner_true.toml")
    assert np.allclose(given.boresight_rad, 0.0)
    assert np.allclose(true.boresight_rad, np.deg2rad(SCANNER["boresight_deg"]))
    assert np.allclose(given.lever_arm_m, SCANNER["lever_arm_m"])
    assert np.allclose(given.boresight_sigma_rad, np.deg2rad(SCANNER["boresight_sigma_deg"]))
    blocks = list(iter_returns(str(f / "returns.csv"), "polygon", 10 ** 7))
    assert len(blocks) == 1
    ret = blocks[0]
    pts = np.loadtxt(f / "points_true.csv", delimiter=",", skiprows=1)
    assert len(ret.time) == len(pts) == manifest["scanner"]["n_returns"]
    assert np.array_equal(ret.strip, pts[:, 4]) and np.allclose(ret.time, pts[:, 0])
    # the returns lie on the plan's strips (ids = strip index + 1), at the pulse rate
    strips = build_truth(load_plan(f / "plan.toml")).strips
    assert sorted(set(ret.strip)) == [s.index + 1 for s in strips] == [1, 2]
    for s in strips:
        t = ret.time[ret.strip == s.index + 1]
        assert t.min() >= s.t_start and t.max() <= s.t_end
        assert np.allclose(np.diff(t), 1 / SCANNER["pulse_rate_hz"], atol=1e-6)
        assert len(t) > 0.95 * (s.t_end - s.t_start) * SCANNER["pulse_rate_hz"]
    # scan angles within the field of view (noise aside), both signs
    half = SCANNER["field_of_view_deg"] / 2 + 0.01
    assert np.all(np.abs(np.rad2deg(ret.scan_angle_rad)) <= half)
    # independent truth: the true trajectory through r = r_imu + C_nb (l_b + C_bs r_s)
    truth = read_trajectory(f / "truth.nav")
    noise_only = Scanner(model="polygon", range_sigma_m=true.range_sigma_m,
                         scan_angle_sigma_rad=true.scan_angle_sigma_rad,
                         lever_arm_m=true.lever_arm_m, boresight_rad=true.boresight_rad)
    r_s = returns_to_scanner(noise_only, ret.range_m, ret.scan_angle_rad)
    p = georeference(truth, ret.time, r_s, noise_only)
    assert len(p.index) == len(ret.time)
    C_en = dcm_en(*p.lla()[:, :2].T)
    d = np.einsum("nji,nj->ni", C_en, p.xyz_ecef_m - pts[:, 1:4])
    z2 = (d ** 2 / p.var_ned_m2).mean(axis=0)      # the scanner's noise alone
    assert np.all(z2 > 0.8) and np.all(z2 < 1.25), z2
    # and the given scanner file (boresight 0) is off by decimetres at 300 m
    p0 = georeference(truth, ret.time, returns_to_scanner(given, ret.range_m,
                                                          ret.scan_angle_rad), given)
    assert np.sqrt(np.mean(np.sum((p0.xyz_ecef_m - pts[:, 1:4]) ** 2, axis=1))) > 0.3


def _gauss_markov(rng, t, tau_s, k):
    """k independent unit-variance first-order Gauss-Markov processes at the times t (s),
    started in their stationary distribution; shape (len(t), k)."""
    x = np.empty((len(t), k))
    x[0] = rng.standard_normal(k)
    a = np.exp(-np.diff(t) / tau_s)
    w = rng.standard_normal((len(t) - 1, k)) * np.sqrt(1 - a * a)[:, None]
    for i in range(1, len(t)):
        x[i] = a[i - 1] * x[i - 1] + w[i - 1]
    return x


def test_point_sigmas_with_time_correlated_trajectory_errors(lidar_folder):
    """Point sigmas against errors that are correlated in time, as a GNSS/INS solution's
    are: the true trajectory plus a drawn error, a sum of a slow (300 s, longer than the
    flight) and a fast (2 s) Gauss-Markov process per position and attitude component
    with the stated, time-varying sigmas of a TrajectoryStd.  Within one flight every
    point shares the one draw of the slow part, so the mean z^2 of a single flight is a
    chi-square of few degrees of freedom (it spreads over about 0.1 .. 3 for honest
    sigmas); over independent draws its mean is 1 per axis."""
    from ins.io.navfiles import read_trajectory
    from ins.lidar.georeference import TrajectoryStd, georeference, returns_to_scanner
    from ins.lidar.lidar_files import iter_returns
    from ins.lidar.scanner import Scanner, read_scanner
    from ins.nav.earth import dcm_en, offset_lla
    from ins.nav.rotation import euler_to_quat, quat_to_euler
    from ins.nav.trajectory import Trajectory
    f = lidar_folder
    truth = read_trajectory(f / "truth.nav")
    true = read_scanner(f / "scanner_true.toml")     # its mounting exact: no mounting sigmas
    scanner = Scanner(model="polygon", range_sigma_m=true.range_sigma_m,
                      scan_angle_sigma_rad=true.scan_angle_sigma_rad,
                      lever_arm_m=true.lever_arm_m, boresight_rad=true.boresight_rad)
    ret = next(iter(iter_returns(str(f / "returns.csv"), "polygon", 10 ** 7)))
    pts = np.loadtxt(f / "points_true.csv", delimiter=",", skiprows=1)
    keep = np.arange(0, len(ret.time), 7)                # a subset: 2 strips, ~3500 points
    t_r = ret.time[keep]
    r_s = returns_to_scanner(scanner, ret.range_m[keep], ret.scan_angle_rad[keep])
    rpy = quat_to_euler(truth.q_nb)
    # stated sigmas (N, E, D m; roll, pitch, yaw rad), varying along the flight
    t_s = truth.time[::50]
    s0 = np.array([0.02, 0.03, 0.04, *np.deg2rad([0.004, 0.006, 0.012])])
    std = TrajectoryStd(t_s, s0 * (1 + 0.4 * np.sin((t_s - t_s[0]) / 30.0))[:, None])
    sig = std.at(truth.time)
    rng = np.random.default_rng(11)
    z2, z2_scanner = [], []
    var_scanner = georeference(truth, t_r, r_s, scanner).var_ned_m2
    for _ in range(120):
        u = (np.sqrt(0.8) * _gauss_markov(rng, t_s, 300.0, 6)
             + np.sqrt(0.2) * _gauss_markov(rng, t_s, 2.0, 6))
        e = np.column_stack([np.interp(truth.time, t_s, u[:, j]) for j in range(6)]) * sig
        est = Trajectory(truth.time, offset_lla(truth.lla, e[:, :3]), truth.v_n,
                         euler_to_quat(rpy + e[:, 3:]))
        p = georeference(est, t_r, r_s, scanner, std=std)
        d = np.einsum("nji,nj->ni", dcm_en(*p.lla()[:, :2].T), p.xyz_ecef_m - pts[keep, 1:4])
        z2.append((d ** 2 / p.var_ned_m2).mean(axis=0))
        z2_scanner.append((d ** 2 / var_scanner).mean(axis=0))
    z2 = np.array(z2)
    # (the interpolation of the drawn error between the 0.5 s samples lowers the fast
    # part's variance a little: honest sigmas give slightly below 1)
    assert np.all(z2.mean(axis=0) > 0.85) and np.all(z2.mean(axis=0) < 1.15), z2.mean(0)
    # one flight alone is no test of them: its z^2 spreads over a decade
    assert z2.min() < 0.3 and z2.max() > 2.5, (z2.min(), z2.max())
    # and sigmas that ignore the trajectory (the scanner's alone) fail by far
    assert np.all(np.mean(z2_scanner, axis=0) > 2.0), np.mean(z2_scanner, axis=0)


def _drawn_flights(folder, n_draws, calibrate=False):
    """Mean z^2 per axis (N, E, D) of the points of ``n_draws`` drawn trajectories:
    with the TRUE scanner and, with ``calibrate``, after the user's calibration
    (boresight 0 -> strip check -> calibrated scanner with its [calibration] split).

    The trajectory errors are drawn as a GNSS/INS solution's are: a tilt (roll, pitch)
    error fixed in the body frame over the flight (accelerometer bias and misalignment
    over g) plus a fast part, a heading error that wanders from strip to strip (a 20 s
    Gauss-Markov process), position errors slow and fast; the stated sigmas are their
    total.  One flight is one draw of the slow errors (a chi-square of few degrees of
    freedom), so the mean z^2 is pooled over the draws."""
    from ins.io.navfiles import read_trajectory
    from ins.lidar.georeference import TrajectoryStd, georeference, returns_to_scanner
    from ins.lidar.lidar_files import iter_returns
    from ins.lidar.scanner import Scanner, read_scanner
    from ins.lidar.strip_check import boresight_from_strips
    from ins.nav.earth import dcm_en, offset_lla
    from ins.nav.rotation import euler_to_quat, quat_to_euler
    from ins.nav.trajectory import Trajectory
    f = folder
    truth = read_trajectory(f / "truth.nav")
    true = read_scanner(f / "scanner_true.toml")
    scanner = Scanner(model="polygon", range_sigma_m=true.range_sigma_m,
                      scan_angle_sigma_rad=true.scan_angle_sigma_rad,
                      lever_arm_m=true.lever_arm_m, boresight_rad=true.boresight_rad)
    given = scanner.with_boresight(np.zeros(3))
    ret = next(iter(iter_returns(str(f / "returns.csv"), "polygon", 10 ** 7)))
    pts = np.loadtxt(f / "points_true.csv", delimiter=",", skiprows=1)
    t_r, strip = ret.time, ret.strip
    r_s = returns_to_scanner(scanner, ret.range_m, ret.scan_angle_rad)
    rpy = quat_to_euler(truth.q_nb)
    t_s = truth.time[::50]
    s0 = np.array([0.01, 0.01, 0.02, *np.deg2rad(np.array([40.0, 40.0, 100.0]) / 3600)])
    std = TrajectoryStd(t_s, np.tile(s0, (len(t_s), 1)))
    rng = np.random.default_rng(5)
    z2 = {"true": [], "calibrated": []}
    for _ in range(n_draws):
        u = np.empty((len(t_s), 6))
        u[:, :3] = (np.sqrt(0.8) * _gauss_markov(rng, t_s, 300.0, 3)
                    + np.sqrt(0.2) * _gauss_markov(rng, t_s, 2.0, 3))
        u[:, 3:5] = (np.sqrt(0.95) * rng.standard_normal(2)
                     + np.sqrt(0.05) * _gauss_markov(rng, t_s, 2.0, 2))
        u[:, 5] = _gauss_markov(rng, t_s, 20.0, 1)[:, 0]
        e = np.column_stack([np.interp(truth.time, t_s, u[:, j]) for j in range(6)]) * s0
        est = Trajectory(truth.time, offset_lla(truth.lla, e[:, :3]), truth.v_n,
                         euler_to_quat(rpy + e[:, 3:]))
        cases = [("true", scanner)]
        if calibrate:
            b, _, _, cal = boresight_from_strips(est, t_r, r_s, strip, given, std=std,
                                                 radius_m=8.0, k=6)
            cases.append(("calibrated", given.replace(boresight_rad=b, calibration=cal)))
        for case, sc in cases:
            p = georeference(est, t_r, r_s, sc, std=std)
            d = np.einsum("nji,nj->ni", dcm_en(*p.lla()[:, :2].T),
                          p.xyz_ecef_m - pts[:, 1:4])
            z2[case].append((d ** 2 / p.var_ned_m2).mean(axis=0))
    return {case: np.mean(v, axis=0) for case, v in z2.items() if v}


@pytest.mark.slow
def test_point_sigmas_per_axis_true_scanner(lidar_folder):
    """Issue 35: with the TRUE scanner file, mean z^2 per axis within 0.7 .. 1.5 over
    drawn trajectories (:func:`_drawn_flights`); measured 1.04 / 1.27 / 0.97 (N, E, D)."""
    m = _drawn_flights(lidar_folder, 40, calibrate=False)["true"]
    assert np.all(m > 0.7) and np.all(m < 1.5), m


def test_calibrated_points_count_the_rotation_left_once(lidar_folder):
    """A scanner calibrated on this flight: its ``attitude_sigma`` is the sigma of the
    whole rotation left in the points, ``e(t) + b_hat - b`` (the trajectory's attitude
    error and the boresight's own error together).  Monte Carlo, independent of the
    propagation: per draw a rotation left ``r ~ N(0, sigma_left^2)`` split at random
    into a trajectory attitude error (Euler angles added to the true attitude) and a
    boresight error ``n`` (added to the true boresight) of the adjustment's sigma; the
    points' mean z^2 per axis over the draws is 1 (measured 1.02 / 1.04 / 0.94 N/E/D;
    0.70 / 0.70 horizontally with ``n`` counted twice, as before the fix)."""
    from ins.io.navfiles import read_trajectory
    from ins.lidar.georeference import TrajectoryStd, georeference, returns_to_scanner
    from ins.lidar.lidar_files import iter_returns
    from ins.lidar.scanner import BoresightCalibration, Scanner, read_scanner
    from ins.nav.earth import dcm_en
    from ins.nav.rotation import euler_to_quat, quat_to_euler
    from ins.nav.trajectory import Trajectory
    f = lidar_folder
    truth = read_trajectory(f / "truth.nav")
    true = read_scanner(f / "scanner_true.toml")
    scanner = Scanner(model="polygon", range_sigma_m=true.range_sigma_m,
                      scan_angle_sigma_rad=true.scan_angle_sigma_rad,
                      lever_arm_m=true.lever_arm_m, boresight_rad=true.boresight_rad)
    ret = next(iter(iter_returns(str(f / "returns.csv"), "polygon", 10 ** 7)))
    pts = np.loadtxt(f / "points_true.csv", delimiter=",", skiprows=1)
    keep = np.arange(0, len(ret.time), 20)
    t_r = ret.time[keep]
    r_s = returns_to_scanner(scanner, ret.range_m[keep], ret.scan_angle_rad[keep])
    rpy = quat_to_euler(truth.q_nb)
    left = np.deg2rad(np.array([20.0, 20.0, 150.0]) / 3600)       # rotation left, rad
    n_sig = np.deg2rad(np.array([15.0, 15.0, 100.0]) / 3600)      # of which the boresight's
    std = TrajectoryStd(truth.time[[0, -1]], np.tile([1e-4, 1e-4, 1e-4, 1e-3, 1e-3, 1e-3],
                                                     (2, 1)))
    cal = BoresightCalibration(t_r[[0, -1]], n_sig, left)
    rng = np.random.default_rng(7)
    z2, z2_twice = [], []
    for _ in range(400):
        n = n_sig * rng.standard_normal(3)
        e = np.sqrt(left ** 2 - n_sig ** 2) * rng.standard_normal(3)   # r = e + n
        est = Trajectory(truth.time, truth.lla, truth.v_n, euler_to_quat(rpy + e))
        sc = scanner.replace(boresight_rad=true.boresight_rad + n, calibration=cal)
        p = georeference(est, t_r, r_s, sc, std=std)
        d = np.einsum("nji,nj->ni", dcm_en(*p.lla()[:, :2].T), p.xyz_ecef_m - pts[keep, 1:4])
        z2.append((d ** 2 / p.var_ned_m2).mean(axis=0))
        # the same with the adjustment's sigma added on top of the rotation left
        twice = georeference(est, t_r, r_s, sc.replace(calibration=None,
                                                       boresight_sigma_rad=n_sig),
                             std=TrajectoryStd(std.time, np.tile([1e-4] * 3 + list(left),
                                                                 (2, 1))))
        z2_twice.append((d ** 2 / twice.var_ned_m2).mean(axis=0))
    z2, z2_twice = np.mean(z2, axis=0), np.mean(z2_twice, axis=0)
    assert np.all(z2 > 0.85) and np.all(z2 < 1.15), z2
    assert np.all(z2_twice[:2] < 0.8), z2_twice
