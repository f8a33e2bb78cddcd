"""comma2k19 segment -> the toolkit's files, and the comparison with comma.ai's pose.

The real-data path of issue 15 item 5 in two commands (and a comparison)::

    python tools/comma2k19.py SEGMENT -o seg              # convert (this script)
    ins process --config seg/config.toml --preset mems -o seg/out
    python tools/comma2k19.py --compare seg/out/solution.nav seg   # the figures

and its land-vehicle variant (non-holonomic constraint in the car's axes, the phone's
mounting estimated from the first solution by ``ins.estimation.tools.vehicle``)::

    python tools/comma2k19.py --land seg/out/solution.nav seg     # seg/config_land.toml
    ins process --config seg/config_land.toml --preset land -o seg/out_land
    python tools/comma2k19.py --compare seg/out_land/solution.nav seg

``SEGMENT`` is a comma2k19 segment folder (``IMU/``, ``GNSS/live_gnss_ublox``,
``global_pose/``: numpy ``t.npy``/``value.npy`` pairs; ``../shared/real/README.md``).

What the conversion writes into ``-o DIR`` (a new or empty folder, ``--force`` replaces):

``imu.txt``
    KF-GINS IMU text (``time dtheta_xyz[rad] dvel_xyz[m/s]``), FRD (the phone's axes are
    forward, right, down already).  The phone reports RATES (gyro rad/s, calibrated by
    the phone; specific force m/s^2) at jittered stamps (about 104 Hz); each increment
    over ``(t[k-1], t[k]]`` is the trapezoid of the two samples times the REAL interval
    (samples taken as instantaneous), stamped at ``t[k]``.
``gnss.txt``
    KF-GINS GNSS text (13 columns): the u-blox fixes with their velocity from speed and
    bearing (``vd = 0``).  The u-blox log has no accuracy field: the sigmas are ASSUMED
    (``--sigma-h``, ``--sigma-v``, ``--sigma-vel``, ``--sigma-vd``, defaults below) and
    written into ``conversion.toml``.
``reference.nav``
    comma.ai's pose (a tightly coupled INS/GNSS/vision estimate) at the video frames
    (20 Hz), ``.nav`` layout: the CAMERA's position and velocity, and the attitude of the
    camera's forward-right-down axes (roll, pitch, yaw of ``C_nc``).  The IMU, the
    camera and the u-blox antenna are in one device (comma EON): the camera-IMU and
    antenna-IMU offsets are taken as zero (a few cm); the camera-to-IMU ROTATION is not
    given and is estimated by ``--compare``.
``config.toml``
    processing config for ``ins process`` (files, alignment from the GNSS track, zero
    lever arm); the IMU noise comes from the preset (``--preset mems``).  For ``land``
    the phone's mounting is needed (it is pitched 3.9 deg against the car's direction
    of travel): ``--land`` writes ``config_land.toml`` = this config + the ``[vehicle]``
    table estimated from a first solution (docs/real-data.md).
``conversion.toml``
    the time base, the assumptions and the figures of the conversion.

Time base: every file is stamped in GPS seconds of week.  The IMU's boot-clock stamps
are carried over by ``global_pose/frame_times`` and ``frame_gps_times`` (one constant
offset, fitted; the residual is stated).  The fixes have two stamps: their UTC epoch
(ms since 1970, GPS = UTC + 18 s) and their arrival on the boot clock, 0.2 s apart;
``--gnss-time utc`` (default: the epoch of the measurement) or ``arrival``.
``ins time-offset`` estimates the IMU-GNSS offset from the data to decide.
"""
import argparse
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: GPS - UTC in 2018 (leap seconds), s.
LEAP_SECONDS = 18.0
#: Unix time of the GPS epoch 1980-01-06 00:00:00 UTC, s.
GPS_EPOCH_UNIX = 315964800.0
WEEK_S = 604800.0
#: Assumed u-blox sigmas (no accuracy field in the log): horizontal, vertical position
#: (m), horizontal velocity, vertical velocity (m/s; the log has no vertical velocity).
SIGMA_H_M = 2.0
SIGMA_V_M = 4.0
SIGMA_VEL_MPS = 0.1
SIGMA_VD_MPS = 10.0


