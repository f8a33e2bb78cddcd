#!/usr/bin/env python3
"""GNSS/INS post-processing on the shared benchmark flight, beside the peers' figures.

Runs ``ins.estimation.pipeline.process`` (forward filter + RTS smoother) on the shared dataset
(../shared/bench/ins, built once into .cache/ins-bench-data) with the noise settings
and the perturbed start that every peer is given (meta.json), and prints, in the layout
of that README (errors from its own peerlib over [t0 + 60 s, end]):

- forward and smoothed position / attitude RMS and max, beside KF-GINS and pyins,
- the smoothed heading RMS over the whole flight,
- the horizontal error at the end of each 60 s outage (gnss_outage.txt),
- the covariance step: 1 s against 0.1 s (the accuracy it costs),
- speed: whole ``ins process`` runs (a fresh process each, no plots)
  with 21, 27 (the default layout) and 31 error states beside KF-GINS in the same run
  (``--kfgins BIN``, else its README figure): wall and CPU seconds, peak resident
  memory (GNU time's %M); with ``--gnss-hz 4,10`` also with GNSS at those rates (files
  built from truth.nav) and the cost per GNSS epoch; then the cost per IMU epoch and
  per node against the number of states (whole runs in-process, and the compiled node
  kernels alone up to 45),
- with ``--with-pyins``, pyins's ``run_feedback_filter`` (1 s step) in the same run.

Usage: python bench/bench_process.py [--data DIR] [--repeat N] [--with-pyins] [--quick]
[--layout kfgins|survey] [--kfgins BIN] [--speed-only] [--speed-layouts kfgins,survey]
[--gnss-hz 4,10] [--no-cost]

KF-GINS (GPL-3, not vendored): clone i2Nav-WHU/KF-GINS and build it against Debian's
Eigen, yaml-cpp and abseil with ``tools/build_kfgins.sh SRC_DIR BUILD_DIR``; then
``--kfgins BUILD_DIR/bin/KF-GINS`` (or ``KFGINS_BIN``).
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
    from ins.estimation.core.error_model import LAYOUTS, ImuNoise, StateLayout
    from ins.estimation.pipeline.config import ProcessConfig
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
    from ins.estimation.pipeline.process import process
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
        kf_rows = []
        if args.kfgins:                         # the peer's figures from this run
            with tempfile.TemporaryDirectory() as tmp:
                cmd = _kfgins_command(args.kfgins, data, tmp, gnss_file)
                _run_child(cmd)
                nav = (Path(tmp) / f"kfgins_out_{Path(gnss_file).stem}"
                       / "KF_GINS_Navresult.nav")
                kf_rows = [report(peerlib, truth, meta, f"KF-GINS this run ({gnss_file})",
                                  peerlib.load_nav(str(nav)))]
        res = process(cfg)
        rows = kf_rows + [report(peerlib, truth, meta, f"ours forward ({gnss_file})",
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
    from ins.estimation.pipeline.process import process
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


#: The layouts of the speed tables: (name, [states] lines of the config, label).
SPEED_LAYOUTS = (("kfgins", 'layout = "kfgins"', "21 (KF-GINS)"),
                 ("survey", 'layout = "survey"', "27 (default: survey)"),
                 ("survey+la+to", 'layout = "survey"\nlever_arm = true\ntime_offset = true',
                  "31 (+ lever arm, time offset)"))


def _layout_config(tmp, name, states):
    """data/configs/kfgins_like.toml with its [states] table replaced."""
    text = (ROOT / "data" / "configs" / "kfgins_like.toml").read_text()
    head, _, tail = text.partition("[states]")
    tail = tail[tail.index("\n[") if "\n[" in tail else len(tail):]
    path = Path(tmp) / f"config_{name}.toml"
    path.write_text(head + "[states]\n" + states + "\n" + tail)
    return path


#: GNU time (Debian package ``time``): the child's peak RSS without this process's.
GNU_TIME = "/usr/bin/time" if os.access("/usr/bin/time", os.X_OK) else None


def _run_child(cmd):
    """Run ``cmd``; (wall s, CPU s of the child, peak RSS MiB of the child).

    Linux's ``ru_maxrss`` of a child started from this process counts this process's
    own resident set at the fork (KF-GINS, 5 MiB, showed 33 MiB, this script's size after
    numpy's import; ``/bin/true`` started by a Python holding 480 MiB shows 485 MiB), so
    the child runs under GNU time, forked from that small process, and its %M is the
    child's own peak. Without GNU time, wait4's figure is printed as an upper bound."""
    t = time.perf_counter()
    with tempfile.TemporaryFile() as err, tempfile.NamedTemporaryFile("r") as rep:
        full = [GNU_TIME, "-q", "-o", rep.name, "-f", "%U %S %M"] + cmd if GNU_TIME else cmd
        proc = subprocess.Popen(full, stdout=subprocess.DEVNULL, stderr=err, cwd=ROOT)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t
        if os.waitstatus_to_exitcode(status) != 0:
            err.seek(0)
            print(err.read().decode(errors="replace")[-2000:])
            raise SystemExit(f"failed: {' '.join(map(str, cmd))}")
        if GNU_TIME:
            user, system, rss_kib = rep.read().split()[-3:]
            return wall, float(user) + float(system), float(rss_kib) / 1024.0
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


#: Key of the KF-GINS runs (not a layout name).
PEER = "KF-GINS"


def _peer_key(hz):
    """Run key of KF-GINS on the GNSS file at ``hz``."""
    return PEER if hz == 1 else f"{PEER}@{hz:g}"


def _kfgins_command(binary, data, tmp, gnss_file="gnss.txt"):
    """KF-GINS on the dataset's kfgins_gnss.yaml with its input paths pointed at ``data``
    (the files ours reads, wherever the folder now is) and its output into ``tmp``
    (beside ours: the same disk, the dataset folder untouched)."""
    path = Path(binary)
    if not (path.is_file() and os.access(path, os.X_OK)):
        raise SystemExit(f"--kfgins {binary}: not an executable file (build one with "
                         f"tools/build_kfgins.sh SRC_DIR BUILD_DIR)")
    src = data / "kfgins_gnss.yaml"                # the outage file differs in gnsspath only
    if not src.is_file():
        raise SystemExit(f"{src}: missing (the dataset is made by make_dataset.py)")
    out = Path(tmp) / f"kfgins_out_{Path(gnss_file).stem}"
    out.mkdir()
    paths = {"imupath": data / "imu_noisy.txt", "gnsspath": data / gnss_file,
             "outputpath": out}                 # ours reads the same two files
    lines = [f'{line.split(":")[0]}: "{paths[line.split(":")[0]]}"'
             if line.split(":")[0] in paths else line
             for line in src.read_text().splitlines()]
    yaml = Path(tmp) / f"kfgins_{Path(gnss_file).stem}.yaml"
    yaml.write_text("\n".join(lines) + "\n")
    return [str(path.resolve()), str(yaml)]


def _medians(runs):
    """(median wall, median CPU, max peak RSS, min wall) of ``_run_child`` results."""
    return (float(np.median([r[0] for r in runs])), float(np.median([r[1] for r in runs])),
            max(r[2] for r in runs), min(r[0] for r in runs))


#: Lever arm of the GNSS files built at other rates (``--gnss-hz``), IMU to antenna, b
#: frame, m, and their noise (N, E, D sigmas, m): those of the dataset's gnss.txt.
RATE_LEVER_B_M = (0.8, 0.2, -1.5)
RATE_SIGMA_NED_M = (0.02, 0.02, 0.05)


def gnss_at_rate(data, hz, path, seed=1):
    """A GNSS position file at ``hz`` from the dataset's truth.nav (every truth epoch
    on the grid of ``1/hz`` s from the first whole second after its start): antenna =
    IMU position + ``C_nb`` :data:`RATE_LEVER_B_M` (through ``D^-1``) plus white noise of
    :data:`RATE_SIGMA_NED_M`; the columns of gnss.txt (time, lat, lon deg, h m, sigmas)."""
    from ins.estimation.core.lever_arm import antenna_lla
    from ins.nav import earth
    from ins.nav.rotation import euler_to_dcm
    nav = np.loadtxt(data / "truth.nav", usecols=range(1, 11))
    t = nav[:, 0]
    step = int(round(1.0 / hz / np.median(np.diff(t))))
    k0 = int(np.searchsorted(t, np.floor(t[0]) + 1.0 - 1e-6))
    nav = nav[k0::step]
    lla = np.column_stack([np.deg2rad(nav[:, 1:3]), nav[:, 3]])
    C_nb = euler_to_dcm(nav[:, 7:10], degrees=True)
    ant = np.array([antenna_lla(p, C, np.array(RATE_LEVER_B_M)) for p, C in zip(lla, C_nb)])
    noise = np.random.default_rng(seed).normal(size=(len(ant), 3)) * RATE_SIGMA_NED_M
    ant += earth.lla_rate(ant[:, 0], ant[:, 2], noise)
    sig = " ".join(f"{v:.3f}" for v in RATE_SIGMA_NED_M)
    with open(path, "w") as f:
        for ti, (lat, lon, h) in zip(nav[:, 0], ant):
            f.write(f"{ti:.3f} {np.rad2deg(lat):.12f} {np.rad2deg(lon):.12f} {h:.5f} {sig}\n")
    return path


def speed(args, data):
    """Whole ``ins process`` runs (fresh process each, no plots)
    beside KF-GINS in the same run (``--kfgins BIN``; else its README figure), then the
    cost per epoch and per node against the number of error states.

    The runs are interleaved (KF-GINS, then each layout, ``--repeat`` times, after one
    unmeasured run of each: the page cache warm), so a change of the
    shared machine's load falls on both sides of the ratio."""
    layouts = [entry for entry in SPEED_LAYOUTS if entry[0] in args.speed_layouts]
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        commands = []
        gnss = {1: data / "gnss.txt"}
        for hz in args.gnss_hz:                      # GNSS at other rates (--gnss-hz)
            gnss[hz] = gnss_at_rate(data, hz, Path(tmp) / f"gnss_{hz:g}hz.txt")
        epochs = {hz: sum(1 for _ in open(gfile)) for hz, gfile in gnss.items()}
        if args.kfgins:                              # the peer on the same GNSS files
            for hz, gfile in gnss.items():
                commands.append((_peer_key(hz), _kfgins_command(args.kfgins, data, tmp,
                                                                gnss_file=str(gfile))))
        for name, states, _ in layouts:
            cfg = _layout_config(tmp, name, states)
            for hz, gfile in gnss.items():
                key = name if hz == 1 else f"{name}@{hz:g}"
                commands.append((key, [sys.executable, "-m", "ins.cli.main", "process",
                                       "--imu", str(data / "imu_noisy.txt"), "--gnss",
                                       str(gfile), "--config", str(cfg), "-q", "-o",
                                       str(Path(tmp) / f"out_{key}"), "--force",
                                       "--no-plots"]))
        for _, cmd in commands:                      # warm: page cache
            _run_child(cmd)
        runs = {name: [] for name, _ in commands}
        for _ in range(args.repeat):
            for name, cmd in commands:
                runs[name].append(_run_child(cmd))
    load1 = os.getloadavg()
    print(f"\nSpeed, {data}: whole processes, interleaved, wall and CPU (user + sys) "
          f"medians of {args.repeat}, peak RSS (MiB) max "
          f"{'(GNU time %M)' if GNU_TIME else '(wait4: upper bound, counts this process)'}; "
          f"load average "
          f"{load0[0]:.1f} before, {load1[0]:.1f} after, on {os.cpu_count()} cores")
    print("| run | states | wall s (min) | CPU s | peak RSS MiB | wall / KF-GINS | "
          "CPU / KF-GINS |")
    print("|---|---|---|---|---|---|---|")
    peer = {}                                        # GNSS rate -> (wall, CPU) of KF-GINS
    for hz in [1] + list(args.gnss_hz):
        if args.kfgins:
            kw, kc, krss, kmin = _medians(runs[_peer_key(hz)])
            print(f"| KF-GINS (this run; forward EKF, writes nav, IMU errors and std at "
                  f"200 Hz), GNSS {hz:g} Hz | 21 | {kw:.2f} ({kmin:.2f}) | {kc:.2f} | "
                  f"{krss:.1f} | 1.00 | 1.00 |")
        elif hz == 1:
            kw, kc, krss, kmin = KFGINS["wall"], float("nan"), 4.7, KFGINS["wall"]
            print(f"| KF-GINS (README figure, not run: --kfgins BIN), GNSS 1 Hz | 21 | "
                  f"{kw:.2f} | - | {krss:.1f} | 1.00 | - |")
        else:
            kw = kc = float("nan")
        peer[hz] = kw, kc
    for name, _, label in layouts:
        for hz in [1] + list(args.gnss_hz):
            key = name if hz == 1 else f"{name}@{hz:g}"
            w, c, rss, wmin = _medians(runs[key])
            kw, kc = peer[hz]                        # against KF-GINS on the same GNSS
            print(f"| ins process (forward + smoother, no plots), GNSS {hz:g} Hz | {label} | "
                  f"{w:.2f} ({wmin:.2f}) | {c:.2f} | {rss:.1f} | {w / kw:.2f} | "
                  f"{c / kc:.2f} |")
    if args.gnss_hz:
        base = {name: _medians(runs[name])[1] for name, _, _ in layouts}
        print("\nCost per GNSS epoch (a filter node and a position update), from the CPU "
              "seconds above: (CPU at the rate - CPU at 1 Hz) / (epochs at the rate - "
              "epochs at 1 Hz), microseconds")
        for name, _, label in layouts:
            for hz in args.gnss_hz:
                c = _medians(runs[f"{name}@{hz:g}"])[1]
                print(f"  {label}, {hz:g} Hz: "
                      f"{1e6 * (c - base[name]) / max(epochs[hz] - epochs[1], 1):.0f} us")
    if not args.no_cost:
        per_state_cost(args, data)


