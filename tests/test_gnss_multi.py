"""Multi-constellation, multi-frequency raw observations (ins.simulate.gnss_multi) against
independent oracles: RTKLIB (pyrtklib5: readrnx, satpos/satposs, geodist, ionmodel,
tropmodel, sat2freq, single-point positioning) on the written RINEX files, the two-body
closed form for the GLONASS equations, the leap-second table, and the geometry.  The
simulator is never tested against itself."""
import warnings
from pathlib import Path

import numpy as np
import pytest

from ins.common.errors import InputError
from ins.simulate.gps_orbit import C_LIGHT

ROOT = Path(__file__).resolve().parents[1]
NAV = ROOT.parent / "shared" / "real" / "slac_cors_2021" / "brdc1180.21n"
WEEK = 2155
T0 = 325800.0                                  # 2021-04-28 18:30 GPS, inside the brdc file
ALL = ("G", "R", "E", "C")
SIGNALS = ("L1", "L2", "L5", "G1", "G2", "E1", "E5a", "B1I", "B2a", "B3I")
LLA = np.array([np.deg2rad(35.17), np.deg2rad(139.60), 60.0])   # sees the BeiDou GEOs
QUIET = dict(sigma_code_m=0.0, sigma_phase_m=0.0, sigma_doppler_hz=0.0, multipath_code_m=0.0,
             multipath_phase_m=0.0, clock_bias_noise=0.0, clock_drift_noise=0.0)
RSYS = {"G": "SYS_GPS", "R": "SYS_GLO", "E": "SYS_GAL", "C": "SYS_CMP"}
needs_nav = pytest.mark.skipif(not NAV.is_file(), reason="../shared/real is absent")


def _rtk():
    return pytest.importorskip("pyrtklib5")


def _read(rtk, *paths):
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    for p in paths:
        assert rtk.readrnx(str(p), 1, "", obs, nav, sta) == 1
    return obs, nav


def _arr(rtk, values):
    a = rtk.Arr1Ddouble(len(values))
    for i, v in enumerate(values):
        a[i] = float(v)
    return a


@pytest.fixture(scope="module")
def quiet(tmp_path_factory):
    """A static receiver, every system and signal, no noise: 20 min at 30 s, written."""
    if not NAV.is_file():
        pytest.skip("../shared/real is absent")
    from ins.nav.earth import lla_to_ecef
    from ins.simulate.gnss_multi import simulate_multi
    from ins.simulate.gnss_multi_product import build_orbits
    from ins.simulate.gnss_raw import RawSettings
    from ins.simulate.rinex_mixed import write_mixed_nav, write_mixed_obs
    xyz = lla_to_ecef(*LLA)
    settings = RawSettings(nav_file=str(NAV), systems=ALL, signals=SIGNALS, **QUIET)
    time = T0 + np.arange(0.0, 1201.0, 30.0)
    orbits, rec = build_orbits(settings, WEEK, time[0] - 1, time[-1] + 1)

    def receiver(t):
        return np.tile(LLA, (len(t), 1)), np.tile(xyz, (len(t), 1))
    obs = simulate_multi(orbits, WEEK, time, receiver, settings, np.random.default_rng(1))
    d = tmp_path_factory.mktemp("multi")
    ch = {p: orbits.channel(f"R{p:02d}") for p in orbits.by_system["R"].prns}
    write_mixed_obs(d / "q.obs", obs, ch, xyz, 30.0, "Q", leap_seconds=rec["leap"])
    write_mixed_nav(d / "q.nav", gps=rec["gps"], kepler=rec["kepler"], glonass=rec["glonass"],
                    ion_alpha=rec["alpha"], ion_beta=rec["beta"], leap_seconds=rec["leap"])
    return obs, orbits, rec, d, xyz


# ---------------------------------------------------------------------------------------
# orbits and clocks

@needs_nav
@pytest.mark.parametrize("system,pos_tol", [("G", 1e-3), ("E", 1e-3), ("C", 1e-3),
                                            ("R", 0.05)])
