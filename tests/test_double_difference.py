"""Tight coupling against a base station (ins.estimation.coupling.double_difference,
ins.gnss.raw_pairs): the DD covariance and the update's independence of the reference
satellite (algebra), the rows against finite differences, the per-satellite w-test
(a blunder on any one satellite, the reference included, is dropped alone), the pairing
of epochs; on the raw-simulated flight with the errors a base cancels (data/flights/
rawsim_dd.toml: ionosphere twice Klobuchar, troposphere 1.1 Saastamoinen) DD beats
single-point tight coupling through masks of 3, 2 and 1 satellites; on the GEONET static
pair the DD pseudorange residuals from RTKLIB's static fix are at the code noise."""
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from ins.estimation.coupling.double_difference import (
    dd_covariance,
    dd_operator,
    screen,
    single_difference_rows,
    w_test,
)
from ins.estimation.core.error_model import StateLayout
from ins.estimation.core.measurements import NavPoint, corrected
from ins.gnss.raw_epochs import RawEpochs
from ins.nav import earth
from ins.nav.rotation import euler_to_quat

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tight_scenario as ts  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PAIR = ROOT.parent / "shared" / "real" / "rtklib_static_pair"
LAYOUT = StateLayout(("gyro_misalignment", "lever_arm", "time_offset"))   # no clock


def _kalman(P, H, R, z):
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return K @ z, P - K @ S @ K.T


def test_dd_covariance_and_reference_invariance():
    """``D Sigma D^T = diag(s_i) + s_ref 1 1^T``; the Kalman update with the DDs of one
    reference equals that with another's (the DDs are an invertible map of each other)."""
    rng = np.random.default_rng(4)
    s = rng.uniform(0.2, 3.0, 5)
    R = dd_covariance(s, 2)
    others = [0, 1, 3, 4]
    np.testing.assert_allclose(R, np.diag(s[others]) + s[2], rtol=1e-14)
    A = rng.normal(size=(6, 6))
    P = A @ A.T
    H_sd, z_sd = rng.normal(size=(5, 6)), rng.normal(size=5)
    out = []
    for ref in range(5):
        D = dd_operator(5, ref)
        out.append(_kalman(P, D @ H_sd, dd_covariance(s, ref), D @ z_sd))
    for dx, P_post in out[1:]:
        np.testing.assert_allclose(dx, out[0][0], atol=1e-10)
        np.testing.assert_allclose(P_post, out[0][1], atol=1e-10)


def _point():
    rng = np.random.default_rng(1)
    state = np.concatenate([[np.deg2rad(30.5), np.deg2rad(114.3), 1200.0],
                            [40.0, 45.0, -2.0],
                            euler_to_quat(np.deg2rad([3.0, -2.0, 40.0]))])
    sensors = rng.normal(0, 1e-4, LAYOUT.n - 9)
    return NavPoint(100.0, state, sensors, LAYOUT, w_meas_b=np.array([0.05, -0.03, 0.1]),
                    l_b=np.array([0.6, 0.25, -1.6]), dl_b=np.zeros(3),
                    a_n=np.array([0.5, -0.3, 0.1]))


def test_dd_rows_match_finite_differences():
    """DD rows ``D H`` against central differences of the predicted DDs (base 2 km
    away; the base's satellite states those of a slightly earlier transmit time)."""
    p = _point()
    t = 100.004
    r_s = np.array([ts.sat_ecef(t, k) for k in range(24)])
    v_s = np.array([(ts.sat_ecef(t + 0.01, k) - ts.sat_ecef(t - 0.01, k)) / 0.02
                    for k in range(24)])
    r_b = earth.lla_to_ecef(np.deg2rad(30.51), np.deg2rad(114.32), 30.0)
    sd_r, sd_d, H_r, H_d, el = single_difference_rows(p, r_s, v_s, r_s - 1e-4 * v_s, v_s,
                                                      r_b, t)
    up = np.flatnonzero(el > np.deg2rad(10))
    assert len(up) >= 5
    D = dd_operator(len(up), int(np.argmax(el[up])))
    steps = np.full(LAYOUT.n, 1e-4)
    steps[LAYOUT.pos], steps[LAYOUT.vel] = 1.0, 0.5
    steps[LAYOUT.lever_arm], steps[LAYOUT.time_offset] = 1e-2, 1e-3
    for j in range(LAYOUT.n):
        dx = np.zeros(LAYOUT.n)
        dx[j] = steps[j]
        a = single_difference_rows(corrected(p, dx), r_s, v_s, r_s - 1e-4 * v_s, v_s, r_b, t)
        b = single_difference_rows(corrected(p, -dx), r_s, v_s, r_s - 1e-4 * v_s, v_s, r_b, t)
        for n, H, tol in ((0, H_r, 2e-4), (1, H_d, 2e-3)):
            fd = -(D @ (a[n][up] - b[n][up])) / (2 * steps[j])
            h = D @ H[up, j]
            extra = 1.5e-5 if (n == 1 and j < 3) else 0.0     # as in test_tight
            np.testing.assert_allclose(fd, h, atol=tol * (np.max(np.abs(h)) + 1e-9) + 2e-7
                                       + extra, err_msg=f"{n} {LAYOUT.names[j]}")


