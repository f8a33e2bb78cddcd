"""``ins gnss ROVER.obs --nav NAV [--base BASE.obs] -o out.pos``: a GNSS solution from raw
observations with RTKLIB's engine (:mod:`ins.gnss.rtklib_engine`; optional extra
``pip install 'insphoto[gnss]'``), with a summary and exit 3 when almost nothing is
solved or fixed."""
import argparse
import os

import numpy as np

from ins.common.errors import InputError, QualityError

EPILOG = """\
inputs:
  ROVER (or --rover), --base: RINEX 2.x/3.x observations, or raw receiver logs in any
  format RTKLIB decodes, converted to RINEX 3.04 on the way with RTKLIB's convrnx
  (their ephemerides too): rtcm2, rtcm3 (MSM4-7 or 1002/1004/1010/1012), oem4 (NovAtel
  OEM4/6/7 binary RANGEB/RANGECMPB), ubx (u-blox RXM-RAWX, RXM-SFRBX), sbf
  (Septentrio), hemisphere, skytraq, javad, nvs, binex, rt17 (Trimble), unicore,
  swift (SBP).  The format is detected from the content (RINEX header; valid UBX,
  RTCM3, NovAtel, Unicore, SBF, SBP, SkyTraq, RT17, BINEX, Javad, $BIN, NVS frames,
  RTCM2 words with their checksums or parity) or the extension, else it is named:
  --gnss-format (the rover's) and --base-format, or [rtklib] rover_format /
  base_format.  RTCM3 and RTCM2 carry no week: it is taken from the rover's first
  epoch (for a base) or the nav file's first ephemeris.  A base log must give its
  antenna position (RTCM3 1005/1006, RTCM2 type 3) unless base_position = "single"
  or base_lla_deg is set.
  --nav: broadcast navigation (RINEX nav, repeatable; needed unless the logs hold
  ephemerides); --sp3, --clk: precise orbits and clocks
  (repeatable; given any, RTKLIB uses the precise ephemeris: they must cover the whole
  span processed, else the error names the file and both spans; RINEX clock 3.04 is
  read through a 3.00 copy); --atx: ANTEX antenna file (satellite and receiver
  antenna phase centres, the receiver antenna type from the RINEX header); --dcb:
  code biases (CODE's P1C1/P1P2 .DCB, as RTKLIB reads them).  RTKLIB drops every
  satellite without a broadcast ephemeris, even with precise products: a system
  with no broadcast file (--nav) is not used.
  --start, --end: process only this span, GPST date and time YYYY-MM-DDThh:mm:ss.

precise point positioning (--mode ppp-static | ppp-kinematic; needs --sp3 and --clk,
  no base): dual-frequency iono-free carrier phase and code, zenith tropospheric
  delay estimated, float ambiguities, solid Earth tides, phase wind-up, eclipsing
  satellites excluded, antenna phase centres with --atx (without one the solution is
  the antenna's mean phase centre, some cm above its reference point).  Ocean tide
  loading is not applied.  Also --mode single with --sp3/--clk: single point with
  precise orbits and clocks.
  The summary states the convergence, from a forward run (the combined solution is
  converged from the start by construction): the time (min) after which the
  horizontal error stays below --convergence-m (m, default 0.1) to the end, against
  --reference-xyz X,Y,Z (the antenna's true position, ECEF m: a station's published
  coordinates, in the frame of the orbits) with the errors after it, else against
  the solution's own horizontal sigma.

settings (--config FILE, its [rtklib] table, strict keys; the command line wins):
  mode = "single"|"dgnss"|"kinematic"|"static"|"ppp-kinematic"|"ppp-static",
  direction = "forward"|"backward"|"combined", elevation_mask_deg = 15, frequencies = 2, systems = ["gps", "glonass",
  "galileo"], dynamics = false, ambiguity = "fix-and-hold", ar_ratio = 3,
  ionosphere = "broadcast", troposphere = "saastamoinen" (PPP: "off", "iono-free",
  "estimate"), base_position = "rinex"|
  "single" or base_lla_deg = [lat deg, lon deg, h m], rover_format, base_format
  (default detected: see inputs).

output: RTKLIB's .pos (lat/lon deg, ellipsoidal height m, GPS week and seconds, Q =
  1 fix, 2 float, 4 DGNSS, 5 single, 6 PPP; sigmas in m).  The summary gives the epochs per
  quality, RTKLIB's run time and the scatter (standard deviation about the mean, E/N/U)
  of all epochs and of the fixed ones: the repeatability of a static receiver.
  Exit 3 (unless --accept-poor) when fewer than half of the rover's epochs are solved,
  or, in kinematic/static mode, fewer than 10 % of them fixed.

forward/backward separation (kinematic mode; --no-separation skips it): RTKLIB is run
  forward and backward as well, and their difference (forward minus backward, north/
  east/up m, at the backward position) written beside the output as
  OUT_fwd_bwd_separation.txt (one epoch a line with both Q flags) and
  OUT_fwd_bwd_separation.png; the summary gives its RMS and max, of all epochs and of
  those both directions fixed.  Two fixes with the same integers give the same position
  (0.1 mm): a fixed epoch where they differ is a wrong fix in one direction.

example:
  ins gnss 07590920.05o --base 30400920.05o --nav 07590920.05n -o rover.pos
  ins gnss rover.obs --nav brdc.nav --mode single -o rover.pos
  ins gnss --rover rover.ubx --base base.obs --nav brdc.nav -o rover.pos
  ins gnss --rover rover.gps --base ntrip.rtcm3 --nav brdc.nav -o rover.pos
  ins gnss --rover rover.log --gnss-format javad --base base.obs --nav brdc.nav -o r.pos
  ins gnss slac1180.21o --nav brdc1180.21n --mode ppp-static --sp3 COD.SP3 \
      --clk COD.CLK --start 2021-04-28T19:30:00 --end 2021-04-28T20:30:00 \
      --reference-xyz -2703116.233,-4291767.080,3854247.826 -o slac.pos
"""

