"""Block adjustment of the angles: datums, consistency with the truth and the covariance,
agreement with the pair adjustment, degenerate blocks."""
import warnings

import numpy as np
import pytest
import scenario as sc

from ins.common.errors import InputError
from photogrammetry.adjustment._coplanarity_kernels import rotation_and_axes
from photogrammetry.adjustment.block import adjust_block
from photogrammetry.adjustment.coplanarity import adjust_pairs
from photogrammetry.orientation.rotation import angles_to_matrix


@pytest.fixture(scope="module")
def block():
    return sc.make_block(n_strips=3, n_per_strip=8, seed=21)


def _run(B, method, datum, **kw):
    kw.setdefault("point_ids", B["point_ids"])
    return adjust_block(B["prior"], B["pairs"], B["pair_points"], B["f_mm"], B["system"],
                        method, datum, positions=B["positions"], sigma_mm=B["sigma_mm"], **kw)


def _chi2_per_angle(B, res):
    """Chi-square per angle of the true angle errors against the full covariance."""
    e = ((res.angles - B["angles"] + np.pi) % (2 * np.pi) - np.pi).ravel()
    k = np.diag(res.cov) > 0
    return e[k] @ np.linalg.solve(res.cov[np.ix_(k, k)], e[k]) / k.sum(), k.sum()


def _errors(B, res, align=False):
    Ra = angles_to_matrix(res.angles, B["system"])
    Rt = angles_to_matrix(B["angles"], B["system"])
    if align:                      # remove the datum's common rotation (first image)
        Ra = (Rt[0] @ Ra[0].T) @ Ra
    return sc.rotation_error(Ra, Rt)


def test_known_base_block_is_absolute_and_consistent(block):
    res = _run(block, "known-base", "none")
    assert res.converged and abs(res.sigma0 - 1) < 0.06
    err = _errors(block, res)
    R, M = rotation_and_axes(res.angles, block["system"])
    # chi-square of the rotation errors with the full per-image covariance
    chi2 = []
    for i in range(len(err)):
        C = M[i] @ res.cov[3 * i:3 * i + 3, 3 * i:3 * i + 3] @ M[i].T
        chi2.append(err[i] @ np.linalg.solve(C, err[i]))
    assert 0.6 < np.mean(chi2) / 3 < 1.5
    prior_err = sc.rotation_error(angles_to_matrix(block["prior"], block["system"]),
                                  angles_to_matrix(block["angles"], block["system"]))
    assert np.sqrt(np.mean(err ** 2)) < 0.02 * np.sqrt(np.mean(prior_err ** 2))


@pytest.mark.parametrize("method", ["relative", "base-free"])
def test_datum_first_keeps_first_image_and_gets_relative_angles(block, method):
    res = _run(block, method, "first")
    np.testing.assert_array_equal(res.angles[0], block["prior"][0])
    assert np.all(res.sigma[0] == 0) and np.all(res.sigma[1:] > 0)
    err = _errors(block, res, align=True)
    rms = np.sqrt(np.mean(err[1:] ** 2))
    assert rms < 2.0 * np.sqrt(np.mean(res.sigma[1:] ** 2))
    assert rms < 300 / 206265                          # far below the INS noise (1031")


def test_datum_ins_and_equal_methods(block):
    rel = _run(block, "relative", "ins")
    free = _run(block, "base-free", "ins")
    np.testing.assert_allclose(free.angles, rel.angles, atol=1e-9)
    np.testing.assert_allclose(free.cov, rel.cov, rtol=1e-5, atol=1e-16)
    assert np.all(free.sigma > 0)


