"""Raw GPS of a simulated flight: satellites in view and DOPs over the flight, the code
residuals against the injected errors, RTKLIB's single-point positions against the
antenna's truth, and (with base.obs) RTKLIB's kinematic RTK.

Simulates data/flights/rawsim.toml (GPS week 1316, 2005-04-02 00:10, near the GEONET
station 0759) with the real broadcast orbits of ../shared/real/rtklib_static_pair into a
temporary folder (or reads an existing flight folder with rover.obs), then prints one
line per 20 s and at each change of the satellites: PRNs observed, their number,
GDOP/PDOP/HDOP/VDOP (from the truth's azimuths and elevations, ins.simulate.gnss_raw.dops),
and the figures.

Run: .venv/bin/python bench/bench_gnss_raw.py [FLIGHT_DIR]
"""
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ins.simulate.gnss_raw import dops
from ins.simulate.gps_orbit import C_LIGHT

ROOT = Path(__file__).resolve().parents[1]
PLAN = ROOT / "data" / "flights" / "rawsim.toml"
NAV = ROOT.parent / "shared" / "real" / "rtklib_static_pair" / "07590920.05n"


#: The variant with a dry atmosphere and no multipath (the carrier phases alone).
CLEAN = "[gnss_raw]\nhumidity_percent = 0.0\nmultipath_code_m = 0.0\nmultipath_phase_m = 0.0\n"


def simulate(out, clean=False):
    from photogrammetry.simulate.folder import simulate_flight
    plan = PLAN
    if clean:
        plan = out.parent / "clean.toml"
        text = PLAN.read_text().replace("[gnss_raw]", CLEAN, 1)
        plan.write_text("\n".join(r for r in text.splitlines()
                                   if not r.startswith("multipath_code_m = 0.3")
                                   and not r.startswith("multipath_phase_m = 0.003")))
    t0 = time.perf_counter()
    simulate_flight(plan, out, seed=1, gnss_raw_nav=NAV)
    return time.perf_counter() - t0


def run_rtk(flight, g, label):
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.nav.earth import ned_offset
    with tempfile.TemporaryDirectory() as d:
        sol = solve(flight / "rover.obs", flight / "rover.nav", Path(d) / "rtk.pos",
                    base=flight / "base.obs",
                    options=RtklibOptions(mode="kinematic", direction="forward",
                                          systems=("gps",), elevation_mask_deg=10.0))
    _, ia, ib = np.intersect1d(np.round(sol.log.time, 3), g.time, return_indices=True)
    fixed = sol.log.quality[ia] == 1
    dn = ned_offset(g.lla[ib], sol.log.lla[ia])
    for name, m in (("fixed", fixed), ("float", ~fixed)):
        if m.any():
            rms = np.sqrt(np.mean(dn[m] ** 2, axis=0))
            print(f"RTKLIB kinematic RTK with base.obs (L1), {label}: {name} {m.sum()} of "
                  f"{len(ia)} epochs, RMS N/E/D {rms[0]:.3f}/{rms[1]:.3f}/{rms[2]:.3f} m, "
                  f"mean D {dn[m, 2].mean():+.3f} m")


def main():
    tmp = None
    if len(sys.argv) > 1:
        flight = Path(sys.argv[1])
    else:
        tmp = tempfile.TemporaryDirectory()
        flight = Path(tmp.name) / "flight"
        print(f"simulated {PLAN.name} with {NAV.name} in {simulate(flight):.1f} s")
    tr = np.genfromtxt(flight / "gnss_raw_truth.csv", delimiter=",", names=True)
    clock = np.loadtxt(flight / "receiver_clock.txt")
    epochs = np.unique(tr["time_rx_s"])
    print(f"{len(epochs)} epochs, {len(tr)} observations; receiver clock bias "
          f"{clock[0, 2] * 1e6:.3f} -> {clock[-1, 2] * 1e6:.3f} us")
    print(" t_s   n  GDOP  PDOP  HDOP  VDOP  PRNs")
    n_all, pdop_all, last = [], [], None
    for t in epochs:
        rows = tr[tr["time_rx_s"] == t]
        d = dops(np.deg2rad(rows["azimuth_deg"]), np.deg2rad(rows["elevation_deg"]))
        n_all.append(len(rows))
        pdop_all.append(d["pdop"])
        changed = last is None or set(rows["prn"]) != last
        last = set(rows["prn"])
        if (t - epochs[0]) % 20 < 1e-6 or changed:
            prns = " ".join(f"{int(p):2d}" for p in rows["prn"])
            print(f"{t - epochs[0]:4.0f} {len(rows):3d} {d['gdop']:5.2f} {d['pdop']:5.2f} "
                  f"{d['hdop']:5.2f} {d['vdop']:5.2f}  {prns}")
    n_all, pdop_all = np.array(n_all), np.array(pdop_all)
    ok = np.isfinite(pdop_all)
    print(f"satellites per epoch: min {n_all.min()}, median {np.median(n_all):.0f}, max "
          f"{n_all.max()}; epochs with < 4: {np.sum(n_all < 4)}; PDOP median "
          f"{np.median(pdop_all[ok]):.2f}, max {pdop_all[ok].max():.2f}")
    try:
        import pyrtklib5 as rtk
    except ImportError:
        print("pyrtklib5 absent: no read-back, no RTKLIB positions")
        return
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(str(flight / "rover.obs"), 1, "", obs, nav, sta)
    P = np.array([obs.data[k].P[0] for k in range(obs.n)])
    tr = tr[np.lexsort((tr["prn"], tr["time_rx_s"]))]
    bias = np.interp(tr["time_rx_s"], clock[:, 0], clock[:, 2])
    res = P - (tr["range_m"] + C_LIGHT * bias - tr["sat_clock_m"] + tr["iono_m"]
               + tr["tropo_m"])
    print(f"C1C read back by RTKLIB minus the modelled range, clocks, iono, tropo: mean "
          f"{res.mean():+.3f} m, std {res.std():.3f} m (injected multipath + noise); minus "
          f"the injected multipath too: std {(res - tr['multipath_code_m']).std():.3f} m")
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.gnss import read_gnss
    from ins.nav.earth import ned_offset
    with tempfile.TemporaryDirectory() as d:
        sol = solve(flight / "rover.obs", flight / "rover.nav", Path(d) / "spp.pos",
                    options=RtklibOptions(mode="single", direction="forward",
                                          systems=("gps",), elevation_mask_deg=10.0))
    g = read_gnss(flight / "gnss.txt")
    _, ia, ib = np.intersect1d(np.round(sol.log.time, 3), g.time, return_indices=True)
    dn = ned_offset(g.lla[ib], sol.log.lla[ia])
    rms = np.sqrt(np.mean(dn ** 2, axis=0))
    print(f"RTKLIB single point: {len(ia)} of {len(epochs)} epochs solved; RMS N/E/D "
          f"{rms[0]:.2f}/{rms[1]:.2f}/{rms[2]:.2f} m against the antenna (gnss.txt)")
    if (flight / "base.obs").is_file():
        run_rtk(flight, g, "as simulated")
        if tmp is not None:
            clean = Path(tmp.name) / "clean"
            simulate(clean, clean=True)
            run_rtk(clean, read_gnss(clean / "gnss.txt"), "dry atmosphere, no multipath")
        print("(RTKLIB's relative mode models the hydrostatic delay only: the wet delay, "
              "different at the base and the aircraft, biases its float solution)")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
