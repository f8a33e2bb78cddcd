"""``photogrammetry lunar-simulate``: a session of Moon images to try ``lunar-heading`` on."""
import argparse
import os
import re
import time as wallclock
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ins.cli.util import Progress, positive_int, triplet
from ins.common.errors import InputError
from photogrammetry.cli.lunar import add_sky_options, check_sky_options

EPILOG = """\
frames and units:
  Horizon frame h = NED at the station (north, east, down); azimuths from north,
  clockwise, deg.  Camera frame c: x, y along the image axes (x = column direction,
  y = up the image), z opposite to the viewing direction (as lunar-heading).
  --heading: azimuth of the camera x axis, deg (what lunar-heading estimates).
  --tilt: angle of the optical axis from the zenith, deg (0 = looking straight up);
  --tilt-azimuth: azimuth the optical axis leans towards, deg, or "moon" (default:
  the Moon's azimuth at mid-session).  The x axis is the direction of --heading made
  normal to the optical axis.
  --station: geodetic latitude, longitude (deg, WGS84) and ellipsoidal height (m);
  south and west are negative (--station -33.9,-70.7,500).
  --start: UTC, ISO 8601 (2017-05-02T14:00:00Z); no time-zone offsets.
  --duration and --interval in s; --count images spread evenly from --start to
  --start + --duration (times rounded to the millisecond).
  Refraction (--pressure hPa, --temperature deg C) and UT1 (--dut1 s) as lunar-heading,
  with the same defaults: run lunar-heading with the same values.
  --noise, --peak, --background: counts of a 16-bit image; --blur: Gaussian PSF sigma, px.

lens:
  --camera CAM.toml (the lunar-heading camera file), default the example lens of
  data/lunar/fisheye.toml (equisolid, f = 800 px, 1600 x 1600 px, radial_k
  0.002,-0.001,0.0005 rad); --focal-length-px, --size W,H (principal point at the new
  image centre) and --radial-k K1,K2,K3 replace its values.  --lens MODEL changes the
  projection (theta off-axis angle, rad; r px from the principal point):
    fisheye-equisolid      r = 2 f sin(theta/2) with radial_k (the paper's eq. 1)
    fisheye-equidistant    r = f theta
    fisheye-stereographic  r = 2 f tan(theta/2)
    fisheye-orthographic   r = f sin(theta)
    opencv-fisheye         r = f theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6
                           + k4 theta^8), --opencv-k K1,K2,K3,K4 (OpenCV's fisheye D)

shading (--shading; the lit disk's photometric law, mu0 / mu the cosines of incidence
and emission):
  lommel-seeliger  mu0 / (mu0 + mu): bright lit limb, close to the real Moon (default)
  lambert          mu0: darkened towards the limb
  flat             1 on the lit part
  hapke            Lommel-Seeliger times Hapke's multiple-scattering and opposition
                   terms (albedo 0.25)
  --saturation COUNTS clips the images there (a saturated core, as real exposures of
  the Moon often have); lunar-heading leaves clipped pixels out of the fit.

output folder (-o DIR; --force replaces an existing one, written whole or not at all):
  images/<image_id>.png   16-bit grayscale Moon images (--shading, the Moon's phase,
                          Gaussian read noise; ids m000, m001, ...)
  times.csv               image_id,utc  (the format of lunar-heading --times)
  camera.toml             the lens (lunar-heading --camera)
  truth.toml              true heading, tilt, tilt azimuth, C_hc and the settings
  centres_true.csv        true Moon centres, px (lunar-heading --centres)

The Moon must be above --min-altitude (default 10 deg) and inside the image at every
time: otherwise an error names the first time that fails and the Moon's altitude (or
its off-axis angle).

example:
  photogrammetry lunar-simulate --station 40.0,116.0,50 --start 2017-05-02T14:00:00Z \\
      --duration 900 --count 72 --heading 123.4 --tilt 20 -o moon
  photogrammetry lunar-heading --images moon/images --times moon/times.csv \\
      --station 40.0,116.0,50 --camera moon/camera.toml
"""

#: The example lens of ``data/lunar/fisheye.toml`` (the default of ``--camera``).
DEFAULT_LENS = dict(focal_length_px=800.0, width_px=1600, height_px=1600,
                    principal_point_px=(799.5, 799.5), radial_k=(0.002, -0.001, 0.0005),
                    pixel_size_mm=0.0055)
#: Free pixels kept between the Moon's limb and the image edge, in Moon radii and px.
EDGE_RADII, EDGE_PX = 2.0, 10.0
_UTC = re.compile(r"^\d{4}-\d\d-\d\d[T ]\d\d:\d\d(?::\d\d(?:\.\d{1,9})?)?Z?$")


