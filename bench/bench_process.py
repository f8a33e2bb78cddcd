#!/usr/bin/env python3
"""GNSS/INS post-processing on the shared benchmark flight, beside the peers' figures.

Runs ``ins.estimation.process`` (forward filter + RTS smoother) on the shared dataset
(../shared/bench/ins, built once into .cache/ins-bench-data) with the noise settings
and the perturbed start that every peer is given (meta.json), and prints, in the layout
of that README (errors from its own peerlib over [t0 + 60 s, end]):

- forward and smoothed position / attitude RMS and max, beside KF-GINS and pyins,
- the smoothed heading RMS over the whole flight,
- the horizontal error at the end of each 60 s outage (gnss_outage.txt),
- the covariance step: 1 s against 0.1 s (the accuracy it costs),
- speed: read + forward + smoother in-process, and whole ``ins process`` runs (a fresh
  process each, numba cache warm): wall seconds and peak resident memory (VmHWM),
- with ``--with-pyins``, pyins's ``run_feedback_filter`` (1 s step) in the same run.

Usage: python bench/bench_process.py [--data DIR] [--repeat N] [--with-pyins] [--quick]
[--layout kfgins|survey]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

KFGINS = {"wall": 5.3, "pos_rms": (0.0104, 0.0096, 0.0183), "att_rms": (4.1, 4.4, 107.0),
          "pos_max": (0.040, 0.039, 0.059), "outage_end_h": (0.087, 0.374, 0.469)}
PYINS = {"wall": 18.8, "pos_rms": (0.0104, 0.0096, 0.0183), "att_rms": (4.1, 4.4, 104.0)}


def _peerlib(shared):
    sys.path.insert(0, str(shared / "bench" / "ins"))
    import peerlib
    return peerlib


#: Error-state layout of the runs (``--layout``): the peers' 21 states by default.
LAYOUT = "kfgins"


def config_for(data, gnss_file, node_interval_s=1.0):
    from ins.estimation.error_model import LAYOUTS, ImuNoise, StateLayout
    from ins.estimation.process_config import ProcessConfig
    meta = json.loads((data / "meta.json").read_text())
    fn, ini, st = meta["filter_noise"], meta["init_filter"], meta["init_std"]
    noise = ImuNoise(fn["arw_dpsh"], fn["vrw_mpsph"], fn["gyro_bias_std_dph"],
                     fn["accel_bias_std_mgal"], fn["scale_std_ppm"], fn["scale_std_ppm"],
                     fn["corr_time_h"])
    initial = {"lat_deg": ini["lat"], "lon_deg": ini["lon"], "h_m": ini["alt"],
               "vel_ned_mps": np.array([ini["VN"], ini["VE"], ini["VD"]]),
               "rpy_deg": np.array([ini["roll"], ini["pitch"], ini["yaw"]]),
               "pos_std_ned_m": np.full(3, st["pos"]), "vel_std_ned_mps": np.full(3, st["vel"]),
               "att_std_deg": np.array([st["level"], st["level"], st["azimuth"]])}
    return ProcessConfig(imu=str(data / "imu_noisy.txt"), gnss=str(data / gnss_file),
                         noise=noise, lever_bp=np.array(meta["lever_arm_frd"], float),
                         initial=initial, node_interval_s=node_interval_s,
                         layout=StateLayout(LAYOUTS[LAYOUT])), meta


def frame(peerlib, traj):
    import pandas as pd
    rows = traj.nav_rows()
    return pd.DataFrame(rows[:, 2:], index=pd.Index(rows[:, 1], name="time"),
                        columns=peerlib.TRAJ_COLS)


def report(peerlib, truth, meta, name, df):
    err = peerlib.nav_errors(df, truth)
    t0 = truth.index[0]
    rep = peerlib.filter_report(err, t0)
    whole = peerlib.filter_report(err, t0, settle=0.0)
    t_turn = meta["turn_starts"][0] + meta["turn_time"]
    after = peerlib.filter_report(err, t0, settle=t_turn)
    outages = peerlib.outage_report(err, meta["outages_sim_time"], t0)
    return {"name": name, "rep": rep, "whole": whole, "after": after, "outages": outages}


def _fmt(r):
    p, w = r["rep"], r["whole"]
    rms = "/".join(f"{p[f'pos_{c}_m']['rms']:.4f}" for c in ("north", "east", "down"))
    mx = "/".join(f"{p[f'pos_{c}_m']['max']:.3f}" for c in ("north", "east", "down"))
    att = "/".join(f"{p[f'att_{c}_arcsec']['rms']:.1f}" for c in ("roll", "pitch", "heading"))
    aft = "/".join(f"{r['after']['att_' + c + '_arcsec']['rms']:.1f}"
                   for c in ("roll", "pitch", "heading"))
    return (f"| {r['name']} | {rms} | {mx} | {att} | {aft} | "
            f"{w['att_heading_arcsec']['rms']:.1f} |")


def accuracy(args, peerlib, truth, data):
    from ins.estimation.process import process
    out = {}
    print("\nGNSS/INS filter, noisy IMU, perturbed start, errors over [t0+60 s, end] "
          "(README layout)")
    print("| | pos RMS N/E/D (m) | pos max N/E/D (m) | att RMS r/p/y (arcsec) | "
          "same after first turn | heading RMS whole flight |")
    print("|---|---|---|---|---|---|")
    k, p = KFGINS, PYINS
    print(f"| KF-GINS (README) | {'/'.join(map(str, k['pos_rms']))} | "
          f"{'/'.join(map(str, k['pos_max']))} | {'/'.join(map(str, k['att_rms']))} | "
          f"2.1/2.2/17.7 | (up to 540 before the 1st turn) |")
    print(f"| pyins (README) | same to 0.1 mm | same | {'/'.join(map(str, p['att_rms']))} | "
          f"2.1/2.2/17.4 | |")
    for gnss_file in ("gnss.txt", "gnss_outage.txt"):
        cfg, meta = config_for(data, gnss_file)
        res = process(cfg)
        rows = [report(peerlib, truth, meta, f"ours forward ({gnss_file})",
                       frame(peerlib, res.forward)),
                report(peerlib, truth, meta, f"ours smoothed ({gnss_file})",
                       frame(peerlib, res.smoothed))]
        for r in rows:
            print(_fmt(r))
        out[gnss_file] = rows
        print(f"|   counts: {res.counts} |")
    print("\nOutages (gnss_outage.txt): horizontal / down error at the end of each (m)")
    print("| | 400-460 s | 880-940 s | 1300-1360 s |")
    print("|---|---|---|---|")
    print("| KF-GINS (README) | 0.087/0.047 | 0.374/0.070 | 0.469/-0.182 |")
    for r in out["gnss_outage.txt"]:
        print(f"| {r['name']} | " + " | ".join(
            f"{o['end_horizontal_m']:.4f}/{o['end_down_m']:.4f}" for o in r["outages"]) + " |")
    return out


def rate_check(peerlib, truth, data):
    from ins.estimation.process import process
    print("\nCovariance step (node interval): accuracy it costs (gnss_outage.txt, smoothed "
          "and forward pos RMS N/E/D mm, heading RMS arcsec)")
    for dt in (1.0, 0.1):
        cfg, meta = config_for(data, "gnss_outage.txt", node_interval_s=dt)
        t = time.perf_counter()
        res = process(cfg)
        wall = time.perf_counter() - t
        for name, traj in (("forward", res.forward), ("smoothed", res.smoothed)):
            r = report(peerlib, truth, meta, name, frame(peerlib, traj))["rep"]
            print(f"  step {dt:>4} s {name:<9}: " + "/".join(
                f"{1e3 * r[f'pos_{c}_m']['rms']:.2f}" for c in ("north", "east", "down"))
                + f" mm, heading {r['att_heading_arcsec']['rms']:.2f} arcsec"
                + f", outage ends {[round(o['end_horizontal_m'], 4) for o in peerlib.outage_report(peerlib.nav_errors(frame(peerlib, traj), truth), meta['outages_sim_time'], truth.index[0])]}"
                + f"  ({res.counts['nodes']} nodes, {wall:.2f} s)")


def speed(args, data):
    from ins.estimation.process import process
    cfg, _ = config_for(data, "gnss.txt")
    process(cfg)                                   # warm the numba cache
    best = []
    for _ in range(args.repeat):
        t = time.perf_counter()
        process(cfg)
        best.append(time.perf_counter() - t)
    print(f"\nSpeed, 302 001 epochs, in-process read + forward + smoother: best "
          f"{min(best):.2f} s of {args.repeat} (KF-GINS forward only, whole process: "
          f"{KFGINS['wall']} s; target <= {KFGINS['wall'] / 2:.2f} s)")
    cfg_path = ROOT / "data" / "configs" / "kfgins_like.toml"
    with tempfile.TemporaryDirectory() as tmp:
        for extra, label in ((["--no-plots"], "ins process (writes solution.nav + sigma + "
                                              "biases, no plots)"),
                             (["--no-plots", "--forward"], "ins process --forward (also "
                                                           "forward.nav, no plots)"),
                             ([], "ins process with PNG plots")):
            walls, rss, cpu = [], [], []
            for _ in range(args.repeat):
                cmd = [sys.executable, "-c", _CHILD, "--imu", str(data / "imu_noisy.txt"),
                       "--gnss", str(data / "gnss.txt"), "--config", str(cfg_path), "-q",
                       "-o", tmp, "--force"] + extra
                t = time.perf_counter()
                proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
                walls.append(time.perf_counter() - t)
                if proc.returncode != 0:
                    print(proc.stderr)
                    raise SystemExit("ins process failed")
                last = proc.stderr.strip().splitlines()[-1].split()
                rss.append(int(last[0]))
                cpu.append(float(last[1]))
            print(f"{label}: wall median {np.median(walls):.2f} s (min {min(walls):.2f}), "
                  f"CPU (user + sys, all threads) median {np.median(cpu):.2f} s, "
                  f"peak RSS {max(rss) / 1024:.0f} MB, load average "
                  f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


# The child runs the CLI and reports its own peak RSS (VmHWM, kB) on the last stderr line.
_CHILD = """
import sys
from ins.cli.main import main
code = main(['process'] + sys.argv[1:])
import os
t = os.times()
for line in open('/proc/self/status'):
    if line.startswith('VmHWM'):
        sys.stderr.write(line.split()[1] + ' ' + str(t.user + t.system) + '\\n')
