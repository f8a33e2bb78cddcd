"""IMU and GNSS from ROS 1 (``.bag``) and ROS 2 (folder, ``.db3``, ``.mcap``) bags, read with
the pure-Python ``rosbags`` library (optional extra: ``pip install 'insphoto[ros]'``).

Messages, selected by topic:

``sensor_msgs/Imu``
    ``angular_velocity`` (rad/s) and ``linear_acceleration`` (m/s^2, specific force) in
    the message's frame, which ROS REP-103 defines as x forward, y left, z up (FLU).
    They are mapped into our body frame FRD by ``C_frd_axes("FLU") = diag(1, -1, -1)``
    (``axes="FRD"`` etc. for a bag that breaks REP-103), and turned into increments with
    the REAL interval of every sample (``increment[k] = rate[k] * (t[k] - t[k-1])``, the
    end-of-interval rule of :func:`ins.nav.imu.rates_to_increments`: a sample is the mean rate
    since the previous one; the first sample takes the median interval).  Orientation and
    the covariances of the message are not used.
``sensor_msgs/NavSatFix``
    ``latitude``, ``longitude`` (deg), ``altitude`` (m above the WGS84 ellipsoid, as the
    message defines it), ``position_covariance`` (m^2, row-major, in the local East,
    North, Up frame) turned into NED (``C = [[0,1,0],[1,0,0],[0,0,-1]]``: swap E and N,
    negate the U row and column).  ``position_covariance_type`` 0 (unknown) takes
    ``default_sigma_ned_m``; 2 (diagonal known) keeps the diagonal only; 1 and 3 the full
    matrix.  ``status.status`` -1 (no fix) and NaN positions are dropped (counted).

Time: the ``header.stamp`` of every message (not the bag's receive time).  With
``time_base="gps"`` (default) stamps are taken as UTC Unix time and turned into GPS
seconds of the week of the first stamp (leap seconds of :data:`ins.io.rtklib.LEAP_SECONDS`,
continuous across a week's end); ``"raw"`` keeps the stamps' seconds as they are (a
simulation clock, a boot clock).  Stamps before the GPS epoch with ``"gps"`` are
refused (use ``"raw"``).

Irregular stamps are reported, not hidden (:class:`StampReport`): messages out of stamp
order are sorted, a repeated stamp keeps its first message, intervals longer than 1.5
median intervals are gaps (count, the largest with its time and message index).
"""
import os
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError

__all__ = ["StampReport", "BagData", "read_bag", "list_topics", "IMU_TYPE", "GNSS_TYPE"]

IMU_TYPE = "sensor_msgs/msg/Imu"
GNSS_TYPE = "sensor_msgs/msg/NavSatFix"
_WEEK_S = 604800
_GPS_EPOCH_UNIX = 315964800          # 1980-01-06T00:00:00Z
_C_NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


@dataclass
class StampReport:
    """What the stamps of one topic looked like.

    Attributes
    ----------
    topic : str
    messages : int
        Messages on the topic.
    kept : int
        Epochs kept (after dropping repeated stamps, no-fix and NaN messages).
    out_of_order : int
        Messages whose stamp is earlier than the one before (sorted).
    duplicates : int
        Messages with a stamp already seen (dropped).
    dropped : int
        Messages dropped for another reason (no fix, NaN position).
    nominal_dt_s : float
        Median interval, s.
    gaps : int
        Intervals longer than 1.5 nominal intervals.
    largest_gap_s : float
        The longest interval, s, ending at ``largest_gap_at_s`` (stamp, s, in the output
        time base) with message ``largest_gap_index`` (0-based, in stamp order).
    first_duplicate_at_s : float or None
        Stamp of the first repeated stamp.
    """

    topic: str
    messages: int
    kept: int = 0
    out_of_order: int = 0
    duplicates: int = 0
    dropped: int = 0
    nominal_dt_s: float = float("nan")
    gaps: int = 0
    largest_gap_s: float = 0.0
    largest_gap_at_s: float = float("nan")
    largest_gap_index: int = -1
    first_duplicate_at_s: float = None

    def summary(self):
        """One line for the command line."""
        text = (f"{self.topic}: {self.messages} messages, {self.kept} epochs kept, nominal "
                f"interval {self.nominal_dt_s:.6g} s; {self.gaps} gaps (largest "
                f"{self.largest_gap_s:.6g} s ending at t = {self.largest_gap_at_s:.6f} s, "
                f"message {self.largest_gap_index}); {self.duplicates} repeated stamps")
        if self.first_duplicate_at_s is not None:
            text += f" (first at t = {self.first_duplicate_at_s:.6f} s)"
        text += f"; {self.out_of_order} out of order (sorted)"
        if self.dropped:
            text += f"; {self.dropped} dropped (no fix or NaN)"
        return text