def _screen_case(k, blunder_on=None, seed=0):
    rng = np.random.default_rng(seed)
    H = np.column_stack([rng.normal(size=(k, 3)), np.zeros((k, 2))])
    H /= np.linalg.norm(H, axis=1, keepdims=True)
    var = rng.uniform(0.5, 2.0, k)
    P = np.diag([0.3, 0.3, 0.5, 1e-2, 1e-2])
    z = rng.normal(0.0, np.sqrt(var)) * 0.3 + H @ rng.normal(0.0, 0.2, 5)
    if blunder_on is not None:
        z[blunder_on] += 40.0
    return z, H, var, P


@pytest.mark.parametrize("bad", [0, 2, 5])
def test_a_bad_satellite_is_rejected_alone(bad):
    """A 40 m blunder on one of 7 satellites (the reference 2 among them): that
    satellite is dropped and no other; the reference moves to the highest remaining."""
    z, H, var, P = _screen_case(7, bad)
    el = np.linspace(0.3, 1.2, 7)[::-1]           # satellite 0 the highest
    thr = 10.83                                    # chi2(1) at 0.001
    kept, ref, rejected = screen(z, H, var, P, 2, thr, el)
    assert [i for i, _ in rejected] == [bad]
    assert kept == [i for i in range(7) if i != bad]
    assert ref == (2 if bad != 2 else 0)
    z, H, var, P = _screen_case(7)
    kept, ref, rejected = screen(z, H, var, P, 2, thr, el)
    assert rejected == [] and len(kept) == 7 and ref == 2


def test_two_satellites_one_dd_used_or_both_dropped():
    z, H, var, P = _screen_case(2)
    kept, ref, rejected = screen(z, H, var, P, 1, 10.83)
    assert kept == [0, 1] and ref == 1 and rejected == []
    z[0] += 40.0
    kept, ref, rejected = screen(z, H, var, P, 1, 10.83)
    assert kept == [] and [i for i, _ in rejected] == [0, 1]


def test_w_test_is_chi2_of_one_dof():
    """Without a blunder each w is chi-square(1): mean 1 over many draws."""
    rng = np.random.default_rng(7)
    S = np.diag([1.0, 2.0, 0.5]) + 0.7
    L = np.linalg.cholesky(S)
    D = dd_operator(4, 1)
    w = np.array([w_test(L @ rng.normal(size=3), S, D) for _ in range(4000)])
    np.testing.assert_allclose(w.mean(axis=0), 1.0, atol=0.08)


def test_reference_kept_while_usable_then_the_highest():
    """Per constellation: the previous reference while it is above the masks, else the
    highest satellite of that constellation; changes counted."""
    from types import SimpleNamespace

    from ins.estimation.coupling.double_difference import DoubleDifferenceUpdater
    choose = DoubleDifferenceUpdater._choose_refs
    u = SimpleNamespace(_refs={}, ref_changes=0)
    assert choose(u, ["G01", "G02", "G03"], np.array([0.3, 1.2, 0.8])) == {"G": 1}
    assert choose(u, ["G01", "G02", "G03"], np.array([0.3, 0.9, 1.3])) == {"G": 1}  # kept
    assert u.ref_changes == 0
    assert choose(u, ["G01", "G02", "G03"], np.array([0.3, -np.inf, 1.3])) == {"G": 2}
    assert choose(u, ["G01", "G03"], np.array([1.4, 1.3])) == {"G": 1}
    assert choose(u, ["G01", "G05"], np.array([1.4, 1.3])) == {"G": 0}              # set
    assert (u._refs["G"], u.ref_changes) == ("G01", 2)
    # a second constellation has its own reference, and a masked one none
    out = choose(u, ["G01", "E11", "E12", "R03"], np.array([1.4, 0.5, 0.9, -np.inf]))
    assert out == {"G": 0, "E": 2} and u._refs["E"] == "E12"


