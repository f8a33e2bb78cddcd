"""Pair adjustment on the coplanarity condition: derivatives, exactness, bias of the
paper's form, Cramer-Rao efficiency, outliers and degenerate input."""
import numpy as np
import pytest
import scenario as sc
from scipy.spatial.transform import Rotation

from ins.common.errors import InputError
from ins.nav.rotation import skew
from photogrammetry.adjustment import _coplanarity_kernels as K
from photogrammetry.adjustment.coplanarity import (
    _paper_terms,
    adjust_pair,
    adjust_pairs,
    pencil_determinants,
)
from photogrammetry.adjustment.quality import sigma0_limit
from photogrammetry.orientation.rotation import angles_to_matrix

ARCSEC = np.pi / 180 / 3600


def _run(p, method, **kw):
    return adjust_pairs(p["u1"][..., :2], p["u2"][..., :2], p["f_mm"], p["ang1"], p["prior2"],
                        p["system"], method, base=p["C2"] - p["C1"], sigma_mm=p["sigma_mm"],
                        **kw)


def _err(p, out):
    return sc.rotation_error(angles_to_matrix(out["angles"], p["system"]), p["R2"])


@pytest.mark.parametrize("system,seq,sign", [("phi-omega-kappa", "YXZ", [-1, 1, 1]),
                                              ("omega-phi-kappa", "XYZ", [1, 1, 1])])
def test_rotation_and_axes_against_scipy_and_differences(system, seq, sign):
    a = np.random.default_rng(1).uniform(-0.5, 0.5, (5, 3))
    R, M = K.rotation_and_axes(a, system)
    # phi-omega-kappa = Ry(-phi) Rx(omega) Rz(kappa) = scipy's 'YXZ' of (-phi, omega, kappa)
    np.testing.assert_allclose(R, Rotation.from_euler(seq, a * sign).as_matrix(), atol=1e-14)
    np.testing.assert_allclose(R, angles_to_matrix(a, system), atol=1e-15)
    for k in range(3):
        d = np.zeros(3)
        d[k] = 1e-6
        dR = (K.rotation_and_axes(a + d, system)[0] - K.rotation_and_axes(a - d, system)[0]) / 2e-6
        np.testing.assert_allclose(dR, skew(M[:, :, k]) @ R, atol=1e-9)


def test_condition_derivatives_against_differences():
    rng = np.random.default_rng(2)
    R = Rotation.random(2, random_state=3).as_matrix()
    R1, R2 = R[:1], R[1:]
    u1, u2 = rng.normal(size=(1, 4, 3)), rng.normal(size=(1, 4, 3))
    b = rng.normal(size=(1, 3))

    def g_of(th2=np.zeros(3), bb=b, th1=np.zeros(3)):
        Ra = Rotation.from_rotvec(th1).as_matrix() @ R1[0]
        Rb = Rotation.from_rotvec(th2).as_matrix() @ R2[0]
        return K.condition_terms(u1 @ Ra.T, u2 @ Rb.T, bb, Ra[None], Rb[None], 1.0)[0][0]

    r1, r2 = u1 @ R1[0].T, u2 @ R2[0].T
    g, var, N, A = K.condition_terms(r1, r2, b, R1, R2, 0.3)
    h = 1e-6
    for k in range(3):
        e = np.eye(3)[k] * h
        np.testing.assert_allclose((g_of(th2=e) - g_of(th2=-e)) / 2 / h, A[0, :, k], rtol=1e-6)
        np.testing.assert_allclose((g_of(bb=b + e) - g_of(bb=b - e)) / 2 / h, N[0, :, k], rtol=1e-6)
        A1 = np.cross(r1, np.cross(r2, b[:, None]))          # the block's dg/dtheta1
        np.testing.assert_allclose((g_of(th1=e) - g_of(th1=-e)) / 2 / h, A1[0, :, k], rtol=1e-6)
    # variance: propagated from the 4 photo coordinates by differences
    J = np.zeros((4, 4))
    for k in range(2):
        e = np.zeros(3)
        e[k] = h
        J[:, k] = (np.cross((u1 + e) @ R1[0].T, r2)[0] @ b[0]
                   - np.cross((u1 - e) @ R1[0].T, r2)[0] @ b[0]) / 2 / h
        J[:, 2 + k] = (np.cross(r1, (u2 + e) @ R2[0].T)[0] @ b[0]
                       - np.cross(r1, (u2 - e) @ R2[0].T)[0] @ b[0]) / 2 / h
    np.testing.assert_allclose(var[0], 0.09 * np.sum(J ** 2, axis=1), rtol=1e-6)


