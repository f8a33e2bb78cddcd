"""Exterior orientation per exposure: from a trajectory at event times, and its files.

The chain (``conventions.md``): interpolate the IMU trajectory at each event time
(:func:`ins.nav.interpolation.interpolate_trajectory`), move to the perspective centre with
the lever arm ``r_cam = r_imu + C_nb lever_b`` (exact, in ECEF), express it in the
mapping frame, and form ``C_mc = C_mn C_nb C_bc`` (:mod:`photogrammetry.orientation.mapping`,
:class:`photogrammetry.orientation.camera.CameraMounting`); the angles are extracted in the named
system.  ``C_nb`` refers to the local level at the IMU, so ``C_mn`` is that of the n
frame at the IMU: for ENU ``dcm_mn_enu(lat_imu, lon_imu, ...)``; for a projection the
convergence is taken at the camera and the n frame carried from the IMU to the camera
(``C_en(cam)^T C_en(imu)``, a ~0.03 arcsec/m correction).

Files:

- EO CSV (``docs/interfaces.md``): header comments naming the system, frame and units,
  then ``image_id,time_s,X_m,Y_m,Z_m,<angles>_deg[,sigmas]``.  Every angle written to a
  file is wrapped to (-180, 180] deg (:func:`wrapped_deg`).
- Applanix-style text: ``ID event time_s E_m N_m h_m omega_deg phi_deg kappa_deg``
  (always omega-phi-kappa, whitespace separated).
- PATB-style: per image a line ``ID X0 Y0 Z0`` and three lines of the rotation matrix
  ``R = C_mc`` by rows (camera to mapping frame), ``-99`` at the end.
"""
import csv
import io
from dataclasses import dataclass, replace

import numpy as np

from ins.common import textfiles
from ins.common.errors import InputError
from ins.common.fileio import atomic_open
from ins.nav.earth import dcm_en, offset_lla
from ins.nav.interpolation import interpolate_linear, interpolate_trajectory
from ins.nav.rotation import euler_to_dcm, quat_to_dcm, quat_to_euler, wrap_to_pi
from photogrammetry.orientation.rotation import (
    SYSTEMS,
    angles_to_matrix,
    check_system,
    matrix_to_angles,
)

__all__ = ["ExposureOrientation", "compute_eo", "read_events", "read_solution_std",
           "read_eo_header",
           "write_eo_csv", "read_eo_csv", "write_eo_applanix", "read_eo_applanix",
           "write_eo_patb", "read_eo_patb", "angle_names", "wrapped_deg"]

_MAGIC = "# insphoto exterior orientation"
_UNITS = "time_s GPS seconds of week; X Y Z m; angles deg; sigmas in the same units"


def angle_names(system):
    """Names of the three angles in the order of `system`, e.g. ``("phi", "omega", "kappa")``."""
    return tuple(check_system(system).split("-"))


@dataclass(frozen=True, eq=False)
class ExposureOrientation:
    """Exterior orientation of n exposures.

    Attributes
    ----------
    image_id : tuple of str
    time : ndarray (n,)
        Event time, s.
    position : ndarray (n, 3)
        Perspective centre in the mapping frame, m.
    angles : ndarray (n, 3)
        Angles of ``C_mc`` in the order of `system`, rad.
    system : str
        ``"phi-omega-kappa"`` or ``"omega-phi-kappa"``.
    frame : str
        Mapping-frame description (the EO CSV ``# frame =`` value).
    position_sigma : ndarray (n, 3) or None
        Standard deviations of the position, m.
    angle_sigma : ndarray (n, 3) or None
        Standard deviations of the angles (same order), rad.
    """

    image_id: tuple
    time: np.ndarray
    position: np.ndarray
    angles: np.ndarray
    system: str
    frame: str
    position_sigma: np.ndarray = None
    angle_sigma: np.ndarray = None

    def __post_init__(self):
        check_system(self.system)
        n = len(self.image_id)
        object.__setattr__(self, "image_id", tuple(str(i) for i in self.image_id))
        for name, shape in (("time", (n,)), ("position", (n, 3)), ("angles", (n, 3)),
                            ("position_sigma", (n, 3)), ("angle_sigma", (n, 3))):
            v = getattr(self, name)
            if v is None:
                continue
            v = np.array(v, dtype=float)
            if v.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {v.shape}")
            v.setflags(write=False)
            object.__setattr__(self, name, v)

    def __len__(self):
        return len(self.image_id)

    @property
    def has_sigmas(self):
        return self.position_sigma is not None and self.angle_sigma is not None

    def matrices(self):
        """``C_mc`` of every exposure, (n, 3, 3)."""
        return angles_to_matrix(self.angles, self.system)

    def in_system(self, system):
        """The same orientation with angles (and their sigmas) in another system."""
        check_system(system)
        if system == self.system:
            return self
        angles = matrix_to_angles(self.matrices(), system)
        sig = None
        if self.angle_sigma is not None:
            J = _angle_jacobian(self.angles, lambda a: matrix_to_angles(
                angles_to_matrix(a, self.system), system))
            sig = _propagate(J, self.angle_sigma)
        return replace(self, angles=angles, system=system, angle_sigma=sig)