def test_two_image_block_equals_pair_adjustment():
    p = sc.make_pairs(1, 30, seed=22)
    pts = [(p["u1"][0, :, :2], p["u2"][0, :, :2])]
    for method in ("known-base", "base-free"):
        res = adjust_block(np.vstack([p["ang1"], p["prior2"]]), [[0, 1]], pts, p["f_mm"],
                           p["system"], method, "first",
                           positions=np.vstack([p["C1"], p["C2"]]), sigma_mm=p["sigma_mm"])
        pair = adjust_pairs(pts[0][0][None], pts[0][1][None], p["f_mm"], p["ang1"], p["prior2"],
                            p["system"], method, base=p["C2"] - p["C1"], sigma_mm=p["sigma_mm"])
        np.testing.assert_allclose(res.angles[1], pair["angles"][0], atol=1e-10)
        # the block's covariance is linearized at its last-but-one iterate when the next
        # step is predicted below tol: equal to 1e-6 of the covariance's scale
        np.testing.assert_allclose(res.cov[3:, 3:], pair["cov"][0], rtol=1e-6,
                                   atol=1e-6 * np.abs(pair["cov"][0]).max())


def test_image_without_tie_points_and_disconnected_block(block):
    B = dict(block)
    keep = [k for k, (i, j) in enumerate(B["pairs"]) if 5 not in (i, j)]
    B["pairs"] = B["pairs"][keep]
    B["pair_points"] = [B["pair_points"][k] for k in keep]
    B["point_ids"] = [B["point_ids"][k] for k in keep]
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        res = _run(B, "base-free", "first")
    assert any("image 5 has no usable pair" in str(x.message) for x in w)
    np.testing.assert_array_equal(res.angles[5], B["prior"][5])
    assert np.all(np.isfinite(res.cov)) and res.sigma[5, 0] == pytest.approx(0.005)
    # two separate pieces: with datum "first" the second piece has no datum
    cut = [k for k, (i, j) in enumerate(block["pairs"]) if (i < 8) == (j < 8)]
    C = dict(block, pairs=block["pairs"][cut], pair_points=[block["pair_points"][k] for k in cut],
             point_ids=[block["point_ids"][k] for k in cut])
    with pytest.raises(InputError, match="singular"):
        _run(C, "base-free", "first")
    assert np.all(np.isfinite(_run(C, "base-free", "ins").angles))
    with pytest.raises(InputError, match="known-base"):
        _run(block, "base-free", "none")


def test_joint_weights_of_points_in_three_or_more_images():
    """Points seen in 3+ images: the conditions of one point weighted jointly (pseudo-
    inverse of their covariance from the shared photo coordinates) make the covariance
    match the true errors (chi-square per angle ~ 1); weighted one by one the covariance
    is optimistic (about 1.2x in sigma; chi2 ~ 1.4 on larger blocks)."""
    from scipy.stats import chi2
    chi_joint, n, ratio = 0.0, 0, []
    for seed in (40, 41):
        B = sc.make_block(n_strips=3, n_per_strip=10, seed=seed)
        B["prior"][0] = B["angles"][0]                 # the datum image at its true angles
        for method, datum in (("known-base", "none"), ("relative", "first")):
            joint, single = _run(B, method, datum), _run(B, method, datum, point_ids=None)
            c, k = _chi2_per_angle(B, joint)
            chi_joint += c * k
            n += k
            assert abs(joint.sigma0 - 1) < 0.05 and joint.redundancy < single.redundancy
            ratio.append(np.sqrt(np.trace(joint.cov) / np.trace(single.cov)))
    lo, hi = chi2.ppf([0.001, 0.999], n) / n
    assert lo < chi_joint / n < hi, chi_joint / n
    assert 1.05 < np.mean(ratio) < 1.4, ratio


def _fd(f, x, h):
    """Central differences of f (array-valued) by every element of x."""
    x = np.asarray(x, dtype=float)
    f0 = np.asarray(f(x))
    out = np.empty(f0.shape + x.shape)
    for idx in np.ndindex(x.shape):
        e = np.zeros_like(x)
        e[idx] = h
        out[(...,) + idx] = (np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * h)
    return out


def _close(analytic, fd, rtol=1e-7):
    """|analytic - fd| <= rtol (|fd| + 1e-3 max|fd|) element-wise (5 % of a term fails)."""
    scale = np.max(np.abs(fd))
    err = np.abs(np.asarray(analytic) - fd)
    bad = err > rtol * (np.abs(fd) + 1e-3 * scale)
    assert not bad.any(), (np.argwhere(bad)[:5], (err / (np.abs(fd) + 1e-3 * scale)).max())