def _epochs(times, sats):
    k = [len(s) for s in sats]
    return RawEpochs(np.asarray(times, float), [np.asarray(s) for s in sats],
                     [np.zeros((n, 3)) for n in k], [np.zeros((n, 3)) for n in k],
                     [np.arange(n, dtype=float) for n in k], [np.zeros(n) for n in k])


def test_pairing_within_tolerance_and_header_position(tmp_path):
    from ins.common.errors import InputError
    from ins.gnss.raw_pairs import header_position, pair_epochs
    rover = _epochs([10.0, 11.0, 12.0, 13.0], [[1, 2], [1, 2, 3], [2, 3], [3]])
    base = _epochs([9.999, 11.3, 12.4, 30.0], [[2, 1], [3, 2, 1], [3], [1]])
    p = pair_epochs(rover, base, np.array([1.0, 2.0, 3.0]), tolerance_s=0.5)
    np.testing.assert_array_equal(p.base.time[:3], [9.999, 11.3, 12.4])
    assert np.isnan(p.base.time[3]) and len(p.base.sats[3]) == 0      # 17 s away
    p = pair_epochs(rover, base, np.array([1.0, 2.0, 3.0]), tolerance_s=0.35)
    assert np.isnan(p.base.time[2])                                     # 0.4 s away
    np.testing.assert_array_equal(p.base.sats[1], [3, 2, 1])
    masked = p.select(lambda i, s: s != 2)
    assert masked.base is p.base and list(masked.sats[0]) == [1]
    obs = tmp_path / "b.obs"
    obs.write_text(" " * 60 + "RINEX VERSION / TYPE\n"
                   + "  -3978242.4348  3382841.1715  3649902.7667"
                   + " " * 18 + "APPROX POSITION XYZ\n" + " " * 60 + "END OF HEADER\n")
    np.testing.assert_allclose(header_position(obs), [-3978242.4348, 3382841.1715,
                                                      3649902.7667])
    obs.write_text(" " * 60 + "END OF HEADER\n")
    with pytest.raises(InputError, match=r"b\.obs.*base_lla_deg"):
        header_position(obs)


# ---------------------------------------------------------------------------------------
# the raw-simulated flight (RINEX through RTKLIB)

def _needs_real():
    pytest.importorskip("pyrtklib5")
    if not PAIR.is_dir():
        pytest.skip("../shared/real is absent")


@pytest.fixture(scope="module")
def dd_flight(tmp_path_factory):
    _needs_real()
    from ins.cli.main import main
    out = tmp_path_factory.mktemp("dd") / "flight"
    rc = main(["simulate", str(ROOT / "data" / "flights" / "rawsim_dd.toml"), "-o", str(out),
               "--gnss-raw", str(PAIR / "07590920.05n"), "--seed", "1", "-q"])
    assert rc in (0, None)
    return out


def _process(folder, base):
    from ins.estimation.pipeline.process import process
    from ins.estimation.pipeline.config import config_from_manifest
    from ins.estimation.pipeline.gnss_source import RawGnss
    from ins.gnss.rtklib_options import RtklibOptions
    cfg = config_from_manifest(str(folder))
    cfg.gnss = None
    cfg.gnss_raw = RawGnss(rover=str(folder / "rover.obs"), nav=(str(folder / "rover.nav"),),
                           base=base, options=RtklibOptions(
                               mode="single", systems=("gps",), frequencies=1,
                               elevation_mask_deg=10.0))
    cfg.coupling = "tight"
    cfg.carrier_phase = False       # the code and Doppler DDs (carrier: test_carrier_phase)
    # DD against single point under the same fixed weights (the simulation's white 0.3 m):
    # the fitted noise ([gnss] range_noise = "auto") makes the single-point run's one
    # satellite far more useful than the DD run's free inertial; tests/test_range_noise.py
    cfg.range_noise, cfg.robust_weighting = "fixed", False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return process(cfg, accept_poor=True), cfg


