"""INS assessment: the noise and boresight estimates against a simulated block whose
injected INS noise and boresight are known."""
import numpy as np
import pytest
import scenario as sc

from photogrammetry.adjustment.assessment import assess
from photogrammetry.adjustment.block import adjust_block
from photogrammetry.adjustment import reml
from photogrammetry.adjustment.reml import BandedV, DenseV
from photogrammetry.adjustment.report import report_text


@pytest.fixture(scope="module")
def block50():
    return sc.make_block(n_strips=5, n_per_strip=10, seed=31,
                         boresight_rad=(0.004, -0.006, 0.008))


def _run(B, method, datum):
    res = adjust_block(B["prior"], B["pairs"], B["pair_points"], B["f_mm"], B["system"],
                       method, datum, positions=B["positions"], sigma_mm=B["sigma_mm"],
                       point_ids=B["point_ids"])
    return res, assess(res, B["prior"], B["system"], datum, method)


def test_noise_and_boresight_from_a_50_image_block(block50):
    B = block50
    res, a = _run(B, "known-base", "none")
    assert a.boresight_observable and a.used.sum() == 50
    realized = B["ins_noise"].std(axis=0, ddof=1)          # the injected noise, this draw
    np.testing.assert_allclose(a.ins_noise, realized, rtol=0.10)
    assert np.all(np.abs(a.ins_noise - 0.005) < 0.10 * 0.005 + 3 * 0.005 / np.sqrt(100))
    assert np.all(np.abs(a.boresight - B["boresight"]) < 2 * a.boresight_sigma)
    np.testing.assert_allclose(a.boresight_sigma, 0.005 / np.sqrt(50), rtol=0.2)
    # the adjustment's own sigma is far below the INS noise; the RMS contains the boresight
    assert np.all(a.adj_sigma_rms < 0.05 * a.ins_noise)
    assert np.all(a.rms > a.residual_rms)
    # correlations of each image's angles are proper correlations
    c = a.correlations
    assert np.allclose(np.einsum("mii->mi", c), 1) and np.all(np.abs(c) <= 1 + 1e-12)


def test_datum_first_hides_the_boresight_but_not_the_noise(block50):
    B = block50
    res, a = _run(B, "base-free", "first")
    assert not a.boresight_observable and np.all(a.boresight == 0)
    assert not a.used[0] and a.used[1:].all()
    realized = B["ins_noise"][1:].std(axis=0, ddof=1)
    np.testing.assert_allclose(a.ins_noise, realized, rtol=0.2)
    text = report_text(type("R", (), {"settings": {"method": "base-free", "datum": "first",
                                                   "system": B["system"], "sigma_mm": 0.005,
                                                   "pixel_size_mm": 0.01, "n_images": 50,
                                                   "n_pairs": len(B["pairs"]),
                                                   "n_observations": 0},
                                      "block": res, "assessment": a, "pairs": B["pairs"],
                                      "eo": type("E", (), {"frame": "enu",
                                                           "image_id": [str(i) for i in range(50)],
                                                           "angles": res.angles})()})())
    assert "not observable" in text and "nan" not in text.lower()


def _z_and_noise(seeds, ins_sigma, position_sigma=0.0):
    z, noise = [], []
    for seed in seeds:
        B = sc.make_block(3, 8, seed=seed, ins_sigma_rad=ins_sigma, points_per_image=40)
        pos = B["positions"] + np.random.default_rng(seed).normal(0, position_sigma,
                                                                   B["positions"].shape)
        res = adjust_block(B["prior"], B["pairs"], B["pair_points"], B["f_mm"], B["system"],
                           "known-base", "none", positions=pos, sigma_mm=B["sigma_mm"],
                           position_sigma=position_sigma or None, point_ids=B["point_ids"])
        a = assess(res, B["prior"], B["system"], "none", "known-base")
        z.append((a.boresight - B["boresight"]) / a.boresight_sigma)
        noise.append(a)
    return np.array(z), noise


def test_boresight_coverage_with_correlated_adjustment_errors():
    """INS noise (4 arcsec) below the adjustment's own per-image sigma (~10-15 arcsec,
    strongly correlated along the strips): the GLS sigmas must still cover the errors."""
    from scipy.stats import chi2
    z, runs = _z_and_noise(range(100, 124), 2e-5)
    n = z.size                                                  # 72 normalized errors
    lo, hi = chi2.ppf([0.0005, 0.9995], n) / n
    assert lo < np.mean(z ** 2) < hi, np.mean(z ** 2)
    # unbiased (the linear fit had -0.8 and -1.0 sigma in rx, ry here: second order of a
    # 0.2 deg boresight; iterated on the exact model it is gone)
    assert np.all(np.abs(z.mean(axis=0)) < 3.3 / np.sqrt(len(z))), z.mean(axis=0)
    noise = np.array([a.ins_noise for a in runs])
    negative = np.array([a.ins_noise_negative for a in runs])
    # with the noise below the adjustment's sigma some components come out negative:
    # reported as NaN and flagged (they used to read as a noise of 0)
    assert negative.any() and np.all(np.isnan(noise[negative]))
    assert np.all(noise[~negative] > 0)
    assert np.all(np.array([a.ins_noise_var for a in runs])[negative] < 0)
    # the constrained estimate (0 where negative) as before, and the signed variances,
    # which average to the true variance
    assert abs(np.mean(np.where(negative, 0.0, noise)) / 2e-5 - 1) < 0.15
    var = np.array([a.ins_noise_var for a in runs])
    assert abs(np.mean(var) / 2e-5 ** 2 - 1) < 0.25, np.mean(var) / 2e-5 ** 2