def _triangle(system, seed=25, n=5):
    """Three images (centres in a triangle, random attitudes), n points seen by all."""
    from photogrammetry.adjustment.block_conditions import _condition_index, pad_pairs
    rng = np.random.default_rng(seed)
    m, f = 3, 100.0
    angles = rng.uniform(-0.5, 0.5, (m, 3))
    X = np.array([[0.0, 0.0, 1000.0], [400.0, 30.0, 1010.0], [150.0, 380.0, 990.0]])
    xy = rng.uniform(-40, 40, (m, n, 2))
    pairs = np.array([[0, 1], [0, 2], [1, 2]])
    pair_points = [(xy[i], xy[j]) for i, j in pairs]
    point_ids = [list(range(n))] * 3
    xy_i, xy_j, mask = pad_pairs(pair_points)
    p_c, s_c, obs, buckets = _condition_index(pairs, mask, point_ids, m)
    img = pairs[p_c]
    U = np.stack([np.concatenate([q[p_c, s_c], np.full((len(p_c), 1), -f)], axis=1)
                  for q in (xy_i, xy_j)], axis=1)
    return dict(angles=angles, X=X, xy=xy, pairs=pairs, p_c=p_c, s_c=s_c, obs=obs,
                buckets=buckets, img=img, U=U, f=f, m=m, n=n, system=system)


def _g(T, angles=None, X=None, xy=None):
    """g of every condition from scratch: (X_j - X_i) . (R_i u_i x R_j u_j)."""
    angles = T["angles"] if angles is None else angles
    X = T["X"] if X is None else X
    xy = T["xy"] if xy is None else xy
    R = angles_to_matrix(angles, T["system"])
    i, j, pt = T["img"][:, 0], T["img"][:, 1], T["s_c"]
    ui = np.concatenate([xy[i, pt], np.full((len(i), 1), -T["f"])], axis=1)
    uj = np.concatenate([xy[j, pt], np.full((len(i), 1), -T["f"])], axis=1)
    ri, rj = np.einsum("cab,cb->ca", R[i], ui), np.einsum("cab,cb->ca", R[j], uj)
    return np.einsum("ca,ca->c", X[j] - X[i], np.cross(ri, rj))


@pytest.mark.parametrize("system", ["phi-omega-kappa", "omega-phi-kappa"])
def test_block_derivatives_and_joint_weights_against_differences(system):
    """The block's condition Jacobian (both images' angles in the named system), the
    derivatives by the photo coordinates, dg/db, the joint weight matrix of a point seen
    in three images (the inverse of the conditions' covariance propagated from the six
    shared photo coordinates) and the position-error term of the covariance, all against
    central differences of g built from scratch, to 1e-7 (issue 12)."""
    from scipy import sparse

    from photogrammetry.adjustment import _coplanarity_kernels as K
    from photogrammetry.adjustment.block import _position_cov
    from photogrammetry.adjustment.block_conditions import _condition_terms, _joint_weights
    T = _triangle(system)
    R, M = K.rotation_and_axes(T["angles"], system)
    base = T["X"][T["pairs"][:, 1]] - T["X"][T["pairs"][:, 0]]
    g, d, J, N = _condition_terms(T["U"], T["img"], T["p_c"], R, M, base)
    _close(g, _g(T), 1e-12)
    C = len(g)
    # by the angles of image i (columns 0-2) and image j (3-5)
    d_ang = _fd(lambda a: _g(T, angles=a), T["angles"], 1e-6)        # (C, m, 3)
    rows = np.arange(C)
    _close(J[:, :3], d_ang[rows, T["img"][:, 0]])
    _close(J[:, 3:], d_ang[rows, T["img"][:, 1]])
    # by the photo coordinates of the observation in image i and in image j
    d_xy = _fd(lambda q: _g(T, xy=q), T["xy"], 1e-3)                  # (C, m, n, 2)
    _close(d[:, 0], d_xy[rows, T["img"][:, 0], T["s_c"]])
    _close(d[:, 1], d_xy[rows, T["img"][:, 1], T["s_c"]])
    # by the base (g = b . N)
    for c in range(C):
        p = T["p_c"][c]
        _close(N[c], _fd(lambda b: np.cross(*(np.einsum(
            "ab,b->a", R[T["img"][c, k]], T["U"][c, k]) for k in (0, 1))) @ b, base[p], 1.0))
    # joint weights: per tie point the inverse of s2 G G^T, G the differences by the six
    # photo coordinates of its three observations
    s2 = 0.004 ** 2
    W, rank, var = _joint_weights(T["buckets"], T["obs"], d, s2, C, 1e-4)
    assert rank == C                                   # a triangle: nothing repeated
    W = W.toarray()
    G = d_xy.reshape(C, -1)
    Sigma = s2 * G @ G.T
    _close(var, np.diag(Sigma))
    for t in range(T["n"]):
        idx = np.flatnonzero(T["s_c"] == t)
        assert len(idx) == 3
        _close(W[np.ix_(idx, idx)], np.linalg.inv(Sigma[np.ix_(idx, idx)]))
        other = np.setdiff1d(np.arange(C), idx)
        assert np.all(W[np.ix_(idx, other)] == 0)      # points are independent
    # the EO position errors in the angles' covariance: T S_X T^T, T = (WJ)^T dg/dX
    rng = np.random.default_rng(26)
    WJ = sparse.csr_matrix(rng.normal(size=(C, 9)))
    ps = rng.uniform(0.01, 0.05, (3, 3))
    got = _position_cov(WJ, N, T["img"], T["m"], 9, ps)
    G_X = _fd(lambda x: _g(T, X=x), T["X"], 1e-3).reshape(C, -1)
    Tm = WJ.toarray().T @ G_X
    _close(got, Tm @ np.diag(ps.ravel() ** 2) @ Tm.T)


