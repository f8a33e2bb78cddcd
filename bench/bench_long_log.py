#!/usr/bin/env python3
"""A 10 h, 200 Hz IMU log (7.2 M epochs): ``ins mechanize`` and ``ins process`` with
bounded memory (issue 8, hardening).  Prints wall time and peak resident memory of each
command (``ru_maxrss`` of that child from ``os.wait4``), and the errors against the
known truth.

The log is generated streaming, in chunks of ``--chunk`` epochs appended to a KF-GINS
binary file (``--format bin``, 56 bytes an epoch: 403 MB) or text file (``--format
txt``, about 1.1 GB): a static IMU at 30.5 deg N, level, heading north, whose exact
increments are ``dtheta = w_ie^n dt`` and ``dvel = -g^n dt`` (normal gravity), plus
white noise (ARW 0.003 deg/sqrt(h), VRW 0.003 m/s/sqrt(h)) and a constant gyro bias of
0.005 deg/h and accelerometer bias of 20 mGal.  GNSS: the antenna (zero lever arm) at
1 Hz with 2/2/4 cm white noise.  So the truth is known: the IMU stays put.

    python bench/bench_long_log.py                 # 10 h at 200 Hz (takes a while)
    python bench/bench_long_log.py --hours 0.5     # a quick check

Kept out of the test suite.  Needs ~2 GB of free disk in --workdir (deleted at the end
unless --keep).
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from ins.common import textformat
from ins.common.errors import InputError
from ins.io.gnss import write_gnss
from ins.io.gnss_log import GnssLog  # noqa: E402
from ins.nav import earth  # noqa: E402
from ins.nav.imu import DPH, MGAL  # noqa: E402

LAT_DEG, LON_DEG, H_M = 30.5, 114.3, 20.0
T0 = 100000.0
ARW_DEG_SQRTH, VRW_MPS_SQRTH = 0.003, 0.003
GYRO_BIAS_DPH, ACCEL_BIAS_MGAL = 0.005, 20.0
GNSS_SIGMA_M = np.array([0.02, 0.02, 0.04])


def write_imu(path, n, rate_hz, fmt, chunk, seed=1):
    """Append ``n`` static epochs in chunks; memory: one chunk."""
    dt = 1.0 / rate_hz
    lat = np.deg2rad(LAT_DEG)
    w = earth.earth_rate_n(lat) + GYRO_BIAS_DPH * DPH
    f = -earth.gravity_n(lat, H_M) + ACCEL_BIAS_MGAL * MGAL
    sg = np.deg2rad(ARW_DEG_SQRTH) / 60.0 * np.sqrt(dt)   # rad per increment
    sa = VRW_MPS_SQRTH / 60.0 * np.sqrt(dt)               # m/s per increment
    rng = np.random.default_rng(seed)
    decimals = np.array([3] + [-1] * 6, np.int64)
    with open(path, "wb") as out:
        for k0 in range(0, n, chunk):
            m = min(chunk, n - k0)
            table = np.empty((m, 7))
            table[:, 0] = T0 + (k0 + np.arange(m)) / rate_hz     # exact at 200 Hz: k / 200
            table[:, 1:4] = w * dt + sg * rng.standard_normal((m, 3))
            table[:, 4:7] = f * dt + sa * rng.standard_normal((m, 3))
            if fmt == "bin":
                out.write(np.ascontiguousarray(table, "<f8").tobytes())
            else:
                out.write(textformat.format_table(table, decimals).data)
    return os.path.getsize(path)


def write_gnss_file(path, hours, seed=2):
    t = T0 + np.arange(1.0, hours * 3600.0 + 0.5, 1.0)
    rng = np.random.default_rng(seed)
    lat, lon = np.deg2rad(LAT_DEG), np.deg2rad(LON_DEG)
    rm, rn = earth.radii(lat)
    e = GNSS_SIGMA_M * rng.standard_normal((len(t), 3))
    lla = np.column_stack([lat + e[:, 0] / (rm + H_M),
                           lon + e[:, 1] / ((rn + H_M) * np.cos(lat)), H_M - e[:, 2]])
    write_gnss(path, GnssLog(t, lla, np.tile(GNSS_SIGMA_M, (len(t), 1))))
    return len(t)


def write_config(path, imu_format):
    path.write_text(f"""