def test_position_sigma_is_propagated_into_the_boresight_sigma():
    """Bases from noisy positions (3 cm over ~320 m, about 27 arcsec of direction): with
    the position sigma given, the angles' covariance matches their errors."""
    z, _ = _z_and_noise(range(300, 306), 5e-5, position_sigma=0.03)
    assert np.mean(z ** 2) < 3.0
    B = sc.make_block(3, 8, seed=301, ins_sigma_rad=5e-5, points_per_image=40)
    pos = B["positions"] + np.random.default_rng(1).normal(0, 0.03, B["positions"].shape)
    chi = []
    for ps in (None, 0.03):
        res = adjust_block(B["prior"], B["pairs"], B["pair_points"], B["f_mm"], B["system"],
                           "known-base", "none", positions=pos, sigma_mm=B["sigma_mm"],
                           position_sigma=ps, point_ids=B["point_ids"])
        e = ((res.angles - B["angles"] + np.pi) % (2 * np.pi) - np.pi).ravel()
        chi.append(e @ np.linalg.solve(res.cov, e) / e.size)
    assert chi[0] > 2.5 and 0.6 < chi[1] < 1.4, chi


@pytest.mark.parametrize("system", ["phi-omega-kappa", "omega-phi-kappa"])
def test_assessment_regressors_against_differences(system):
    """The assessment's regressors: d angles / d (camera-frame rotation) = M^-1 R (the
    boresight) and d angles / d (model-frame rotation) = M^-1 (the datum), against
    central differences of the angles of R exp([e]) and exp([e]) R (issue 12)."""
    from ins.nav.rotation import rotvec_to_dcm
    from photogrammetry.adjustment import _coplanarity_kernels as K
    from photogrammetry.orientation.rotation import angles_to_matrix, matrix_to_angles
    a = np.random.default_rng(27).uniform(-0.6, 0.6, (4, 3))
    R, M = K.rotation_and_axes(a, system)
    J_cam, J_model = np.linalg.solve(M, R), np.linalg.inv(M)
    R0 = angles_to_matrix(a, system)
    h = 1e-6
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        for J, fwd, bwd in ((J_cam, R0 @ rotvec_to_dcm(e), R0 @ rotvec_to_dcm(-e)),
                            (J_model, rotvec_to_dcm(e) @ R0, rotvec_to_dcm(-e) @ R0)):
            fd = (matrix_to_angles(fwd, system) - matrix_to_angles(bwd, system)) / (2 * h)
            err = np.abs(J[:, :, k] - fd)
            assert np.all(err <= 1e-7 * (np.abs(fd) + 1e-3 * np.abs(fd).max())), err.max()


def test_large_boresight_recovered_without_second_order_bias():
    """A 0.6-1.1 deg boresight on an almost noise-free block: the iterated fit recovers
    it to its sigma; the first-order (one-step) fit was off by several sigma."""
    B = sc.make_block(3, 8, seed=105, ins_sigma_rad=2e-6, points_per_image=40,
                      boresight_rad=(0.01, -0.015, 0.02))
    res, a = _run(B, "known-base", "none")
    z = (a.boresight - B["boresight"]) / a.boresight_sigma
    assert np.all(np.abs(z) < 4), z
    assert a.boresight_iterations >= 2