def test_noise_free_pairs_exact_and_paper_biased():
    p = sc.make_pairs(20, 15, seed=5, noise_px=1e-9)
    errs = {}
    for method in ("known-base", "relative", "base-free", "paper"):
        out = _run(p, method, snooping=False)
        assert np.all(out["status"] == 0)
        errs[method] = np.sqrt(np.mean(_err(p, out) ** 2))
    for method in ("known-base", "relative", "base-free"):
        assert errs[method] < 1e-4 * ARCSEC
    assert errs["paper"] > 100 * ARCSEC       # erratum 1: biased even without noise
    # at the true orientation the pencil determinants vanish, the paper's F1, F2 do not
    r1 = np.einsum("pij,pnj->pni", p["R1"], p["u1"])
    r2 = np.einsum("pij,pnj->pni", p["R2"], p["u2"])
    triples = [[0, 1, k] for k in range(2, 15)]
    assert np.max(np.abs(pencil_determinants(r1[0], r2[0], triples))) < 1e-9
    F, _, _ = _paper_terms(r1, r2, p["mask"])
    N = np.linalg.norm(np.cross(r1, r2), axis=2)
    assert np.median(np.abs(F) / (N[:, 2:].repeat(2, axis=1) * N[:, :1])) > 1e-3


def test_paper_jacobian_against_differences():
    p = sc.make_pairs(2, 6, seed=8)
    r1 = np.einsum("pij,pnj->pni", p["R1"], p["u1"])
    r2 = np.einsum("pij,pnj->pni", p["R2"], p["u2"])
    _, dF, _ = _paper_terms(r1, r2, p["mask"])
    for k in range(3):
        e = np.zeros((2, 3))
        e[:, k] = 1e-7
        Rp, Rm = Rotation.from_rotvec(e).as_matrix(), Rotation.from_rotvec(-e).as_matrix()
        Fp = _paper_terms(r1, np.einsum("pij,pnj->pni", Rp, r2), p["mask"])[0]
        Fm = _paper_terms(r1, np.einsum("pij,pnj->pni", Rm, r2), p["mask"])[0]
        np.testing.assert_allclose((Fp - Fm) / 2e-7, dF[..., k], rtol=1e-5, atol=1e-3)


@pytest.mark.parametrize("method,known", [("known-base", True), ("relative", False),
                                          ("base-free", False)])
def test_reaches_the_cramer_rao_bound(method, known):
    p = sc.make_pairs(150, 20, seed=11)
    out = _run(p, method, snooping=False)
    assert np.all(out["status"] == 0)
    err = _err(p, out)
    rms = np.sqrt(np.mean(err ** 2))
    bound = np.sqrt(np.mean(np.trace(sc.crb_rotation(p, known), axis1=1, axis2=2)) / 3)
    assert 0.88 < rms / bound < 1.12
    assert np.all(np.abs(err.mean(axis=0)) < 3.5 * rms / np.sqrt(len(err)))   # unbiased
    # the adjustment's own covariance agrees with the bound and with the errors
    R2, M2 = K.rotation_and_axes(out["angles"], p["system"])
    cov_rot = M2 @ out["cov"] @ M2.transpose(0, 2, 1)
    assert 0.85 < np.sqrt(np.mean(np.trace(cov_rot, axis1=1, axis2=2)) / 3) / bound < 1.15
    s0 = np.sqrt(out["vtpv"].sum() / out["redundancy"].sum())
    assert abs(s0 - 1) < 0.05


