"""ROS 1 and ROS 2 bags built here with rosbags' writers, with known values: IMU rates at
irregular stamps (a repeated stamp, one out of order, a gap) integrated over their real
intervals, FLU -> FRD; NavSatFix covariance ENU -> NED; the UTC -> GPS time base; the
stamp report; ``ins import-bag`` writing imu.txt and gnss.pos."""
import numpy as np
import pytest

pytest.importorskip("rosbags")
from rosbags.typesys import Stores, get_typestore  # noqa: E402

from ins.cli.main import main  # noqa: E402
from ins.common.errors import InputError  # noqa: E402
from ins.io.gnss import read_gnss  # noqa: E402
from ins.io.imu_files import read_imu  # noqa: E402
from ins.io.rosbag import read_bag  # noqa: E402

T0 = 1577836800                        # 2020-01-01T00:00:00Z: GPS week 2086, tow 259218 s
# stamp offsets (ns) in bag order: 10 ms steps, a repeat at 30 ms, 60 ms written before
# 50 ms (out of order), then a gap of 40 ms (from 60 to 100 ms)
IMU_NS = [0, 10_000_000, 21_000_000, 30_000_000, 30_000_000, 40_000_000, 60_000_000,
          50_000_000, 100_000_000, 110_000_000]
W_FLU = np.array([0.1, 0.2, 0.3])
F_FLU = np.array([1.0, 2.0, 9.8])
COV_ENU = np.array([[4.0, 0.5, 0.1], [0.5, 9.0, -0.2], [0.1, -0.2, 16.0]]) * 1e-4


def scale(k):
    return 1.0 + 0.1 * k           # rates differ per message (k in bag order)


