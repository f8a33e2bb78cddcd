"""IMU-GNSS clock offset from the data (ins.time_offset, ins time-offset): a simulated
flight (ins.simulate, the short test plan: turns and a stabilized, nearly level IMU)
with a known offset injected into the GNSS stamps, and the real comma2k19 segment."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ins.errors import InputError
from ins.gnss import read_gnss, write_gnss
from ins.imu_files import write_kfgins_text
from ins.time_offset import estimate_time_offset, shift_gnss

PLAN = Path(__file__).parent / "data" / "flights" / "short.toml"
REAL = Path(__file__).resolve().parents[1].parent / "shared" / "real" / "comma2k19_segment"
INJECTED_S = 0.137


@pytest.fixture(scope="module")
def flight():
    """IMU at 100 Hz and GNSS at 10 Hz (2 cm, 1 cm/s white noise, antenna at the IMU)
    of the short plan; the GNSS stamps LATE by INJECTED_S (GNSS clock - IMU clock)."""
    from ins.simulate.gnss import gnss_times, simulate_gnss
    from ins.simulate.imu_synth import synthesize_imu
    from ins.simulate.plan import load_plan
    from ins.simulate.truth import build_truth
    truth = build_truth(load_plan(PLAN))
    imu = synthesize_imu(truth, 100.0)
    t = gnss_times(truth.t_start + 2.0, truth.t_end - 2.0, 10.0)
    gnss = simulate_gnss(truth, t, np.zeros(3), np.zeros(3), [0.02, 0.02, 0.04],
                         np.random.default_rng(7), velocity=True, sigma_vel_mps=0.01)
    return imu, replace(gnss, time=gnss.time + INJECTED_S)


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

    from ins.imu import ImuLog
    imu, gnss = flight
    C = Rotation.from_euler("ZYX", [90.0, 30.0, 150.0], degrees=True).as_matrix()
    turned = ImuLog(imu.time, imu.dtheta_b @ C, imu.dvel_b @ C)
    a = estimate_time_offset(imu, gnss, source="velocity")
    b = estimate_time_offset(turned, gnss, source="velocity")
    assert abs(a.offset_s - b.offset_s) < 1e-3


def test_negative_offset_and_sign(flight):
    """Stamps EARLY by 0.25 s: the estimate is -0.25 (GNSS clock - IMU clock)."""
    imu, gnss = flight
    early = replace(gnss, time=gnss.time - INJECTED_S - 0.25)
    r = estimate_time_offset(imu, early, source="velocity")
    assert abs(r.offset_s + 0.25) < 0.005


def test_no_information_refused(flight):
    imu, gnss = flight
    straight = replace(gnss, v_n=np.tile([50.0, 0.0, 0.0], (len(gnss), 1)))
    with pytest.raises(InputError, match="no information"):
        estimate_time_offset(imu, straight, source="velocity")
    with pytest.raises(InputError, match="edge of the searched range"):
        estimate_time_offset(imu, replace(gnss, time=gnss.time + 0.6), max_offset_s=0.5)
    with pytest.raises(InputError, match="no velocity columns"):
        estimate_time_offset(imu, replace(gnss, v_n=None, sigma_vel_ned_mps=None))


def test_command(flight, tmp_path, capsys):
    from ins.cli import main
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
    np.testing.assert_allclose(shifted.time, gnss.time - offsets["velocity"], atol=2e-6)
    assert main(["time-offset", "--imu", str(tmp_path / "imu.txt"), "--gnss",
                 str(tmp_path / "nope.txt")]) == 2


@pytest.mark.skipif(not REAL.is_dir(), reason="../shared/real is absent")
def test_real_segment_ublox_stamps():
    """The u-blox fixes of comma2k19: with their UTC epochs the Doppler velocities are
    within a few hundredths of a second of the IMU, the positions lead them by about
    0.09 s; with their boot-clock ARRIVAL stamps the velocities are 0.2 s late.  The
    reference pose itself is on the IMU's clock."""
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
    assert -0.07 < v.offset_s < 0.02 and v.sigma_s < 0.03
    assert -0.13 < p.offset_s < -0.05 and p.sigma_s < 0.03
    assert 0.12 < a.offset_s < 0.22
    ref = comma2k19.read_reference(REAL, boot)
    from ins.gnss import GnssLog
    n = len(ref)
    as_fixes = GnssLog(ref.time, ref.lla, np.ones((n, 3)), ref.v_n, np.ones((n, 3)))
    r = estimate_time_offset(imu, as_fixes, source="velocity")
    assert abs(r.offset_s) < 3 * r.sigma_s + 0.01