def test_compiled_condition_terms_equal_the_numpy_expressions():
    """The compiled condition terms against the numpy expressions they replaced (cross
    products and einsums over all conditions of random images, rays and bases): equal to
    1e-15 relative (bit for bit where numpy adds in the kernel's order)."""
    from photogrammetry.adjustment import _coplanarity_kernels as K
    from photogrammetry.adjustment.block_conditions import _condition_terms
    rng = np.random.default_rng(40)
    m, P, C = 7, 9, 300
    R, M = K.rotation_and_axes(rng.uniform(-0.3, 0.3, (m, 3)), "omega-phi-kappa")
    img = rng.integers(0, m, (C, 2))
    bp = rng.integers(0, P, C)
    b = rng.normal(size=(P, 3))
    U = np.concatenate([rng.uniform(-50, 50, (C, 2, 2)), np.full((C, 2, 1), -100.0)], 2)
    R_i, R_j = R[img[:, 0]], R[img[:, 1]]
    r_i = np.einsum("cab,cb->ca", R_i, U[:, 0])
    r_j = np.einsum("cab,cb->ca", R_j, U[:, 1])
    N = np.cross(r_i, r_j)
    g = np.einsum("ci,ci->c", N, b[bp])
    d_i = np.einsum("cji,cj->ci", R_i, np.cross(r_j, b[bp]))[:, :2]
    d_j = np.einsum("cji,cj->ci", R_j, np.cross(b[bp], r_i))[:, :2]
    A_i = np.cross(r_i, np.cross(r_j, b[bp]))
    A_j = np.cross(r_j, np.cross(b[bp], r_i))
    J = np.concatenate([np.einsum("ca,cak->ck", A_i, M[img[:, 0]]),
                        np.einsum("ca,cak->ck", A_j, M[img[:, 1]])], axis=1)
    got = _condition_terms(U, img, bp, R, M, b)
    for name, x, ref in zip("g d J N".split(), got, (g, np.stack([d_i, d_j], 1), J, N)):
        np.testing.assert_allclose(x, ref, rtol=0, atol=1e-15 * np.abs(ref).max(),
                                   err_msg=name)
    with pytest.raises(IndexError):
        _condition_terms(U, img + m, bp, R, M, b)