def test_bordered_assessment_operator_against_the_dense_covariance():
    """``V = lambda C + D`` of a base-free block's bordered operator (angles and bases
    factored together): ``V^-1 v`` and ``V v`` against the dense covariance's ``V``, in
    the Woodbury form, the quasi-definite augmented form (INS noise held at 0) and for
    lambda = 0."""
    B = sc.make_block(n_strips=3, n_per_strip=10, seed=71)
    kw = dict(positions=B["positions"], sigma_mm=B["sigma_mm"], point_ids=B["point_ids"])
    args = (B["prior"], B["pairs"], B["pair_points"], B["f_mm"], B["system"], "base-free",
            "first")
    d = adjust_block(*args, algebra="dense", **kw)
    b = adjust_block(*args, algebra="banded", **kw)
    fr = np.repeat(b.cov_op.free, 3)
    C = d.cov[np.ix_(fr, fr)]
    n = len(C)
    rng = np.random.default_rng(1)
    v = rng.normal(size=(n, 2))
    cases = [(1.3, np.full(n, 1e-5), True), (2.0, rng.uniform(1e-7, 1e-5, n), True),
             (0.7, np.full(n, 1e-15), False), (0.0, np.full(n, 1e-9), False)]
    for lam, dd, woodbury in cases:
        V = lam * C + np.diag(dd)
        Vs = BandedV(b.cov_op, lam, dd)
        assert bool(Vs.woodbury) == woodbury
        x = Vs.solve(v)
        if woodbury or lam == 0:
            np.testing.assert_allclose(x, np.linalg.solve(V, v), rtol=0,
                                       atol=1e-9 * np.abs(x).max())
        else:        # V's condition number ~1e9 here: its backward error
            assert np.abs(V @ x - v).max() < 1e-6 * np.abs(v).max()
        np.testing.assert_allclose(Vs.dot(v), V @ v, rtol=0, atol=1e-10 * np.abs(V @ v).max())


def test_dense_covariance_of_a_bordered_block_against_the_dense_algebra():
    """The bordered operator's dense ``C`` (the Schur complement of the bases by the
    sparse half solve, inverted) against the dense algebra's covariance (the reduced
    normal matrix formed and inverted on its own), and :class:`DenseV` against numpy's
    solve with that covariance, a component at its bound included."""
    B = sc.make_block(n_strips=3, n_per_strip=10, seed=71)
    kw = dict(positions=B["positions"], sigma_mm=B["sigma_mm"], point_ids=B["point_ids"])
    args = (B["prior"], B["pairs"], B["pair_points"], B["f_mm"], B["system"], "base-free",
            "first")
    d = adjust_block(*args, algebra="dense", **kw)
    b = adjust_block(*args, algebra="banded", **kw)
    fr = np.repeat(b.cov_op.free, 3)
    C = d.cov[np.ix_(fr, fr)]
    Cb = b.cov_op.dense()
    np.testing.assert_allclose(Cb, C, rtol=0, atol=1e-9 * np.abs(C).max())
    np.testing.assert_array_equal(Cb, Cb.T)
    rng = np.random.default_rng(2)
    v = rng.normal(size=(len(C), 2))
    for lam, dd in [(1.3, rng.uniform(1e-7, 1e-5, len(C))), (0.7, np.full(len(C), 1e-15))]:
        V = lam * C + np.diag(dd)
        Vs = DenseV(b.cov_op, Cb, lam, dd)
        x = Vs.solve(v)
        assert np.abs(V @ x - v).max() < 1e-6 * np.abs(v).max()
        np.testing.assert_allclose(Vs.dot(v), V @ v, rtol=0, atol=1e-9 * np.abs(V @ v).max())


def test_dense_and_sparse_assessment_of_a_bordered_block_agree(monkeypatch):
    """The REML of a base-free block on the dense ``C`` (:class:`DenseV`, up to
    ``DENSE_V_MAX_ANGLES``) and on the sparse augmented system (:class:`BandedV`): the
    same iterations and estimates to the solves' rounding (the same Hutchinson probes)."""
    B = sc.make_block(n_strips=4, n_per_strip=10, seed=72)
    res = adjust_block(B["prior"], B["pairs"], B["pair_points"], B["f_mm"], B["system"],
                       "base-free", "first", positions=B["positions"],
                       sigma_mm=B["sigma_mm"], point_ids=B["point_ids"], algebra="banded")
    made = []
    monkeypatch.setattr(reml, "DenseV", lambda *a: made.append(1) or DenseV(*a))
    dense = assess(res, B["prior"], B["system"], "first", "base-free")
    assert made
    monkeypatch.setattr(reml, "DENSE_V_MAX_ANGLES", 0)
    n_made = len(made)
    sparse_ = assess(res, B["prior"], B["system"], "first", "base-free")
    assert len(made) == n_made                      # the sparse path only
    assert dense.boresight_iterations == sparse_.boresight_iterations
    np.testing.assert_array_equal(dense.ins_noise_negative, sparse_.ins_noise_negative)
    for name in ("ins_noise_var", "ins_noise_sigma", "gls_mean", "gls_mean_sigma",
                 "mean_sigma", "residual_rms"):
        np.testing.assert_allclose(getattr(dense, name), getattr(sparse_, name),
                                   rtol=1e-7, err_msg=name)
    assert abs(dense.chi2 - sparse_.chi2) < 1e-7 * sparse_.chi2
    assert abs(dense.cov_factor - sparse_.cov_factor) < 1e-8


