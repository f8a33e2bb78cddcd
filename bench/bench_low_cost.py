"""Low-cost logs as a new user runs them: the simulated consumer car and handheld walk of
:mod:`ins.simulate.ground` (rest or walking-pace start, consumer MEMS biases, 4 Hz
centimetre RTK fixes with late velocities, 15 s outages), processed by ``ins process``
with only the facts of the hardware in the config (lever arm, the IMU's mounting in the
car) and ``--preset``.  Prints per run: exit code, rejected fixes, and against the truth
the horizontal error over the outages (RMS and largest) of the forward filter and of the
smoothed solution, and the attitude RMS.

    .venv/bin/python bench/bench_low_cost.py [--seeds 1] [--keep DIR]
"""
import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]

from ins.io.navfiles import read_nav
from ins.nav import earth
from ins.simulate.ground import write_journey


def figures(truth, journey, traj):
    s = truth.evaluate(traj.time)
    dn = earth.ned_offset(s.lla, traj.lla)
    hor = np.hypot(dn[:, 0], dn[:, 1])
    rel = traj.time - truth.t_start
    gap = np.zeros(len(rel), bool)
    for a, n in journey.outages:
        gap |= (rel >= a) & (rel < a + n)
    att = (Rotation.from_quat(traj.q_nb) * Rotation.from_quat(s.q_nb).inv()).as_rotvec()
    return {"out_rms": float(np.sqrt(np.mean(hor[gap] ** 2))) if gap.any() else np.nan,
            "out_max": float(hor[gap].max()) if gap.any() else np.nan,
            "h_rms": float(np.sqrt(np.mean(hor ** 2))),
            "att_deg": np.rad2deg(np.sqrt(np.mean(att ** 2, axis=0)))}


def run(name, preset, seed, keep):
    folder = Path(keep) / f"{name}_{seed}" if keep else Path(tempfile.mkdtemp())
    truth, journey, cfg = write_journey(name, folder, seed=seed)
    out = folder / f"out_{preset}"
    cmd = [str(Path(sys.executable).parent / "ins"), "process", "--config", str(cfg),
           "--preset", preset, "-o", str(out), "--force", "--forward", "--no-plots", "-q"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    line = f"{name:<13} {preset:<9} seed {seed}: exit {proc.returncode}"
    if not (out / "solution.nav").exists():
        msg = (proc.stderr.strip().splitlines() or [""])[-1][:150]
        print(f"{line}  (no solution) {msg}")
        return
    fw = figures(truth, journey, read_nav(out / "forward.nav"))
    sm = figures(truth, journey, read_nav(out / "solution.nav"))
    rej = ""
    for ln in proc.stdout.splitlines() + proc.stderr.splitlines():
        if "rejected" in ln:
            rej = ln.strip()[:90]
            break
    print(f"{line}  outages fwd RMS {fw['out_rms']:.2f} max {fw['out_max']:.2f} m | "
          f"smoothed RMS {sm['out_rms']:.2f} max {sm['out_max']:.2f} m | smoothed att "
          f"r/p/y {'/'.join(f'{x:.2f}' for x in sm['att_deg'])} deg  [{rej}]")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=1)
    p.add_argument("--keep", help="keep the scenario folders here")
    args = p.parse_args()
    for seed in range(args.seeds):
        for name, presets in (("consumer-car", ("mems", "land", "consumer")),
                              ("walk", ("mems", "consumer"))):
            for preset in presets:
                run(name, preset, seed, args.keep)


if __name__ == "__main__":
    main()