def test_pair_whose_screening_did_not_converge_is_left_out_with_a_warning(block, monkeypatch):
    """A pair whose pair-wise screening did not converge has no valid outlier tests: it
    is left out with a QualityWarning naming it (it used to enter the block silently),
    and the block is the one adjusted without that pair."""
    from ins.common.errors import QualityWarning
    from photogrammetry.adjustment import _coplanarity_kernels as K
    from photogrammetry.adjustment import block as block_mod
    real = block_mod.adjust_pairs
    k_bad = 4

    def screening(*args, **kw):
        out = real(*args, **kw)
        out["status"] = out["status"].copy()
        out["status"][k_bad] = K.STATUS_NOT_CONVERGED
        return out
    monkeypatch.setattr(block_mod, "adjust_pairs", screening)
    i, j = block["pairs"][k_bad]
    with pytest.warns(QualityWarning, match=f"pair {i}-{j} left out: its pair-wise "
                                            "screening did not converge"):
        res = _run(block, "known-base", "none")
    assert res.pair_status[k_bad] == K.STATUS_NOT_CONVERGED and not res.mask[k_bad].any()
    monkeypatch.setattr(block_mod, "adjust_pairs", real)
    keep = [k for k in range(len(block["pairs"])) if k != k_bad]
    B = dict(block, pairs=block["pairs"][keep], pair_points=[block["pair_points"][k] for k in keep],
             point_ids=[block["point_ids"][k] for k in keep])
    ref = _run(B, "known-base", "none")
    np.testing.assert_allclose(res.angles, ref.angles, atol=1e-12)
    np.testing.assert_allclose(res.cov, ref.cov, rtol=1e-9, atol=1e-20)


def test_block_refuses_zero_photo_variance(block):
    """A condition of zero variance in the block (a point on the base line) is refused
    with the pair and the point named, not weighted 0 silently."""
    p = sc.make_pairs(1, 8, seed=28)
    pts = [(p["u1"][0, :, :2].copy(), p["u2"][0, :, :2].copy())]
    pts[0][0][3] = pts[0][1][3] = 0.0                  # straight below both cameras
    X = np.array([[0.0, 0.0, 1000.0], [0.0, 0.0, 900.0]])   # one above the other
    with pytest.raises(InputError, match="pair 0-1, tie point 3: .* variance 0.0"):
        adjust_block(np.zeros((2, 3)), [[0, 1]], pts, p["f_mm"], p["system"], "known-base",
                     "none", positions=X, sigma_mm=p["sigma_mm"], snooping=False)


def _priors(B, seed):
    """Two priors drawn within the stated sigma (0.005 rad) and one 0.25 deg off in
    every angle (random signs)."""
    rng = np.random.default_rng(seed)
    a = B["angles"]
    return [a + rng.normal(0, 0.005, a.shape), a + rng.normal(0, 0.005, a.shape),
            a + np.deg2rad(0.25) * rng.choice([-1.0, 1.0], a.shape)]


@pytest.mark.parametrize("method,datum", [("known-base", "none"), ("base-free", "first")])
def test_block_with_outliers_does_not_depend_on_the_prior(method, datum):
    """6 % of the observations are gross mismatches (10-100 px), so 10-30 % of each pair's
    conditions: from priors within sigma and 0.25 deg off, the same rejected set (rule:
    identical when every pair has at least 15 common points, i.e. enough inliers to
    out-vote its outliers) and the same angles (1e-8 rad); the errors (datum first: after
    the datum's common rotation) are within 4.5 sigma, sigma0 near 1, no quality flag."""
    B = sc.make_block(n_strips=3, n_per_strip=6, seed=61, outlier_fraction=0.06,
                      min_common=15)
    per_pair = [np.mean(B["outliers"][i][q] | B["outliers"][j][q])
                for (i, j), q in zip(B["pairs"], B["point_ids"])]
    assert 0.08 < np.mean(per_pair) < 0.2 and max(per_pair) >= 0.2
    runs = [adjust_block(p, B["pairs"], B["pair_points"], B["f_mm"], B["system"], method,
                         datum, positions=B["positions"], sigma_mm=B["sigma_mm"],
                         point_ids=B["point_ids"]) for p in _priors(B, 62)]
    for r in runs[1:]:
        np.testing.assert_array_equal(r.rejected, runs[0].rejected)
    res = runs[0]
    if datum == "none":
        for r in runs[1:]:
            np.testing.assert_allclose(r.angles, res.angles, atol=1e-8)
    assert res.converged and abs(res.sigma0 - 1) < 0.1 and not res.quality.poor
    err = _errors(B, res, align=datum == "first")
    M = rotation_and_axes(res.angles, B["system"])[1]
    s = np.sqrt(np.einsum("mij,mjk,mik->mi", M,
                          np.stack([res.cov[3 * i:3 * i + 3, 3 * i:3 * i + 3]
                                    for i in range(len(M))]), M))
    k = s[:, 0] > 0
    assert np.all(np.abs(err[k]) < 4.5 * s[k] + (0 if datum == "none" else 4.5 * s[k].max()))
    # the detectable outliers are out: what stays is along the epipolar lines
    truth = [B["outliers"][i][q] | B["outliers"][j][q]
             for (i, j), q in zip(B["pairs"], B["point_ids"])]
    kept = sum(int((t & res.mask[p, :len(t)]).sum()) for p, t in enumerate(truth))
    assert kept < 0.2 * sum(int(t.sum()) for t in truth)