def _npy(path):
    try:
        return np.load(path)
    except OSError as exc:
        from ins.common.errors import InputError
        raise InputError(f"{path}: {exc.strerror or exc} (a comma2k19 segment folder is "
                         f"expected: IMU/, GNSS/live_gnss_ublox/, global_pose/)") from None


def _load(segment, name):
    d = Path(segment) / name
    return _npy(d / "t.npy"), _npy(d / "value.npy")


def boot_to_gps(segment):
    """GPS week and the offset ``tow - boot`` (s) from the frames' two stamps, with the
    RMS residual of the fit (s)."""
    ft = _npy(Path(segment) / "global_pose" / "frame_times.npy")
    g = _npy(Path(segment) / "global_pose" / "frame_gps_times.npy")
    weeks = np.unique(g[:, 0])
    if len(weeks) != 1:
        raise ValueError("the segment crosses a GPS week")
    d = g[:, 1] - ft
    offset = float(np.mean(d))
    return int(weeks[0]), offset, float(np.sqrt(np.mean((d - offset) ** 2)))


def imu_increments(t, gyro, accel):
    """Trapezoid increments over ``(t[k-1], t[k]]`` of instantaneous rate samples.

    Returns the stamps ``t[1:]``, ``dtheta`` (rad) and ``dvel`` (m/s), shape (n-1, 3).
    """
    dt = np.diff(t)[:, None]
    return t[1:], 0.5 * (gyro[1:] + gyro[:-1]) * dt, 0.5 * (accel[1:] + accel[:-1]) * dt


def read_imu(segment, offset):
    """The segment's IMU as an :class:`ins.nav.imu.ImuLog` in GPS seconds of week."""
    from ins.nav.imu import ImuLog
    tg, gyro = _load(segment, "IMU/gyro")
    ta, accel = _load(segment, "IMU/accelerometer")
    if len(tg) != len(ta) or np.max(np.abs(tg - ta)) > 1e-6:
        raise ValueError("gyro and accelerometer stamps differ")
    t, dth, dv = imu_increments(tg + offset, gyro, accel)
    return ImuLog(t, dth, dv)


def read_ublox(segment, offset, week, stamp="utc", sigma_h=SIGMA_H_M, sigma_v=SIGMA_V_M,
               sigma_vel=SIGMA_VEL_MPS, sigma_vd=SIGMA_VD_MPS):
    """The u-blox fixes as an :class:`ins.io.gnss_log.GnssLog` (GPS seconds of week).

    ``stamp`` = ``"utc"`` (the fix epoch) or ``"arrival"`` (boot clock of arrival).
    Returns the log and the mean of (arrival - epoch), s.
    """
    from ins.io.gnss_log import GnssLog
    t_boot, v = _load(segment, "GNSS/live_gnss_ublox")
    t_utc = v[:, 3] / 1e3 + LEAP_SECONDS - GPS_EPOCH_UNIX - week * WEEK_S
    t_arr = t_boot + offset
    t = t_utc if stamp == "utc" else t_arr
    keep = np.concatenate([[True], np.diff(t) > 0])
    speed, bearing = v[:, 2], np.deg2rad(v[:, 5])
    v_n = np.column_stack([speed * np.cos(bearing), speed * np.sin(bearing),
                           np.zeros(len(t))])
    n = len(t)
    log = GnssLog(time=t, lla=np.column_stack([np.deg2rad(v[:, 0]), np.deg2rad(v[:, 1]),
                                                v[:, 4]]),
                  sigma_ned_m=np.tile([sigma_h, sigma_h, sigma_v], (n, 1)), v_n=v_n,
                  sigma_vel_ned_mps=np.tile([sigma_vel, sigma_vel, sigma_vd], (n, 1)))
    return log.select(keep), float(np.mean(t_arr - t_utc))