def _angle_jacobian(x, func, step=1e-7):
    """Central-difference Jacobian (n, 3, 3) of angle-valued func at x (n, 3)."""
    J = np.empty(x.shape + (3,))
    for j in range(3):
        d = np.zeros(3)
        d[j] = step
        J[:, :, j] = wrap_to_pi(func(x + d) - func(x - d)) / (2 * step)
    return J


def _propagate(J, sigma):
    """sqrt(diag(J diag(sigma^2) J^T)), (n, 3)."""
    return np.sqrt(np.einsum("nij,nj->ni", J * J, sigma * sigma))


# --------------------------------------------------------------------------
def compute_eo(traj, image_ids, times, mounting, frame, system="phi-omega-kappa",
               sigma=None, method="cubic", path=None):
    """Exterior orientation of exposures from an IMU trajectory.

    Parameters
    ----------
    traj : ins.nav.trajectory.Trajectory
        IMU trajectory (lat/lon rad, h m ellipsoidal, NED velocity m/s, q_nb).
    image_ids : sequence of str, length n
    times : array_like, shape (n,)
        Event (mid-exposure) times, s, inside the trajectory.
    mounting : photogrammetry.orientation.camera.CameraMounting
        Camera axes, boresight (``C_bc``) and lever arm (IMU to perspective centre, b, m).
    frame : EnuFrame or ProjectedFrame
        Mapping frame (:mod:`photogrammetry.orientation.mapping`).
    system : {"phi-omega-kappa", "omega-phi-kappa"}
    sigma : (ndarray (k,), ndarray (k, 9)), optional
        Time (s) and standard deviations of the trajectory: N, E, D (m), vN, vE, vD
        (m/s), roll, pitch, yaw (rad) (:func:`read_solution_std`).  Interpolated
        linearly; position sigmas rotated into the mapping frame (correlations and the
        lever arm's share neglected), angle sigmas through the Jacobian of the angles
        with respect to roll, pitch, yaw.
    method : {"cubic", "slerp"}
        Attitude interpolation.
    path : str, optional
        Trajectory file name for error messages.

    Returns
    -------
    ExposureOrientation
    """
    check_system(system)
    image_ids = [str(i) for i in image_ids]
    times = np.asarray(times, dtype=float)
    if times.shape != (len(image_ids),):
        raise ValueError(f"times must have shape ({len(image_ids)},), got {times.shape}")
    at = interpolate_trajectory(traj, times, method=method, names=image_ids, path=path)
    C_nb = quat_to_dcm(at.q_nb)
    lla_c = offset_lla(at.lla, C_nb @ np.asarray(mounting.lever_arm_m, dtype=float))
    # C_nb refers to the n frame at the IMU: C_mn(camera) C_en(camera)^T C_en(IMU)
    C_ncam_nimu = np.swapaxes(dcm_en(lla_c[:, 0], lla_c[:, 1]), -1, -2) @ dcm_en(
        at.lla[:, 0], at.lla[:, 1])
    C_mn = frame.C_mn(lla_c) @ C_ncam_nimu
    C_bc = mounting.C_bc

    def angles_of(rpy_):
        return matrix_to_angles(C_mn @ euler_to_dcm(rpy_) @ C_bc, system)

    angles = matrix_to_angles(C_mn @ C_nb @ C_bc, system)
    sig_pos = sig_ang = None
    if sigma is not None:
        s_time, s_val = sigma
        std = interpolate_linear(s_time, s_val, times, names=image_ids)
        sig_pos = np.sqrt(np.einsum("nij,nj->ni", C_mn * C_mn, std[:, 0:3] ** 2))
        sig_ang = _propagate(_angle_jacobian(quat_to_euler(at.q_nb), angles_of), std[:, 6:9])
    return ExposureOrientation(image_ids, times, frame.position(lla_c), angles, system,
                               frame.header(), sig_pos, sig_ang)


