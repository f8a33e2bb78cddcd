"""``ins vehicle-mounting SOLUTION``: the IMU's pitch and yaw in a land vehicle estimated
from a solution processed without the non-holonomic constraint (:mod:`ins.estimation.tools.vehicle`),
printed as the ``[vehicle]`` table of the processing config."""
import argparse

from ins.cli.util import number

EPILOG = """\
method:
  At the epochs faster than --min-speed (m/s) and turning slower than --max-turn
  (deg/s of heading), the direction of the IMU's velocity in its own axes, C_nb^T v_n:
  on a straight road the vehicle moves along its forward axis, so that direction is the
  vehicle's forward axis seen from the IMU.  Its mean gives the pitch and yaw; sigma
  from the scatter of --block s block means (it does not hold the solution's own tilt
  error, common to all epochs).  A turn about the vehicle's forward axis cannot be
  seen in the velocity and does not matter to the constraint; the roll is held at
  --roll (0) and the pitch and yaw found for it: use the three printed angles together.

frames and units:
  v = the vehicle's forward, right, down axes; C_vb = Rz(yaw) Ry(pitch) Rx(roll), the
  IMU's attitude in v (the Euler convention of C_nb); positive pitch = the IMU's nose
  up against the vehicle's.  Angles in deg.  SOLUTION: .nav or SBET (ins process).

output:
  the [vehicle] table to paste into the processing config, then process again with the
  constraint (--preset land or [measurements] nhc = true).

exit codes: 0 success, 2 bad input (file, fewer than two blocks of straight driving at
  speed), 130 Ctrl-C, 143 SIGTERM.

example:
  ins process --config car.toml --preset mems -o first
  ins vehicle-mounting first/solution.nav
  ins process --config car_with_vehicle_table.toml --preset land -o out
"""


def add_parser(sub):
    from ins.estimation.tools.vehicle import BLOCK_S, MAX_TURN_DPS, MIN_SPEED_MPS
    p = sub.add_parser("vehicle-mounting", help="IMU pitch and yaw in a land vehicle from a "
                       "solution (for the non-holonomic constraint)",
                       description="Estimate the IMU's mounting rotation in a land vehicle "
                                   "(pitch and yaw against the direction of travel, deg) "
                                   "from a solution, with its 1-sigma.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("solution", metavar="SOLUTION",
                   help="trajectory (.nav or SBET) processed without the constraint")
    p.add_argument("--min-speed", type=number(0, lo_open=True, unit="m/s"), default=MIN_SPEED_MPS, metavar="MPS",
                   help=f"slowest epoch used, m/s (default {MIN_SPEED_MPS:g})")
    p.add_argument("--max-turn", type=number(0, lo_open=True, unit="deg/s"), default=MAX_TURN_DPS, metavar="DPS",
                   help=f"fastest heading rate used, deg/s (default {MAX_TURN_DPS:g})")
    p.add_argument("--block", type=number(0, lo_open=True, unit="s"), default=BLOCK_S, metavar="S",
                   help=f"block length of the sigma, s (default {BLOCK_S:g})")
    p.add_argument("--roll", type=number(-180, 180, unit="deg"), default=0.0, metavar="DEG",
                   help="the IMU's roll in the vehicle when known, deg (default 0)")
    p.set_defaults(func=_cmd_vehicle_mounting)


def _cmd_vehicle_mounting(args):
    from ins.common.errors import InputError
    from ins.estimation.tools.vehicle import estimate_mounting
    from ins.io.navfiles import read_trajectory
    traj = read_trajectory(args.solution)
    try:
        m = estimate_mounting(traj, min_speed_mps=args.min_speed, max_turn_dps=args.max_turn,
                              block_s=args.block, roll_deg=args.roll)
    except InputError as exc:
        raise InputError(f"{args.solution}: {exc}") from None
    print(f"{m.n_epochs} epochs of straight driving in {m.n_blocks} blocks: pitch "
          f"{m.rpy_deg[1]:+.3f} deg (sigma {m.sigma_deg[0]:.3f}), yaw {m.rpy_deg[2]:+.3f} deg "
          f"(sigma {m.sigma_deg[1]:.3f}); per-epoch scatter {m.scatter_deg[0]:.3f} / "
          f"{m.scatter_deg[1]:.3f} deg")
    print(m.toml(), end="")
    return 0
