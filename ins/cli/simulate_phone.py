"""``ins simulate-phone OUT --nav NAV``: the simulated twin of an Android phone's
GnssLogger log (:func:`ins.simulate.gnsslogger_writer.write_android_journey`): a phone
carried on a walk or in a car, its raw GPS, inertial sensors and own fixes as the app
writes them, with the truth beside them."""
import argparse

from ins.cli.util import nonnegative_int

EPILOG = """\
what is simulated (ins.simulate.gnsslogger_writer):
  walk  a 240 s handheld walk (the phone held 60 deg off the walking direction and
        pitched 20 deg down, steps bouncing 3 cm, two stops, five turns), 4.6 s at rest
        at the start
  car   the consumer car: parked 40 s, then 4 min of town driving, the phone in a
        cradle turned 1, -2, 3 deg (roll, pitch, yaw) from the car's axes
  both beside the GSI station of the 2005 day 092 navigation file of
  ../shared/real/rtklib_static_pair (GPS week 1316, from 524400 s), which --nav must
  be (or cover that span and place).  The phone: consumer MEMS errors with 1.5 x the
  preset's white noise, 200 Hz UncalGyro/UncalAccel on a boot clock 3.7 ppm off GPS
  time with 0.2 ms stamp jitter, in the phone's axes (x right, y top, z out of the
  screen); GPS L1 Raw records at 1 Hz (2 m code noise and 2 m multipath at zenith,
  the chip's clock 1.2 us off drifting 80 ns/s; the white paper's pseudorange formula
  inverted: TimeNanos, FullBiasNanos, BiasNanos, ReceivedSvTimeNanos, TimeOffsetNanos,
  PseudorangeRateMetersPerSecond, AccumulatedDeltaRangeMeters/State, Cn0DbHz, State,
  ChipsetElapsedRealtimeNanos); GPS fixes at 1 Hz, 3 m off (north, east) and 5 m
  (up) in a 30 s Gauss-Markov wander.

outputs (in OUT, new or empty; --force replaces it):
  gnss_log.txt        the GnssLogger log: 'ins import-android gnss_log.txt -o DIR'
  rover.nav           the navigation file's records of the span (ins process --nav)
  truth.nav           the phone's true trajectory at 10 Hz (ins process --truth)
  android_truth.csv   one row per Raw measurement: time_gps_s, svid, pseudorange_m (what
                      the fields encode), range_m, clock_bias_m, sat_clock_m, iono_m,
                      tropo_m, multipath_m, elevation_deg
  android_truth.toml  the clocks drawn (boot clock offset and rate, the chip's clock
                      fields and bias) and the settings

example:
  ins simulate-phone phone --nav ../shared/real/rtklib_static_pair/07590920.05n
  ins import-android phone/gnss_log.txt -o imp
  ins process --imu imp/imu.csv --rover imp/gnss.obs --nav phone/rover.nav \\
      --config hw.toml --preset consumer --coupling tight --truth phone/truth.nav -o walk
"""


def add_parser(sub):
    p = sub.add_parser(
        "simulate-phone", help="simulated Android GnssLogger log of a walk or a car",
        description="Write the simulated twin of an Android phone's GnssLogger log (raw "
                    "GPS, inertial sensors, the phone's fixes) with its truth.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("output", metavar="OUT", help="output folder (new or empty)")
    p.add_argument("--nav", required=True, metavar="NAV",
                   help="RINEX GPS navigation file covering the journey")
    p.add_argument("--journey", choices=["walk", "car"], default="walk",
                   help="what carries the phone (default walk)")
    p.add_argument("--seed", type=nonnegative_int, default=0,
                   help="seed of every random draw (default 0)")
    p.add_argument("--force", action="store_true", help="replace a non-empty OUT whole")
    p.add_argument("-q", "--quiet", action="store_true", help="no summary")
    p.set_defaults(func=run)


def run(args):
    import os

    from ins.common.errors import InputError
    from ins.common.fileio import output_folder
    from ins.simulate.gnsslogger_writer import ANDROID_CAR, ANDROID_WALK, write_android_journey
    if not os.path.isfile(args.nav):
        raise InputError(f"--nav {args.nav}: no such file (a RINEX GPS navigation file)")
    journey = {"walk": ANDROID_WALK, "car": ANDROID_CAR}[args.journey]
    with output_folder(args.output, force=args.force) as stage:
        facts = write_android_journey(stage, args.nav, journey=journey, seed=args.seed)
    if not args.quiet:
        g, s, f = facts["gnss"], facts["sensors"], facts["fixes"]
        sats = " ".join(f"G{p:02d}" for p in g["satellites"])
        print(f"wrote {args.output}: {args.journey}, "
              f"{facts['journey_end_gps_s'] - facts['journey_start_gps_s']:.0f} s from GPS "
              f"week {facts['gps_week']} {facts['journey_start_gps_s']:.0f} s, seed "
              f"{args.seed}")
        print(f"  gnss_log.txt: {g['n_measurements']} Raw measurements in {g['n_epochs']} "
              f"epochs ({sats}), {s['n_gyro']} UncalGyro and {s['n_accel']} UncalAccel "
              f"samples, {f['n']} fixes")
    return 0
