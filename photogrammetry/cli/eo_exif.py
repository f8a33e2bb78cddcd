"""``photogrammetry eo --from-exif IMAGES...``: exterior orientation from drone metadata
(DJI XMP gimbal angles, GPS); the options and the run of that path of ``eo``."""
import os

import numpy as np

from ins.cli.util import triplet
from ins.common.errors import InputError
from ins.common.fileio import check_output_file

EPILOG = """\
drone images (--from-exif IMAGE...):
  DJI XMP (drone-dji:GpsLatitude, GpsLongtitude, AbsoluteAltitude, GimbalRollDegree,
  GimbalPitchDegree, GimbalYawDegree; RtkStdLat/Lon/Hgt when RtkFlag != 0), else the EXIF
  GPS position.  The gimbal angles are NED Euler angles of the camera body g
  (C_ng = Rz(yaw) Ry(pitch) Rx(roll); x_g the viewing direction, y_g right, z_g down
  the image; pitch -90 = nadir, image top to the north at yaw 0), and
  C_mc = C_mn C_ng C_gc with C_gc = [[0,0,-1],[1,0,0],[0,-1,0]] (x_c = y_g, y_c = -z_g,
  z_c = -x_g) times the camera file's boresight (its axes and lever arm are not used;
  the drone's position is the perspective centre's).  Image ids: file names without
  extension.  Heights: the drone's altitude, in the frame's height system.
  Sigmas: RTK standard deviations (else --position-sigma-m), --gimbal-sigma-deg
  propagated into the angles.  time_s: EXIF DateTimeOriginal taken as UTC, GPS
  seconds of week (0 if absent; DJI clocks often keep local time).
  --camera-out: the camera file of DewarpData (date;fx,fy,cx,cy,k1,k2,p1,p2,k3 for the
  full sensor 2 CalibratedOpticalCenterX x 2 CalibratedOpticalCenterY px, cx, cy offsets
  from its centre, OpenCV distortion) scaled to the image size.
  photogrammetry eo --from-exif DJI_*.JPG --frame utm -o eo.csv
"""


def add_options(p):
    """The --from-exif options of the ``eo`` parser."""
    p.add_argument("--from-exif", nargs="+", metavar="IMAGE",
                   help="drone images (DJI XMP gimbal angles, GPS) instead of a trajectory")
    p.add_argument("--gimbal-sigma-deg", type=triplet, default=np.array([0.5, 0.5, 2.0]),
                   metavar="R,P,Y", help="sigma of the gimbal roll, pitch, yaw (deg; "
                                         "default 0.5,0.5,2)")
    p.add_argument("--position-sigma-m", type=float, default=3.0, metavar="M",
                   help="position sigma per axis without RTK standard deviations (m; 3)")
    p.add_argument("--camera-out", metavar="CAM.toml",
                   help="also write the camera of the first image's DJI DewarpData "
                        "(pixel size 0.01 mm; fx, fy averaged)")


def height_system(args):
    """The ``--height`` of ``args`` (None when not given); refused beside
    ``--geoid-undulation``."""
    text = getattr(args, "height", None)
    if text is None:
        return None
    if args.geoid_undulation is not None:
        raise InputError("give --height orthometric[:MODEL] or --geoid-undulation N, not both")
    from ins.io.geoid import parse_height
    return parse_height(text)


def run(args):
    """The ``eo --from-exif`` path (exit code)."""
    from photogrammetry.orientation.camera import read_camera
    from photogrammetry.orientation.drone import eo_from_drone, read_drone_shot
    from photogrammetry.orientation.exposure import write_eo_applanix, write_eo_csv, write_eo_patb
    from photogrammetry.orientation.mapping import parse_frame

    if args.flight_dir or args.trajectory or args.events or args.sigma:
        raise InputError("--from-exif replaces FLIGHT_DIR, --trajectory, --events and "
                         "--sigma: give images or a trajectory")
    check_output_file(args.output)
    out = os.path.abspath(args.output)
    for p in list(args.from_exif) + [args.camera]:
        if p is not None and os.path.abspath(p) == out:
            raise InputError(f"--output {args.output} would overwrite the input file {p}")
    if np.any(np.asarray(args.gimbal_sigma_deg) <= 0):
        raise InputError(f"--gimbal-sigma-deg must be three numbers > 0 (deg), got "
                         f"{args.gimbal_sigma_deg}")
    if not args.position_sigma_m > 0:
        raise InputError(f"--position-sigma-m must be > 0 m, got {args.position_sigma_m}")
    boresight = np.zeros(3)
    if args.camera:
        _, mounting = read_camera(args.camera)
        boresight = mounting.boresight_rad
    shots = [read_drone_shot(p) for p in args.from_exif]
    seen = {}
    for s in shots:
        if s.image_id in seen:
            raise InputError(f"image id {s.image_id!r} given twice (also {seen[s.image_id]})",
                             path=s.path)
        seen[s.image_id] = s.path
    if args.origin is not None:
        if abs(args.origin[0]) > 90:
            raise InputError(f"--origin: latitude {args.origin[0]} deg is outside +-90 deg")
        origin = np.array([np.deg2rad(args.origin[0]), np.deg2rad(args.origin[1]),
                           args.origin[2]])
    else:
        origin = np.array([np.deg2rad(shots[0].lat_deg), np.deg2rad(shots[0].lon_deg), 0.0])
    frame = parse_frame(args.frame, origin, args.geoid_undulation, height_system(args))
    eo = eo_from_drone(shots, frame, args.system, np.deg2rad(args.gimbal_sigma_deg),
                       args.position_sigma_m, boresight)
    if args.camera_out:
        from photogrammetry.orientation.camera import write_camera
        from photogrammetry.orientation.drone import camera_from_dji
        check_output_file(args.camera_out)
        camera, anisotropy = camera_from_dji(shots[0].path)
        write_camera(args.camera_out, camera)
        if not args.quiet:
            print(f"wrote {args.camera_out} (DJI DewarpData of {shots[0].image_id}; fx, fy "
                  f"differ by {1e6 * anisotropy:.0f} ppm, averaged)")
    if args.format == "csv":
        g = args.gimbal_sigma_deg
        write_eo_csv(args.output, eo, comments=(
            f"from drone metadata of {len(shots)} images (DJI XMP gimbal angles; position "
            f"from {', '.join(sorted({s.source for s in shots}))})",
            f"gimbal sigma roll, pitch, yaw = {g[0]:g}, {g[1]:g}, {g[2]:g} deg",))
    elif args.format == "applanix":
        write_eo_applanix(args.output, eo)
    else:
        write_eo_patb(args.output, eo)
    if not args.quiet:
        rtk = sum(s.rtk_std_m is not None for s in shots)
        print(f"{len(eo)} images ({rtk} with RTK sigmas)")
        print(f"wrote {args.output} ({args.format}; {eo.system}; frame {eo.frame})")
    return 0