def test_orbits_and_clocks_against_rtklib(quiet, system, pos_tol):
    """The simulator's satellites (position, velocity, clock, clock rate) against RTKLIB's
    satpos on the written navigation file, every satellite every 5 min over the span:
    Kepler systems within 1 mm, GLONASS (two RK4 integrations of different steps) 5 cm."""
    rtk = _rtk()
    _, orbits, _, d, _ = quiet
    _, nav = _read(rtk, d / "q.nav")
    worst, n = np.zeros(4), 0
    for prn in orbits.by_system[system].prns:
        sat = f"{system}{prn:02d}"
        for ts in T0 + np.arange(0.0, 1201.0, 300.0) + 0.37:
            r, v, dt, ddt = orbits.state(sat, WEEK, [ts])
            tgd = orbits.tgd(sat, WEEK, [ts])[0]
            t = rtk.gpst2time(WEEK, ts)
            rs, dts, var, svh = (rtk.Arr1Ddouble(6), rtk.Arr1Ddouble(2), rtk.Arr1Ddouble(1),
                                 rtk.Arr1Dint(1))
            ok = rtk.satpos(t, t, rtk.satno(getattr(rtk, RSYS[system]), prn), rtk.EPHOPT_BRDC,
                            nav, rs, dts, var, svh)
            assert bool(ok) == bool(np.isfinite(r[0, 0])), (sat, ts)
            if not ok:
                continue
            worst = np.maximum(worst, [np.max(np.abs(r[0] - [rs[i] for i in range(3)])),
                                       np.max(np.abs(v[0] - [rs[i] for i in range(3, 6)])),
                                       C_LIGHT * abs(dt[0] + tgd - dts[0]),
                                       C_LIGHT * abs(ddt[0] - dts[1])])
            n += 1
    assert n >= 5 * len(orbits.by_system[system].prns) * 0.9
    assert worst[0] < pos_tol and worst[2] < 1e-3          # m
    assert worst[1] < 2e-3 and worst[3] < 1e-6             # m/s


def test_glonass_equations_without_j2_are_the_two_body_orbit(monkeypatch):
    """With J2 and the luni-solar terms zero the ICD's equations in the rotating frame are
    the two-body problem seen from the rotating Earth: the integrated state equals the
    closed-form Kepler orbit (f and g series solved exactly) rotated by w t."""
    from ins.simulate import glonass_orbit as go
    monkeypatch.setattr(go, "J2_GLO", 0.0)
    a, inc, w, mu = 25510.0e3, np.deg2rad(64.8), go.OMEGA_GLO, go.MU_GLO
    n = np.sqrt(mu / a ** 3)
    r0 = a * np.array([1.0, 0.0, 0.0])
    v0_i = a * n * np.array([0.0, np.cos(inc), np.sin(inc)])
    state0 = np.r_[r0, v0_i - np.cross([0, 0, w], r0)]
    dt = np.array([-900.0, 300.0, 900.0])
    s = go.integrate(state0, np.zeros(3), dt)
    for k, t in enumerate(dt):
        u = n * t
        r_i = a * np.array([np.cos(u), np.sin(u) * np.cos(inc), np.sin(u) * np.sin(inc)])
        c, sn = np.cos(w * t), np.sin(w * t)
        r_e = np.array([c * r_i[0] + sn * r_i[1], -sn * r_i[0] + c * r_i[1], r_i[2]])
        assert np.linalg.norm(s[k, :3] - r_e) < 1e-3


def test_glonass_j2_matches_the_secular_node_rate():
    """J2 turns the orbit's node at the classical rate -3/2 n J2 (a_e/a)^2 cos i (to a few
    percent over one orbit, the short-period terms aside)."""
    from ins.simulate import glonass_orbit as go
    a, inc, w, mu = 25510.0e3, np.deg2rad(64.8), go.OMEGA_GLO, go.MU_GLO
    n = np.sqrt(mu / a ** 3)
    period = 2 * np.pi / n
    r0 = a * np.array([1.0, 0.0, 0.0])
    v0_i = a * n * np.array([0.0, np.cos(inc), np.sin(inc)])
    s = go.integrate(np.r_[r0, v0_i - np.cross([0, 0, w], r0)], np.zeros(3), [period], 30.0)[0]
    c, sn = np.cos(w * period), np.sin(w * period)
    rot = np.array([[c, -sn, 0], [sn, c, 0], [0, 0, 1]])          # rotating -> inertial
    r_i = rot @ s[:3]
    v_i = rot @ s[3:] + np.cross([0, 0, w], r_i)
    h = np.cross(r_i, v_i)
    node = np.arctan2(h[0], -h[1])
    expected = -1.5 * n * go.J2_GLO * (go.AE_GLO / a) ** 2 * np.cos(inc) * period
    assert abs(node - expected) < 0.05 * abs(expected)