def test_base_free_equals_relative_and_needs_no_base():
    p = sc.make_pairs(30, 12, seed=12)
    rel = _run(p, "relative", snooping=False)
    free = adjust_pairs(p["u1"][..., :2], p["u2"][..., :2], p["f_mm"], p["ang1"], p["prior2"],
                        p["system"], "base-free", sigma_mm=p["sigma_mm"], snooping=False)
    np.testing.assert_allclose(free["angles"], rel["angles"], atol=1e-10)
    np.testing.assert_allclose(free["cov"], rel["cov"], rtol=1e-6, atol=1e-18)
    b_true = (p["C2"] - p["C1"]) / np.linalg.norm(p["C2"] - p["C1"], axis=1)[:, None]
    assert np.all(np.abs(np.einsum("pi,pi->p", free["base"], b_true)) > 0.999)


def test_outlier_rejected_by_data_snooping():
    p = sc.make_pairs(40, 25, seed=13)
    u2 = p["u2"].copy()
    u2[:, 7, 1] += 0.05                                   # 5 px across the epipolar line
    q = dict(p, u2=u2)
    out = _run(q, "base-free")
    assert out["rejected"][:, 7].mean() > 0.9
    assert out["rejected"].sum() < 40 * 1.15
    clean = _run(p, "base-free", snooping=False)
    e_out, e_clean = np.sqrt(np.mean(_err(p, out) ** 2)), np.sqrt(np.mean(_err(p, clean) ** 2))
    assert e_out < 1.3 * e_clean


def test_single_pair_and_degenerate_input():
    p = sc.make_pairs(1, 12, seed=14, system="omega-phi-kappa")
    xy1, xy2 = p["u1"][0, :, :2], p["u2"][0, :, :2]
    res = adjust_pair(xy1, xy2, p["f_mm"], p["ang1"][0], p["prior2"][0], p["system"],
                      "known-base", base=p["C2"][0] - p["C1"][0], sigma_mm=p["sigma_mm"])
    assert res.status == "ok" and np.all(np.isfinite(res.sigma)) and res.redundancy >= 8
    err = sc.rotation_error(angles_to_matrix(res.angles, p["system"])[None], p["R2"])
    assert np.linalg.norm(err) < 6 * np.linalg.norm(res.sigma)
    with pytest.raises(InputError, match="at least 5"):
        adjust_pair(xy1[:4], xy2[:4], p["f_mm"], p["ang1"][0], p["prior2"][0], p["system"])
    with pytest.raises(InputError, match="zero base"):
        adjust_pair(xy1, xy2, p["f_mm"], p["ang1"][0], p["prior2"][0], p["system"],
                    "known-base", base=np.zeros(3))
    line = np.column_stack([np.linspace(-30, 30, 12), np.zeros(12)])   # collinear points
    with pytest.raises(InputError, match="singular"):
        adjust_pair(line, line + [0.1, 0], p["f_mm"], np.zeros(3), np.zeros(3), p["system"])
    # in a batch a bad pair gets a status and says it failed: its prior angles with a NaN
    # covariance (never 0, which would read as perfect) and the reason; the others are
    # solved and finite.  (This test used to require "nothing is NaN": the zero
    # covariance of the failed pair was the red flag of issue 12.)
    q = sc.make_pairs(3, 12, seed=15)
    xy2b = q["u2"][..., :2].copy()
    mask = np.ones((3, 12), bool)
    mask[1, 3:] = False
    out = adjust_pairs(q["u1"][..., :2], xy2b, q["f_mm"], q["ang1"], q["prior2"], q["system"],
                       mask=mask, sigma_mm=q["sigma_mm"])
    assert list(out["status"]) == [0, K.STATUS_TOO_FEW, 0]
    assert list(out["converged"]) == [True, False, True]
    assert list(out["failed"]) == [False, True, False]
    assert out["reason"][1] == "too few tie points" and out["reason"][0] == "ok"
    np.testing.assert_array_equal(out["angles"][1], q["prior2"][1])
    assert np.all(np.isnan(out["cov"][1])) and np.all(np.isnan(out["sigma"][1]))
    assert np.isnan(out["sigma0"][1]) and out["redundancy"][1] == 0
    good = [0, 2]
    for key in ("angles", "cov", "sigma", "sigma0", "base", "vtpv"):
        assert np.all(np.isfinite(out[key][good])), key
    assert np.all(out["sigma"][good] > 0) and np.all(out["sigma0_estimated"][good])