def per_state_cost(args, data):
    """Cost per IMU epoch and per node against the number of error states: whole runs
    in-process (read + forward + smoother, warm), and the compiled node kernels alone
    (prior covariance + one 3-axis update + one smoother step) for larger n, the price
    of extra states (tight coupling's clocks)."""
    from ins.estimation.core.error_model import LAYOUTS, StateLayout
    from ins.estimation.pipeline.process import process
    global LAYOUT
    print("\nCost against the number of error states (in-process, warm, CPU time of the "
          "process; best of the repeats)")
    print("| states | CPU per IMU epoch (us) | CPU per node (ms) | wall s |")
    print("|---|---|---|---|")
    for groups, label in (((), "21"), (LAYOUTS["survey"], "27"),
                          (LAYOUTS["survey"] + ("lever_arm", "time_offset"), "31")):
        cfg, _ = config_for(data, "gnss.txt")
        cfg.layout = StateLayout(groups)
        process(cfg)
        best = None
        for _ in range(args.repeat):
            t, c = time.perf_counter(), time.process_time()
            res = process(cfg)
            run = (time.process_time() - c, time.perf_counter() - t)
            best = run if best is None or run[0] < best[0] else best
        ep, nodes = res.counts["imu_epochs"], res.counts["nodes"]
        print(f"| {label} | {1e6 * best[0] / ep:.2f} | {1e3 * best[0] / nodes:.3f} | "
              f"{best[1]:.2f} |")
    try:
        from ins.estimation.core import _kalman_kernels as kk
    except ImportError:                     # an older tree (the "before" figures)
        return
    print("\nCompiled node kernels alone (node_predict + joseph_update 3x n + rts_step), "
          "per node, best of 5 x 200:")
    print("| states | us per node | us per IMU epoch at 200 Hz, 1 s nodes |")
    print("|---|---|---|")
    rng = np.random.default_rng(0)
    for n in (21, 27, 31, 33, 39, 45):
        M = rng.normal(size=(n, n))
        P = M @ M.T * 1e-3 + np.eye(n)
        G = np.diag(rng.uniform(1e-9, 1e-6, n))
        H = rng.normal(size=(3, n))
        R, z, v = np.eye(3), rng.normal(size=3) * 1e-3, rng.normal(size=n)
        acc = rng.normal(size=(16, 3)) * 0.1
        gm, am = (21, 24) if n >= 27 else (-1, -1)

        def one():
            Phi, _, Pp = kk.node_predict(0.5, 1000.0, np.array([60.0, 1.0, 0.1]), acc, 1.0,
                                         14400.0, gm, am, -1, G, P)
            _, _, Pu, _, _ = kk.joseph_update(Pp, H, R, z, 1e9)
            kk.rts_step(Pp, Phi, Pu, Pu, v)
        one()
        best = min(_timeit(one, 200) for _ in range(5))
        print(f"| {n} | {1e6 * best:.1f} | {1e6 * best / 200:.3f} |")


