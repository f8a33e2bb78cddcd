"""Issue 26 item 2: cross-strip pairs like the real aerial ones (22 and 46 SIFT matches, a
few per cent mismatches, the prior 0.2 deg off), refined as a user runs it.

The real pairs came out 1017 and 1506 arcsec from the published relative orientation
with exit 0.  Simulated (``tests/scenario.py``, ``make_cross_strip_pair``: the truth is
known), such a pair is weak: its common points lie in the 30 % side overlap, and with
the default method (base-free) the rotation about the base is determined to 300-500
arcsec.  Errors near 1000 arcsec are what those sigmas state -- once the sigmas are
not shrunk by a sigma0 below 1, which at a redundancy of 16 is the scatter of its
estimate (the covariance is now scaled by ``max(sigma0, 1)^2``).  So these pairs are
not flagged: their stated sigmas say how far they may be.
"""
import re
import warnings

import numpy as np
import pytest
import scenario as sc
from scipy.stats import chi2

from photogrammetry.adjustment.block import adjust_block
from photogrammetry.cli.main import main
from photogrammetry.orientation.exposure import read_eo_csv

AS = 180 / np.pi * 3600


@pytest.mark.parametrize("n_points,n_mismatches,seed", [(22, 1, 4), (46, 2, 0)])
def test_ngi_like_cross_strip_pair_exit_flag_and_sigma(tmp_path, capsys, n_points,
                                                       n_mismatches, seed):
    """The CLI (defaults: base-free, datum first) on the two largest errors of 200
    simulated pairs of each size: exit 0, no flag, the mismatches rejected, the error
    of image 2 (949-1178 arcsec in omega) within 2.6 of its stated sigma (369-484
    arcsec; before the max(sigma0, 1) scaling: 349 arcsec, 3.4 sigma, for the first)."""
    p = sc.make_cross_strip_pair(n_points, n_mismatches, seed)
    eo, tp, cam = sc.write_pair_files(p, tmp_path)
    out, rep = tmp_path / "r.csv", tmp_path / "r.md"
    code = main(["refine", eo, tp, "--camera", cam, "-o", str(out), "--report", str(rep),
                 "-q"])
    assert code == 0 and "Traceback" not in capsys.readouterr().err
    assert "QUALITY" not in out.read_text() and "Trust: no flag" in rep.read_text()
    n_rej = int(re.search(r"(\d+) rejected \(data snooping\)", rep.read_text()).group(1))
    assert n_rej >= n_mismatches
    res = read_eo_csv(str(out))
    err = np.abs((res.angles[1] - p["angles"][1] + np.pi) % (2 * np.pi) - np.pi)
    sigma = res.angle_sigma[1]
    assert err.max() * AS > 900                # as far off as the real pairs
    assert sigma.max() * AS > 300              # and its sigma says so
    assert np.all(err / sigma < 2.6)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["base-free", "known-base"])
def test_cross_strip_pair_sigmas_cover_their_errors(method):
    """200 pairs of each size: the chi-square of image 2's true error against its
    stated covariance exceeds its 99 % point in at most 2 % of the pairs (measured:
    base-free 0.5 % and 1.5 % for 22 and 46 points, known-base 0 % and 1 %); with the
    covariance scaled by sigma0^2 instead (as before) base-free was at 3.5 % for 22
    points.  None of these pairs is flagged and the mismatches are rejected in at
    least 99 % of them."""
    lim = chi2.ppf(0.99, 3)
    for n_points, n_mismatches in ((22, 1), (46, 2)):
        q, q_old, missed = [], [], 0
        for seed in range(200):
            p = sc.make_cross_strip_pair(n_points, n_mismatches, seed)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = adjust_block(p["prior"], [[0, 1]], [(p["xy1"], p["xy2"])], p["f_mm"],
                                 p["system"], method, "first", positions=p["positions"],
                                 sigma_mm=p["sigma_mm"])
            assert not r.quality.poor
            missed += not set(p["mismatched"]) <= set(np.flatnonzero(r.rejected[0]))
            e = (r.angles[1] - p["angles"][1] + np.pi) % (2 * np.pi) - np.pi
            q.append(e @ np.linalg.solve(r.cov[3:, 3:], e))
            q_old.append(q[-1] * max(r.sigma0, 1.0) ** 2 / r.sigma0 ** 2)
        assert np.mean(np.array(q) > lim) <= 0.02
        assert missed <= 2
        if method == "base-free" and n_points == 22:
            assert np.mean(np.array(q_old) > lim) > 0.03