@pytest.mark.parametrize("method,datum,ins_sigma", [("base-free", "first", 0.005),
                                                    ("relative", "ins", 0.005),
                                                    ("relative", "ins", 1e-6)])
def test_bordered_banded_assessment_agrees_with_dense(method, datum, ins_sigma):
    """The assessment of a relative/base-free block on the bordered covariance operator
    against the dense REML: INS noise within 0.1 of its sigma (measured 0.04), the same
    negative-variance flags, means and correlations exact; a noise below the adjustment's
    sigma (1e-6 rad): lambda estimated within 1.5 of its sigma (measured 1.18 against
    1.64 +- 0.44: the Hutchinson traces decide there)."""
    B = sc.make_block(n_strips=3, n_per_strip=10, seed=71, ins_sigma_rad=ins_sigma)
    out = []
    for algebra in ("dense", "banded"):
        res = adjust_block(B["prior"], B["pairs"], B["pair_points"], B["f_mm"],
                           B["system"], method, datum, positions=B["positions"],
                           sigma_mm=B["sigma_mm"], point_ids=B["point_ids"],
                           algebra=algebra)
        out.append(assess(res, B["prior"], B["system"], datum, method))
    d, b = out
    np.testing.assert_array_equal(b.ins_noise_negative, d.ins_noise_negative)
    ok = ~d.ins_noise_negative
    assert np.all(np.abs(b.ins_noise[ok] - d.ins_noise[ok]) < 0.1 * d.ins_noise_sigma[ok])
    np.testing.assert_allclose(b.mean, d.mean, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(b.correlations, d.correlations, atol=1e-8)
    if ins_sigma > 1e-4:
        np.testing.assert_allclose(b.mean_sigma, d.mean_sigma, rtol=0.02)
        assert b.cov_factor == d.cov_factor == 1.0
    else:
        assert d.ins_noise_negative.all()
        assert abs(b.cov_factor - d.cov_factor) < 1.5 * d.cov_factor_sigma


@pytest.mark.parametrize("ins_sigma,position_sigma", [(0.005, None), (0.005, 0.05),
                                                       (1e-6, None)])
def test_banded_assessment_agrees_with_dense(ins_sigma, position_sigma):
    """The assessment on the banded covariance operator (REML with Hutchinson traces,
    64 probes) against the dense REML: boresight within 0.05 of its sigma (measured
    0.0001 when the INS noise dominates, 0.012 when it is below the adjustment's), INS noise
    within 0.1 of its sigma (measured 0.013; 0.25 and 0.12 when the noise is below the
    adjustment's sigma), the same flags of a noise below
    the adjustment's sigma (1e-6 rad: not estimable), the means and correlations exact."""
    B = sc.make_block(n_strips=3, n_per_strip=10, seed=71, ins_sigma_rad=ins_sigma)
    out = []
    for algebra in ("dense", "banded"):
        res = adjust_block(B["prior"], B["pairs"], B["pair_points"], B["f_mm"],
                           B["system"], "known-base", "none", positions=B["positions"],
                           sigma_mm=B["sigma_mm"], point_ids=B["point_ids"],
                           position_sigma=position_sigma, algebra=algebra)
        out.append(assess(res, B["prior"], B["system"], "none", "known-base"))
    d, b = out
    assert np.all(np.abs(b.boresight - d.boresight) < 0.05 * d.boresight_sigma)
    # (its sigma within 10 %: measured 0.1 % with the INS noise dominant, 5 % below)
    np.testing.assert_allclose(b.boresight_sigma, d.boresight_sigma, rtol=0.1)
    np.testing.assert_array_equal(b.ins_noise_negative, d.ins_noise_negative)
    ok = ~d.ins_noise_negative
    # the Hutchinson error of the traces: 0.013 sigma with the INS noise dominant, 0.12
    # sigma when it is below the adjustment's own (the traces then decide more)
    tol = 0.1 if ins_sigma > 1e-4 else 0.25
    assert np.all(np.abs(b.ins_noise[ok] - d.ins_noise[ok]) < tol * d.ins_noise_sigma[ok])
    np.testing.assert_allclose(b.mean, d.mean, rtol=1e-9)
    np.testing.assert_allclose(b.correlations, d.correlations, atol=1e-8)
    if ins_sigma > 1e-4:
        np.testing.assert_allclose(b.mean_sigma, d.mean_sigma, rtol=0.02)
        assert b.cov_factor == d.cov_factor == 1.0          # held: the noise dominates
    else:      # lambda estimated: 0.72 +- 0.20 against the dense 0.82 +- 0.23 here
        assert abs(b.cov_factor - d.cov_factor) < 0.5 * d.cov_factor_sigma
        np.testing.assert_allclose(b.mean_sigma, d.mean_sigma, rtol=0.1)
    if ins_sigma < 1e-5:
        assert d.ins_noise_negative.any()
