"""Output files of ``ins process``: solution.nav, solution_std.txt, imu_errors.txt,
innovations.txt, states.txt (optional state groups) and forward.nav
(:func:`write_outputs`), or the solution as an Applanix SBET with its SMRMSG
accuracy file (``formats=("sbet",)``: sbet_solution.out, smrmsg_solution.out,
sbet_forward.out), and the roll, pitch, yaw sigmas of a phi-angle covariance
(:func:`euler_std_deg`)."""
import os

import numpy as np

from ins.estimation.core.error_model import NAV, SENSORS, STATE, attitude_block


def euler_std_deg(q_nb, P_att):
    """Roll, pitch, yaw standard deviations (deg) from the phi-angle covariance (rad^2).

    ``phi = E d(roll, pitch, yaw)`` with the columns of ``E`` the roll axis
    ``Rz(yaw) Ry(pitch) e_x``, the pitch axis ``Rz(yaw) e_y`` and the yaw axis ``e_z``
    (in n), so ``Cov(rpy) = E^-1 P E^-T``.
    """
    from ins.nav.rotation import quat_to_euler
    rpy = quat_to_euler(q_nb)
    _, p, y = rpy.T
    E = np.zeros((len(rpy), 3, 3))
    E[:, :, 0] = np.column_stack([np.cos(y) * np.cos(p), np.sin(y) * np.cos(p), -np.sin(p)])
    E[:, :, 1] = np.column_stack([-np.sin(y), np.cos(y), np.zeros_like(y)])
    E[:, 2, 2] = 1.0
    Ei = np.linalg.inv(E)
    cov = Ei @ P_att @ np.swapaxes(Ei, 1, 2)
    # with P_att positive semi-definite the diagonal is >= 0 up to rounding; a variance
    # below -1e-9 of the sum of the terms that make it is a failure, not rounding
    from ins.estimation.core.error_model import checked_std
    scale = np.einsum("mij,mjk,mik->mi", np.abs(Ei), np.abs(P_att), np.abs(Ei))
    return np.rad2deg(checked_std(np.einsum("mii->mi", cov), scale,
                                  names=("roll", "pitch", "yaw"),
                                  what="attitude (roll, pitch, yaw) covariance"))


#: Trajectory formats of :func:`write_outputs`.
OUTPUT_FORMATS = ("nav", "sbet")