@pytest.mark.parametrize("datum", ["first", "ins"])
def test_two_strip_block_of_four_images_with_outliers_converges(datum):
    """4 images in two strips (cross-strip pairs, kappa 0 and 180 deg), 8 % outlying
    observations: from priors within sigma and 0.25 deg off the block converges to the
    truth within its sigma (the issue's case returned 2.5-19 deg off, exit 0)."""
    B = sc.make_block(n_strips=2, n_per_strip=2, seed=63, outlier_fraction=0.08,
                      forward_overlap=0.8, side_overlap=0.6, points_per_image=120)
    for prior in _priors(B, 64):
        res = adjust_block(prior, B["pairs"], B["pair_points"], B["f_mm"], B["system"],
                           "base-free", datum, positions=B["positions"],
                           sigma_mm=B["sigma_mm"], point_ids=B["point_ids"])
        assert res.converged and not res.quality.poor
        # datum ins: the block sits in the INS frame (boresight ~0.3 deg, common rotation)
        err = _errors(B, res, align=True)
        assert np.abs(err).max() < np.deg2rad(0.1)
        assert np.all(np.abs(err) < 5 * np.maximum(res.sigma, res.sigma.max()))


def test_quality_flags_sigma0_and_angle_change(block):
    """The trust rule: a stated photo sigma 4x too small makes sigma0 implausible (block
    and pairs flagged); an image whose refined angle moves 3 deg from its prior (a prior
    3 deg off, datum ins) is flagged by name; a good block has no flag."""
    good = _run(block, "known-base", "none")
    assert not good.quality.poor and not good.quality.pair_flags.any()
    tight = _run(dict(block, sigma_mm=block["sigma_mm"] / 4), "known-base", "none")
    # (the robust start and snooping, at the wrong sigma, throw good points out too:
    # sigma0 2.3 instead of 4, still beyond the limit)
    assert tight.quality.poor and tight.sigma0 > tight.quality.sigma0_limit == 2.0
    assert any(r.startswith("block sigma0") for r in tight.quality.reasons)
    assert tight.quality.pair_flags.any()
    B = dict(block, prior=block["prior"].copy())
    B["prior"][5, 2] += np.deg2rad(3.0)
    off = _run(B, "known-base", "ins", image_ids=[f"img{i:03d}" for i in range(24)])
    assert off.quality.poor and off.quality.image_flags[5]
    assert off.quality.image_flags.sum() == 1
    assert any(r.startswith("image img005: angle change") for r in off.quality.reasons)


