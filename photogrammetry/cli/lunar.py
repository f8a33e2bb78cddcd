"""``photogrammetry lunar-heading``: heading of a fisheye camera from Moon images and times."""
import argparse
import time as wallclock

import numpy as np

from ins.cli.util import Progress, triplet
from ins.common.errors import InputError
from ins.common.fileio import check_output_file

EPILOG = """\
frames and units:
  Horizon frame h = NED at the station (north, east, down); azimuth from north,
  clockwise.  Camera frame c: x, y along the image axes (x = column direction, y = up
  the image), z opposite to the viewing direction.  HEADING = azimuth of the camera x
  axis (the paper's eq. 14 axis; its xi counts from south: xi = heading - 180 deg).
  --station: geodetic latitude, longitude (deg, WGS84) and ellipsoidal height (m).
  Times: UTC (ISO 8601) or GPS week/seconds (GPS = UTC + 18 s); UT1 from the IERS table
  shipped with skyfield, or UTC + --dut1.  Refraction from --pressure (hPa, default
  the standard atmosphere at the station height) and --temperature (deg C, default 10).
  Pixel coordinates (u, v) = (column, row), pixel centres at integers.

inputs:
  TIMES.csv    image_id,utc   or   image_id,gps_week,gps_time_s  (increasing times)
  CENTRES.csv  image_id,u_px,v_px[,sigma_px]  (default sigma 0.1 px)
  --images DIR <image_id>.png/.tif/.fits (FITS needs astropy: pip install
               'insphoto[fits]').  Without --times the times come from the FITS
               headers: DATE-AVG (mid-exposure), else DATE-OBS (with TIME-OBS or UT
               when DATE-OBS is a date) + EXPTIME/2; TIMESYS must be UTC or absent.
               Header times are in --time-zone (default UTC; +08:00 = China
               standard time: UTC = header time - 8 h).
  CAM.toml     [camera] model, focal_length_px (or focal_length_mm with
               pixel_size_mm), width_px, height_px required; optional:
               principal_point_px = [(width_px-1)/2, (height_px-1)/2], pixel_size_mm,
               radial_k = [0, 0, 0] (rad, eq. 1; equisolid only), opencv_k =
               [0, 0, 0, 0] (opencv-fisheye only), focal_length_y_px (fy, px, for
               non-square pixels; default f); any other key is an error.
               model (theta = off-axis angle, r = px from the principal point):
                 fisheye-equisolid      r = 2 f sin(theta/2), radial_k (paper eq. 1)
                 fisheye-equidistant    r = f theta
                 fisheye-stereographic  r = 2 f tan(theta/2)
                 fisheye-orthographic   r = f sin(theta)
                 opencv-fisheye         r = f theta (1 + k1 theta^2 + .. + k4 theta^8)
                                        (cv2.fisheye with fx = f, fy, D = opencv_k)

the Moon in the images:
  The centre is fitted on the lit limb (the half of the outline facing the Sun, known
  from the ephemeris and a first solution) with the photometric law fitted too (a
  non-negative mix of flat, Lambert and Lommel-Seeliger shading), the radius known
  from the ephemeris' semidiameter (sigma 0.2 %) and the disk flattened by refraction
  at the Moon's altitude (vertical semi-axis 0.8 % shorter at 10 deg with
  --pressure 1013).  Clipped pixels are left out:
  --saturation, else a FITS file's SATURATE or DATAMAX, else an integer image's maximum
  when at least 3 pixels hold it (a saturated core), else its type's largest value.
  Errors: an image without a Moon (peak < 10 sky-noise sigmas above the sky, or a
  brightest object not 0.5-2 times the Moon's predicted radius) is named;
  a session whose crescent is thinner than 2 px (lit width R (1 + cos phase), R = f
  times the semidiameter) is refused.

output:
  heading and sigma (deg and arcsec), per-image residuals (arcsec; '*' = outlier,
  whitened residual > 3.5), and a convergence plot (heading - final heading and sigma
  against the number of images, as the paper's Figure 3) written to --plot.

example:
  photogrammetry lunar-heading --images moon/ --times times.csv \\
      --station 40.0,116.0,50 --camera fisheye.toml --plot convergence.png
  ... --station -33.9,-70.7,500 --temperature -5   (south/west: negative values as typed)

output streams: the table goes to stdout (| head is fine: the rest is dropped, exit 0);
  exit 2 on bad input, 130 on Ctrl-C, 143 on SIGTERM (nothing half-written).
"""

OUTLIER = 3.5


def add_sky_options(p):
    """The refraction and UT1 options shared by lunar-heading and lunar-simulate."""
    p.add_argument("--pressure", type=float, metavar="hPa",
                   help="air pressure for refraction, hPa (default: standard atmosphere; "
                        "0 = no refraction)")
    p.add_argument("--temperature", type=float, default=10.0, metavar="C",
                   help="air temperature, deg C (default 10)")
    p.add_argument("--dut1", type=float, metavar="S", help="UT1 - UTC, s (overrides the IERS table)")