def _quarter_wrong(p, seed, n_wrong=None):
    """A quarter (or `n_wrong`) of image 2's matches replaced by random wrong ones: the
    photo position of no ground point, uniform over the frame (errors of hundreds of px,
    not Gaussian); the indices replaced."""
    rng = np.random.default_rng(seed + 500)
    n = len(p["xy2"])
    bad = rng.choice(n, int(round(0.25 * n)) if n_wrong is None else n_wrong, replace=False)
    half = 0.5 * np.array([p["width_px"], p["height_px"]]) * p["pixel_mm"]
    p["xy2"][bad] = rng.uniform(-half, half, (len(bad), 2))
    return bad


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cross_strip_pair_quarter_wrong_prior_03_deg_off(tmp_path, capsys, seed):
    """Issue 35 item 6: 42 matches of which 10 random wrong ones (not Gaussian: anywhere
    in the frame), the prior of image 2 0.3 deg off in every angle.  The CLI (defaults)
    solves it: exit 0, no flag, every wrong match rejected, and the error of image 2
    against the simulation's truth consistent with its stated covariance (chi-square of
    the three angles below its 99.9 % point, 16.3; measured 0.3-2.6 for these seeds)."""
    p = sc.make_cross_strip_pair(42, 0, seed, prior_off_deg=0.3)
    bad = _quarter_wrong(p, seed)
    eo, tp, cam = sc.write_pair_files(p, tmp_path)
    out = tmp_path / "r.csv"
    code = main(["refine", eo, tp, "--camera", cam, "-o", str(out), "-q"])
    assert code == 0, capsys.readouterr().err
    assert "QUALITY" not in out.read_text()
    res = read_eo_csv(str(out))
    e = (res.angles[1] - p["angles"][1] + np.pi) % (2 * np.pi) - np.pi
    r = _block(p)
    assert set(bad) <= set(np.flatnonzero(r.rejected[0]))
    # the file's angles are the adjustment's (to the CSV's digits)
    assert np.all(np.abs((r.angles[1] - res.angles[1] + np.pi) % (2 * np.pi) - np.pi) < 1e-7)
    assert e @ np.linalg.solve(r.cov[3:, 3:], e) < chi2.ppf(0.999, 3)
    assert np.all(np.abs(e) < 3.5 * res.angle_sigma[1])


def _block(p, method="base-free"):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return adjust_block(p["prior"], [[0, 1]], [(p["xy1"], p["xy2"])], p["f_mm"],
                            p["system"], method, "first", positions=p["positions"],
                            sigma_mm=p["sigma_mm"])


def test_pair_with_fewer_inliers_than_the_model_needs_is_refused(tmp_path, capsys):
    """12 matches of which 8 wrong: 4 right ones, fewer than the 5 a base-free pair
    needs (any 5 points fit exactly, so the best hypothesis holds at least 5 and nothing
    checks it).  Still refused: exit 3, nothing written, the block not adjusted (no pair
    left, or no redundancy after the screening), never solved on wrong matches."""
    p = sc.make_cross_strip_pair(12, 0, 3, prior_off_deg=0.3)
    _quarter_wrong(p, 3, n_wrong=8)
    eo, tp, cam = sc.write_pair_files(p, tmp_path)
    code = main(["refine", eo, tp, "--camera", cam, "-o", str(tmp_path / "r.csv"), "-q"])
    err = capsys.readouterr().err
    assert code == 3 and ("no pair of images is left after the pair-wise screening" in err
                          or "no redundancy after the screening" in err), err
    assert not (tmp_path / "r.csv").exists()


def test_essential_start_does_not_use_the_prior_and_matches_the_truth():
    """The prior-free start alone (five-point RANSAC, OpenCV USAC_MAGSAC, and its pose)
    on 20 cross-strip pairs with a quarter of their matches wrong: image 2's rotation
    within 1.5 deg of the truth and the base direction within 1 deg of the true
    ``X2 - X1`` (measured at most 0.93 and 0.51 deg: a start, from a minimal sample, on
    the weak rotation about the base), image 1 held at its truth; an error in the frame
    conversion (OpenCV's y down, z forward) would show as tens of degrees."""
    from photogrammetry.adjustment.essential import essential_starts
    from photogrammetry.orientation.rotation import angles_to_matrix
    worst_rot, worst_base = 0.0, 0.0
    for seed in range(20):
        p = sc.make_cross_strip_pair(42, 0, seed)
        _quarter_wrong(p, seed)
        R1 = angles_to_matrix(p["angles"][:1], p["system"])
        ang, base, ok = essential_starts(p["xy1"][None], p["xy2"][None],
                                         np.ones((1, 42), bool), p["f_mm"], R1,
                                         p["system"], 5 * p["sigma_mm"])
        assert ok[0]
        R_err = angles_to_matrix(ang, p["system"])[0] @ p["R"][1].T
        worst_rot = max(worst_rot, np.degrees(np.arccos(np.clip((np.trace(R_err) - 1) / 2,
                                                                -1, 1))))
        b = p["positions"][1] - p["positions"][0]
        worst_base = max(worst_base, np.degrees(np.arccos(base[0] @ b / np.linalg.norm(b))))
    assert worst_rot < 1.5 and worst_base < 1.0