# --------------------------------------------------------------------------
# inputs: events, solution standard deviations
def read_events(path):
    """Read an events file ``image_id,time_s`` (header line required): ids, times (s)."""
    path = str(path)
    ids, times, seen = [], [], {}
    text = textfiles.read_text(path, "a CSV file image_id,time_s")
    rows = csv.reader(io.StringIO(text, newline=""))
    header = None
    for row in rows:
        line = rows.line_num
        if not row or row[0].lstrip().startswith("#"):
            continue
        row = [c.strip() for c in row]
        if header is None:
            header = row
            if header[:2] != ["image_id", "time_s"]:
                raise InputError(f"header must start with image_id,time_s, got "
                                 f"{','.join(header)!r}", path=path, line=line)
            continue
        if len(row) < 2:
            raise InputError("expected image_id,time_s", path=path, line=line)
        try:
            t = float(row[1])
        except ValueError:
            raise InputError(f"time_s {row[1]!r} is not a number (s)", path=path,
                             line=line) from None
        if not np.isfinite(t):
            raise InputError(f"time_s {row[1]!r} is not finite", path=path, line=line)
        if row[0] in seen:
            raise InputError(f"image_id {row[0]!r} repeats line {seen[row[0]]}",
                             path=path, line=line)
        seen[row[0]] = line
        ids.append(row[0])
        times.append(t)
    if header is None or not ids:
        raise InputError("no events (expected a header image_id,time_s and rows)", path=path)
    return ids, np.array(times)


def read_solution_std(path):
    """Read a solution standard-deviation file (``solution_std.txt``).

    Columns: ``time_s std_N std_E std_D [m] std_vN std_vE std_vD [m/s]
    std_roll std_pitch std_yaw [deg]``.

    Returns
    -------
    time : ndarray (k,)
    std : ndarray (k, 9)
        SI units (m, m/s, rad).
    """
    rows, row_line = textfiles.read_table(path, ncols_min=10, ncols_max=64,
                                        hint="time std_N std_E std_D std_vN std_vE std_vD "
                                             "std_roll std_pitch std_yaw")
    rows = np.array(rows[:, :10])
    bad = np.flatnonzero(~np.all(np.isfinite(rows), axis=1) | np.any(rows[:, 1:] < 0, axis=1))
    if bad.size:
        raise InputError("standard deviations must be finite and >= 0", path=str(path),
                         line=int(row_line[bad[0]]))
    if np.any(np.diff(rows[:, 0]) <= 0):
        k = int(np.flatnonzero(np.diff(rows[:, 0]) <= 0)[0]) + 1
        raise InputError("time not increasing", path=str(path), line=int(row_line[k]))
    rows[:, 7:10] = np.deg2rad(rows[:, 7:10])
    return rows[:, 0], rows[:, 1:]


# --------------------------------------------------------------------------
# EO CSV
def _fmt(v, decimals):
    return f"{v:.{decimals}f}"


def wrapped_deg(angles_rad, decimals=10):
    """Angles (rad) as degrees in (-180, 180], rounded to `decimals` (what the files
    hold: an angle written as -180.0000000000 after rounding is written as 180).

    Parameters
    ----------
    angles_rad : array_like
        Any shape; unwrapped values (e.g. an adjustment's kappa of 180.05 deg) allowed.
    decimals : int

    Returns
    -------
    ndarray, same shape, deg
    """
    d = np.round(np.rad2deg(wrap_to_pi(np.asarray(angles_rad, dtype=float))), decimals)
    return np.where(d <= -180.0, d + 360.0, d) + 0.0


def write_eo_csv(path, eo, system=None, comments=()):
    """Write an EO CSV (atomically).

    Parameters
    ----------
    path : str
    eo : ExposureOrientation
    system : str, optional
        Convert the angles (and their sigmas) to this system first.
    comments : iterable of str
        Extra ``# key = value`` lines after the units line (e.g. the sources).
    """
    if system is not None:
        eo = eo.in_system(system)
    names = angle_names(eo.system)
    cols = ["image_id", "time_s", "X_m", "Y_m", "Z_m"] + [f"{a}_deg" for a in names]
    if eo.has_sigmas:
        cols += ["sigma_X_m", "sigma_Y_m", "sigma_Z_m"] + [f"sigma_{a}_deg" for a in names]
    out = io.StringIO()
    out.write(f"{_MAGIC}\n# system = {eo.system}\n# frame = {eo.frame}\n# units: {_UNITS}\n")
    for c in comments:
        out.write(f"# {c}\n")
    out.write(",".join(cols) + "\n")
    deg = wrapped_deg(eo.angles)                 # (-180, 180], whatever eo holds
    for i in range(len(eo)):
        fields = [eo.image_id[i], _fmt(eo.time[i], 6)]
        fields += [_fmt(v, 6) for v in eo.position[i]] + [_fmt(v, 10) for v in deg[i]]
        if eo.has_sigmas:
            fields += [_fmt(v, 6) for v in eo.position_sigma[i]]
            fields += [_fmt(v, 10) for v in np.rad2deg(eo.angle_sigma[i])]
        out.write(",".join(fields) + "\n")
    with atomic_open(path, "w") as f:
        f.write(out.getvalue())