@needs_nav
def test_glonass_times_and_leap_seconds(quiet):
    """RTKLIB's toe of every GLONASS record (its UTC epoch + RTKLIB's own leap table) is
    the simulator's t_b in GPS time; the epochs are whole quarter hours of UTC; the
    leap seconds of the table at both sides of 2017-01-01 and of 2005."""
    rtk = _rtk()
    from ins.simulate.glonass_orbit import leap_seconds
    _, _, rec, d, _ = quiet
    _, nav = _read(rtk, d / "q.nav")
    assert nav.ng == len(rec["glonass"])
    tb = {(e.slot, round(e.tb)) for e in rec["glonass"]}
    week = rtk.Arr1Dint(1)
    got = set()
    for i in range(nav.ng):
        g = nav.geph[i]
        sow = rtk.time2gpst(g.toe, week)
        assert week[0] == WEEK
        prn = rtk.Arr1Dint(1)
        rtk.satsys(g.sat, prn)
        got.add((prn[0], round(sow)))
    assert got == tb
    assert leap_seconds(WEEK, T0) == 18 and leap_seconds(1316, 518400.0) == 13
    # 2016-12-31 23:59:59 UTC = GPS week 1929, 604799 + 17 - 604800 ... (day 0 of 1930)
    assert leap_seconds(1930, 16.0) == 17 and leap_seconds(1930, 18.0) == 18
    e = rec["glonass"][0]
    utc = e.tb_utc
    assert utc.minute in (15, 45) and utc.second == 0
    assert e.tb_glonass_tod == ((utc.hour + 3) % 24) * 3600 + utc.minute * 60


@needs_nav
def test_beidou_time_and_geo_satellites(quiet):
    """BeiDou records: RTKLIB's toe (GPS time) is the BDT toe + 14 s; the GEOs stay over
    their longitudes at the synchronous radius; no BeiDou before BDT week 0."""
    rtk = _rtk()
    from ins.simulate.kepler_orbit import beidou_constellation
    _, orbits, rec, d, _ = quiet
    _, nav = _read(rtk, d / "q.nav")
    week = rtk.Arr1Dint(1)
    prn = rtk.Arr1Dint(1)
    ours = {(e.prn, e.toe) for e in rec["kepler"] if e.system == "C"}
    got = set()
    for i in range(nav.n):
        if rtk.satsys(nav.eph[i].sat, prn) == rtk.SYS_CMP:
            sow = rtk.time2gpst(nav.eph[i].toe, week)
            got.add((prn[0], round(sow - 14.0 + (week[0] - WEEK) * 604800.0) % 604800))
    assert got == {(p, round(t)) for p, t in ours}
    t = T0 + np.linspace(0.0, 1200.0, 5)
    for p, lon in zip(range(1, 6), (58.75, 80.0, 110.5, 140.0, 160.0)):
        r = orbits.state(f"C{p:02d}", WEEK, t)[0]
        assert np.all(np.abs(np.rad2deg(np.arctan2(r[:, 1], r[:, 0])) - lon) < 0.2)
        assert np.all(np.abs(np.linalg.norm(r, axis=1) - 42164.2e3) < 10e3)
    with pytest.raises(InputError, match="before BDT week 0"):
        beidou_constellation(1316, 518400.0, 519000.0)


def test_generated_ephemerides_agree_where_the_selection_changes():
    """Consecutive ephemerides of a generated satellite give the same position and clock
    at the midpoint of their reference times (where the nearest-toe rule of RTKLIB and of
    the simulator changes from one to the next): no jump in the truth (< 1 mm)."""
    from ins.simulate.glonass_orbit import glonass_constellation, integrate
    from ins.simulate.kepler_orbit import (beidou_constellation, galileo_constellation,
                                           kepler_state)
    worst = 0.0
    g = glonass_constellation(WEEK, T0, T0 + 3600.0)
    for a, b in zip(g[:-1], g[1:]):
        if a.slot == b.slot:
            mid = 0.5 * (a.tb + b.tb)
            ra = integrate(np.r_[a.pos, a.vel], a.acc, [mid - a.tb])[0, :3]
            rb = integrate(np.r_[b.pos, b.vel], b.acc, [mid - b.tb])[0, :3]
            ca, cb = -a.tau_n + a.gamma_n * (mid - a.tb), -b.tau_n + b.gamma_n * (mid - b.tb)
            worst = max(worst, np.linalg.norm(ra - rb), C_LIGHT * abs(ca - cb))
    for ephs in (galileo_constellation(WEEK, T0, T0 + 3600.0),
                 beidou_constellation(WEEK, T0, T0 + 3600.0)):
        for a, b in zip(ephs[:-1], ephs[1:]):
            if a.prn == b.prn and a.week == b.week:
                mid = 0.5 * (a.toe + b.toe)
                ra, _, ca, _ = kepler_state(a, [mid])
                rb, _, cb, _ = kepler_state(b, [mid])
                worst = max(worst, np.linalg.norm(ra - rb), C_LIGHT * abs(ca - cb)[0])
    assert worst < 1e-3


