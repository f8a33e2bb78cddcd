#!/usr/bin/env python3
"""How far the demo flight's smoothed attitude can go: information bounds (issue 16).

Issue 16 asks, on the demo flight (``data/flights/demo.toml``: tactical IMU, stabilized
mount, in-air start), for a smoothed tilt of at most 25 arcsec RMS per axis and a heading
of at most 60 arcsec.  This script runs ``ins process``'s pipeline (config from the
flight's manifest, default layout) on variants of the flight and prints, per variant,
the smoothed attitude error RMS against the truth (tilt N, tilt E, heading, over every
filter node of the flight and after the first ``LATE_S`` s) and the RMS of the filter's
own smoothed sigmas.  With the filter model equal to the simulator's error model
(``ImuNoise`` with the bias instability: random constants plus the instability, priors
the injected magnitudes), the stated sigma is the information bound of the flight: no
honest model can do better in expectation with the same measurements.

Variants (the same seed, the plan's [imu] overrides in manifest units):

- ``preset``: the demo flight as it is;
- ``preset-gm``: the same flight, every sensor state a Gauss-Markov process of its total
  sigma (the model before the constant sensor states);
- ``constants``: the preset's constant errors only (no bias instability, no
  quantization): the exact filter model;
- ``arw-only``: only the angle and velocity random walks (the filter then knows every
  other error is zero: priors at their floor): the bound set by the noise alone;
- ``only ...``: one constant error group at a time (the others zero);
- ``misalignments``: the gyro and the accelerometer non-orthogonality together;
- ``gnss-velocity``: GNSS velocity measurements added; ``ground``: the flight starts on
  the ground (static alignment, take-off) instead of in the air.

Measured (seed 1, 2026-11-24; smoothed, arcsec, tilt N / tilt E / heading):

==================  ======================  =====================
variant             error RMS (whole)       stated sigma RMS
==================  ======================  =====================
preset              42.4 / 21.5 / 111.3     39.8 / 28.9 / 61.4
preset-gm           47.8 / 26.8 / 110.2     48.7 / 37.9 / 67.9
constants           43.6 / 23.1 / 100.5     39.5 / 27.8 / 59.5
arw-only            11.0 / 11.3 / 76.3      10.8 / 10.6 / 46.3
only gyro bias      11.4 / 11.8 / 89.3      10.9 / 10.7 / 50.7
only accel bias     18.2 / 12.0 / 75.8      14.3 / 13.1 / 47.0
only accel misal.   17.4 / 11.9 / 89.7      13.8 / 12.2 / 51.8
only instability    20.4 / 13.2 / 97.6      14.3 / 13.6 / 51.1
misal. gyro+accel   27.5 / 15.3 / 87.2      32.0 / 19.8 / 52.8
gnss-velocity       49.7 / 25.1 / 115.1     39.2 / 28.5 / 60.9
ground start        30.6 / 27.1 / 96.6      36.8 / 27.0 / 68.6
==================  ======================  =====================

(gyro scale, accel scale, gyro misalignment alone: within 1 arcsec of ``arw-only``;
pairs measured once: accel bias + accel misalignment 14.8/13.9/52.0 stated, accel bias
+ gyro bias 14.4/13.2/51.6, all gyro errors 11.3/11.1/53.8, all accelerometer errors
14.8/14.0/52.0.)
Over 8 seeds with drawn constant errors (``bench_consistency.py --seeds 8``) the smoothed
RMS is 43.6/26.0/74.1 against stated 39.8/28.9/61.4 (NEES in band); with the old
Gauss-Markov model 46.4/30.3/79.7 against 48.7/37.9/67.9.  Node interval 0.5 or 2 s:
within 0.5 arcsec.

Reading: the heading bound is about 46 arcsec with the random walks alone (the first
two minutes are a straight line where the heading is observed only through the first
turn, and ARW 0.12 deg/sqrt(h) is 7.2 arcsec/sqrt(s)) and 60 with the constant errors at
the preset's magnitudes; a single flight's heading RMS scatters widely around it (seed 1:
76 with ARW alone).  The tilt bound is about 40/28 arcsec: no single error group costs
more than ~15 arcsec, but the gyro and accelerometer non-orthogonality TOGETHER cost
32/20: in a turn the gyro's ``m_x w_z`` turns into a tilt (50 arcsec over a 200 deg turn
is 170 arcsec), which the GNSS sees only through the specific force, where the
accelerometer's ``m g`` is a horizontal bias of the same look; the accelerometer biases
and the bias instability add to that.  Neither GNSS velocity nor a ground start
(static alignment cannot separate tilt from accelerometer bias) moves the bound.
The issue's 25 arcsec per tilt axis is therefore not reachable on this flight with the
tactical preset by any honest model; 60 arcsec heading is at the bound in expectation,
not on every seed.  After the first two minutes (the strips and turns, where the images
are) the preset's smoothed heading is 38 arcsec against a stated 54 (seed 1; 8 seeds:
the straight-line and turn classes of ``bench_consistency.py``, 72/39 against 63/41),
while the tilt stays at 40/24 against 39/30.

Usage: python bench/bench_demo_bound.py [--seed 1] [--plan data/flights/demo.toml]
                                        [--quick]   (preset, preset-gm, arw-only only)
"""
import argparse
import sys
import tempfile
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
ARCSEC = np.pi / 180.0 / 3600.0
LATE_S = 120.0

