"""Tests of photogrammetry.orientation.rotation against the textbooks' elements written out, the
Wolf/Dewitt matrix, scipy compositions, pymap3d and OpenCV."""
import numpy as np
import pymap3d
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from ins.nav.earth import lla_to_ecef
from ins.nav.rotation import euler_to_dcm, wrap_to_pi
from photogrammetry.orientation import rotation as pr

rng = np.random.default_rng(7)
N = 2000
SCIPY_SEQ = {"phi-omega-kappa": "YXZ", "omega-phi-kappa": "XYZ"}
#: scipy's intrinsic angles of each system: phi-omega-kappa is Ry(-phi) Rx(omega) Rz(kappa)
SCIPY_SIGN = {"phi-omega-kappa": np.array([-1.0, 1.0, 1.0]), "omega-phi-kappa": np.ones(3)}


def scipy_matrix(a, system):
    return Rotation.from_euler(SCIPY_SEQ[system], np.asarray(a) * SCIPY_SIGN[system]).as_matrix()


def scipy_angles(R, system):
    return Rotation.from_matrix(R).as_euler(SCIPY_SEQ[system]) * SCIPY_SIGN[system]


def textbook_elements(phi, omega, kappa):
    """The nine elements a1..c3 of the phi-omega-kappa matrix as the Russian/Vietnamese/
    Chinese textbooks print them (conventions.md), written out; rows a, b, c."""
    sp, cp, so, co, sk, ck = (np.sin(phi), np.cos(phi), np.sin(omega), np.cos(omega),
                              np.sin(kappa), np.cos(kappa))
    a1 = cp * ck - sp * so * sk
    a2 = -cp * sk - sp * so * ck
    a3 = -sp * co
    b1 = co * sk
    b2 = co * ck
    b3 = -so
    c1 = sp * ck + cp * so * sk
    c2 = -sp * sk + cp * so * ck
    c3 = cp * co
    return np.array([[a1, a2, a3], [b1, b2, b3], [c1, c2, c3]]).transpose(2, 0, 1)


def wolf_dewitt_M(omega, phi, kappa):
    """Wolf/Dewitt's object-to-image matrix M (Elements of Photogrammetry), element by
    element; the omega-phi-kappa R = C_mc is its transpose."""
    so, co, sp, cp, sk, ck = (np.sin(omega), np.cos(omega), np.sin(phi), np.cos(phi),
                              np.sin(kappa), np.cos(kappa))
    m11 = cp * ck
    m12 = so * sp * ck + co * sk
    m13 = -co * sp * ck + so * sk
    m21 = -cp * sk
    m22 = -so * sp * sk + co * ck
    m23 = co * sp * sk + so * ck
    m31 = sp
    m32 = -so * cp
    m33 = co * cp
    return np.array([[m11, m12, m13], [m21, m22, m23], [m31, m32, m33]]).transpose(2, 0, 1)


def random_angles(n):
    a = np.column_stack([rng.uniform(-np.pi, np.pi, n), rng.uniform(-np.pi / 2, np.pi / 2, n),
                         rng.uniform(-np.pi, np.pi, n)])
    return a


@pytest.mark.parametrize("system", pr.SYSTEMS)
def test_matrix_equals_scipy_composition(system):
    a = random_angles(N)
    R = pr.angles_to_matrix(a, system)
    # scipy: phi-omega-kappa = from_euler('YXZ', [-phi, omega, kappa])
    assert_allclose(R, scipy_matrix(a, system), atol=2e-15)
    # and the elementary product of ins.nav.rotation's rot_x/rot_y/rot_z for one item
    from ins.nav.rotation import rot_x, rot_y, rot_z
    p, m, k = a[0]
    prod = rot_y(-p) @ rot_x(m) @ rot_z(k) if system == "phi-omega-kappa" else \
        rot_x(p) @ rot_y(m) @ rot_z(k)
    assert_allclose(pr.angles_to_matrix(a[0], system), prod, atol=2e-16 * 10)


