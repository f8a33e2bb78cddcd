"""Tight coupling with every constellation (issue 33 item 3), against the simulator's
known truth (GPS, GLONASS on its frequency channels, Galileo, BeiDou; GPS L1/L2,
GLONASS G1/G2, Galileo E1/E5a, BeiDou B1I/B2a; real GPS broadcast orbits of
2021-04-28, generated ones for the others): the reader's corrected pseudoranges per
system; tight coupling of one receiver with inter-system bias states; RTK against a
base with double differences within each constellation (GLONASS float)."""
import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyrtklib5")

ROOT = Path(__file__).resolve().parents[1]
NAV = ROOT.parent / "shared" / "real" / "slac_cors_2021" / "brdc1180.21n"
WEEK, T0 = 2155, 325800.0                   # 2021-04-28 18:30 GPS, inside the brdc file
SYSTEMS = ("gps", "glonass", "galileo", "beidou")
PLAN = """
[block]
origin_lat_deg = 35.17
origin_lon_deg = 139.60
origin_h_m = 60.0
strip_azimuth_deg = 90.0
strip_length_m = 1500.0
n_strips = 1
forward_overlap_percent = 60.0
[flight]
height_agl_m = 400.0
start = "air"
stationary_s = 60.0
run_in_m = 200.0
gps_week = {week}
start_time_s = {start}
[imu]
rate_hz = 50.0
[gnss_raw]
nav_file = "{nav}"
slips = [[20.0, 0, 4]]
humidity_percent = 0.0
multipath_code_m = 0.0
multipath_phase_m = 0.0
base_lla_deg = [35.165, 139.61, 62.0]
systems = ["G", "R", "E", "C"]
signals = ["L1", "L2", "G1", "G2", "E1", "E5a", "B1I", "B2a"]
"""


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    if not NAV.is_file():
        pytest.skip("../shared/real is absent (the GPS broadcast orbits)")
    from ins.simulate.folder import simulate_flight
    d = tmp_path_factory.mktemp("multitight")
    (d / "plan.toml").write_text(PLAN.format(week=WEEK, start=T0, nav=NAV))
    return simulate_flight(d / "plan.toml", d / "flight", seed=8)


def test_corrected_ranges_of_every_system_against_the_truth(flight):
    """The reader's corrected pseudoranges (satellite clock, group delay, Klobuchar at
    the signal's frequency, Saastamoinen removed) less the true geometric range and the
    true receiver clock: the code noise only, for every system."""
    from ins.gnss.raw_epochs import read_raw_epochs
    from ins.io.navfiles import read_nav
    from ins.nav import earth
    truth = read_nav(str(flight / "truth.nav"))
    clock = np.loadtxt(flight / "receiver_clock.txt", comments="#")
    tr = np.genfromtxt(flight / "gnss_raw_truth.csv", delimiter=",", names=True,
                       dtype=None, encoding="ascii")
    first = {}
    for row in tr:
        if row["signal"] in ("L1", "G1", "E1", "B1I"):
            first[(round(float(row["time_rx_s"]), 3), str(row["sat"]))] = float(row["range_m"])
    j = np.clip(np.searchsorted(truth.time, clock[:, 1]), 0, len(truth.time) - 1)
    raw = read_raw_epochs(flight / "rover.obs", flight / "rover.nav",
                          lambda t: earth.lla_to_ecef(*truth.lla[np.searchsorted(
                              truth.time, t).clip(0, len(truth.time) - 1)]),
                          systems=("G", "R", "E", "C"))
    res = {}
    for k, t in enumerate(raw.time):
        i_clk = int(np.argmin(np.abs(clock[:, 0] - t)))
        c_dt = clock[i_clk, 2] * 299792458.0
        for name, y in zip(raw.names[k], raw.range_m[k]):
            key = (round(float(t), 3), name)
            if key in first:
                res.setdefault(name[0], []).append(y - first[key] - c_dt)
    assert set(res) == {"G", "R", "E", "C"}
    for s, r in res.items():
        r = np.array(r)
        assert abs(np.median(r)) < 0.3 and np.std(r) < 1.0, (s, np.median(r), np.std(r))


def _run(folder, base, systems, carrier=True):
    from ins.estimation.pipeline.config import config_from_manifest
    from ins.estimation.pipeline.gnss_source import RawGnss
    from ins.estimation.pipeline.process import process
    from ins.gnss.rtklib_options import RtklibOptions
    cfg = config_from_manifest(str(folder))
    cfg.gnss = None
    cfg.gnss_raw = RawGnss(rover=str(folder / "rover.obs"), nav=(str(folder / "rover.nav"),),
                           base=base, options=RtklibOptions(
                               mode="single", systems=systems, frequencies=1,
                               elevation_mask_deg=10.0))
    cfg.coupling = "tight"
    cfg.carrier_phase = carrier
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return process(cfg, accept_poor=True)


def _horizontal(folder, traj):
    from ins.io.navfiles import read_nav
    from ins.nav import earth
    truth = read_nav(str(folder / "truth.nav"))
    j = np.clip(np.searchsorted(truth.time, traj.time - 1e-6), 0, len(truth.time) - 1)
    d = earth.ned_offset(truth.lla[j], traj.lla)
    return float(np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2)))


def test_one_receiver_with_inter_system_biases(flight):
    """Every system in one receiver's tight coupling: the layout gains the inter-system
    biases, the satellites used are those of all four systems, and the smoothed
    solution is at the code-noise level (the simulator has no inter-system bias: the
    estimates stay near 0)."""
    res = _run(flight, None, SYSTEMS)
    L = res.fwd.layout
    assert L.isb is not None and res.counts["satellites_mean"] > 15
    assert _horizontal(flight, res.smoothed) < 0.5
    isb = L.estimate(np.asarray(res.smoothed_sensors)[-1], "isb")
    assert np.all(np.abs(isb[:3]) < 1.0), isb


def test_rtk_with_every_system_fixes_at_once(flight):
    """RTK against the base with every system: double differences within each
    constellation, fixed from the first epochs (GPS L1 alone takes tens of seconds),
    the smoothed solution at the centimetre; GLONASS ambiguities stay float."""
    res = _run(flight, str(flight / "base.obs"), SYSTEMS)
    up = res.fwd.updater
    c = res.counts
    assert c["fix_rate"] > 0.85, c
    assert np.min(np.array(up.fixed_at) - up.gnss.time[0]) < 10.0
    assert not any(key[0].startswith("R") for key in up.held)
    assert {n[0] for names in up.gnss.names for n in names} == {"G", "R", "E", "C"}
    assert _horizontal(flight, res.smoothed) < 0.03


def test_geometry_free_finds_the_slips_without_their_flags(flight, monkeypatch):
    """The loss-of-lock flags removed: the slip of every satellite at 20 s (4 cycles on
    each frequency) is found by the geometry-free combination of the two carriers and
    the RTK solution stays at the centimetre."""
    from ins.estimation.pipeline import tight
    read = tight._read

    def no_flags(raw_in, positions):
        raw = read(raw_in, positions)
        for r in (raw, raw.base):
            r.lli = r.lli2 = None
        return raw
    monkeypatch.setattr(tight, "_read", no_flags)
    res = _run(flight, str(flight / "base.obs"), SYSTEMS)
    up = res.fwd.updater
    t0 = up.gnss.time[0]
    assert up.gf_slips >= 10
    at_20 = {s for t, s in up.slips if abs(t - t0 - 20.0) < 1.5}
    assert len(at_20) >= 10
    assert _horizontal(flight, res.smoothed) < 0.03
