"""Read speed (records/s) of every log and trajectory format the toolkit reads (issue 15),
beside the KF-GINS text reader.

Files are made here from one simulated motion (N records each; the writers of the
toolkit, so the bytes are the documented layouts): the IMU as KF-GINS text (the
reference, ``ins.io.imu_files.read_kfgins_text``), KF-GINS binary and CSV; GNSS as
KF-GINS text and as RTKLIB ``.pos`` (llh, week/tow, full covariance columns; and the
date-time variant); the trajectory as SBET and its SMRMSG; IMU messages in a ROS 1 and
a ROS 2 bag (``sensor_msgs/Imu``, fewer records: deserialized in Python).  Peers on the
KF-GINS text IMU log: the shared benchmark's reader (``../shared/bench/ins/peerlib.py``,
pandas' C engine, as the pyins and KF-GINS baselines read it) and KF-GINS's own C++
reader, quoted from that README (reading the 302 001-line log in 0.4-0.5 s).

Each figure is the best of ``--repeat`` warm reads (the whole reader: parsing, checks,
conversion into ImuLog/GnssLog/Trajectory).

Measured (2 cores shared with five other jobs, load average about 6, warm, best of 3;
N = 302 001, bags 20 000 messages; expect 20-30 % noise):

==============================================  ===========  ======
format                                           records/s   vs ref
==============================================  ===========  ======
IMU KF-GINS text (ours, the reference)              683 000    1.00
IMU KF-GINS binary                                6 380 000    9.3
IMU CSV with header                                 800 000    1.17
GNSS KF-GINS text                                   952 000    1.39
GNSS RTKLIB .pos, week/tow, 14 columns + cov        382 000    0.56
GNSS RTKLIB .pos, date-time (18 fields)             286 000    0.42
trajectory SBET (to Trajectory: Euler -> quat)    1 050 000    1.54
accuracy SMRMSG                                   4 340 000    6.4
IMU KF-GINS text, shared peerlib (pandas C)         778 000    1.14
IMU ROS 1 bag (sensor_msgs/Imu)                      32 900    0.05
IMU ROS 2 bag (sqlite3, CDR)                         44 500    0.07
KF-GINS C++ reader (quoted: 0.4-0.5 s)              671 000    0.98
==============================================  ===========  ======

The text readers are within a factor 2 of one another and of KF-GINS's C++ reader
(their cost is the exact parse, about 60 ns a field); an RTKLIB record has twice the
fields of a KF-GINS GNSS record plus the covariance algebra.  Bags are two orders of
magnitude slower: every message is deserialized in Python by rosbags (about 25 us a
message), which is why ``ins import-bag`` converts a bag once into the text formats
rather than ``ins process`` reading bags on every run.

Usage: python bench/bench_formats.py [--n N] [--bag-n N] [--repeat R]
"""
import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
SHARED = ROOT.parent / "shared" / "bench" / "ins"


