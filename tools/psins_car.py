"""The PSINS car (``../shared/real/psins_vehicle/transfer_align_fog_mems.mat``) as a new
user would process it: the car's MEMS IMU (100 Hz, biases of hundreds of deg/h), GNSS
emulated from the navigation-grade FOG INS's positions with 1 m noise at 1 Hz, no
attitude given (the car moves from the first second), and the FOG INS as the reference.

PSINS's conventions, checked against the data: navigation frame east-north-up, body
right-forward-up, Euler angles ``[pitch, roll, yaw]`` with yaw counter-clockwise from
north: our heading is ``-yaw`` (the FOG's track then sits 4.5 deg from it, constant:
the FOG's mounting in the car), roll and pitch keep their signs; the body axes FRD are
``(y, x, -z)`` of RFU.

    .venv/bin/python tools/psins_car.py [--data DIR] [--preset consumer] [--seed 0]

Prints the position error and the attitude RMS against the FOG (raw, and with the
constant MEMS-to-FOG rotation removed: the two IMUs are not aligned).
"""
import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "real" / "psins_vehicle"
T0 = 100000.0          # GPS seconds of week given to PSINS's time 0 (arbitrary)


def load(data=DATA):
    """(imu ImuLog FRD, reference Trajectory) from the .mat file."""
    import scipy.io

    from ins.nav.imu import ImuLog
    from ins.nav.rotation import euler_to_quat
    from ins.nav.trajectory import Trajectory
    m = scipy.io.loadmat(Path(data) / "transfer_align_fog_mems.mat")
    mimu, fog = np.asarray(m["mimu"], float), np.asarray(m["fogavp"], float)
    rfu2frd = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    imu = ImuLog(T0 + mimu[:, 6], mimu[:, 0:3] @ rfu2frd.T, mimu[:, 3:6] @ rfu2frd.T)
    pitch, roll, yaw = fog[:, 0], fog[:, 1], fog[:, 2]
    v_n = np.column_stack([fog[:, 4], fog[:, 3], -fog[:, 5]])
    lla = np.column_stack([fog[:, 6], fog[:, 7], fog[:, 8]])
    q = euler_to_quat(np.column_stack([roll, pitch, -yaw]))
    return imu, Trajectory(T0 + fog[:, 9], lla, v_n, q)


def gnss_from(ref, sigma_m=1.0, rate_hz=1.0, seed=0):
    """GnssLog: the reference positions every 1/rate_hz s with Gaussian noise (m)."""
    from ins.io.gnss_log import GnssLog
    from ins.nav import earth
    step = max(int(round(1.0 / (rate_hz * np.median(np.diff(ref.time))))), 1)
    k = np.arange(0, len(ref), step)
    rng = np.random.default_rng(seed)
    lla = earth.offset_lla(ref.lla[k], rng.standard_normal((len(k), 3)) * sigma_m)
    return GnssLog(ref.time[k], lla, np.full((len(k), 3), sigma_m))


def write_case(folder, data=DATA, seed=0):
    """imu.txt, gnss.txt, reference.nav and config.toml (facts only) in ``folder``."""
    from ins.io.gnss import write_gnss
    from ins.io.imu_files import write_kfgins_text
    from ins.io.navfiles import write_nav
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    imu, ref = load(data)
    write_kfgins_text(folder / "imu.txt", imu)
    write_gnss(folder / "gnss.txt", gnss_from(ref, seed=seed))
    write_nav(folder / "reference.nav", ref)
    (folder / "config.toml").write_text('[files]\nimu = "imu.txt"\ngnss = "gnss.txt"\n'
                                        "[gnss]\nlever_arm_b_m = [0.0, 0.0, 0.0]\n")
    return ref


def attitude_figures(traj, ref, skip_s=10.0):
    """Roll, pitch, heading RMS (deg) against the reference: raw, and with the constant
    rotation between the two IMUs (the chordal mean of C_ref^T C_est) removed."""
    from ins.nav.interpolation import interpolate_trajectory
    t = ref.time[(ref.time >= traj.time[0] + skip_s) & (ref.time <= traj.time[-1])]
    est = interpolate_trajectory(traj, t)
    r = interpolate_trajectory(ref, t)
    R_est, R_ref = Rotation.from_quat(est.q_nb), Rotation.from_quat(r.q_nb)
    mount = (R_ref.inv() * R_est).mean()
    out = {}
    for name, R in (("raw", R_est), ("mounting removed", R_est * mount.inv())):
        e_n = (R * R_ref.inv()).as_rotvec()
        head = (R.as_euler("ZYX")[:, 0] - R_ref.as_euler("ZYX")[:, 0] + np.pi) % (2 * np.pi) \
            - np.pi
        tilt = np.rad2deg(np.sqrt(np.mean(e_n[:, :2] ** 2, axis=0)))
        out[name] = (*tilt, float(np.rad2deg(np.sqrt(np.mean(head ** 2)))))
    out["mounting_deg"] = np.rad2deg(mount.as_euler("ZYX")[::-1])
    from ins.nav import earth
    dn = earth.ned_offset(r.lla, est.lla)
    out["horizontal_rms_m"] = float(np.sqrt(np.mean(dn[:, 0] ** 2 + dn[:, 1] ** 2)))
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--data", default=str(DATA))
    p.add_argument("--preset", default="consumer", help="a preset of ins process, or none")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--keep", help="folder to keep the files in")
    args = p.parse_args()
    from ins.io.navfiles import read_nav
    folder = Path(args.keep or tempfile.mkdtemp())
    ref = write_case(folder, args.data, args.seed)
    cmd = [str(Path(sys.executable).parent / "ins"), "process", "--config",
           str(folder / "config.toml"), "-o", str(folder / "out"), "--force", "--forward",
           "--no-plots"] + (["--preset", args.preset] if args.preset != "none" else [])
    proc = subprocess.run(cmd, capture_output=True, text=True)
    print(proc.stdout + proc.stderr)
    if proc.returncode != 0 or not (folder / "out" / "solution.nav").is_file():
        raise SystemExit(f"ins process: exit {proc.returncode}, no solution to compare")
    for which in ("forward", "solution"):
        f = attitude_figures(read_nav(folder / "out" / f"{which}.nav"), ref)
        print(f"{which}: horizontal RMS {f['horizontal_rms_m']:.2f} m; MEMS-to-FOG rotation "
              f"r/p/y {'/'.join(f'{x:.2f}' for x in f['mounting_deg'])} deg")
        for name in ("raw", "mounting removed"):
            print(f"  attitude RMS vs FOG ({name}): tilt N/E, heading "
                  f"{'/'.join(f'{x:.3f}' for x in f[name])} deg")


if __name__ == "__main__":
    main()
