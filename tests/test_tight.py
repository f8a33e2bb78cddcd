"""Tight GNSS/INS coupling (ins.estimation.coupling.pseudorange): the measurement rows against
finite differences, the range model against an exact rotation of the Earth during the
signal's travel, the clock states' transition, and runs on a simulated flight with a
synthetic constellation (tests/tight_scenario.py) whose truth is known: one, two and
three satellites carry the solution through a span where loose coupling has no fix,
with all satellites tight coupling is not worse than loose, and a blunder on one
satellite is rejected alone."""
import os
from pathlib import Path

import numpy as np
import pytest
import tight_scenario as ts

from ins.estimation.core.error_model import (
    ImuNoise,
    StateLayout,
    discretize,
    interval_matrix,
    noise_matrix,
)
from ins.estimation.core.measurements import NavPoint, corrected
from ins.estimation.coupling.pseudorange import range_rows, sagnac_range, sagnac_range_rate
from ins.nav import earth
from ins.nav.rotation import euler_to_quat

LAYOUT = StateLayout(("gyro_misalignment", "lever_arm", "time_offset", "clock"))


def _point():
    rng = np.random.default_rng(1)
    state = np.concatenate([[np.deg2rad(30.5), np.deg2rad(114.3), 1200.0],
                            [40.0, 45.0, -2.0],
                            euler_to_quat(np.deg2rad([3.0, -2.0, 40.0]))])
    sensors = np.zeros(LAYOUT.n - 9)
    sensors[:12] = rng.normal(0, 1e-4, 12)
    sensors[-2:] = [3000.0, 0.4]
    return NavPoint(100.0, state, sensors, LAYOUT, w_meas_b=np.array([0.05, -0.03, 0.1]),
                    l_b=np.array([0.6, 0.25, -1.6]), dl_b=np.zeros(3),
                    a_n=np.array([0.5, -0.3, 0.1]))


def _sats(t):
    return (np.array([ts.sat_ecef(t, k) for k in range(24)]),
            np.array([(ts.sat_ecef(t + 0.01, k) - ts.sat_ecef(t - 0.01, k)) / 0.02
                      for k in range(24)]))


def test_rows_match_finite_differences():
    p = _point()
    r_s, v_s = _sats(100.0)
    rho, rate, H_r, H_d, el = range_rows(p, r_s, v_s, 100.004)
    up = el > 0
    assert up.sum() >= 4
    # steps large enough for float64 ranges of 2e7 m (rounding 4e-9 m), small enough
    # for the curvature (ranges and rates are close to linear in every state)
    steps = np.full(LAYOUT.n, 1e-4)
    steps[LAYOUT.pos], steps[LAYOUT.vel] = 1.0, 0.5
    steps[LAYOUT.clock] = 1.0
    steps[LAYOUT.lever_arm] = 1e-2
    steps[LAYOUT.time_offset] = 1e-3
    for j in range(LAYOUT.n):
        dx = np.zeros(LAYOUT.n)
        dx[j] = steps[j]
        a = range_rows(corrected(p, dx), r_s, v_s, 100.004)
        b = range_rows(corrected(p, -dx), r_s, v_s, 100.004)
        # residual(predict(point), predict(true)) ~ H dx with true = corrected(point, dx)
        fd_r = -(a[0] - b[0]) / (2 * steps[j])
        fd_d = -(a[1] - b[1]) / (2 * steps[j])
        scale_r = np.max(np.abs(H_r[up, j])) + 1e-9
        scale_d = np.max(np.abs(H_d[up, j])) + 1e-9
        np.testing.assert_allclose(fd_r[up], H_r[up, j], atol=2e-4 * scale_r + 1e-7,
                                   err_msg=f"range column {LAYOUT.names[j]}")
        # position columns of the range rate: the ECEF velocity also turns with the n
        # frame when the position moves (|v| / R ~ 1e-5 (m/s)/m), left out of H as in
        # the loose velocity measurement
        extra = 1.5e-5 if j < 3 else 0.0
        np.testing.assert_allclose(fd_d[up], H_d[up, j], atol=2e-3 * scale_d + 2e-7 + extra,
                                   err_msg=f"range-rate column {LAYOUT.names[j]}")


