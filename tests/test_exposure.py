"""Tests of photogrammetry.orientation.exposure and photogrammetry.orientation.mapping: the EO chain on a
closed-form flight, the effect sizes of convergence and boresight, the files."""
import numpy as np
import pymap3d
import pyproj
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation
from test_interpolation import Turn

from ins.common.errors import InputError
from ins.nav.rotation import euler_to_dcm
from photogrammetry.orientation import exposure as ex
from photogrammetry.orientation.camera import NADIR_AXES, CameraMounting
from photogrammetry.orientation.mapping import EnuFrame, ProjectedFrame, parse_frame, utm_epsg
from photogrammetry.orientation.rotation import P_NED_ENU, dcm_mn_enu

ARCSEC = np.pi / 180 / 3600
SCIPY_SEQ = {"phi-omega-kappa": "YXZ", "omega-phi-kappa": "XYZ"}
#: phi-omega-kappa is Ry(-phi) Rx(omega) Rz(kappa): scipy's 'YXZ' angles are (-phi, omega, kappa)
SCIPY_SIGN = {"phi-omega-kappa": np.array([-1.0, 1.0, 1.0]), "omega-phi-kappa": np.ones(3)}
TURN = Turn()
T200 = np.arange(0.0, 20.0 + 1e-9, 0.005)
TRAJ = TURN.trajectory(T200)
T_EV = np.arange(0.3, 19.8, 0.731)            # off the 200 Hz grid
IDS = [f"IMG_{i:04d}" for i in range(len(T_EV))]
MOUNT = CameraMounting(NADIR_AXES, [0.4, -0.2, -1.1], np.deg2rad([0.01, -0.02, 0.05]))
ORIGIN = (TURN.lat0, TURN.lon0 + 0.002, 50.0)


def angle_diff(a, b):
    return np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b))))


@pytest.mark.parametrize("system", ["phi-omega-kappa", "omega-phi-kappa"])
def test_chain_reproduces_closed_form_eo(system):
    frame = EnuFrame(*ORIGIN)
    eo = ex.compute_eo(TRAJ, IDS, T_EV, MOUNT, frame, system)
    # truth, independently: closed-form IMU position in ENU (pymap3d) plus the lever arm
    # rotated by the exact C_mn at the IMU; attitude by scipy's composition
    lla = TURN.lla(T_EV)
    C_nb = euler_to_dcm(TURN.rpy(T_EV))
    enu = np.column_stack(pymap3d.geodetic2enu(lla[:, 0], lla[:, 1], lla[:, 2], *ORIGIN,
                                               deg=False))
    C_mn = dcm_mn_enu(lla[:, 0], lla[:, 1], ORIGIN[0], ORIGIN[1])
    X_true = enu + np.einsum("nij,j->ni", C_mn @ C_nb, MOUNT.lever_arm_m)
    assert np.abs(eo.position - X_true).max() < 1e-6            # < 1 um
    # the attitude is rigid: C_nb refers to the n frame at the IMU, so C_mn is the IMU's
    C_mc = C_mn @ C_nb @ MOUNT.C_bc
    ref = Rotation.from_matrix(C_mc).as_euler(SCIPY_SEQ[system]) * SCIPY_SIGN[system]
    err = np.abs(angle_diff(eo.angles, ref)).max() / ARCSEC
    assert err < 0.01, err                                      # well under 0.1 arcsec
    assert eo.system == system and eo.frame.startswith("enu; origin_lat_deg")


def level_trajectory(lat_deg, lon_deg, heading_deg=0.0):
    t = np.arange(0.0, 2.0, 0.005)
    n = len(t)
    from ins.nav.rotation import euler_to_quat
    from ins.nav.trajectory import Trajectory
    lla = np.column_stack([np.full(n, np.deg2rad(lat_deg)), np.full(n, np.deg2rad(lon_deg)),
                           np.full(n, 1000.0)])
    return Trajectory(t, lla, np.zeros((n, 3)),
                      euler_to_quat(np.tile(np.deg2rad([0, 0, heading_deg]), (n, 1))))


