"""Tight against loose coupling on what a u-blox shows (tests/ublox_scenario.py: C/N0
fades, multipath of 1 m / sin el over 30 s, C/N0-dependent noise, 10-50 m blunders on
weak satellites), with the weights of white noise, with the noise model estimated from
a first pass (ins.estimation.coupling.range_noise) and with the IGG-III down-weighting.

Run: ``PYTHONPATH=. python bench/bench_robust_gnss.py [seed ...]``; prints a table of the
smoothed horizontal RMS over the run and in a 20 s window of 3 satellites.
"""
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import tight_scenario as ts  # noqa: E402
import ublox_scenario as us  # noqa: E402

from ins.estimation.coupling.pseudorange import TightOptions  # noqa: E402
from ins.estimation.coupling.range_noise import RangeNoise, fit_receiver  # noqa: E402
from ins.nav import earth  # noqa: E402

RUN_S, WIN_START, WIN_S = 200.0, 120.0, 20.0


def errors(fwd, states, truth, t0, span):
    j = np.searchsorted(truth.time, fwd.time - 1e-6)
    d = earth.ned_offset(truth.lla[j], states[:, :3])
    h = np.hypot(d[:, 0], d[:, 1])
    m = fwd.time > t0 + 30
    w = (fwd.time >= span[0]) & (fwd.time <= span[1])
    return float(np.sqrt(np.mean(h[m] ** 2))), float(np.sqrt(np.mean(h[w] ** 2)))


def scenario(seed, flight=None, outlier_rate=us.OUTLIER_RATE):
    imu, truth, noise, t0 = flight or ts.flight()
    times = np.arange(t0 + 1.0, t0 + RUN_S + 5.0, 1.0)
    epochs, _, _ = us.make_ublox_epochs(truth, times, ts.L_B, seed=seed,
                                        outlier_rate=outlier_rate)
    span = (t0 + WIN_START, t0 + WIN_START + WIN_S)
    win = ts.masked(epochs, span, 3, truth.lla[np.searchsorted(truth.time, span[0])])
    return imu, truth, noise, t0, win, span


def fitted(imu, truth, noise, t0, epochs, options, passes=1):
    """The noise model from ``passes`` tight passes (each fitted on the previous one's
    innovations; the pipeline's ``range_noise = "auto"``: one pass with the configured
    sigmas, no robust weighting); returns the last model."""
    opt = options
    model = None
    for _ in range(passes):
        fwd, _ = ts.run(imu, truth, noise, t0, t0 + RUN_S, epochs, True,
                        options=replace(opt, keep_samples=True), clock_psd=us.TCXO)
        model = fit_receiver(fwd.updater.samples)
        opt = replace(options, noise=RangeNoise(model, robust=opt.noise is not None
                                                and opt.noise.robust))
    return model


def table(seed, flight=None):
    imu, truth, noise, t0, epochs, span = scenario(seed, flight)
    rows = {}
    lo = us.spp_fde(epochs, truth.lla[0])
    fwd, st = ts.run(imu, truth, noise, t0, t0 + RUN_S, lo, False, smooth=True)
    rows["loose (SPP with FDE)"] = errors(fwd, st, truth, t0, span)
    base = TightOptions()
    model = fitted(imu, truth, noise, t0, epochs, base)
    cases = {"tight, 0.3 + 0.3/sin el": base,
             "tight, 0.3 + 0.3/sin el, IGG-III": replace(base, noise=RangeNoise(robust=True)),
             "tight, fitted model": replace(base, noise=RangeNoise(model, robust=False)),
             "tight, fitted model, IGG-III": replace(base, noise=RangeNoise(model))}
    for name, opt in cases.items():
        fwd, st = ts.run(imu, truth, noise, t0, t0 + RUN_S, epochs, True, smooth=True,
                         options=opt, clock_psd=us.TCXO)
        rows[name] = errors(fwd, st, truth, t0, span)
    return rows, model


if __name__ == "__main__":
    seeds = [int(s) for s in sys.argv[1:]] or [1]
    fl = ts.flight()
    allrows = {}
    for seed in seeds:
        rows, model = table(seed, fl)
        print(f"seed {seed}: fitted {model.describe()}")
        for k, v in rows.items():
            allrows.setdefault(k, []).append(v)
    print(f"| case (smoothed horizontal RMS, m) | run, per seed | run, mean | 3-sat window, "
          f"per seed | window, mean |\n|---|---|---|---|---|")
    for k, v in allrows.items():
        v = np.array(v)
        print(f"| {k} | {' '.join(f'{x:.2f}' for x in v[:, 0])} | {v[:, 0].mean():.2f} | "
              f"{' '.join(f'{x:.2f}' for x in v[:, 1])} | {v[:, 1].mean():.2f} |")