def test_sagnac_range_matches_the_exact_rotation():
    lla = np.array([np.deg2rad(30.5), np.deg2rad(114.3), 1200.0])
    r = earth.lla_to_ecef(*lla)
    v = earth.dcm_en(lla[0], lla[1]) @ np.array([40.0, 45.0, -2.0])
    for k in range(24):
        rho, r_s, v_s = ts.exact_range(500.0, r, k)
        if np.dot(r_s - r, r) < 0:
            continue                                   # below the horizon
        assert abs(sagnac_range(r_s[None], r)[0] - rho) < 1e-3
        h = 1e-3
        fd = (ts.exact_range(500.0 + h, r + v * h, k)[0]
              - ts.exact_range(500.0 - h, r - v * h, k)[0]) / (2 * h)
        assert abs(sagnac_range_rate(r_s[None], v_s[None], r, v)[0] - fd) < 2e-3


def test_clock_states_transition_and_noise():
    L = StateLayout(("clock",))
    dt = 0.7
    A = interval_matrix(0.5, 100.0, np.zeros(3), np.array([0, 0, -9.8]),
                        (np.eye(3) * dt, np.zeros((3, 3)), np.zeros((3, 3))), dt, np.inf, L)
    GQG = noise_matrix(ImuNoise(), L, (0.01, 0.04))
    Phi, Qd = discretize(A, GQG, dt)
    c = L.clock
    np.testing.assert_allclose(Phi[c, c], [[1.0, dt], [0.0, 1.0]], atol=1e-15)
    assert np.all(Phi[c, :c.start] == 0) and np.all(Phi[:c.start, c] == 0)
    assert Qd[c.start + 1, c.start + 1] == pytest.approx(0.04 * dt)
    # exact integrated random-walk variance: q_b dt + q_d dt^3 / 3 (trapezoid: dt^3 / 2)
    assert Qd[c.start, c.start] == pytest.approx(0.01 * dt + 0.04 * dt ** 3 / 2)


# ---------------------------------------------------------------------------------------
# the simulated flight

SPAN_START, SPAN_S = 250.0, 60.0


@pytest.fixture(scope="module")
def scene():
    imu, truth, noise, t0 = ts.flight()
    times = np.arange(t0 + 1.0, t0 + SPAN_START + SPAN_S + 20.0, 1.0)
    epochs, bias = ts.make_epochs(truth, times, ts.L_B, seed=3)
    return imu, truth, noise, t0, epochs, bias


def _horizontal_sigma(fwd, t):
    j = int(np.argmin(np.abs(fwd.node_time - t)))
    return float(np.sqrt(fwd.P_post[j, 0, 0] + fwd.P_post[j, 1, 1]))


@pytest.mark.parametrize("n_keep", [1, 2, 3])
def test_few_satellites_are_used_through_a_loose_outage(scene, n_keep):
    """One, two, three satellites for 60 s: loose coupling has an outage; tight uses
    exactly them, its stated horizontal sigma is below the free inertial one (far below
    with three), and its error agrees with it (one realization: within 3 sigma)."""
    imu, truth, noise, t0, epochs, _ = scene
    span = (t0 + SPAN_START, t0 + SPAN_START + SPAN_S)
    mep = ts.masked(epochs, span, n_keep, truth.lla[np.searchsorted(truth.time, span[0])])
    loose = ts.spp(mep, truth.lla[0])
    assert not np.any((loose.time > span[0]) & (loose.time < span[1]))   # an outage
    fwd_l, _ = ts.run(imu, truth, noise, t0, span[1] + 5, loose, False)
    fwd_t, st_t = ts.run(imu, truth, noise, t0, span[1] + 5, mep, True)
    e_t = ts.horizontal_error(fwd_t.time, st_t, truth, span[1])
    s_l, s_t = _horizontal_sigma(fwd_l, span[1]), _horizontal_sigma(fwd_t, span[1])
    used = [ep.used for ep in fwd_t.updater.epochs if span[0] < ep.time < span[1]]
    assert min(used) == max(used) == n_keep
    assert s_t < {1: 0.95, 2: 0.8, 3: 0.3}[n_keep] * s_l, (n_keep, s_t, s_l)
    assert e_t < 3.0 * s_t, (n_keep, e_t, s_t)


