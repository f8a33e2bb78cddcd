"""The boresight's sigma over simulated flights: is the total sigma (adjustment + INS
attitude common to the exposures, ``photogrammetry.orientation.boresight_sigma``) honest?

Runs the demo chain (``tools/demo.py``: simulate -> process -> eo -> refine) for several
seeds and prints per seed the boresight estimate, the adjustment's sigma, the INS
common sigma, the total, and the distance of the estimate from the SIMULATED boresight
in adjustment sigmas and in total sigmas; then the RMS of those z-scores over the seeds
(honest: near 1; the fully correlated INS part is an upper bound, so somewhat below 1
is the expected side).  The split: the INS error the data hold (the "apparent"
boresight minus the simulated, in INS sigmas) and the adjustment's own error (estimate
minus apparent, in adjustment sigmas).

    .venv/bin/python bench/bench_boresight_sigma.py --seeds 8 [--plan data/flights/demo.toml]

The chain's commands write to ``--log`` (default /tmp/bench_boresight_sigma.log).
"""
import argparse
import contextlib
import importlib.util
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
AS = np.pi / 180 / 3600


@contextlib.contextmanager
def output_to(path):
    """Send this process's and its children's stdout/stderr to ``path``."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    with open(path, "a") as f:
        os.dup2(f.fileno(), 1)
        os.dup2(f.fileno(), 2)
        try:
            yield
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--first-seed", type=int, default=1)
    p.add_argument("--plan", type=Path, default=ROOT / "data" / "flights" / "demo.toml")
    p.add_argument("--log", type=Path, default=Path(tempfile.gettempdir())
                   / "bench_boresight_sigma.log")
    args = p.parse_args(argv)
    spec = importlib.util.spec_from_file_location("demo", ROOT / "tools" / "demo.py")
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    rows = []
    print(f"plan {args.plan.name}; seeds {args.first_seed}..{args.first_seed + args.seeds - 1};"
          " arcsec, rx/ry/rz of the camera file")
    print(f"{'seed':>4} | {'estimate':>20} | {'simulated':>20} | {'adj sigma':>16} | "
          f"{'INS sigma':>16} | {'total sigma':>16} | {'z adj-only':>17} | {'z total':>17}")
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        with tempfile.TemporaryDirectory() as tmp, output_to(args.log):
            fig = demo.main(["--plan", str(args.plan), "--out", str(Path(tmp) / "demo"),
                             "--seed", str(seed)])
        est, true = fig["boresight_rad"], fig["boresight_true_rad"]
        app = fig["boresight_apparent_rad"]
        adj, ins = fig["boresight_sigma_rad"], fig["boresight_sigma_ins_rad"]
        tot = fig["boresight_sigma_with_ins_rad"]
        r = {"z_adj": (est - true) / adj, "z_tot": (est - true) / tot,
             "z_ins_part": (app - true) / ins, "z_adj_part": (est - app) / adj}
        rows.append(r)

        def f3(v, d=1):
            return "/".join(f"{x:.{d}f}" for x in v)
        print(f"{seed:4d} | {f3(est / AS):>20} | {f3(true / AS):>20} | {f3(adj / AS):>16} | "
              f"{f3(ins / AS):>16} | {f3(tot / AS):>16} | {f3(r['z_adj'], 2):>17} | "
              f"{f3(r['z_tot'], 2):>17}", flush=True)
    print()
    for key, what in (("z_adj", "(estimate - simulated) / adjustment sigma"),
                      ("z_tot", "(estimate - simulated) / total sigma"),
                      ("z_ins_part", "(apparent - simulated) / INS common sigma"),
                      ("z_adj_part", "(estimate - apparent) / adjustment sigma")):
        z = np.array([r[key] for r in rows])
        per_axis = np.sqrt(np.mean(z ** 2, axis=0))
        print(f"RMS over {len(rows)} seeds of {what}: rx/ry/rz "
              + "/".join(f"{x:.2f}" for x in per_axis)
              + f", all {np.sqrt(np.mean(z ** 2)):.2f}; max |z| {np.abs(z).max():.2f}")


if __name__ == "__main__":
    main()