def read_reference(segment, offset):
    """comma.ai's camera pose as an :class:`ins.nav.trajectory.Trajectory` (GPS seconds of
    week): position and velocity of the camera, attitude ``C_nc`` of the camera's
    forward-right-down axes."""
    import pymap3d
    from scipy.spatial.transform import Rotation

    from ins.nav import earth
    from ins.nav.trajectory import Trajectory
    gp = Path(segment) / "global_pose"
    t = _npy(gp / "frame_times.npy") + offset
    r_e = _npy(gp / "frame_positions.npy")
    v_e = _npy(gp / "frame_velocities.npy")
    q_wxyz = _npy(gp / "frame_orientations.npy")
    lat, lon, h = pymap3d.ecef2geodetic(r_e[:, 0], r_e[:, 1], r_e[:, 2], deg=False)
    C_en = earth.dcm_en(lat, lon)
    v_n = np.einsum("nji,nj->ni", C_en, v_e)
    C_ec = Rotation.from_quat(q_wxyz[:, [1, 2, 3, 0]]).as_matrix()
    C_nc = np.einsum("nji,njk->nik", C_en, C_ec)
    q_nc = Rotation.from_matrix(C_nc).as_quat()
    return Trajectory(time=t, lla=np.column_stack([lat, lon, h]), v_n=v_n, q_nb=q_nc)


CONFIG = """\
# ins process config of a comma2k19 segment (written by tools/comma2k19.py).
# IMU noise: from the preset (ins process --preset mems).  For --preset land the
# phone's mounting in the car is needed: tools/comma2k19.py --land writes
# config_land.toml with the [vehicle] table estimated from a first solution.
[files]
imu = "imu.txt"
gnss = "gnss.txt"

[imu]
format = "kfgins"
axes = "FRD"

[gnss]
lever_arm_b_m = [0.0, 0.0, 0.0]   # IMU and u-blox antenna in one device (comma EON)

[alignment]
method = "gnss-heading"           # the car drives from the first fix: heading from the track
"""


def retime_gnss(gnss, position_offset_s, velocity_offset_s):
    """The fixes on the IMU's time scale when their positions and velocities carry
    different offsets (IMU clock minus GNSS clock, s, the sign of ``ins.estimation.tools.time_offset``
    and of ``[gnss] time_shift_s``): each record is stamped at its position's IMU time
    ``t + position_offset_s`` and carries the velocity interpolated (linearly) at that
    time from the velocities' IMU times ``t + velocity_offset_s``; records outside the
    velocities' span are dropped."""
    from dataclasses import replace
    t_p = gnss.time + position_offset_s
    t_v = gnss.time + velocity_offset_s
    keep = (t_p >= t_v[0]) & (t_p <= t_v[-1])
    v_n = np.column_stack([np.interp(t_p, t_v, gnss.v_n[:, j]) for j in range(3)])
    return replace(gnss, time=t_p, v_n=v_n).select(keep)


def estimate_offsets(imu, gnss):
    """``ins.estimation.tools.time_offset`` estimates of the positions' and the velocities' offsets."""
    from ins.estimation.tools.time_offset import estimate_time_offset
    return (estimate_time_offset(imu, gnss, source="position"),
            estimate_time_offset(imu, gnss, source="velocity"))


def convert(segment, out_dir, force=False, stamp="utc", offsets="estimate", **sigmas):
    """Write ``imu.txt``, ``gnss.txt``, ``reference.nav``, ``config.toml`` and
    ``conversion.toml`` (module notes) into ``out_dir``; returns a dict of figures.

    ``offsets``: ``"estimate"`` (the positions' and velocities' clock offsets estimated
    from the data by ``ins.estimation.tools.time_offset`` and removed), ``None`` (the stamps as they are)
    or a pair ``(position_offset_s, velocity_offset_s)`` (IMU minus GNSS clock, s).
    """
    from ins.common.fileio import atomic_open, output_folder
    from ins.io.gnss import write_gnss
    from ins.io.imu_files import write_kfgins_text
    from ins.io.navfiles import write_nav
    week, offset, fit_rms = boot_to_gps(segment)
    imu = read_imu(segment, offset)
    gnss, arrival_lag = read_ublox(segment, offset, week, stamp, **sigmas)
    est = {}
    if offsets == "estimate":
        pos, vel = estimate_offsets(imu, gnss)
        est = {"position_offset_sigma_s": pos.sigma_s, "velocity_offset_sigma_s": vel.sigma_s}
        offsets = (pos.offset_s, vel.offset_s)
    if offsets is not None:
        gnss = retime_gnss(gnss, *offsets)
    ref = read_reference(segment, offset)
    dt = np.diff(imu.time)
    info = {"gps_week": week, "boot_to_gps_tow_s": offset, "boot_fit_rms_s": fit_rms,
            "imu_epochs": len(imu), "imu_rate_hz": float(1 / np.median(dt)),
            "imu_dt_min_s": float(dt.min()), "imu_dt_max_s": float(dt.max()),
            "gnss_records": len(gnss), "gnss_stamp": stamp,
            "gnss_arrival_minus_epoch_s": arrival_lag,
            "position_offset_s": offsets[0] if offsets else 0.0,
            "velocity_offset_s": offsets[1] if offsets else 0.0,
            "reference_epochs": len(ref), **est}
    with output_folder(out_dir, force=force) as stage:
        write_kfgins_text(os.path.join(stage, "imu.txt"), imu)
        write_gnss(os.path.join(stage, "gnss.txt"), gnss)
        write_nav(os.path.join(stage, "reference.nav"), ref, week=week)
        with atomic_open(os.path.join(stage, "config.toml"), "w") as f:
            f.write(CONFIG)
        with atomic_open(os.path.join(stage, "conversion.toml"), "w") as f:
            f.write(_conversion_text(segment, info, gnss))
    return info


