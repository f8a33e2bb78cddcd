"""LiDAR direct georeferencing: laser returns to points on the Earth from the trajectory.

For each return at time t (the INS paper's "mathematical basis of integrating LiDAR with
INS/IMU")::

    r_point = r_imu(t) + C_nb(t) (l_b + C_bs r_s)

with ``r_imu``, ``C_nb`` the trajectory interpolated at t by
:func:`ins.nav.interpolation.interpolate_trajectory` (the EO interpolation: Hermite
position, cubic attitude), ``l_b`` and ``C_bs`` the scanner's lever arm and axes with
boresight (:mod:`ins.lidar.scanner`) and ``r_s`` the return in the scanner frame.  The sum is
formed in NED at the IMU and added in ECEF (exact for any offset).

Each point's variance in NED (first order, the sources independent): position sigmas
of the trajectory, its roll, pitch and yaw sigmas through the rotation axes of the
Euler angles (``d r / d roll = (Rz Ry e_x) x d``, ``d r / d pitch = (Rz e_y) x d``,
``d r / d yaw = e_z x d`` with ``d = C_nb (l_b + C_bs r_s)``), the lever-arm sigmas,
the boresight sigmas (``d (C_bs r_s) / d rx = axes Rx (e_x x Ry Rz r_s)`` and alike),
the range noise along the ray and the scan-angle noise (``d r_s / d theta = r_s x
e_x``).  The correlations between the trajectory's states are neglected (the files
give no more than sigmas).  The time correlation of its errors does not change a point's
own (marginal) sigma, but all points of a strip share one draw of the slowly varying
trajectory error: the mean z^2 of one flight's points has one or two degrees of freedom
per axis, and only independent flights (or draws) average it to 1
(``docs/interfaces.md``, "Sigmas").  The trajectory sigmas come
from ``solution_std.txt`` (``ins process``) or an Applanix SMRMSG file, interpolated
linearly, held constant beyond their first and last epochs.

Each axis has its own sigma (``Points.sigma_enu_m``, the LAZ's ``sigma_e_m``,
``sigma_n_m``, ``sigma_u_m``): a roll error moves the points across the flight line, a
pitch error along it, a yaw error along it in proportion to the distance from the
track, so one horizontal sigma cannot serve both horizontal axes.

A boresight calibrated on the strips of the same flight (a scanner with a
``calibration``, :class:`ins.lidar.scanner.BoresightCalibration`, written by ``ins
strip-check --scanner-out``) is not an independent source.  The strip check estimates
``b_hat = b + a + n``: the true boresight, the trajectory's attitude error common to the
strips (body frame; a boresight and a body-fixed attitude error move the points alike,
so the strips cannot tell them apart) and the adjustment's error.  A point of that
flight then carries ``J (e(t) + b_hat - b) = J (e(t) + a) + J n`` (first order, ``J``
the Jacobian of the body-frame rotation): the common part of the trajectory's error
``e(t)`` cancels against ``a`` and what is left is its strip-to-strip and faster
part.  Counting the trajectory's whole attitude variance and the calibration's total
sigma (which holds the variance of ``a``) counts the same error twice.  So for the
points inside the calibration's time span the trajectory's roll, pitch, yaw sigmas are
replaced by the attitude error left after the calibration (``attitude_sigma_rad``,
estimated by the strip check from the strips' height differences,
:func:`ins.lidar.strip_check.strip_attitude`), and no boresight sigma is added: that
estimate is of the whole rotation left, ``e(t) + b_hat - b``, the adjustment's error
``n`` included (adding ``n`` again counted it twice: mean z^2 N/E 0.40/0.43 instead of
0.42/0.47 on the flight of ``tests/test_strip_check.py``).  Without trajectory sigmas
those points get the adjustment's sigma ``n`` alone; points outside the span (another
flight) get the file's total boresight sigma and the trajectory's whole attitude
sigma.  Measured (``bench/bench_lidar_sigmas.py --calibrated 12``: drawn, processed
and calibrated flights of the 3-strip demo plan at 3 places and headings, 36
flights): pooled mean z^2 N/E/D 0.95/0.94/0.89 (+- 0.12/0.12/0.01) calibrated,
0.76/0.95/0.84 (+- 0.14/0.17/0.04) with the true scanner file.  Limits:
the rotation left is estimated per segment from the strips' height differences,
whose adjustment treats them as independent (they are not: the plane fits and the
trajectory's faster errors correlate them), so its stated sigmas are far too small
(the per-segment estimates' errors are 10-20 times them) and their squares carry
that noise: the rotation left is over-stated on a flight whose strips see little of
it and under-stated on another.  The strips do not see a pitch error fixed in the
navigation frame, nor a common yaw when only two strips on one line overlap (rz not
estimable, ``ins strip-check`` exit 3; there z^2 spreads over 0.01 .. 7 per flight).

The work is done block by block (:func:`georeference_blocks`), the per-point algebra in
a compiled kernel (Cython, :mod:`ins.lidar._georeference_kernels`).
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.io.trajectory_std import TrajectoryStd, read_trajectory_std  # noqa: F401 (kept here)
from ins.lidar._georeference_kernels import georeference_kernel, interpolate_kernel
from ins.lidar.scanner import scanner_rays
from ins.nav.earth import lla_rate
from ins.nav.interpolation import interpolate_trajectory, locate
from ins.nav.rotation import quat_conjugate, quat_multiply, quat_to_rotvec, rot_x, rot_y, wrap_to_pi

__all__ = ["Points", "TrajectoryStd", "georeference", "georeference_blocks",
           "read_trajectory_std", "returns_to_scanner", "ecef_to_lla", "boresight_jacobian",
           "interpolate_pose",
           "attitude_jacobian"]


@dataclass(frozen=True)
class Points:
    """Georeferenced points.

    Attributes
    ----------
    time : ndarray, shape (n,)
        s.
    xyz_ecef_m : ndarray, shape (n, 3)
        ECEF (WGS84), m.
    var_ned_m2 : ndarray, shape (n, 3)
        Propagated variances north, east, down, m^2 (zeros without sigmas): each axis's
        own (marginal) variance.
    index : ndarray, shape (n,)
        Position of each point among the block's returns (returns outside the
        trajectory are dropped).
    """

    time: np.ndarray
    xyz_ecef_m: np.ndarray
    var_ned_m2: np.ndarray
    index: np.ndarray

    @property
    def sigma_enu_m(self):
        """Sigmas east, north, up (m), shape (n, 3): the marginal sigma of each axis."""
        return np.sqrt(self.var_ned_m2[:, [1, 0, 2]])

    @property
    def sigma_h_m(self):
        """Horizontal sigma ``sqrt(var_N + var_E)`` (m)."""
        return np.sqrt(self.var_ned_m2[:, 0] + self.var_ned_m2[:, 1])

    @property
    def sigma_v_m(self):
        """Vertical sigma (m)."""
        return np.sqrt(self.var_ned_m2[:, 2])

    def lla(self):
        """Latitude, longitude (rad), ellipsoidal height (m), shape (n, 3)."""
        return ecef_to_lla(self.xyz_ecef_m)


def ecef_to_lla(xyz_e):
    """ECEF (m) to latitude, longitude (rad), ellipsoidal height (m), WGS84; (n, 3)."""
    import pymap3d
    xyz_e = np.atleast_2d(xyz_e)
    lat, lon, h = pymap3d.ecef2geodetic(xyz_e[:, 0], xyz_e[:, 1], xyz_e[:, 2], deg=False)
    return np.column_stack([lat, lon, h])


def returns_to_scanner(scanner, range_m=None, scan_angle_rad=None, xyz_s_m=None):
    """Scanner-frame points ``r_s`` (n, 3) of returns: range and scan angle for the line
    scanners, the points themselves for model ``"points"``."""
    if scanner.model == "points":
        if xyz_s_m is None:
            raise InputError('scanner model "points" needs points in the scanner frame '
                             '(x, y, z m), not range and scan angle')
        return np.asarray(xyz_s_m, dtype=float)
    if range_m is None or scan_angle_rad is None:
        raise InputError(f"scanner model {scanner.model!r} needs range (m) and scan angle "
                         "(deg) per return")
    return scanner_rays(range_m, scan_angle_rad, scanner.forward_tilt_rad)


def interpolate_pose(traj, t, method="cubic", path=None):
    """IMU position (lat, lon rad, h m; (m, 3)) and ``q_nb`` ((m, 4)) at the times ``t``.

    ``"cubic"``: the EO interpolation (:func:`ins.nav.interpolation.interpolate_trajectory`,
    same formulas) with the per-interval work (Hermite slopes, the stencil's rotation
    vectors) done once per trajectory interval used and the per-return evaluation in a
    compiled kernel (equal to the library's to rounding, ``tests/test_georeference.py``);
    ``"slerp"`` or fewer than 4 epochs: the library function itself.
    """
    n = len(traj.time)
    if method != "cubic" or n < 4:
        at = interpolate_trajectory(traj, t, method=method, path=path)
        return at.lla, at.q_nb
    k = locate(traj.time, t, path=path)
    uk, slot = np.unique(k, return_inverse=True)
    y0, y1 = traj.lla[uk].copy(), traj.lla[uk + 1].copy()
    y1[:, 1] = y0[:, 1] + wrap_to_pi(y1[:, 1] - y0[:, 1])
    d0 = lla_rate(y0[:, 0], y0[:, 2], traj.v_n[uk])
    d1 = lla_rate(y1[:, 0], y1[:, 2], traj.v_n[uk + 1])
    idx = np.clip(uk - 1, 0, n - 4)[:, None] + np.arange(4)
    q0 = traj.q_nb[uk]
    rv = np.stack([quat_to_rotvec(quat_multiply(quat_conjugate(q0), traj.q_nb[idx[:, j]]))
                   for j in range(4)], axis=1)
    lla = np.empty((len(t), 3))
    q = np.empty((len(t), 4))
    interpolate_kernel(np.ascontiguousarray(t, dtype=float), slot.astype(np.int64),
                       traj.time[uk], traj.time[uk + 1], y0, y1, d0, d1,
                       np.ascontiguousarray(traj.time[idx]), np.ascontiguousarray(rv),
                       np.ascontiguousarray(q0), lla, q)
    lla[:, 1] = wrap_to_pi(lla[:, 1])
    return lla, q


def georeference(traj, time, r_s, scanner, std=None, method="cubic", path=None, mount=None):
    """Georeference returns given in the scanner frame.

    Parameters
    ----------
    traj : ins.nav.trajectory.Trajectory
        IMU trajectory (lat/lon rad, h m ellipsoidal, NED velocity, q_nb).
    time : array_like, shape (n,)
        Return times, s, on the trajectory's time scale.
    r_s : array_like, shape (n, 3)
        Returns in the scanner frame, m (:func:`returns_to_scanner`).
    scanner : ins.lidar.scanner.Scanner
    std : TrajectoryStd, optional
        Trajectory sigmas; without them only the scanner's own sigmas propagate.  With a
        scanner calibrated on this flight (``scanner.calibration`` covering the return
        times) the attitude sigmas are replaced by the calibration's attitude error left,
        which holds the boresight's own error (no boresight sigma added); without
        ``std`` those points get the adjustment's boresight sigma (module notes).
    method : {"cubic", "slerp"}
        Attitude interpolation.
    path : str, optional
        Trajectory file, for messages.
    mount : ins.io.mount.MountLog, optional
        Mount angles ``C_ap(t)``; required by a scanner with ``on = "aircraft"``
        (:mod:`ins.lidar.scanner`), ignored otherwise.

    Returns
    -------
    Points
        Returns outside ``[traj.time[0], traj.time[-1]]`` (and, for a scanner on the
        aircraft, outside the mount log or in its gaps) are dropped (``index`` tells
        which were kept).
    """
    time = np.asarray(time, dtype=float)
    r_s = np.asarray(r_s, dtype=float)
    if r_s.shape != (len(time), 3):
        raise ValueError(f"r_s must have shape ({len(time)}, 3), got {r_s.shape}")
    inside = (time >= traj.time[0]) & (time <= traj.time[-1]) & np.all(np.isfinite(r_s), 1)
    use_P = scanner.on == "aircraft"
    if use_P:
        if mount is None:
            raise InputError('a scanner on the aircraft (on = "aircraft") needs the mount '
                             "angles (mount log)")
        C_ap, valid = mount.C_ap(time)
        inside &= valid
    index = np.flatnonzero(inside)
    t = time[index]
    n = len(t)
    xyz = np.empty((n, 3))
    var = np.empty((n, 3))
    if n == 0:
        return Points(t, xyz, var, index)
    lla, q_nb = interpolate_pose(traj, t, method=method, path=path)
    s = np.zeros((n, 6)) if std is None else std.at(t)
    rx, ry = rot_x(scanner.boresight_rad[0]), rot_y(scanner.boresight_rad[1])
    M_x = scanner.axes @ rx
    P = np.ascontiguousarray(np.swapaxes(C_ap[index], 1, 2)) if use_P else np.zeros((1, 3, 3))
    r_k = r_s[index]
    # a boresight calibrated on this flight: with the trajectory's sigmas, the attitude
    # error left after the calibration, which holds the boresight's own error too (one
    # rotation, counted once); without them the boresight's own sigma (module notes)
    cal = scanner.calibration
    same = cal.covers(t) if cal is not None else np.zeros(n, bool)
    bore_same = None if cal is None else cal.boresight_sigma_rad
    if std is not None and same.any():
        s[same, 3:6] = cal.attitude_sigma_rad
        bore_same = np.zeros(3)
    for sel, bore_sig in ((~same, scanner.boresight_sigma_rad), (same, bore_same)):
        if not sel.any():
            continue
        k = np.flatnonzero(sel)
        xk, vk = np.empty((len(k), 3)), np.empty((len(k), 3))
        georeference_kernel(np.ascontiguousarray(lla[k]), np.ascontiguousarray(q_nb[k]),
                            np.ascontiguousarray(r_k[k]), np.ascontiguousarray(scanner.C_bs),
                            np.ascontiguousarray(scanner.lever_arm_m), M_x, M_x @ ry,
                            np.ascontiguousarray(P[k]) if use_P else P, use_P,
                            np.ascontiguousarray(scanner.imu_to_platform_centre_b_m),
                            np.ascontiguousarray(s[k]),
                            np.ascontiguousarray(scanner.lever_arm_sigma_m),
                            np.ascontiguousarray(bore_sig),
                            float(scanner.range_sigma_m), float(scanner.scan_angle_sigma_rad),
                            scanner.model != "points", xk, vk)
        xyz[k], var[k] = xk, vk
    return Points(t, xyz, var, index)


def georeference_blocks(traj, blocks, scanner, std=None, method="cubic", path=None,
                        mount=None):
    """Georeference a stream of return blocks.

    Parameters
    ----------
    blocks : iterable of (time (n,), r_s (n, 3))
        Blocks of returns (bounded memory: one block at a time).

    Yields
    ------
    Points
        One per block (see :func:`georeference`).
    """
    for time, r_s in blocks:
        yield georeference(traj, time, r_s, scanner, std=std, method=method, path=path,
                           mount=mount)


def boresight_jacobian(traj, time, r_s, scanner, method="cubic"):
    """Derivative of each point (NED at the IMU, m) with respect to the boresight
    ``(rx, ry, rz)`` (rad): ``C_nb d(C_bs r_s)/d b``, shape (n, 3, 3) (rows N, E, D).

    ``d(C_bs r)/d rx = axes Rx (e_x x Ry Rz r)``, ``.../d ry = axes Rx Ry (e_y x Rz r)``,
    ``.../d rz = C_bs (e_z x r)`` (``C_bs = axes Rx Ry Rz``, active rotations).  Times
    must lie inside the trajectory.
    """
    from ins.nav.rotation import quat_to_dcm, rot_z
    if scanner.on != "imu":
        raise InputError('the strip check handles a scanner on the IMU only (on = "imu")')
    at = interpolate_trajectory(traj, np.asarray(time, float), method=method)
    C_nb = quat_to_dcm(at.q_nb)
    b = scanner.boresight_rad
    Rx, Ry, Rz = rot_x(b[0]), rot_y(b[1]), rot_z(b[2])
    A = scanner.axes
    r = np.asarray(r_s, float)
    cols = [(A @ Rx) @ np.cross([1.0, 0, 0], r @ (Ry @ Rz).T).T,
            (A @ Rx @ Ry) @ np.cross([0, 1.0, 0], r @ Rz.T).T,
            scanner.C_bs @ np.cross([0, 0, 1.0], r).T]
    J_b = np.stack([c.T for c in cols], axis=2)              # (n, 3 body, 3 angles)
    return C_nb @ J_b


def attitude_jacobian(traj, time, r_s, scanner, method="cubic"):
    """Derivative of each point (NED, m) with respect to the trajectory's roll, pitch and
    yaw (rad): columns ``(Rz Ry e_x) x d``, ``(Rz e_y) x d``, ``e_z x d`` with
    ``d = C_nb (l_b + C_bs r_s)``; shape (n, 3, 3) (rows N, E, D)."""
    from ins.nav.rotation import quat_to_dcm
    if scanner.on != "imu":
        raise InputError('the strip check handles a scanner on the IMU only (on = "imu")')
    at = interpolate_trajectory(traj, np.asarray(time, float), method=method)
    C_nb = quat_to_dcm(at.q_nb)
    v_b = scanner.lever_arm_m + np.asarray(r_s, float) @ scanner.C_bs.T
    d = np.einsum("nij,nj->ni", C_nb, v_b)
    h = np.hypot(C_nb[:, 0, 0], C_nb[:, 1, 0])
    cy = np.where(h > 0, C_nb[:, 0, 0] / np.where(h > 0, h, 1), 1.0)
    sy = np.where(h > 0, C_nb[:, 1, 0] / np.where(h > 0, h, 1), 0.0)
    pitch_axis = np.column_stack([-sy, cy, np.zeros_like(cy)])
    yaw_axis = np.tile([0.0, 0.0, 1.0], (len(d), 1))
    return np.stack([np.cross(C_nb[:, :, 0], d), np.cross(pitch_axis, d),
                     np.cross(yaw_axis, d)], axis=2)