@pytest.mark.parametrize("datum,position_sigma", [("none", None), ("ins", 0.05)])
def test_banded_algebra_equals_dense(block, datum, position_sigma):
    """The banded normal equations (reverse Cuthill-McKee order, banded Cholesky,
    Takahashi covariance blocks) give the dense path's angles, sigmas, covariance
    blocks (with the EO-position term) and sigma0; the operator's product with a vector
    is the dense covariance's."""
    kw = dict(position_sigma=position_sigma)
    dense = _run(block, "known-base", datum, algebra="dense", **kw)
    band = _run(block, "known-base", datum, algebra="banded", **kw)
    assert band.cov is None and band.cov_op is not None and dense.cov_op is None
    np.testing.assert_allclose(band.angles, dense.angles, atol=1e-13)
    assert band.sigma0 == pytest.approx(dense.sigma0, rel=1e-12)
    np.testing.assert_allclose(band.sigma, dense.sigma, rtol=1e-9)
    np.testing.assert_allclose(band.cov_blocks(), dense.cov_blocks(), rtol=1e-8,
                               atol=1e-12 * dense.sigma.max() ** 2)
    v = np.random.default_rng(0).normal(size=3 * len(block["angles"]))
    np.testing.assert_allclose(band.cov_op.apply(v), dense.cov @ v,
                               rtol=1e-7, atol=1e-9 * np.abs(dense.cov @ v).max())
    with pytest.raises(ValueError, match="operator"):
        band.correlation()


@pytest.mark.parametrize("method,datum,keep_dense", [("relative", "first", True),
                                                     ("base-free", "ins", True),
                                                     ("relative", "ins", True),
                                                     ("relative", "first", False),
                                                     ("base-free", "ins", False)])
def test_bordered_banded_algebra_equals_dense(block, method, datum, keep_dense,
                                              monkeypatch):
    """Relative and base-free blocks: the whole normal matrix (angles, then two
    base-direction parameters per pair) factored sparse, its inverse's angle blocks by
    selected inversion (Takahashi) or, up to ``DENSE_MAX_ANGLES``, the dense covariance
    from the bases' Schur complement by the sparse half solve, against the dense
    algebra's Schur complement of the bases and its inverse: angles (1e-12 rad),
    sigma0, sigmas and covariance blocks (1e-9), the operator's product with a vector
    (1e-9 of its size); measured 1e-15 rad and 1e-11."""
    from photogrammetry.adjustment import block_covariance
    if not keep_dense:
        monkeypatch.setattr(block_covariance, "DENSE_MAX_ANGLES", 0)
    dense = _run(block, method, datum, algebra="dense")
    band = _run(block, method, datum, algebra="banded")
    assert band.cov is None and band.cov_op.bordered and dense.cov_op is None
    assert (band.cov_op.C is not None) == keep_dense
    assert band.cov_op.S.shape[0] > band.cov_op.n_angles == 3 * band.cov_op.free.sum()
    np.testing.assert_allclose(band.angles, dense.angles, atol=1e-12)
    assert band.sigma0 == pytest.approx(dense.sigma0, rel=1e-10)
    np.testing.assert_allclose(band.sigma, dense.sigma, rtol=1e-9)
    np.testing.assert_allclose(band.cov_blocks(), dense.cov_blocks(), rtol=1e-9,
                               atol=1e-10 * dense.sigma.max() ** 2)
    fr = np.repeat(band.cov_op.free, 3)
    v = np.random.default_rng(0).normal(size=3 * len(block["angles"]))
    Cv = (dense.cov @ np.where(fr, v, 0.0))[fr]
    np.testing.assert_allclose(band.cov_op.apply(v[fr]), Cv, rtol=1e-9,
                               atol=1e-9 * np.abs(Cv).max())
    with pytest.raises(ValueError, match="not sparse"):
        band.cov_op.K()


def test_cholmod_steps_give_the_superlu_angles(block, monkeypatch):
    """A base-free block's Gauss-Newton steps factored by CHOLMOD (optional, cvxopt) and
    by SuperLU: the same angles (1e-12 rad; measured 1e-16), sigma0 and sigmas."""
    pytest.importorskip("cvxopt")
    from photogrammetry.adjustment import block as block_mod
    from photogrammetry.adjustment import cholmod
    made = []
    real = cholmod.CholmodSPD
    monkeypatch.setattr(cholmod, "CholmodSPD", lambda *a, **k: made.append(1) or real(*a, **k))
    fast = _run(block, "base-free", "first", algebra="banded")
    assert made and block_mod.cholmod is cholmod
    monkeypatch.setattr(cholmod, "USE_CHOLMOD", False)
    n_made = len(made)
    slow = _run(block, "base-free", "first", algebra="banded")
    assert len(made) == n_made
    np.testing.assert_allclose(fast.angles, slow.angles, rtol=0, atol=1e-12)
    assert fast.sigma0 == pytest.approx(slow.sigma0, rel=1e-10)
    np.testing.assert_allclose(fast.sigma, slow.sigma, rtol=1e-9)


