"""Tight against loose coupling on the raw-GPS simulated flight (data/flights/rawsim.toml:
tactical IMU, real broadcast orbits of 2005-04-02, RINEX 3 rover observations with
cycle slips, multipath and masks of 3, 2 and 1 satellites for 20 s each), through
``ins.estimation.pipeline.process.process`` as ``ins process`` runs it.

Loose: RTKLIB's single-point solution of the rover (mode single, GPS L1) as the GNSS
log.  Tight: the same run with ``coupling = "tight"`` (pseudoranges and Doppler through
RTKLIB's satellite positions and corrections).  Tight DD (when the folder has
``base.obs``; ``--no-dd``: not): double differences against the simulated base station
(``[files] base``; no clock states).  Prints the horizontal error against the
simulator's truth at the last second of each mask (the masks follow each other:
loose has one 60 s outage), the RMS over the flight (forward and
smoothed), the satellites used per epoch (DD: the common satellites in the pseudorange
DDs, reference included: one satellite gives no DD, hence 0) and the processing time.

    .venv/bin/ins simulate data/flights/rawsim.toml -o /tmp/flight_raw \\
        --gnss-raw ../shared/real/rtklib_static_pair/07590920.05n --seed 1
    .venv/bin/python bench/bench_tight_rawsim.py /tmp/flight_raw

``data/flights/rawsim_dd.toml`` is the same flight with the errors a base cancels
(ionosphere twice Klobuchar, troposphere 1.1 Saastamoinen) and white code noise only.
"""
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import tomllib

from ins.estimation.pipeline.process import process
from ins.estimation.pipeline.config import config_from_manifest
from ins.estimation.pipeline.gnss_source import RawGnss
from ins.gnss.rtklib_options import RtklibOptions
from ins.io.navfiles import read_nav
from ins.nav import earth


def main(folder, single_only=False):
    folder = Path(folder)
    man = tomllib.loads((folder / "manifest.toml").read_text())
    plan = tomllib.loads((folder / "plan.toml").read_text())
    t0 = man["flight"]["start_time_s"]
    masks = plan["gnss_raw"]["masks"]
    truth = read_nav(str(folder / "truth.nav"))
    print(f"# {folder}: masks (start s, length s, satellites kept) {masks}")
    print("| coupling | " + " | ".join(f"end of {int(k)}-sat mask fwd/smoothed"
                                       for _, _, k in masks) + " | RMS fwd | RMS smoothed "
          "| sats used min/mean | time s |")
    print("|---|" + "---|" * (len(masks) + 4))
    base = str(folder / "base.obs") if (folder / "base.obs").is_file() else None
    runs = [("loose", None, None), ("tight", None, None), ("tight", (1.0, 1.0), None)]
    if base and not single_only:
        runs += [("tight", None, base), ("tight", (1.0, 1.0), base)]
    for coupling, range_sigma, base_obs in runs:
        cfg = config_from_manifest(str(folder))
        cfg.gnss = None
        cfg.gnss_raw = RawGnss(rover=str(folder / "rover.obs"), nav=(str(folder / "rover.nav"),),
                               base=base_obs,
                               options=RtklibOptions(mode="single", systems=("gps",),
                                                     frequencies=1, elevation_mask_deg=10.0))
        cfg.coupling = coupling
        if range_sigma is not None:         # [gnss] range_sigma_m: the multipath's share
            cfg.range_sigma_m = range_sigma
        tic = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = process(cfg, accept_poor=True)
        dt = time.perf_counter() - tic
        cells, rms = [], []
        for traj in (res.forward, res.smoothed):
            j = np.clip(np.searchsorted(truth.time, traj.time - 1e-6), 0, len(truth.time) - 1)
            d = earth.ned_offset(truth.lla[j], traj.lla)
            h = np.hypot(d[:, 0], d[:, 1])
            rms.append(float(np.sqrt(np.mean(h ** 2))))
            cells.append([float(h[np.argmin(np.abs(traj.time - (t0 + a + b - 1.0)))])
                          for a, b, _ in masks])
        c = res.counts
        used = (f"{c['satellites_min']}/{c['satellites_mean']:.1f}"
                if c.get("coupling") == "tight" else "-")
        name = coupling + (" DD" if base_obs else " SPP" if coupling == "tight" else "") + (
            "" if range_sigma is None else f", range_sigma_m {list(range_sigma)}")
        print(f"| {name} | " + " | ".join(f"{f:.2f} / {s:.2f}" for f, s in
                                            zip(*cells)) +
              f" | {rms[0]:.2f} | {rms[1]:.2f} | {used} | {dt:.1f} |")


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    main(args[0] if args else "/tmp/flight_raw", single_only="--no-dd" in sys.argv)
