"""``ins georeference``: LiDAR returns to georeferenced points (LAS/LAZ) from a
trajectory and a scanner file (:mod:`ins.lidar.georeference`)."""
import argparse

from ins.common.errors import InputError

EPILOG = """\
frames and units:
  r_point = r_imu(t) + C_nb(t) (l_b + C_bs r_s), the trajectory (.nav or SBET: IMU
  position and attitude) interpolated at each return time t (Hermite position, cubic
  attitude, as for the EO).  Scanner frame s: x along the scan axis (forward), y right,
  z down; a return at range rho (m) and scan angle theta (deg, positive to the right of
  the flight direction) with forward tilt tau is rho (sin tau, cos tau sin theta,
  cos tau cos theta).  The scanner file (TOML, data/scanner/example_scanner.toml) gives
  the model (polygon | oscillating | points), the axes (rows of C_bs, scanner to body
  FRD), lever_arm_m (IMU to scanner origin, body FRD, m), boresight_deg (rx, ry, rz:
  C_bs = axes Rx Ry Rz) and the sigmas (range m, scan angle deg, lever arm m,
  boresight deg): the camera file's conventions.  A scanner on the aircraft with the
  IMU on the stabilized platform ([mounting] on = "aircraft": axes = C_as, lever arm
  from the platform centre in the aircraft frame, imu_to_platform_centre_b_m) needs
  --mount: C_bs(t) = C_ap(t)^T C_as, l_b(t) = l_bp + C_ap(t)^T l_a.

returns:
  CSV with a header: time_s,range_m,scan_angle_deg[,intensity,return_number,
  number_of_returns,strip]
  (model points: time_s,x_s_m,y_s_m,z_s_m[,...]), or LAS/LAZ with the points in the
  scanner frame (m) and GPS time (model points).  Times on the trajectory's time scale
  (s).  Returns outside the trajectory's time span are counted, dropped and reported;
  none inside is an error.

output (LAS 1.4, point format 6; LAZ by the .laz extension; written atomically):
  x, y in --crs (default: the WGS84 / UTM zone of the trajectory's centre, EPSG
  326zz/327zz; a geographic CRS gives lon, lat in deg), z the ellipsoidal height (WGS84,
  m) or, with --height orthometric[:MODEL], H = h - N of the geoid model (EGM2008, the
  default, or EGM96, from a grid installed locally: pip install 'insphoto[geoid]'; the
  WKT is then the compound CRS with EGM2008 height EPSG:3855 / EGM96 height EPSG:5773);
  GPS time (s), intensity, return number, scan angle (deg), point source id = strip;
  extra dimensions sigma_e_m, sigma_n_m, sigma_u_m (each axis's own sigma, east, north,
  up), sigma_h_m = sqrt(var_N + var_E) and sigma_v_m (m), first-order from the
  trajectory sigmas (--trajectory-std: solution_std.txt of ins process or an SMRMSG
  file; without it only the scanner's sigmas), the boresight, lever-arm, range and
  scan-angle sigmas.  A scanner file calibrated by ins strip-check on this flight (its
  [calibration] table, whose time span covers the returns) counts the trajectory's
  attitude error once: its common part is in the calibrated boresight, so those points
  get the rotation the strip check left ([calibration] attitude_sigma_deg: the
  trajectory's strip-to-strip part and the boresight's own error) instead of the
  trajectory's attitude sigma and any boresight sigma (without --trajectory-std: the
  boresight's adjustment sigma).  The CRS is written
  as a WKT VLR.

example:
  ins georeference --trajectory out/solution.nav --trajectory-std out/solution_std.txt \\
      --scanner scanner.toml returns.csv -o points.laz
"""


