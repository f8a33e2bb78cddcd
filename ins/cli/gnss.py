"""``ins gnss ROVER.obs --nav NAV [--base BASE.obs] -o out.pos``: a GNSS solution from raw
observations with RTKLIB's engine (:mod:`ins.gnss.rtklib_engine`; optional extra
``pip install 'insphoto[gnss]'``), with a summary and exit 3 when almost nothing is
solved or fixed."""
import argparse

import numpy as np

from ins.common.errors import QualityError

EPILOG = """\
inputs:
  ROVER.obs, --base: RINEX 2.x/3.x observations; --nav: broadcast navigation (RINEX
  nav, repeatable); --sp3, --clk: precise orbits and clocks (repeatable; given any,
  RTKLIB uses the precise ephemeris).  u-blox logs (.ubx): convert them first with
  RTKLIB's convbin (see the issue notes; not yet built in).

settings (--config FILE, its [rtklib] table, strict keys; the command line wins):
  mode = "single"|"dgnss"|"kinematic"|"static", direction = "forward"|"backward"|
  "combined", elevation_mask_deg = 15, frequencies = 2, systems = ["gps", "glonass",
  "galileo"], dynamics = false, ambiguity = "fix-and-hold", ar_ratio = 3,
  ionosphere = "broadcast", troposphere = "saastamoinen", base_position = "rinex"|
  "single" or base_lla_deg = [lat deg, lon deg, h m].

output: RTKLIB's .pos (lat/lon deg, ellipsoidal height m, GPS week and seconds, Q =
  1 fix, 2 float, 4 DGNSS, 5 single; sigmas in m).  The summary gives the epochs per
  quality, RTKLIB's run time and the scatter (standard deviation about the mean, E/N/U)
  of all epochs and of the fixed ones: the repeatability of a static receiver.
  Exit 3 (unless --accept-poor) when fewer than half of the rover's epochs are solved,
  or, in kinematic/static mode, fewer than 10 % of them fixed.

example:
  ins gnss 07590920.05o --base 30400920.05o --nav 07590920.05n -o rover.pos
  ins gnss rover.obs --nav brdc.nav --mode single -o rover.pos
"""

_QNAME = {1: "fix", 2: "float", 3: "sbas", 4: "dgnss", 5: "single", 6: "ppp"}


def add_parser(sub):
    from ins.gnss.rtklib_options import DIRECTIONS, MODES
    p = sub.add_parser("gnss", help="GNSS solution from raw observations (RTKLIB's engine)",
                       description="Post-process a rover's RINEX observations (with a base "
                                   "station's, broadcast navigation and optional precise "
                                   "products) with RTKLIB demo5's engine into a .pos file.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("rover", metavar="ROVER.obs")
    p.add_argument("--nav", action="append", required=True, metavar="NAV",
                   help="broadcast navigation file (RINEX nav; repeatable)")
    p.add_argument("--base", metavar="BASE.obs", help="base station observations (RINEX)")
    p.add_argument("--sp3", action="append", default=[], metavar="SP3",
                   help="precise orbits (repeatable)")
    p.add_argument("--clk", action="append", default=[], metavar="CLK",
                   help="precise clocks, RINEX CLK (repeatable)")
    p.add_argument("--config", metavar="TOML", help="file with an [rtklib] table of settings")
    p.add_argument("--mode", choices=MODES, default=None,
                   help="positioning mode (default: the config's, else kinematic)")
    p.add_argument("--direction", choices=DIRECTIONS, default=None,
                   help="filter direction (default: the config's, else combined)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.pos")
    p.add_argument("--accept-poor", action="store_true",
                   help="exit 0 even when almost nothing is solved or fixed (default: 3)")
    p.set_defaults(func=_cmd_gnss)


def _options(args):
    from ins.gnss.rtklib_options import read_rtklib_options
    table, path = None, None
    if args.config:
        from ins.common.textfiles import read_toml
        path = args.config
        doc = read_toml(path, "a config with an [rtklib] table (TOML)")
        table = doc.get("rtklib")
    return read_rtklib_options(table, path, mode=args.mode, direction=args.direction)


def _cmd_gnss(args):
    from ins.gnss.rtklib_engine import poor_reason, solve, spread_enu_m
    from ins.gnss.rtklib_options import CARRIER_MODES
    opts = _options(args)
    sol = solve(args.rover, args.nav, args.output, base=args.base, sp3=args.sp3,
                clk=args.clk, options=opts)
    log = sol.log
    n = len(log)
    counts = sol.counts()
    parts = ", ".join(f"{_QNAME.get(q, q)} {c} ({100 * c / n:.0f} %)"
                      for q, c in sorted(counts.items()))
    how = opts.mode + (f", {opts.direction}" if opts.mode in CARRIER_MODES else "")
    print(f"{args.output}: {n} of {sol.rover_epochs} rover epochs solved ({how}); {parts}; "
          f"RTKLIB {sol.run_time_s:.2f} s")
    for label, q in (("all", None), ("fixed", 1)):
        s = spread_enu_m(log, q)
        if np.all(np.isfinite(s)):
            print(f"  scatter E/N/U ({label}): {1000 * s[0]:.1f} / {1000 * s[1]:.1f} / "
                  f"{1000 * s[2]:.1f} mm")
    if log.screen:
        print(f"  covariance screen: {log.screen.repaired_lines.size} repaired, "
              f"{log.screen.dropped_lines.size} dropped")
    reason = poor_reason(sol)
    if reason and not args.accept_poor:
        raise QualityError(f"{args.output}: {reason} (--accept-poor: exit 0)")
    return 0
