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