def test_phi_omega_kappa_is_the_textbooks_nine_elements():
    """The nine elements written out as the textbooks print them (not through our code
    or scipy), for random angles: matrix, extraction phi = atan2(-a3, c3),
    omega = asin(-b3), kappa = atan2(b1, b2), and the round trip; near the lock too."""
    a = random_angles(N)
    T = textbook_elements(*a.T)
    R = pr.angles_to_matrix(a, "phi-omega-kappa")
    assert np.abs(R - T).max() < 1e-15
    ang = pr.matrix_to_angles(T, "phi-omega-kappa")
    a3, b1, b2, b3, c3 = T[:, 0, 2], T[:, 1, 0], T[:, 1, 1], T[:, 1, 2], T[:, 2, 2]
    book = np.column_stack([np.arctan2(-a3, c3), np.arcsin(-b3), np.arctan2(b1, b2)])
    assert np.abs(ang - book).max() < 1e-12
    assert np.abs(ang - a).max() < 1e-12                       # the generating angles
    # the sign that gave its name to the issue: phi alone, a3 = -sin(phi)
    R = pr.angles_to_matrix([10.0, 0.0, 0.0], "phi-omega-kappa", degrees=True)
    assert R[0, 2] == pytest.approx(-np.sin(np.deg2rad(10.0)), abs=1e-16)
    assert R[2, 0] == pytest.approx(+np.sin(np.deg2rad(10.0)), abs=1e-16)
    # near the lock (omega -> +-90 deg): the literal elements still round-trip
    for near in (1e-3, 1e-6, 1e-9):
        b = random_angles(200)
        b[:, 1] = np.sign(b[:, 1]) * (np.pi / 2 - near)
        Tb = textbook_elements(*b.T)
        out = pr.matrix_to_angles(Tb, "phi-omega-kappa")
        assert np.abs(textbook_elements(*out.T) - Tb).max() < 1e-14
        assert np.abs(out[:, 1] - b[:, 1]).max() < 1e-7        # asin is ill-conditioned
        if near >= 1e-6:              # conditioning ~ 1/cos(omega): 1e-16 / near
            assert np.abs(wrap_to_pi(out - b)).max() < 1e-8


def test_omega_phi_kappa_is_the_transpose_of_wolf_dewitt_M():
    """Wolf/Dewitt's M (object to image), element by element, is R^T of omega-phi-kappa."""
    a = random_angles(N)                 # (omega, phi, kappa): primary, middle, kappa
    M = wolf_dewitt_M(*a.T)
    R = pr.angles_to_matrix(a, "omega-phi-kappa")
    assert np.abs(R - np.swapaxes(M, 1, 2)).max() < 1e-15
    # extraction from M^T, in Wolf's terms: phi = asin(m31), omega = atan2(-m32, m33),
    # kappa = atan2(-m21, m11)
    ang = pr.matrix_to_angles(np.swapaxes(M, 1, 2), "omega-phi-kappa")
    wolf = np.column_stack([np.arctan2(-M[:, 2, 1], M[:, 2, 2]), np.arcsin(M[:, 2, 0]),
                            np.arctan2(-M[:, 1, 0], M[:, 0, 0])])
    assert np.abs(ang - wolf).max() < 1e-12 and np.abs(ang - a).max() < 1e-12


def test_near_nadir_phi_changes_sign_omega_agrees():
    """Near nadir with the mapping x axis east, the Western and the textbooks' systems
    differ in the sign of phi (phi_W ~ -phi_CN) and agree in omega to first order."""
    for eps in (1e-2, 1e-3):
        a = rng.uniform(-eps, eps, (500, 3))
        a[:, 2] = rng.uniform(-np.pi, np.pi, 500)               # any kappa
        w = pr.convert_angles(a, "phi-omega-kappa", "omega-phi-kappa")
        # second order: |phi_W + phi_CN|, |omega_W - omega_CN| <= (3 eps)^2
        assert np.abs(w[:, 1] + a[:, 0]).max() < 2 * eps ** 2
        assert np.abs(w[:, 0] - a[:, 1]).max() < 2 * eps ** 2
        assert np.abs(wrap_to_pi(w[:, 2] - a[:, 2])).max() < 2 * eps ** 2
    # literally: the Western M (Wolf/Dewitt) and the textbooks' elements for phi_W = -phi
    phi, omega, kappa = 1e-3, -2e-3, 0.7
    MT = np.swapaxes(wolf_dewitt_M(np.array([omega]), np.array([-phi]), np.array([kappa])),
                     1, 2)
    T = textbook_elements(np.array([phi]), np.array([omega]), np.array([kappa]))
    assert np.abs(MT - T).max() < 3e-6            # equal up to products of two small angles


