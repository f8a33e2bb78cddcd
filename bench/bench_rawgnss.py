"""Raw GNSS in, on the real GEONET pair 0759 (rover) / 3040 (base), GPS, an hour at 30 s:
prints the figures of the raw-GNSS path of ``ins gnss`` / ``ins process``.

- kinematic PPK (combined, forward, backward): epochs per Q, rover scatter E/N/U of the
  fixes (the receiver is static), their mean against RTKLIB's static solution of the
  hour, and the baseline length against the RINEX headers' (GEONET coordinates);
- forward minus backward separation: RMS/max of all epochs and of those both fixed;
- the rover as a u-blox log (RXM-RAWX encoded from its RINEX, tests/ubx_frames.py;
  then with RXM-SFRBX from the navigation file and no --nav): largest position
  difference to the RINEX run;
- an SP3 synthesized from the broadcast orbits (tests/sp3_synth.py): largest position
  difference to the broadcast run; an SP3 ending at 00:35: where the solution ends;
- dynamics on (demo5's default): records the covariance screen repairs/drops;
- with ``rnx2rtkp`` on PATH (another RTKLIB build, e.g. Debian's 2.4.3 b34: ``apt-get
  install rtklib``): its kinematic combined solution of the same files against ours
  (epochs, Q flags, largest position difference).

Writes the separation plot to ``fwd_bwd_separation.png`` in the folder given (default:
a temporary one, removed).

    .venv/bin/python bench/bench_rawgnss.py [OUT_DIR]
"""
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from sp3_synth import satellite_states, write_sp3  # noqa: E402
from ubx_frames import rinex2_to_ubx, rinex2_to_ubx_with_nav  # noqa: E402

from ins.gnss.rtklib_engine import binding, solve  # noqa: E402
from ins.gnss.rtklib_options import RtklibOptions  # noqa: E402
from ins.gnss.separation import (  # noqa: E402
    forward_backward,
    plot_separation,
    summary_lines,
)
from ins.nav.earth import lla_to_ecef, ned_offset  # noqa: E402

PAIR = Path(__file__).resolve().parents[2] / "shared" / "real" / "rtklib_static_pair"
ROVER, BASE, NAV = (str(PAIR / n) for n in ("07590920.05o", "30400920.05o", "07590920.05n"))
ROVER_HDR = np.array([-3976219.5082, 3382372.5671, 3652512.9849])
BASE_HDR = np.array([-3978242.4348, 3382841.1715, 3649902.7667])
GPS = ("gps",)


