"""Scenario of issue 6: coplanarity refinement of 200+ pairs at n = 10, 30, 100 tie points
against the Cramer-Rao bound, sigma0, the paper's bias, and INS assessment on 50-image
blocks.  Prints figures; ``--quick`` for a short run.

    .venv/bin/python bench/refine_scenario.py [--pairs 200] [--quick]

Scenario: frame camera f = 10 000 px (100 mm, 0.01 mm pixels, 8000 x 6000), flying height
1000 m, relief +-50 m, 60 % forward overlap, true angles within +-3 deg, photo noise
0.5 px, INS prior noise 0.005 rad; image 1 of each pair carries its true angles.  Errors
and bounds are RMS per rotation axis of image 2 (arcsec).  Generator and bound:
``tests/scenario.py`` (test scaffolding, also used by the tests).
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

from ins.nav.rotation import wrap_to_pi
from photogrammetry.adjustment.assessment import assess
from photogrammetry.adjustment.block import adjust_block
from photogrammetry.adjustment.coplanarity import adjust_pairs
from photogrammetry.orientation.rotation import angles_to_matrix

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import scenario as sc  # noqa: E402  (test scaffolding: tests/scenario.py)

AS = 180 / np.pi * 3600


def rms_axis(err):
    """RMS per rotation axis over pairs, (P, 3) rad -> arcsec."""
    return np.sqrt(np.mean(err ** 2)) * AS


def bound_axis(cov):
    return np.sqrt(np.mean(np.trace(cov, axis1=1, axis2=2)) / 3) * AS


def run_pairs(pairs, method, snooping=True, repeat=3):
    """Adjust the pairs; returns (output, error (P, 3) rad, best ms per pair)."""
    best = np.inf
    for _ in range(repeat):
        t = time.perf_counter()
        out = adjust_pairs(pairs["u1"][..., :2], pairs["u2"][..., :2], pairs["f_mm"],
                           pairs["ang1"], pairs["prior2"], pairs["system"], method,
                           base=pairs["C2"] - pairs["C1"], sigma_mm=pairs["sigma_mm"],
                           snooping=snooping)
        best = min(best, time.perf_counter() - t)
    err = sc.rotation_error(angles_to_matrix(out["angles"], pairs["system"]), pairs["R2"])
    return out, err, 1e3 * best / len(err)


def pair_table(n_pairs, sizes, seed=0):
    print(f"pairs: {n_pairs} per size; RMS per axis of image 2's rotation error (arcsec), "
          "Cramer-Rao bound of the exact model")
    print(f"{'n':>4} {'method':<11} {'RMS':>8} {'bound':>8} {'ratio':>6} {'bias':>7} "
          f"{'sigma0 px':>9} {'ms/pair':>8}")
    rows = []
    for n in sizes:
        p = sc.make_pairs(n_pairs, n, seed=seed + n)
        crb = {True: sc.crb_rotation(p, True), False: sc.crb_rotation(p, False)}
        for method in ("known-base", "relative", "base-free", "paper"):
            out, err, ms = run_pairs(p, method, snooping=method != "paper",
                                     repeat=1 if method == "paper" else 3)
            bound = bound_axis(crb[method == "known-base"])
            bias = np.linalg.norm(err.mean(axis=0)) * AS
            s0 = (np.sqrt(out["vtpv"].sum() / max(out["redundancy"].sum(), 1))
                  * p["sigma_mm"] / p["pixel_mm"]) if method != "paper" else float("nan")
            rms = rms_axis(err)
            print(f"{n:>4} {method:<11} {rms:8.1f} {bound:8.1f} {rms / bound:6.3f} "
                  f"{bias:7.1f} {s0:9.3f} {ms:8.3f}")
            rows.append((n, method, rms, bound, s0, ms))
    return rows


def chi2_per_angle(res, B):
    """Chi-square per angle of the true angle errors against the full covariance."""
    e = wrap_to_pi(res.angles - B["angles"]).ravel()
    k = np.diag(res.cov) > 0
    return e[k] @ np.linalg.solve(res.cov[np.ix_(k, k)], e[k]) / k.sum()


def block_table(seeds, n_strips=5, n_per_strip=10):
    print(f"\n{n_strips * n_per_strip}-image blocks ({n_strips} strips flown back and forth), "
          "known-base, datum none: INS assessment")
    print("chi2 = true angle errors against the block's full covariance, per angle (~1; "
          "'indep': the conditions of a point in 3+ images weighted one by one, as before)")
    print(f"{'seed':>4} {'noise est/real (phi omega kappa)':>36} {'boresight err / sigma':>26} "
          f"{'sigma0':>7} {'lambda':>6} {'chi2':>5} {'indep':>5} {'s':>6}")
    for seed in seeds:
        B = sc.make_block(n_strips, n_per_strip, seed=seed)
        t = time.perf_counter()
        res = adjust_block(B["prior"], B["pairs"], B["pair_points"], B["f_mm"], B["system"],
                           "known-base", "none", positions=B["positions"],
                           sigma_mm=B["sigma_mm"], point_ids=B["point_ids"])
        a = assess(res, B["prior"], B["system"], "none", "known-base")
        dt = time.perf_counter() - t
        indep = adjust_block(B["prior"], B["pairs"], B["pair_points"], B["f_mm"], B["system"],
                             "known-base", "none", positions=B["positions"],
                             sigma_mm=B["sigma_mm"])
        ratio = a.ins_noise / B["ins_noise"].std(axis=0, ddof=1)
        z = (a.boresight - B["boresight"]) / a.boresight_sigma
        est = " ".join("   neg" if neg else f"{r:6.3f}"      # negative: not estimable
                       for r, neg in zip(ratio, a.ins_noise_negative))
        print(f"{seed:>4} {est:>36} "
              f"{' '.join(f'{v:+6.2f}' for v in z):>26} {res.sigma0:7.3f} "
              f"{a.cov_factor:6.2f} {chi2_per_angle(res, B):5.2f} {chi2_per_angle(indep, B):5.2f} "
              f"{dt:6.2f}")


def flight(folder, eo_path=None, boresight_deg=(0.1, -0.15, 0.2), ins_sigma_deg=0.005,
           seed=7, method="known-base", datum="none"):
    """Refine a simulator flight folder end to end through the CLI.

    Without `eo_path` an INS EO is made from ``eo_true.csv``: the true attitude times a
    boresight misalignment plus white angle noise (``FOLDER/eo_ins.csv``).
    """
    import os
    from dataclasses import replace

    from photogrammetry.cli.main import main as cli
    from photogrammetry.orientation.exposure import read_eo_csv, write_eo_csv
    from photogrammetry.orientation.rotation import boresight_matrix, matrix_to_angles
    truth = read_eo_csv(os.path.join(folder, "eo_true.csv"))
    if eo_path is None:
        rng = np.random.default_rng(seed)
        R = truth.matrices() @ boresight_matrix(np.deg2rad(boresight_deg)).T
        ang = matrix_to_angles(R, truth.system) + rng.normal(0, np.deg2rad(ins_sigma_deg),
                                                             (len(truth), 3))
        eo_path = os.path.join(folder, "eo_ins.csv")
        write_eo_csv(eo_path, replace(truth, angles=ang))
    out, rep = os.path.join(folder, "refined.csv"), os.path.join(folder, "report.md")
    t = time.perf_counter()
    code = cli(["refine", folder, "--eo", eo_path, "--method", method, "--datum", datum,
                "-o", out, "--report", rep, "-q"])
    dt = time.perf_counter() - t
    refined, ins = read_eo_csv(out), read_eo_csv(eo_path)
    e_ref = sc.rotation_error(refined.matrices(), truth.matrices())
    e_ins = sc.rotation_error(ins.matrices(), truth.matrices())
    print(f"\nflight {folder}: {len(truth)} images, exit {code}, {dt:.1f} s (CLI, files to report)")
    print(f"  RMS per axis vs truth: INS {rms_axis(e_ins):.1f}\", refined {rms_axis(e_ref):.2f}\"; "
          f"mean refined sigma {np.sqrt(np.mean(refined.angle_sigma ** 2)) * AS:.2f}\"")
    print(f"  report: {rep}")
    for line in open(rep).read().splitlines()[:16]:
        print("  | " + line)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=200)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--flight", metavar="FOLDER", help="also refine this simulator flight "
                    "(ins simulate data/flights/demo.toml -o FOLDER)")
    ap.add_argument("--eo", metavar="EO.csv", help="INS EO of the flight (default: made "
                    "from eo_true.csv with a boresight and noise)")
    args = ap.parse_args(argv)
    if args.flight:
        flight(args.flight, args.eo)
    sizes = (10, 30) if args.quick else (10, 30, 100)
    pair_table(50 if args.quick else args.pairs, sizes)
    block_table(range(2) if args.quick else range(6))
    return 0


if __name__ == "__main__":
    sys.exit(main())