def build(path, ros1):
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    Imu = ts.types["sensor_msgs/msg/Imu"]
    Fix = ts.types["sensor_msgs/msg/NavSatFix"]
    Status = ts.types["sensor_msgs/msg/NavSatStatus"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    V3 = ts.types["geometry_msgs/msg/Vector3"]
    Q = ts.types["geometry_msgs/msg/Quaternion"]

    def header(sec, ns, seq=0):
        if ros1:
            return Header(seq=seq, stamp=Time(sec=sec, nanosec=ns), frame_id="imu")
        return Header(stamp=Time(sec=sec, nanosec=ns), frame_id="imu")

    def ser(msg, typ):
        return ts.serialize_ros1(msg, typ) if ros1 else ts.serialize_cdr(msg, typ)

    if ros1:
        from rosbags.rosbag1 import Writer
        writer = Writer(path)
    else:
        from rosbags.rosbag2 import Writer
        writer = Writer(path, version=9)
    with writer:
        ci = writer.add_connection("/imu/data", Imu.__msgtype__, typestore=ts)
        cg = writer.add_connection("/fix", Fix.__msgtype__, typestore=ts)
        for k, ns in enumerate(IMU_NS):
            w, f = W_FLU * scale(k), F_FLU * scale(k)
            msg = Imu(header=header(T0, ns, k), orientation=Q(x=0, y=0, z=0, w=1),
                      orientation_covariance=np.zeros(9),
                      angular_velocity=V3(x=w[0], y=w[1], z=w[2]),
                      angular_velocity_covariance=np.zeros(9),
                      linear_acceleration=V3(x=f[0], y=f[1], z=f[2]),
                      linear_acceleration_covariance=np.zeros(9))
            writer.write(ci, T0 * 10**9 + k * 1000, ser(msg, Imu.__msgtype__))
        for k in range(4):
            status = Status(status=-1 if k == 2 else 2, service=1)
            msg = Fix(header=header(T0 + k, 0, k), status=status, latitude=30.0 + 1e-6 * k,
                      longitude=114.0, altitude=20.0 + k, position_covariance=COV_ENU.ravel(),
                      position_covariance_type=3)
            writer.write(cg, (T0 + k) * 10**9, ser(msg, Fix.__msgtype__))


@pytest.fixture(params=["ros1", "ros2"])
def bag(request, tmp_path):
    ros1 = request.param == "ros1"
    path = tmp_path / ("drive.bag" if ros1 else "drive")
    build(path, ros1)
    return path


def expected_imu():
    """Stamp order, repeat dropped (the first message at 30 ms kept)."""
    order = [0, 1, 2, 3, 5, 7, 6, 8, 9]
    t = np.array([IMU_NS[k] for k in order]) * 1e-9
    C = np.diag([1.0, -1.0, -1.0])                         # FLU -> FRD
    w = np.array([C @ (W_FLU * scale(k)) for k in order])
    f = np.array([C @ (F_FLU * scale(k)) for k in order])
    dt = np.diff(t, prepend=np.nan)
    dt[0] = np.median(np.diff(t))
    return t, w * dt[:, None], f * dt[:, None]


def test_read_bag(bag):
    data = read_bag(bag, "/imu/data", "/fix")
    t, dtheta, dvel = expected_imu()
    assert data.week == 2086
    np.testing.assert_allclose(data.imu.time, 259218.0 + t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(data.imu.dtheta_b, dtheta, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(data.imu.dvel_b, dvel, rtol=1e-12, atol=1e-15)
    rep = data.imu_report
    assert (rep.messages, rep.kept, rep.duplicates, rep.out_of_order) == (10, 9, 1, 1)
    assert rep.gaps == 1 and rep.largest_gap_s == pytest.approx(0.04)
    assert rep.largest_gap_at_s == pytest.approx(259218.1) and rep.largest_gap_index == 7
    assert rep.first_duplicate_at_s == pytest.approx(259218.03)
    assert "1 gaps (largest 0.04 s" in rep.summary()
    g = data.gnss
    assert len(g) == 3 and data.gnss_report.dropped == 1          # status -1 dropped
    np.testing.assert_allclose(g.time, [259218.0, 259219.0, 259221.0])
    np.testing.assert_allclose(np.rad2deg(g.lla[1, :2]), [30.000001, 114.0])
    assert g.lla[2, 2] == 23.0
    # ENU -> NED by hand: N row/column from E's and vice versa, D = -U
    e, n, u = 0, 1, 2
    want = np.array([[COV_ENU[n, n], COV_ENU[n, e], -COV_ENU[n, u]],
                     [COV_ENU[e, n], COV_ENU[e, e], -COV_ENU[e, u]],
                     [-COV_ENU[u, n], -COV_ENU[u, e], COV_ENU[u, u]]])
    np.testing.assert_allclose(g.cov_ned_m2[0], want, rtol=1e-15)
    np.testing.assert_allclose(g.sigma_ned_m[0], [0.03, 0.02, 0.04])


def test_raw_time_base_and_axes(bag):
    data = read_bag(bag, time_base="raw", axes="FRD", read_gnss=False)
    t, _, _ = expected_imu()
    np.testing.assert_allclose(data.imu.time, T0 + t, rtol=0, atol=1e-6)
    assert data.week is None and data.gnss is None
    # FRD: no sign change of the message's y, z
    k_last = len(IMU_NS) - 1
    dt = 0.01
    np.testing.assert_allclose(data.imu.dtheta_b[-1], W_FLU * scale(k_last) * dt, rtol=1e-9)


def test_import_bag_command(bag, tmp_path, capsys):
    out = tmp_path / "imp"
    assert main(["import-bag", str(bag), "--imu-topic", "/imu/data", "--gnss-topic", "/fix",
                 "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "/imu/data: 10 messages, 9 epochs kept" in text and "GPS seconds of week 2086" in text
    imu = read_imu(out / "imu.txt")
    t, dtheta, _ = expected_imu()
    np.testing.assert_allclose(imu.time, 259218.0 + t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(imu.dtheta_b, dtheta, rtol=1e-15)
    g = read_gnss(out / "gnss.pos")
    direct = read_bag(bag, "/imu/data", "/fix").gnss
    np.testing.assert_allclose(g.time, direct.time)
    np.testing.assert_allclose(g.lla[:, :2], direct.lla[:, :2], rtol=0, atol=1e-13)
    np.testing.assert_allclose(g.cov_ned_m2, direct.cov_ned_m2, rtol=1e-5)
    assert list(g.quality) == [4, 4, 4]                          # GBAS fix -> dgps
    assert main(["import-bag", str(bag), "--list"]) == 0
    assert "/fix  sensor_msgs/msg/NavSatFix  4 messages" in capsys.readouterr().out


def test_bag_errors(bag, tmp_path, capsys):
    with pytest.raises(InputError, match="--imu-topic /nope: no such topic; the bag has"):
        read_bag(bag, imu_topic="/nope")
    with pytest.raises(InputError, match="--gnss-topic /imu/data: messages of type "
                                         "sensor_msgs/msg/Imu"):
        read_bag(bag, gnss_topic="/imu/data", read_imu=False)
    with pytest.raises(InputError, match="not a readable ROS"):
        bad = tmp_path / "x.bag"
        bad.write_bytes(b"not a bag")
        read_bag(bad)
    assert main(["import-bag", str(bag), "-o", str(tmp_path / "o"), "--gnss-sigma-m",
                 "1,0,1"]) == 2
    assert "--gnss-sigma-m" in capsys.readouterr().err


def test_process_points_to_import_bag(bag, tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text("[initial]\nlat_deg = 30\nlon_deg = 114\nh_m = 0\n")
    assert main(["process", "--imu", str(bag), "--gnss", str(bag), "--config", str(cfg),
                 "-q", "-o", str(tmp_path / "o")]) == 2
    assert "a ROS bag; convert it first with 'ins import-bag" in capsys.readouterr().err