def test_all_satellites_tight_not_worse_than_loose(scene):
    imu, truth, noise, t0, epochs, bias = scene
    t_end = t0 + 200.0
    out = {}
    for tight, gnss in ((False, ts.spp(epochs, truth.lla[0])), (True, epochs)):
        fwd, st = ts.run(imu, truth, noise, t0, t_end, gnss, tight)
        j = np.searchsorted(truth.time, fwd.time - 1e-6)
        d = earth.ned_offset(truth.lla[j], st[:, :3])
        m = fwd.time > t0 + 30
        out[tight] = np.sqrt(np.mean(np.sum(d[m, :2] ** 2, axis=1)))
        if tight:
            k = int(np.searchsorted(epochs.time, fwd.node_time[-1] - 1e-6))
            # the clock estimate follows the truth (5 km + drift + random walk)
            assert abs(fwd.sensors[-1, -2] - bias[k]) < 1.0
            assert fwd.n_rejected <= 0.002 * len(fwd.updater.records)
    assert out[True] <= out[False], out


def test_one_bad_satellite_is_rejected_alone(scene):
    imu, truth, noise, t0, epochs, _ = scene
    i = int(np.searchsorted(epochs.time, t0 + 150.0))
    bad = epochs.select(lambda k, sats: np.ones(len(sats), bool))
    bad.range_m[i] = bad.range_m[i].copy()
    bad.range_m[i][0] += 60.0
    fwd, st = ts.run(imu, truth, noise, t0, t0 + 155.0, bad, True)
    recs = [r for r in fwd.updater.records
            if r.time == epochs.time[i] and r.name == "pseudorange"]
    assert len(recs) == len(epochs.sats[i])
    assert [r.accepted for r in recs] == [False] + [True] * (len(recs) - 1)
    assert recs[0].axes == (bad.names[i][0],)
    assert ts.horizontal_error(fwd.time, st, truth, epochs.time[i]) < 1.0


# ---------------------------------------------------------------------------------------
# real observations through RTKLIB: the GEONET static pair (rover 0759 at its header
# position, GEONET's coordinates)

PAIR = Path(__file__).resolve().parents[1].parent / "shared" / "real" / "rtklib_static_pair"
ROVER_HDR = np.array([-3976219.5082, 3382372.5671, 3652512.9849])


@pytest.fixture(scope="module")
def pair_epochs():
    pytest.importorskip("pyrtklib5")
    if not PAIR.is_dir():
        pytest.skip("../shared/real is absent")
    from ins.gnss.raw_epochs import read_raw_epochs
    return read_raw_epochs(PAIR / "07590920.05o", PAIR / "07590920.05n", ROVER_HDR)


def test_static_pair_ranges_agree_with_the_known_station(pair_epochs):
    """Corrected pseudoranges minus the Sagnac range from the station's coordinates,
    less one clock per epoch: metres (2005 broadcast orbits and clocks, Klobuchar)."""
    ep = pair_epochs
    assert len(ep) == 120 and min(map(len, ep.sats)) >= 6
    assert ep.time[0] == 518400.0                      # GPS seconds of week
    assert all(n.startswith("G") and len(n) == 3 for n in ep.names[0])
    res = np.concatenate([(y - sagnac_range(r, ROVER_HDR)) - np.median(
        y - sagnac_range(r, ROVER_HDR)) for y, r in zip(ep.range_m, ep.sat_pos_e)])
    assert np.sqrt(np.mean(res ** 2)) < 3.0
    assert np.max(np.abs(res)) < 12.0