def land_config(solution, folder):
    """Write ``folder/config_land.toml``: ``folder/config.toml`` plus the ``[vehicle]``
    table of the phone's mounting estimated from ``solution`` (a trajectory processed
    without the constraint; :func:`ins.estimation.tools.vehicle.estimate_mounting`).  Returns the
    :class:`ins.estimation.tools.vehicle.Mounting`."""
    from ins.common.fileio import atomic_open
    from ins.estimation.tools.vehicle import estimate_mounting
    from ins.io.navfiles import read_trajectory
    m = estimate_mounting(read_trajectory(solution))
    base = Path(folder, "config.toml").read_text(encoding="utf-8")
    with atomic_open(os.path.join(folder, "config_land.toml"), "w") as f:
        f.write(base + f"\n# the phone's mounting estimated from {os.path.abspath(solution)} "
                f"({m.n_epochs} epochs of straight driving, {m.n_blocks} blocks of 5 s)\n"
                + m.toml())
    return m


def _sigma(info, name):
    key = f"{name}_offset_sigma_s"
    return f" (estimated, sigma {info[key]:.4f} s)" if key in info else " (given)"


def _conversion_text(segment, info, gnss):
    s, sv = gnss.sigma_ned_m[0], gnss.sigma_vel_ned_mps[0]
    lines = [f"# tools/comma2k19.py of {os.path.abspath(segment)}",
             "[time]",
             f"gps_week = {info['gps_week']}",
             f"boot_to_gps_tow_s = {info['boot_to_gps_tow_s']:.6f}   # tow = boot + this "
             f"(frame_times vs frame_gps_times, RMS {info['boot_fit_rms_s']:.1e} s)",
             f"gnss_stamp = \"{info['gnss_stamp']}\"   # utc: fix epoch; arrival: boot clock",
             f"gnss_arrival_minus_epoch_s = {info['gnss_arrival_minus_epoch_s']:.4f}",
             f"position_offset_s = {info['position_offset_s']:.4f}   # IMU - GNSS clock, "
             f"removed{_sigma(info, 'position')}",
             f"velocity_offset_s = {info['velocity_offset_s']:.4f}   # IMU - GNSS clock, "
             f"removed{_sigma(info, 'velocity')}",
             "[imu]",
             f"epochs = {info['imu_epochs']}",
             f"rate_hz = {info['imu_rate_hz']:.3f}",
             f"interval_s = [{info['imu_dt_min_s']:.6f}, {info['imu_dt_max_s']:.6f}]",
             "increments = \"trapezoid of the rate samples times the real interval\"",
             "[gnss]   # ASSUMED sigmas: the u-blox log has no accuracy field",
             f"records = {info['gnss_records']}",
             f"sigma_ned_m = [{s[0]:g}, {s[1]:g}, {s[2]:g}]",
             f"sigma_vel_ned_mps = [{sv[0]:g}, {sv[1]:g}, {sv[2]:g}]   # vd = 0 (not logged)",
             "[reference]",
             f"epochs = {info['reference_epochs']}",
             "what = \"comma.ai global_pose: camera position, velocity, C_nc of the "
             "camera's FRD axes\"",
             "camera_imu_offset_m = [0.0, 0.0, 0.0]   # one device; rotation estimated"]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------
# comparison with the reference