_QNAME = {1: "fix", 2: "float", 3: "sbas", 4: "dgnss", 5: "single", 6: "ppp"}


def add_parser(sub):
    from ins.cli.util import triplet
    from ins.gnss.rtklib_options import DIRECTIONS, MODES
    p = sub.add_parser("gnss", help="GNSS solution from raw observations (RTKLIB's engine)",
                       description="Post-process a rover's RINEX observations (with a base "
                                   "station's, broadcast navigation and optional precise "
                                   "products) with RTKLIB demo5's engine into a .pos file.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("rover_file", nargs="?", metavar="ROVER",
                   help="rover observations (RINEX, or a receiver log: see inputs)")
    p.add_argument("--rover", metavar="ROVER", help="the same, as an option")
    p.add_argument("--nav", action="append", default=[], metavar="NAV",
                   help="broadcast navigation file (RINEX nav; repeatable)")
    p.add_argument("--base", metavar="BASE",
                   help="base station observations (RINEX or a receiver log)")
    from ins.gnss.receiver_formats import RAW_FORMATS
    names = ("rinex",) + RAW_FORMATS
    p.add_argument("--gnss-format", "--rover-format", dest="rover_format",
                   type=str.lower, choices=names, metavar="NAME",
                   help="the rover's receiver format (default: detected): "
                        + ", ".join(names))
    p.add_argument("--base-format", type=str.lower, choices=names, metavar="NAME",
                   help="the base's receiver format (default: detected)")
    p.add_argument("--sp3", action="append", default=[], metavar="SP3",
                   help="precise orbits (repeatable)")
    p.add_argument("--clk", action="append", default=[], metavar="CLK",
                   help="precise clocks, RINEX CLK (repeatable)")
    p.add_argument("--atx", metavar="ATX",
                   help="antenna phase centres (ANTEX): satellites' and the receiver's")
    p.add_argument("--dcb", metavar="DCB", help="code biases (CODE .DCB, as RTKLIB reads)")
    p.add_argument("--start", metavar="TIME",
                   help="first epoch to process, GPST YYYY-MM-DDThh:mm:ss (default: the "
                        "first observed)")
    p.add_argument("--end", metavar="TIME",
                   help="last epoch to process, GPST YYYY-MM-DDThh:mm:ss (default: the last)")
    p.add_argument("--reference-xyz", type=triplet, metavar="X,Y,Z",
                   help="PPP: the antenna's true position, ECEF m (X,Y,Z), for the "
                        "convergence and the errors after it")
    p.add_argument("--convergence-m", type=float, default=None, metavar="M",
                   help="PPP: horizontal threshold of convergence, m (default 0.1)")
    p.add_argument("--config", metavar="TOML", help="file with an [rtklib] table of settings")
    p.add_argument("--mode", choices=MODES, default=None,
                   help="positioning mode (default: the config's, else kinematic with --base and "
                        "single without)")
    p.add_argument("--direction", choices=DIRECTIONS, default=None,
                   help="filter direction (default: the config's, else combined)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.pos")
    p.add_argument("--no-separation", action="store_true",
                   help="kinematic mode: skip the forward/backward runs and their "
                        "separation files")
    p.add_argument("--accept-poor", action="store_true",
                   help="exit 0 even when almost nothing is solved or fixed (default: 3)")
    p.set_defaults(func=_cmd_gnss)


