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