def test_meridian_convergence_effect():
    # 3 deg east of the UTM zone 50 central meridian (117 E), 45 deg N
    traj = level_trajectory(45.0, 120.0, heading_deg=30.0)
    frame = parse_frame("EPSG:32650")
    mount = CameraMounting()
    eo = ex.compute_eo(traj, ["a"], [1.0], mount, frame, "omega-phi-kappa")

    class NoConvergence(ProjectedFrame):
        def C_mn(self, lla):
            return np.broadcast_to(P_NED_ENU, (len(lla), 3, 3))

    eo0 = ex.compute_eo(traj, ["a"], [1.0], mount, NoConvergence("EPSG:32650"),
                        "omega-phi-kappa")
    dk = angle_diff(eo.angles[0, 2], eo0.angles[0, 2]) / ARCSEC
    # independent: grid azimuth of true north by finite differences of the projection
    tr = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32650", always_xy=True)
    e0, n0 = tr.transform(120.0, 45.0 - 1e-6)
    e1, n1 = tr.transform(120.0, 45.0 + 1e-6)
    gamma = -np.arctan2(e1 - e0, n1 - n0) / ARCSEC
    assert abs(dk - gamma) < 0.05
    assert 7500 < dk < 7700                                     # "about 7600 arcsec"
    assert_allclose(gamma, np.rad2deg(np.arctan(np.tan(np.deg2rad(3)) * np.sin(
        np.deg2rad(45)))) * 3600, rtol=2e-3)                    # textbook series
    assert np.abs(eo.angles[0, :2] - eo0.angles[0, :2]).max() < 1e-12
    # positions: pyproj's UTM directly
    e, n = tr.transform(120.0, 45.0)
    assert_allclose(eo.position[0], [e, n, 1000.0], atol=1e-6)
    assert eo.frame == "EPSG:32650; heights = ellipsoidal"
    orth = ex.compute_eo(traj, ["a"], [1.0], mount, ProjectedFrame(32650, 12.5), "omega-phi-kappa")
    assert_allclose(orth.position[0, 2], 1000.0 - 12.5, atol=1e-9)
    assert "orthometric" in orth.frame


def test_boresight_effect():
    traj = level_trajectory(30.0, 114.0, heading_deg=70.0)
    frame = EnuFrame(np.deg2rad(30.0), np.deg2rad(114.0), 0.0)
    b_deg = np.array([0.01, -0.02, 0.05])
    with_b = ex.compute_eo(traj, ["a"], [1.0], CameraMounting(NADIR_AXES, np.zeros(3),
                                                             np.deg2rad(b_deg)), frame)
    without = ex.compute_eo(traj, ["a"], [1.0], CameraMounting(), frame)
    d = np.abs(angle_diff(with_b.angles[0], without.angles[0])) / ARCSEC
    # tens to hundreds of arcsec: the tilt magnitude and kappa are rotation invariants
    assert_allclose(np.hypot(d[0], d[1]), np.hypot(*b_deg[:2]) * 3600, rtol=1e-3)
    assert_allclose(d[2], b_deg[2] * 3600, rtol=1e-3)
    assert 10 < d.min() and d.max() < 500


def test_sigmas_level_flight():
    traj = level_trajectory(30.0, 114.0, heading_deg=0.0)
    frame = EnuFrame(np.deg2rad(30.0), np.deg2rad(114.0), 0.0)
    s_time = np.array([0.0, 2.0])
    std = np.array([[0.02, 0.03, 0.05, 0, 0, 0, *np.deg2rad([0.002, 0.003, 0.01])]] * 2)
    eo = ex.compute_eo(traj, ["a"], [1.0], CameraMounting(), frame, "omega-phi-kappa",
                       sigma=(s_time, std))
    # ENU: X = east, Y = north, Z = up
    assert_allclose(eo.position_sigma[0], [0.03, 0.02, 0.05], rtol=1e-9)
    # nadir camera, x_c forward = north: omega is about east (pitch), phi about north (roll)
    assert_allclose(eo.angle_sigma[0], np.deg2rad([0.003, 0.002, 0.01]), rtol=1e-5)


def test_csv_round_trip(tmp_path):
    eo = ex.compute_eo(TRAJ, IDS, T_EV, MOUNT, EnuFrame(*ORIGIN),
                       sigma=(T200[[0, -1]], np.full((2, 9), 0.01)))
    p = tmp_path / "eo.csv"
    ex.write_eo_csv(p, eo, comments=["trajectory = closed form"])
    text = p.read_text().splitlines()
    assert text[0] == "# insphoto exterior orientation"
    assert text[1] == "# system = phi-omega-kappa"
    assert text[5].startswith("image_id,time_s,X_m,Y_m,Z_m,phi_deg,omega_deg,kappa_deg,sigma_X_m")
    back = ex.read_eo_csv(p)
    assert back.image_id == eo.image_id and back.frame == eo.frame
    assert np.abs(back.position - eo.position).max() <= 5e-7
    assert np.abs(back.angles - eo.angles).max() <= np.deg2rad(5e-11)
    # the other system: same rotation matrices
    ex.write_eo_csv(p, eo, system="omega-phi-kappa")
    opk = ex.read_eo_csv(p)
    assert opk.system == "omega-phi-kappa"
    assert np.abs(opk.matrices() - eo.matrices()).max() < 1e-11
    assert p.read_text().splitlines()[4].split(",")[5:8] == ["omega_deg", "phi_deg", "kappa_deg"]


