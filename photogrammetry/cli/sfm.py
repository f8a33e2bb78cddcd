"""``photogrammetry sfm-import`` and ``sfm-export``: OpenSfM/ODM and COLMAP projects in,
refined EO out (OpenSfM reconstruction, COLMAP text model, orthority's OPK CSV)."""
import argparse
import os

from ins.common.errors import InputError
from ins.common.fileio import check_output_file, output_folder

IMPORT_EPILOG = """\
sources:
  reconstruction.json   OpenSfM / ODM (opensfm/ folder): the first reconstruction; its
                        tracks.csv beside it (or --tracks) gives the tie points (without
                        one: camera and EO only, and the summary says so).  Cameras
                        "brown" (focal, c_x, c_y normalised by the larger image side;
                        k1, k2, k3, p1, p2) and "perspective" (focal, k1, k2).
  COLMAP model folder   cameras/images/points3D .bin or .txt, read with pycolmap
                        (pip install 'insphoto[colmap]'); SIMPLE_PINHOLE, PINHOLE,
                        SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV (k4..k6 = 0); a model
                        with no or an empty points3D gives camera and EO only.

output folder (refused when not empty unless --force):
  camera.toml      the camera file; focal length in mm for --pixel-size-mm (an SfM
                   project has no physical pixel size; the angles do not depend on
                   it); distortion converted into the camera file's mm polynomial
                   (docs/interfaces.md: k1' = k1/f^2, k2' = k2/f^4, k3' = k3/f^6,
                   p1' = p2/f, p2' = -p1/f with f in mm; principal point in px with
                   pixel centres at integers)
  eo.csv           the SfM poses as an EO CSV: OpenSfM in ENU at its reference_lla,
                   COLMAP in the model's world frame
  tiepoints.csv    image_id,point_id,x_mm,y_mm (observed photo coordinates); image ids
                   = image file names without extension; written only when the project
                   has tie points (elsewhere with --tiepoints, which requires them)
"""

EXPORT_EPILOG = """\
formats:
  opensfm    reconstruction.json: shots with rotation = axis-angle of R_cw (world to
             computer-vision camera: x right, y down, z along the view), translation
             t = -R_cw X0; the camera as "brown"; reference_lla = the ENU origin (the
             EO must be in an enu frame)
  colmap     a COLMAP text model in the folder -o: cameras.txt (OPENCV), images.txt
             (QW QX QY QZ of R_cw, t), empty points3D.txt: known poses for COLMAP's
             point_triangulator
  colmap-db  COLMAP pose priors in a database (-o OUT.db; --database IN.db to start
             from, copied, never changed unless it is -o): per image matched by name
             (a.jpg is the EO's a) position + covariance (m^2) + gravity (the down
             vertical in the CV camera frame: the tilt of the refined rotation);
             WGS84 (lat deg, lon deg, ellipsoidal h m; covariance on local east,
             north, up) for an enu or EPSG EO, else the EO's frame as CARTESIAN.
             COLMAP's pose prior holds no full rotation: use --format colmap too.
  orthority  filename x y z omega phi kappa (deg, omega-phi-kappa: R = Rx(omega)
             Ry(phi) Rz(kappa) camera (x right, y up, z backwards) to world), space
             separated, with a .prj beside it for an EPSG frame
"""