def add_parser(sub):
    p = sub.add_parser("georeference", help="LiDAR returns to georeferenced points (LAS/LAZ)",
                       description="Direct georeferencing of laser returns from the "
                                   "trajectory: r_point = r_imu + C_nb (l_b + C_bs r_s), "
                                   "with each point's propagated sigma.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("returns", metavar="RETURNS",
                   help="returns: CSV (time_s,range_m,scan_angle_deg,...) or LAS/LAZ in the "
                        "scanner frame")
    p.add_argument("--trajectory", required=True, metavar="T",
                   help="trajectory of the IMU: KF-GINS .nav or Applanix SBET")
    p.add_argument("--trajectory-std", metavar="F",
                   help="its sigmas: solution_std.txt (m, m/s, deg) or SMRMSG (.out)")
    p.add_argument("--scanner", required=True, metavar="SCANNER.toml",
                   help="scanner file: model, axes, lever arm (m, body FRD), boresight "
                        "(deg), sigmas")
    p.add_argument("--mount", metavar="F",
                   help="mount-angle log (time_s roll_deg pitch_deg yaw_deg, C_ap), needed by "
                        'a scanner on the aircraft ([mounting] on = "aircraft")')
    p.add_argument("--crs", metavar="EPSG:xxxx",
                   help="output CRS of x, y (default: UTM zone of the trajectory's centre); "
                        "z: see --height")
    p.add_argument("--height", default="ellipsoidal",
                   metavar="ellipsoidal|orthometric[:MODEL]",
                   help="z: ellipsoidal height (WGS84, m; default) or orthometric H = h - N "
                        "with the geoid MODEL EGM2008 (default) or EGM96, m")
    from ins.cli.util import positive_int
    p.add_argument("--block-size", type=positive_int, default=250_000, metavar="N",
                   help="returns per block (memory: about 0.7 KiB a return), default 250000")
    p.add_argument("-o", "--output", required=True, metavar="points.laz",
                   help="output LAS (.las) or LAZ (.laz)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_georeference)


def _crs(text, traj):
    import numpy as np
    from pyproj import CRS
    from pyproj.exceptions import CRSError

    from ins.lidar.lidar_files import utm_crs
    if text is None:
        lat, lon = np.rad2deg(np.mean(traj.lla[:, 0])), np.rad2deg(np.mean(traj.lla[:, 1]))
        return utm_crs(lat, lon)
    try:
        crs = CRS.from_user_input(text)
    except CRSError as exc:
        raise InputError(f"--crs {text!r}: not a CRS pyproj knows ({exc})") from None
    if not (crs.is_projected or crs.is_geographic):
        raise InputError(f"--crs {text!r}: expected a projected or geographic CRS, got "
                         f"{crs.type_name}")
    return crs


def _cmd_georeference(args):
    import numpy as np
    from pyproj import Transformer

    from ins.cli.util import Progress
    from ins.common.fileio import atomic_open, check_output_file
    from ins.io.navfiles import read_trajectory
    from ins.lidar.georeference import georeference, read_trajectory_std, returns_to_scanner
    from ins.lidar.lidar_files import LasPointWriter, count_returns, import_laspy, iter_returns
    from ins.lidar.scanner import read_scanner

    if not args.output.lower().endswith((".las", ".laz")):
        raise InputError(f"-o {args.output!r}: expected a .las or .laz file name")
    import_laspy()
    check_output_file(args.output)
    scanner = read_scanner(args.scanner)
    mount = None
    if scanner.on == "aircraft":
        if not args.mount:
            raise InputError('the scanner is on the aircraft ([mounting] on = "aircraft"): '
                             "--mount (the mount-angle log) is needed", path=args.scanner)
        from ins.io.mount import read_mount
        mount = read_mount(args.mount)
    elif args.mount:
        raise InputError('--mount is used by a scanner on the aircraft only ([mounting] on = '
                         '"aircraft"); this scanner sits on the IMU', path=args.scanner)
    traj = read_trajectory(args.trajectory)
    if len(traj) < 2:
        raise InputError("the trajectory needs at least 2 epochs", path=args.trajectory)
    std = read_trajectory_std(args.trajectory_std) if args.trajectory_std else None
    crs = _crs(args.crs, traj)
    from ins.io.geoid import parse_height
    height = parse_height(args.height)
    centre = np.mean(traj.lla, axis=0)
    import pymap3d
    xyz0 = pymap3d.geodetic2ecef(*np.rad2deg(centre[:2]), centre[2])
    offset = Transformer.from_crs("EPSG:4978", crs, always_xy=True).transform(*xyz0)
    offset = np.round(np.array(offset[:2] + (0.0,)), 0 if crs.is_projected else 2)
    total = count_returns(args.returns)
    progress = Progress("georeference", not args.quiet)
    done = kept = 0
    t_min, t_max = np.inf, -np.inf
    with atomic_open(args.output, "wb") as f:
        with LasPointWriter(f, crs, offset, args.output.lower().endswith(".laz"),
                            height=height) as w:
            for blk in iter_returns(args.returns, scanner.model, args.block_size):
                r_s = returns_to_scanner(scanner, blk.range_m, blk.scan_angle_rad,
                                         blk.xyz_s_m)
                pts = georeference(traj, blk.time, r_s, scanner, std=std,
                                   path=args.trajectory, mount=mount)
                i = pts.index
                angle = (np.rad2deg(blk.scan_angle_rad[i]) if blk.scan_angle_rad is not None
                         else np.rad2deg(np.arctan2(r_s[i, 1], r_s[i, 2])))
                w.write(pts, blk.intensity[i], blk.return_number[i], angle, blk.strip[i],
                        blk.number_of_returns[i])
                done += len(blk)
                kept += len(i)
                t_min, t_max = min(t_min, blk.time.min()), max(t_max, blk.time.max())
                progress(min(done, total), max(total, done))
            if kept == 0:
                raise InputError(
                    f"none of the {done} returns ({t_min!r} .. {t_max!r} s) lies inside the "
                    f"trajectory {traj.time[0]!r} .. {traj.time[-1]!r} s (same time scale?)",
                    path=args.returns)
    progress(done, done)
    dropped = done - kept
    zname = ("ellipsoidal" if not height.orthometric else
             f"orthometric {height.geoid.name} (EPSG:{height.geoid.vertical_epsg})")
    print(f"{args.output}: {kept} points in {crs.name} (EPSG:{crs.to_epsg()}), z "
          f"{zname}" + (f"; {dropped} returns outside the trajectory"
                            + (" or the mount log" if mount is not None else "") + " "
                            f"{traj.time[0]:.3f} .. {traj.time[-1]:.3f} s dropped"
                            if dropped else "")
          + ("" if std is not None else "; no --trajectory-std: the sigmas hold the "
             "scanner's terms only"))
    return 0