def test_glonass_channel_frequencies_of_the_icd():
    """ICD table 3.1/3.2: channel -7 at 1598.0625 / 1242.9375 MHz, 0 at 1602 / 1246, 6 at
    1605.375 / 1248.625 MHz."""
    from ins.simulate.glonass_orbit import glonass_frequencies
    f1, f2 = glonass_frequencies([-7, 0, 6])
    np.testing.assert_allclose(f1, [1598.0625e6, 1602.0e6, 1605.375e6], atol=0.1)
    np.testing.assert_allclose(f2, [1242.9375e6, 1246.0e6, 1248.625e6], atol=0.1)
    np.testing.assert_allclose(f1 / f2, 9.0 / 7.0)


# ---------------------------------------------------------------------------------------
# observations

def _rtk_epochs(rtk, obs):
    """(time_rx, satellite id, {code: (P, L, D)}) of RTKLIB's reading."""
    week = rtk.Arr1Dint(1)
    prn = rtk.Arr1Dint(1)
    name = {v: k for k, v in RSYS.items()}
    out = []
    for k in range(obs.n):
        d = obs.data[k]
        sys = rtk.satsys(d.sat, prn)
        letter = next(x for x in name if getattr(rtk, x) == sys)
        sigs = {}
        for i in range(rtk.NFREQ + rtk.NEXOBS):
            if d.code[i]:
                sigs[rtk.code2obs(d.code[i])] = (d.code[i], d.P[i], d.L[i], d.D[i])
        out.append((rtk.time2gpst(d.time, week), f"{name[letter]}{prn[0]:02d}", d, sigs))
    return out


@needs_nav
def test_ranges_against_rtklib_geometry(quiet):
    """Every error-free pseudorange of every signal is RTKLIB's model of it: satposs (from
    the pseudorange's transmit time) and geodist (Sagnac) at the true antenna, the true
    receiver clock, RTKLIB's satellite clock (with GPS's tgd scaled per signal),
    Klobuchar ionmodel x (f_L1 / f)^2 and Saastamoinen tropmodel: within 5 mm."""
    rtk = _rtk()
    from ins.simulate.gnss_signals import SIGNALS as TABLE
    obs, orbits, _, d, xyz = quiet
    robs, nav = _read(rtk, d / "q.obs", d / "q.nav")
    codes = {(sy, c[2]): i for sy, v in TABLE.items() for i, c in enumerate(v)}
    rr, pos = _arr(rtk, xyz), rtk.Arr1Ddouble(3)
    rtk.ecef2pos(rr, pos)
    res, n = [], 0
    for sow, sat, dd, sigs in _rtk_epochs(rtk, robs):
        i = int(np.argmin(np.abs(obs.time_rx - sow)))
        bias = obs.clock_bias_s[i]
        rs, dts, var, svh = (rtk.Arr1Ddouble(6), rtk.Arr1Ddouble(2), rtk.Arr1Ddouble(1),
                             rtk.Arr1Dint(1))
        rtk.satposs(dd.time, dd, 1, nav, rtk.EPHOPT_BRDC, rs, dts, var, svh)
        e = rtk.Arr1Ddouble(3)
        rho = rtk.geodist(rs, rr, e)
        azel = rtk.Arr1Ddouble(2)
        rtk.satazel(pos, e, azel)
        ion = rtk.ionmodel(dd.time, _arr(rtk, (*orbits.alpha, *orbits.beta)), pos, azel)
        trop = rtk.tropmodel(dd.time, pos, azel, 0.7)
        tgd = orbits.tgd(sat, WEEK, [sow])[0]
        for code, (c, P, L, D) in sigs.items():
            f = rtk.sat2freq(dd.sat, c, nav)
            q = codes[(sat[0], code)]
            g = (77 / 60) ** 2 if (sat[0], q) == ("G", 1) else 1.0
            model = (rho + C_LIGHT * (bias - dts[0] + g * tgd) + ion * (1575.42e6 / f) ** 2
                     + trop)
            res.append(P - model)
            n += 1
    res = np.array(res)
    assert n > 1500
    assert np.max(np.abs(res)) < 5e-3


