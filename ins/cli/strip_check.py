"""``ins strip-check POINTS.las``: height differences of overlapping strips and the
scanner boresight estimated from them (:mod:`ins.lidar.strip_check`)."""
import argparse

from ins.cli.util import number, positive_int
from ins.common.errors import InputError, QualityError

EPILOG = """\
input:
  POINTS.las/.laz as written by `ins georeference` (x, y in its CRS, z ellipsoidal
  height, GPS time, point source id = strip), with the SAME trajectory and scanner file:
  each point's scanner-frame vector is recovered from them, the points recomputed with
  each new boresight.  Strips are the point source ids (the `strip` column of the
  returns CSV); every pair of strips is tried.

method:
  for points of strip a, the k nearest points of strip b within --radius-m (horizontal)
  give a local plane; dz = z_a - plane_b.  Linearised in the boresight (rx, ry, rz;
  C_bs = axes Rx Ry Rz), least squares over all pairs, iterated until the correction is
  below 0.05 sigma.  Sigmas: sigma0^2 (A^T A)^-1, plus (with --trajectory-std) the
  trajectory's roll, pitch, yaw sigmas as an error constant over each strip.  An angle
  whose sigma exceeds 0.1 deg is not estimable (ry, rz need terrain slopes): exit 3
  unless --accept-poor.

output:
  a table per strip pair: differences used, mean and RMS dz (m) before and after; the
  boresight (deg) with sigmas; --scanner-out writes the scanner file with the estimated
  boresight and its sigmas (other keys unchanged).  With --trajectory-std it adds a
  [calibration] table: the flight's time span, the boresight's adjustment sigma alone
  and the rotation left in this flight's points after the calibration (roll, pitch,
  yaw deg: the trajectory's strip-to-strip attitude error and the boresight's own
  error; estimated per 6 s segment of each strip from the height differences, pitch's
  strip-to-strip part held at zero), which ins georeference uses for this flight's
  points instead of the total boresight sigma and the trajectory's attitude sigma
  (they hold the same error).

example:
  ins strip-check points.laz --trajectory out/solution.nav \\
      --trajectory-std out/solution_std.txt --scanner scanner.toml --scanner-out s2.toml
"""