def test_zero_redundancy_flags_sigma0_and_not_converged_warns():
    """Three points, known base: 3 conditions for 3 angles.  No variance factor can be
    estimated: sigma0 is NaN, the covariance is the a-priori one (sigma0 = 1), marked,
    with a QualityWarning (it used to set s0^2 = 1 silently)."""
    from ins.common.errors import QualityWarning
    p = sc.make_pairs(1, 3, seed=17)
    args = (p["u1"][0, :, :2], p["u2"][0, :, :2], p["f_mm"], p["ang1"][0], p["prior2"][0],
            p["system"], "known-base")
    with pytest.warns(QualityWarning, match="no redundancy.*not estimable"):
        res = adjust_pair(*args, base=p["C2"][0] - p["C1"][0], sigma_mm=p["sigma_mm"])
    assert res.redundancy == 0 and np.isnan(res.sigma0) and not res.sigma0_estimated
    assert res.converged and res.status == "ok"
    # the covariance is Q itself: the inverse of the normal matrix of the 3 conditions
    R1 = angles_to_matrix(p["ang1"], p["system"])
    out = K.solve_pairs(p["u1"], p["u2"], p["mask"], R1, res.angles[None],
                        p["C2"] - p["C1"], "known", p["system"], p["sigma_mm"], max_iter=0,
                        engine="numpy")
    np.testing.assert_allclose(res.cov, out["Q"][0], rtol=1e-6)
    assert np.all(np.isfinite(res.sigma)) and np.all(res.sigma > 0)
    # one Gauss-Newton step only: not converged, said so by a flag and a warning
    q = sc.make_pairs(1, 12, seed=18)
    with pytest.warns(QualityWarning, match="did not converge"):
        res = adjust_pair(q["u1"][0, :, :2], q["u2"][0, :, :2], q["f_mm"], q["ang1"][0],
                          q["prior2"][0], q["system"], "base-free", sigma_mm=q["sigma_mm"],
                          max_iter=1)
    assert res.status == "not converged" and not res.converged


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_zero_photo_variance_refused_by_both_engines(engine):
    """A condition of zero variance used to weigh 1 in the numpy engine and 0 in the numba
    one; both refuse it, naming the pair and the point."""
    p = sc.make_pairs(2, 9, seed=19)
    args = [p["u1"], p["u2"], p["mask"], p["R1"], p["prior2"], p["C2"] - p["C1"], "known",
            p["system"]]
    with pytest.raises(InputError, match="sigma_xy.*> 0 mm"):
        K.solve_pairs(*args, sigma_xy=0.0, engine=engine)
    # a tie point on the base line (at the epipole of both images): g does not move with
    # its photo coordinates, its variance is exactly zero
    u1, u2, R1, prior2 = p["u1"].copy(), p["u2"].copy(), p["R1"].copy(), p["prior2"].copy()
    R1[1], prior2[1] = np.eye(3), 0.0            # two level cameras, one above the other
    u1[1, 4] = u2[1, 4] = [0.0, 0.0, -p["f_mm"]]  # the point straight below both
    base = p["C2"] - p["C1"]
    base[1] = [0.0, 0.0, -1.0]
    with pytest.raises(InputError, match="pair 1, tie point 4: .* variance 0.0"):
        K.solve_pairs(u1, u2, p["mask"], R1, prior2, base, "known", p["system"],
                      p["sigma_mm"], engine=engine)
    # a non-finite photo coordinate: refused the same way
    u2[0, 2, 0] = np.nan
    with pytest.raises(InputError, match="pair 0, tie point 2: .* variance nan"):
        K.solve_pairs(u1, u2, p["mask"], p["R1"], p["prior2"], p["C2"] - p["C1"], "known",
                      p["system"], p["sigma_mm"], engine=engine)


