"""``ins import-bag``: IMU and GNSS topics of a ROS 1 / ROS 2 bag into the toolkit's files.

A converter rather than a bag reader inside ``ins process``: choosing the topics, the
IMU axes and the time base is done once, with the stamp report (gaps, repeated and
out-of-order stamps) in front of the user; the bag's messages are deserialized in Python
(tens of thousands a second), whereas ``ins process`` rereads the text files at millions
of values a second when settings are tuned; and the files can be inspected, plotted and
shifted like any other log.
"""
import argparse
import os

from ins.common.errors import InputError

EPILOG = """\
topics:
  --imu-topic       sensor_msgs/Imu: angular_velocity [rad/s], linear_acceleration
                    [m/s^2] in the message frame, x forward, y left, z up (ROS REP-103,
                    FLU), mapped into our body frame forward-right-down (FRD): y and z
                    change sign (--axes for a bag in other axes).  Each sample is
                    integrated over its REAL interval from the previous stamp:
                    dtheta[k] = w[k] (t[k] - t[k-1]), dvel[k] = f[k] (t[k] - t[k-1]).
  --gnss-topic      sensor_msgs/NavSatFix: latitude, longitude [deg], altitude [m above
                    the WGS84 ellipsoid], position_covariance [m^2, East-North-Up]
                    turned into North-East-Down; fixes with status -1 (no fix) dropped;
                    covariance type 0 (unknown) takes --gnss-sigma-m.
  Without a topic option the bag's only topic of that type is used.  --list prints the
  topics and their types.

time:
  header stamps (not the bag's receive times).  --time-base gps (default): stamps are
  UTC Unix time, written as GPS seconds of the week of the first IMU stamp (leap
  seconds applied; continuous across the week's end); raw: the stamps' seconds as they
  are (simulation or boot clock).  Out-of-order stamps are sorted, a repeated stamp
  keeps its first message, and the report gives the count of each, the gaps (> 1.5
  nominal intervals) and the largest gap with its time.

outputs (in -o DIR, new or empty; --force replaces it):
  imu.txt           KF-GINS text: time [s], dtheta x y z [rad], dvel x y z [m/s], FRD
  gnss.pos          RTKLIB .pos (llh, GPST week/tow) with the full covariance
                    (sdn sde sdu sdne sdeu sdun; ins process reads it as --gnss)

example:
  ins import-bag drive.bag --imu-topic /imu/data --gnss-topic /fix -o drive
  ins process --imu drive/imu.txt --gnss drive/gnss.pos --config land.toml -o out
"""


def add_parser(sub):
    from ins.cli.util import triplet
    p = sub.add_parser(
        "import-bag", help="IMU and GNSS topics of a ROS 1/ROS 2 bag into imu.txt, gnss.pos",
        description="Read sensor_msgs/Imu and sensor_msgs/NavSatFix topics of a ROS 1 (.bag) "
                    "or ROS 2 (folder, .db3, .mcap) bag, map the IMU into FRD, integrate "
                    "the rates over their real intervals and write the toolkit's IMU and "
                    "GNSS files, with a report of the stamps.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("bag", metavar="BAG", help="ROS 1 .bag file or ROS 2 bag folder")
    p.add_argument("--imu-topic", metavar="T", help="sensor_msgs/Imu topic")
    p.add_argument("--gnss-topic", metavar="T", help="sensor_msgs/NavSatFix topic")
    p.add_argument("--no-imu", action="store_true", help="do not read an IMU topic")
    p.add_argument("--no-gnss", action="store_true", help="do not read a GNSS topic")
    p.add_argument("--axes", choices=["FLU", "FRD", "RFU", "FUR"], default="FLU",
                   help="axes of the IMU messages (default FLU, ROS REP-103)")
    p.add_argument("--time-base", choices=["gps", "raw"], default="gps",
                   help="stamps as UTC Unix time into GPS seconds of week (default), or raw")
    p.add_argument("--gnss-sigma-m", type=triplet, metavar="N,E,D",
                   help="position sigma north, east, down (m) of fixes without covariance")
    p.add_argument("--list", action="store_true", help="list the bag's topics and exit")
    p.add_argument("-q", "--quiet", action="store_true", help="no report")
    p.add_argument("-o", "--output", metavar="DIR", help="output folder (new or empty)")
    p.add_argument("--force", action="store_true", help="replace a non-empty DIR whole")
    p.set_defaults(func=run)


def run(args):
    from ins.common.fileio import output_folder
    from ins.io.rosbag import list_topics, read_bag
    if args.list:
        for topic, (msgtype, count) in sorted(list_topics(args.bag).items()):
            print(f"{topic}  {msgtype}  {count} messages")
        return 0
    if not args.output:
        raise InputError("-o DIR is required (or --list)")
    if args.no_imu and args.no_gnss:
        raise InputError("--no-imu and --no-gnss: nothing to import")
    if args.gnss_sigma_m is not None and min(args.gnss_sigma_m) <= 0:
        raise InputError("--gnss-sigma-m: expected three values > 0 (m), got "
                         + ",".join(f"{float(v):g}" for v in args.gnss_sigma_m))
    data = read_bag(args.bag, args.imu_topic, args.gnss_topic, axes=args.axes,
                    time_base=args.time_base, default_sigma_ned_m=args.gnss_sigma_m,
                    read_imu=not args.no_imu, read_gnss=not args.no_gnss)
    with output_folder(args.output, force=args.force) as stage:
        written = _write(data, stage, args)
    if not args.quiet:
        for rep in (data.imu_report, data.gnss_report):
            if rep is not None:
                print(rep.summary())
        if data.week is not None:
            print(f"time: GPS seconds of week {data.week}")
        for name in written:
            print(f"  {os.path.join(args.output, name)}")
    return 0


def _write(data, stage, args):
    from ins.io.imu_files import write_kfgins_text
    from ins.io.rtklib import write_pos
    written = []
    if data.imu is not None:
        write_kfgins_text(os.path.join(stage, "imu.txt"), data.imu)
        written.append("imu.txt")
    if data.gnss is not None:
        week = data.week if data.week is not None else 0
        comments = [f"ins import-bag {os.path.basename(args.bag)} topic "
                    f"{data.gnss_report.topic}; time base {args.time_base}"
                    + ("" if data.week is not None else " (raw stamps as seconds of week 0)")]
        write_pos(os.path.join(stage, "gnss.pos"), data.gnss, week, comments=comments)
        written.append("gnss.pos")
    return written