def add_parser(sub):
    p = sub.add_parser(
        "lunar-simulate", help="Moon images, times and a camera file to try lunar-heading on",
        description="Simulate a lunar-heading session: the Moon (DE421 ephemeris, its phase\n"
                    "and apparent size) imaged by a fisheye camera of known heading and tilt\n"
                    "at a station, at times from a start date.  Writes the images, their\n"
                    "times, the camera file and the truth into a folder.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--station", required=True, type=triplet, metavar="LAT,LON,H",
                   help="station latitude, longitude (deg) and ellipsoidal height (m)")
    p.add_argument("--start", required=True, metavar="UTC",
                   help="time of the first image, UTC, ISO 8601 (2017-05-02T14:00:00Z)")
    p.add_argument("--duration", type=float, default=900.0, metavar="S",
                   help="from the first to the last image, s (default 900)")
    n = p.add_mutually_exclusive_group()
    n.add_argument("--count", type=positive_int, metavar="N",
                   help="number of images, evenly spread over --duration (default 72)")
    n.add_argument("--interval", type=float, metavar="S", help="time between images, s")
    p.add_argument("--camera", metavar="CAM.toml",
                   help="fisheye camera file (default: the example lens, f = 800 px)")
    p.add_argument("--focal-length-px", type=float, metavar="F", help="focal length, px")
    p.add_argument("--size", metavar="W,H", help="image width and height, px")
    p.add_argument("--radial-k", type=triplet, metavar="K1,K2,K3",
                   help="radial terms of the equisolid model (eq. 1), rad")
    p.add_argument("--lens", metavar="MODEL",
                   help="lens model: fisheye-equisolid (default), fisheye-equidistant, "
                        "fisheye-stereographic, fisheye-orthographic, opencv-fisheye")
    p.add_argument("--opencv-k", metavar="K1,K2,K3,K4",
                   help="OpenCV fisheye distortion D (with --lens opencv-fisheye)")
    p.add_argument("--shading", default="lommel-seeliger", metavar="LAW",
                   help="photometric law of the lit disk: lommel-seeliger (default), "
                        "lambert, flat, hapke")
    p.add_argument("--saturation", type=float, metavar="COUNTS",
                   help="clip the images at this level, counts (default: 65535)")
    p.add_argument("--heading", type=float, default=0.0, metavar="DEG",
                   help="true azimuth of the camera x axis, deg (default 0)")
    p.add_argument("--tilt", type=float, default=2.0, metavar="DEG",
                   help="optical axis from the zenith, deg, 0 .. 85 (default 2)")
    p.add_argument("--tilt-azimuth", default="moon", metavar="DEG|moon",
                   help="azimuth the optical axis leans towards, deg (default: the Moon's "
                        "at mid-session)")
    add_sky_options(p)
    p.add_argument("--min-altitude", type=float, default=10.0, metavar="DEG",
                   help="refuse a Moon lower than this, deg (default 10)")
    p.add_argument("--noise", type=float, default=5.0, metavar="COUNTS",
                   help="Gaussian read noise per pixel, counts (default 5)")
    p.add_argument("--peak", type=float, default=3000.0, metavar="COUNTS",
                   help="brightness of the fully lit limb above the sky, counts (default 3000)")
    p.add_argument("--background", type=float, default=100.0, metavar="COUNTS",
                   help="sky level, counts (default 100)")
    p.add_argument("--blur", type=float, default=0.7, metavar="PX",
                   help="Gaussian PSF sigma, px (default 0.7)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise (default 0)")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="output folder")
    p.add_argument("--force", action="store_true", help="replace an existing output folder")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def parse_utc(text, option="--start"):
    """An ISO 8601 UTC date-time (``Z`` optional, no offset) as ``datetime64[ns]``."""
    t = None
    if _UTC.match(text.strip()):
        try:
            t = np.datetime64(text.strip().rstrip("Z").replace(" ", "T"), "ns")
        except ValueError:
            t = None
    if t is None or np.isnat(t) or not np.datetime64("1980") <= t < np.datetime64("2200"):
        raise InputError(f"{option}: expected a UTC date-time in ISO 8601 between 1980 and "
                         f"2200 (2017-05-02T14:00:00Z; no time-zone offset), got {text!r}")
    return t