def test_applanix_and_patb_round_trip(tmp_path):
    eo = ex.compute_eo(TRAJ, IDS, T_EV, MOUNT, EnuFrame(*ORIGIN))
    p = tmp_path / "eo.txt"
    ex.write_eo_applanix(p, eo)
    a = ex.read_eo_applanix(p)
    assert a.system == "omega-phi-kappa" and a.image_id == eo.image_id
    assert np.abs(a.matrices() - eo.matrices()).max() < 1e-11
    assert_allclose(a.time, eo.time, atol=5e-7)
    q = tmp_path / "eo.patb"
    ex.write_eo_patb(q, eo)
    b = ex.read_eo_patb(q, system="phi-omega-kappa")
    assert np.abs(b.matrices() - eo.matrices()).max() < 1e-14
    assert np.abs(b.position - eo.position).max() <= 5e-7
    # PATB holds R = C_mc: the camera's viewing direction -z_c points down in ENU
    assert np.all(b.matrices()[:, 2, 2] > 0.9)


def test_read_errors(tmp_path):
    p = tmp_path / "events.csv"
    p.write_text("image_id,time_s\nA,1.0\nB,x\n")
    with pytest.raises(InputError, match=r"events.csv:3: time_s 'x' is not a number"):
        ex.read_events(p)
    p.write_text("image_id,time_s\nA,1.0\nA,2.0\n")
    with pytest.raises(InputError, match=r"events.csv:3: image_id 'A' repeats line 2"):
        ex.read_events(p)
    p.write_text("id,t\nA,1.0\n")
    with pytest.raises(InputError, match=r"events.csv:1: header"):
        ex.read_events(p)
    e = tmp_path / "eo.csv"
    e.write_text("# system = phi-omega-kappa\nimage_id,time_s,X_m,Y_m,Z_m,omega_deg,phi_deg,"
                 "kappa_deg\nA,1,2,3,4,5,6,7\n")
    with pytest.raises(InputError, match=r"eo.csv:2: columns must be"):
        ex.read_eo_csv(e)
    with pytest.raises(InputError, match="event IMG_0000 at t = 30.0 s"):
        ex.compute_eo(TRAJ, ["IMG_0000"], [30.0], MOUNT, EnuFrame(*ORIGIN))
    with pytest.raises(InputError, match="not a projected CRS"):
        parse_frame("EPSG:4326")
    with pytest.raises(InputError, match="unknown mapping frame"):
        parse_frame("lambert")


def test_mapping_frames():
    assert utm_epsg(np.deg2rad(45.0), np.deg2rad(119.9)) == 32650
    assert utm_epsg(np.deg2rad(-10.0), np.deg2rad(-179.0)) == 32701
    f = parse_frame("utm", ORIGIN)
    lla = TURN.lla(T_EV)
    assert_allclose(f.to_lla(f.position(lla)), lla, atol=1e-9)
    e = EnuFrame(*ORIGIN)
    assert_allclose(e.to_lla(e.position(lla)), lla, atol=1e-9)
    # the convergence from pyproj has the sign of the finite-difference grid azimuth
    g = f.convergence(lla[:1])[0]
    tr = pyproj.Transformer.from_crs("EPSG:4326", f.crs, always_xy=True)
    lat, lon = np.rad2deg(lla[0, :2])
    e0, n0 = tr.transform(lon, lat - 1e-6)
    e1, n1 = tr.transform(lon, lat + 1e-6)
    assert abs(g + np.arctan2(e1 - e0, n1 - n0)) < 1e-8


def test_position_sigmas_rotated_into_a_projected_frame():
    """The NED position sigmas rotated into a grid frame 3 deg off the central meridian
    (convergence ~2.1 deg), against the grid azimuth of north from pyproj by differences:
    sigma_X^2 = sin^2(g) sN^2 + cos^2(g) sE^2, sigma_Y^2 = cos^2(g) sN^2 + sin^2(g) sE^2
    (a mutation using |C_mn| instead of C_mn^2 survived: at the ENU origin C_mn is a
    permutation and both agree)."""
    traj = level_trajectory(45.0, 120.0, heading_deg=30.0)
    s_time = np.array([0.0, 2.0])
    sN, sE, sD = 0.02, 0.03, 0.05
    std = np.array([[sN, sE, sD, 0, 0, 0, *np.deg2rad([0.002, 0.003, 0.01])]] * 2)
    eo = ex.compute_eo(traj, ["a"], [1.0], CameraMounting(), parse_frame("EPSG:32650"),
                       "omega-phi-kappa", sigma=(s_time, std))
    tr = pyproj.Transformer.from_crs("EPSG:4326", "EPSG:32650", always_xy=True)
    e0, n0 = tr.transform(120.0, 45.0 - 1e-6)
    e1, n1 = tr.transform(120.0, 45.0 + 1e-6)
    g = np.arctan2(e1 - e0, n1 - n0)                  # grid azimuth of true north
    assert np.deg2rad(2.0) < abs(g) < np.deg2rad(2.2)
    ref = [np.sqrt(np.sin(g) ** 2 * sN ** 2 + np.cos(g) ** 2 * sE ** 2),
           np.sqrt(np.cos(g) ** 2 * sN ** 2 + np.sin(g) ** 2 * sE ** 2), sD]
    assert_allclose(eo.position_sigma[0], ref, rtol=1e-6)
