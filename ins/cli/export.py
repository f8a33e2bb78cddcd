"""``ins export``: a trajectory (``ins process``'s solution.nav or an SBET) to GeoJSON, KML
or CSV in a chosen CRS for GIS tools and Google Earth."""
import argparse
import os

from ins.common.errors import InputError

EPILOG = """\
inputs:
  SOLUTION          KF-GINS .nav (week t lat lon[deg] h[m, ellipsoidal] vN vE vD[m/s]
                    roll pitch yaw[deg]) or an Applanix SBET (.out/.sbet, detected)
  --std F           its sigmas: solution_std.txt of ins process (time, std N E D m, ...)
                    or an SMRMSG file; default: solution_std.txt (smrmsg_solution.out for
                    an SBET) beside SOLUTION when present.  Interpolated linearly at the
                    epochs (the filter nodes are sparser than the trajectory)
  --gnss F          the GNSS solution the run used, for the quality per epoch: an RTKLIB
                    .pos (Q: fix, float, SBAS, DGPS, single, PPP); default: gnss.pos
                    beside SOLUTION when present (ins process writes it for raw GNSS).
                    An epoch takes the Q of the nearest GNSS epoch within half the GNSS
                    interval, else 0 ('no GNSS': the INS alone)

time:
  GPS seconds of the week (the .nav's t); with the GPS week (the .nav's first column
  when > 0, or --week) also the UTC time (ISO 8601, GPS - UTC = 18 s since 2017).
  Without a week no UTC time is written.

outputs (by the extension of -o, or --format; written atomically, inputs never touched):
  .geojson/.json    RFC 7946 FeatureCollection: a LineString (the track) and a Point per
                    epoch with gps_week, gps_time_s, utc, h_ellipsoidal_m, sigma_n/e/d/h_m,
                    gnss_quality(_name), roll/pitch/yaw_deg, speed_mps.  Coordinates lon,
                    lat (deg) and the height above the WGS84 ellipsoid (m) as RFC 7946
                    requires; --height orthometric adds H_<model>_m and the undulation
  .kml              KML 2.2: the track as LineStrings and a placemark per epoch, coloured
                    by --color-by (quality: fix green, float yellow, SBAS/DGPS orange,
                    single red, PPP blue, none grey; sigma: horizontal sigma < 0.05 m
                    green, < 0.2 m yellow, < 1 m orange, else red), UTC time stamps;
                    altitude 'absolute' is above mean sea level for Google Earth, so the
                    default height is orthometric:EGM96 there
  .csv              columns named with units, in --crs: a geographic CRS gives lat_deg,
                    lon_deg; a projected one easting_m, northing_m (pyproj from WGS84);
                    the header names the CRS and the height system

heights (--height):
  ellipsoidal (WGS84, the default for GeoJSON and CSV) or orthometric[:MODEL] with MODEL
  EGM2008 (default) or EGM96: H = h - N, N from a geoid grid installed locally (pip
  install 'insphoto[geoid]'; PROJ's grids where present); the model is named in the
  file.

decimation (long tracks): --every N keeps every N-th epoch; --min-spacing-m D keeps
  epochs at least D metres apart along the track; the first and last are always kept.

exit codes: 0 success; 2 bad input or an unwritable output (one line naming the file).

examples:
  ins export out/solution.nav -o track.geojson --week 2300
  ins export out/solution.nav -o track.kml --min-spacing-m 5 --color-by sigma
  ins export out/solution.nav -o track.csv --crs EPSG:32650 --height orthometric:EGM2008
"""

FORMATS = {".geojson": "geojson", ".json": "geojson", ".kml": "kml", ".csv": "csv"}


def add_parser(sub):
    from ins.cli.util import nonnegative_int, number, positive_int
    p = sub.add_parser(
        "export", help="trajectory to GeoJSON, KML or CSV (any CRS) for GIS tools",
        description="Export a trajectory with its times (GPS, UTC), sigmas and GNSS "
                    "quality for GIS tools and Google Earth.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("solution", metavar="SOLUTION", help="trajectory: .nav or SBET")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output .geojson, .kml or .csv")
    p.add_argument("--format", choices=["geojson", "kml", "csv"],
                   help="output format (default: from the extension of -o)")
    p.add_argument("--std", metavar="F", help="sigmas: solution_std.txt or SMRMSG "
                                              "(default: beside SOLUTION when present)")
    p.add_argument("--gnss", metavar="F", help="GNSS solution for the quality per epoch "
                                               "(RTKLIB .pos; default: gnss.pos beside "
                                               "SOLUTION when present)")
    p.add_argument("--week", type=nonnegative_int, metavar="WEEK",
                   help="GPS week of the times (default: the .nav's week column)")
    p.add_argument("--crs", default="EPSG:4326", metavar="EPSG:xxxx",
                   help="CSV: CRS of the coordinates (default EPSG:4326: lat_deg, "
                        "lon_deg; a projected CRS: easting_m, northing_m)")
    p.add_argument("--height", metavar="ellipsoidal|orthometric[:MODEL]",
                   help="height system: ellipsoidal (WGS84) or orthometric H = h - N with "
                        "MODEL EGM2008 (default) or EGM96 (default: ellipsoidal; KML: "
                        "orthometric:EGM96, Google Earth's sea level)")
    dec = p.add_mutually_exclusive_group()
    dec.add_argument("--every", type=positive_int, metavar="N",
                     help="keep every N-th epoch")
    dec.add_argument("--min-spacing-m", type=number(0, lo_open=True, unit="m"), metavar="D",
                     help="keep epochs at least D m apart along the track (m)")
    p.add_argument("--color-by", choices=["quality", "sigma", "none"],
                   help="KML colours (default: quality when known, else sigma when "
                        "known, else one colour)")
    p.add_argument("--no-points", action="store_true",
                   help="GeoJSON/KML: the line only, no feature per epoch")
    p.add_argument("-q", "--quiet", action="store_true", help="no summary")
    p.set_defaults(func=_cmd_export)