def session_times(start, duration_s, count=None, interval_s=None):
    """Exposure times: `count` images from `start` to `start + duration_s` (or one every
    `interval_s` within it), rounded to the millisecond; ``datetime64[ns]``."""
    if not np.isfinite(duration_s) or duration_s < 0:
        raise InputError(f"--duration: expected s >= 0, got {duration_s}")
    if interval_s is not None:
        if not np.isfinite(interval_s) or interval_s <= 0:
            raise InputError(f"--interval: expected s > 0, got {interval_s}")
        count = int(np.floor(duration_s / interval_s + 1e-9)) + 1
        offsets = np.arange(count) * interval_s
    else:
        count = 72 if count is None else count
        offsets = np.linspace(0.0, duration_s, count)
    if count < 2:
        raise InputError(f"{count} image(s): lunar-heading needs at least 2 (--count, or a "
                         "--duration longer than --interval)")
    ms = np.rint(offsets * 1e3).astype(np.int64)
    if np.any(np.diff(ms) <= 0):
        raise InputError("images less than 1 ms apart: fewer images or a longer --duration")
    return start + ms.astype("timedelta64[ms]").astype("timedelta64[ns]")


def _lens(args):
    from photogrammetry.lunar.fisheye import MODELS, FisheyeCamera, read_camera
    cam = dict(DEFAULT_LENS)
    if args.camera:
        c = read_camera(args.camera)
        cam = dict(focal_length_px=c.focal_length_px, width_px=c.width_px,
                   height_px=c.height_px, principal_point_px=tuple(c.principal_point_px),
                   radial_k=tuple(c.radial_k), pixel_size_mm=c.pixel_size_mm, model=c.model,
                   opencv_k=tuple(c.opencv_k), focal_length_y_px=c.focal_length_y_px)
    if args.focal_length_px is not None:
        if not np.isfinite(args.focal_length_px) or args.focal_length_px <= 0:
            raise InputError(f"--focal-length-px: expected px > 0, got {args.focal_length_px}")
        if cam.get("focal_length_y_px") is not None:      # the file's pixel aspect kept
            cam["focal_length_y_px"] *= args.focal_length_px / cam["focal_length_px"]
        cam["focal_length_px"] = args.focal_length_px
    if args.size is not None:
        try:
            w, h = (int(x) for x in args.size.replace("x", ",").split(","))
        except ValueError:
            w = h = 0
        if w < 16 or h < 16:
            raise InputError(f"--size: expected W,H in px (integers >= 16), got {args.size!r}")
        cam.update(width_px=w, height_px=h, principal_point_px=((w - 1) / 2, (h - 1) / 2))
    if args.lens is not None:
        if args.lens not in MODELS:
            raise InputError(f"--lens: expected one of {', '.join(MODELS)}, got {args.lens!r}")
        if args.lens != cam.get("model", "fisheye-equisolid"):
            cam.update(model=args.lens, radial_k=(0.0, 0.0, 0.0), opencv_k=(0.0,) * 4)
    model = cam.get("model", "fisheye-equisolid")
    if args.radial_k is not None:
        if model != "fisheye-equisolid":
            raise InputError(f"--radial-k: applies to --lens fisheye-equisolid, not {model}")
        cam["radial_k"] = tuple(float(k) for k in args.radial_k)
    if args.opencv_k is not None:
        try:
            k = tuple(float(x) for x in args.opencv_k.split(","))
        except ValueError:
            k = ()
        if len(k) != 4 or not all(np.isfinite(k)):
            raise InputError(f"--opencv-k: expected K1,K2,K3,K4 (4 numbers), got "
                             f"{args.opencv_k!r}")
        if model != "opencv-fisheye":
            raise InputError(f"--opencv-k: applies to --lens opencv-fisheye, not {model}")
        cam["opencv_k"] = k
    return FisheyeCamera(**cam)


def camera_toml(camera):
    """The text of a fisheye camera file (``lunar.fisheye.read_camera``) for `camera`."""
    from photogrammetry.lunar.fisheye import camera_file_text
    return camera_file_text(camera, "Fisheye camera of a simulated session "
                                    "(photogrammetry lunar-simulate)")