@needs_nav
def test_frequencies_and_the_ionospheric_relations(quiet):
    """Per satellite and signal: the simulator's frequency is RTKLIB's (sat2freq: the
    GLONASS channel from the navigation file); the geometry-free code P_b - P_a is RTKLIB's
    Klobuchar delay times ((f1/f_b)^2 - (f1/f_a)^2) (plus GPS's tgd difference for L2);
    carrier minus code changes along an arc by -2 times the change of the delay; the
    ionosphere-free code of GPS L1/L2 carries the broadcast dt_sv without tgd."""
    rtk = _rtk()
    obs, orbits, _, d, xyz = quiet
    robs, nav = _read(rtk, d / "q.obs", d / "q.nav")
    rr, pos = _arr(rtk, xyz), rtk.Arr1Ddouble(3)
    rtk.ecef2pos(rr, pos)
    per_sat = {}
    worst = np.zeros(4)
    for sow, sat, dd, sigs in _rtk_epochs(rtk, robs):
        rs, dts, var, svh = (rtk.Arr1Ddouble(6), rtk.Arr1Ddouble(2), rtk.Arr1Ddouble(1),
                             rtk.Arr1Dint(1))
        rtk.satposs(dd.time, dd, 1, nav, rtk.EPHOPT_BRDC, rs, dts, var, svh)
        e = rtk.Arr1Ddouble(3)
        rho = rtk.geodist(rs, rr, e)
        azel = rtk.Arr1Ddouble(2)
        rtk.satazel(pos, e, azel)
        ion = rtk.ionmodel(dd.time, _arr(rtk, (*orbits.alpha, *orbits.beta)), pos, azel)
        j = obs.sats.index(sat)
        f = {code: rtk.sat2freq(dd.sat, c, nav) for code, (c, *_) in sigs.items()}
        for q, code in enumerate(sigs):
            worst[0] = max(worst[0], abs(f[code] - obs.frequency_hz[j, q]))
        items = list(sigs.items())
        (ca, (_, Pa, La, _)), (cb, (_, Pb, Lb, _)) = items[0], items[1]
        sa, sb = (1575.42e6 / f[ca]) ** 2, (1575.42e6 / f[cb]) ** 2
        tgd = orbits.tgd(sat, WEEK, [sow])[0]
        dclk = (77 / 60) ** 2 * tgd - tgd if (sat[0], cb) == ("G", "2W") else 0.0
        worst[1] = max(worst[1], abs((Pb - Pa) - ion * (sb - sa) - C_LIGHT * dclk))
        for code, (_, P, L, _) in items:
            cmc = L * C_LIGHT / f[code] - P
            per_sat.setdefault((sat, code), []).append((cmc, ion * (1575.42e6 / f[code]) ** 2))
        if sat[0] == "G":
            fa, fb = f[ca], f[cb]
            p_if = (fa ** 2 * Pa - fb ** 2 * Pb) / (fa ** 2 - fb ** 2)
            i = int(np.argmin(np.abs(obs.time_rx - sow)))
            trop = rtk.tropmodel(dd.time, pos, azel, 0.7)
            worst[2] = max(worst[2], abs(p_if - rho - C_LIGHT * (obs.clock_bias_s[i] - dts[0])
                                         - trop))
    for rows in per_sat.values():
        rows = np.array(rows)
        worst[3] = max(worst[3], np.max(np.abs((rows[:, 0] - rows[0, 0])
                                               + 2.0 * (rows[:, 1] - rows[0, 1]))))
    assert worst[0] < 1e-3                 # Hz
    assert worst[1] < 2e-3 and worst[2] < 1e-2 and worst[3] < 2e-3       # m
    assert len({s for s, _ in per_sat}) > 30