def write_outputs(result, out_dir, week=0, forward=False, formats=("nav",), height=None):
    """Write the smoothed trajectory in each of ``formats`` (``"nav"``: solution.nav;
    ``"sbet"``: sbet_solution.out and its accuracy file smrmsg_solution.out at the filter
    nodes), solution_std.txt, imu_errors.txt and, with ``forward=True``, the forward
    filter's trajectory (forward.nav / sbet_forward.out, a diagnostic).  With an
    orthometric ``height`` (:class:`ins.io.geoid.HeightSystem`) also
    solution_orthometric.txt (:func:`write_orthometric`); the trajectories keep their
    ellipsoidal heights (the formats define them so).

    The roll, pitch, yaw sigmas (solution_std.txt, smrmsg_solution.out) are
    :func:`euler_std_deg` of the whole smoothed phi-angle block: the attitude sigmas and
    cross covariances of the nodes (``smoothed_att_cross``; uncorrelated only for a
    ``result`` without them).

    The trajectories are written piece by piece as they are streamed (bounded memory).
    Returns the list of written paths.  Every file is written atomically.
    """
    from ins.common import textformat
    from ins.common.fileio import atomic_open
    from ins.estimation.core.error_model import DPH, MGAL, PPM
    from ins.io.navfiles import write_nav
    from ins.io.sbet import write_sbet, write_smrmsg
    unknown = [f for f in formats if f not in OUTPUT_FORMATS]
    if unknown or not formats:
        raise ValueError(f"formats must be some of {', '.join(OUTPUT_FORMATS)}, got {formats!r}")
    os.makedirs(out_dir, exist_ok=True)
    paths = []
    if "nav" in formats:
        paths.append(os.path.join(out_dir, "solution.nav"))
        write_nav(paths[-1], result.iter_smoothed(), week=week)
    if "sbet" in formats:
        paths.append(os.path.join(out_dir, "sbet_solution.out"))
        write_sbet(paths[-1], result.iter_smoothed())
    if forward:
        if "nav" in formats:
            paths.append(os.path.join(out_dir, "forward.nav"))
            write_nav(paths[-1], result.iter_forward(), week=week)
        if "sbet" in formats:
            paths.append(os.path.join(out_dir, "sbet_forward.out"))
            write_sbet(paths[-1], result.iter_forward())
    std_path = os.path.join(out_dir, "solution_std.txt")
    err_path = os.path.join(out_dir, "imu_errors.txt")
    std_header = ("# time_s std_n_m std_e_m std_d_m std_vn_mps std_ve_mps std_vd_mps "
                  "std_roll_deg std_pitch_deg std_yaw_deg  (smoothed, at the filter nodes)\n")
    err_header = ("# time_s gyro_bias_x_dph gyro_bias_y_dph gyro_bias_z_dph "
                  "accel_bias_x_mgal accel_bias_y_mgal accel_bias_z_mgal gyro_scale_x_ppm "
                  "gyro_scale_y_ppm gyro_scale_z_ppm accel_scale_x_ppm accel_scale_y_ppm "
                  "accel_scale_z_ppm (smoothed estimates)\n")
    std_dec = np.array([6] + [6] * 6 + [8] * 3, dtype=np.int64)
    err_dec = np.array([6] + [5] * 12, dtype=np.int64)
    smrmsg = []
    # block by block over the nodes (bounded memory)
    with atomic_open(std_path, "wb") as f_std, atomic_open(err_path, "wb") as f_err:
        f_std.write(std_header.encode())
        f_err.write(err_header.encode())
        for c in _node_chunks(result):
            sd = c.smoothed_std
            # roll/pitch/yaw sigmas from the whole smoothed phi-angle block: the N/E/D
            # errors are correlated (a level platform at a diagonal heading mixes the
            # roll and pitch errors into N and E), their cross terms matter
            cross = getattr(c, "smoothed_att_cross", None)
            P_att = attitude_block(sd[:, STATE.att], np.zeros((len(sd), 3)) if cross is None
                                   else cross)
            att = euler_std_deg(c.solution[:, NAV.q_nb], P_att)
            table = np.column_stack([c.time, sd[:, STATE.pos], sd[:, STATE.vel], att])
            f_std.write(textformat.format_fixed(table, std_dec).tobytes())
            if "sbet" in formats:
                smrmsg.append(np.column_stack([c.time, sd[:, STATE.pos], sd[:, STATE.vel],
                                               np.deg2rad(att)]))
            s = c.smoothed_sensors
            table = np.column_stack([c.time, s[:, SENSORS.gyro_bias] / DPH,
                                     s[:, SENSORS.accel_bias] / MGAL,
                                     s[:, SENSORS.gyro_scale] / PPM,
                                     s[:, SENSORS.accel_scale] / PPM])
            f_err.write(textformat.format_fixed(table, err_dec).tobytes())
    paths.append(std_path)
    if "sbet" in formats:
        rows = np.concatenate(smrmsg)
        paths.append(os.path.join(out_dir, "smrmsg_solution.out"))
        write_smrmsg(paths[-1], rows[:, 0], rows[:, 1:4], rows[:, 4:7], rows[:, 7:10])
    paths.append(err_path)
    if height is not None and height.orthometric:
        paths.append(os.path.join(out_dir, ORTHOMETRIC_FILE))
        write_orthometric(paths[-1], result.iter_smoothed(), height, week=week)
    from ins.estimation.core.measurements import write_innovations
    from ins.estimation.pipeline.state_files import write_optional_states
    records = getattr(result.fwd, "records", None)
    if records:
        paths.append(os.path.join(out_dir, "innovations.txt"))
        write_innovations(paths[-1], records)
    states = write_optional_states(os.path.join(out_dir, "states.txt"), result)
    if states:
        paths.append(states)
    return paths


#: The file of the smoothed trajectory's orthometric heights.
ORTHOMETRIC_FILE = "solution_orthometric.txt"


def write_orthometric(path, pieces, height, week=0):
    """Write the orthometric heights of trajectory ``pieces`` (Trajectory blocks) under a
    header naming the height system and the geoid model: ``week time_s lat_deg lon_deg
    h_ellipsoidal_m geoid_undulation_m H_<model>_m``, atomically.  Returns the epochs."""
    from ins.common import textformat
    from ins.common.fileio import atomic_open
    dec = np.array([0, 6, 12, 12, 5, 5, 5], dtype=np.int64)
    n = 0
    with atomic_open(path, "wb") as f:
        f.write((f"# heights: {height.description()}\n"
                 f"# week time_s lat_deg lon_deg h_ellipsoidal_m geoid_undulation_m "
                 f"{height.column()}  (smoothed trajectory of solution.nav, its epochs)\n"
                 ).encode())
        for piece in pieces:
            lat, lon, h = piece.lla.T
            N = height.undulation(lat, lon)
            table = np.column_stack([np.full(len(piece), float(week)), piece.time,
                                     np.rad2deg(lat), np.rad2deg(lon), h, N, h - N])
            f.write(textformat.format_fixed(table, dec).tobytes())
            n += len(piece)
    return n


def _node_chunks(result):
    """Per-node blocks of ``result`` (:meth:`ins.estimation.pipeline.process.ProcessResult.node_chunks`),
    or one block of its arrays (a result given as arrays)."""
    if hasattr(result, "node_chunks"):
        yield from result.node_chunks()
        return
    from types import SimpleNamespace
    yield SimpleNamespace(j0=0, time=result.node_time, smoothed_std=result.smoothed_std,
                          smoothed_att_cross=getattr(result, "smoothed_att_cross", None),
                          smoothed_sensors=result.smoothed_sensors,
                          solution=result.node_solution())
