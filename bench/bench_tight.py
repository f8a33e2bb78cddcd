"""Tight against loose GNSS/INS coupling on a simulated flight with satellites masked.

The flight of tests/test_filter.py's plan (60 s on the ground, take-off, climb, strips at
60 m/s) with a tactical IMU (or ``--grade``); a synthetic 24-satellite GPS constellation
(tests/tight_scenario.py: exact ranges with the Earth's rotation during the travel,
Doppler from the exact ranges, clock bias + drift + random walk, noise
sqrt(0.3^2 + 0.3^2/sin^2 el) m and sqrt(0.05^2 + 0.05^2/sin^2 el) m/s).  Loose coupling
gets a weighted least-squares point position from the same pseudoranges at every epoch
with >= 4 satellites; tight coupling the pseudoranges and range rates.  Inside a span
starting at ``--span-start`` (s after the start) only 3, 2, 1 or 0 satellites remain
(those spread most in azimuth, or the highest: ``--choose``) for 30, 60, 120 s: loose
has an outage there.  Prints, with all satellites, the horizontal RMS over the run and
the processing times; then the horizontal error at the end of the span, forward and
RTS-smoothed, as an RMS over ``--seeds`` realizations of the GNSS noise and the clock
(one IMU realization: the flight's), with the filters' stated sigmas.

    .venv/bin/python bench/bench_tight.py [--grade tactical] [--seed 3]
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import tight_scenario as ts  # noqa: E402

from ins.nav import earth  # noqa: E402


def rms_h(fwd_time, states, truth, t_lo):
    j = np.searchsorted(truth.time, fwd_time - 1e-6)
    d = earth.ned_offset(truth.lla[j], states[:, :3])
    m = fwd_time > t_lo
    return float(np.sqrt(np.mean(np.sum(d[m, :2] ** 2, axis=1))))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grade", default=ts.TACTICAL)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--span-start", type=float, default=250.0)
    ap.add_argument("--lengths", default="30,60,120")
    ap.add_argument("--keep", default="3,2,1,0")
    ap.add_argument("--seeds", type=int, default=5, help="noise and clock seeds")
    ap.add_argument("--choose", default="spread", choices=("spread", "highest"),
                    help="which satellites remain (tests/tight_scenario.masked)")
    a = ap.parse_args(argv)
    imu, truth, noise, t0 = ts.flight(a.grade, a.seed)
    lengths = [float(x) for x in a.lengths.split(",")]
    t_end = t0 + a.span_start + max(lengths) + 30.0
    times = np.arange(t0 + 1.0, t_end, 1.0)
    epochs, _ = ts.make_epochs(truth, times, ts.L_B, seed=a.seed)
    print(f"# {a.grade} IMU, seed {a.seed}; span from t0 + {a.span_start:.0f} s; "
          f"satellites above 10 deg: {min(map(len, epochs.sats))}-"
          f"{max(map(len, epochs.sats))}")
    timing = {}

    def go(gnss, tight, t_stop, smooth):
        t = time.perf_counter()
        fwd, st = ts.run(imu, truth, noise, t0, t_stop, gnss, tight, smooth=smooth)
        timing.setdefault(("tight" if tight else "loose", smooth), []).append(
            time.perf_counter() - t)
        return fwd, st
    go(epochs, True, t0 + 20, False)                    # warm-up (imports, page cache)
    go(ts.spp(epochs, truth.lla[0]), False, t0 + 20, False)
    timing.clear()
    print("\n## All satellites: horizontal RMS after the first 30 s, m")
    print("| coupling | forward | smoothed |")
    print("|---|---|---|")
    loose_all = ts.spp(epochs, truth.lla[0])
    for name, gnss, tight in (("loose", loose_all, False), ("tight", epochs, True)):
        row = []
        for sm in (False, True):
            fwd, st = go(gnss, tight, t_end, sm)
            row.append(rms_h(fwd.time, st, truth, t0 + 30.0))
        print(f"| {name} | {row[0]:.3f} | {row[1]:.3f} |")
    print("\n## Processing time (forward, and forward + smoother), s per run of ~"
          f"{t_end - t0:.0f} s at 200 Hz")
    for (name, sm), v in sorted(timing.items()):
        print(f"{name} {'smoothed' if sm else 'forward'}: {np.mean(v):.2f} s ({len(v)} runs)")
    print(f"\n## Masked: horizontal error at the end of the span, m: RMS over "
          f"{a.seeds} noise/clock seeds (forward / smoothed), and the forward filter's "
          f"stated horizontal sigma (mean)")
    print("| satellites | span s | loose | tight | loose sigma | tight sigma |")
    print("|---|---|---|---|---|---|")
    seeds = [a.seed + 100 * k for k in range(a.seeds)]
    sets = {s: ts.make_epochs(truth, times, ts.L_B, seed=s)[0] for s in seeds}
    for n_keep in (int(x) for x in a.keep.split(",")):
        for length in lengths:
            span = (t0 + a.span_start, t0 + a.span_start + length)
            lla = truth.lla[np.searchsorted(truth.time, span[0])]
            err = np.zeros((len(seeds), 2, 2))
            sig = np.zeros((len(seeds), 2))
            for k, s in enumerate(seeds):
                mep = ts.masked(sets[s], span, n_keep, lla, choose=a.choose)
                for c, (gnss, tight) in enumerate(((ts.spp(mep, truth.lla[0]), False),
                                                   (mep, True))):
                    for sm in (False, True):
                        fwd, st = ts.run(imu, truth, noise, t0, span[1] + 20.0, gnss, tight,
                                         smooth=sm)
                        err[k, c, int(sm)] = ts.horizontal_error(fwd.time, st, truth,
                                                                 span[1])
                    j = int(np.argmin(np.abs(fwd.node_time - span[1])))
                    sig[k, c] = np.sqrt(fwd.P_post[j, 0, 0] + fwd.P_post[j, 1, 1])
                    if tight:
                        used = [ep.used for ep in fwd.updater.epochs
                                if span[0] < ep.time < span[1]]
                        assert min(used) == max(used) == n_keep, used
            rms = np.sqrt(np.mean(err ** 2, axis=0))
            print(f"| {n_keep} | {length:.0f} | {rms[0, 0]:.2f} / {rms[0, 1]:.2f} | "
                  f"{rms[1, 0]:.2f} / {rms[1, 1]:.2f} | {sig[:, 0].mean():.2f} | "
                  f"{sig[:, 1].mean():.2f} |")


if __name__ == "__main__":
    main()
