"""Centre bias on Hapke laws other than the limb fit's basis term (w = 0.25).

The limb fit's fourth basis disk is Hapke's isotropic multiple scattering for a
single-scattering albedo w = 0.25 (`photogrammetry.lunar._limb_kernels.HAPKE_W`); any
phase function and opposition surge are then in the span.  This script patches other
parameters into ``tests/lunar_truth.py``'s ``hapke`` law (the independent renderer) and
prints the bias along the Sun (px, mean +- standard error of 4 images; blur 0.8 px, noise
3/3000, as in bench_lunar_bias.py) at R = 20 / 40 px and phase 60 / 120 / 140 deg.

Run: ``.venv/bin/python bench/bench_lunar_hapke_albedo.py``.

Measured (2026-11-24, four-law basis):  w = 0.1: at most 0.006 px; w = 0.5: 0.005 px;
w = 0.9 (a bright icy surface, not the Moon's 0.2-0.3): -0.002 to -0.074 px; w = 0.25
with b = +0.3 and B0 = 2 (in the span): 0.006 px.
"""
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "bench"))

import bench_lunar_bias as bench  # noqa: E402
import lunar_truth  # noqa: E402

_original = lunar_truth.brightness
PARAMS = {"p": (0.25, 1.0, 0.06, -0.3)}          # w, B0, h, b (Henyey-Greenstein)


def brightness(law, mu0, mu, phase):
    """``lunar_truth.brightness`` with the Hapke parameters of ``PARAMS``."""
    if law != "hapke":
        return _original(law, mu0, mu, phase)
    w, b0, h, b = PARAMS["p"]
    lit = mu0 > 0
    m0, m = np.where(lit, mu0, 0.0), np.maximum(mu, 1e-12)
    gamma = np.sqrt(1 - w)

    def H(x):
        return (1 + 2 * x) / (1 + 2 * gamma * x)
    p = (1 - b * b) / (1 + 2 * b * np.cos(phase) + b * b) ** 1.5
    surge = b0 / (1 + np.tan(phase / 2) / h)
    out = w / 4 * m0 / (m0 + m) * ((1 + surge) * p + H(m0) * H(m) - 1)
    return np.where(lit, out, 0.0)


def main():
    lunar_truth.brightness = brightness
    print("Hapke (w, B0, h, b), R_px: bias along the Sun at phase 60 / 120 / 140 deg, px")
    for prm in [(0.1, 1.0, 0.06, -0.3), (0.5, 1.0, 0.06, -0.3), (0.9, 1.0, 0.06, -0.3),
                (0.25, 2.0, 0.06, 0.3)]:
        PARAMS["p"] = prm
        for R in (20.0, 40.0):
            out = [bench.cell("hapke", p, R, 4) for p in (60, 120, 140)]
            print(f"{prm} R={R:.0f}: " + "  ".join(f"{b:+.4f}+-{se:.4f}" for b, se, _ in out),
                  flush=True)


if __name__ == "__main__":
    main()