def add_parser(sub):
    p = sub.add_parser("strip-check", help="strip height differences and the scanner "
                                           "boresight from them",
                       description="Height differences of overlapping LiDAR strips and a "
                                   "least-squares estimate of the scanner boresight.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("points", metavar="POINTS", help="LAS/LAZ from ins georeference")
    p.add_argument("--trajectory", required=True, metavar="T",
                   help="the trajectory used (.nav or SBET)")
    p.add_argument("--trajectory-std", metavar="F",
                   help="its sigmas (solution_std.txt or SMRMSG): add to the boresight's")
    p.add_argument("--scanner", required=True, metavar="SCANNER.toml",
                   help="the scanner file used")
    p.add_argument("--radius-m", type=number(0, lo_open=True, unit="m"), default=3.0, metavar="R",
                   help="neighbours of the other strip within R m (horizontal), default 3")
    p.add_argument("--neighbours", type=positive_int, default=8, metavar="K",
                   help="points per local plane, default 8 (at least 3)")
    p.add_argument("--scanner-out", metavar="S.toml",
                   help="write the scanner file with the estimated boresight")
    p.add_argument("--accept-poor", action="store_true",
                   help="exit 0 even when an angle is not estimable")
    p.set_defaults(func=_cmd_strip_check)


def read_points_las(path):
    """GPS time (s), ECEF (m) and strip of the points of a LAS/LAZ written by
    ``ins georeference`` (its CRS from the file, z ellipsoidal)."""
    import numpy as np
    from pyproj import Transformer

    from ins.lidar.lidar_files import import_laspy
    laspy = import_laspy()
    try:
        las = laspy.read(path)
    except Exception as exc:          # laspy's own errors and OSError
        raise InputError(f"not a readable LAS/LAZ file: {exc}", path=path) from None
    crs = las.header.parse_crs()
    if crs is None:
        raise InputError("no CRS in the file (expected the WKT of ins georeference)",
                         path=path)
    if "gps_time" not in las.point_format.dimension_names:
        raise InputError("no GPS time in the points", path=path)
    tr = Transformer.from_crs(crs, "EPSG:4978", always_xy=True)
    x, y, z = tr.transform(np.asarray(las.x), np.asarray(las.y), np.asarray(las.z))
    return (np.asarray(las.gps_time, float), np.column_stack([x, y, z]),
            np.asarray(las.point_source_id, np.int64))


def scanner_vectors(traj, time, xyz_e, scanner):
    """``r_s = C_bs^T (C_nb^T C_en^T (r_point - r_imu) - l_b)`` of georeferenced points."""
    import numpy as np

    from ins.nav.earth import dcm_en, lla_to_ecef
    from ins.nav.interpolation import interpolate_trajectory
    from ins.nav.rotation import quat_to_dcm
    at = interpolate_trajectory(traj, time)
    r_imu = lla_to_ecef(at.lla[:, 0], at.lla[:, 1], at.lla[:, 2])
    d_n = np.einsum("nji,nj->ni", dcm_en(at.lla[:, 0], at.lla[:, 1]), xyz_e - r_imu)
    v_b = np.einsum("nji,nj->ni", quat_to_dcm(at.q_nb), d_n) - scanner.lever_arm_m
    return v_b @ scanner.C_bs


def _cmd_strip_check(args):
    import numpy as np

    from ins.io.navfiles import read_trajectory
    from ins.lidar.georeference import read_trajectory_std
    from ins.lidar.scanner import read_scanner, write_scanner
    from ins.lidar.strip_check import boresight_from_strips

    if not (args.radius_m > 0 and np.isfinite(args.radius_m)):
        raise InputError(f"--radius-m {args.radius_m!r}: expected a positive distance (m)")
    if args.neighbours < 3:
        raise InputError(f"--neighbours {args.neighbours}: a plane needs at least 3 points")
    if args.scanner_out:
        from ins.common.fileio import check_output_file
        check_output_file(args.scanner_out)
    scanner = read_scanner(args.scanner)
    if scanner.model == "points":
        raise InputError('a scanner of model "points" has no scan geometry to check here; '
                         "use the line-scanner model of its returns", path=args.scanner)
    traj = read_trajectory(args.trajectory)
    std = read_trajectory_std(args.trajectory_std) if args.trajectory_std else None
    time, xyz_e, strip = read_points_las(args.points)
    inside = (time >= traj.time[0]) & (time <= traj.time[-1])
    if not inside.all():
        raise InputError(f"{(~inside).sum()} points lie outside the trajectory "
                         f"{traj.time[0]:.3f} .. {traj.time[-1]:.3f} s (not the trajectory "
                         "they were computed with?)", path=args.points)
    if len(np.unique(strip)) < 2:
        raise InputError("the points hold one strip (point source id) only; two or more "
                         "overlapping strips are needed", path=args.points)
    r_s = scanner_vectors(traj, time, xyz_e, scanner)
    b, est, first, calibration = boresight_from_strips(traj, time, r_s, strip, scanner, std=std,
                                          radius_m=args.radius_m, k=args.neighbours)
    print(f"{'strips':<10}{'n':>9}{'mean dz m':>12}{'rms dz m':>11}{'after: mean':>13}"
          f"{'rms':>9}")
    for p0, p1 in zip(first.pairs, est.pairs):
        print(f"{p0.a:>4}-{p0.b:<5}{len(p0.dz_m):>9}{p0.mean_m:>12.4f}{p0.rms_m:>11.4f}"
              f"{p1.mean_m:>13.4f}{p1.rms_m:>9.4f}")
    deg = np.rad2deg
    print("boresight rx, ry, rz (deg): " + ", ".join(
        f"{deg(v):.5f} +- {deg(s):.5f}{'' if ok else ' (not estimable)'}"
        for v, s, ok in zip(b, est.sigma_rad, est.estimable))
          + f"  (was {', '.join(f'{v:.5f}' for v in deg(scanner.boresight_rad))}); "
          f"sigma0 {est.sigma0_m:.4f} m, {est.n_used} differences, "
          f"{est.n_rejected} left out")
    if not est.estimable.all() and not args.accept_poor:
        raise QualityError("boresight angle(s) " + ", ".join(
            n for n, ok in zip(("rx", "ry", "rz"), est.estimable) if not ok)
            + " not estimable (sigma above 0.1 deg: too little terrain slope or overlap); "
              "nothing written (--accept-poor writes anyway)")
    if args.scanner_out:
        write_scanner(args.scanner_out, scanner.replace(
            boresight_rad=b, boresight_sigma_rad=est.sigma_rad, calibration=calibration))
        print(f"wrote {args.scanner_out}" + (
            "" if calibration is None else
            " (with [calibration]: for this flight's points the rotation left, roll/pitch/yaw "
            + ", ".join(f"{v:.5f}" for v in np.rad2deg(calibration.attitude_sigma_rad))
            + " deg, the boresight's own error, sigma "
            + ", ".join(f"{v:.5f}" for v in np.rad2deg(calibration.boresight_sigma_rad))
            + " deg, included)"))
    return 0
