#!/usr/bin/env python3
"""Exterior orientation: interpolation error at 200 Hz, speed, and the chain on a flight.

Prints
- the interpolation error (position, velocity, attitude "cubic" and "slerp") on the
  closed-form turn of tests/test_interpolation.py at 200 Hz, 100 Hz and 50 Hz, and
  with 4x stronger turbulence (1.4 rad/s^2),
- the speed of compute_eo for 1e4 and 1e5 events (wall time, best of 3) and the peak
  memory of the process,
- the chain on a simulated 200 Hz flight (photogrammetry.simulate;
  tests/data/flights/short.toml): largest difference from the simulator's true EO, in
  mm and arcsec.

Usage: python bench/bench_eo.py [--work DIR]
"""
import argparse
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
ARCSEC = np.pi / 180.0 / 3600.0
sys.path.insert(0, str(ROOT / "tests"))

from test_interpolation import Turn, attitude_error_arcsec  # noqa: E402

from ins.nav.earth import ned_offset  # noqa: E402
from ins.nav.interpolation import interpolate_trajectory  # noqa: E402
from ins.nav.rotation import euler_to_quat  # noqa: E402
from photogrammetry.orientation.camera import NADIR_AXES, CameraMounting  # noqa: E402
from photogrammetry.orientation.exposure import compute_eo, read_eo_csv  # noqa: E402
from photogrammetry.orientation.mapping import EnuFrame  # noqa: E402


def interpolation_errors():
    print("interpolation error on the closed-form turn (max over 2000 random events)")
    print(f"{'case':<34}{'pos um':>10}{'vel mm/s':>10}{'cubic as':>12}{'slerp as':>12}")
    rng = np.random.default_rng(1)
    for label, rate, amp in (("200 Hz, 0.34 rad/s^2 roll accel", 200, 2.0),
                             ("100 Hz, 0.34 rad/s^2", 100, 2.0),
                             ("50 Hz, 0.34 rad/s^2", 50, 2.0),
                             ("200 Hz, 1.4 rad/s^2", 200, 8.0)):
        turn = Turn()
        turn.roll_amp = np.deg2rad(amp)
        t = np.arange(0.0, 60.0 + 1e-9, 1.0 / rate)
        traj = turn.trajectory(t)
        te = np.sort(rng.uniform(0, 60.0, 2000))
        out = interpolate_trajectory(traj, te)
        slerp = interpolate_trajectory(traj, te, method="slerp")
        q_true = euler_to_quat(turn.rpy(te))
        pos = np.linalg.norm(ned_offset(turn.lla(te), out.lla), axis=1).max() * 1e6
        vel = np.abs(out.v_n - turn.v_n(te)).max() * 1e3
        print(f"{label:<34}{pos:>10.2g}{vel:>10.2g}"
              f"{attitude_error_arcsec(out.q_nb, q_true).max():>12.2g}"
              f"{attitude_error_arcsec(slerp.q_nb, q_true).max():>12.2g}")


def speed():
    turn = Turn()
    t = np.arange(0.0, 600.0 + 1e-9, 0.005)
    traj = turn.trajectory(t)
    frame = EnuFrame(turn.lat0, turn.lon0, 0.0)
    mount = CameraMounting(NADIR_AXES, [0.1, 0.2, -0.5], np.deg2rad([0.01, -0.02, 0.05]))
    print(f"\ncompute_eo speed ({len(t)} trajectory epochs, ENU, cubic attitude)")
    for n in (10_000, 100_000):
        te = np.sort(np.random.default_rng(2).uniform(0, 600.0, n))
        ids = [f"IMG_{i}" for i in range(n)]
        best = np.inf
        for _ in range(3):
            t0 = time.perf_counter()
            compute_eo(traj, ids, te, mount, frame)
            best = min(best, time.perf_counter() - t0)
        print(f"  {n:>7} events: {best:.3f} s ({n / best:,.0f} events/s)")
    print(f"  peak RSS of this process: "
          f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")


def flight(work):
    try:
        from photogrammetry.simulate.folder import simulate_flight
    except ImportError:
        print("\nflight: photogrammetry.simulate not available")
        return
    from photogrammetry.cli.main import main
    plan = work / "short200.toml"
    text = (ROOT / "tests/data/flights/short.toml").read_text()
    plan.write_text(text.replace("rate_hz = 100.0", "rate_hz = 200.0", 1))
    folder = simulate_flight(plan, work / "flight", seed=3, force=True)
    print("\nchain on a simulated 200 Hz flight (photogrammetry eo FLIGHT_DIR) vs eo_true")
    for system, truth in (("phi-omega-kappa", "eo_true.csv"),
                          ("omega-phi-kappa", "eo_true_omega-phi-kappa.csv")):
        out = work / f"eo_{system}.csv"
        main(["eo", str(folder), "--system", system, "-q", "-o", str(out)])
        a, b = read_eo_csv(out), read_eo_csv(folder / truth)
        dpos = np.abs(a.position - b.position).max(axis=0) * 1e3
        dang = np.abs(np.angle(np.exp(1j * (a.angles - b.angles)))).max(axis=0) / ARCSEC
        print(f"  {system}: {len(a)} images, max |dX dY dZ| = "
              + " ".join(f"{v:.4f}" for v in dpos) + " mm, max |d angles| = "
              + " ".join(f"{v:.2g}" for v in dang) + " arcsec")
    print("  (floor: truth.nav stores h to 1e-5 m and angles to 1e-9 deg)")


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", type=Path, help="working folder (default: a temporary one)")
    args = ap.parse_args()
    interpolation_errors()
    speed()
    if args.work:
        args.work.mkdir(parents=True, exist_ok=True)
        flight(args.work)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            flight(Path(tmp))


if __name__ == "__main__":
    main()