@needs_nav
def test_doppler_is_minus_the_carrier_rate_on_every_signal(quiet):
    """-lambda_f D_f equals the rate of lambda_f L_f (central difference over +-30 s of
    the error-free carrier: the model's curvature leaves < 3 cm/s) on every signal."""
    obs, *_ = quiet
    lam = C_LIGHT / obs.frequency_hz[None, :, :]
    rng_ = obs.phase * lam
    rate = (rng_[2:] - rng_[:-2]) / 60.0
    dop = -obs.doppler[1:-1] * lam
    ok = np.isfinite(rate) & np.isfinite(dop)
    assert ok.sum() > 1000
    assert np.max(np.abs(rate[ok] - dop[ok])) < 0.03


# ---------------------------------------------------------------------------------------
# a simulated flight with every system

PLAN_EXTRA = ('systems = ["G", "R", "E", "C"]\n'
              'signals = ["L1", "L2", "L5", "G1", "G2", "E1", "E5a", "B1I", "B2a", "B3I"]\n'
              'signal_noise = { L2 = 2.0 }\n')


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    if not NAV.is_file():
        pytest.skip("../shared/real is absent")
    from test_gnss_raw import PLAN

    from ins.simulate.folder import simulate_flight
    d = tmp_path_factory.mktemp("multiflight")
    text = PLAN.format(start=T0, nav=NAV).replace("gps_week = 1316", f"gps_week = {WEEK}")
    text = text.replace("[gnss_raw]\n", "[gnss_raw]\n" + PLAN_EXTRA)
    (d / "plan.toml").write_text(text)
    return simulate_flight(d / "plan.toml", d / "flight", seed=5)


def test_flight_files_read_by_rtklib(flight):
    """rover.obs and rover.nav (mixed RINEX 3.04) are read by RTKLIB: every observation of
    the truth file is there, by system and signal, with its LLI."""
    rtk = _rtk()
    import tomllib
    m = tomllib.loads((flight / "manifest.toml").read_text())["gnss_raw"]
    assert m["systems"] == list(ALL) and m["obs_types"]["C"][:4] == ["C2I", "L2I", "D2I", "S2I"]
    assert len(m["slips_made"]) >= 6
    tr = np.genfromtxt(flight / "gnss_raw_truth.csv", delimiter=",", names=True, dtype=None,
                       encoding="ascii")
    robs, nav = _read(rtk, flight / "rover.obs", flight / "rover.nav")
    seen = {}
    for sow, sat, dd, sigs in _rtk_epochs(rtk, robs):
        for code, (c, P, L, D) in sigs.items():
            seen[(round(sow, 3), sat, code[0])] = seen.get((round(sow, 3), sat, code[0]), 0) + 1
    # RTKLIB-EX 2.5.0 (NFREQ = 3) drops BeiDou band 6 (B3I): the rest is all there
    assert sum(seen.values()) == np.count_nonzero(tr["signal"] != "B3I")
    assert np.count_nonzero(tr["signal"] == "B3I") > 100
    assert "C6I" in (flight / "rover.obs").read_text()[:4000]
    assert {s[0] for s in tr["sat"]} == set(ALL)
    assert set(np.unique(tr["lli"])) == {0, 1}
    assert nav.ng > 24 and nav.n > 100
    # every slip made: LLI on each signal of the satellite, its ambiguity up by the cycles
    for t_slip, sat, cycles in m["slips_made"]:
        now = tr[(tr["time_rx_s"] == t_slip) & (tr["sat"] == sat)]
        before = tr[(np.abs(tr["time_rx_s"] - (t_slip - 1.0)) < 1e-6) & (tr["sat"] == sat)]
        assert len(now) == len(before) >= 2 and np.all(now["lli"] == 1), sat
        np.testing.assert_array_equal(now["ambiguity_cycles"] - before["ambiguity_cycles"],
                                      cycles)