#: Plausible air at a station: deg C (the coldest and hottest air measured are -89 and
#: +57 deg C; absolute zero is -273.15 deg C) and hPa (sea level is 1013 hPa).
TEMPERATURE_RANGE_C = (-100.0, 70.0)
PRESSURE_MAX_HPA = 1100.0
DUT1_MAX_S = 0.9


def check_sky_options(args):
    """InputError naming the option for a station, pressure, temperature or DUT1 that is
    not finite or not plausible (shared by lunar-heading and lunar-simulate)."""
    lat_deg, lon_deg, h = (float(x) for x in args.station)
    if abs(lat_deg) > 90:
        raise InputError(f"--station: latitude {lat_deg:g} deg is outside +-90 deg")
    if not -1e4 <= h <= 1e5:
        raise InputError(f"--station: height {h:g} m is not plausible (-10000 .. 100000 m)")
    if args.pressure is not None and not 0 <= args.pressure <= PRESSURE_MAX_HPA:
        raise InputError(f"--pressure: expected hPa in 0 .. {PRESSURE_MAX_HPA:g} (0 = no "
                         f"refraction), got {args.pressure:g}")
    lo, hi = TEMPERATURE_RANGE_C
    t = args.temperature
    if not lo <= t <= hi:
        why = " (below absolute zero, -273.15 deg C)" if t < -273.15 else ""
        raise InputError(f"--temperature: expected deg C in {lo:g} .. {hi:g}, got {t:g}"
                         + why)
    if args.dut1 is not None and not abs(args.dut1) <= DUT1_MAX_S:
        raise InputError(f"--dut1: expected UT1 - UTC in s, |DUT1| <= {DUT1_MAX_S:g} s, got "
                         f"{args.dut1:g}")


def add_parser(sub):
    p = sub.add_parser(
        "lunar-heading", help="heading of a fisheye camera from Moon images and their times",
        description="Heading (azimuth of the camera x axis) from a series of Moon images "
                    "without level information: the Moon centre's direction in the camera "
                    "(a fisheye of one of five lens models) and in the horizon frame "
                    "(DE421 ephemeris), and the rotation between them by least squares.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--images", metavar="DIR", help="folder of Moon images <image_id>.png|tif|fits")
    src.add_argument("--centres", metavar="CENTRES.csv", help="measured Moon centres, px")
    p.add_argument("--times", metavar="TIMES.csv",
                   help="exposure times (UTC); optional with FITS images whose headers "
                        "hold the times")
    p.add_argument("--time-zone", default="UTC", metavar="+HH:MM",
                   help="time zone of the FITS header times (default UTC)")
    p.add_argument("--saturation", type=float, metavar="COUNTS",
                   help="clipping level of the images, counts (default: FITS SATURATE/"
                        "DATAMAX, or an integer image's saturated plateau)")
    p.add_argument("--station", required=True, type=triplet, metavar="LAT,LON,H",
                   help="station latitude, longitude (deg) and ellipsoidal height (m)")
    p.add_argument("--camera", required=True, metavar="CAM.toml", help="fisheye camera file")
    add_sky_options(p)
    p.add_argument("--plot", metavar="OUT.png", help="write the convergence plot here")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def _select(ids_times, utc, ids_other, what):
    index = {k: i for i, k in enumerate(ids_times)}
    missing = [k for k in ids_other if k not in index]
    if missing:
        raise InputError(f"{what}: image_id {missing[0]!r} has no time in --times")
    return np.array([index[k] for k in ids_other], int)


def header_times(files, zone, folder):
    """(ids, UTC times) of FITS images from their headers (`lunar.io.fits_time`), the
    header times being local times of offset ``zone`` (timedelta64); in time order."""
    from photogrammetry.lunar.io import fits_header_time
    ids, times = [], []
    for name, path in files.items():
        if not path.lower().endswith((".fits", ".fit")):
            raise InputError(f"{path}: not a FITS file: give the times with --times")
        t = fits_header_time(path)
        if t is None:
            raise InputError("no DATE-OBS or DATE-AVG in the FITS header: give the times "
                             "with --times", path)
        ids.append(name)
        times.append(t - zone)
    if not ids:
        raise InputError("--images: no image files (.png .tif .tiff .fits .fit)", folder)
    order = np.argsort(np.array(times, "datetime64[ns]"), kind="stable")
    utc = np.array(times, "datetime64[ns]")[order]
    if np.any(np.diff(utc) <= np.timedelta64(0, "ns")):
        k = int(np.flatnonzero(np.diff(utc) <= np.timedelta64(0, "ns"))[0])
        raise InputError(f"two images with the same header time {utc[k]}: "
                         f"{ids[order[k]]} and {ids[order[k + 1]]}", folder)
    return [ids[i] for i in order], utc