@pytest.fixture(scope="module")
def dd_runs(dd_flight):
    """Tight single-point and tight DD runs of the flight: ``(spp, dd, dd_cfg)``."""
    spp, _ = _process(dd_flight, None)
    dd, cfg = _process(dd_flight, str(dd_flight / "base.obs"))
    return spp, dd, cfg


def test_dd_beats_single_point_on_the_simulated_flight(dd_flight, dd_runs, capsys):
    import tomllib

    from ins.cli.process_summary import summary
    from ins.io.navfiles import read_nav
    folder = dd_flight
    man = tomllib.loads((folder / "manifest.toml").read_text())
    t0 = man["flight"]["start_time_s"]
    masks = man["gnss_raw"]["masks"]
    truth = read_nav(str(folder / "truth.nav"))
    spp, dd, cfg = dd_runs
    err = {}
    for name, res in (("spp", spp), ("dd", dd)):
        for kind, traj in (("fwd", res.forward), ("smo", res.smoothed)):
            j = np.clip(np.searchsorted(truth.time, traj.time - 1e-6), 0, len(truth.time) - 1)
            d = earth.ned_offset(truth.lla[j], traj.lla)
            h = np.hypot(d[:, 0], d[:, 1])
            ends = [h[np.argmin(np.abs(traj.time - (t0 + a + b - 1.0)))] for a, b, _ in masks]
            err[name, kind] = (np.sqrt(np.mean(h ** 2)), np.sqrt(np.mean(d[:, 2] ** 2)), ends)
    # smoothed: horizontal and vertical RMS (the ionosphere's residual is a height error
    # of metres for a single receiver), and at the end of every mask
    assert err["dd", "smo"][0] <= err["spp", "smo"][0], err
    assert err["dd", "smo"][1] < 0.3 * err["spp", "smo"][1], err
    assert all(a <= b for a, b in zip(err["dd", "smo"][2], err["spp", "smo"][2])), err
    # forward, at the ends of the 3- and 2-satellite masks (2 and 1 DDs); with one
    # satellite there is no DD: free inertial, near the single-point run's one satellite
    f_dd, f_spp = err["dd", "fwd"][2], err["spp", "fwd"][2]
    assert f_dd[0] <= f_spp[0] and f_dd[1] <= 1.05 * f_spp[1], err
    assert f_dd[2] < 1.3 * f_spp[2], err
    # the DDs of 3 and 2 common satellites are used; none with one
    up = dd.fwd.updater
    for (a, b, n), want in zip(masks, (3, 2, 0)):
        used = [ep.used for ep in up.epochs if t0 + a + 1 < ep.time < t0 + a + b - 1]
        assert used and set(used) == {want}, (n, used)
    assert dd.fwd.layout.clock is None and spp.fwd.layout.clock is not None
    c = dd.counts
    assert c["base"] == "base.obs" and c["satellites_min"] == 0
    summary(dd, cfg, [], 1.0, 1.0)
    assert "tight coupling (double differences against base.obs)" in capsys.readouterr().out



def test_satellite_residuals_plot_of_double_differences(dd_runs, tmp_path):
    """satellite_residuals.png with the DD records: one series per pair, the satellites
    used (the reference counted) as the updater counted them."""
    from ins.estimation.pipeline.plots import plot_satellite_residuals, satellites_used
    _, dd, _ = dd_runs
    path = plot_satellite_residuals(dd, str(tmp_path / "sat.png"))
    assert path and (tmp_path / "sat.png").stat().st_size > 10_000
    used = satellites_used(dd.fwd.records)
    want = {ep.time: ep.used for ep in dd.fwd.updater.epochs if ep.used}
    assert want and {t: n for t, n in used.items() if n} == want