@dataclass
class BagData:
    """What :func:`read_bag` returns: the logs (None for a topic not asked), the reports
    per topic, and the GPS week of ``time`` 0 (``time_base="gps"``; None for ``"raw"``)."""

    imu: object = None
    gnss: object = None
    imu_report: StampReport = None
    gnss_report: StampReport = None
    week: int = None


def _rosbags():
    try:
        from rosbags.highlevel import AnyReader
    except ImportError:
        raise InputError("reading ROS bags needs the rosbags library: pip install "
                         "'insphoto[ros]'") from None
    return AnyReader


def _open(path):
    AnyReader = _rosbags()
    from pathlib import Path
    p = Path(path)
    if not p.exists():
        raise InputError("no such file or folder", path=os.fspath(path))
    if p.is_file() and p.suffix in (".db3", ".mcap"):
        p = p.parent                      # a ROS 2 bag is its folder
    try:
        reader = AnyReader([p])
        reader.open()
    except Exception as exc:              # rosbags raises its own error types
        raise InputError(f"not a readable ROS 1 or ROS 2 bag: {exc}",
                         path=os.fspath(path)) from None
    return reader


def list_topics(path):
    """``{topic: (message type, count)}`` of a bag."""
    reader = _open(path)
    try:
        return {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
    finally:
        reader.close()


def _pick(reader, topic, msgtype, option, path):
    conns = [c for c in reader.connections if c.msgtype == msgtype]
    names = sorted({c.topic for c in conns})
    if topic is None:
        if len(names) != 1:
            raise InputError(f"{option}: {'no' if not names else 'several'} {msgtype} "
                             f"topics ({', '.join(names) or 'none'}); name one", path=path)
        topic = names[0]
    chosen = [c for c in reader.connections if c.topic == topic]
    if not chosen:
        have = ", ".join(f"{c.topic} ({c.msgtype})" for c in reader.connections)
        raise InputError(f"{option} {topic}: no such topic; the bag has {have}", path=path)
    wrong = [c.msgtype for c in chosen if c.msgtype != msgtype]
    if wrong:
        raise InputError(f"{option} {topic}: messages of type {wrong[0]}, expected "
                         f"{msgtype}", path=path)
    return topic, chosen


def _stamp(msg):
    st = msg.header.stamp
    return int(st.sec), int(getattr(st, "nanosec", getattr(st, "nsec", 0)))


def _times(sec, nsec, time_base, path, topic, week=None):
    """Stamps -> seconds in the output time base (and the week, for "gps")."""
    sec = np.asarray(sec, np.int64)
    nsec = np.asarray(nsec, np.int64)
    if time_base == "raw":
        return sec.astype(np.float64) + nsec * 1e-9, None
    if time_base != "gps":
        raise ValueError(f"time_base must be 'gps' or 'raw', got {time_base!r}")
    if sec.size and sec.min() < _GPS_EPOCH_UNIX:
        raise InputError(f"topic {topic}: stamp {int(sec.min())} s is before the GPS epoch "
                         f"(1980-01-06): not UTC Unix time (a simulation or boot clock?); "
                         f"read it with the raw time base", path=path)
    from ins.io.rtklib import utc_to_gps_seconds
    gps = utc_to_gps_seconds(sec - _GPS_EPOCH_UNIX)
    if week is None:
        week = int(gps[0] // _WEEK_S) if gps.size else 0
    return (gps - week * _WEEK_S).astype(np.float64) + nsec * 1e-9, week


def _order(t, topic, nmsg):
    """Stable stamp order, the duplicates dropped; the report's first fields."""
    rep = StampReport(topic, nmsg)
    rep.out_of_order = int(np.count_nonzero(np.diff(t) < 0))
    order = np.argsort(t, kind="stable")
    ts = t[order]
    dup = np.zeros(len(ts), bool)
    dup[1:] = ts[1:] == ts[:-1]
    rep.duplicates = int(dup.sum())
    if rep.duplicates:
        rep.first_duplicate_at_s = float(ts[np.flatnonzero(dup)[0]])
    return order[~dup], rep


def _gap_report(rep, t):
    rep.kept = len(t)
    if len(t) < 2:
        return rep
    d = np.diff(t)
    rep.nominal_dt_s = float(np.median(d))
    rep.gaps = int(np.count_nonzero(d > 1.5 * rep.nominal_dt_s))
    k = int(np.argmax(d))
    rep.largest_gap_s = float(d[k])
    rep.largest_gap_at_s = float(t[k + 1])
    rep.largest_gap_index = k + 1
    return rep


def _read_imu(reader, conns, topic, axes, time_base, path, week):
    from ins.nav.imu import C_frd_axes, ImuLog, rates_to_increments
    sec, nsec, rows = [], [], []
    for conn, _, raw in reader.messages(connections=conns):
        m = reader.deserialize(raw, conn.msgtype)
        s, n = _stamp(m)
        sec.append(s)
        nsec.append(n)
        w, a = m.angular_velocity, m.linear_acceleration
        rows.append((w.x, w.y, w.z, a.x, a.y, a.z))
    if len(rows) < 2:
        raise InputError(f"--imu-topic {topic}: {len(rows)} message(s); at least two are "
                         f"needed", path=path)
    t, week = _times(sec, nsec, time_base, path, topic, week)
    vals = np.array(rows, dtype=np.float64)
    bad = np.flatnonzero(~np.all(np.isfinite(vals), axis=1))
    if bad.size:
        raise InputError(f"--imu-topic {topic}: message {int(bad[0])} (at t = "
                         f"{float(t[bad[0]]):.6f} s) holds a non-finite rate", path=path)
    from ins.nav.imu import MAX_ANGULAR_RATE, MAX_SPECIFIC_FORCE
    big = np.flatnonzero((np.linalg.norm(vals[:, :3], axis=1) > MAX_ANGULAR_RATE)
                         | (np.linalg.norm(vals[:, 3:], axis=1) > MAX_SPECIFIC_FORCE))
    if big.size:
        raise InputError(f"--imu-topic {topic}: message {int(big[0])} (at t = "
                         f"{float(t[big[0]]):.6f} s): an angular rate above "
                         f"{MAX_ANGULAR_RATE:g} rad/s or a specific force above "
                         f"{MAX_SPECIFIC_FORCE:g} m/s^2 that no IMU measures", path=path)
    keep, rep = _order(t, topic, len(rows))
    t, vals = t[keep], vals[keep]
    if len(t) < 2:
        raise InputError(f"--imu-topic {topic}: fewer than two distinct stamps", path=path)
    C = C_frd_axes(axes)
    gyro, accel = vals[:, :3] @ C.T, vals[:, 3:] @ C.T
    # the intervals from the integer stamps (ns), exact whatever the size of t
    ns = (np.asarray(sec, np.int64) * 1_000_000_000 + np.asarray(nsec, np.int64))[keep]
    dtheta, dvel = rates_to_increments((ns - ns[0]) * 1e-9, gyro, accel)
    return ImuLog.adopt(t, dtheta, dvel), _gap_report(rep, t), week


def _nav_cov(m, default_sigma_ned_m, topic, path, index):
    kind = int(m.position_covariance_type)
    c = np.asarray(m.position_covariance, dtype=np.float64).reshape(3, 3)
    if kind == 0:
        if default_sigma_ned_m is None:
            raise InputError(f"--gnss-topic {topic}: message {index} has no covariance "
                             f"(position_covariance_type 0): give the sigma (--gnss-sigma-m "
                             f"N,E,D)", path=path)
        return np.diag(np.asarray(default_sigma_ned_m, float) ** 2)
    if kind == 2:
        c = np.diag(np.diag(c))
    return _C_NED_ENU @ c @ _C_NED_ENU.T


def _read_gnss(reader, conns, topic, default_sigma_ned_m, time_base, path, week):
    from ins.io.gnss_log import GnssLog
    sec, nsec, lla, covs, status = [], [], [], [], []
    dropped = 0
    nmsg = 0
    for conn, _, raw in reader.messages(connections=conns):
        m = reader.deserialize(raw, conn.msgtype)
        nmsg += 1
        pos = (m.latitude, m.longitude, m.altitude)
        if int(m.status.status) < 0 or not np.all(np.isfinite(pos)):
            dropped += 1
            continue
        s, n = _stamp(m)
        sec.append(s)
        nsec.append(n)
        lla.append(pos)
        covs.append(_nav_cov(m, default_sigma_ned_m, topic, path, nmsg - 1))
        status.append(int(m.status.status))
    if not lla:
        raise InputError(f"--gnss-topic {topic}: no fix among {nmsg} messages", path=path)
    t, week = _times(sec, nsec, time_base, path, topic, week)
    keep, rep = _order(t, topic, nmsg)
    rep.dropped = dropped
    lla = np.array(lla, dtype=np.float64)[keep]
    from ins.common.limits import check_position
    for k in range(len(lla)):
        msg = check_position(*lla[k], f"--gnss-topic {topic}: fix at t = "
                                      f"{float(t[keep][k]):.6f} s")
        if msg is not None:
            raise InputError(msg, path=path)
    cov = np.array(covs)[keep]
    diag = np.einsum("nii->ni", cov)
    bad = np.flatnonzero(~np.all(diag > 0, axis=1))
    if bad.size:
        raise InputError(f"--gnss-topic {topic}: a position variance <= 0 at t = "
                         f"{float(t[keep][bad[0]]):.6f} s (give --gnss-sigma-m for messages "
                         f"without covariance)", path=path)
    # NavSatStatus -> RTKLIB-like quality: FIX 5 single, SBAS 3, GBAS 4 (dgps/RTK)
    q = np.array([{0: 5, 1: 3, 2: 4}.get(s, 5) for s in status], np.int64)[keep]
    tk = t[keep]
    log = GnssLog(tk, np.column_stack([np.deg2rad(lla[:, :2]), lla[:, 2]]), np.sqrt(diag),
                  line=np.zeros(len(tk), np.int64), path=os.fspath(path), cov_ned_m2=cov,
                  quality=q)
    return log, _gap_report(rep, tk), week


def read_bag(path, imu_topic=None, gnss_topic=None, axes="FLU", time_base="gps",
             default_sigma_ned_m=None, read_imu=True, read_gnss=True):
    """Read the IMU and GNSS topics of a ROS 1 or ROS 2 bag (module notes).

    Parameters
    ----------
    path : str or os.PathLike
        A ROS 1 ``.bag`` file, or a ROS 2 bag folder (or its ``.db3``/``.mcap`` file).
    imu_topic, gnss_topic : str, optional
        Topics of ``sensor_msgs/Imu`` and ``sensor_msgs/NavSatFix``; ``None`` takes the
        only topic of that type.
    axes : {"FLU", "FRD", "RFU", "FUR"}
        Axes of the IMU messages (REP-103: FLU), mapped into FRD.
    time_base : {"gps", "raw"}
        Header stamps as UTC Unix time into GPS seconds of week, or as they are.
    default_sigma_ned_m : array_like, shape (3,), optional
        Position sigma (m) of fixes without a covariance.
    read_imu, read_gnss : bool
        Which logs to read.

    Returns
    -------
    BagData

    Raises
    ------
    InputError
        Not a bag, a missing or ambiguous topic, a topic of another type, too few
        messages, a non-finite rate, fixes without covariance and no default, stamps
        that are not Unix time with ``time_base="gps"``.
    """
    path_s = os.fspath(path)
    reader = _open(path_s)
    out = BagData()
    try:
        week = None
        if read_imu:
            topic, conns = _pick(reader, imu_topic, IMU_TYPE, "--imu-topic", path_s)
            out.imu, out.imu_report, week = _read_imu(reader, conns, topic, axes, time_base,
                                                      path_s, week)
        if read_gnss:
            topic, conns = _pick(reader, gnss_topic, GNSS_TYPE, "--gnss-topic", path_s)
            out.gnss, out.gnss_report, week = _read_gnss(reader, conns, topic,
                                                         default_sigma_ned_m, time_base,
                                                         path_s, week)
        out.week = week
    finally:
        reader.close()
    return out