def check_visible(utc, sky, camera, C_hc, min_altitude):
    """Raise InputError at the first time the Moon is below `min_altitude` (rad) or its
    disk (with a margin for the centre fit) leaves the image."""
    stamp = np.datetime_as_string(utc, unit="ms")
    alt = np.rad2deg(sky.alt)
    low = np.flatnonzero(sky.alt < min_altitude)
    if len(low):
        k = low[0]
        where = "below the horizon" if alt[k] < 0 else "too low"
        raise InputError(
            f"the Moon is {where} at {stamp[k]}Z UTC: altitude {alt[k]:.2f} deg (< "
            f"--min-altitude {np.rad2deg(min_altitude):g} deg; {len(low)} of {len(utc)} "
            f"times; Moon altitude {alt.min():.2f} .. {alt.max():.2f} deg in the session)")
    moon_c = sky.moon_h @ C_hc
    uv = camera.direction_to_image(moon_c)
    margin = EDGE_RADII * camera.focal_length_px * sky.semidiameter + EDGE_PX
    out = ((uv[:, 0] < margin) | (uv[:, 0] > camera.width_px - 1 - margin)
           | (uv[:, 1] < margin) | (uv[:, 1] > camera.height_px - 1 - margin))
    if np.any(out):
        k = np.flatnonzero(out)[0]
        off_axis = np.rad2deg(np.arccos(np.clip(-moon_c[k, 2], -1, 1)))
        raise InputError(
            f"the Moon leaves the image at {stamp[k]}Z UTC: altitude {alt[k]:.2f} deg, "
            f"{off_axis:.1f} deg off the optical axis, centre at pixel ({uv[k, 0]:.0f}, "
            f"{uv[k, 1]:.0f}) of {camera.width_px} x {camera.height_px} ({int(out.sum())} of "
            f"{len(utc)} times); tilt the camera towards it (--tilt about "
            f"{90 - alt[k]:.0f} deg, --tilt-azimuth moon) or use a wider lens")
    return uv


def _truth_toml(args, C_hc, tilt_azimuth_deg, pressure, utc):
    import tomli_w
    lat, lon, h = (float(x) for x in args.station)
    orientation = ("[camera_orientation]\n"
                   f"heading_deg = {float(args.heading % 360.0)!r}\n"
                   f"tilt_deg = {float(args.tilt)!r}\n"
                   f"tilt_azimuth_deg = {float(tilt_azimuth_deg % 360.0)!r}\n"
                   "C_hc = [\n" + "".join("    [" + ", ".join(repr(float(x)) for x in row)
                                          + "],\n" for row in C_hc) + "]\n\n")
    doc = {
        "station": {"lat_deg": lat, "lon_deg": lon, "h_m": h},
        "sky": {"pressure_hpa": float(pressure), "temperature_c": float(args.temperature)},
        "images": {"count": len(utc),
                   "first_utc": str(np.datetime_as_string(utc[0], unit="ms")) + "Z",
                   "last_utc": str(np.datetime_as_string(utc[-1], unit="ms")) + "Z",
                   "noise_counts": args.noise, "peak_counts": args.peak,
                   "background_counts": args.background, "blur_px": args.blur,
                   "shading": args.shading, "seed": args.seed}}
    if args.saturation is not None:
        doc["images"]["saturation_counts"] = float(args.saturation)
    if args.dut1 is not None:
        doc["sky"]["dut1_s"] = float(args.dut1)
    head = ("# Truth of a simulated lunar-heading session (photogrammetry lunar-simulate).\n"
            "# heading_deg: azimuth of the camera x axis (NED, from north, clockwise), the\n"
            "# HEADING of lunar-heading; tilt_deg: optical axis from the zenith, leaning\n"
            "# towards tilt_azimuth_deg; C_hc: camera -> horizon NED (S_h = C_hc S_c).\n")
    return head + orientation + tomli_w.dumps(doc)


