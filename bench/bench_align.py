"""Static alignment without GNSS (``ins align``): heading error against its stated sigma
over 100 seeds of a simulated tactical IMU at rest at 30 deg latitude, 5 and 15 min.

The IMU: the simulator's tactical preset (ARW 0.12 deg/sqrt(h), gyro instability 0.5
deg/h over 1 h, scale factors, non-orthogonality, quantization) with turn-on biases
drawn per seed (gyro 1 deg/h, accelerometer 1000 mGal per axis); the attitude drawn per
seed.  Two modes: the priors given (gyro bias sigma hypot(1, 0.5) deg/h, ARW 0.12) and
everything estimated from the log.  Prints per case the RMS of error/sigma, the
fraction within 1 and 2 sigma, the RMS error and the mean stated sigma.

    .venv/bin/python bench/bench_align.py
"""
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_align import tactical_log, tactical_priors  # noqa: E402

from ins.estimation.alignment.fine import align_at_rest  # noqa: E402


def run(minutes, mode, lat_deg=30.0, seeds=100):
    lat = np.deg2rad(lat_deg)
    z, err, sig, unknown = [], [], [], 0
    for seed in range(seeds):
        imu, rpy = tactical_log(seed, lat, 60.0 * minutes)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            al = align_at_rest(imu, [lat, 0.3, 50.0],
                               **(tactical_priors() if mode == "given" else {}))
        if not al.heading_known:
            unknown += 1
            continue
        d = (al.rpy[2] - np.deg2rad(rpy[2]) + np.pi) % (2 * np.pi) - np.pi
        z.append(d / al.rpy_std[2])
        err.append(d)
        sig.append(al.rpy_std[2])
    z = np.array(z)
    return dict(n=len(z), unknown=unknown, rms_z=np.sqrt(np.mean(z ** 2)),
                within1=np.mean(np.abs(z) < 1), within2=np.mean(np.abs(z) < 2),
                rms_err_deg=np.rad2deg(np.sqrt(np.mean(np.square(err)))),
                mean_sigma_deg=np.rad2deg(np.mean(sig)))


def main():
    print(f"{'window':>7} {'priors':>7} {'n':>4} {'unknown':>8} {'RMS e/s':>8} {'<1 s':>6} "
          f"{'<2 s':>6} {'RMS err deg':>12} {'mean sigma deg':>15}")
    for minutes in (5, 15):
        for mode in ("given", "log"):
            t0 = time.perf_counter()
            r = run(minutes, mode)
            print(f"{minutes:>5} m {mode:>7} {r['n']:>4} {r['unknown']:>8} {r['rms_z']:>8.3f} "
                  f"{r['within1']:>6.2f} {r['within2']:>6.2f} {r['rms_err_deg']:>12.3f} "
                  f"{r['mean_sigma_deg']:>15.3f}   ({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
