"""``photogrammetry eo``: exterior orientation per exposure from an INS trajectory."""
import argparse
import os
from pathlib import Path

import numpy as np

from ins.cli.util import Progress, triplet
from ins.common import textfiles
from ins.common.errors import InputError
from ins.common.fileio import check_output_file
from photogrammetry.cli import eo_exif as cli_eo_exif

EPILOG = """\
frames and units:
  The trajectory is the IMU's (.nav: lat, lon deg, ellipsoidal h m, NED velocity m/s,
  roll, pitch, yaw deg with C_nb = Rz(yaw) Ry(pitch) Rx(roll), body forward-right-down;
  or an Applanix SBET, detected by the extension .out/.sbet or the content: radians,
  heading = platform heading - wander angle).
  It is interpolated at each event time (s, same time scale): position by cubic Hermite
  with the velocities, attitude by a cubic on rotation vectors (error at 200 Hz below
  1 um and 0.001 arcsec).  The camera file gives the camera axes C_bc, the boresight
  (deg) and the lever arm (IMU centre to perspective centre, body frame, m).
  Camera attitude C_mc = C_mn C_nb C_bc; angles in deg in the named system:
    phi-omega-kappa  R = Ry(-phi) Rx(omega) Rz(kappa)  (columns phi, omega, kappa)
                     the textbooks' sign (Russian/Chinese/Vietnamese programs):
                     a3 = R[0,2] = -sin(phi) cos(omega), phi = atan2(-a3, c3)
    omega-phi-kappa  R = Rx(omega) Ry(phi) Rz(kappa)   (columns omega, phi, kappa)
                     (Wolf/Dewitt's object-to-image matrix is its transpose)
  R maps camera-frame rays (x, y, -f) into the mapping frame; elementary rotations
  are active (Rx(a) = [[1, 0, 0], [0, cos a, -sin a], [0, sin a, cos a]]).
  Mapping frame: enu = east, north, up (m) at the block origin (--origin, or the
  flight folder's, or the first exposure's lat/lon at h = 0); utm or EPSG:<code> =
  easting, northing (m) of the projection with the meridian convergence applied to
  the attitude, heights ellipsoidal (default) or orthometric H = h - N: with --height
  orthometric[:MODEL] N of a geoid model (EGM2008, the default, or EGM96; a grid
  installed locally: pip install 'insphoto[geoid]') at each perspective centre, or one
  constant N with --geoid-undulation N (m); the EO header names the model.

inputs:
  FLIGHT_DIR with manifest.toml (ins simulate) supplies truth.nav, events.csv,
  camera.toml and the mapping-frame origin; --trajectory etc. override them.
  CAM.toml (docs/interfaces.md; any other section or key is an error, with the known
  keys and a "did you mean"):
    [camera]   focal_length_mm, pixel_size_mm, width_px, height_px,
               principal_point_px = [u0, v0] (px), all required;
               optional: model = "frame", radial_k = [0, 0, 0] (mm^-2, mm^-4, mm^-6),
               tangential_p = [0, 0] (mm^-1)
    [mounting] optional, and each of its keys: axes = [[1,0,0],[0,-1,0],[0,0,-1]]
               (C_bc rows, nadir camera with x forward), lever_arm_m = [0, 0, 0] (m,
               body FRD), boresight_deg = [0, 0, 0] (rx, ry, rz)
  events: CSV image_id,time_s.  --sigma: solution_std.txt (time, std N E D m,
  std vN vE vD m/s, std roll pitch yaw deg) adds sigma columns.

output formats:
  csv       EO CSV: header comments (system, frame, units), image_id,time_s,X_m,...
  applanix  ID event time_s E_m N_m h_m omega_deg phi_deg kappa_deg (omega-phi-kappa)
  patb      per image: ID X0 Y0 Z0, then R = C_mc by rows; -99 at the end

examples:
  photogrammetry eo FLIGHT_DIR -o eo.csv
  photogrammetry eo --trajectory sol.nav --events events.csv --camera camera.toml \\
      --frame EPSG:32650 --system omega-phi-kappa -o eo.csv
  photogrammetry eo FLIGHT_DIR --origin -33.9,151.2,20 -o eo.csv   (negative values
      work as typed, also --origin=-33.9,151.2,20)
"""


