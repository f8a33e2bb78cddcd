"""Start-up of the command-line tools: wall time and peak resident memory of
``photogrammetry --help``, ``photogrammetry refine --help``, ``ins --help``,
``ins simulate --help`` and ``ins process --help``, each run as a subprocess of the
environment's console scripts.

The peak RSS is the child's own (``os.wait4``: the ``resource.getrusage`` record of that
child, ``ru_maxrss``), in MiB; the wall time runs from the start of the process to its
exit.  Each command runs ``--repeat`` times (default 5); the first run is shown apart
(it may read cold files or write byte-code caches), then the median of the others.

    .venv/bin/python bench/bench_startup.py [--bin DIR] [--repeat N]

``--bin`` is the folder of the console scripts (default: that of this interpreter), so
that another environment (another checkout's ``.venv/bin``) is measured the same way.

Measured 2026-12-01 (2-core VM at load 8, fresh clones before and after issue 35 in
their own environments, runs interleaved; wall s median / peak MiB median):

    command                        numba kernels    Cython kernels
    photogrammetry --help           0.66 / 29.7      0.67 / 29.6
    photogrammetry refine --help    0.67 / 29.7      0.58 / 29.6
    ins --help                      0.82 / 31.7      0.71 / 31.4
    ins simulate --help             0.79 / 31.7      0.64 / 31.5
    ins process --help              0.84 / 31.7      0.57 / 31.4

(a second pair of runs: 0.47-0.76 s before, 0.64-0.87 s after): the same within the
noise.  None of these loads numba, scipy or a compiled kernel (numpy only, on both
sides); the kernels' effect is on the first real run (README, "The demo").
"""
import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

COMMANDS = (("photogrammetry", "--help"), ("photogrammetry", "refine", "--help"),
            ("ins", "--help"), ("ins", "simulate", "--help"), ("ins", "process", "--help"))


def run_once(argv):
    """(wall s, peak RSS MiB, exit status) of one run of ``argv``."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    scale = 1.0 / 1024.0 if sys.platform != "darwin" else 1.0 / 1024.0 ** 2   # KiB or bytes
    return wall, usage.ru_maxrss * scale, proc.returncode


def measure(bin_dir, repeat):
    """One row per command: (command, first wall, median wall, first RSS, median RSS)."""
    rows = []
    for cmd in COMMANDS:
        argv = [str(Path(bin_dir) / cmd[0]), *cmd[1:]]
        runs = [run_once(argv) for _ in range(repeat)]
        bad = [r[2] for r in runs if r[2] != 0]
        if bad:
            raise SystemExit(f"{' '.join(cmd)}: exit status {bad[0]}")
        rest = runs[1:] or runs
        rows.append((" ".join(cmd), runs[0][0], statistics.median(r[0] for r in rest),
                     runs[0][1], statistics.median(r[1] for r in rest)))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", default=str(Path(sys.executable).parent),
                    help="folder of the console scripts ins and photogrammetry")
    ap.add_argument("--repeat", type=int, default=5, help="runs per command (default 5)")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        ap.error("--repeat must be >= 1")
    rows = measure(args.bin, args.repeat)
    print(f"console scripts of {args.bin}; {args.repeat} runs per command")
    print(f"{'command':32s} {'first s':>8s} {'median s':>9s} {'first MiB':>10s} "
          f"{'median MiB':>11s}")
    for name, w0, w, m0, m in rows:
        print(f"{name:32s} {w0:8.3f} {w:9.3f} {m0:10.1f} {m:11.1f}")


if __name__ == "__main__":
    main()