def test_quality_judges_known_base_changes_without_the_boresight():
    """Known-base, datum none: a 1 deg boresight (common camera-frame rotation; 7x the
    INS sigma) is not an implausible change (it is what the assessment estimates), one
    image 3 deg off in kappa on top of it is."""
    B = sc.make_block(n_strips=2, n_per_strip=6, seed=23, boresight_rad=(0.01, -0.015, 0.01))
    res = _run(B, "known-base", "none")
    assert not res.quality.poor, res.quality.reasons
    B["prior"][4, 2] += np.deg2rad(3.0)
    res = _run(B, "known-base", "none")
    assert res.quality.poor and np.flatnonzero(res.quality.image_flags).tolist() == [4]


def _few_point_pair(seed):
    """A known-base pair of 8 common points, 2 of them gross mismatches (20-100 px), the
    prior of image 2 0.2 deg off in every angle (the issue's case)."""
    p = sc.make_pairs(1, 8, seed=seed)
    u1, u2 = p["u1"][0, :, :2].copy(), p["u2"][0, :, :2].copy()
    rng = np.random.default_rng(seed)
    u2[:2] += rng.choice([-1, 1], (2, 2)) * rng.uniform(0.2, 1.0, (2, 2))
    prior = np.vstack([p["ang1"], p["ang2"] + np.deg2rad(0.2) * rng.choice([-1.0, 1.0], 3)])
    return p, prior, [(u1, u2)]


@pytest.mark.parametrize("seed,datum", [(9, "first"), (9, "ins"), (0, "first")])
def test_pair_whose_conditions_vanish_in_the_screening_is_flagged(seed, datum):
    """Seed 9: the screening leaves the pair out (no condition left: used to end in
    'need at least one array to concatenate'); seed 0: 3 conditions for 3 angles (no
    redundancy: used to be an InputError).  Both: no exception, every image at its prior
    with the prior sigma, not adjusted, the quality poor with the reason first."""
    p, prior, pts = _few_point_pair(seed)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        res = adjust_block(prior, [[0, 1]], pts, p["f_mm"], p["system"], "known-base", datum,
                           positions=np.vstack([p["C1"], p["C2"]]), sigma_mm=p["sigma_mm"])
    if seed == 0 and datum == "first":
        assert "no redundancy" in res.quality.reasons[0]
    else:
        assert "no pair of images is left" in res.quality.reasons[0]
    assert res.quality.poor and res.quality.reasons[0].startswith("block not adjusted")
    assert any("block not adjusted" in str(x.message) for x in w)
    np.testing.assert_array_equal(res.angles, prior)
    assert not res.adjusted.any() and np.isnan(res.sigma0) and not res.converged
    np.testing.assert_allclose(res.sigma, 0.005)


@pytest.mark.parametrize("seed", [12, 16, 18, 19])
def test_few_point_pair_off_beyond_its_sigma_is_flagged(seed):
    """The same kind of pair, screened into redundancy 1-3 with one mismatch kept or good
    points rejected: 2000-6000 arcsec off the truth, 10-26 of its own sigmas, sigma0
    below the chi-square limit and the change below 5 sqrt(2) prior sigmas -- every
    test passed (exit 0).  Flagged now by the redundancy rule."""
    p, prior, pts = _few_point_pair(seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = adjust_block(prior, [[0, 1]], pts, p["f_mm"], p["system"], "known-base",
                           "first", positions=np.vstack([p["C1"], p["C2"]]),
                           sigma_mm=p["sigma_mm"])
    err = np.abs(res.angles[1] - p["ang2"][0])
    assert np.max(err / res.sigma[1]) > 5                  # beyond what its sigma states
    assert res.redundancy < 5 and res.rejected.sum() > 0
    assert res.quality.poor
    assert any("too few conditions left" in r for r in res.quality.reasons)
