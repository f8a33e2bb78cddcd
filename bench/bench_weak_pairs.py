"""Weak cross-strip pairs like the real aerial ones (issue 26 item 2): 22 and 46 tie
points with 1 and 2 mismatches, the prior 0.2 deg off, 30 % side overlap, kappa 180 deg
apart (``tests/scenario.make_cross_strip_pair``: the truth is known), refined as a user
runs it (``photogrammetry refine``, base-free and known-base).  Prints, per pair: the
exit code, whether it was flagged, image 2's true error and its stated sigma
(arcsec).  The seeds are those of the largest errors over 200 pairs of each size
(``tests/test_refine_weak_pairs.py``).

    .venv/bin/python bench/bench_weak_pairs.py
"""
import contextlib
import io
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import scenario as sc  # noqa: E402

from photogrammetry.cli.main import main  # noqa: E402
from photogrammetry.orientation.exposure import read_eo_csv  # noqa: E402

AS = 180.0 / np.pi * 3600.0


def main_bench():
    print("| pair | method | exit | flag | true error phi/omega/kappa (arcsec) | "
          "stated sigma (arcsec) | error / sigma |")
    print("|---|---|---|---|---|---|---|")
    for n, k, seed in ((22, 1, 4), (46, 2, 0)):
        for method in ("base-free", "known-base"):
            p = sc.make_cross_strip_pair(n, k, seed)
            with tempfile.TemporaryDirectory() as tmp:
                d = Path(tmp)
                eo, tp, cam = sc.write_pair_files(p, d)
                with contextlib.redirect_stderr(io.StringIO()):
                    code = main(["refine", eo, tp, "--camera", cam, "--method", method,
                                 "-o", str(d / "r.csv"), "--report", str(d / "r.md"), "-q"])
                r = read_eo_csv(str(d / "r.csv")) if (d / "r.csv").exists() else None
                flag = r is not None and "QUALITY" in (d / "r.csv").read_text()
            if r is None:
                print(f"| {n} points, {k} mismatched, seed {seed} | {method} | {code} | "
                      f"nothing written | | | |")
                continue
            e = np.abs((r.angles[1] - p["angles"][1] + np.pi) % (2 * np.pi) - np.pi) * AS
            s = r.angle_sigma[1] * AS
            fmt = lambda v, f="{:.0f}": " / ".join(f.format(x) for x in v)  # noqa: E731
            print(f"| {n} points, {k} mismatched, seed {seed} | {method} | {code} | "
                  f"{'yes' if flag else 'no'} | {fmt(e)} | {fmt(s)} | {fmt(e / s, '{:.2f}')} |")


if __name__ == "__main__":
    main_bench()