def test_a_bad_satellite_is_rejected_alone_in_the_filter(dd_flight, dd_runs, monkeypatch):
    """60 m on the rover's pseudorange of the reference satellite at one epoch and of
    another satellite at a later one: each is dropped alone at its epoch (the other
    DDs used, the reference moved), every other epoch as in the clean run."""
    from ins.gnss import raw_pairs
    _, clean, _ = dd_runs
    up0 = clean.fwd.updater
    e1 = int(np.argmin(np.abs(np.array([ep.time for ep in up0.epochs]) - up0.epochs[0].time
                              - 90.0)))
    e2 = e1 + 7
    bad1 = up0.reference[e1]
    bad2 = next(n for n in clean_names(up0, e2) if n != up0.reference[e2])
    t1, t2 = up0.epochs[e1].time, up0.epochs[e2].time
    read = raw_pairs.read_pair

    def blunder(*a, **k):
        p = read(*a, **k)
        for t, name in ((t1, bad1), (t2, bad2)):
            i = int(np.argmin(np.abs(p.time - t)))
            p.range_m[i] = p.range_m[i].copy()
            p.range_m[i][p.names[i].index(name)] += 60.0
        return p
    monkeypatch.setattr(raw_pairs, "read_pair", blunder)
    res, _ = _process(dd_flight, str(dd_flight / "base.obs"))
    up = res.fwd.updater
    for e, t, name in ((e1, t1, bad1), (e2, t2, bad2)):
        recs = [r for r in up.records if r.time == t and r.name == "dd_pseudorange"]
        assert [r.axes for r in recs if not r.accepted] == [(name,)], recs
        ok = [r for r in recs if r.accepted]
        assert len(ok) == up0.epochs[e].used - 2
        assert all(name not in r.axes[0].split("-") for r in ok)      # "G07-G28": DD, ref
        assert up.epochs[e].used == up0.epochs[e].used - 1
    assert up.reference[e1] != bad1
    n_bad = sum(not r.accepted for r in up.records)
    assert n_bad == sum(not r.accepted for r in up0.records) + 2


def test_base_without_doppler_keeps_the_range_rates(dd_flight, dd_runs, monkeypatch):
    """The base's Doppler removed (a reference station's RINEX 2 often has none): the
    rover's range rates are still used (between satellites), the smoothed solution as
    good as with the base's Doppler."""
    from ins.gnss import raw_pairs
    from ins.io.navfiles import read_nav
    _, clean, _ = dd_runs
    read = raw_pairs.read_pair

    def no_doppler(*a, **k):
        p = read(*a, **k)
        p.base.range_rate_mps = [np.full(len(v), np.nan) for v in p.base.range_rate_mps]
        return p
    monkeypatch.setattr(raw_pairs, "read_pair", no_doppler)
    res, _ = _process(dd_flight, str(dd_flight / "base.obs"))
    n = {r: sum(x.name == "dd_range_rate" and x.accepted for x in u.records)
         for r, u in (("clean", clean.fwd.updater), ("none", res.fwd.updater))}
    assert n["none"] >= 0.99 * n["clean"] > 500, n
    truth = read_nav(str(dd_flight / "truth.nav"))
    rms = []
    for r in (clean, res):
        j = np.clip(np.searchsorted(truth.time, r.smoothed.time - 1e-6), 0, len(truth.time) - 1)
        d = earth.ned_offset(truth.lla[j], r.smoothed.lla)
        rms.append(np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2)))
    assert rms[1] < 1.2 * rms[0], rms


def clean_names(updater, e):
    """Satellites of epoch ``e`` in the accepted pseudorange DDs."""
    t = updater.epochs[e].time
    return sorted({a for r in updater.records if r.time == t and r.accepted
                   and r.name == "dd_pseudorange" for a in r.axes[0].split("-")})


# ---------------------------------------------------------------------------------------
# the GEONET static pair (0759 rover, 3040 base, 3.3 km)

