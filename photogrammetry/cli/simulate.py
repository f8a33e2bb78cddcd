"""``ins simulate PLAN.toml -o FLIGHT_DIR``: simulate a survey flight into a flight folder.

A sub-command of the ``ins`` tool that lives in ``photogrammetry`` because the flight
folder holds image products (camera file, true EO, tie points) that need the camera
model, and ``ins`` never imports ``photogrammetry``.  ``ins.cli.main`` finds it through the
entry-point group ``ins.commands`` declared in ``pyproject.toml``
(``simulate = "photogrammetry.cli.simulate:add_parser"``); the interface, messages and
exit codes are those of every ``ins`` command (:func:`ins.cli.main.run_command`).
"""
import argparse
import time as wallclock
from pathlib import Path

from ins.cli.util import nonnegative_int
from ins.common import textfiles
from ins.common.errors import InputError

EPILOG = """\
frames and units:
  The plan (TOML, units in the key names: _deg, _m, _mps, _hz, _s, _percent; see
  data/flights/demo.toml) gives the block origin (WGS84 lat/lon deg, ellipsoidal h m),
  strips, flying height, speed, wind, turbulence, the stabilized mount, the IMU grade,
  GNSS, camera, terrain and tie points.  Every section and key is optional (with the
  defaults of ins/simulate/plan_model.py) except [block] origin_lat_deg and origin_lon_deg;
  an unknown section or key is an error listing the known keys of its section, with a
  "did you mean" for a near miss.  Refused, naming the key: a bank (or turn rate)
  above [flight] max_bank_deg; wind crab + yaw turbulence, or roll/pitch turbulence,
  beyond 80 % of the mount's limits on the strips (the mount must follow there; in the
  turns it saturates smoothly); a run-in shorter than 3 servo lags.

output folder (docs/interfaces.md; manifest.toml names every file, frame and unit):
  imu.txt      KF-GINS IMU text: time_s, dtheta x y z (rad), dvel x y z (m/s), body FRD
               (IMU on the stabilized platform), increments stamped at their END
  gnss.txt     antenna: time_s lat_deg lon_deg h_m std_n std_e std_d (m) [vN vE vD, std m/s]
  mount.txt    time_s roll pitch yaw (deg) of the platform relative to the aircraft
  truth.nav    the IMU's true trajectory at every IMU epoch (.nav: week t lat lon h vN vE vD
               roll pitch yaw; deg, m, m/s)
  events.csv   image_id,time_s (mid-exposure, GPS s of week)
  camera.toml  frame camera and its mounting (axes, lever arm m, boresight deg)
  eo_true.csv, eo_true_omega-phi-kappa.csv
               true exterior orientation in the mapping frame ENU at the block origin (m),
               angles (deg) of C_mc = C_mn C_nb C_bc in the named system
  tiepoints.csv    image_id,point_id,x_mm,y_mm (distorted, with pixel noise)
  ground_points.csv  point_id,X_m,Y_m,Z_m (mapping frame)
  plan.toml    a verbatim copy of the plan
  with a [scanner] table in the plan (a laser line scanner rigid on the IMU; see
  data/flights/lidar_demo.toml), for ins georeference and ins strip-check:
  returns.csv  time_s,range_m,scan_angle_deg,intensity,return_number,strip (the strips)
  scanner.toml the scanner file a user has: boresight 0 (unknown), the plan's lever arm
               and sigmas; scanner_true.toml with the true boresight
  points_true.csv  time_s,x_ecef_m,y_ecef_m,z_ecef_m,strip: the terrain point of each
               return (WGS84 ECEF, m)
  with [gnss_raw] in the plan or --gnss-raw NAV_FILE (raw GPS L1 from broadcast orbits):
  rover.obs    RINEX 3.04 C1C L1C D1C S1C (m, cycles, Hz, dB-Hz) of the antenna, epochs in
               receiver clock time, LLI bit 0 at arc starts and cycle slips
  rover.nav    the navigation file's header and GPS records of the flight's span
  receiver_clock.txt  time_rx_s time_gps_s clock_bias_s clock_drift_s_per_s (truth)
  gnss_raw_truth.csv  per observation: geometric range (light time, Sagnac), satellite
               clock, iono, tropo, multipath, ambiguity, elevation, azimuth (m, cycles, deg)

  The same plan and seed give the same bytes.  The folder is built beside FLIGHT_DIR and
  renamed into place when complete; a non-empty FLIGHT_DIR is refused unless --force,
  which replaces it whole (never a mix of two runs).  Ctrl-C leaves nothing behind.

example:
  ins simulate data/flights/demo.toml -o flight1 --seed 1 --grade tactical
"""