def test_sagnac_range_equals_rtklib_geodist(pair_epochs):
    rtk = pytest.importorskip("pyrtklib5")
    ep = pair_epochs
    rr, e = rtk.Arr1Ddouble(3), rtk.Arr1Ddouble(3)
    for k in range(3):
        rr[k] = ROVER_HDR[k]
    for r_s in ep.sat_pos_e[0]:
        rs = rtk.Arr1Ddouble(6)
        for k in range(3):
            rs[k] = r_s[k]
        assert sagnac_range(r_s[None], ROVER_HDR)[0] == pytest.approx(
            rtk.geodist(rs, rr, e), abs=1e-6)


# ---------------------------------------------------------------------------------------
# the pipeline: ins process with [gnss] coupling = "tight"

def test_config_coupling_keys(tmp_path):
    from ins.common.errors import InputError
    from ins.estimation.pipeline.config import load_config
    cfg_path = tmp_path / "c.toml"
    cfg_path.write_text('[files]\nimu = "imu.txt"\nrover = "r.obs"\n'
                        'nav = "r.nav"\n[gnss]\ncoupling = "tight"\nelevation_mask_deg = 15\n')
    cfg = load_config(cfg_path)
    assert (cfg.coupling, cfg.elevation_mask_deg) == ("tight", 15.0)
    assert cfg.gnss_raw.rover == str(tmp_path / "r.obs")
    assert cfg.gnss_raw.nav == (str(tmp_path / "r.nav"),)
    cfg_path.write_text('[files]\nimu = "imu.txt"\ngnss = "gnss.txt"\n[gnss]\n'
                        'coupling = "tigth"\n')
    with pytest.raises(InputError, match=r"c\.toml: \[gnss\] coupling: expected \"loose\" "
                                         r"or \"tight\""):
        load_config(cfg_path)


def test_process_tight_end_to_end(scene, monkeypatch):
    """``process`` with coupling = "tight" on the simulated flight: the RINEX reader
    replaced by the synthetic constellation (antenna on the config's static arm) and
    RTKLIB's solution by the flight's GNSS log; the summary counts and the smoothed
    solution against the truth."""
    from test_filter import PLAN, given_config, short_flight

    from ins.estimation.pipeline.process import process
    from ins.gnss import raw_epochs
    imu, truth, noise, t0, epochs, bias = scene
    folder = short_flight(3, PLAN.replace('grade = "navigation"', 'grade = "tactical"'))
    cfg = given_config(folder, varying=False)
    cfg.end_s = t0 + 200.0
    from ins.estimation.pipeline.gnss_source import RawGnss
    cfg.coupling = "tight"
    cfg.gnss_raw = RawGnss(rover="rover.obs", nav=("brdc.nav",))
    l_b = cfg.lever_bp + cfg.lever_ap
    times = np.arange(t0 + 1.0, t0 + 200.0, 1.0)
    synth, _ = ts.make_epochs(truth, times, l_b, seed=5)
    seen = {}

    def fake(obs, nav, receiver_ecef, *a, **k):
        seen["args"] = (obs, nav, receiver_ecef(t0 + 10.0))
        return synth
    monkeypatch.setattr(raw_epochs, "read_raw_epochs", fake)
    from ins.gnss import receiver_formats      # the files are stand-ins: taken as RINEX
    monkeypatch.setattr(receiver_formats, "detect_format", lambda path: "rinex")
    # RTKLIB's loose solution of the raw input: the flight's own GNSS log
    from ins.estimation.pipeline import process as process_module
    from ins.io.gnss import read_gnss
    monkeypatch.setattr(process_module, "_gnss", lambda c, folder: (read_gnss(c.gnss), None))
    result = process(cfg)
    c = result.counts
    assert seen["args"][:2] == ("rover.obs", ("brdc.nav",))
    r10 = earth.lla_to_ecef(*truth.lla[np.searchsorted(truth.time, t0 + 10.0)])
    assert np.linalg.norm(seen["args"][2] - r10) < 5.0      # from the loose log
    assert c["coupling"] == "tight" and c["satellites_min"] >= 6
    assert result.fwd.layout.clock is not None
    sm = result.smoothed
    j = np.searchsorted(truth.time, sm.time - 1e-6)
    d = earth.ned_offset(truth.lla[j], sm.lla)
    assert np.sqrt(np.mean(np.sum(d[:, :2] ** 2, axis=1))) < 0.3