def interpolate(traj, t):
    """``traj`` at times ``t`` (inside its span): position and velocity linear, attitude
    by slerp (scipy); a :class:`ins.nav.trajectory.Trajectory`."""
    from scipy.spatial.transform import Rotation, Slerp

    from ins.nav.trajectory import Trajectory
    lla = np.column_stack([np.interp(t, traj.time, traj.lla[:, i]) for i in range(3)])
    v_n = np.column_stack([np.interp(t, traj.time, traj.v_n[:, i]) for i in range(3)])
    q = Slerp(traj.time, Rotation.from_quat(traj.q_nb))(t).as_quat()
    return Trajectory(time=np.asarray(t, float), lla=lla, v_n=v_n, q_nb=q)


def mount_rotation(q_nb, q_nc, block_s=5.0, time=None):
    """The constant rotation ``C_bc`` from the body (IMU) to the camera axes, least
    squares on SO(3) (the chordal mean of ``C_nb^T C_nc``, scipy ``Rotation.mean``),
    with its 1-sigma per axis (rad) from the scatter of ``block_s`` block means (the
    residuals are correlated over seconds: one block one independent sample).

    Returns ``(C_bc, sigma_rad (3,), residual rotation vectors (n, 3) in b, rad)``.
    """
    from scipy.spatial.transform import Rotation
    R = Rotation.from_quat(q_nb).inv() * Rotation.from_quat(q_nc)
    mean = R.mean()
    res = (R * mean.inv()).as_rotvec()
    if time is None:
        time = np.arange(len(res), dtype=float)
    blocks = np.floor((time - time[0]) / block_s).astype(int)
    means = np.array([res[blocks == b].mean(axis=0) for b in np.unique(blocks)])
    sigma = means.std(axis=0, ddof=1) / np.sqrt(len(means)) if len(means) > 1 \
        else np.full(3, np.nan)
    return mean.as_matrix(), sigma, res


def compare(solution, reference, gnss=None):
    """Figures of a solution (IMU) against the reference camera pose (module notes).

    Returns a dict: ``horizontal_rms_m``, ``down_rms_m``, ``vel_rms_ned_mps`` (3,),
    ``C_bc`` and ``mount_rpy_deg`` (the estimated camera-to-IMU rotation as roll, pitch,
    yaw of ``C_bc``) with ``mount_sigma_deg`` (3,), ``att_std_deg`` (tilt N, tilt E,
    heading after removing ``C_bc``), ``att_rms_deg`` and, with ``gnss``, the fixes'
    ``fixes_horizontal_rms_m`` against the reference (interpolated at the fix times).
    """
    from scipy.spatial.transform import Rotation

    from ins.nav import earth
    inside = (reference.time >= solution.time[0]) & (reference.time <= solution.time[-1])
    t = reference.time[inside]
    sol = interpolate(solution, t)
    lla_ref = reference.lla[inside]
    d_n = earth.ned_offset(lla_ref, sol.lla)
    dv = sol.v_n - reference.v_n[inside]
    q_nc = reference.q_nb[inside]
    C_bc, sigma, _ = mount_rotation(sol.q_nb, q_nc, time=t)
    q_nb_ref = (Rotation.from_quat(q_nc) * Rotation.from_matrix(C_bc).inv()).as_quat()
    att = (Rotation.from_quat(sol.q_nb) * Rotation.from_quat(q_nb_ref).inv()).as_rotvec()
    out = {"epochs": int(len(t)), "span_s": float(t[-1] - t[0]),
           "horizontal_rms_m": float(np.sqrt(np.mean(np.sum(d_n[:, :2] ** 2, axis=1)))),
           "down_rms_m": float(np.sqrt(np.mean(d_n[:, 2] ** 2))),
           "vel_rms_ned_mps": np.sqrt(np.mean(dv ** 2, axis=0)),
           "C_bc": C_bc,
           "mount_rpy_deg": Rotation.from_matrix(C_bc).as_euler("ZYX", degrees=True)[::-1],
           "mount_sigma_deg": np.rad2deg(sigma),
           "att_std_deg": np.rad2deg(att.std(axis=0)),
           "att_rms_deg": np.rad2deg(np.sqrt(np.mean(att ** 2, axis=0)))}
    if gnss is not None:
        ok = (gnss.time >= reference.time[0]) & (gnss.time <= reference.time[-1])
        at = interpolate(reference, gnss.time[ok])
        e = earth.ned_offset(at.lla, gnss.lla[ok])
        out["fixes_horizontal_rms_m"] = float(np.sqrt(np.mean(np.sum(e[:, :2] ** 2, 1))))
    return out