def run(args):
    from photogrammetry.lunar import heading_from_centres, heading_from_images
    from photogrammetry.lunar.ephemeris import standard_pressure_hpa
    from photogrammetry.lunar.fisheye import read_camera
    from photogrammetry.lunar.io import find_images, parse_time_zone, read_centres, read_times
    from photogrammetry.lunar.solve import convergence

    t0 = wallclock.perf_counter()
    lat_deg, lon_deg, h = args.station
    check_sky_options(args)
    if args.plot:
        check_output_file(args.plot)      # an unwritable plot: now, not after the work
    camera = read_camera(args.camera)
    zone = parse_time_zone(args.time_zone)
    if args.saturation is not None and not (np.isfinite(args.saturation)
                                            and args.saturation > 0):
        raise InputError(f"--saturation: expected counts > 0, got {args.saturation}")
    if args.times:
        ids, utc = read_times(args.times)
    elif args.images:
        ids, utc = header_times(find_images(args.images), zone, args.images)
    else:
        raise InputError("--times: required with --centres")
    pressure = standard_pressure_hpa(h) if args.pressure is None else args.pressure
    sky_options = dict(pressure_hpa=None if pressure == 0 else float(pressure),
                       temperature_c=args.temperature, dut1_s=args.dut1)
    lat, lon = np.deg2rad(lat_deg), np.deg2rad(lon_deg)
    if args.centres:
        cids, uv, cov = read_centres(args.centres)
        sel = _select(ids, utc, cids, args.centres)
        if np.any(np.diff(sel) <= 0):
            raise InputError(f"{args.centres}: rows are not in the order of the times")
        used = [ids[i] for i in sel]
        result = heading_from_centres(camera, uv, cov, utc[sel], lat, lon, h, **sky_options)
    else:
        files = find_images(args.images)
        used = [k for k in ids if k in files]
        if len(used) < 2:
            raise InputError(f"{args.images}: {len(used)} image(s) match the ids of "
                             f"{args.times or 'the FITS headers'}; at least 2 usable images "
                             "are needed")
        sel = np.array([ids.index(k) for k in used])
        progress = Progress("lunar-heading", not args.quiet, unit="images")
        result = heading_from_images(camera, [files[k] for k in used], utc[sel], lat, lon, h,
                                     progress=progress, saturation=args.saturation,
                                     **sky_options)
    sol = result.solution
    arcsec = np.rad2deg(1.0) * 3600
    print(f"{len(used)} images, {str(utc[sel][0])[:23]} .. {str(utc[sel][-1])[:23]} UTC; "
          f"Moon altitude {np.rad2deg(result.sky.alt.mean()):.2f} deg, "
          f"phase angle {np.rad2deg(result.sky.phase_angle.mean()):.1f} deg")
    print(f"heading (azimuth of camera x axis) {np.rad2deg(sol.heading):.6f} deg  "
          f"sigma {sol.heading_sigma * arcsec:.1f} arcsec  "
          f"(variance factor {sol.variance_factor:.2f}; paper's Rodrigues LSQ: "
          f"{np.rad2deg(sol.heading_rodrigues):.6f} deg)")
    print(f"{'image_id':<16}{'u_px':>10}{'v_px':>10}{'resid_arcsec':>14}{'whitened':>10}")
    norm = np.linalg.norm(sol.residuals, axis=1)
    for k, name in enumerate(used):
        flag = (" * dropped" if not sol.used[k] else " *") if norm[k] > OUTLIER else ""
        print(f"{name:<16}{result.uv[k, 0]:>10.3f}{result.uv[k, 1]:>10.3f}"
              f"{sol.residuals_rad[k] * arcsec:>14.2f}{norm[k]:>10.2f}{flag}")
    n_out = int(np.sum(norm > OUTLIER))
    if n_out:
        print(f"{n_out} outlier(s) (whitened residual > {OUTLIER})")
    if args.plot:
        counts, hdg, sig = convergence(result.sky.moon_h, result.S_c, result.cov_c)
        _plot(args.plot, counts, hdg, sig, sol.heading)
        print(f"wrote {args.plot}")
    if not args.quiet:
        print(f"done in {wallclock.perf_counter() - t0:.2f} s")
    return 0


def _plot(path, counts, headings, sigmas, final):
    """Convergence plot: heading from the first n images minus the heading from all
    (arcsec) with its 1-sigma band, against n."""
    from ins.common.plotstyle import legend_right, pyplot, save_png
    plt = pyplot()
    arcsec = np.rad2deg(1.0) * 3600
    diff = np.angle(np.exp(1j * (headings - final))) * arcsec
    fig, ax = plt.subplots(figsize=(8.5, 4.2))
    ax.fill_between(counts, -sigmas * arcsec, sigmas * arcsec, color="C1", alpha=0.25,
                    lw=0, label="+-1 sigma of the heading\nfrom the first n images")
    ax.plot(counts, diff, "o", ms=3, color="C0",
            label="heading from the first n images\nminus heading from all")
    ax.axhline(0, color="k", lw=0.5)
    lim = 5 * np.median(sigmas) * arcsec
    ax.set_ylim(-lim, lim)
    ax.set_xlabel("n, number of images used (time order)")
    ax.set_ylabel("heading difference, arcsec")
    ax.set_title(f"Lunar heading convergence: heading {np.rad2deg(final) % 360:.6f} deg, "
                 f"sigma {sigmas[-1] * arcsec:.1f} arcsec with {counts[-1]} images",
                 fontsize=10)
    legend_right(ax)
    ax.grid(alpha=0.3)
    save_png(fig, path, dpi=100)
