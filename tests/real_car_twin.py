"""The simulated twin of the real car of ``../shared/real/rtklibexplorer_drive``: the
consumer car of :func:`ins.simulate.ground.write_journey` (rest at the start, 4 Hz
centimetre RTK fixes, 15 s outages) with what that real log shows and the datasheet
does not:

- vibration: the increments carry a differenced white sequence ``n_k - n_k-1`` per axis
  (its sum telescopes: nothing of it survives the integration beyond one sample, but the
  100 Hz samples scatter as a gyro of :data:`VIBRATION_ARW_DEG_SQRTH` and an
  accelerometer of :data:`VIBRATION_VRW_MPS_SQRTH` read as white noise), 4 times as
  strong while driving as at rest;
- scale errors of a few per cent (:data:`GYRO_SCALE`, :data:`ACCEL_SCALE`), beyond the
  consumer datasheet's 1 %;
- the receiver's velocities 0.125 s behind its positions, NOT stated in the config
  (the user does not know it).

The truth is the simulator's; the config holds only the lever arm and the mounting.
"""
import numpy as np

from ins.io.imu_files import read_imu, write_kfgins_text
from ins.nav.imu import ImuLog
from ins.simulate.ground import write_journey

VIBRATION_ARW_DEG_SQRTH = (3.0, 14.0, 1.0)
VIBRATION_VRW_MPS_SQRTH = (0.5, 0.6, 1.5)
GYRO_SCALE = (0.01, 0.03, -0.02)
ACCEL_SCALE = (0.005, -0.01, 0.03)
VELOCITY_LAG_S = 0.125


def write_twin(folder, seed=0):
    """Write the twin into ``folder``; returns ``(truth, journey, config_path)``."""
    truth, journey, cfg = write_journey("consumer-car", folder, seed=seed,
                                        velocity_latency_s=VELOCITY_LAG_S)
    imu = read_imu(folder / "imu.txt")
    rng = np.random.default_rng(seed + 7)
    dt = float(np.median(np.diff(imu.time)))
    moving_s = journey.speed_steps[0][0]            # the first speed step ends the rest
    amp = np.where((imu.time - truth.t_start) < moving_s, 1.0, 4.0)[:, None]
    arw = np.deg2rad(np.asarray(VIBRATION_ARW_DEG_SQRTH)) / 60.0      # rad/sqrt(s)
    vrw = np.asarray(VIBRATION_VRW_MPS_SQRTH) / 60.0                  # m/s/sqrt(s)
    # a sample of the differenced sequence has twice the variance of n_k: scatter of
    # the rate w = dtheta/dt reads as arw/sqrt(dt) when std(n) = arw sqrt(dt) / sqrt(2)
    n_w = rng.standard_normal((len(imu.time) + 1, 3)) * arw * np.sqrt(dt / 2.0)
    n_f = rng.standard_normal((len(imu.time) + 1, 3)) * vrw * np.sqrt(dt / 2.0)
    dth = imu.dtheta_b * (1.0 + np.asarray(GYRO_SCALE)) + amp * np.diff(n_w, axis=0)
    dv = imu.dvel_b * (1.0 + np.asarray(ACCEL_SCALE)) + amp * np.diff(n_f, axis=0)
    write_kfgins_text(folder / "imu.txt", ImuLog(imu.time, dth, dv))
    text = "".join(ln + "\n" for ln in cfg.read_text().splitlines()
                   if not ln.startswith("velocity_time_shift_s"))
    cfg.write_text(text)
    return truth, journey, cfg