def add_parser(sub):
    p = sub.add_parser(
        "sfm-import", help="camera, EO and tie points from an OpenSfM/ODM or COLMAP project",
        description="Convert an OpenSfM/ODM reconstruction (with tracks.csv) or a COLMAP "
                    "model into a camera file, an EO CSV and a tie-point CSV.",
        epilog=IMPORT_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("source", metavar="reconstruction.json|COLMAP_DIR")
    p.add_argument("--tracks", metavar="tracks.csv", help="OpenSfM tracks (default: beside "
                                                          "the reconstruction; without "
                                                          "one, camera and EO only)")
    p.add_argument("--tiepoints", metavar="TIEPOINTS.csv",
                   help="write the tie points here instead of FOLDER/tiepoints.csv; "
                        "refused when the project has none (no tracks.csv, no points3D)")
    p.add_argument("--pixel-size-mm", type=float, default=0.01, metavar="MM",
                   help="pixel pitch of the camera file (mm; default 0.01)")
    p.add_argument("--system", choices=["phi-omega-kappa", "omega-phi-kappa"],
                   default="omega-phi-kappa", help="angle system of eo.csv")
    p.add_argument("--force", action="store_true", help="replace a non-empty output folder")
    p.add_argument("-q", "--quiet", action="store_true")
    p.add_argument("-o", "--output", required=True, metavar="FOLDER")
    p.set_defaults(func=run_import)
    e = sub.add_parser(
        "sfm-export", help="refined EO as OpenSfM, COLMAP or orthority input",
        description="Write an EO CSV (and its camera) for SfM tools and orthorectification.",
        epilog=EXPORT_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    e.add_argument("eo", metavar="EO.csv")
    e.add_argument("--camera", metavar="CAM.toml", help="camera file (opensfm, colmap)")
    e.add_argument("--format", required=True,
                   choices=["opensfm", "colmap", "colmap-db", "orthority"])
    e.add_argument("--database", metavar="DB", help="colmap-db: the COLMAP database to start "
                   "from (not modified unless it is -o; default: a new one)")
    e.add_argument("--prior-coordinates", choices=["auto", "wgs84", "cartesian"],
                   default="auto", help="colmap-db: WGS84 (lat, lon deg, h m) or the EO's "
                   "frame (m); auto = WGS84 for an enu or EPSG frame")
    e.add_argument("--add-missing", action="store_true", help="colmap-db: add EO images "
                   "missing from --database (with --camera) instead of refusing")
    e.add_argument("--image-suffix", default=".jpg", metavar="EXT",
                   help="colmap-db: name of an added image = EO id + EXT (.jpg)")
    e.add_argument("--force", action="store_true", help="colmap: replace a non-empty "
                   "folder; colmap-db: replace an existing database other than --database")
    e.add_argument("-q", "--quiet", action="store_true")
    e.add_argument("-o", "--output", required=True, metavar="OUT")
    e.set_defaults(func=run_export)


def _tiepoint_source(args, src):
    """The OpenSfM tracks file, or None (with the reason) when there is none and no tie
    point was asked for explicitly."""
    tracks = args.tracks or os.path.join(os.path.dirname(os.path.abspath(src)), "tracks.csv")
    if os.path.isfile(tracks):
        return tracks, None
    if args.tracks or args.tiepoints:
        asked = "--tracks" if args.tracks else f"--tiepoints {args.tiepoints}"
        raise InputError(f"tracks file not found ({asked} needs the project's tie points"
                         + ("" if args.tracks else f"; none beside {src}, give --tracks")
                         + ")", path=tracks)
    return None, f"no tracks.csv beside {src} (give --tracks)"


def run_import(args):
    from photogrammetry.imagery.tiepoints import write_tiepoints
    from photogrammetry.orientation.camera import write_camera
    from photogrammetry.orientation.exposure import write_eo_csv
    if not (args.pixel_size_mm > 0):
        raise InputError(f"--pixel-size-mm must be > 0 mm, got {args.pixel_size_mm}")
    src = args.source
    if args.tiepoints:
        check_output_file(args.tiepoints)
        for p in (src, args.tracks):
            if p and os.path.abspath(p) == os.path.abspath(args.tiepoints):
                raise InputError(f"--tiepoints {args.tiepoints} would overwrite the input "
                                 f"file {p}")
    skipped, why = 0, None
    if os.path.isdir(src):
        from photogrammetry.sfm.colmap import read_colmap
        model = read_colmap(src, args.system, args.pixel_size_mm)
        cams = {model.cameras[c] for c in set(model.image_camera.values())}
        eo, ids, pids, xy, kind = (model.eo, model.image_id, model.point_id, model.xy_mm,
                                   "COLMAP")
        why = model.no_tiepoints
        if why and args.tiepoints:
            raise InputError(f"--tiepoints {args.tiepoints}: {why}", path=src)
    else:
        from photogrammetry.sfm.opensfm import read_reconstruction, read_tracks
        proj = read_reconstruction(src, args.system, args.pixel_size_mm)
        tracks, why = _tiepoint_source(args, src)
        cams = {proj.cameras[c][0] for c in set(proj.shot_camera.values())}
        ids, pids, xy = [], [], None
        if tracks:
            ids, pids, xy, skipped = read_tracks(tracks, proj)
        eo, kind = proj.eo, "OpenSfM"
    if len(cams) != 1:
        raise InputError(f"{src}: {len(cams)} cameras; the tie-point file and refine take "
                         "one camera per block")
    camera = cams.pop()
    tp_path = None if why else args.tiepoints
    with output_folder(args.output, args.force) as tmp:
        write_camera(os.path.join(tmp, "camera.toml"), camera)
        write_eo_csv(os.path.join(tmp, "eo.csv"), eo, comments=(f"from the {kind} project "
                                                                f"{src}",))
        if not why and not tp_path:
            write_tiepoints(os.path.join(tmp, "tiepoints.csv"), ids, pids, xy,
                            comments=(f"from the {kind} project {src}",))
    if tp_path:
        write_tiepoints(tp_path, ids, pids, xy, comments=(f"from the {kind} project {src}",))
    if not args.quiet:
        if why:
            print(f"{kind}: {len(eo)} images; no tie points written: {why}")
            print(f"wrote {args.output}/camera.toml, eo.csv")
        else:
            print(f"{kind}: {len(eo)} images, {len(set(pids))} tracks, {len(ids)} "
                  "observations" + (f" ({skipped} of images outside the reconstruction "
                                    "left out)" if skipped else ""))
            print(f"wrote {args.output}/camera.toml, eo.csv"
                  + (f" and {tp_path}" if tp_path else ", tiepoints.csv"))
    return 0


def run_export(args):
    from photogrammetry.orientation.camera import read_camera
    from photogrammetry.orientation.exposure import read_eo_csv
    eo = read_eo_csv(args.eo)
    if os.path.abspath(args.output) == os.path.abspath(args.eo):
        raise InputError(f"--output {args.output} would overwrite the input file {args.eo}")
    if args.format == "colmap-db":
        return _export_database(args, eo)
    if args.format == "orthority":
        from photogrammetry.sfm.opensfm import write_orthority_csv
        check_output_file(args.output)
        write_orthority_csv(args.output, eo)
        return 0
    if not args.camera:
        raise InputError(f"--format {args.format} needs --camera CAM.toml")
    camera, _ = read_camera(args.camera)
    if args.format == "opensfm":
        from photogrammetry.sfm.opensfm import write_reconstruction
        check_output_file(args.output)
        write_reconstruction(args.output, eo, camera)
    else:
        from photogrammetry.sfm.colmap import write_colmap_text
        with output_folder(args.output, args.force) as tmp:
            write_colmap_text(tmp, eo, camera)
    return 0


def _export_database(args, eo):
    from photogrammetry.orientation.camera import read_camera
    from photogrammetry.sfm.colmap_db import write_pose_priors
    out = os.path.abspath(args.output)
    same = args.database is not None and os.path.abspath(args.database) == out
    if os.path.exists(out) and not same and not args.force:
        raise InputError(f"--output {args.output} exists (give --force to replace it, or "
                         "name it as --database to update it)")
    camera = read_camera(args.camera)[0] if args.camera else None
    if args.database is None and camera is None:
        raise InputError("--format colmap-db without --database creates one: it needs "
                         "--camera CAM.toml")
    res = write_pose_priors(args.output, eo, args.database, camera, args.prior_coordinates,
                            args.add_missing, args.image_suffix)
    if not args.quiet:
        print(f"{len(res.written)} pose priors ({res.system}) written to {args.output}"
              + (f"; {len(res.replaced)} replaced earlier ones" if res.replaced else ""))
        if res.added:
            print(f"added {len(res.added)} images to the database: "
                  + ", ".join(i + args.image_suffix for i in res.added[:10])
                  + (", ..." if len(res.added) > 10 else ""))
        if res.without_prior:
            print(f"{len(res.without_prior)} database images are not in {args.eo} and "
                  "have no new prior: " + ", ".join(res.without_prior[:10])
                  + (", ..." if len(res.without_prior) > 10 else ""))
        print("the refined rotations: gravity (roll, pitch) in the priors; the full "
              "rotation with --format colmap (images.txt)")
    return 0