@pytest.mark.parametrize("mode", ["known", "relative", "free"])
def test_numba_kernel_equals_numpy_reference(mode):
    p = sc.make_pairs(12, 9, seed=16, system="omega-phi-kappa")
    p["mask"][2, 6:] = False
    args = (p["u1"], p["u2"], p["mask"], p["R1"], p["prior2"], p["C2"] - p["C1"], mode,
            p["system"], p["sigma_mm"])
    a, b = K.solve_pairs(*args, engine="numpy"), K.solve_pairs(*args, engine="numba")
    ok = a["status"] <= 1
    np.testing.assert_array_equal(a["status"], b["status"])
    np.testing.assert_allclose(b["angles"], a["angles"], atol=1e-12)
    np.testing.assert_allclose(b["Q"][ok], a["Q"][ok], rtol=1e-7, atol=1e-20)
    np.testing.assert_allclose(b["vtpv"][ok], a["vtpv"][ok], rtol=1e-7)
    m = p["mask"][ok]
    np.testing.assert_allclose(b["g"][ok] * m, a["g"][ok] * m, rtol=1e-7, atol=1e-14)


def _fd(f, x, h):
    """Central differences of f (array-valued) by every element of x: (f.shape + x.shape)."""
    x = np.asarray(x, dtype=float)
    f0 = np.asarray(f(x))
    out = np.empty(f0.shape + x.shape)
    for idx in np.ndindex(x.shape):
        e = np.zeros_like(x)
        e[idx] = h
        out[(...,) + idx] = (np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * h)
    return out


def _close(analytic, fd, rtol=1e-7):
    """Element-wise |analytic - fd| <= rtol (|fd| + 1e-3 max|fd|): a 5 % change of any
    term of any element fails."""
    scale = np.max(np.abs(fd))
    err = np.abs(analytic - fd)
    bad = err > rtol * (np.abs(fd) + 1e-3 * scale)
    assert not bad.any(), (np.argwhere(bad)[:5], (err / (np.abs(fd) + 1e-3 * scale)).max())