sys.exit(code)
"""


def with_pyins(peerlib, truth, data):
    import pandas as pd
    from pyins import filters, inertial_sensor, measurements, strapdown
    meta = json.loads((data / "meta.json").read_text())
    fn, ini, st = meta["filter_noise"], meta["init_filter"], meta["init_std"]
    imu = peerlib.load_imu(str(data / "imu_noisy.txt"))
    gnss = peerlib.load_gnss(str(data / "gnss_outage.txt"))
    t = time.perf_counter()
    inc = strapdown.compute_increments_from_imu(imu, "increment")
    pva = pd.Series({"lat": ini["lat"], "lon": ini["lon"], "alt": ini["alt"], "VN": ini["VN"],
                     "VE": ini["VE"], "VD": ini["VD"], "roll": ini["roll"],
                     "pitch": ini["pitch"], "heading": ini["yaw"]}, name=float(imu.index[0]))
    tau = fn["corr_time_h"] * 3600
    gb, ab = np.deg2rad(fn["gyro_bias_std_dph"]) / 3600, fn["accel_bias_std_mgal"] * 1e-5
    gyro = inertial_sensor.EstimationModel(bias_sd=gb, noise=np.deg2rad(fn["arw_dpsh"]) / 60,
                                           bias_walk=gb * np.sqrt(2 / tau))
    accel = inertial_sensor.EstimationModel(bias_sd=ab, noise=fn["vrw_mpsph"] / 60,
                                            bias_walk=ab * np.sqrt(2 / tau))
    pos = measurements.Position(gnss[["lat", "lon", "alt"]], np.array(meta["gnss_std_ned"]),
                                np.array(meta["lever_arm_frd"]))
    result = filters.run_feedback_filter(pva, st["pos"], st["vel"], st["level"], st["azimuth"],
                                         inc, gyro, accel, [pos], time_step=1.0)
    wall = time.perf_counter() - t
    r = report(peerlib, truth, meta, f"pyins run_feedback_filter 1 s step ({wall:.1f} s)",
               result.trajectory)
    print(_fmt(r))
    print("| pyins outage ends | " + " | ".join(
        f"{o['end_horizontal_m']:.4f}/{o['end_down_m']:.4f}" for o in r["outages"]) + " |")


def lever_arm_tables(folder):
    """The lever-arm paper's Tables 1 and 2: position and attitude errors of the
    varying-arm compensation (method 1) and the constant arm l_bp + l_ap (method 2)."""
    from test_filter import given_config

    from ins.estimation.process import process
    from ins.io.navfiles import read_nav
    arcsec = np.pi / 180 / 3600
    rows = {}
    for method, varying in (("1 varying arm", True), ("2 constant arm", False)):
        t = time.perf_counter()
        res = process(given_config(folder, varying=varying))
        truth = read_nav(Path(folder) / "truth.nav")
        for kind in ("forward", "smoothed"):
            e = getattr(res, f"errors_{kind}")
            sel = e.time > e.time[0] + 60.0
            traj = getattr(res, kind)
            k = np.searchsorted(truth.time, e.time[sel] - 1e-7)
            i = np.searchsorted(traj.time, e.time[sel] - 1e-7)
            d_rpy = traj.rpy()[i] - truth.rpy()[k]            # Euler differences, wrapped
            d_rpy = (d_rpy + np.pi) % (2 * np.pi) - np.pi
            rows[(method, kind)] = (e.pos_n[sel], d_rpy / arcsec)
        print(f"  method {method}: {time.perf_counter() - t:.1f} s, counts {res.counts}")
    print("\nTable 1  position error (m): RMS / max |.|, north (latitude), east (longitude), "
          "height")
    print("| method | pass | north | east | height |")
    print("|---|---|---|---|---|")
    for (method, kind), (pos, _) in rows.items():
        print(f"| {method} | {kind} | " + " | ".join(
            f"{np.sqrt(np.mean(pos[:, i] ** 2)):.4f} / {np.max(np.abs(pos[:, i])):.4f}"
            for i in range(3)) + " |")
    print("\nTable 2  attitude error (arcsec): RMS / max |.| of the Euler-angle differences")
    print("| method | pass | heading | pitch | roll |")
    print("|---|---|---|---|---|")
    for (method, kind), (_, att) in rows.items():
        print(f"| {method} | {kind} | " + " | ".join(
            f"{np.sqrt(np.mean(att[:, i] ** 2)):.1f} / {np.max(np.abs(att[:, i])):.1f}"
            for i in (2, 1, 0)) + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default=None, help="dataset folder (default: the cache)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--with-pyins", action="store_true", help="also run pyins's filter")
    ap.add_argument("--flight", default=None,
                    help="flight folder with mount motion for the lever-arm tables "
                         "(default: the tests' short simulated flight)")
    ap.add_argument("--quick", action="store_true", help="accuracy only (no 0.1 s step, "
                                                         "no subprocess timings)")
    ap.add_argument("--layout", default="kfgins", choices=["kfgins", "survey"],
                    help="error states of the in-process runs (the subprocess timings use "
                         "data/configs/kfgins_like.toml: kfgins)")
    args = ap.parse_args()
    global LAYOUT
    LAYOUT = args.layout
    print(f"layout: {LAYOUT}")
    from benchdata import SHARED, ensure_bench_data
    data = Path(args.data) if args.data else ensure_bench_data()
    if data is None:
        raise SystemExit("the shared dataset script is missing (../shared/bench/ins)")
    peerlib = _peerlib(SHARED)
    truth = peerlib.load_nav(str(data / "truth.nav"))
    accuracy(args, peerlib, truth, data)
    if args.with_pyins:
        print("\npyins in the same run (gnss_outage.txt):")
        with_pyins(peerlib, truth, data)
    if not args.quick:
        from test_filter import short_flight
        folder = Path(args.flight) if args.flight else short_flight()
        print(f"\nVarying against constant lever arm (the lever-arm paper), {folder}, "
              f"errors after 60 s, true initial state:")
        lever_arm_tables(folder)
        rate_check(peerlib, truth, data)
        speed(args, data)


if __name__ == "__main__":
    main()