def test_flight_code_noise_of_each_signal(flight):
    """RTKLIB's reading of each pseudorange minus the truth's model of it (range, clocks,
    delays, multipath) is the white noise of 0.3 m / sin(el) times the signal's factor
    (L2: 2): unit variance, zero mean, per signal."""
    rtk = _rtk()
    from ins.simulate.gnss_signals import SIGNALS as TABLE
    tr = np.genfromtxt(flight / "gnss_raw_truth.csv", delimiter=",", names=True, dtype=None,
                       encoding="ascii")
    clock = np.loadtxt(flight / "receiver_clock.txt")
    robs, _ = _read(rtk, flight / "rover.obs")
    read = {}
    for sow, sat, dd, sigs in _rtk_epochs(rtk, robs):
        for code, (_, P, _, _) in sigs.items():
            read[(round(sow, 3), sat, code)] = P
    code_of = {(sy, n): c for sy, v in TABLE.items() for n, _, c in v}
    bias = np.interp(tr["time_rx_s"], clock[:, 0], clock[:, 2])
    model = (tr["range_m"] + C_LIGHT * bias - tr["sat_clock_m"] + tr["iono_m"] + tr["tropo_m"]
             + tr["multipath_code_m"])
    sigma = 0.3 / np.sin(np.deg2rad(tr["elevation_deg"])) * np.where(tr["signal"] == "L2", 2, 1)
    for name in ("L1", "L2", "L5", "G1", "G2", "E1", "E5a", "B1I", "B2a"):
        rows = np.flatnonzero(tr["signal"] == name)
        P = np.array([read[(round(tr["time_rx_s"][r], 3), tr["sat"][r],
                            code_of[(tr["sat"][r][0], name)])] for r in rows])
        z = (P - model[rows]) / sigma[rows]
        assert len(rows) > 200 and 0.85 < np.std(z) < 1.15 and abs(np.mean(z)) < 0.15, name


@pytest.mark.parametrize("system", ["gps", "glonass", "galileo", "beidou"])
def test_flight_single_point_positions_of_each_system_alone(flight, tmp_path, system):
    """RTKLIB's single-point solution of each constellation alone (its own orbits, clocks,
    Sagnac, Klobuchar, Saastamoinen) lands within the noise of the antenna of gnss.txt."""
    _rtk()
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.gnss import read_gnss
    from ins.nav.earth import ned_offset
    sol = solve(flight / "rover.obs", flight / "rover.nav", tmp_path / "spp.pos",
                options=RtklibOptions(mode="single", direction="forward", systems=(system,),
                                      elevation_mask_deg=10.0))
    g = read_gnss(flight / "gnss.txt")
    t, ia, ib = np.intersect1d(np.round(sol.log.time, 3), g.time, return_indices=True)
    assert len(t) > 0.7 * len(g.time)
    rms = np.sqrt(np.mean(ned_offset(g.lla[ib], sol.log.lla[ia]) ** 2, axis=0))
    assert np.all(rms[:2] < 1.5) and rms[2] < 3.0


def test_flight_truth_ranges_are_the_geometry(flight):
    """The truth's range of every system is the distance from the satellite to the
    antenna of gnss.txt (2-4 cm noise, stamped 1e-4 s apart)."""
    from ins.io.gnss import read_gnss
    from ins.nav.earth import lla_to_ecef
    tr = np.genfromtxt(flight / "gnss_raw_truth.csv", delimiter=",", names=True, dtype=None,
                       encoding="ascii")
    g = read_gnss(flight / "gnss.txt")
    k = np.searchsorted(g.time, np.round(tr["time_rx_s"]))
    ant = lla_to_ecef(g.lla[k, 0], g.lla[k, 1], g.lla[k, 2])
    sat = np.column_stack([tr["x_sat_m"], tr["y_sat_m"], tr["z_sat_m"]])
    dist = np.linalg.norm(sat - ant, axis=1)
    assert np.max(np.abs(dist - tr["range_m"])) < 0.25
    assert np.sqrt(np.mean((dist - tr["range_m"]) ** 2)) < 0.06


@pytest.fixture(scope="module")
def flight_with_base(tmp_path_factory):
    """60 s static then the strip, with a base 1.5 km away; dry air and no multipath (as
    the GPS base test of test_gnss_raw: RTKLIB's relative mode leaves the wet delay out),
    dual-frequency GPS, GLONASS, Galileo, BeiDou."""
    if not NAV.is_file():
        pytest.skip("../shared/real is absent")
    from test_gnss_raw import PLAN

    from ins.simulate.folder import simulate_flight
    d = tmp_path_factory.mktemp("multibase")
    text = PLAN.format(start=T0, nav=NAV).replace("gps_week = 1316", f"gps_week = {WEEK}")
    text = text.replace("masks = [[40.0, 10.0, 3]]\n", "")
    text = text.replace("stationary_s = 20.0", "stationary_s = 60.0")
    text = text.replace("[gnss_raw]\n", '[gnss_raw]\nhumidity_percent = 0.0\n'
                        'multipath_code_m = 0.0\nmultipath_phase_m = 0.0\n'
                        'base_lla_deg = [35.165, 139.61, 62.0]\n'
                        'systems = ["G", "R", "E", "C"]\n'
                        'signals = ["L1", "L2", "G1", "G2", "E1", "E5a", "B1I", "B2a"]\n')
    (d / "plan.toml").write_text(text)
    return simulate_flight(d / "plan.toml", d / "flight", seed=8)