def format_figures(fig):
    """Lines of text stating the figures of :func:`compare`."""
    v, m, ms = fig["vel_rms_ned_mps"], fig["mount_rpy_deg"], fig["mount_sigma_deg"]
    a, ar = fig["att_std_deg"], fig["att_rms_deg"]
    lines = [f"{fig['epochs']} reference epochs over {fig['span_s']:.1f} s",
             f"horizontal position RMS {fig['horizontal_rms_m']:.3f} m (down "
             f"{fig['down_rms_m']:.3f} m)"]
    if "fixes_horizontal_rms_m" in fig:
        lines.append(f"  the GNSS fixes alone: horizontal RMS "
                     f"{fig['fixes_horizontal_rms_m']:.3f} m")
    lines += [f"velocity RMS N/E/D {v[0]:.3f} / {v[1]:.3f} / {v[2]:.3f} m/s",
              f"camera-to-IMU rotation C_bc (roll, pitch, yaw of the camera's FRD axes in "
              f"b): {m[0]:.3f} / {m[1]:.3f} / {m[2]:.3f} deg, sigma about x/y/z "
              f"{ms[0]:.3f} / {ms[1]:.3f} / {ms[2]:.3f} deg",
              f"attitude after removing C_bc: std tilt N {a[0]:.3f}, tilt E {a[1]:.3f}, "
              f"heading {a[2]:.3f} deg (RMS {ar[0]:.3f} / {ar[1]:.3f} / {ar[2]:.3f})"]
    return lines


# ---------------------------------------------------------------------------------------
# command line

EPILOG = """\
two commands and a comparison:
  python tools/comma2k19.py ../shared/real/comma2k19_segment -o seg
  ins process --config seg/config.toml --preset mems -o seg/out
  python tools/comma2k19.py --compare seg/out/solution.nav seg
the land variant (non-holonomic constraint in the car's axes):
  python tools/comma2k19.py --land seg/out/solution.nav seg
  ins process --config seg/config_land.toml --preset land -o seg/out_land
  python tools/comma2k19.py --compare seg/out_land/solution.nav seg

--compare SOLUTION.nav DIR interpolates the solution (IMU) at the reference epochs of
DIR/reference.nav (camera pose, 20 Hz), estimates the constant camera-to-IMU rotation
C_bc (chordal least squares on SO(3), sigma from 5 s block means) and prints the
horizontal position RMS (m), the velocity RMS north/east/down (m/s), C_bc as roll,
pitch, yaw (deg) with its sigma, and the attitude agreement after removing C_bc (std of
tilt about north and east and of heading, deg); the fixes of DIR/gnss.txt alone for
comparison.  --json writes the same figures.

time base: GPS seconds of week (boot clock + the offset of frame_times to
frame_gps_times).  Offsets: IMU clock - GNSS clock, s (a fix stamped t holds the
IMU time t + offset; the sign of ins time-offset and of [gnss] time_shift_s).
"""


