#!/usr/bin/env python3
"""Mechanization speed and memory, with pyins's Integrator on the same increments.

Prints, for the shared benchmark flight (1510 s, 200 Hz) and for a 1 h 200 Hz log:
- kernel throughput (epochs/s, warm: numba cache loaded, best of 5),
- pyins 1.0.1 on the same increments in the same run: ``Integrator.integrate`` (what
  a user calls) and its bare numba kernel ``pyins.strapdown.integrate``, and the ratios,
- whole ``ins mechanize`` runs (a fresh process each: import, read, mechanize, write
  .nav) from the text and the binary file: wall seconds and peak resident memory,
- for the flight, the error of the written .nav against the simulator's truth.

Usage: python bench/bench_mechanize.py [--data DIR] [--work DIR] [--repeat N]
The shared dataset is built with ../shared/bench/ins/make_dataset.py if DIR lacks it.
"""
import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ARCSEC = np.pi / 180.0 / 3600.0
sys.path.insert(0, str(ROOT / "tests"))


def _best(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def kernel_speed(log, init, repeat):
    from ins.nav import _kernels
    state0 = init.as_vector()
    out = np.empty((len(log) - 1, _kernels.N_STATE))

    def run():
        s = state0.copy()
        _kernels.mechanize_rows(log.time, log.dtheta_b, log.dvel_b, 1, len(log), s, out)
    run()
    return (len(log) - 1) / _best(run, repeat)


def pyins_speed(log, init_deg, repeat):
    import pandas as pd
    import pyins.strapdown as sd
    from pyins.util import TRAJECTORY_COLS
    imu = pd.DataFrame(np.hstack([log.dtheta_b, log.dvel_b]), index=pd.Index(log.time, name="time"),
                       columns=["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z"])
    inc = sd.compute_increments_from_imu(imu, "increment")
    pva = pd.Series(init_deg, index=TRAJECTORY_COLS)

    def integrator():
        sd.Integrator(pva).integrate(inc)
    integrator()
    t_int = _best(integrator, repeat)
    # bare kernel, on arrays prepared as Integrator does
    n = len(inc) + 1
    theta = np.ascontiguousarray(inc[["theta_x", "theta_y", "theta_z"]])
    dv = np.ascontiguousarray(inc[["dv_x", "dv_y", "dv_z"]])
    dt = np.asarray(inc.dt)
    from pyins import transform

    def bare():
        lla = np.empty((n, 3))
        vel = np.empty((n, 3))
        mat = np.empty((n, 3, 3))
        lla[0] = init_deg[:3]
        vel[0] = init_deg[3:6]
        mat[0] = transform.mat_from_rph(init_deg[6:9])
        sd.integrate(dt, lla, vel, mat, theta, dv, 0, True)
    bare()
    t_bare = _best(bare, repeat)
    return len(inc) / t_int, len(inc) / t_bare


_CHILD = """
import sys
from ins.cli.main import main
code = main(sys.argv[1:])
with open('/proc/self/status') as f:      # VmHWM: this process's own peak (reset at exec)
    hwm = [line.split()[1] for line in f if line.startswith('VmHWM')][0]
sys.stderr.write('VMHWM_KB ' + hwm + chr(10))
sys.exit(code)
"""


def end_to_end(imu_path, init_args, out_path, repeat):
    """Best wall time and the peak RSS (MB) of fresh ``ins mechanize`` processes.

    The peak is the child's own VmHWM: ``ru_maxrss`` of a child started from this
    (large) process would include the parent's memory copied at fork.
    """
    cmd = [sys.executable, "-c", _CHILD, "mechanize", str(imu_path), *init_args, "-q",
           "-o", str(out_path)]
    best, peak = np.inf, 0.0
    for _ in range(repeat):
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            raise SystemExit(f"ins mechanize failed on {imu_path}: {proc.stderr}")
        best = min(best, wall)
        kb = [ln.split()[1] for ln in proc.stderr.splitlines() if ln.startswith("VMHWM_KB")]
        peak = max(peak, float(kb[0]) / 1024.0)
    return best, peak


def one_hour_log(log, path_txt, path_bin):
    """A 1 h 200 Hz log: the benchmark flight's increments repeated, time continued."""
    from ins.io.imu_files import write_kfgins_binary, write_kfgins_text
    from ins.nav.imu import ImuLog
    n = 720_001
    reps = -(-n // len(log))
    t = log.time[0] + np.arange(n) * 0.005
    big = ImuLog(time=t, dtheta_b=np.tile(log.dtheta_b, (reps, 1))[:n],
                 dvel_b=np.tile(log.dvel_b, (reps, 1))[:n])
    if not path_txt.exists():
        write_kfgins_text(path_txt, big)
    if not path_bin.exists():
        write_kfgins_binary(path_bin, big)
    return big


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=ROOT / ".cache" / "ins-bench-data")
    ap.add_argument("--work", type=Path, default=ROOT / ".cache" / "bench")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    os.environ.setdefault("INS_BENCH_DATA", str(args.data))
    import benchdata
    data = args.data if (args.data / "meta.json").exists() else benchdata.ensure_bench_data()
    if data is None:
        raise SystemExit(f"no benchmark data in {args.data} and no shared script under "
                         f"{benchdata.SHARED}")
    from ins.io.imu_files import read_kfgins_text, write_kfgins_binary
    from ins.nav.mechanization import NavState

    args.work.mkdir(parents=True, exist_ok=True)
    meta = json.loads((data / "meta.json").read_text())
    x = meta["init_exact"]
    init_deg = np.array([x["lat"], x["lon"], x["alt"], x["VN"], x["VE"], x["VD"],
                         x["roll"], x["pitch"], x["yaw"]])
    init = NavState.from_degrees(*init_deg[:3], init_deg[3:6], init_deg[6:9])
    init_args = ["--init-lla", ",".join(repr(float(v)) for v in init_deg[:3]),
                 "--init-vel", ",".join(repr(float(v)) for v in init_deg[3:6]),
                 "--init-att", ",".join(repr(float(v)) for v in init_deg[6:9])]

    flight_txt = data / "imu_clean.txt"
    flight = read_kfgins_text(flight_txt)
    flight_bin = args.work / "imu_clean.bin"
    if not flight_bin.exists():
        write_kfgins_binary(flight_bin, flight)
    hour_txt, hour_bin = args.work / "imu_1h.txt", args.work / "imu_1h.bin"
    hour = one_hour_log(flight, hour_txt, hour_bin)

    print(f"python {sys.version.split()[0]}, numpy {np.__version__}, {os.cpu_count()} cores")
    rows = []
    for name, log, txt, binf in [("benchmark flight 1510 s", flight, flight_txt, flight_bin),
                                 ("1 h at 200 Hz", hour, hour_txt, hour_bin)]:
        ours = kernel_speed(log, init, 5)
        p_int, p_bare = pyins_speed(log, init_deg, 3)
        e_txt, m_txt = end_to_end(txt, init_args, args.work / "out_txt.nav", args.repeat)
        e_bin, m_bin = end_to_end(binf, init_args, args.work / "out_bin.nav", args.repeat)
        rows.append((name, len(log), ours, p_int, p_bare, e_txt, m_txt, e_bin, m_bin))
        print(f"\n{name}: {len(log)} epochs")
        print(f"  kernel (ins.nav._kernels.mechanize_rows)  {ours / 1e6:6.2f} M epochs/s")
        print(f"  pyins Integrator.integrate            {p_int / 1e6:6.2f} M epochs/s"
              f"   ratio ours/pyins {ours / p_int:5.1f}x")
        print(f"  pyins bare kernel strapdown.integrate {p_bare / 1e6:6.2f} M epochs/s"
              f"   ratio ours/pyins {ours / p_bare:5.1f}x")
        print(f"  ins mechanize from text   {e_txt:6.2f} s   peak RSS {m_txt:6.0f} MB")
        print(f"  ins mechanize from binary {e_bin:6.2f} s   peak RSS {m_bin:6.0f} MB")
        if log is flight:                  # accuracy of the written .nav against the truth
            from ins.io.navfiles import read_nav
            from ins.nav.accuracy import compare
            err = compare(read_nav(args.work / "out_txt.nav"), read_nav(data / "truth.nav"))
            att = np.max(np.linalg.norm(err.att_n, axis=1)) / ARCSEC
            print(f"  error at {err.time[-1] - err.time[0]:.0f} s: horizontal "
                  f"{1e3 * err.horizontal[-1]:.4f} mm, down {1e3 * err.pos_n[-1, 2]:.4f} mm, "
                  f"max attitude {att:.1e} arcsec (KF-GINS: 8.3 mm / 54 mm / 2e-4 arcsec)")
    print("\nTargets: kernel >= 3x pyins Integrator; 1510 s text log < 2 s end to end; "
          "1 h of 200 Hz < 300 MB.")


if __name__ == "__main__":
    main()