def main(out):
    rtk = binding()
    o = RtklibOptions(systems=GPS)
    static = solve(ROVER, NAV, out / "static.pos", base=BASE,
                   options=RtklibOptions(systems=GPS, mode="static", direction="forward"))
    truth = static.log.lla[-1]
    for d in ("combined", "forward", "backward"):
        s = solve(ROVER, NAV, out / f"{d}.pos", base=BASE,
                  options=RtklibOptions(systems=GPS, direction=d))
        fixed = s.log.quality == 1
        ned = ned_offset(truth, s.log.lla[fixed])
        print(f"kinematic {d:8s}: {len(s.log)} of {s.rover_epochs} epochs, Q {s.counts()}; "
              f"fixes: scatter E/N/U {1e3 * ned[:, 1].std(ddof=1):.1f}/"
              f"{1e3 * ned[:, 0].std(ddof=1):.1f}/{1e3 * ned[:, 2].std(ddof=1):.1f} mm, "
              f"mean vs static {1e3 * ned[:, 1].mean():.1f}/{1e3 * ned[:, 0].mean():.1f}/"
              f"{-1e3 * ned[:, 2].mean():.1f} mm")
    rover = lla_to_ecef(*truth)
    print(f"baseline: {np.linalg.norm(rover - BASE_HDR):.3f} m (static) vs headers "
          f"{np.linalg.norm(ROVER_HDR - BASE_HDR):.3f} m")
    sep = forward_backward(ROVER, NAV, str(out), base=BASE, options=o)
    for line in summary_lines(sep):
        print(line)
    print(f"figure: {plot_separation(sep, out / 'fwd_bwd_separation.png')}")
    ref = solve(ROVER, NAV, out / "ref.pos", base=BASE, options=o)
    (out / "rover.ubx").write_bytes(rinex2_to_ubx(ROVER))
    u = solve(out / "rover.ubx", NAV, out / "ubx.pos", base=BASE, options=o)
    print(f"u-blox rover: Q equal {np.array_equal(u.log.quality, ref.log.quality)}, "
          f"max |NED| difference to RINEX "
          f"{1e3 * np.abs(ned_offset(ref.log.lla, u.log.lla)).max():.2f} mm")
    data, _ = rinex2_to_ubx_with_nav(ROVER, NAV, rtk)
    (out / "rover_nav.ubx").write_bytes(data)
    un = solve(out / "rover_nav.ubx", None, out / "ubx_nav.pos", base=BASE, options=o)
    print(f"u-blox rover with RXM-SFRBX, no --nav: Q equal "
          f"{np.array_equal(un.log.quality, ref.log.quality)}, max |NED| difference to "
          f"RINEX {1e3 * np.abs(ned_offset(ref.log.lla, un.log.lla)).max():.2f} mm")
    tows = np.arange(518400.0 - 3600, 521970.0 + 3601, 300.0)
    states = satellite_states(rtk, NAV, 1316, tows, 520185.0)
    p = solve(ROVER, NAV, out / "prec.pos", base=BASE, options=o,
              sp3=[write_sp3(out / "b.sp3", rtk, states, 1316, tows)])
    print(f"SP3 from broadcast: Q equal {np.array_equal(p.log.quality, ref.log.quality)}, "
          f"max |NED| difference {1e3 * np.abs(ned_offset(ref.log.lla, p.log.lla)).max():.2f}"
          f" mm")
    s = solve(ROVER, NAV, out / "short.pos", base=BASE, options=o,
              sp3=[write_sp3(out / "s.sp3", rtk, states, 1316, tows[:20])])
    print(f"SP3 to {tows[19]:.0f} s: {len(s.log)} epochs, last {s.log.time[-1]:.0f} s "
          f"(broadcast: {len(ref.log)}, last {ref.log.time[-1]:.0f} s)")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dyn = solve(ROVER, NAV, out / "dyn.pos", base=BASE,
                    options=RtklibOptions(systems=GPS, dynamics=True))
    _rnx2rtkp(out, ref.log)
    print(f"dynamics on: Q {dyn.counts()}, screen {dyn.log.screen.repaired_lines.size} "
          f"repaired, {dyn.log.screen.dropped_lines.size} dropped of "
          f"{dyn.log.screen.records}")


def _rnx2rtkp(out, ours):
    import shutil
    import subprocess

    from ins.io.rtklib import read_pos
    if shutil.which("rnx2rtkp") is None:
        print("rnx2rtkp: not on PATH (skipped)")
        return
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_rawgnss import RNX2RTKP_CONF
    (out / "k.conf").write_text(RNX2RTKP_CONF)
    subprocess.run(["rnx2rtkp", "-k", str(out / "k.conf"), "-o", str(out / "r.pos"), ROVER,
                    BASE, NAV], check=True, capture_output=True)
    a = read_pos(out / "r.pos")
    same = len(a) == len(ours) and np.array_equal(a.time, ours.time)
    q = {int(k): int(n) for k, n in zip(*np.unique(a.quality, return_counts=True))}
    if not same:
        print(f"rnx2rtkp: {len(a)} epochs against our {len(ours)}")
        return
    print(f"rnx2rtkp (other build): {len(a)} epochs, Q {q}; same epochs, same Q "
          f"{np.array_equal(a.quality, ours.quality)}, max |NED| difference "
          f"{1e3 * np.abs(ned_offset(a.lla, ours.lla)).max():.2f} mm")


if __name__ == "__main__":
    if len(sys.argv) > 1:
        folder = Path(sys.argv[1])
        folder.mkdir(parents=True, exist_ok=True)
        main(folder)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            main(Path(tmp))
