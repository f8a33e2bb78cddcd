"""Tests of ins.nav.rotation against scipy.spatial.transform.Rotation and closed forms."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.spatial.transform import Rotation

from ins.nav import rotation as rot

N = 1000
TOL = 1e-12
MTOL = 5e-15  # matrix elements of |.| <= 1

rng = np.random.default_rng(20240521)
R_RAND = Rotation.random(N, rng)
C_RAND = R_RAND.as_matrix()
Q_RAND = R_RAND.as_quat()          # either sign
RPY_RAND = R_RAND.as_euler("ZYX")[:, ::-1]
RV_RAND = R_RAND.as_rotvec()
AXES = rng.normal(size=(50, 3))
AXES /= np.linalg.norm(AXES, axis=1, keepdims=True)


def canon(q):
    """w >= 0, independent of the module."""
    q = np.asarray(q)
    return np.where(q[..., 3:] < 0, -q, q)


def assert_same_rotation_quat(q, q_ref, tol=TOL):
    q, q_ref = np.atleast_2d(q), np.atleast_2d(q_ref)
    err = np.minimum(np.abs(q - q_ref).max(axis=-1), np.abs(q + q_ref).max(axis=-1))
    assert err.max() <= tol, err.max()


def angle_diff(a, b):
    return np.angle(np.exp(1j * (np.asarray(a) - np.asarray(b))))


# --------------------------------------------------------------------------
# skew and elementary rotations
def test_skew_cross_product():
    a, b = rng.normal(size=(2, N, 3))
    S = rot.skew(a)
    assert S.shape == (N, 3, 3)
    assert_allclose(np.einsum("nij,nj->ni", S, b), np.cross(a, b), rtol=0, atol=1e-14)
    assert_array_equal(S, -np.swapaxes(S, 1, 2))
    assert_allclose(rot.skew(a[0]) @ b[0], np.cross(a[0], b[0]), rtol=0, atol=1e-14)
    assert_array_equal(rot.skew([1.0, 2.0, 3.0]), [[0, -3, 2], [3, 0, -1], [-2, 1, 0]])


@pytest.mark.parametrize("func, axis", [(rot.rot_x, "x"), (rot.rot_y, "y"), (rot.rot_z, "z")])
def test_elementary_vs_scipy(func, axis):
    a = rng.uniform(-4, 4, N)
    assert_allclose(func(a), Rotation.from_euler(axis, a[:, None]).as_matrix(), rtol=0, atol=MTOL)
    assert_allclose(func(a[3]), Rotation.from_euler(axis, a[3]).as_matrix(), rtol=0, atol=MTOL)
    assert func(0.3).shape == (3, 3) and func(a).shape == (N, 3, 3)


def test_rot_x_explicit():
    a = 0.7
    c, s = np.cos(a), np.sin(a)
    assert_array_equal(rot.rot_x(a), [[1, 0, 0], [0, c, -s], [0, s, c]])


def test_euler_is_zyx_product():
    rpy = rng.uniform(-np.pi, np.pi, (N, 3))
    expected = rot.rot_z(rpy[:, 2]) @ rot.rot_y(rpy[:, 1]) @ rot.rot_x(rpy[:, 0])
    assert_allclose(rot.euler_to_dcm(rpy), expected, rtol=0, atol=MTOL)


# --------------------------------------------------------------------------
# quaternion <-> DCM
def test_quat_to_dcm_vs_scipy():
    assert_allclose(rot.quat_to_dcm(Q_RAND), C_RAND, rtol=0, atol=MTOL)
    # non-unit quaternions are normalised, as scipy does
    q = rng.normal(size=(N, 4)) * rng.uniform(0.1, 10, (N, 1))
    assert_allclose(rot.quat_to_dcm(q), Rotation.from_quat(q).as_matrix(), rtol=0, atol=MTOL)


def test_quat_to_dcm_c13_erratum():
    """conventions.md erratum 2: C13 = 2 (q1 q3 + q2 q4); the INS paper prints a minus."""
    q = canon(Q_RAND)
    C = rot.quat_to_dcm(q)
    assert_allclose(C[:, 0, 2], 2 * (q[:, 0] * q[:, 2] + q[:, 1] * q[:, 3]), rtol=0, atol=1e-15)
    # 90 deg about y: C13 = sin(90 deg) = +1 (the paper's sign would give -1)
    qy = [0.0, np.sin(np.pi / 4), 0.0, np.cos(np.pi / 4)]
    assert_allclose(rot.quat_to_dcm(qy)[0, 2], 1.0, rtol=0, atol=1e-15)
    assert_allclose(rot.quat_to_dcm(qy), rot.rot_y(np.pi / 2), rtol=0, atol=MTOL)


def test_dcm_to_quat_vs_scipy():
    q = rot.dcm_to_quat(C_RAND)
    assert np.all(q[:, 3] >= 0)
    assert_allclose(q, canon(Rotation.from_matrix(C_RAND).as_quat()), rtol=0, atol=TOL)
    assert_allclose(rot.quat_to_dcm(q), C_RAND, rtol=0, atol=MTOL)


@pytest.mark.parametrize("i", [0, 1, 2])
def test_dcm_to_quat_180_about_basis_axes(i):
    C = -np.eye(3)
    C[i, i] = 1.0
    expected = np.zeros(4)
    expected[i] = 1.0
    q = rot.dcm_to_quat(C)
    assert np.all(np.isfinite(q))
    assert_allclose(q, expected, rtol=0, atol=1e-15)


def test_dcm_to_quat_180_about_random_axes():
    exact = 2 * AXES[:, :, None] * AXES[:, None, :] - np.eye(3)    # 2 u u^T - I
    expected = np.concatenate([AXES, np.zeros((len(AXES), 1))], axis=1)
    assert_same_rotation_quat(rot.dcm_to_quat(exact), expected, tol=1e-15)
    C = Rotation.from_rotvec(np.pi * AXES).as_matrix()
    assert_same_rotation_quat(rot.dcm_to_quat(C), expected, tol=1e-15)
    rv = rot.dcm_to_rotvec(exact)
    assert_allclose(np.linalg.norm(rv, axis=1), np.pi, rtol=0, atol=1e-15)
    assert_allclose(np.abs(np.sum(rv * AXES, axis=1)), np.pi, rtol=0, atol=1e-15)


def test_dcm_to_quat_just_below_180():
    theta = np.pi - 1e-9
    C = Rotation.from_rotvec(theta * AXES).as_matrix()
    q = rot.dcm_to_quat(C)
    expected = np.concatenate([AXES * np.sin(theta / 2), np.full((len(AXES), 1), np.cos(theta / 2))],
                              axis=1)
    assert np.all(q[:, 3] > 0)
    assert_allclose(q, expected, rtol=0, atol=1e-15)
    assert_allclose(rot.dcm_to_rotvec(C), theta * AXES, rtol=0, atol=TOL)


# --------------------------------------------------------------------------
# Euler angles
def test_euler_to_dcm_vs_scipy():
    rpy = rng.uniform(-2 * np.pi, 2 * np.pi, (N, 3))
    expected = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix()
    assert_allclose(rot.euler_to_dcm(rpy), expected, rtol=0, atol=MTOL)
    assert_allclose(rot.euler_to_dcm(np.rad2deg(rpy), degrees=True), expected, rtol=0, atol=MTOL)


def test_dcm_to_euler_vs_scipy():
    rpy = rot.dcm_to_euler(C_RAND)
    assert_allclose(angle_diff(rpy, RPY_RAND), 0, rtol=0, atol=TOL)
    assert np.all((rpy[:, [0, 2]] > -np.pi) & (rpy[:, [0, 2]] <= np.pi))
    assert np.all(np.abs(rpy[:, 1]) <= np.pi / 2)
    # the yaw is the paper's omega = atan2(C21, C11)
    assert_allclose(angle_diff(rpy[:, 2], np.arctan2(C_RAND[:, 1, 0], C_RAND[:, 0, 0])), 0,
                    rtol=0, atol=TOL)
    deg = rot.dcm_to_euler(C_RAND, degrees=True)
    assert_allclose(angle_diff(np.deg2rad(deg), RPY_RAND), 0, rtol=0, atol=TOL)


def test_euler_round_trip():
    rpy = np.column_stack([rng.uniform(-np.pi, np.pi, N), rng.uniform(-np.pi / 2, np.pi / 2, N),
                           rng.uniform(-np.pi, np.pi, N)])
    assert_allclose(rot.dcm_to_euler(rot.euler_to_dcm(rpy)), rpy, rtol=0, atol=TOL)
    assert_allclose(rot.quat_to_euler(rot.euler_to_quat(rpy)), rpy, rtol=0, atol=TOL)
    assert_allclose(rot.euler_to_dcm(rot.dcm_to_euler(C_RAND)), C_RAND, rtol=0, atol=MTOL)


def test_euler_to_quat_and_back_vs_scipy():
    rpy = rng.uniform(-2 * np.pi, 2 * np.pi, (N, 3))
    q = rot.euler_to_quat(rpy)
    assert np.all(q[:, 3] >= 0)
    assert_allclose(q, canon(Rotation.from_euler("ZYX", rpy[:, ::-1]).as_quat()), rtol=0, atol=TOL)
    assert_allclose(rot.euler_to_quat(np.rad2deg(rpy), degrees=True), q, rtol=0, atol=TOL)
    assert_allclose(angle_diff(rot.quat_to_euler(Q_RAND), RPY_RAND), 0, rtol=0, atol=TOL)
    assert_allclose(angle_diff(np.deg2rad(rot.quat_to_euler(Q_RAND, degrees=True)), RPY_RAND), 0,
                    rtol=0, atol=TOL)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_gimbal_lock(sign):
    """Pitch exactly +-90 deg: roll = 0, yaw carries yaw -+ roll, matrix round trip exact."""
    roll, yaw = rng.uniform(-np.pi, np.pi, (2, 200))
    pitch = np.full(200, sign * np.pi / 2)
    C = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_matrix()
    for rpy in (rot.dcm_to_euler(C), rot.quat_to_euler(Rotation.from_matrix(C).as_quat())):
        assert_array_equal(rpy[:, 0], 0.0)
        assert_allclose(rpy[:, 1], sign * np.pi / 2, rtol=0, atol=1e-15)
        assert_allclose(angle_diff(rpy[:, 2], yaw - sign * roll), 0, rtol=0, atol=TOL)
        back = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix()
        assert_allclose(back, C, rtol=0, atol=MTOL)
        assert_allclose(rot.euler_to_dcm(rpy), C, rtol=0, atol=MTOL)


@pytest.mark.parametrize("offset", [1e-4, 1e-7, 1e-9, 1e-12, 1e-14, 1e-15, 1e-16])
def test_near_gimbal_lock_matrix_round_trip(offset):
    roll, yaw = rng.uniform(-np.pi, np.pi, (2, 200))
    pitch = rng.choice([-1.0, 1.0], 200) * (np.pi / 2 - offset)
    C = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_matrix()
    rpy = rot.dcm_to_euler(C)
    assert_allclose(Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix(), C, rtol=0, atol=1e-13)
    assert_allclose(rpy[:, 1], pitch, rtol=0, atol=1e-12)


def test_euler_range_edges():
    # -0.0 elements would give atan2 = -pi: must come out as +pi
    assert_array_equal(rot.dcm_to_euler(np.diag([-1.0, -1.0, 1.0])), [0.0, 0.0, np.pi])
    assert_array_equal(rot.dcm_to_euler([[1.0, 0, 0], [0, -1, -0.0], [0, -0.0, -1]]), [np.pi, 0, 0])
    assert_array_equal(rot.dcm_to_euler(np.diag([-1.0, -1.0, 1.0]), degrees=True), [0, 0, 180.0])
    assert_array_equal(rot.dcm_to_euler([[-1.0, 0, 0], [0, -1, 0], [0, -0.0, 1]]), [0, 0, np.pi])
    # yaw = -pi + 1e-16 rounds to -pi in atan2: must still come out as +pi
    for C in (rot.rot_z(-np.pi), Rotation.from_euler("z", -np.pi).as_matrix()):
        assert rot.dcm_to_euler(C)[2] == np.pi
        assert rot.quat_to_euler(rot.dcm_to_quat(C))[2] == np.pi


# --------------------------------------------------------------------------
# rotation vectors
def test_rotvec_vs_scipy():
    rv = rng.normal(size=(N, 3)) * rng.uniform(0, 3 * np.pi, (N, 1))   # norms beyond pi too
    q = rot.rotvec_to_quat(rv)
    assert np.all(q[:, 3] >= 0)
    assert_allclose(q, canon(Rotation.from_rotvec(rv).as_quat()), rtol=0, atol=TOL)
    assert_allclose(rot.rotvec_to_dcm(rv), Rotation.from_rotvec(rv).as_matrix(), rtol=0, atol=MTOL)
    assert_allclose(rot.quat_to_rotvec(Q_RAND), RV_RAND, rtol=0, atol=TOL)
    assert_allclose(rot.quat_to_rotvec(-Q_RAND), RV_RAND, rtol=0, atol=TOL)
    assert_allclose(rot.dcm_to_rotvec(C_RAND), RV_RAND, rtol=0, atol=TOL)
    assert np.all(np.linalg.norm(rot.quat_to_rotvec(Q_RAND), axis=1) <= np.pi * (1 + 4e-16))


def test_rotvec_round_trip():
    assert_allclose(rot.quat_to_rotvec(rot.rotvec_to_quat(RV_RAND)), RV_RAND, rtol=0, atol=TOL)
    assert_allclose(rot.dcm_to_rotvec(rot.rotvec_to_dcm(RV_RAND)), RV_RAND, rtol=0, atol=TOL)


@pytest.mark.parametrize("angle", [0.0, 1e-20, 1e-12, 1e-7, 1e-5, 0.99e-4, 1.01e-4, 1e-3])
def test_tiny_rotvec_exact(angle):
    rv = AXES * angle
    with np.errstate(all="raise"):
        q = rot.rotvec_to_quat(rv)
        C = rot.rotvec_to_dcm(rv)
    half = np.sin(angle / 2) / angle if angle > 0 else 0.5   # independent truth
    assert_allclose(q[:, :3], rv * half, rtol=2e-16 * 8, atol=0)
    assert_allclose(q[:, 3], np.cos(angle / 2), rtol=0, atol=1e-16)
    assert_allclose(C, Rotation.from_rotvec(rv).as_matrix(), rtol=0, atol=MTOL)
    assert_allclose(C - np.eye(3), rot.skew(rv) + rot.skew(rv) @ rot.skew(rv) / 2,
                    rtol=0, atol=angle**3 + 4e-16)


@pytest.mark.parametrize("s", [0.0, 5e-21, 5e-13, 1e-6, 0.99e-4, 1.01e-4])
def test_tiny_quat_to_rotvec_exact(s):
    v = AXES * s
    q = np.concatenate([v, np.sqrt(1 - s * s) * np.ones((len(AXES), 1))], axis=1)
    with np.errstate(all="raise"):
        rv = rot.quat_to_rotvec(q)
    assert_allclose(rv, AXES * 2 * np.arcsin(s), rtol=2e-16 * 8, atol=0)


@pytest.mark.parametrize("theta", [np.pi - 1e-9, np.pi, np.pi + 1e-9])
def test_quat_to_rotvec_near_pi(theta):
    q = np.concatenate([AXES * np.sin(theta / 2), np.full((len(AXES), 1), np.cos(theta / 2))],
                       axis=1)
    rv = rot.quat_to_rotvec(q)
    norms = np.linalg.norm(rv, axis=1)
    assert np.all(norms <= np.pi * (1 + 4e-16))   # angle <= pi; the norm itself has rounding
    assert_allclose(norms, np.pi - abs(theta - np.pi), rtol=0, atol=1e-15)
    if theta != np.pi:
        assert_allclose(rv, np.sign(np.pi - theta) * AXES * (np.pi - abs(theta - np.pi)),
                        rtol=0, atol=TOL)
    assert_allclose(rot.rotvec_to_dcm(rv), Rotation.from_quat(q).as_matrix(), rtol=0, atol=MTOL)


# --------------------------------------------------------------------------
# quaternion algebra
def test_quat_multiply_vs_scipy():
    p, q = Q_RAND, Q_RAND[::-1]
    expected = (Rotation.from_quat(p) * Rotation.from_quat(q)).as_quat()
    assert_same_rotation_quat(rot.quat_multiply(p, q), expected)
    # C_ab @ C_bc
    assert_allclose(rot.quat_to_dcm(rot.quat_multiply(p, q)), C_RAND @ C_RAND[::-1], rtol=0,
                    atol=MTOL)
    # single with stack, both ways
    assert_array_equal(rot.quat_multiply(p[0], q)[:5], [rot.quat_multiply(p[0], x) for x in q[:5]])
    assert_same_rotation_quat(rot.quat_multiply(p, q[0]),
                              (Rotation.from_quat(p) * Rotation.from_quat(q[0])).as_quat())


def test_quat_multiply_hamilton_table():
    i, j, k, one = np.eye(4)
    assert_array_equal(rot.quat_multiply(i, j), k)
    assert_array_equal(rot.quat_multiply(j, k), i)
    assert_array_equal(rot.quat_multiply(k, i), j)
    assert_array_equal(rot.quat_multiply(j, i), -k)
    assert_array_equal(rot.quat_multiply(i, i), -one)
    assert_array_equal(rot.quat_multiply(one, Q_RAND), Q_RAND)


def test_quat_conjugate_normalize_rotate():
    qc = rot.quat_conjugate(Q_RAND)
    assert_same_rotation_quat(qc, Rotation.from_quat(Q_RAND).inv().as_quat())
    assert_allclose(rot.quat_multiply(Q_RAND, qc), np.tile([0, 0, 0, 1.0], (N, 1)), rtol=0,
                    atol=1e-15)
    raw = rng.normal(size=(N, 4))
    qn = rot.quat_normalize(raw)
    assert_allclose(np.linalg.norm(qn, axis=1), 1, rtol=0, atol=1e-15)
    assert_allclose(qn * np.linalg.norm(raw, axis=1, keepdims=True), raw, rtol=1e-15)
    v = rng.normal(size=(N, 3))
    R = Rotation.from_quat(Q_RAND)
    assert_allclose(rot.quat_rotate(Q_RAND, v), R.apply(v), rtol=0, atol=1e-14)
    assert_allclose(rot.quat_rotate(Q_RAND, v[0]), R.apply(v[0]), rtol=0, atol=1e-14)
    assert_allclose(rot.quat_rotate(Q_RAND[0], v), R[0].apply(v), rtol=0, atol=1e-14)
    assert_allclose(rot.quat_rotate(Q_RAND[0], v[0]), R[0].apply(v[0]), rtol=0, atol=1e-14)
    assert_allclose(rot.quat_rotate(raw, v), Rotation.from_quat(raw).apply(v), rtol=0, atol=1e-14)


# --------------------------------------------------------------------------
# angle wrapping
def test_wrap_to_pi():
    assert rot.wrap_to_pi(np.pi) == np.pi
    assert rot.wrap_to_pi(-np.pi) == np.pi
    assert rot.wrap_to_pi(3 * np.pi) == np.pi
    assert rot.wrap_to_pi(-1e-20) == -1e-20
    assert rot.wrap_to_pi(0.0) == 0.0
    assert_allclose(rot.wrap_to_pi(2 * np.pi + 0.1), 0.1, rtol=0, atol=1e-15)
    assert_allclose(rot.wrap_to_pi(-np.pi - 0.1), np.pi - 0.1, rtol=0, atol=1e-15)
    a = rng.uniform(-100, 100, (40, 25))
    w = rot.wrap_to_pi(a)
    assert w.shape == a.shape
    assert np.all((w > -np.pi) & (w <= np.pi))
    assert_allclose(angle_diff(w, a), 0, rtol=0, atol=1e-13)
    inside = a[np.abs(a) < np.pi]
    assert_array_equal(rot.wrap_to_pi(inside), inside)


def test_wrap_to_2pi():
    assert rot.wrap_to_2pi(2 * np.pi) == 0.0
    assert rot.wrap_to_2pi(0.0) == 0.0
    assert rot.wrap_to_2pi(-2 * np.pi) == 0.0
    assert_allclose(rot.wrap_to_2pi(-np.pi / 2), 1.5 * np.pi, rtol=0, atol=1e-15)
    assert_allclose(rot.wrap_to_2pi(7.0), 7.0 - 2 * np.pi, rtol=0, atol=1e-15)
    assert 0 <= rot.wrap_to_2pi(-1e-20) < 2 * np.pi
    a = rng.uniform(-100, 100, (40, 25))
    w = rot.wrap_to_2pi(a)
    assert w.shape == a.shape
    assert np.all((w >= 0) & (w < 2 * np.pi))
    assert_allclose(angle_diff(w, a), 0, rtol=0, atol=1e-13)
    inside = a[(a >= 0) & (a < 2 * np.pi)]
    assert_array_equal(rot.wrap_to_2pi(inside), inside)


# --------------------------------------------------------------------------
# shapes, errors, inputs
CASES = [  # function, single input, stack input, single output shape (tail)
    (rot.skew, RV_RAND[0], RV_RAND[:7], (3, 3)),
    (rot.quat_conjugate, Q_RAND[0], Q_RAND[:7], (4,)),
    (rot.quat_normalize, Q_RAND[0], Q_RAND[:7], (4,)),
    (rot.quat_to_dcm, Q_RAND[0], Q_RAND[:7], (3, 3)),
    (rot.dcm_to_quat, C_RAND[0], C_RAND[:7], (4,)),
    (rot.euler_to_dcm, RPY_RAND[0], RPY_RAND[:7], (3, 3)),
    (rot.dcm_to_euler, C_RAND[0], C_RAND[:7], (3,)),
    (rot.euler_to_quat, RPY_RAND[0], RPY_RAND[:7], (4,)),
    (rot.quat_to_euler, Q_RAND[0], Q_RAND[:7], (3,)),
    (rot.rotvec_to_quat, RV_RAND[0], RV_RAND[:7], (4,)),
    (rot.quat_to_rotvec, Q_RAND[0], Q_RAND[:7], (3,)),
    (rot.rotvec_to_dcm, RV_RAND[0], RV_RAND[:7], (3, 3)),
    (rot.dcm_to_rotvec, C_RAND[0], C_RAND[:7], (3,)),
]


@pytest.mark.parametrize("func, one, many, tail", CASES, ids=[c[0].__name__ for c in CASES])
def test_shapes_and_read_only_inputs(func, one, many, tail):
    one, many = one.copy(), many.copy()
    one_ref, many_ref = one.copy(), many.copy()
    one.setflags(write=False)
    many.setflags(write=False)
    out_one, out_many = func(one), func(many)
    assert out_one.shape == tail
    assert out_many.shape == (len(many),) + tail
    assert_allclose(out_many[0], out_one, rtol=0, atol=1e-15)
    assert func(many[:1]).shape == (1,) + tail
    assert func(one.tolist()).shape == tail
    assert_array_equal(one, one_ref)
    assert_array_equal(many, many_ref)


def test_read_only_inputs_two_argument_functions():
    p, q, v = Q_RAND[:5].copy(), Q_RAND[5:10].copy(), RV_RAND[:5].copy()
    refs = [x.copy() for x in (p, q, v)]
    for x in (p, q, v):
        x.setflags(write=False)
    assert rot.quat_multiply(p, q).shape == (5, 4)
    assert rot.quat_multiply(p[0], q[0]).shape == (4,)
    assert rot.quat_rotate(q, v).shape == (5, 3)
    assert rot.quat_rotate(q[0], v[0]).shape == (3,)
    a = RPY_RAND[:5, 0].copy()
    a.setflags(write=False)
    for f in (rot.rot_x, rot.rot_y, rot.rot_z, rot.wrap_to_pi, rot.wrap_to_2pi):
        f(a * 5)
        f(a)
    assert rot.rot_z(a).shape == (5, 3, 3)
    for x, ref in zip((p, q, v), refs):
        assert_array_equal(x, ref)


@pytest.mark.parametrize("call, message", [
    (lambda: rot.euler_to_dcm(np.zeros((2, 4))),
     r"rpy must have shape \(3,\) or \(n, 3\), got \(2, 4\)"),
    (lambda: rot.euler_to_quat(np.zeros(4), degrees=True), r"rpy must have shape \(3,\)"),
    (lambda: rot.dcm_to_euler(np.zeros(9)), r"C must have shape \(3, 3\) or \(n, 3, 3\), got \(9,\)"),
    (lambda: rot.dcm_to_quat(np.zeros((3, 4))), r"C must have shape \(3, 3\) or \(n, 3, 3\)"),
    (lambda: rot.dcm_to_rotvec(np.zeros((2, 2, 3, 3))), r"C must have shape"),
    (lambda: rot.quat_to_dcm(np.zeros((3, 3))), r"q must have shape \(4,\) or \(n, 4\), got \(3, 3\)"),
    (lambda: rot.quat_to_euler(np.zeros(3)), r"q must have shape \(4,\)"),
    (lambda: rot.quat_to_rotvec(np.zeros((2, 3))), r"q must have shape \(4,\)"),
    (lambda: rot.quat_conjugate(np.zeros(5)), r"q must have shape \(4,\)"),
    (lambda: rot.quat_normalize(np.zeros((1, 1, 4))), r"q must have shape \(4,\)"),
    (lambda: rot.quat_multiply(np.zeros(3), Q_RAND[0]), r"p must have shape \(4,\)"),
    (lambda: rot.quat_multiply(Q_RAND[0], np.zeros((2, 3))), r"q must have shape \(4,\)"),
    (lambda: rot.quat_multiply(Q_RAND[:3], Q_RAND[:5]), r"p and q"),
    (lambda: rot.quat_rotate(Q_RAND[0], np.zeros((2, 2))), r"v must have shape \(3,\) or \(n, 3\)"),
    (lambda: rot.quat_rotate(Q_RAND[:3], RV_RAND[:5]), r"q and v"),
    (lambda: rot.rotvec_to_quat(np.zeros((2, 3, 1))), r"rv must have shape \(3,\) or \(n, 3\)"),
    (lambda: rot.rotvec_to_dcm(np.zeros(2)), r"rv must have shape"),
    (lambda: rot.skew(np.zeros(4)), r"v must have shape \(3,\) or \(n, 3\), got \(4,\)"),
    (lambda: rot.rot_x(np.zeros((2, 2))), r"angle must be a scalar or have shape \(n,\)"),
    (lambda: rot.quat_to_dcm(np.zeros(4)), r"q must have nonzero norm"),
    (lambda: rot.quat_normalize(np.zeros((2, 4))), r"q must have nonzero norm"),
])
def test_errors(call, message):
    with pytest.raises(ValueError, match=message):
        call()


# --------------------------------------------------------------------------
# non-finite input (issue 12: a NaN quaternion passed the `norm == 0` test and came out
# as a NaN "rotation"); every conversion refuses it, naming the row of a stack
_NONFINITE = [
    ("quat_to_dcm", "q", Q_RAND), ("quat_to_euler", "q", Q_RAND),
    ("quat_to_rotvec", "q", Q_RAND), ("quat_normalize", "q", Q_RAND),
    ("dcm_to_quat", "C", C_RAND), ("dcm_to_euler", "C", C_RAND),
    ("dcm_to_rotvec", "C", C_RAND), ("euler_to_dcm", "rpy", RPY_RAND),
    ("euler_to_quat", "rpy", RPY_RAND), ("rotvec_to_quat", "rv", RV_RAND),
    ("rotvec_to_dcm", "rv", RV_RAND),
]


@pytest.mark.parametrize("func, name, good", _NONFINITE)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nonfinite_input_is_refused(func, name, good, bad):
    f = getattr(rot, func)
    one = np.array(good[0])
    one.flat[1] = bad
    with pytest.raises(ValueError, match=rf"^{name} must (be finite|have finite elements), "
                                         r"got \[") as exc:
        f(one)
    assert "row" not in str(exc.value)
    stack = np.array(good[:6])
    stack[3].flat[0] = bad
    stack[5].flat[-1] = bad
    with pytest.raises(ValueError, match=rf"^{name} must .*finite.*\(row 3 of 6; 2 such\)"):
        f(stack)


def test_nan_quaternion_never_becomes_a_rotation():
    """The exact red flag: [nan, 0, 0, 1] has a NaN norm, which is not == 0."""
    q = np.array([np.nan, 0.0, 0.0, 1.0])
    assert not np.linalg.norm(q) == 0                     # why the old test let it pass
    for f in (rot.quat_to_dcm, rot.quat_normalize, rot.quat_to_euler, rot.quat_to_rotvec,
              lambda q: rot.quat_rotate(q, [1.0, 0.0, 0.0])):
        with pytest.raises(ValueError, match="finite"):
            f(q)
    with pytest.raises(ValueError, match=r"v must be finite"):
        rot.quat_rotate(Q_RAND[0], [0.0, np.nan, 0.0])
    with pytest.raises(ValueError, match=r"q must have nonzero norm, got \[0\., 0\., 0\., 0\.\] "
                                          r"\(row 1 of 2; 1 such\)"):
        rot.quat_normalize(np.array([[0, 0, 0, 1.0], [0, 0, 0, 0]]))


def test_quat_to_dcm_one_is_the_numpy_form_to_the_bit():
    """The filter's fast path (four floats, no checks) sums the norm in numpy's order:
    the same matrix, bit for bit, as the vectorized arithmetic it replaced, for unit and
    unnormalized quaternions; and the rotation scipy gives."""
    rng = np.random.default_rng(7)
    Q = rng.normal(size=(20000, 4))
    Q[:10000] /= np.linalg.norm(Q[:10000], axis=1)[:, None]
    Q[10000:] *= rng.uniform(1e-3, 1e3, size=(10000, 1))
    for a in Q:
        x, y, z, w = a / np.sqrt(np.add.reduce(a * a))
        ref = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        assert_array_equal(rot.quat_to_dcm_one(*a.tolist()), ref)
    assert_allclose(rot.quat_to_dcm_one(*Q[3].tolist()), Rotation.from_quat(Q[3]).as_matrix(),
                    atol=1e-15)
