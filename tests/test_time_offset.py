"""IMU-GNSS clock offset from the data (ins.estimation.tools.time_offset, ins time-offset): a simulated
flight (ins.simulate, the short test plan: turns and a stabilized, nearly level IMU)
with a known offset injected into the GNSS stamps, and the real comma2k19 segment."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ins.common.errors import InputError
from ins.estimation.tools.time_offset import estimate_time_offset, shift_gnss
from ins.io.gnss import read_gnss, write_gnss
from ins.io.imu_files import write_kfgins_text

PLAN = Path(__file__).parent / "data" / "flights" / "short.toml"
REAL = Path(__file__).resolve().parents[1].parent / "shared" / "real" / "comma2k19_segment"
INJECTED_S = 0.137


@pytest.fixture(scope="module")
def flight():
    """IMU at 100 Hz and GNSS at 10 Hz (2 cm, 1 cm/s white noise, antenna at the IMU)
    of the short plan, with INJECTED_S injected by the simulator (IMU clock - GNSS
    clock: a record stamped t holds the truth at IMU time t + INJECTED_S, the sign of
    the filter's time_offset state)."""
    from ins.simulate.gnss import gnss_times, simulate_gnss
    from ins.simulate.imu_synth import synthesize_imu
    from ins.simulate.plan_read import load_plan
    from ins.simulate.truth import build_truth
    truth = build_truth(load_plan(PLAN))
    imu = synthesize_imu(truth, 100.0)
    t = gnss_times(truth.t_start + 2.0, truth.t_end - 2.0, 10.0)
    gnss = simulate_gnss(truth, t, np.zeros(3), np.zeros(3), [0.02, 0.02, 0.04],
                         np.random.default_rng(7), velocity=True, sigma_vel_mps=0.01,
                         time_offset_s=INJECTED_S)
    return imu, gnss


@pytest.mark.parametrize("source", ["velocity", "position"])
def test_injected_offset_recovered(flight, source):
    imu, gnss = flight
    r = estimate_time_offset(imu, gnss, source=source)
    assert abs(r.offset_s - INJECTED_S) < 0.002          # 2 ms of 137: sub-sample (10 ms IMU)
    assert abs(r.offset_s - INJECTED_S) < 4 * r.sigma_s   # the sigma is not optimistic
    # 2 cm position noise differenced at 10 Hz is 0.3 m/s of velocity noise
    assert 1e-4 < r.sigma_s < (0.005 if source == "velocity" else 0.05)
    # the shifted log is on the IMU's time scale: nothing left to find
    again = estimate_time_offset(imu, shift_gnss(gnss, r.offset_s), source=source)
    assert abs(again.offset_s) < 0.002


def test_any_imu_attitude(flight):
    """The same increments in axes turned by a constant rotation (yaw 90, pitch 30,
    roll 150 deg: far from FRD) give the same offset: the attitude is fitted."""
    from scipy.spatial.transform import Rotation

    from ins.nav.imu import ImuLog
    imu, gnss = flight
    C = Rotation.from_euler("ZYX", [90.0, 30.0, 150.0], degrees=True).as_matrix()
    turned = ImuLog(imu.time, imu.dtheta_b @ C, imu.dvel_b @ C)
    a = estimate_time_offset(imu, gnss, source="velocity")
    b = estimate_time_offset(turned, gnss, source="velocity")
    assert abs(a.offset_s - b.offset_s) < 1e-3


def test_negative_offset_and_sign(flight):
    """Stamps LATE by 0.25 s (a record stamped t holds the IMU time t - 0.25, as a
    fix stamped on its arrival): the estimate is -0.25 (IMU clock - GNSS clock), and
    adding it to the stamps ([gnss] time_shift_s) puts them on the IMU's clock."""
    imu, gnss = flight
    late = replace(gnss, time=gnss.time + INJECTED_S + 0.25)
    r = estimate_time_offset(imu, late, source="velocity")
    assert abs(r.offset_s + 0.25) < 0.005
    np.testing.assert_allclose(shift_gnss(late, -0.25).time, gnss.time + INJECTED_S)  # IMU time


def test_no_information_refused(flight):
    imu, gnss = flight
    straight = replace(gnss, v_n=np.tile([50.0, 0.0, 0.0], (len(gnss), 1)))
    with pytest.raises(InputError, match="no information"):
        estimate_time_offset(imu, straight, source="velocity")
    with pytest.raises(InputError, match="edge of the searched range"):
        estimate_time_offset(imu, replace(gnss, time=gnss.time - 0.6), max_offset_s=0.5)
    with pytest.raises(InputError, match="no velocity columns"):
        estimate_time_offset(imu, replace(gnss, v_n=None, sigma_vel_ned_mps=None))


def test_command(flight, tmp_path, capsys):
    from ins.cli.main import main
    imu, gnss = flight
    write_kfgins_text(tmp_path / "imu.txt", imu)
    write_gnss(tmp_path / "gnss.txt", gnss)
    out = tmp_path / "shifted.txt"
    code = main(["time-offset", "--imu", str(tmp_path / "imu.txt"), "--gnss",
                 str(tmp_path / "gnss.txt"), "-o", str(out)])
    text = capsys.readouterr().out
    assert code == 0
    offsets = {line.split()[0]: float(line.split()[2]) for line in text.splitlines()
               if line.startswith(("position", "velocity"))}
    assert set(offsets) == {"position", "velocity"}
    for value in offsets.values():
        assert abs(value - INJECTED_S) < 0.005
    shifted = read_gnss(out)
    np.testing.assert_allclose(shifted.time, gnss.time + offsets["velocity"], atol=2e-6)
    assert main(["time-offset", "--imu", str(tmp_path / "imu.txt"), "--gnss",
                 str(tmp_path / "nope.txt")]) == 2


@pytest.mark.skipif(not REAL.is_dir(), reason="../shared/real is absent")
def test_real_segment_ublox_stamps():
    """The u-blox fixes of comma2k19: with their UTC epochs the Doppler velocities are
    within a few hundredths of a second of the IMU, the positions lead them by about
    0.09 s (a position stamped t holds the IMU time t + 0.09); with their boot-clock
    ARRIVAL stamps the velocities are 0.2 s late (offset -0.2, IMU clock - GNSS clock).
    The reference pose itself is on the IMU's clock."""
    import sys
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
    import comma2k19
    week, boot, _ = comma2k19.boot_to_gps(REAL)
    imu = comma2k19.read_imu(REAL, boot)
    utc, lag = comma2k19.read_ublox(REAL, boot, week, "utc")
    arrival, _ = comma2k19.read_ublox(REAL, boot, week, "arrival")
    assert 0.19 < lag < 0.21
    v = estimate_time_offset(imu, utc, source="velocity")
    p = estimate_time_offset(imu, utc, source="position")
    a = estimate_time_offset(imu, arrival, source="velocity")
    assert -0.02 < v.offset_s < 0.07 and v.sigma_s < 0.03
    assert 0.05 < p.offset_s < 0.13 and p.sigma_s < 0.03
    assert -0.22 < a.offset_s < -0.12
    ref = comma2k19.read_reference(REAL, boot)
    from ins.io.gnss_log import GnssLog
    n = len(ref)
    as_fixes = GnssLog(ref.time, ref.lla, np.ones((n, 3)), ref.v_n, np.ones((n, 3)))
    r = estimate_time_offset(imu, as_fixes, source="velocity")
    assert abs(r.offset_s) < 3 * r.sigma_s + 0.01


@pytest.mark.slow
def test_command_and_filter_state_agree_in_sign_and_value(flight, tmp_path, capsys):
    """One convention: on the simulated flight with INJECTED_S injected by the simulator,
    the offset that `ins time-offset` prints and the filter's time_offset state that
    `ins process` writes into states.txt (from the true start, IMU and GNSS files as
    they are) both come back as +INJECTED_S (IMU clock - GNSS clock); and pasting the
    printed value into [gnss] time_shift_s leaves the filter nothing to find.
    Measured: printed 0.1360; the state 0.13685 +- 0.00016 s as is, +0.88 ms after the
    shift (positions and velocities; positions alone 0.13681 and +0.84 ms).  Before the
    GNSS velocity prediction was carried by the node's acceleration over the offset, the
    velocities left -4.1 +- 0.09 ms after the shift."""
    from ins.cli.main import main
    from ins.simulate.plan_read import load_plan
    from ins.simulate.truth import build_truth
    imu, gnss = flight
    write_kfgins_text(tmp_path / "imu.txt", imu)
    write_gnss(tmp_path / "gnss.txt", gnss)
    assert main(["time-offset", "--imu", str(tmp_path / "imu.txt"), "--gnss",
                 str(tmp_path / "gnss.txt"), "--source", "velocity"]) == 0
    printed = float(next(ln.split()[2] for ln in capsys.readouterr().out.splitlines()
                         if ln.startswith("velocity")))
    assert abs(printed - INJECTED_S) < 0.003
    t0 = float(imu.time[0])
    s = build_truth(load_plan(PLAN)).evaluate(np.array([t0]))
    from scipy.spatial.transform import Rotation
    rpy = Rotation.from_quat(s.q_nb[0]).as_euler("ZYX", degrees=True)[::-1]
    lat, lon = (float(x) for x in np.rad2deg(s.lla[0, :2]))
    h = float(s.lla[0, 2])

    def run(name, shift_s, velocity=True):
        cfg = tmp_path / f"{name}.toml"
        cfg.write_text(
            '[files]\nimu = "imu.txt"\ngnss = "gnss.txt"\n'
            f"[gnss]\nlever_arm_b_m = [0.0, 0.0, 0.0]\ntime_shift_s = {shift_s!r}\n"
            f"use_velocity = {str(velocity).lower()}\n"
            f"[initial]\nlat_deg = {lat!r}\nlon_deg = {lon!r}\nh_m = {h!r}\n"
            f"vel_ned_mps = {s.v_n[0].tolist()}\nrpy_deg = {rpy.tolist()}\ntime_s = {t0!r}\n"
            "pos_std_ned_m = [0.1, 0.1, 0.1]\nvel_std_ned_mps = [0.05, 0.05, 0.05]\n"
            "att_std_deg = [0.05, 0.05, 0.2]\n"
            "[imu_noise]\narw_deg_sqrth = 0.01\nvrw_mps_sqrth = 0.01\n"
            "gyro_bias_std_dph = 0.1\naccel_bias_std_mgal = 50.0\n"
            "gyro_scale_std_ppm = 10.0\naccel_scale_std_ppm = 10.0\ncorr_time_h = 1.0\n"
            '[states]\nlayout = "kfgins"\ntime_offset = true\ntime_offset_std_ms = 300.0\n')
        out = tmp_path / name
        assert main(["process", "--config", str(cfg), "-o", str(out), "--no-plots"]) == 0
        rows = np.loadtxt(out / "states.txt")
        return rows[-1, 1] * 1e-3, rows[-1, 2] * 1e-3       # s
    state, sd = run("as_is", 0.0)
    assert abs(state - INJECTED_S) < max(3 * sd, 0.001), (state, sd)
    assert sd < 0.002 and abs(state - printed) < 0.005     # same sign, same value
    pos_only, sd_p = run("positions", 0.0, velocity=False)
    assert abs(pos_only - state) < 3 * sd_p
    again, sd2 = run("shifted", printed)
    # what is left is the command's own error: INJECTED_S - printed
    assert abs(again - (INJECTED_S - printed)) < max(3 * sd2, 0.0005), (again, sd2)


def test_positions_and_velocities_offset_differently(flight):
    """Positions stamped +0.10 s and velocities -0.025 s from the IMU's clock (the
    simulator's velocity_time_offset_s): each source recovers its own within 3 sigma
    and the two differ by far more than their sigmas."""
    from ins.simulate.gnss import gnss_times, simulate_gnss
    from ins.simulate.plan_read import load_plan
    from ins.simulate.truth import build_truth
    imu, _ = flight
    truth = build_truth(load_plan(PLAN))
    t = gnss_times(truth.t_start + 2.0, truth.t_end - 2.0, 10.0)
    # 5 mm positions (differenced at 10 Hz: 0.07 m/s of velocity noise)
    gnss = simulate_gnss(truth, t, np.zeros(3), np.zeros(3), [0.005, 0.005, 0.01],
                         np.random.default_rng(8), velocity=True, sigma_vel_mps=0.01,
                         time_offset_s=0.10, velocity_time_offset_s=-0.025)
    pos = estimate_time_offset(imu, gnss, source="position")
    vel = estimate_time_offset(imu, gnss, source="velocity")
    assert abs(pos.offset_s - 0.10) < 3 * pos.sigma_s
    assert abs(vel.offset_s + 0.025) < 3 * vel.sigma_s
    assert pos.offset_s - vel.offset_s > 5 * np.hypot(pos.sigma_s, vel.sigma_s)
    print(f"flight: position {pos.offset_s:+.4f} +- {pos.sigma_s:.4f} s, velocity "
          f"{vel.offset_s:+.4f} +- {vel.sigma_s:.4f} s")