def add_parser(sub):
    p = sub.add_parser(
        "eo", help="exterior orientation per exposure from an INS trajectory",
        description="Interpolate an IMU trajectory at the exposure events and compute the "
                    "perspective centre and camera angles (phi-omega-kappa or "
                    "omega-phi-kappa) in a mapping frame.",
        epilog=EPILOG + cli_eo_exif.EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("flight_dir", nargs="?", metavar="FLIGHT_DIR",
                   help="simulated flight folder with manifest.toml")
    p.add_argument("--trajectory", metavar="T.nav",
                   help="IMU trajectory (.nav, or SBET .out/.sbet)")
    p.add_argument("--events", metavar="EVENTS.csv", help="exposure events image_id,time_s")
    p.add_argument("--camera", metavar="CAM.toml", help="camera file")
    p.add_argument("--sigma", metavar="STD.txt", help="trajectory standard deviations")
    p.add_argument("--system", choices=["phi-omega-kappa", "omega-phi-kappa"],
                   default="phi-omega-kappa", help="angle system (default phi-omega-kappa)")
    p.add_argument("--frame", default="enu", metavar="enu|utm|EPSG:CODE",
                   help="mapping frame (default enu)")
    p.add_argument("--origin", type=triplet, metavar="LAT,LON,H",
                   help="ENU origin: lat, lon (deg), ellipsoidal h (m)")
    p.add_argument("--geoid-undulation", type=float, metavar="N_M",
                   help="constant geoid undulation (m): orthometric heights H = h - N "
                        "(projected frames)")
    p.add_argument("--height", metavar="ellipsoidal|orthometric[:MODEL]",
                   help="heights of projected frames: ellipsoidal (default) or "
                        "orthometric H = h - N with the geoid MODEL EGM2008 (default) or "
                        "EGM96 (not with --geoid-undulation)")
    p.add_argument("--attitude-interp", choices=["cubic", "slerp"], default="cubic",
                   help="attitude interpolation (default cubic)")
    p.add_argument("--format", choices=["csv", "applanix", "patb"], default="csv",
                   help="output format (default csv)")
    p.add_argument("-q", "--quiet", action="store_true", help="no summary")
    p.add_argument("-o", "--output", required=True, metavar="EO.csv", help="output file")
    cli_eo_exif.add_options(p)
    p.set_defaults(func=run)


def _flight_inputs(folder):
    """Paths and origin from a flight folder's manifest.toml."""
    folder = Path(folder)
    manifest = folder / "manifest.toml"
    if not manifest.is_file():
        raise InputError(f"{folder} has no manifest.toml (not a flight folder)")
    doc = textfiles.read_toml(manifest, "a flight manifest (TOML)")
    files = doc.get("files", {})
    out = {}
    for key in ("truth", "events", "camera"):
        if key not in files:
            raise InputError(f"missing key [files] {key}", path=str(manifest))
        out[key] = str(folder / files[key])
    mf = doc.get("mapping_frame", {})
    if mf:
        try:
            out["origin"] = np.array([float(mf["origin_lat_deg"]), float(mf["origin_lon_deg"]),
                                      float(mf.get("origin_h_m", 0.0))])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"[mapping_frame] needs origin_lat_deg, origin_lon_deg "
                             f"(deg), origin_h_m (m): {exc}", path=str(manifest)) from None
    return out


def _inputs(args):
    found = _flight_inputs(args.flight_dir) if args.flight_dir else {}
    traj = args.trajectory or found.get("truth")
    events = args.events or found.get("events")
    camera = args.camera or found.get("camera")
    for name, value in (("--trajectory", traj), ("--events", events), ("--camera", camera)):
        if value is None:
            raise InputError(f"{name} is required without a FLIGHT_DIR")
    origin = args.origin if args.origin is not None else found.get("origin")
    return traj, events, camera, origin


def run(args):
    if args.from_exif:
        return cli_eo_exif.run(args)
    from ins.io.navfiles import read_trajectory
    from photogrammetry.orientation.camera import read_camera
    from photogrammetry.orientation.exposure import (
        compute_eo,
        read_events,
        read_solution_std,
        write_eo_applanix,
        write_eo_csv,
        write_eo_patb,
    )
    from photogrammetry.orientation.mapping import parse_frame

    traj_path, events_path, camera_path, origin = _inputs(args)
    check_output_file(args.output)        # an unwritable output: now, not after the work
    out = os.path.abspath(args.output)
    for p in (traj_path, events_path, camera_path, args.sigma):
        if p is not None and os.path.abspath(p) == out:
            raise InputError(f"--output {args.output} would overwrite the input file {p}")
    if origin is not None and abs(origin[0]) > 90:
        raise InputError(f"--origin: latitude {origin[0]} deg is outside +-90 deg")
    ids, times = read_events(events_path)
    _, mounting = read_camera(camera_path)
    progress = Progress("eo", not args.quiet)
    progress.note(f"reading {traj_path}...")
    traj = read_trajectory(traj_path)
    sigma = read_solution_std(args.sigma) if args.sigma else None
    outside = np.flatnonzero((times < traj.time[0]) | (times > traj.time[-1]))
    if outside.size:                 # the events file is at fault: name it, not the .nav
        k = int(outside[0])
        raise InputError(f"event {ids[k]} at t = {float(times[k])!r} s is outside the "
                         f"trajectory {traj_path} ({float(traj.time[0])!r} .. "
                         f"{float(traj.time[-1])!r} s; {outside.size} such)", path=events_path)
    if origin is None:
        from ins.nav.interpolation import interpolate_trajectory
        first = interpolate_trajectory(traj, times[:1], names=ids[:1], path=traj_path)
        origin_rad = np.array([first.lla[0, 0], first.lla[0, 1], 0.0])
    else:
        origin_rad = np.array([np.deg2rad(origin[0]), np.deg2rad(origin[1]), origin[2]])
    frame = parse_frame(args.frame, origin_rad, args.geoid_undulation,
                        cli_eo_exif.height_system(args))
    eo = compute_eo(traj, ids, times, mounting, frame, args.system, sigma=sigma,
                    method=args.attitude_interp, path=traj_path)
    progress.note("")
    if args.format == "csv":
        comments = [f"trajectory = {traj_path}", f"events = {events_path}",
                    f"camera = {camera_path}", f"attitude interpolation = {args.attitude_interp}"]
        if args.sigma:          # photogrammetry refine finds the INS sigma here (boresight)
            comments.insert(1, f"trajectory sigma = {args.sigma}")
        write_eo_csv(args.output, eo, comments=comments)
    elif args.format == "applanix":
        write_eo_applanix(args.output, eo)
    else:
        write_eo_patb(args.output, eo)
    if not args.quiet:
        print(f"{len(eo)} exposures, {times.min():.3f} .. {times.max():.3f} s, "
              f"trajectory {traj_path} ({len(traj)} epochs)")
        print(f"wrote {args.output} ({args.format}; {eo.system}; frame {eo.frame})")
    return 0