def test_multi_gnss_rtk_fixes_fast_to_the_truth(flight_with_base, tmp_path):
    """RTKLIB's kinematic RTK on every system and frequency (RTKLIB's index 3 holds E5a
    and B2a) with the simulated base: fixed within seconds (GPS L1 alone takes about 45 s
    here), the fixes within the 2-4 cm noise of gnss.txt."""
    _rtk()
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.gnss import read_gnss
    from ins.nav.earth import ned_offset
    f = flight_with_base
    with warnings.catch_warnings():       # RTKLIB's sigma columns in kinematic mode
        warnings.simplefilter("ignore")
        sol = solve(f / "rover.obs", f / "rover.nav", tmp_path / "rtk.pos", base=f / "base.obs",
                    options=RtklibOptions(mode="kinematic", direction="forward",
                                          systems=("gps", "glonass", "galileo", "beidou"),
                                          frequencies=3, elevation_mask_deg=10.0))
    g = read_gnss(f / "gnss.txt")
    t, ia, ib = np.intersect1d(np.round(sol.log.time, 3), g.time, return_indices=True)
    fixed = sol.log.quality[ia] == 1
    assert fixed.mean() > 0.8 and np.argmax(fixed) < 15
    d = ned_offset(g.lla[ib[fixed]], sol.log.lla[ia[fixed]])
    rms = np.sqrt(np.mean(d ** 2, axis=0))
    assert np.all(rms < [0.04, 0.04, 0.07]), rms


def test_without_gps_no_navigation_file_is_needed():
    """Galileo alone needs no navigation file (RTKLIB's default Klobuchar coefficients);
    GPS without one is refused naming the key."""
    from ins.simulate.gnss_multi_product import KLOBUCHAR_DEFAULT, build_orbits
    from ins.simulate.gnss_raw import RawSettings
    orbits, rec = build_orbits(RawSettings(systems=("E",)), WEEK, T0, T0 + 60.0)
    assert orbits.alpha == KLOBUCHAR_DEFAULT[0] and rec["gps"] == [] and len(orbits.sats) == 24
    with pytest.raises(InputError, match="nav_file"):
        build_orbits(RawSettings(systems=("G", "E")), WEEK, T0, T0 + 60.0)


# ---------------------------------------------------------------------------------------
# plan keys

@pytest.mark.parametrize("line,message", [
    ('systems = ["G", "X"]', r"\[gnss_raw\] systems"),
    ('systems = "G"', r"\[gnss_raw\] systems"),
    ('signals = ["L7"]', r"\[gnss_raw\] signals"),
    ("beidou_geo = 1", r"\[gnss_raw\] beidou_geo"),
    ("signal_noise = { L9 = 2.0 }", r"\[gnss_raw\] signal_noise"),
    ("signal_noise = { L2 = 0.0 }", r"\[gnss_raw\] signal_noise"),
])
def test_plan_multi_keys_errors(tmp_path, line, message):
    from test_gnss_raw import PLAN

    from ins.simulate.plan_read import load_plan
    p = tmp_path / "plan.toml"
    p.write_text(PLAN.format(start=T0, nav=NAV).replace("[gnss_raw]\n", f"[gnss_raw]\n{line}\n"))
    with pytest.raises(InputError, match=message):
        load_plan(p)


def test_plan_multi_keys_read(tmp_path):
    from test_gnss_raw import PLAN

    from ins.simulate.plan_read import load_plan
    p = tmp_path / "plan.toml"
    p.write_text(PLAN.format(start=T0, nav=NAV).replace(
        "[gnss_raw]\n", '[gnss_raw]\nsystems = ["E", "R"]\nsignals = ["E5a"]\n'
                        "beidou_geo = false\nsignal_noise = { E5a = 2.5 }\n"))
    raw = load_plan(p).gnss_raw
    assert raw.systems == ("E", "R") and raw.signals == ("E5a",) and raw.multi
    assert not raw.beidou_geo and raw.signal_noise == (("E5a", 2.5),)
    from ins.simulate.gnss_signals import signal_table
    assert signal_table(raw.systems, raw.signals) == {"E": (1,), "R": (0,)}