def add_parser(sub):
    """Register ``ins simulate`` on the ``ins`` tool's sub-parsers ``sub``."""
    from ins.simulate.sensor_errors import PRESETS
    p = sub.add_parser(
        "simulate", help="simulate a survey flight (IMU, GNSS, mount, images, tie points)",
        description="Simulate a photogrammetric survey flight from a TOML flight plan: the "
                    "true trajectory with a stabilized mount, IMU increments with sensor "
                    "errors, the GNSS antenna log, mount angles, exposures with their true "
                    "exterior orientation, terrain and tie points; written as a flight "
                    "folder with manifest.toml.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("plan", metavar="PLAN.toml", help="flight plan (TOML)")
    p.add_argument("-o", "--output", required=True, metavar="FLIGHT_DIR",
                   help="flight folder to create (its parent must exist)")
    p.add_argument("--seed", type=nonnegative_int, default=0, metavar="N",
                   help="seed of all random errors (integer >= 0, default 0)")
    p.add_argument("--grade", choices=sorted(PRESETS), default=None,
                   help="IMU grade, replacing the plan's [imu] grade (its overrides still "
                        "apply)")
    p.add_argument("--force", action="store_true",
                   help="replace a non-empty FLIGHT_DIR (only once the new folder is complete)")
    p.add_argument("--gnss-raw", metavar="NAV_FILE", default=None,
                   help="RINEX GPS navigation file (broadcast orbits): also write raw L1 "
                        "observations rover.obs (RINEX 3.04) with rover.nav, "
                        "receiver_clock.txt and gnss_raw_truth.csv, with the plan's "
                        "[gnss_raw] settings or their defaults; the plan's [flight] gps_week "
                        "and start_time_s must fall within the file's ephemerides")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=_cmd_simulate)


def _cmd_simulate(args):
    from ins.cli.util import Progress
    from ins.common.fileio import check_output_folder
    from photogrammetry.simulate.folder import simulate_flight

    t0 = wallclock.perf_counter()
    out = Path(args.output)
    plan_path = Path(args.plan)
    if not plan_path.is_file():
        raise InputError("no such plan file", path=args.plan)
    textfiles.read_toml(plan_path, "a TOML flight plan")      # binary data, bad TOML: early
    if out.exists() and out.resolve() == plan_path.resolve().parent:
        raise InputError("--output is the plan's own folder; choose a new folder",
                         path=args.output)
    check_output_folder(out, args.force)      # OSError naming FLIGHT_DIR: exit 2
    progress = Progress("simulate", not args.quiet)
    if args.gnss_raw is not None and not Path(args.gnss_raw).is_file():
        raise InputError("--gnss-raw: no such RINEX navigation file", path=args.gnss_raw)
    folder = simulate_flight(args.plan, out, args.seed, grade=args.grade, force=args.force,
                             progress=progress, gnss_raw_nav=args.gnss_raw)
    if not args.quiet:
        import tomllib
        with open(folder / "manifest.toml", "rb") as f:
            manifest = tomllib.load(f)
        fl = manifest["flight"]
        print(f"wrote {folder}: {fl['end_time_s'] - fl['start_time_s']:.1f} s of flight, "
              f"{fl['imu_rate_hz']:g} Hz IMU ({fl['grade']}), {fl['n_images']} images, "
              f"{fl['n_tiepoint_observations']} tie-point observations, "
              + (f"{manifest['scanner']['n_returns']} laser returns, "
                 if "scanner" in manifest else "")
              + f"seed {fl['seed']}, "
              f"in {wallclock.perf_counter() - t0:.1f} s")
    return 0
