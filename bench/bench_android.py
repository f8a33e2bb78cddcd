"""An Android phone log as a user runs it, on its simulated twin: the handheld walk of
:data:`ins.simulate.gnsslogger_writer.ANDROID_WALK` (240 s, the phone held 60 deg off
the walking direction, pitched 20 deg down, bouncing 3 cm at 1.8 Hz; consumer IMU
errors with 1.5 x the preset's white noise, 200 Hz stamps jittering 0.2 ms on a boot
clock 3.7 ppm off GPS time; raw GPS L1 at 1 Hz with 2 m code noise and 2 m multipath;
the phone's own fixes 3 m off in a 30 s Gauss-Markov wander) written as a GnssLogger
log, then

    ins import-android gnss_log.txt -o imp
    ins process --imu imp/imu.csv --rover imp/gnss.obs --nav rover.nav --config hw.toml
                --preset consumer [--coupling tight] -o OUT

``--journey car``: the consumer car of
:data:`ins.simulate.gnsslogger_writer.ANDROID_CAR` instead (parked 40 s, 4 min of town
driving, the phone in a cradle; ``[vehicle] mounting_rpy_deg`` in the config).  Prints
per seed the horizontal RMS (m) of the phone's fixes, RTKLIB's single point and the
tight and loose solutions against the truth, and of the solutions against the phone's
fixes (the solution interpolated to the fix epochs).

    .venv/bin/python bench/bench_android.py [--journey walk|car] [--seeds 3] [--keep DIR]
"""
import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
NAV = ROOT / ".." / "shared" / "real" / "rtklib_static_pair" / "07590920.05n"

from ins.io.navfiles import read_nav  # noqa: E402
from ins.io.rtklib import read_pos  # noqa: E402
from ins.nav.interpolation import interpolate_trajectory  # noqa: E402
from ins.nav.trajectory import Trajectory  # noqa: E402
from ins.simulate.gnsslogger_writer import (ANDROID_CAR, ANDROID_WALK,  # noqa: E402
                                            write_android_journey)

JOURNEYS = {"walk": (ANDROID_WALK, ""),
            "car": (ANDROID_CAR, "[vehicle]\nmounting_rpy_deg = [1.0, -2.0, 3.0]\n")}


def _traj(path):
    if str(path).endswith(".pos"):
        g = read_pos(path)
        t = np.asarray(g.time)
        return Trajectory(t, np.asarray(g.lla), np.zeros((len(t), 3)),
                          np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1)))
    return read_nav(path)


def horizontal_rms(est, ref):
    """RMS of the horizontal distance of ``est``'s epochs to ``ref`` interpolated there, m."""
    k = (est.time >= ref.time[0]) & (est.time <= ref.time[-1])
    r = interpolate_trajectory(ref, est.time[k])
    dn = (est.lla[k, 0] - r.lla[:, 0]) * 6378137.0
    de = (est.lla[k, 1] - r.lla[:, 1]) * 6378137.0 * np.cos(r.lla[:, 0])
    return float(np.sqrt(np.mean(dn ** 2 + de ** 2)))


def run(name, seed, keep):
    d = Path(keep) / f"{name}_{seed}" if keep else Path(tempfile.mkdtemp())
    journey, facts = JOURNEYS[name]
    write_android_journey(d, NAV, journey=journey, seed=seed)
    (d / "hw.toml").write_text("[gnss]\nlever_arm_b_m = [0.0, 0.0, 0.0]\n" + facts)
    ins = [sys.executable, "-m", "ins.cli.main"]
    subprocess.run(ins + ["import-android", str(d / "gnss_log.txt"), "-o", str(d / "imp"),
                    "--force", "-q"], check=True)
    truth = read_nav(d / "truth.nav")
    fixes = _traj(d / "imp" / "fix.pos")
    row = {"fixes": horizontal_rms(fixes, truth)}
    for coupling in ("tight", "loose"):
        out = d / coupling
        cmd = ins + ["process", "--imu", str(d / "imp" / "imu.csv"), "--rover",
               str(d / "imp" / "gnss.obs"), "--nav", str(d / "rover.nav"), "--config",
               str(d / "hw.toml"), "--preset", "consumer", "--no-plots", "--force", "-q",
               "-o", str(out)] + (["--coupling", "tight"] if coupling == "tight" else [])
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0 or not (out / "solution.nav").exists():
            row[coupling] = row[coupling + "_fix"] = np.nan
            print(f"seed {seed} {coupling}: exit {proc.returncode} "
                  f"{(proc.stderr.strip().splitlines() or [''])[-1][:160]}")
            continue
        sol = read_nav(out / "solution.nav")
        row[coupling] = horizontal_rms(sol, truth)
        row[coupling + "_fix"] = horizontal_rms(fixes, sol)
        row["spp"] = horizontal_rms(_traj(out / "gnss.pos"), truth)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--keep", help="keep the folders here")
    ap.add_argument("--journey", choices=sorted(JOURNEYS), default="walk")
    a = ap.parse_args()
    print("horizontal RMS, m     fixes-truth  spp-truth  tight-truth  loose-truth  "
          "tight-fixes  loose-fixes")
    rows = []
    for seed in range(a.seeds):
        r = run(a.journey, seed, a.keep)
        rows.append(r)
        print(f"seed {seed:<16} {r['fixes']:11.2f} {r.get('spp', np.nan):10.2f} "
              f"{r['tight']:12.2f} {r['loose']:12.2f} {r['tight_fix']:12.2f} "
              f"{r['loose_fix']:12.2f}")
    if len(rows) > 1:
        m = {k: np.sqrt(np.nanmean([r.get(k, np.nan) ** 2 for r in rows])) for k in rows[0]}
        print(f"{'RMS over seeds':<21} {m['fixes']:11.2f} {m.get('spp', np.nan):10.2f} "
              f"{m['tight']:12.2f} {m['loose']:12.2f} {m['tight_fix']:12.2f} "
              f"{m['loose_fix']:12.2f}")


if __name__ == "__main__":
    main()