@pytest.mark.parametrize("engine", ["numpy", "numba"])
@pytest.mark.parametrize("system", ["phi-omega-kappa", "omega-phi-kappa"])
@pytest.mark.parametrize("mode", ["known", "relative", "free"])
def test_every_analytic_derivative_against_central_differences(engine, system, mode):
    """The solvers' Jacobian (by image 2's angles in the named system and by the two
    base-direction parameters) and the condition variances (from the derivatives by the
    four photo coordinates) against central differences of g = b . (R1 u1 x R2 u2) built
    from photogrammetry.orientation.rotation (itself checked against the textbooks' elements), to
    1e-7: a 5 % error in any derivative term fails (issue 12, mutation 'a 5 % error in a
    coplanarity derivative passes every Cramer-Rao band')."""
    rng = np.random.default_rng(23)
    P, n, f = 3, 7, 100.0
    R1 = Rotation.random(P, random_state=24).as_matrix()
    ang2 = rng.uniform(-0.6, 0.6, (P, 3))
    u1 = np.concatenate([rng.uniform(-40, 40, (P, n, 2)), np.full((P, n, 1), -f)], axis=2)
    u2 = np.concatenate([rng.uniform(-40, 40, (P, n, 2)), np.full((P, n, 1), -f)], axis=2)
    base = rng.normal(size=(P, 3)) * 300.0
    mask = np.ones((P, n), bool)
    s = 0.004
    out = K.solve_pairs(u1, u2, mask, R1, ang2, base, mode, system, s, max_iter=0,
                        engine=engine)
    b = out["base"] if mode != "known" else base / np.linalg.norm(base, axis=1)[:, None]
    if mode == "free":                     # the profiled base: a unit null-ish vector
        assert np.allclose(np.linalg.norm(b, axis=1), 1.0)
    np.testing.assert_array_equal(out["angles"], ang2)          # no step taken

    def g_of(a2, bb, uu1=u1, uu2=u2):
        r1 = np.einsum("pij,pnj->pni", R1, uu1)
        r2 = np.einsum("pij,pnj->pni", angles_to_matrix(a2, system), uu2)
        return np.einsum("pni,pi->pn", np.cross(r1, r2), bb)

    for p in range(P):
        g_p = g_of(ang2, b)[p]
        _close(out["g"][p], g_p, 1e-12)
        # by the angles of image 2 (system order)
        d_ang = _fd(lambda a: g_of(np.where(np.arange(P)[:, None] == p, a, ang2), b)[p],
                    ang2[p], 1e-6)
        _close(out["J"][p, :, :3], d_ang)
        if mode != "known":                # by the base direction's tangent parameters
            E = K.tangent_basis(b[p:p + 1])[0]

            def g_t(t):
                bb = b.copy()
                bb[p] = (b[p] + E @ t) / np.linalg.norm(b[p] + E @ t)
                return g_of(ang2, bb)[p]
            _close(out["J"][p, :, 3:], _fd(g_t, np.zeros(2), 1e-6))
        # the variance: sigma^2 times the squared derivatives by x1, y1, x2, y2
        d_xy = np.zeros((n, 4))
        for i in range(n):
            for c in range(4):
                def g_xy(v, i=i, c=c):
                    w1, w2 = u1.copy(), u2.copy()
                    (w1 if c < 2 else w2)[p, i, c % 2] = v[0]
                    return g_of(ang2, b, w1, w2)[p, i]
                x0 = (u1 if c < 2 else u2)[p, i, c % 2]
                d_xy[i, c] = _fd(g_xy, [x0], 1e-3)[0]
        _close(out["var"][p], s ** 2 * np.sum(d_xy ** 2, axis=1))
        # and the weights used are their inverses
        _close(out["w"][p], 1.0 / (s ** 2 * np.sum(d_xy ** 2, axis=1)))


@pytest.mark.parametrize("system", ["phi-omega-kappa", "omega-phi-kappa"])
def test_paper_jacobian_by_the_angles_against_differences(system):
    """The paper's F1/F2 by image 2's angles in the named system (dF . M), to 1e-7."""
    p = sc.make_pairs(2, 6, seed=8, system=system)
    r1 = np.einsum("pij,pnj->pni", p["R1"], p["u1"])
    a2 = p["prior2"]

    def F_of(a):
        r2 = np.einsum("pij,pnj->pni", angles_to_matrix(a, system), p["u2"])
        return _paper_terms(r1, r2, p["mask"])[0]
    R2, M2 = K.rotation_and_axes(a2, system)
    r2 = np.einsum("pij,pnj->pni", R2, p["u2"])
    J = np.einsum("pmi,pij->pmj", _paper_terms(r1, r2, p["mask"])[1], M2)
    for q in range(2):
        fd = _fd(lambda a: F_of(np.where(np.arange(2)[:, None] == q, a, a2))[q], a2[q], 1e-6)
        _close(J[q], fd, 1e-6)


def _with_outliers(p, fraction, seed):
    """Pairs whose image-2 observations are gross mismatches (10-100 px in a random
    direction) at `fraction` of the points; returns the pairs and the outlier mask."""
    rng = np.random.default_rng(seed)
    bad = rng.random(p["mask"].shape) < fraction
    size = rng.uniform(10, 100, bad.shape) * p["pixel_mm"]
    turn = rng.uniform(0, 2 * np.pi, bad.shape)
    u2 = p["u2"].copy()
    u2[..., 0] += bad * size * np.cos(turn)
    u2[..., 1] += bad * size * np.sin(turn)
    return dict(p, u2=u2), bad