def test_active_sign_convention():
    # phi-omega-kappa with only kappa = 90 deg turns the camera x axis onto the map Y axis
    R = pr.angles_to_matrix([0, 0, 90], "phi-omega-kappa", degrees=True)
    assert_allclose(R @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    # only omega = 90 deg turns camera y onto map Z (active rotation about X)
    R = pr.angles_to_matrix([90, 0, 0], "omega-phi-kappa", degrees=True)
    assert_allclose(R @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    # phi-omega-kappa with only phi = 90 deg: Ry(-phi) turns camera z onto map -X, so a
    # positive phi tilts the view (-z) towards +X (east); omega-phi-kappa's phi the other way
    R = pr.angles_to_matrix([90, 0, 0], "phi-omega-kappa", degrees=True)
    assert_allclose(R @ [0, 0, -1], [1, 0, 0], atol=1e-15)
    R = pr.angles_to_matrix([0, 90, 0], "omega-phi-kappa", degrees=True)
    assert_allclose(R @ [0, 0, -1], [-1, 0, 0], atol=1e-15)


@pytest.mark.parametrize("system", pr.SYSTEMS)
def test_round_trip(system):
    a = random_angles(N)
    b = pr.matrix_to_angles(pr.angles_to_matrix(a, system), system)
    assert np.abs(b - a).max() < 1e-12
    # matrix -> angles -> matrix for random rotations, and the scipy angles
    R = Rotation.random(N, rng).as_matrix()
    ang = pr.matrix_to_angles(R, system)
    assert np.abs(pr.angles_to_matrix(ang, system) - R).max() < 1e-14
    ref = scipy_angles(R, system)
    assert np.abs(wrap_to_pi(ang - ref)).max() < 1e-10
    # degrees
    d = pr.matrix_to_angles(R[:5], system, degrees=True)
    assert_allclose(pr.angles_to_matrix(d, system, degrees=True), R[:5], atol=1e-14)


@pytest.mark.parametrize("system", pr.SYSTEMS)
@pytest.mark.parametrize("middle_deg", [90.0, -90.0])
def test_gimbal_lock(system, middle_deg):
    for near in (0.0, 1e-9, 1e-6):
        a = np.array([0.7, np.deg2rad(middle_deg) - np.sign(middle_deg) * near, -0.4])
        R = pr.angles_to_matrix(a, system)
        b = pr.matrix_to_angles(R, system)
        assert np.abs(pr.angles_to_matrix(b, system) - R).max() < 1e-14
        assert np.all(np.isfinite(b))
        if near == 0.0:
            assert b[2] == 0.0                        # documented rule: kappa = 0
            assert abs(b[1] - np.deg2rad(middle_deg)) < 1e-12
        elif near >= 1e-6:   # conditioning ~ 1/cos(middle) = 1e6: still 1e-9 rad
            assert np.abs(b - a).max() < 1e-8


def test_systems_differ_and_convert():
    a_pok = np.deg2rad([2.0, -3.0, 40.0])
    R = pr.angles_to_matrix(a_pok, "phi-omega-kappa")
    a_opk = pr.convert_angles(a_pok, "phi-omega-kappa", "omega-phi-kappa")
    assert_allclose(pr.angles_to_matrix(a_opk, "omega-phi-kappa"), R, atol=1e-15)
    # merely reordering the numbers is NOT a conversion: it gives another rotation
    wrong = pr.angles_to_matrix(a_pok[[1, 0, 2]], "omega-phi-kappa")
    assert np.abs(wrong - R).max() > 1e-4


def test_errors():
    with pytest.raises(ValueError, match="phi-omega-kappa.*omega-phi-kappa"):
        pr.angles_to_matrix([0, 0, 0], "opk")
    with pytest.raises(ValueError, match=r"\(3,\) or \(n, 3\)"):
        pr.angles_to_matrix(np.zeros((2, 4)), "omega-phi-kappa")
    with pytest.raises(ValueError, match=r"\(3, 3\) or \(n, 3, 3\)"):
        pr.matrix_to_angles(np.eye(4), "omega-phi-kappa")
    a = np.zeros(3)
    pr.angles_to_matrix(a, "phi-omega-kappa", degrees=True)
    assert np.all(a == 0)


def test_dcm_mn_enu_against_pymap3d():
    lat0, lon0 = np.deg2rad(30.5), np.deg2rad(114.3)
    lat = lat0 + rng.uniform(-0.01, 0.01, 20)
    lon = lon0 + rng.uniform(-0.01, 0.01, 20)
    C_mn = pr.dcm_mn_enu(lat, lon, lat0, lon0)
    assert C_mn.shape == (20, 3, 3)
    # a NED vector at (lat, lon) in ECEF, then pymap3d's ecef2enuv at the origin
    v_n = rng.normal(size=(20, 3))
    from ins.nav.earth import dcm_en
    v_e = np.einsum("nij,nj->ni", dcm_en(lat, lon), v_n)
    ref = np.column_stack(pymap3d.ecef2enuv(v_e[:, 0], v_e[:, 1], v_e[:, 2], lat0, lon0,
                                            deg=False))
    assert_allclose(np.einsum("nij,nj->ni", C_mn, v_n), ref, atol=1e-14)
    # at the origin it is the plain swap
    assert_allclose(pr.dcm_mn_enu(lat0, lon0, lat0, lon0), pr.P_NED_ENU, atol=1e-16)
    # 1 km east of the origin the n frame is tilted by ~32 arcsec about north
    from ins.nav.earth import radii
    _, rn = radii(lat0)
    C = pr.dcm_mn_enu(lat0, lon0 + 1000 / (rn * np.cos(lat0)), lat0, lon0)
    tilt = np.rad2deg(np.arccos(C[2, 2] * -1)) * 3600
    assert 31 < tilt < 33.5


def test_boresight_and_camera_attitude():
    b = np.deg2rad([0.01, -0.02, 0.05])
    B = pr.boresight_matrix(b)
    assert_allclose(B, Rotation.from_euler("XYZ", b).as_matrix(), atol=1e-16)
    C_nb = euler_to_dcm(rng.normal(size=(5, 3)))
    C_mc = pr.camera_attitude(C_nb, B, pr.P_NED_ENU)
    assert_allclose(C_mc, pr.P_NED_ENU @ C_nb @ B, atol=0)
    with pytest.raises(ValueError, match="C_bc"):
        pr.camera_attitude(C_nb, np.eye(2), np.eye(3))


def test_cv_rotation_projects_like_opencv():
    cv2 = pytest.importorskip("cv2")
    f_px, u0, v0 = 5000.0, 2000.0, 1500.0
    X0 = np.array([100.0, -50.0, 800.0])
    C_mc = pr.angles_to_matrix([2.0, -1.5, 30.0], "omega-phi-kappa", degrees=True)
    X = X0 + rng.uniform(-300, 300, (10, 3)) * [1, 1, 0] - [0, 0, 800.0]
    # our collinearity: photo (x, y) = -f * (C_cm dX)[:2] / (C_cm dX)[2], y up
    d_c = (X - X0) @ C_mc                 # rows: C_mc.T @ dX
    xy = -d_c[:, :2] / d_c[:, 2:] * f_px  # pixels, y up
    uv_ours = np.column_stack([u0 + xy[:, 0], v0 - xy[:, 1]])
    R_cw = pr.to_cv_rotation(C_mc)
    rvec, _ = cv2.Rodrigues(R_cw)
    K = np.array([[f_px, 0, u0], [0, f_px, v0], [0, 0, 1.0]])
    uv_cv, _ = cv2.projectPoints(X, rvec, -R_cw @ X0, K, None)
    assert_allclose(uv_cv[:, 0], uv_ours, atol=1e-6)
    assert_allclose(pr.from_cv_rotation(R_cw), C_mc, atol=1e-16)
    assert_allclose(pr.from_cv_rotation(pr.to_cv_rotation(np.stack([C_mc] * 3))),
                    np.stack([C_mc] * 3), atol=1e-16)


def test_lla_to_ecef_used_consistently():
    # guard: ins.nav.earth and pymap3d agree on WGS84 (the ENU frame relies on both)
    x = lla_to_ecef(0.5, 2.0, 100.0)
    assert_allclose(x, pymap3d.geodetic2ecef(0.5, 2.0, 100.0, deg=False), atol=1e-8)