def _beside(solution, names):
    folder = os.path.dirname(os.path.abspath(solution))
    for name in names:
        path = os.path.join(folder, name)
        if os.path.isfile(path):
            return path
    return None


def _format(args):
    if args.format:
        return args.format
    ext = os.path.splitext(args.output)[1].lower()
    if ext not in FORMATS:
        raise InputError(f"-o {args.output}: unknown extension {ext or '(none)'!r}; expected "
                         f"{', '.join(FORMATS)} or --format")
    return FORMATS[ext]


def _height(text, fmt, parse_height):
    """The --height system; for KML by default EGM96 (Google Earth's sea level), else
    EGM2008 with a warning (the two differ by decimetres), else an error naming both
    ways out."""
    if text is not None or fmt != "kml":
        return parse_height(text or "ellipsoidal")
    try:
        return parse_height("orthometric:EGM96")
    except InputError as exc96:
        try:
            height = parse_height("orthometric:EGM2008")
        except InputError:
            raise InputError(f"KML altitudes are above mean sea level: {exc96.reason}; or "
                             "write ellipsoidal heights with --height ellipsoidal") from None
    import warnings
    from ins.common.errors import InputWarning
    warnings.warn("KML altitudes are above mean sea level (Google Earth: EGM96); no EGM96 "
                  "grid installed, EGM2008 heights written (decimetres apart)", InputWarning)
    return height


def _week(args):
    if args.week is not None:
        return args.week
    from ins.io.navfiles import read_nav_week, trajectory_format
    if trajectory_format(args.solution) != "nav":
        return None
    week = read_nav_week(args.solution)
    return week if week else None


def _cmd_export(args):
    import numpy as np

    from ins.common.fileio import check_output_file
    from ins.io.geoid import parse_height
    from ins.io.navfiles import read_trajectory, trajectory_format
    from ins.io.track import Track, decimate_indices, quality_at

    fmt = _format(args)
    if fmt != "csv" and args.crs != "EPSG:4326":
        raise InputError(f"--crs is for CSV; {fmt} coordinates are WGS84 longitude, latitude")
    crs = None
    if fmt == "csv":
        from ins.io.trackcsv import parse_crs
        crs = parse_crs(args.crs)
    height = _height(args.height, fmt, parse_height)
    is_sbet = trajectory_format(args.solution) == "sbet"
    std_path = args.std or _beside(args.solution, ["smrmsg_solution.out"] if is_sbet
                                   else ["solution_std.txt"])
    gnss_path = args.gnss or _beside(args.solution, ["gnss.pos"])
    inputs = [p for p in (args.solution, std_path, gnss_path) if p]
    for p in inputs:
        if os.path.exists(args.output) and os.path.samefile(p, args.output):
            raise InputError(f"-o {args.output} would overwrite the input file {p}")
    check_output_file(args.output)

    traj = read_trajectory(args.solution)
    if len(traj) == 0:
        raise InputError("no epoch in the trajectory", path=args.solution)
    week = _week(args)
    rpy = traj.rpy(degrees=True)
    rpy[:, 2] = np.mod(rpy[:, 2], 360.0)
    track = Track(time=traj.time, lla=traj.lla, week=week, rpy_deg=rpy,
                  speed_mps=np.hypot(traj.v_n[:, 0], traj.v_n[:, 1]),
                  source=os.path.basename(args.solution))
    idx = decimate_indices(track, every=args.every, min_spacing_m=args.min_spacing_m)
    track = track.take(idx)
    if std_path:
        from ins.io.trajectory_std import read_trajectory_std
        std = read_trajectory_std(std_path)
        track.sigma_ned_m = std.at(track.time)[:, :3]
    n_q = None
    if gnss_path:
        from ins.io.gnss import read_gnss
        log = read_gnss(gnss_path)
        if log.quality is not None:
            track.quality = quality_at(track.time, log.time, log.quality)
            n_q = {int(q): int(np.sum(track.quality == q)) for q in np.unique(track.quality)}
    track.height = height
    if fmt == "geojson":
        from ins.io.geojson import write_geojson
        write_geojson(args.output, track, points=not args.no_points)
    elif fmt == "kml":
        from ins.io.kml import write_kml
        color_by = args.color_by or ("quality" if track.quality is not None else
                                     "sigma" if track.sigma_ned_m is not None else "none")
        if color_by == "quality" and track.quality is None:
            raise InputError("--color-by quality needs the GNSS quality: --gnss gnss.pos "
                             "(an RTKLIB solution)")
        if color_by == "sigma" and track.sigma_ned_m is None:
            raise InputError("--color-by sigma needs the sigmas: --std solution_std.txt")
        write_kml(args.output, track, color_by=color_by, points=not args.no_points)
    else:
        from ins.io.trackcsv import write_track_csv
        write_track_csv(args.output, track, crs)
    if not args.quiet:
        from ins.io.gnss_quality import QUALITY_NAME
        used = [f"sigmas from {std_path}" if std_path else "no sigmas",
                f"GNSS quality from {gnss_path}" if n_q is not None else "no GNSS quality"]
        print(f"{args.output}: {len(track)} of {len(traj)} epochs ({fmt}; heights "
              f"{height.name}; {'; '.join(used)}"
              + ("" if week is not None else "; GPS week unknown: no UTC times") + ")")
        if n_q:
            print("  epochs by GNSS quality: " + ", ".join(
                f"{QUALITY_NAME.get(q, 'none')} {c}" for q, c in sorted(n_q.items())))
    return 0