def best_of(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def motion(n, rate_hz=200.0):
    """A smooth simulated motion: IMU increments, GNSS fixes (1 in 200), a trajectory."""
    from ins.io.gnss_log import GnssLog
    from ins.nav.imu import ImuLog
    from ins.nav.rotation import euler_to_quat
    from ins.nav.trajectory import Trajectory
    rng = np.random.default_rng(0)
    t = 345600.0 + np.arange(n) / rate_hz
    dt = 1.0 / rate_hz
    dtheta = (1e-3 * np.sin(np.outer(t, [0.1, 0.2, 0.3])) + rng.normal(0, 1e-6, (n, 3))) * dt
    dvel = (np.array([0.0, 0.0, -9.8]) + rng.normal(0, 1e-3, (n, 3))) * dt
    imu = ImuLog(t, dtheta, dvel)
    lla = np.column_stack([np.deg2rad(30.44 + 1e-6 * np.arange(n) / 20),
                           np.deg2rad(114.47 + 1e-7 * np.sin(t)), 1000 + np.sin(t)])
    v = np.column_stack([60 + np.sin(t), np.cos(t), 0.1 * np.sin(t)])
    rpy = np.column_stack([0.01 * np.sin(t), 0.02 * np.cos(t), 0.5 + 0.001 * t % 6])
    traj = Trajectory(t, lla, v, euler_to_quat(rpy))
    k = np.arange(0, n, 1)
    cov = np.tile(np.diag([4e-4, 4e-4, 2.5e-3]), (len(k), 1, 1))
    cov[:, 0, 1] = cov[:, 1, 0] = 1e-4
    gnss = GnssLog(t[k], lla[k], np.sqrt(np.einsum("nii->ni", cov)), cov_ned_m2=cov,
                   quality=np.ones(len(k), np.int64))
    return imu, gnss, traj


def make_bag(path, imu, ros1):
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    Imu = ts.types["sensor_msgs/msg/Imu"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    V3 = ts.types["geometry_msgs/msg/Vector3"]
    Q = ts.types["geometry_msgs/msg/Quaternion"]
    if ros1:
        from rosbags.rosbag1 import Writer
        writer = Writer(path)
    else:
        from rosbags.rosbag2 import Writer
        writer = Writer(path, version=9)
    w = imu.dtheta_b / imu.dt[:, None]
    f = imu.dvel_b / imu.dt[:, None]
    z9 = np.zeros(9)
    with writer:
        conn = writer.add_connection("/imu", Imu.__msgtype__, typestore=ts)
        for k in range(len(imu)):
            ns = 1_600_000_000 * 10**9 + int(round((imu.time[k] - imu.time[0]) * 1e9))
            stamp = Time(sec=ns // 10**9, nanosec=ns % 10**9)
            head = Header(seq=k, stamp=stamp, frame_id="imu") if ros1 else \
                Header(stamp=stamp, frame_id="imu")
            msg = Imu(header=head, orientation=Q(x=0, y=0, z=0, w=1), orientation_covariance=z9,
                      angular_velocity=V3(x=w[k, 0], y=w[k, 1], z=w[k, 2]),
                      angular_velocity_covariance=z9,
                      linear_acceleration=V3(x=f[k, 0], y=f[k, 1], z=f[k, 2]),
                      linear_acceleration_covariance=z9)
            data = ts.serialize_ros1(msg, Imu.__msgtype__) if ros1 else \
                ts.serialize_cdr(msg, Imu.__msgtype__)
            writer.write(conn, ns, data)


def pos_date_variant(src, dst):
    """The .pos with yyyy/mm/dd hh:mm:ss.ssssss stamps instead of week/tow (GPST)."""
    epoch = np.datetime64("1980-01-06T00:00:00")
    with open(src) as f, open(dst, "w") as g:
        for line in f:
            if line.startswith("%"):
                g.write(line)
                continue
            week, tow, rest = line.split(None, 2)
            us = int(round((int(week) * 604800 + float(tow)) * 1e6))
            d = str(epoch + np.timedelta64(us, "us")).replace("-", "/").replace("T", " ")
            g.write(f"{d} {rest}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=302_001, help="records per file (default 302001)")
    ap.add_argument("--bag-n", type=int, default=20_000, help="IMU messages in the bags")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    from ins.io.gnss import read_gnss, write_gnss
    from ins.io.imu_files import (
        read_csv,
        read_kfgins_binary,
        read_kfgins_text,
        write_csv,
        write_kfgins_binary,
        write_kfgins_text,
    )
    from ins.io.rtklib import read_pos, write_pos
    from ins.io.sbet import read_sbet, read_smrmsg, write_sbet, write_smrmsg

    imu, gnss, traj = motion(args.n)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        files = {
            "imu.txt": lambda p: write_kfgins_text(p, imu),
            "imu.bin": lambda p: write_kfgins_binary(p, imu),
            "imu.csv": lambda p: write_csv(p, imu),
            "gnss.txt": lambda p: write_gnss(p, gnss),
            "gnss.pos": lambda p: write_pos(p, gnss, week=2300),
            "sbet.out": lambda p: write_sbet(p, traj),
            "smrmsg.out": lambda p: write_smrmsg(p, traj.time, np.full((args.n, 3), 0.02),
                                                 np.full((args.n, 3), 0.01),
                                                 np.full((args.n, 3), 1e-4)),
        }
        for name, make in files.items():
            make(tmp / name)
        pos_date_variant(tmp / "gnss.pos", tmp / "gnss_date.pos")
        cases = [
            ("IMU KF-GINS text (ours, reference)", args.n, lambda: read_kfgins_text(tmp / "imu.txt")),
            ("IMU KF-GINS binary", args.n, lambda: read_kfgins_binary(tmp / "imu.bin")),
            ("IMU CSV with header", args.n, lambda: read_csv(tmp / "imu.csv")),
            ("GNSS KF-GINS text", args.n, lambda: read_gnss(tmp / "gnss.txt")),
            ("GNSS RTKLIB .pos week/tow, cov", args.n, lambda: read_pos(tmp / "gnss.pos")),
            ("GNSS RTKLIB .pos date-time", args.n, lambda: read_pos(tmp / "gnss_date.pos")),
            ("trajectory SBET", args.n, lambda: read_sbet(tmp / "sbet.out")),
            ("accuracy SMRMSG", args.n, lambda: read_smrmsg(tmp / "smrmsg.out")),
        ]
        if (SHARED / "peerlib.py").exists():
            sys.path.insert(0, str(SHARED))
            try:
                import peerlib
                cases.append(("IMU KF-GINS text, shared peerlib (pandas C)", args.n,
                              lambda: peerlib.load_imu(tmp / "imu.txt")))
            except ImportError as exc:
                print(f"(shared peerlib not run: {exc})")
        try:
            from ins.io.rosbag import read_bag
            small = imu.slice_time(None, imu.time[min(args.bag_n, args.n) - 1])
            make_bag(tmp / "imu.bag", small, ros1=True)
            make_bag(tmp / "imu_ros2", small, ros1=False)
            cases += [
                ("IMU ROS 1 bag (sensor_msgs/Imu)", len(small),
                 lambda: read_bag(tmp / "imu.bag", read_gnss=False)),
                ("IMU ROS 2 bag (sqlite3, CDR)", len(small),
                 lambda: read_bag(tmp / "imu_ros2", read_gnss=False)),
            ]
        except ImportError as exc:
            print(f"(bags not run: {exc}; pip install 'insphoto[ros]')")
        for label, n, fn in cases:
            fn()                                          # warm (imports, cache)
            t = best_of(fn, args.repeat)
            rows.append((label, n, t))
    ref = rows[0][1] / rows[0][2]
    print(f"{'format':<46}{'records':>9}{'time s':>9}{'records/s':>12}{'vs ref':>8}")
    for label, n, t in rows:
        print(f"{label:<46}{n:>9}{t:>9.3f}{n / t:>12.3g}{(n / t) / ref:>8.2f}")
    print(f"{'KF-GINS C++ reader (shared README: 0.4-0.5 s)':<46}{302001:>9}{'0.45':>9}"
          f"{302001 / 0.45:>12.3g}{(302001 / 0.45) / ref:>8.2f}")


if __name__ == "__main__":
    main()