def test_config_weights_and_clock_keys(tmp_path):
    """[gnss] range_sigma_m, range_rate_sigma_mps and receiver_clock reach the tight
    settings; bad values name the key and the unit."""
    from ins.common.errors import InputError
    from ins.estimation.pipeline.config import load_config
    from ins.estimation.coupling.pseudorange import CLOCKS, clock_psd
    cfg_path = tmp_path / "c.toml"
    base = '[files]\nimu = "imu.txt"\nrover = "r.obs"\nnav = "r.nav"\n[gnss]\ncoupling = "tight"\n'
    cfg_path.write_text(base + 'range_sigma_m = [1.0, 0.5]\nrange_rate_sigma_mps = 0.1\n'
                               'receiver_clock = "ocxo"\n')
    cfg = load_config(cfg_path)
    assert cfg.range_sigma_m == (1.0, 0.5) and cfg.range_rate_sigma_mps == (0.1, 0.1)
    assert cfg.receiver_clock == "ocxo"
    # the two-state clock: S_b = c^2 h0 / 2, S_d = 2 pi^2 c^2 h-2 (an OCXO's drift
    # wanders sqrt(S_d) = 8.4e-3 m/s per sqrt(s))
    s_b, s_d = clock_psd(*CLOCKS["ocxo"])
    assert s_b == pytest.approx(299792458.0 ** 2 * 4e-20)
    assert np.sqrt(s_d) == pytest.approx(8.43e-3, rel=1e-3)
    for bad, match in (('range_sigma_m = [-1, 1]', r"range_sigma_m: expected \[a, b\] in m"),
                       ('range_sigma_m = [0, 0]', r"range_sigma_m: expected \[a, b\] in m"),
                       ('receiver_clock = "rubidium"', r"receiver_clock: expected one of")):
        cfg_path.write_text(base + bad + "\n")
        with pytest.raises(InputError, match=match):
            load_config(cfg_path)


def test_ubx_rover_gives_the_rinex_ranges(tmp_path):
    """Tight coupling takes a u-blox log as the rover: the static pair's rover encoded as
    RXM-RAWX frames (tests/ubx_frames.py) gives the same corrected ranges as its RINEX."""
    pytest.importorskip("pyrtklib5")
    if not PAIR.is_dir():
        pytest.skip("../shared/real is absent")
    from ubx_frames import rinex2_to_ubx

    from ins.estimation.pipeline.gnss_source import RawGnss
    from ins.estimation.pipeline.tight import _read
    from ins.gnss.raw_epochs import read_raw_epochs
    rover, nav = PAIR / "07590920.05o", PAIR / "07590920.05n"
    ubx = tmp_path / "rover.ubx"
    ubx.write_bytes(rinex2_to_ubx(str(rover)))
    a = read_raw_epochs(rover, nav, ROVER_HDR)
    b = _read(RawGnss(rover=str(ubx), nav=(str(nav),)), lambda t: ROVER_HDR)
    assert len(a) == len(b) == 120
    np.testing.assert_array_equal(a.time, b.time)
    for ra, rb, sa, sb in zip(a.range_m, b.range_m, a.sats, b.sats):
        np.testing.assert_array_equal(sa, sb)
        np.testing.assert_allclose(ra, rb, atol=1e-3)
    assert os.listdir(tmp_path) == ["rover.ubx"]          # converted in a temporary folder


