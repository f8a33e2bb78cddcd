"""Throughput and peak memory of LiDAR georeferencing (issue 18).

1. Library: ``ins.lidar.georeference.georeference`` on N returns (default 10 million) in
   blocks of 250 000 (the CLI default), a 200 Hz trajectory of a straight 1000 s flight, trajectory
   sigmas and every scanner sigma on (the full kernel).
2. Command line: ``ins georeference`` on a CSV of N returns to LAZ and to LAS (a
   subprocess; peak RSS of the child from ``getrusage``).

Prints points/s and peak memory (MiB).  Usage::

    python bench/bench_georeference.py [--n 10000000] [--skip-cli]
"""
import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from ins.io.navfiles import write_nav
from ins.lidar.georeference import TrajectoryStd, georeference  # noqa: E402
from ins.lidar.scanner import Scanner, scanner_rays  # noqa: E402
from ins.nav.trajectory import Trajectory  # noqa: E402


def make_trajectory(duration_s=1000.0, rate_hz=200.0):
    n = int(duration_s * rate_hz) + 1
    t = 300000.0 + np.arange(n) / rate_hz
    lat0, lon0 = np.deg2rad(30.5), np.deg2rad(114.3)
    east = 60.0 * (t - t[0])
    lla = np.column_stack([np.full(n, lat0), lon0 + east / (6378137.0 * np.cos(lat0)),
                           np.full(n, 1000.0)])
    roll = np.deg2rad(2.0) * np.sin(0.5 * (t - t[0]))
    pitch = np.deg2rad(1.0) * np.sin(0.3 * (t - t[0]))
    from scipy.spatial.transform import Rotation
    q = Rotation.from_euler("ZYX", np.column_stack([np.full(n, np.pi / 2), pitch, roll])
                            ).as_quat()
    v = np.tile([0.0, 60.0, 0.0], (n, 1))
    return Trajectory(t, lla, v, q)


def peak_mib(who=resource.RUSAGE_SELF):
    return resource.getrusage(who).ru_maxrss / 1024.0


def bench_library(traj, n, block=250_000):
    sc = Scanner(range_sigma_m=0.02, scan_angle_sigma_rad=np.deg2rad(0.001),
                 lever_arm_m=[0.1, 0.05, 0.2], boresight_rad=np.deg2rad([0.01, 0.02, 0.03]),
                 lever_arm_sigma_m=[0.005] * 3, boresight_sigma_rad=np.deg2rad([0.003] * 3))
    std = TrajectoryStd(traj.time[[0, -1]], np.tile([0.02, 0.02, 0.04, 1e-4, 1e-4, 3e-4],
                                                    (2, 1)))
    rng = np.random.default_rng(0)
    t_span = traj.time[-1] - traj.time[0]
    # compile outside the timing
    georeference(traj, traj.time[:10] + 0.001, scanner_rays(np.full(10, 900.0), np.zeros(10)),
                 sc, std=std)
    start = time.perf_counter()
    done = 0
    while done < n:
        m = min(block, n - done)
        t = traj.time[0] + (done + np.arange(m)) * (t_span / n)
        r_s = scanner_rays(rng.uniform(900, 1200, m), rng.uniform(-0.5, 0.5, m))
        p = georeference(traj, t, r_s, sc, std=std)
        done += len(p.time)
    dt = time.perf_counter() - start
    print(f"library: {n} returns in {dt:.1f} s = {n / dt / 1e6:.2f} M points/s "
          f"(blocks of {block}); peak RSS {peak_mib():.0f} MiB")


def bench_cli(traj, n, folder):
    nav = os.path.join(folder, "t.nav")
    write_nav(nav, traj)
    scanner = os.path.join(ROOT, "data", "scanner", "example_scanner.toml")
    csv = os.path.join(folder, "returns.csv")
    rng = np.random.default_rng(1)
    t_span = traj.time[-1] - traj.time[0]
    start = time.perf_counter()
    with open(csv, "w") as f:
        f.write("time_s,range_m,scan_angle_deg\n")
        block = 1_000_000
        for s in range(0, n, block):
            m = min(block, n - s)
            t = traj.time[0] + (s + np.arange(m)) * (t_span / n)
            table = np.column_stack([t, rng.uniform(900, 1200, m), rng.uniform(-30, 30, m)])
            np.savetxt(f, table, fmt=["%.6f", "%.4f", "%.5f"], delimiter=",",
                       footer="", comments="")
    print(f"wrote {n} returns ({os.path.getsize(csv) / 2**20:.0f} MiB CSV) in "
          f"{time.perf_counter() - start:.1f} s")
    for ext in (".laz", ".las"):
        out = os.path.join(folder, "points" + ext)
        cmd = [sys.executable, "-m", "ins.cli.main", "georeference", "--trajectory", nav,
               "--scanner", scanner, csv, "-o", out, "-q"]
        start = time.perf_counter()
        before = peak_mib(resource.RUSAGE_CHILDREN)
        res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
        dt = time.perf_counter() - start
        if res.returncode:
            print(res.stderr)
            raise SystemExit(res.returncode)
        peak = peak_mib(resource.RUSAGE_CHILDREN)
        print(f"ins georeference -> {ext}: {n} returns in {dt:.1f} s = "
              f"{n / dt / 1e6:.2f} M points/s; child peak RSS {peak:.0f} MiB "
              f"(max over children so far; was {before:.0f}); "
              f"{os.path.getsize(out) / 2**20:.0f} MiB out")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000_000)
    ap.add_argument("--skip-cli", action="store_true")
    args = ap.parse_args()
    traj = make_trajectory()
    bench_library(traj, args.n)
    if not args.skip_cli:
        with tempfile.TemporaryDirectory() as folder:
            bench_cli(traj, args.n, folder)


if __name__ == "__main__":
    main()