@pytest.fixture(scope="module")
def short_flight(tmp_path_factory):
    """The simulator's short flight (two strips flown in opposite directions, its own
    tie points, the true EO): cross-strip pairs of 5-30 points."""
    from pathlib import Path
    from photogrammetry.simulate.folder import simulate_flight
    plan = Path(__file__).resolve().parent / "data" / "flights" / "short.toml"
    return simulate_flight(plan, tmp_path_factory.mktemp("weak") / "flight", seed=9)


def _flight_pairs(folder):
    from photogrammetry.adjustment.batch import prepare
    from photogrammetry.adjustment.block_conditions import pad_pairs
    from photogrammetry.imagery.tiepoints import read_tiepoints
    from photogrammetry.orientation.camera import read_camera
    eo = read_eo_csv(str(folder / "eo_true.csv"))
    cam = read_camera(str(folder / "camera.toml"))[0]
    eo, s_mm, _, _, pairs, points, _ = prepare(eo, read_tiepoints(str(folder /
                                                                      "tiepoints.csv")), cam)
    strip = np.array([str(i)[:3] for i in eo.image_id])
    xy1, xy2, mask = pad_pairs(points)
    return eo, cam, s_mm, pairs, strip[pairs[:, 0]] != strip[pairs[:, 1]], xy1, xy2, mask


def _screen(eo, cam, s_mm, pairs, xy1, xy2, mask, prior2):
    from photogrammetry.adjustment.coplanarity import adjust_pairs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = adjust_pairs(xy1, xy2, cam.focal_length_mm, eo.angles[pairs[:, 0]], prior2,
                           eo.system, "base-free", mask=mask, sigma_mm=s_mm)
    e = (out["angles"] - eo.angles[pairs[:, 1]] + np.pi) % (2 * np.pi) - np.pi
    ok = out["status"] == 0
    q = np.full(len(pairs), np.nan)
    q[ok] = np.einsum("pi,pi->p", e[ok], np.linalg.solve(out["cov"][ok], e[ok][..., None])[..., 0])
    return ok, q, e


def test_cross_strip_pairs_of_the_simulated_flight(short_flight):
    """The pair-wise screening (base-free, image i at its true angles) of the simulated
    flight's cross-strip pairs of 20 or more points, against the simulation's truth.

    Clean, image j's prior the truth: all 13 converge, each within its covariance
    (chi-square below the 99.9 % point); before, pair 2-23 (26 points) did not converge
    (the MSAC winner from a minimal sample 6000 arcsec off, Gauss-Newton from there).

    A quarter of every pair's matches replaced by random wrong ones, image j's prior
    0.3 deg off in every angle: all 13 converge, none more than 2 deg off (measured at
    most 1.6 deg, pair 2-23, chi-square 7.3: its sigmas are of that size) and at most
    one beyond the 99.9 % point (measured: one, pair 6-19, chi-square 84, with a wrong
    match that the weak rotation about the base can absorb); before, 12 converged and
    pair 1-24 came out 12 deg off, chi-square 9500 (its re-classification let 3 wrong
    matches in through the wide prediction sigmas of a weak pair).  Over this flight and 5 other seeds (69 such
    pairs): converged 69 (before 68), beyond the 99.9 % point 8 (11), more than 1 deg
    off 1 (3); all pairs in the strips: beyond the 99.9 % point 50 of 276 (65)."""
    eo, cam, s_mm, pairs, cross, xy1, xy2, mask = _flight_pairs(short_flight)
    big = cross & (mask.sum(axis=1) >= 20)
    assert big.sum() == 13
    lim = chi2.ppf(0.999, 3)
    ok, q, _ = _screen(eo, cam, s_mm, pairs, xy1, xy2, mask, eo.angles[pairs[:, 1]])
    assert ok[big].all() and np.all(q[big] < lim)
    rng = np.random.default_rng(1)
    half = 0.5 * np.array([cam.width_px, cam.height_px]) * cam.pixel_size_mm
    for k in range(len(pairs)):
        n = mask[k].sum()
        w = rng.choice(n, int(round(0.25 * n)), replace=False)
        xy2[k, w] = rng.uniform(-half, half, (len(w), 2))
    prior2 = eo.angles[pairs[:, 1]] + np.deg2rad(0.3) * rng.choice([-1.0, 1.0], (len(pairs), 3))
    ok, q, e = _screen(eo, cam, s_mm, pairs, xy1, xy2, mask, prior2)
    assert ok[big].all()
    assert np.all(np.abs(e[big]).max(axis=1) < np.deg2rad(2.0))
    assert np.sum(q[big] > lim) <= 1