def _header_values(lines, path):
    meta = {}
    for k, text in enumerate(lines, 1):
        body = text[1:].strip()
        if body.startswith("units:"):
            meta["units"] = body[6:].strip()
        elif "=" in body:
            key, value = body.split("=", 1)
            meta.setdefault(key.strip(), value.strip())
    return meta


def read_eo_header(path):
    """The ``# key = value`` comment lines at the top of an EO CSV as a dict of strings
    (the first of a repeated key; ``units`` from ``# units:``), e.g. ``system``,
    ``frame`` and the sources ``photogrammetry eo`` names (``trajectory``,
    ``trajectory sigma``, ``events``, ``camera``)."""
    text = textfiles.read_text(str(path), "an EO CSV file (image_id,time_s,X_m,...)")
    comments = []
    for line in text.splitlines():
        if line.startswith("#"):
            comments.append(line)
        elif line.strip():
            break
    return _header_values(comments, str(path))


def read_eo_csv(path):
    """Read an EO CSV into an :class:`ExposureOrientation` (angles in rad, SI).

    The system comes from the ``# system =`` line (or, failing that, from the angle
    columns), the frame from ``# frame =``.  Errors name the file and line.
    """
    path = str(path)
    text = textfiles.read_text(path, "an EO CSV file (image_id,time_s,X_m,...)").splitlines()
    comments, k = [], 0
    while k < len(text) and (text[k].startswith("#") or not text[k].strip()):
        comments.append(text[k]) if text[k].startswith("#") else None
        k += 1
    if k == len(text):
        raise InputError("no header line (image_id,time_s,X_m,...)", path=path)
    meta = _header_values(comments, path)
    header = [c.strip() for c in text[k].split(",")]
    header_line = k + 1
    system = meta.get("system")
    if system is None:
        for s in SYSTEMS:
            if header[5:8] == [f"{a}_deg" for a in angle_names(s)]:
                system = s
    if system is None:
        raise InputError("angle system not stated: no '# system = ...' comment and the "
                         f"angle columns {','.join(header[5:8])} name none; expected "
                         "'# system = phi-omega-kappa' or 'omega-phi-kappa'", path=path,
                         line=header_line)
    if system not in SYSTEMS:
        raise InputError(f"unknown angle system {system!r}; expected "
                         "'# system = phi-omega-kappa' or 'omega-phi-kappa'", path=path)
    names = angle_names(system)
    base = ["image_id", "time_s", "X_m", "Y_m", "Z_m"] + [f"{a}_deg" for a in names]
    sig = ["sigma_X_m", "sigma_Y_m", "sigma_Z_m"] + [f"sigma_{a}_deg" for a in names]
    if header not in (base, base + sig):
        raise InputError(f"columns must be {','.join(base)}[,{','.join(sig)}] for "
                         f"{system}, got {','.join(header)}", path=path, line=header_line)
    ids, rows = [], []
    for j in range(k + 1, len(text)):
        if not text[j].strip() or text[j].startswith("#"):
            continue
        parts = [c.strip() for c in text[j].split(",")]
        if len(parts) != len(header):
            raise InputError(f"expected {len(header)} fields, got {len(parts)}", path=path,
                             line=j + 1)
        try:
            values = [float(v) for v in parts[1:]]
        except ValueError as exc:
            raise InputError(f"not a number: {exc}", path=path, line=j + 1) from None
        if not np.all(np.isfinite(values)):
            raise InputError("non-finite value", path=path, line=j + 1)
        ids.append(parts[0])
        rows.append(values)
    if not rows:
        raise InputError("no exposures", path=path)
    a = np.array(rows)
    has_sig = a.shape[1] == 13
    return ExposureOrientation(ids, a[:, 0], a[:, 1:4], np.deg2rad(a[:, 4:7]), system,
                               meta.get("frame", "unknown"),
                               a[:, 7:10] if has_sig else None,
                               np.deg2rad(a[:, 10:13]) if has_sig else None)