def run(args):
    from PIL import Image

    from ins.common.fileio import atomic_open, check_output_folder, output_folder
    from photogrammetry.lunar.ephemeris import moon_sun_directions, standard_pressure_hpa
    from photogrammetry.lunar.io import write_times
    from photogrammetry.lunar.render import camera_attitude, session_image

    t0 = wallclock.perf_counter()
    check_output_folder(args.output, args.force)      # now, not after the rendering
    lat_deg, lon_deg, h = (float(x) for x in args.station)
    check_sky_options(args)
    if not 0 <= args.tilt <= 85:
        raise InputError(f"--tilt: expected deg from the zenith, 0 .. 85, got {args.tilt}")
    if not np.isfinite(args.heading):
        raise InputError(f"--heading: expected deg, got {args.heading}")
    from photogrammetry.lunar.render import SHADING_LAWS
    if args.shading not in SHADING_LAWS:
        raise InputError(f"--shading: expected one of {', '.join(SHADING_LAWS)}, got "
                         f"{args.shading!r}")
    if args.saturation is not None and not (np.isfinite(args.saturation)
                                            and args.saturation > 0):
        raise InputError(f"--saturation: expected counts > 0, got {args.saturation}")
    for name in ("noise", "peak", "background", "blur"):
        value = getattr(args, name)
        if not (np.isfinite(value) and value >= 0):
            raise InputError(f"--{name}: expected a value >= 0, got {value}")
    tilt_az = None
    if args.tilt_azimuth.strip().lower() != "moon":
        try:
            tilt_az = float(args.tilt_azimuth)
        except ValueError:
            tilt_az = np.nan
        if not np.isfinite(tilt_az):
            raise InputError(f"--tilt-azimuth: expected deg or 'moon', got {args.tilt_azimuth!r}")
    camera = _lens(args)
    utc = session_times(parse_utc(args.start), args.duration, args.count, args.interval)
    pressure = standard_pressure_hpa(h) if args.pressure is None else args.pressure
    sky = moon_sun_directions(utc, np.deg2rad(lat_deg), np.deg2rad(lon_deg), h,
                              pressure_hpa=None if pressure == 0 else float(pressure),
                              temperature_c=args.temperature, dut1_s=args.dut1)
    if tilt_az is None:
        tilt_az = float(np.rad2deg(sky.az[len(utc) // 2]))
    C_hc = camera_attitude(np.deg2rad(args.heading), np.deg2rad(args.tilt), np.deg2rad(tilt_az))
    uv = check_visible(utc, sky, camera, C_hc, np.deg2rad(args.min_altitude))

    n = len(utc)
    ids = [f"m{k:0{max(3, len(str(n - 1)))}d}" for k in range(n)]
    progress = Progress("lunar-simulate", not args.quiet, unit="images")
    options = dict(peak=args.peak, background=args.background, psf_sigma_px=args.blur,
                   noise_sigma=args.noise, shading=args.shading,
                   dtype=np.float64 if args.saturation is not None else np.uint16)
    sat = args.saturation
    with output_folder(args.output, args.force) as tmp:
        os.mkdir(os.path.join(tmp, "images"))

        def write_image(k):            # PNG compression releases the GIL: threads help
            img = session_image(camera, C_hc, sky, k, seed=args.seed, **options)
            if sat is not None:
                img = np.clip(np.rint(np.minimum(img, sat)), 0, 65535).astype(np.uint16)
            Image.fromarray(img).save(os.path.join(tmp, "images", f"{ids[k]}.png"),
                                      compress_level=1)

        with ThreadPoolExecutor(max_workers=min(os.cpu_count() or 1, 4)) as pool:
            for done, _ in enumerate(pool.map(write_image, range(n)), 1):
                progress(done, n)
        write_times(os.path.join(tmp, "times.csv"), ids, utc)
        with atomic_open(os.path.join(tmp, "camera.toml"), "w") as f:
            f.write(camera_toml(camera))
        with atomic_open(os.path.join(tmp, "truth.toml"), "w") as f:
            f.write(_truth_toml(args, C_hc, tilt_az, pressure, utc))
        with atomic_open(os.path.join(tmp, "centres_true.csv"), "w") as f:
            f.write("image_id,u_px,v_px\n")
            f.writelines(f"{i},{u:.6f},{v:.6f}\n" for i, (u, v) in zip(ids, uv))

    alt, phase = np.rad2deg(sky.alt), np.rad2deg(sky.phase_angle)
    stamp = np.datetime_as_string(utc[[0, -1]], unit="ms")
    print(f"{n} images {stamp[0]}Z .. {stamp[1]}Z UTC at {lat_deg:g}, {lon_deg:g} deg, "
          f"{h:g} m: Moon altitude {alt.min():.2f} .. {alt.max():.2f} deg, phase angle "
          f"{phase.mean():.1f} deg, diameter {2 * camera.focal_length_px * sky.semidiameter.mean():.1f} px")
    print(f"true heading {args.heading % 360.0:.6f} deg, tilt {args.tilt:g} deg towards "
          f"azimuth {tilt_az % 360.0:.2f} deg; wrote {args.output}/ (images/, times.csv, "
          "camera.toml, truth.toml, centres_true.csv)")
    extra = "" if args.pressure is None else f" --pressure {args.pressure:g}"
    extra += "" if args.temperature == 10.0 else f" --temperature {args.temperature:g}"
    extra += "" if args.dut1 is None else f" --dut1 {args.dut1:g}"
    out = args.output.rstrip("/")
    print(f"next: photogrammetry lunar-heading --images {out}/images --times {out}/times.csv "
          f"--station={lat_deg:.10g},{lon_deg:.10g},{h:.10g} --camera {out}/camera.toml{extra}")
    if not args.quiet:
        print(f"done in {wallclock.perf_counter() - t0:.2f} s")
    return 0
