"""Simulator benchmark: 1 h at 200 Hz of a 4-strip block (truth, error-free increments,
sensor errors), peak RSS; pyins's generate_imu on the same truth; the mechanization round
trip of a 30-min flight with turns.

Run: .venv/bin/python bench/bench_simulate.py
"""
import copy
import resource
import time
import tomllib
from pathlib import Path

import numpy as np

from ins.accuracy import compare
from ins.mechanization import NavState, mechanize
from ins.rotation import quat_to_euler
from ins.simulate.imu_synth import synthesize_imu
from ins.simulate.plan import parse_plan
from ins.simulate.sensor_errors import ImuErrorModel, apply_errors
from ins.simulate.truth import build_truth
from ins.trajectory import Trajectory

DEMO = Path(__file__).resolve().parents[1] / "data" / "flights" / "demo.toml"


def peak_rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main():
    with open(DEMO, "rb") as f:
        d = tomllib.load(f)
    d = copy.deepcopy(d)
    d["block"]["strip_length_m"] = 15000.0          # 4 strips, > 1 h in all
    plan = parse_plan(d, "demo.toml (15 km strips)")
    t = time.perf_counter()
    truth = build_truth(plan)
    t_truth = time.perf_counter() - t
    t_end = truth.t_start + 3600.0
    t = time.perf_counter()
    log = synthesize_imu(truth, 200.0, truth.t_start, t_end)
    t_synth = time.perf_counter() - t
    t = time.perf_counter()
    noisy = apply_errors(log, ImuErrorModel.preset("tactical"), seed=1)
    t_err = time.perf_counter() - t
    print(f"flight {truth.t_end - truth.t_start:.0f} s, {len(truth.strips)} strips; "
          f"simulated 3600 s at 200 Hz = {len(log)} epochs")
    print(f"  truth build        {t_truth:8.2f} s")
    print(f"  increments (GL4)   {t_synth:8.2f} s")
    print(f"  sensor errors      {t_err:8.2f} s")
    print(f"  total              {t_truth + t_synth + t_err:8.2f} s, peak RSS {peak_rss_mb():.0f} MB")
    del noisy

    # pyins on the same truth (sampled at 200 Hz)
    t = time.perf_counter()
    s = truth.evaluate(log.time)
    rph = np.degrees(quat_to_euler(s.q_nb))
    rph[:, 2] = np.degrees(np.unwrap(np.radians(rph[:, 2])))
    lla = np.column_stack([np.degrees(s.lla[:, :2]), s.lla[:, 2]])
    t_sample = time.perf_counter() - t
    from pyins import sim
    t = time.perf_counter()
    _, imu = sim.generate_imu(log.time - log.time[0], lla, rph, s.v_n, sensor_type="increment")
    t_py = time.perf_counter() - t
    g = imu[["gyro_x", "gyro_y", "gyro_z"]].to_numpy()[1:]
    a = imu[["accel_x", "accel_y", "accel_z"]].to_numpy()[1:]
    print(f"pyins generate_imu on the same truth: {t_py:.2f} s (+ {t_sample:.2f} s sampling "
          f"the truth), peak RSS now {peak_rss_mb():.0f} MB")
    print(f"  max |dtheta - pyins| {np.abs(g - log.dtheta_b[1:]).max():.3g} rad, "
          f"max |dvel - pyins| {np.abs(a - log.dvel_b[1:]).max():.3g} m/s "
          f"(gravity models differ)")
    del imu, s, g, a

    # round trip: 30 min from the ground start (static, take-off, climb, strip, turn)
    t_end = truth.t_start + 1800.0
    sub = log.slice_time(None, t_end)
    s0 = truth.evaluate(sub.time[0])
    nav = mechanize(sub, NavState(s0.lla[0], s0.v_n[0], s0.q_nb[0]))
    s = truth.evaluate(sub.time)
    e = compare(nav, Trajectory(time=s.time, lla=s.lla, v_n=s.v_n, q_nb=s.q_nb)).summary()
    print("mechanization of the error-free increments, 30 min with take-off, climb, "
          "strips and turns:")
    print(f"  max horizontal {1e3 * e['horizontal_m']['max']:.3f} mm, max down "
          f"{1e3 * abs(e['down_m']['max']):.4f} mm, max velocity {1e3 * e['vel_3d_mps']['max']:.2e} mm/s")
    print("  max attitude " + ", ".join(f"{k} {abs(e[k]['max']):.2e}" for k in
                                        ("tilt_n_arcsec", "tilt_e_arcsec", "heading_arcsec"))
          + " arcsec")


if __name__ == "__main__":
    main()
