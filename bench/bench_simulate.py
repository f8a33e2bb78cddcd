"""Simulator benchmark: 1 h at 200 Hz of a 4-strip block (truth, error-free increments,
sensor errors), peak RSS; pyins's generate_imu on the same truth; the mechanization round
trip of a 30-min flight with take-off, climb, strips and turns; the strip placement on
the geodetic path; the mount on the strips and in the turns (demo plan).

Run: .venv/bin/python bench/bench_simulate.py
"""
import copy
import resource
import time
from pathlib import Path

import numpy as np
import tomllib

from ins.nav.accuracy import compare
from ins.nav.mechanization import NavState, mechanize
from ins.nav.rotation import quat_to_euler
from ins.nav.trajectory import Trajectory
from ins.simulate.imu_synth import GL_NODES, synthesize_imu
from ins.simulate.plan_read import load_plan, parse_plan
from ins.simulate.sensor_errors import ImuErrorModel, apply_errors
from ins.simulate.truth import build_truth

DEMO = Path(__file__).resolve().parents[1] / "data" / "flights" / "demo.toml"


def peak_rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def demo_variant(**changes):
    with open(DEMO, "rb") as f:
        d = copy.deepcopy(tomllib.load(f))
    for key, value in changes.items():
        section, name = key.split("__")
        d[section][name] = value
    return parse_plan(d, "demo.toml (" + ", ".join(f"{k.split('__')[1]}={v}" for k, v in
                                                   changes.items()) + ")")


def speed():
    plan = demo_variant(block__n_strips=4, block__strip_length_m=50000.0)
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
    print(f"{plan.source}: flight {truth.t_end - truth.t_start:.0f} s, {len(truth.strips)} "
          f"strips; simulated 3600 s at 200 Hz = {len(log)} epochs")
    print(f"  truth build        {t_truth:8.2f} s")
    print(f"  increments (GL{GL_NODES})   {t_synth:8.2f} s")
    print(f"  sensor errors      {t_err:8.2f} s")
    print(f"  total              {t_truth + t_synth + t_err:8.2f} s, peak RSS "
          f"{peak_rss_mb():.0f} MB")
    del noisy
    return truth, log


def pyins_same_truth(truth, log):
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


def round_trip():
    plan = demo_variant(flight__start="ground", block__n_strips=4,
                        block__strip_length_m=20000.0)
    truth = build_truth(plan)
    t_end = truth.t_start + 1800.0
    n_turns = sum(st.t_end < t_end for st in truth.strips[:-1])
    for nodes in sorted({GL_NODES, 4}):
        log = synthesize_imu(truth, 200.0, truth.t_start, t_end, nodes=nodes)
        s0 = truth.evaluate(log.time[0])
        nav = mechanize(log, NavState(s0.lla[0], s0.v_n[0], s0.q_nb[0]))
        s = truth.evaluate(log.time)
        e = compare(nav, Trajectory(time=s.time, lla=s.lla, v_n=s.v_n, q_nb=s.q_nb)).summary()
        print(f"mechanization of the error-free increments (GL{nodes}), 30 min: static "
              f"minute, take-off, climb, {n_turns} turns of 25 deg bank:")
        print(f"  max horizontal {1e3 * e['horizontal_m']['max']:.3f} mm, max down "
              f"{1e3 * abs(e['down_m']['max']):.4f} mm, max velocity "
              f"{1e3 * e['vel_3d_mps']['max']:.2e} mm/s")
        print("  max attitude " + ", ".join(
            f"{k} {abs(e[k]['max']):.2e}" for k in ("tilt_n_arcsec", "tilt_e_arcsec",
                                                     "heading_arcsec")) + " arcsec")


def demo_figures():
    plan = load_plan(DEMO)
    t = time.perf_counter()
    truth = build_truth(plan)
    t_build = time.perf_counter() - t
    print(f"demo plan: {truth.t_end - truth.t_start:.0f} s, {len(truth.strips)} strips, "
          f"spacing {plan.strip_spacing_m:.0f} m, truth built in {t_build:.2f} s")
    err = np.hypot(*truth.strip_start_error_m.T)
    print(f"  strip starts vs planned points (local level at the origin): max "
          f"{1e3 * err.max():.2f} mm")
    on = np.concatenate([np.linspace(st.t_start, st.t_end, 2000) for st in truth.strips])
    s = truth.evaluate(on)
    tilt = np.degrees(np.abs(quat_to_euler(s.q_nb)[:, :2]).max())
    print("  on the strips: max |mount| roll/pitch/yaw "
          + "/".join(f"{x:.2f}" for x in np.degrees(np.abs(s.mount_rpy).max(0)))
          + f" deg (knee 80 % of 5/5/30), platform tilt max {tilt:.3f} deg")
    s = truth.evaluate(np.linspace(truth.t_start, truth.t_end, 20000))
    roll_a = np.degrees(np.abs(quat_to_euler(s.q_na)[:, 0]).max())
    roll_b = np.degrees(np.abs(quat_to_euler(s.q_nb)[:, 0]).max())
    print(f"  whole flight: aircraft roll max {roll_a:.1f} deg, mount roll max "
          f"{np.degrees(np.abs(s.mount_rpy[:, 0]).max()):.3f} deg (saturated), platform "
          f"roll max {roll_b:.1f} deg; mount rate max "
          + "/".join(f"{x:.1f}" for x in np.degrees(np.abs(s.mount_rate).max(0))) + " deg/s")


def whole_folder():
    """``ins simulate`` as a user runs it: the same 1 h, 4-strip plan written as a flight
    folder (IMU, truth, GNSS, mount log, exposures, tie points), in a child process."""
    import os
    import subprocess
    import sys
    import tempfile

    import tomli_w
    with open(DEMO, "rb") as f:
        d = tomllib.load(f)
    d["block"].update(n_strips=4, strip_length_m=50000.0)
    with tempfile.TemporaryDirectory() as tmp:
        plan = Path(tmp) / "one_hour.toml"
        plan.write_text(tomli_w.dumps(d))
        cmd = [str(Path(sys.executable).parent / "ins"), "simulate", str(plan), "-o",
               str(Path(tmp) / "flight"), "-q"]
        t = time.perf_counter()
        proc = subprocess.Popen(cmd)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t
        if status:
            raise SystemExit("ins simulate failed")
        man = tomllib.loads((Path(tmp) / "flight" / "manifest.toml").read_text())
        size = sum(p.stat().st_size for p in (Path(tmp) / "flight").iterdir())
        fl = man["flight"]
        print(f"ins simulate, 4 strips of 50 km ({fl['end_time_s'] - fl['start_time_s']:.0f} s "
              f"at {fl['imu_rate_hz']:.0f} Hz, {fl['n_images']} images, "
              f"{fl['n_tiepoint_observations']} tie-point observations): wall {wall:.1f} s, "
              f"peak RSS {usage.ru_maxrss / 1024:.0f} MB, folder {size / 1e6:.0f} MB")


def main():
    whole_folder()
    truth, log = speed()
    pyins_same_truth(truth, log)
    del truth, log
    round_trip()
    demo_figures()


if __name__ == "__main__":
    main()