def _parser():
    p = argparse.ArgumentParser(
        prog="tools/comma2k19.py", description="Convert a comma2k19 segment to the "
        "toolkit's IMU, GNSS, reference and config files; or compare a solution with the "
        "reference pose.", epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("segment", nargs="?", metavar="SEGMENT", help="comma2k19 segment folder")
    p.add_argument("-o", "--output", metavar="DIR", help="output folder (new or empty)")
    p.add_argument("--force", action="store_true", help="replace a non-empty DIR")
    p.add_argument("--gnss-time", choices=["utc", "arrival"], default="utc",
                   help="stamp of the fixes: their UTC epoch (default) or their arrival "
                        "on the boot clock (0.2 s later)")
    p.add_argument("--offsets", default="estimate", metavar="POS,VEL|estimate|none",
                   help="clock offsets (IMU - GNSS, s) of the positions and the velocities "
                        "to remove: 'estimate' (default: ins.estimation.tools.time_offset from the data), "
                        "'none', or two numbers")
    p.add_argument("--sigma-h", type=float, default=SIGMA_H_M, metavar="M",
                   help=f"assumed horizontal sigma of a fix, m (default {SIGMA_H_M:g})")
    p.add_argument("--sigma-v", type=float, default=SIGMA_V_M, metavar="M",
                   help=f"assumed vertical sigma of a fix, m (default {SIGMA_V_M:g})")
    p.add_argument("--sigma-vel", type=float, default=SIGMA_VEL_MPS, metavar="MPS",
                   help=f"assumed horizontal velocity sigma, m/s (default {SIGMA_VEL_MPS:g})")
    p.add_argument("--sigma-vd", type=float, default=SIGMA_VD_MPS, metavar="MPS",
                   help=f"sigma of the unlogged vertical velocity written as 0, m/s "
                        f"(default {SIGMA_VD_MPS:g}: practically unused)")
    p.add_argument("--compare", nargs=2, metavar=("SOLUTION", "DIR"),
                   help="figures of a solution .nav against DIR/reference.nav")
    p.add_argument("--json", metavar="F", help="with --compare: also write the figures")
    p.add_argument("--land", nargs=2, metavar=("SOLUTION", "DIR"),
                   help="write DIR/config_land.toml: DIR/config.toml + the [vehicle] table "
                        "of the phone's mounting (pitch, yaw in the car, deg) estimated from "
                        "SOLUTION (processed without the constraint)")
    return p


def _offsets(text):
    if text in ("estimate", "none"):
        return None if text == "none" else "estimate"
    try:
        pos, vel = (float(x) for x in text.split(","))
    except ValueError:
        raise SystemExit(f"tools/comma2k19.py: error: --offsets {text!r}: expected "
                         f"'estimate', 'none' or POS,VEL in s") from None
    return pos, vel


def _figures_json(fig, path):
    import json

    from ins.common.fileio import atomic_open
    clean = {k: (np.asarray(v).tolist() if isinstance(v, np.ndarray) else v)
             for k, v in fig.items()}
    with atomic_open(path, "w") as f:
        json.dump(clean, f, indent=1)


def main(argv=None):
    from ins.common.errors import InputError
    from ins.io.gnss import read_gnss
    from ins.io.navfiles import read_nav
    args = _parser().parse_args(argv)
    try:
        if args.compare:
            sol, folder = args.compare
            fig = compare(read_nav(sol), read_nav(os.path.join(folder, "reference.nav")),
                          read_gnss(os.path.join(folder, "gnss.txt")))
            print("\n".join(format_figures(fig)))
            if args.json:
                _figures_json(fig, args.json)
            return 0
        if args.land:
            m = land_config(*args.land)
            print(f"mounting of the IMU in the car: pitch {m.rpy_deg[1]:+.3f} deg (sigma "
                  f"{m.sigma_deg[0]:.3f}), yaw {m.rpy_deg[2]:+.3f} deg (sigma "
                  f"{m.sigma_deg[1]:.3f}); wrote {os.path.join(args.land[1], 'config_land.toml')}")
            return 0
        if not args.segment or not args.output:
            raise InputError("SEGMENT and -o DIR are required (or --compare SOLUTION DIR)")
        info = convert(args.segment, args.output, force=args.force, stamp=args.gnss_time,
                       offsets=_offsets(args.offsets), sigma_h=args.sigma_h,
                       sigma_v=args.sigma_v, sigma_vel=args.sigma_vel, sigma_vd=args.sigma_vd)
    except (InputError, OSError) as exc:
        print(f"tools/comma2k19.py: error: {exc}", file=sys.stderr)
        return 2
    print(f"{info['imu_epochs']} IMU epochs at {info['imu_rate_hz']:.1f} Hz, "
          f"{info['gnss_records']} fixes, {info['reference_epochs']} reference epochs; "
          f"GPS week {info['gps_week']}, tow = boot + {info['boot_to_gps_tow_s']:.6f} s")
    print(f"fixes stamped by their {info['gnss_stamp']} time; removed clock offsets "
          f"(IMU - GNSS clock): positions {info['position_offset_s']:+.4f} s, velocities "
          f"{info['velocity_offset_s']:+.4f} s" +
          (f" (estimated, sigma {info['position_offset_sigma_s']:.4f} / "
           f"{info['velocity_offset_sigma_s']:.4f} s)" if "position_offset_sigma_s" in info
           else ""))
    print(f"wrote {args.output}/: imu.txt gnss.txt reference.nav config.toml conversion.toml")
    return 0


if __name__ == "__main__":
    sys.exit(main())