def test_cli_tight_on_a_simulated_raw_flight(tmp_path):
    """``ins simulate`` with raw GPS (data/flights/rawsim.toml, the pair's real broadcast
    orbits, masks of 3, 2 and 1 satellites), then ``ins process FLIGHT --coupling tight``
    as a user types it: exit 0, the per-satellite plot, and the smoothed receiver clock
    of states.txt against the simulator's clock truth (an output the loose run has not)."""
    pytest.importorskip("pyrtklib5")
    if not PAIR.is_dir():
        pytest.skip("../shared/real is absent")
    from ins.cli.main import main
    from ins.io.navfiles import read_nav
    root = Path(__file__).resolve().parents[1]
    flight, out = tmp_path / "flight", tmp_path / "out"
    assert main(["simulate", str(root / "data" / "flights" / "rawsim.toml"), "-o", str(flight),
                 "--gnss-raw", str(PAIR / "07590920.05n"), "--seed", "2", "-q"]) == 0
    assert main(["process", str(flight), "--coupling", "tight", "-o", str(out), "-q"]) == 0
    assert (out / "satellite_residuals.png").is_file() and (out / "states.txt").is_file()
    names = open(out / "states.txt").readline().split()[1:]
    st = np.loadtxt(out / "states.txt")
    clock = np.loadtxt(flight / "receiver_clock.txt")          # time_rx, time_gps, bias, drift
    c = 299792458.0
    bias = np.interp(st[:, 0], clock[:, 0], clock[:, 2] * c)
    drift = np.interp(st[:, 0], clock[:, 0], clock[:, 3] * c)
    d_b = st[:, names.index("clock_bias_m")] - bias
    d_d = st[:, names.index("clock_drift_mps")] - drift
    # the clock absorbs the ranges' common error (troposphere and ionosphere model
    # mismatch, multipath): metres; the drift: the TCXO's random walk between epochs
    assert np.sqrt(np.mean(d_b ** 2)) < 2.0     # seed 2: 0.91 m
    assert np.sqrt(np.mean(d_d ** 2)) < 0.05    # seed 2: 0.020 m/s
    sol, truth = read_nav(str(out / "solution.nav")), read_nav(str(flight / "truth.nav"))
    j = np.clip(np.searchsorted(truth.time, sol.time - 1e-6), 0, len(truth.time) - 1)
    d = earth.ned_offset(truth.lla[j], sol.lla)
    h = np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2))
    assert h < 1.0                     # seed 2: 0.35 m


def test_receiver_clock_jump_is_followed(scene):
    """A millisecond jump of the receiver clock (299.8 km in every pseudorange from an
    epoch on, as u-blox receivers do): the clock bias is set again at that epoch, the
    satellites stay in use, and the position does not notice."""
    from ins.estimation.coupling.pseudorange import TightUpdater
    imu, truth, noise, t0, epochs, _ = scene
    i = int(np.searchsorted(epochs.time, t0 + 120.0))
    jumped = epochs.select(lambda k, sats: np.ones(len(sats), bool))
    ms = 299792.458
    for k in range(i, len(jumped.time)):
        jumped.range_m[k] = jumped.range_m[k] + ms
    fwd, st = ts.run(imu, truth, noise, t0, t0 + 160.0, jumped, True)
    assert isinstance(fwd.updater, TightUpdater)
    assert len(fwd.updater.clock_jumps) == 1
    t_jump, size = fwd.updater.clock_jumps[0]
    assert t_jump == epochs.time[i] and abs(size - ms) < 5.0
    after = [ep.used for ep in fwd.updater.epochs if ep.time > epochs.time[i]]
    assert min(after) >= 4
    ref, _ = ts.run(imu, truth, noise, t0, t0 + 160.0, epochs, True)
    assert ts.horizontal_error(fwd.time, st, truth, t0 + 159.0) < 1.0
    assert not ref.updater.clock_jumps                    # no jump without one