ZERO = {"gyro_bias_dph": 0.0, "accel_bias_mgal": 0.0, "gyro_bias_instability_dph": 0.0,
        "accel_bias_instability_mgal": 0.0, "gyro_scale_ppm": 0.0, "accel_scale_ppm": 0.0,
        "gyro_misalignment_arcsec": 0.0, "accel_misalignment_arcsec": 0.0,
        "gyro_quantization_rad": 0.0, "accel_quantization_mps": 0.0}
CONSTANT = ("gyro_bias_dph", "accel_bias_mgal", "gyro_scale_ppm", "accel_scale_ppm",
            "gyro_misalignment_arcsec", "accel_misalignment_arcsec")


def plan_variant(text, grade_values, imu=None, replace_lines=()):
    """The plan's text with ``[imu]`` overrides (manifest units) and line replacements."""
    for old, new in replace_lines:
        assert old in text, f"the plan has no line {old!r}"
        text = text.replace(old, new, 1)
    if imu:
        lines = "\n".join(
            f"{k} = {[float(x) for x in np.broadcast_to(np.asarray(v, float), 3)]}"
            for k, v in imu.items())
        text = text.replace("\n[imu]\n", "\n[imu]\n" + lines + "\n", 1)
    return text


def variants(preset):
    """(name, imu overrides, plan line replacements, Gauss-Markov model)."""
    const = dict(ZERO, **{k: preset[k] for k in CONSTANT})
    out = [("preset", None, (), False), ("preset-gm", None, (), True),
           ("constants", const, (), False), ("arw-only", dict(ZERO), (), False)]
    for key in CONSTANT + ("bias instability",):
        keys = (("gyro_bias_instability_dph", "accel_bias_instability_mgal")
                if key == "bias instability" else (key,))
        out.append((f"only {key}", dict(ZERO, **{k: preset[k] for k in keys}), (), False))
    out.append(("misalignments (gyro + accel)",
                 dict(ZERO, **{k: preset[k] for k in ("gyro_misalignment_arcsec",
                                                      "accel_misalignment_arcsec")}),
                 (), False))
    out.append(("gnss-velocity", None, (("\nvelocity = false", "\nvelocity = true"),),
                False))
    out.append(("ground start", None, (('\nstart = "air"', '\nstart = "ground"'),), False))
    return out


def figures(folder, gauss_markov):
    """Smoothed attitude error RMS and stated sigma RMS (arcsec), whole and late."""
    from ins.estimation.pipeline.process import process
    from ins.estimation.pipeline.config import config_from_manifest
    from ins.estimation.core.smoother import rts_errors
    from ins.io.navfiles import read_nav
    from ins.nav.accuracy import compare
    from ins.nav.trajectory import Trajectory
    cfg = config_from_manifest(str(folder))
    cfg.truth = None
    if gauss_markov:
        cfg.noise = replace(cfg.noise, gyro_bias_instability_dph=None,
                            accel_bias_instability_mgal=None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = process(cfg, accept_poor=True)
    t = res.node_time
    _, Ps = rts_errors(res.fwd, full=True)
    st = res.node_solution()
    e = compare(Trajectory(t, st[:, 0:3], st[:, 3:6], st[:, 6:10]),
                read_nav(Path(folder) / "truth.nav"))
    sd2 = np.einsum("mii->mi", Ps[:, 6:9, 6:9])
    late = (t - t[0]) >= LATE_S
    rms = lambda x: np.sqrt(np.mean(x, axis=0)) / ARCSEC  # noqa: E731
    return (rms(e.att_n ** 2), rms(sd2), rms(e.att_n[late] ** 2), rms(sd2[late]))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--plan", default=str(ROOT / "data" / "flights" / "demo.toml"))
    ap.add_argument("--quick", action="store_true",
                    help="only preset, preset-gm and arw-only")
    args = ap.parse_args()
    import tomllib

    from ins.simulate.folder import simulate_flight
    from ins.simulate.sensor_errors import PRESETS
    text = Path(args.plan).read_text()
    preset = PRESETS[tomllib.loads(text).get("imu", {}).get("grade", "tactical")]
    rows = variants(preset)
    if args.quick:
        rows = [r for r in rows if r[0] in ("preset", "preset-gm", "arw-only")]
    fmt = lambda v: " / ".join(f"{x:.1f}" for x in v)  # noqa: E731
    print(f"seed {args.seed}, {Path(args.plan).name}: smoothed attitude, arcsec "
          f"(tilt N / tilt E / heading); late = after the first {LATE_S:g} s\n")
    print("| variant | error RMS | stated sigma RMS | error RMS late | sigma RMS late |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, imu, lines, gm in rows:
            folder = Path(tmp) / name.replace(" ", "_")
            plan = Path(tmp) / f"{folder.name}.toml"
            plan.write_text(plan_variant(text, preset, imu, lines))
            simulate_flight(plan, folder, seed=args.seed, force=True)
            e, s, el, sl = figures(folder, gm)
            print(f"| {name} | {fmt(e)} | {fmt(s)} | {fmt(el)} | {fmt(sl)} |", flush=True)


if __name__ == "__main__":
    main()