def _timeit(f, k):
    t = time.process_time()
    for _ in range(k):
        f()
    return (time.process_time() - t) / k


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

    from ins.estimation.pipeline.process import process
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
    ap.add_argument("--kfgins", default=os.environ.get("KFGINS_BIN"),
                    help="KF-GINS executable, run on the dataset's kfgins_gnss.yaml in the "
                         "speed table (default: $KFGINS_BIN; without it the README figure)")
    ap.add_argument("--speed-only", action="store_true", help="only the speed tables")
    ap.add_argument("--speed-layouts", default=",".join(e[0] for e in SPEED_LAYOUTS),
                    type=lambda text: text.split(","),
                    help="error-state layouts of the whole-process timings, comma-separated "
                         "(default: %(default)s)")
    ap.add_argument("--gnss-hz", default=[], type=lambda text: [float(x) for x in
                                                                 text.split(",") if x],
                    help="also time the speed table's runs with GNSS positions at these "
                         "rates, comma-separated (e.g. 4,10; files built from truth.nav "
                         "beside the 1 Hz gnss.txt)")
    ap.add_argument("--no-cost", action="store_true",
                    help="skip the cost-per-state tables after the speed table")
    ap.add_argument("--layout", default="kfgins", choices=["kfgins", "survey"],
                    help="error states of the in-process runs (the subprocess timings use "
                         "data/configs/kfgins_like.toml: kfgins)")
    args = ap.parse_args()
    unknown = set(args.speed_layouts) - {e[0] for e in SPEED_LAYOUTS}
    if unknown:
        ap.error(f"--speed-layouts: unknown {sorted(unknown)}; expected some of "
                 f"{[e[0] for e in SPEED_LAYOUTS]}")
    global LAYOUT
    LAYOUT = args.layout
    print(f"layout: {LAYOUT}")
    from benchdata import SHARED, ensure_bench_data
    data = Path(args.data) if args.data else ensure_bench_data()
    if data is None:
        raise SystemExit("the shared dataset script is missing (../shared/bench/ins)")
    if args.speed_only:
        speed(args, data)
        return
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