[imu]
format = "{'kfgins-bin' if imu_format == 'bin' else 'kfgins'}"
[initial]
time_s = {T0}
lat_deg = {LAT_DEG}
lon_deg = {LON_DEG}
h_m = {H_M}
vel_ned_mps = [0.0, 0.0, 0.0]
rpy_deg = [0.0, 0.0, 0.0]
pos_std_ned_m = [0.05, 0.05, 0.05]
vel_std_ned_mps = [0.01, 0.01, 0.01]
att_std_deg = [0.01, 0.01, 0.1]
[imu_noise]
arw_deg_sqrth = {ARW_DEG_SQRTH}
vrw_mps_sqrth = {VRW_MPS_SQRTH}
gyro_bias_std_dph = 0.02
accel_bias_std_mgal = 50.0
gyro_scale_std_ppm = 10.0
accel_scale_std_ppm = 10.0
corr_time_h = 4.0
[gnss]
lever_arm_b_m = [0.0, 0.0, 0.0]
[filter]
node_interval_s = 1.0
""")


#: GNU time (Debian package ``time``): the child's own peak RSS.  Linux's ``ru_maxrss`` of
#: a child forked from this process counts this process's resident set at the fork (this
#: script holds the generated log's chunks: mechanize showed 116 MiB under wait4 and 80
#: MiB under GNU time on the 4 h log), so wait4's figure is only an upper bound.
GNU_TIME = "/usr/bin/time" if os.access("/usr/bin/time", os.X_OK) else None


def run(argv):
    """Run a command; (exit code, wall s, peak RSS MiB of that child, stderr tail)."""
    t = time.perf_counter()
    with tempfile.TemporaryFile() as err, tempfile.NamedTemporaryFile("r") as rep:
        full = [GNU_TIME, "-q", "-o", rep.name, "-f", "%M"] + argv if GNU_TIME else argv
        proc = subprocess.Popen(full, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - t
        err.seek(0)
        tail = err.read().decode(errors="replace").strip().splitlines()[-3:]
        rss = float(rep.read().split()[-1]) / 1024.0 if GNU_TIME else usage.ru_maxrss / 1024.0
    return proc.returncode, wall, rss, tail


def horizontal_error_m(nav_path, every=1):
    """Horizontal distance (m) of every ``every``-th epoch from the static truth."""
    from ins.io.navfiles import read_nav
    traj = read_nav(nav_path)
    lat0, lon0 = np.deg2rad(LAT_DEG), np.deg2rad(LON_DEG)
    rm, rn = earth.radii(lat0)
    dn = (traj.lla[::every, 0] - lat0) * (rm + H_M)
    de = (traj.lla[::every, 1] - lon0) * (rn + H_M) * np.cos(lat0)
    return traj.time[::every], np.hypot(dn, de), len(traj)


def mechanize(cli, imu, work, n, every):
    """``ins mechanize`` of the log (every ``every``-th epoch written) and its drift."""
    code, wall, rss, tail = run(cli + [
        "mechanize", str(imu), "--init-lla", f"{LAT_DEG},{LON_DEG},{H_M}",
        "--init-vel", "0,0,0", "--init-att", "0,0,0", "--every", str(every), "-q",
        "-o", str(work / "mech.nav")])
    print(f"ins mechanize: exit {code}, wall {wall:.1f} s, peak RSS {rss:.0f} MiB "
          f"({n / wall / 1e6:.2f} M epochs/s)")
    if code:
        print("  " + "\n  ".join(tail))
        return
    try:
        tt, h, m = horizontal_error_m(work / "mech.nav")
    except InputError as exc:       # the unaided vertical channel left the file's range
        print(f"  (not evaluated: {exc})")
        return
    k = min(np.searchsorted(tt, T0 + 3600.0), len(tt) - 1)
    print(f"  free-inertial horizontal drift (no aiding; noise and biases): "
          f"{h[k]:.0f} m after {(tt[k] - T0) / 3600:.2g} h; {m:,} epochs written "
          f"(every {every}th; later the unaided vertical channel diverges)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=200.0, help="IMU rate, Hz")
    ap.add_argument("--format", choices=["bin", "txt"], default="bin")
    ap.add_argument("--chunk", type=int, default=500_000, help="epochs per written chunk")
    ap.add_argument("--workdir", default=None, help="folder for the files (default: temp)")
    ap.add_argument("--keep", action="store_true", help="keep the files")
    ap.add_argument("--skip-process", action="store_true")
    ap.add_argument("--skip-mechanize", action="store_true")
    args = ap.parse_args()

    work = Path(args.workdir or tempfile.mkdtemp(prefix="long-log-", dir=ROOT / ".cache"
                                                  if (ROOT / ".cache").is_dir() else None))
    work.mkdir(parents=True, exist_ok=True)
    n = int(round(args.hours * 3600 * args.rate)) + 1
    imu = work / f"imu.{args.format}"
    try:
        t = time.perf_counter()
        size = write_imu(imu, n, args.rate, args.format, args.chunk)
        n_gnss = write_gnss_file(work / "gnss.txt", args.hours)
        write_config(work / "config.toml", args.format)
        print(f"log: {args.hours:g} h at {args.rate:g} Hz = {n:,} epochs, {size / 1e6:.0f} MB "
              f"({args.format}), {n_gnss:,} GNSS records; written in chunks of {args.chunk:,} "
              f"in {time.perf_counter() - t:.1f} s ({work})")
        print(f"for scale: the log as float64 arrays is {n * 7 * 8 / 2**20:.0f} MiB; one 21x21 "
              f"covariance per epoch would be {n * 21 * 21 * 8 / 2**30:.1f} GiB")
        cli = [sys.executable, "-m", "ins.cli.main"]
        every = int(round(args.rate))
        if not args.skip_mechanize:
            mechanize(cli, imu, work, n, every)
        if args.skip_process:
            return
        out = work / "out"
        code, wall, rss, tail = run(cli + [
            "process", "--imu", str(imu), "--gnss", str(work / "gnss.txt"), "--config",
            str(work / "config.toml"), "--no-plots", "-q", "-o", str(out)])
        print(f"ins process (forward + RTS smoother, 1 s nodes): exit {code}, wall {wall:.1f} s, "
              f"peak RSS {rss:.0f} MiB ({n / wall / 1e3:.0f} k epochs/s)")
        if code:
            print("  " + "\n  ".join(tail))
            return
        for name in ("forward.nav", "solution.nav"):
            if not (out / name).is_file():          # forward.nav only with --forward
                continue
            tt, h, m = horizontal_error_m(out / name, every=every)
            rms = 1e3 * np.sqrt(np.mean(h ** 2))
            print(f"  {name}: {m:,} epochs; horizontal error vs truth RMS {rms:.1f} mm, "
                  f"max {1e3 * h.max():.1f} mm (1 Hz samples)")
        sizes = {p.name: p.stat().st_size / 1e6 for p in out.iterdir()}
        print("  outputs: " + ", ".join(f"{k} {v:.0f} MB" for k, v in sorted(sizes.items())))
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