def test_static_pair_dd_residuals_at_code_noise(tmp_path):
    """DD pseudorange residuals of the real pair from RTKLIB's static fixed rover
    position (the base at its header): decimetres to a metre (C/A code noise and
    multipath of both receivers; these RINEX 2 files have no Doppler), well below the
    rover's own residuals (bench/bench_dd_static_pair.py prints the figures)."""
    _needs_real()
    import pymap3d

    from ins.estimation.coupling.pseudorange import line_of_sight, sagnac_range
    from ins.gnss.raw_pairs import read_pair
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    rover, base, nav = (PAIR / n for n in ("07590920.05o", "30400920.05o", "07590920.05n"))
    st = solve(str(rover), str(nav), str(tmp_path / "static.pos"), base=str(base),
               options=RtklibOptions(systems=("gps",), mode="static", direction="forward"))
    r_r = earth.lla_to_ecef(*st.log.lla[-1])
    pairs = read_pair(rover, base, nav, r_r)
    assert np.linalg.norm(r_r - pairs.base.r_e) == pytest.approx(3335.39, abs=0.05)
    lla = np.array(pymap3d.ecef2geodetic(*r_r, deg=False))
    res_r, und, n_dd = [], [], []
    for k in range(len(pairs)):
        sb = list(pairs.base.sats[k])
        i = [n for n, s in enumerate(pairs.sats[k]) if s in sb]
        j = [sb.index(pairs.sats[k][n]) for n in i]
        if len(i) < 2:
            continue
        rs, rsb = pairs.sat_pos_e[k][i], pairs.base.sat_pos_e[k][j]
        u = pairs.range_m[k][i] - sagnac_range(rs, r_r)
        und.append(u - np.median(u))
        sd = u - (pairs.base.range_m[k][j] - sagnac_range(rsb, pairs.base.r_e))
        ref = int(np.argmax(line_of_sight(rs, lla)[1]))          # the highest
        res_r.append(dd_operator(len(i), ref) @ sd)
        n_dd.append(len(i) - 1)
    res_r = np.concatenate(res_r)
    rms = float(np.sqrt(np.mean(res_r ** 2)))
    assert min(n_dd) >= 4 and len(n_dd) >= 100
    assert 0.1 < rms < 0.8, rms                              # 0.48 m
    assert np.max(np.abs(res_r)) < 5.0                       # 2.8 m
    # the rover alone after one clock per epoch (orbits, satellite clocks, Klobuchar and
    # Saastamoinen residuals left): 1.46 m
    assert rms < 0.5 * np.sqrt(np.mean(np.concatenate(und) ** 2))


def test_static_position_of_the_real_base():
    """``base_position = "single"``: the base's least-squares position from its own
    pseudoranges, started 400 m off, lands within metres of its GEONET coordinates."""
    _needs_real()
    from ins.gnss.raw_epochs import read_raw_epochs
    from ins.gnss.raw_pairs import header_position, static_position
    base = PAIR / "30400920.05o"
    hdr = header_position(base)
    ep = read_raw_epochs(base, PAIR / "07590920.05n", hdr)
    x = static_position(ep, hdr + np.array([300.0, -200.0, 100.0]))
    assert np.linalg.norm(x - hdr) < 3.0                     # 1.8 m


def test_ubx_rover_pairs_like_its_rinex(tmp_path):
    """Tight DD with a u-blox rover log: converted on the way, the same pairs as its
    RINEX (the pair's rover encoded as RXM-RAWX, tests/ubx_frames.py)."""
    _needs_real()
    from ubx_frames import rinex2_to_ubx

    from ins.estimation.pipeline.gnss_source import RawGnss
    from ins.estimation.pipeline.tight import _read
    rover, base, nav = (PAIR / n for n in ("07590920.05o", "30400920.05o", "07590920.05n"))
    hdr = np.array([-3976219.5082, 3382372.5671, 3652512.9849])
    (tmp_path / "rover.ubx").write_bytes(rinex2_to_ubx(str(rover)))
    a = _read(RawGnss(rover=str(rover), base=str(base), nav=(str(nav),)), lambda t: hdr)
    b = _read(RawGnss(rover=str(tmp_path / "rover.ubx"), base=str(base), nav=(str(nav),)),
              lambda t: hdr)
    assert len(a) == len(b) == 120
    np.testing.assert_array_equal(a.base.time, b.base.time)
    for k in range(len(a)):
        np.testing.assert_array_equal(a.sats[k], b.sats[k])
        np.testing.assert_allclose(a.range_m[k], b.range_m[k], atol=1e-3)
        np.testing.assert_array_equal(a.base.range_m[k], b.base.range_m[k])