def _options(args):
    from ins.gnss.rtklib_options import mode_without_base, read_rtklib_options
    table, path = None, None
    if args.config:
        from ins.common.textfiles import read_toml
        path = args.config
        doc = read_toml(path, "a config with an [rtklib] table (TOML)")
        table = doc.get("rtklib")
    return read_rtklib_options(table, path, direction=args.direction,
                               mode=mode_without_base(table, args.base, args.mode),
                               rover_format=args.rover_format,
                               base_format=args.base_format)


def _window(args):
    """(start, end) GPS seconds since 1980 of --start/--end, or None."""
    if args.start is None and args.end is None:
        return None
    from ins.gnss.products import parse_gpst
    return (-np.inf if args.start is None else parse_gpst(args.start, "--start"),
            np.inf if args.end is None else parse_gpst(args.end, "--end"))


def separation_paths(pos_path):
    """The separation table and figure beside a ``.pos`` output: ``X_fwd_bwd_separation
    .txt`` and ``.png`` for ``X.pos``."""
    stem = os.path.splitext(os.fspath(pos_path))[0]
    return stem + "_fwd_bwd_separation.txt", stem + "_fwd_bwd_separation.png"


def _cmd_gnss(args):
    from ins.gnss.rtklib_engine import poor_reason, solve, spread_enu_m
    from ins.gnss.rtklib_options import CARRIER_MODES
    if bool(args.rover_file) == bool(args.rover):
        raise InputError("give the rover's observations once: ROVER or --rover")
    rover = args.rover_file or args.rover
    opts = _options(args)
    kw = dict(base=args.base, sp3=args.sp3, clk=args.clk, atx=args.atx, dcb=args.dcb,
              window=_window(args))
    if (args.reference_xyz is not None or args.convergence_m is not None) and not opts.is_ppp:
        raise InputError("--reference-xyz and --convergence-m go with --mode ppp-static or "
                         "ppp-kinematic")
    sol = solve(rover, args.nav or None, args.output, options=opts, **kw)
    log = sol.log
    n = len(log)
    counts = sol.counts()
    parts = ", ".join(f"{_QNAME.get(q, q)} {c} ({100 * c / n:.0f} %)"
                      for q, c in sorted(counts.items()))
    how = opts.mode + (f", {opts.direction}" if opts.mode in CARRIER_MODES or opts.is_ppp
                       else "")
    print(f"{args.output}: {n} of {sol.rover_epochs} rover epochs solved ({how}, "
          f"{sol.ephemeris} ephemeris); {parts}; RTKLIB {sol.run_time_s:.2f} s")
    if sol.unused_systems:
        print(f"  not used: {', '.join(sol.unused_systems)} (observed, but no broadcast "
              f"ephemeris in --nav: RTKLIB drops such satellites even with precise products)")
    for label, q in (("all", None), ("fixed", 1)):
        s = spread_enu_m(log, q)
        if np.all(np.isfinite(s)):
            print(f"  scatter E/N/U ({label}): {1000 * s[0]:.1f} / {1000 * s[1]:.1f} / "
                  f"{1000 * s[2]:.1f} mm")
    if log.screen:
        print(f"  covariance screen: {log.screen.repaired_lines.size} repaired, "
              f"{log.screen.dropped_lines.size} dropped")
    if opts.is_ppp:
        from ins.gnss.convergence import DEFAULT_THRESHOLD_M, forward_convergence
        conv, _ = forward_convergence(
            sol, rover, args.nav or None, os.path.dirname(os.path.abspath(args.output)),
            reference_ecef=args.reference_xyz,
            threshold_m=DEFAULT_THRESHOLD_M if args.convergence_m is None
            else args.convergence_m, **kw)
        print("  " + conv.line() + ("" if opts.direction == "forward"
                                    else " (of a forward run)"))
    if opts.mode == "kinematic" and not args.no_separation:
        from ins.gnss.separation import (
            forward_backward,
            plot_separation,
            summary_lines,
            write_separation,
        )
        sep = forward_backward(rover, args.nav or None,
                               os.path.dirname(os.path.abspath(args.output)), options=opts,
                               **kw)
        txt, png = separation_paths(args.output)
        write_separation(sep, txt)
        plot_separation(sep, png)
        for line in summary_lines(sep):
            print("  " + line)
        print(f"  {txt}\n  {png}")
    reason = poor_reason(sol)
    if reason and not args.accept_poor:
        raise QualityError(f"{args.output}: {reason} (--accept-poor: exit 0)")
    return 0
