"""RTK/INS against tight code-only and loose coupling on a simulated flight with raw
multi-GNSS and a base (data/flights/rawsim_rtk.toml: four constellations on two
frequencies, multipath, a slip of every satellite, spans of 3, 2 and 1 satellites, a
60 s total outage; the base 10 km away), through ``ins process`` as a user runs it
(``FLIGHT_DIR --coupling tight --base base.obs``; loose: RTKLIB's kinematic solution).
Prints, forward and smoothed, the horizontal error at the end of each span, the RMS
over the flight, the fix rate, the slips and the re-fix time after the total outage, and
the time per epoch against the satellites and ambiguity states.

    .venv/bin/ins simulate data/flights/rawsim_rtk.toml -o /tmp/flight_rtk \\
        --gnss-raw ../shared/real/slac_cors_2021/brdc1180.21n --seed 1
    .venv/bin/python bench/bench_rtk_sim.py /tmp/flight_rtk
"""
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import tomllib

from ins.estimation.pipeline.config import config_from_manifest
from ins.estimation.pipeline.gnss_source import RawGnss
from ins.estimation.pipeline.process import process
from ins.gnss.rtklib_options import RtklibOptions
from ins.io.navfiles import read_nav
from ins.nav import earth

NAMES = {"G": "gps", "R": "glonass", "E": "galileo", "C": "beidou"}


def run(folder, coupling, carrier, systems):
    cfg = config_from_manifest(str(folder))
    base = str(folder / "base.obs")
    mode = "kinematic" if coupling == "loose" else "single"
    cfg.gnss = None
    cfg.gnss_raw = RawGnss(rover=str(folder / "rover.obs"), nav=(str(folder / "rover.nav"),),
                           base=base if coupling == "loose" or carrier is not None else None,
                           options=RtklibOptions(mode=mode, systems=systems,
                                                 frequencies=2, elevation_mask_deg=10.0))
    cfg.coupling = coupling
    if carrier is not None:
        cfg.carrier_phase = carrier
    tic = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = process(cfg, accept_poor=True)
    return res, time.process_time() - tic


def main(folder):
    folder = Path(folder)
    man = tomllib.loads((folder / "manifest.toml").read_text())
    plan = tomllib.loads((folder / "plan.toml").read_text())
    t0 = man["flight"]["start_time_s"]
    masks = plan["gnss_raw"]["masks"]
    systems = tuple(NAMES[s] for s in man["gnss_raw"]["systems"] if s in NAMES)
    truth = read_nav(str(folder / "truth.nav"))
    print(f"# {folder}: systems {systems}, masks (start s, length s, satellites kept) "
          f"{masks}")
    print("| run | " + " | ".join(f"end of {int(k)}-sat span fwd / smoothed m"
                                   for _, _, k in masks)
          + " | RMS fwd / smoothed m | fix rate | slips | re-fix s | CPU s |")
    print("|---|" + "---|" * (len(masks) + 5))
    for name, coupling, carrier in (("loose (RTKLIB kinematic)", "loose", None),
                                    ("tight code DD", "tight", False),
                                    ("tight RTK", "tight", True)):
        res, cpu = run(folder, coupling, carrier, systems)
        cells, rms = [], []
        for traj in (res.forward, res.smoothed):
            j = np.clip(np.searchsorted(truth.time, traj.time - 1e-6), 0, len(truth.time) - 1)
            d = earth.ned_offset(truth.lla[j], traj.lla)
            h = np.hypot(d[:, 0], d[:, 1])
            rms.append(float(np.sqrt(np.mean(h ** 2))))
            cells.append([float(h[np.argmin(np.abs(traj.time - (t0 + a + b - 1.0)))])
                          for a, b, _ in masks])
        c = res.counts
        refix = ",".join(f"{v:g}" for v in c.get("refix_s", [])) or "-"
        print(f"| {name} | " + " | ".join(f"{f:.3f} / {s:.3f}" for f, s in zip(*cells))
              + f" | {rms[0]:.3f} / {rms[1]:.3f} | {c.get('fix_rate', '-')} | "
              f"{c.get('cycle_slips', '-')} | {refix} | {cpu:.1f} |")
    print(f"\nTime per epoch (RTK, the whole run's CPU over its GNSS epochs, the "
          f"{man['flight']['imu_rate_hz']:g} Hz IMU included):")
    print("| systems | satellites per epoch, mean | ambiguity slots | states n | "
          "fix rate | CPU ms per epoch |")
    print("|---|---|---|---|---|---|")
    for subset in (systems[:1], systems[:1] + systems[2:3], systems):
        res, cpu = run(folder, "tight", True, subset)
        up, L = res.fwd.updater, res.fwd.layout
        print(f"| {'+'.join(subset)} | {res.counts['satellites_mean']:.1f} | "
              f"{L.n_ambiguities} | {L.n} | {res.counts.get('fix_rate')} | "
              f"{1e3 * cpu / max(len(up.epochs), 1):.1f} |")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "/tmp/flight_rtk")