@pytest.mark.parametrize("method", ["base-free", "known-base", "relative"])
def test_robust_start_does_not_depend_on_the_prior(method):
    """10-30 % gross outliers: from two priors drawn within the stated sigma (0.005 rad)
    and one 0.25 deg off in every angle, the rejected set is the same and the angles agree
    to 1e-8 rad; the errors against the truth are within the Cramer-Rao bound (chi-square
    of 3 angles below 25 for every pair, i.e. no pair captured by its outliers); the
    non-robust start (Gauss-Newton from the prior on all points, then snooping) is not."""
    p = sc.make_pairs(24, 60, seed=31)
    rng = np.random.default_rng(32)
    q, bad = _with_outliers(p, rng.uniform(0.1, 0.3, (24, 1)), 33)
    priors = [p["ang2"] + rng.normal(0, 0.005, (24, 3)) for _ in range(2)]
    priors.append(p["ang2"] + np.deg2rad(0.25) * rng.choice([-1.0, 1.0], (24, 3)))
    outs = [_run(dict(q, prior2=a), method) for a in priors]
    for out in outs[1:]:
        np.testing.assert_array_equal(out["rejected"], outs[0]["rejected"])
        np.testing.assert_allclose(out["angles"], outs[0]["angles"], atol=1e-8)
    # errors against the pair's own covariance (model frame: R = R_true exp(e)), which
    # is that of its inliers: within the Cramer-Rao bound of all 60 points / 0.65
    crb = sc.crb_rotation(p, method == "known-base")
    e = _err(p, outs[0])
    R, M = K.rotation_and_axes(outs[0]["angles"], p["system"])
    C = np.einsum("pij,pjk,plk->pil", M, outs[0]["cov"], M)
    chi2 = np.einsum("pi,pij,pj->p", e, np.linalg.inv(C), e)
    assert chi2.max() < 25 and np.mean(chi2) < 3 * 1.6
    ratio = np.sqrt(np.trace(C, axis1=1, axis2=2) / np.trace(crb, axis1=1, axis2=2))
    assert np.all(ratio < 1.3 / np.sqrt(0.65))
    assert np.all(outs[0]["sigma0"] < sigma0_limit(outs[0]["redundancy"]))   # none flagged
    # outliers along the epipolar line are invisible to coplanarity: a few stay
    assert (bad & ~outs[0]["rejected"]).sum() < 0.1 * bad.sum()
    assert (~bad & outs[0]["rejected"]).sum() < 0.02 * (~bad).sum()
    plain = _run(dict(q, prior2=priors[0]), method, robust=False)
    e_plain = _err(p, plain)
    chi2_plain = np.einsum("pi,pij,pj->p", e_plain, np.linalg.inv(crb), e_plain)
    assert chi2_plain.max() > 25                # a pair captured by its outliers


def test_robust_single_pair_per_call_keeps_its_result():
    """adjust_pair with the robust start gives the batch's result for its pair, and
    its rejected indices are the robust start's outliers plus snooping's."""
    p = sc.make_pairs(3, 40, seed=35)
    q, bad = _with_outliers(p, 0.2, 36)
    batch = _run(q, "base-free")
    for k in range(3):
        one = adjust_pair(q["u1"][k, :, :2], q["u2"][k, :, :2], q["f_mm"], q["ang1"][k],
                          q["prior2"][k], q["system"], sigma_mm=q["sigma_mm"])
        np.testing.assert_allclose(one.angles, batch["angles"][k], atol=1e-12)
        np.testing.assert_array_equal(one.rejected, np.flatnonzero(batch["rejected"][k]))
        assert set(np.flatnonzero(bad[k] & batch["robust_rejected"][k])) <= set(one.rejected)