# --------------------------------------------------------------------------
# Applanix-style text and PATB-style matrices
def write_eo_applanix(path, eo):
    """Applanix-style EO text: ``ID event time_s E_m N_m h_m omega_deg phi_deg kappa_deg``
    (omega-phi-kappa, whitespace separated, event = 1-based exposure number)."""
    eo = eo.in_system("omega-phi-kappa")
    deg = wrapped_deg(eo.angles)
    out = io.StringIO()
    out.write(f"{_MAGIC}, Applanix-style\n# system = omega-phi-kappa\n# frame = {eo.frame}\n"
              "# ID event time_s E_m N_m h_m omega_deg phi_deg kappa_deg\n")
    for i in range(len(eo)):
        x, y, z = eo.position[i]
        out.write(f"{eo.image_id[i]} {i + 1} {eo.time[i]:.6f} {x:.6f} {y:.6f} {z:.6f} "
                  f"{deg[i, 0]:.10f} {deg[i, 1]:.10f} {deg[i, 2]:.10f}\n")
    with atomic_open(path, "w") as f:
        f.write(out.getvalue())


def _data_lines(path):
    for n, line in enumerate(textfiles.read_text(path, "an EO text file").splitlines(), 1):
        s = line.strip()
        if s and not s.startswith("#"):
            yield n, s.split()


def _numbers(parts, path, line, count):
    if len(parts) != count:
        raise InputError(f"expected {count} fields, got {len(parts)}", path=path, line=line)
    try:
        v = [float(p) for p in parts]
    except ValueError as exc:
        raise InputError(f"not a number: {exc}", path=path, line=line) from None
    if not np.all(np.isfinite(v)):
        raise InputError("non-finite value", path=path, line=line)
    return v


def _frame_of(path):
    lines = textfiles.read_text(path, "an EO text file").splitlines()
    meta = _header_values([ln for ln in lines if ln.startswith("#")], path)
    return meta.get("frame", "unknown")


def read_eo_applanix(path):
    """Read the Applanix-style EO text (omega-phi-kappa, deg) into an ExposureOrientation."""
    path = str(path)
    ids, rows = [], []
    for line, parts in _data_lines(path):
        rows.append(_numbers(parts[1:], path, line, 8))
        ids.append(parts[0])
    if not rows:
        raise InputError("no exposures", path=path)
    a = np.array(rows)
    return ExposureOrientation(ids, a[:, 1], a[:, 2:5], np.deg2rad(a[:, 5:8]),
                               "omega-phi-kappa", _frame_of(path))


def write_eo_patb(path, eo):
    """PATB-style file: per image ``ID X0 Y0 Z0`` then ``R = C_mc`` by rows; ``-99`` ends."""
    R = eo.matrices()
    out = io.StringIO()
    out.write(f"{_MAGIC}, PATB-style rotation matrices\n# frame = {eo.frame}\n"
              "# ID X0_m Y0_m Z0_m, then R = C_mc (camera to mapping frame) row by row\n")
    for i in range(len(eo)):
        x, y, z = eo.position[i]
        out.write(f"{eo.image_id[i]} {x:.6f} {y:.6f} {z:.6f}\n")
        for row in R[i]:
            out.write("  " + " ".join(f"{v:.15f}" for v in row) + "\n")
    out.write("-99\n")
    with atomic_open(path, "w") as f:
        f.write(out.getvalue())


def read_eo_patb(path, system="phi-omega-kappa"):
    """Read a PATB-style file; angles in `system` (the file has no times: NaN).

    Raises InputError naming the line for a truncated record or a matrix that is not a
    rotation (``|R R^T - I| > 1e-9`` or det < 0).
    """
    path = str(path)
    check_system(system)
    ids, pos, mats = [], [], []
    lines = list(_data_lines(path))
    k = 0
    while k < len(lines):
        line, parts = lines[k]
        if parts == ["-99"]:
            break
        if k + 3 >= len(lines):
            raise InputError("truncated record: an ID line needs three matrix rows",
                             path=path, line=line)
        pos.append(_numbers(parts[1:], path, line, 3))
        ids.append(parts[0])
        R = np.array([_numbers(lines[k + j][1], path, lines[k + j][0], 3) for j in (1, 2, 3)])
        if np.abs(R @ R.T - np.eye(3)).max() > 1e-9 or np.linalg.det(R) < 0:
            raise InputError("not a rotation matrix", path=path, line=lines[k + 1][0])
        mats.append(R)
        k += 4
    if not ids:
        raise InputError("no exposures", path=path)
    return ExposureOrientation(ids, np.full(len(ids), np.nan), np.array(pos),
                               matrix_to_angles(np.array(mats), system), system,
                               _frame_of(path))
