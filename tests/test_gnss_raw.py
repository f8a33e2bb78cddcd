"""Raw GPS observations of the simulator (ins.simulate.gnss_raw and its files) against
independent truths: the broadcast orbit, the Klobuchar and Saastamoinen delays against
RTKLIB's (pyrtklib5, an oracle only: the simulator does not use it); light time and
Sagnac against the closed-form range to a satellite moving uniformly in inertial space;
the RINEX 3.04 writer read back by RTKLIB's readrnx; masks, cycle slips and the Doppler
against the carrier's time differences; and a whole simulated flight solved by RTKLIB's
single-point positioning against the antenna's truth.  Skipped without
../shared/real/rtklib_static_pair (the real broadcast orbits)."""
from pathlib import Path

import numpy as np
import pytest

from ins.common.errors import InputError
from ins.simulate.gnss_raw import (
    L1_WAVELENGTH,
    RawSettings,
    az_el,
    dops,
    klobuchar,
    light_time,
    saastamoinen,
    simulate_raw,
)
from ins.simulate.gps_orbit import C_LIGHT, OMEGA_E_GPS

ROOT = Path(__file__).resolve().parents[1]
PAIR = ROOT.parent / "shared" / "real" / "rtklib_static_pair"
NAV = PAIR / "07590920.05n"
needs_nav = pytest.mark.skipif(not NAV.is_file(), reason="../shared/real is absent")
WEEK = 1316
T0 = 518400.0 + 600.0                       # 2005-04-02 00:10 GPS
#: The GEONET station 0759 (RINEX header), ECEF m.
STATION = np.array([-3976219.5082, 3382372.5671, 3652512.9849])
QUIET = dict(sigma_code_m=0.0, sigma_phase_m=0.0, sigma_doppler_hz=0.0, multipath_code_m=0.0,
             multipath_phase_m=0.0, clock_bias_noise=0.0, clock_drift_noise=0.0)


def _station_lla():
    import pymap3d
    return np.array(pymap3d.ecef2geodetic(*STATION, deg=False))


def _static(lla, xyz):
    def receiver(t):
        return np.tile(lla, (len(t), 1)), np.tile(xyz, (len(t), 1))
    return receiver


@pytest.fixture(scope="module")
def orbits():
    if not NAV.is_file():
        pytest.skip("../shared/real is absent")
    from ins.io.rinex_nav import read_gps_nav
    from ins.simulate.gps_orbit import BroadcastOrbits
    return BroadcastOrbits(read_gps_nav(NAV))


@pytest.fixture(scope="module")
def rtk_nav():
    rtk = pytest.importorskip("pyrtklib5")
    if not NAV.is_file():
        pytest.skip("../shared/real is absent")
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    assert rtk.readrnx(str(NAV), 1, "", obs, nav, sta) == 1
    return rtk, nav


# ---------------------------------------------------------------------------------------
# orbits, delays

def test_nav_header_and_records(orbits):
    nav = orbits.nav
    assert nav.ion_alpha == (1.118e-08, 1.49e-08, -5.96e-08, -5.96e-08)
    assert nav.ion_beta == (88060.0, 16380.0, -196600.0, -131100.0)
    assert nav.leap_seconds == 13 and len(nav.ephemerides) == 162
    e = nav.ephemerides[0]          # PRN 1, 2005-04-02 02:00:00 = 525600 s of week 1316
    assert (e.prn, e.toc_week, e.toc, e.toe, e.week, e.iodc) == (1, 1316, 525600.0, 525600.0,
                                                                 1316, 396)
    assert e.sqrt_a == 5153.63647842 and e.tgd == -3.25962901115e-09


def test_orbit_and_clock_against_rtklib(orbits, rtk_nav):
    """Position and clock within 1 mm (clock in m) of RTKLIB's satpos at every healthy
    satellite over the first hour; velocity within 1 mm/s (RTKLIB differentiates
    numerically over 1 ms)."""
    rtk, nav = rtk_nav
    worst = np.zeros(4)
    n = 0
    for prn in orbits.prns:
        for ts in np.arange(518400.0, 522000.0, 450.0):
            r, v, dt, ddt = orbits.state(prn, WEEK, [ts])
            t = rtk.gpst2time(WEEK, ts)
            rs, dts, var, svh = (rtk.Arr1Ddouble(6), rtk.Arr1Ddouble(2), rtk.Arr1Ddouble(1),
                                 rtk.Arr1Dint(1))
            ok = rtk.satpos(t, t, prn, rtk.EPHOPT_BRDC, nav, rs, dts, var, svh)
            assert bool(ok) == bool(np.isfinite(r[0, 0])), (prn, ts)
            if not ok:
                continue
            eph = orbits.select(prn, WEEK, [ts])
            tgd = eph[0][eph[1][0]].tgd
            worst = np.maximum(worst, [
                np.max(np.abs(r[0] - [rs[i] for i in range(3)])),
                np.max(np.abs(v[0] - [rs[i] for i in range(3, 6)])),
                C_LIGHT * abs(dt[0] + tgd - dts[0]), C_LIGHT * abs(ddt[0] - dts[1])])
            n += 1
    assert n > 100
    assert worst[0] < 1e-3 and worst[2] < 1e-3          # m
    assert worst[1] < 1e-3 and worst[3] < 1e-6          # m/s


def test_velocity_is_the_derivative_of_the_position(orbits):
    t = T0 + np.array([-0.01, 0.0, 0.01])
    for prn in orbits.prns[:6]:
        r, v, dt, ddt = orbits.state(prn, WEEK, t)
        if not np.all(np.isfinite(r)):
            continue
        np.testing.assert_allclose((r[2] - r[0]) / 0.02, v[1], atol=2e-5)
        assert abs((dt[2] - dt[0]) / 0.02 - ddt[1]) < 1e-14


def test_klobuchar_and_saastamoinen_against_rtklib(rtk_nav):
    rtk, nav = rtk_nav
    lla = _station_lla()
    ion = [nav.ion_gps[i] for i in range(8)]
    rng = np.random.default_rng(3)
    for _ in range(40):
        az, el = rng.uniform(0, 2 * np.pi), rng.uniform(np.deg2rad(5), np.pi / 2)
        ts = rng.uniform(0, 604800)
        h = rng.uniform(0, 8000)
        pos = rtk.Arr1Ddouble(3)
        for i, x in enumerate((lla[0], lla[1], h)):
            pos[i] = x
        azel = rtk.Arr1Ddouble(2)
        azel[0], azel[1] = az, el
        ionp = rtk.Arr1Ddouble(8)
        for i, x in enumerate(ion):
            ionp[i] = x
        t = rtk.gpst2time(WEEK, ts)
        ref_i = rtk.ionmodel(t, ionp, pos, azel)
        ref_t = rtk.tropmodel(t, pos, azel, 0.7)
        assert klobuchar(lla[0], lla[1], az, el, ts, ion[:4], ion[4:]) == \
            pytest.approx(ref_i, abs=1e-6)
        assert saastamoinen(lla[0], h, el, 0.7) == pytest.approx(ref_t, abs=1e-6)


# ---------------------------------------------------------------------------------------
# light time and Sagnac: a satellite moving uniformly in inertial space

def test_light_time_and_sagnac_closed_form():
    """Inertial frame = ECEF at t = 0.  The satellite at ``s0 + v t`` (inertial) is seen in
    ECEF at ``Rz(w t) (s0 + v t)``; the receiver fixed in ECEF is at ``Rz(w t)^T r`` in
    inertial space.  The light time solves ``|s0 + v (t - tau) - p| = c tau`` (a
    quadratic): the range of :func:`light_time` must be ``c tau``."""
    w = OMEGA_E_GPS

    def Rz(th):
        c, s = np.cos(th), np.sin(th)
        return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])

    s0 = np.array([15e6, -12e6, 18e6])
    vel = np.array([-2500.0, 3100.0, 900.0])

    def sat(t_tx):
        return np.array([Rz(w * tt) @ (s0 + vel * tt) for tt in t_tx]), np.zeros(len(t_tx))

    t = np.array([0.0, 100.0, 3000.0])
    r_rx = np.tile(STATION, (3, 1))
    rho, r_sat, _ = light_time(sat, t, r_rx)
    for k, tk in enumerate(t):
        a = s0 + vel * tk - Rz(w * tk).T @ STATION
        A, B, C = vel @ vel - C_LIGHT ** 2, -2.0 * (a @ vel), a @ a
        tau = (-B - np.sqrt(B * B - 4 * A * C)) / (2 * A)
        assert rho[k] == pytest.approx(C_LIGHT * tau, abs=1e-6)
        # the satellite at transmit time in the ECEF frame at reception
        np.testing.assert_allclose(r_sat[k], Rz(w * tk) @ (s0 + vel * (tk - tau)), atol=1e-6)
    # without the rotation during the light time the range is off by metres here
    naive = np.linalg.norm(sat(t - rho / C_LIGHT)[0] - r_rx, axis=1)
    assert np.max(np.abs(naive - rho)) > 0.5


def test_dops_of_a_symmetric_constellation():
    """Zenith + three at elevation 0, 120 deg apart: closed form of (H^T H)^-1."""
    d = dops([0.0, 0.0, 2 * np.pi / 3, 4 * np.pi / 3], [np.pi / 2, 0.0, 0.0, 0.0])
    # H^T H = diag(1.5, 1.5, .) in N, E; up/clock block [[1, 1], [1, 4]] -> inv diag 4/3, 1/3
    assert d["hdop"] == pytest.approx(np.sqrt(2 / 1.5))
    assert d["vdop"] == pytest.approx(np.sqrt(4 / 3))
    assert d["tdop"] == pytest.approx(np.sqrt(1 / 3))
    assert np.isnan(dops([0.0, 1.0, 2.0], [1.0, 1.0, 1.0])["pdop"])


# ---------------------------------------------------------------------------------------
# the observations of a static receiver at the station

def _simulate(orbits, settings, n=600, seed=1):
    lla = _station_lla()
    return simulate_raw(orbits, WEEK, T0 + np.arange(n, dtype=float), _static(lla, STATION),
                        settings, np.random.default_rng(seed))


def test_error_free_code_and_phase_equal_the_model(orbits):
    obs = _simulate(orbits, RawSettings(**QUIET), n=120)
    o = obs.observed
    clk = C_LIGHT * obs.clock_bias_s[:, None]
    model = obs.rho + clk - obs.sat_clock_m + obs.tropo_m
    np.testing.assert_allclose(obs.code[o], (model + obs.iono_m)[o], atol=1e-6)
    np.testing.assert_allclose(((obs.phase - obs.ambiguity) * L1_WAVELENGTH)[o],
                               (model - obs.iono_m)[o], atol=1e-6)
    # the receiver clock: bias integrates the drift (no noise)
    np.testing.assert_allclose(np.diff(obs.clock_bias_s), obs.clock_drift[:-1], rtol=1e-12)
    np.testing.assert_allclose(obs.time_gps, obs.time_rx - obs.clock_bias_s)
    # elevation from the range geometry, independent of az_el: sin(el) = up . los
    up = STATION / np.linalg.norm(STATION)       # geocentric up: within 0.2 deg of geodetic
    los = obs.r_sat_e - STATION
    el_geo = np.arcsin(np.einsum("nmi,i->nm", los, up) / np.linalg.norm(los, axis=2))
    assert np.nanmax(np.abs(el_geo - obs.elevation)) < np.deg2rad(0.25)
    assert np.all(obs.elevation[o] >= np.deg2rad(10.0))
    assert 6 <= o.sum(axis=1).min() and o.sum(axis=1).max() <= 12


def test_doppler_is_minus_the_carrier_rate(orbits):
    """Error free: D = -dL/dt (central difference of the carrier over 2 s) within 2 mHz;
    with noise, the scatter of D + dL/dt is that of the stated noise."""
    obs = _simulate(orbits, RawSettings(**QUIET), n=200)
    rate = (obs.phase[2:] - obs.phase[:-2]) / 2.0
    diff = (obs.doppler[1:-1] + rate)
    ok = np.isfinite(diff)
    assert ok.sum() > 1000 and np.max(np.abs(diff[ok])) < 2e-3
    s = RawSettings(sigma_code_m=0.0, sigma_phase_m=0.002, sigma_doppler_hz=0.05,
                    multipath_code_m=0.0, multipath_phase_m=0.0)
    obs = _simulate(orbits, s, n=400, seed=5)
    rate = (obs.phase[2:] - obs.phase[:-2]) / 2.0
    z = (obs.doppler[1:-1] + rate)
    sin_el = np.sin(obs.elevation[1:-1])
    sigma = np.sqrt((0.05 / sin_el) ** 2 + 2 * (0.002 / sin_el / L1_WAVELENGTH) ** 2 / 4)
    # the clock over the 2 s: (b[k+1] - b[k-1]) / 2 - d[k] = (w_b[k-1] + w_b[k] - w_d[k-1]) / 2
    clock_rw = C_LIGHT / L1_WAVELENGTH * np.sqrt(2 * s.clock_bias_noise ** 2
                                                 + s.clock_drift_noise ** 2) / 2.0
    norm = z / np.sqrt(sigma ** 2 + clock_rw ** 2)
    ok = np.isfinite(norm) & (obs.lli[1:-1] == 0) & (obs.lli[2:] == 0)
    assert 0.85 < np.std(norm[ok]) < 1.15 and abs(np.mean(norm[ok])) < 0.1


def test_masks_keep_exactly_n_highest(orbits):
    masks = ((100.0, 30.0, 3), (130.0, 30.0, 2), (160.0, 30.0, 1), (200.0, 10.0, 0))
    obs = _simulate(orbits, RawSettings(masks=masks, **QUIET), n=260)
    rel = obs.time_rx - obs.time_rx[0]
    n_sat = obs.observed.sum(axis=1)
    visible = np.isfinite(obs.rho) & (obs.elevation >= np.deg2rad(10.0))
    for start, dur, n in masks:
        rows = (rel >= start) & (rel < start + dur)
        assert np.all(n_sat[rows] == n)
        for i in np.flatnonzero(rows):     # the kept ones are the highest in view
            kept = obs.elevation[i, obs.observed[i]]
            dropped = obs.elevation[i, visible[i] & ~obs.observed[i]]
            assert n == 0 or dropped.max() < kept.min()
    free = rel < 100.0
    assert np.all(n_sat[free] == visible[free].sum(axis=1)) and n_sat[free].min() >= 6
    # the satellites coming back after the mask start a new arc: LLI set, new ambiguity
    back = obs.observed[210] & ~obs.observed[209]
    assert back.sum() >= 6 and np.all(obs.lli[210, back] == 1)


def test_cycle_slips_set_lli_and_jump_by_the_cycles(orbits):
    lla = _station_lla()
    probe = _simulate(orbits, RawSettings(**QUIET), n=2)
    prn = int(probe.prns[probe.observed[0]][0])
    slips = ((30.0, prn, 7), (60.0, 0, -2))
    obs = _simulate(orbits, RawSettings(slips=slips, **QUIET), n=100)
    j = int(np.flatnonzero(obs.prns == prn)[0])
    amb = obs.ambiguity
    assert amb[30, j] - amb[29, j] == 7 and obs.lli[30, j] == 1
    seen = obs.observed[60] & obs.observed[59]
    assert np.all(amb[60, seen] - amb[59, seen] == -2) and np.all(obs.lli[60, seen] == 1)
    assert obs.slips[0] == (obs.time_rx[30], prn, 7)
    assert len(obs.slips) == 1 + seen.sum()
    with pytest.raises(InputError, match=r"\[gnss_raw\] slips: 500 s is outside"):
        _simulate(orbits, RawSettings(slips=((500.0, 0, 1),), **QUIET), n=100)
    other = np.ones(obs.lli.shape, bool)
    other[[30, 60]] = False
    assert not np.any(obs.lli[other])                       # no slip elsewhere
    # the slip shows in the carrier minus the code (time-differenced): the cycles * lambda
    d = np.diff((obs.phase * L1_WAVELENGTH - obs.code)[:, j])
    assert d[29] == pytest.approx(7 * L1_WAVELENGTH + np.diff(-2 * obs.iono_m[:, j])[29],
                                  abs=1e-6)
    del lla


# ---------------------------------------------------------------------------------------
# RINEX 3.04 round trip through RTKLIB's reader

def test_rinex_obs_round_trip(tmp_path):
    rtk = pytest.importorskip("pyrtklib5")
    from ins.io.rinex_obs import write_rinex3_obs
    rng = np.random.default_rng(2)
    time = 519000.0 + np.arange(5) * 0.5
    prns = [3, 17, 32]
    vals = np.column_stack([rng.uniform(2e7, 2.6e7, 15), rng.uniform(-1e8, 1.3e8, 15),
                            rng.uniform(-4000, 4000, 15), rng.uniform(30, 50, 15)])
    vals = np.round(vals.reshape(5, 3, 4), 3)
    vals[1, 2] = np.nan                      # PRN 32 not seen at epoch 1
    vals[3, :] = np.nan                      # an epoch without satellites: skipped
    lli = np.zeros(vals.shape, int)
    lli[2, 0, 1] = 1
    path = tmp_path / "r.obs"
    assert write_rinex3_obs(path, WEEK, time, prns, vals, lli=lli, approx_xyz_m=STATION,
                            leap_seconds=13) == 4
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    assert rtk.readrnx(str(path), 1, "", obs, nav, sta) == 1
    assert obs.n == 11
    np.testing.assert_allclose([sta.pos[i] for i in range(3)], STATION, atol=1e-4)
    for k in range(obs.n):
        d = obs.data[k]
        week = rtk.Arr1Dint(1)
        sow = rtk.time2gpst(d.time, week)
        i = int(np.argmin(np.abs(time - sow)))
        assert week[0] == WEEK and abs(time[i] - sow) < 1e-6
        j = prns.index(d.sat)                       # GPS: sat number = PRN
        got = [d.P[0], d.L[0], d.D[0], d.SNR[0]]
        np.testing.assert_allclose(got, vals[i, j], atol=1e-3)
        assert d.LLI[0] == lli[i, j, 1]


# ---------------------------------------------------------------------------------------
# a simulated flight: files, truth, RTKLIB single-point positions

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
stationary_s = 20.0
run_in_m = 200.0
gps_week = 1316
start_time_s = {start}
[imu]
rate_hz = 50.0
[gnss_raw]
nav_file = "{nav}"
masks = [[40.0, 10.0, 3]]
slips = [[20.0, 0, 4]]
"""


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    if not NAV.is_file():
        pytest.skip("../shared/real is absent")
    from ins.simulate.folder import simulate_flight
    d = tmp_path_factory.mktemp("raw")
    plan = d / "plan.toml"
    plan.write_text(PLAN.format(start=T0, nav=NAV))
    return simulate_flight(plan, d / "flight", seed=4)


def test_flight_files_and_truth(flight):
    import tomllib
    m = tomllib.loads((flight / "manifest.toml").read_text())
    assert m["files"]["gnss_raw_obs"] == "rover.obs" and m["gnss_raw"]["min_satellites"] == 3
    made = m["gnss_raw"]["slips_made"]
    assert len(made) >= 6 and all(c == 4 for _, _, c in made)
    clock = np.loadtxt(flight / "receiver_clock.txt")
    tr = np.genfromtxt(flight / "gnss_raw_truth.csv", delimiter=",", names=True)
    assert len(tr) > 200 and set(np.unique(tr["lli"])) == {0.0, 1.0}
    bias = np.interp(tr["time_rx_s"], clock[:, 0], clock[:, 2])
    np.testing.assert_allclose(tr["time_gps_s"], tr["time_rx_s"] - bias, atol=1e-9)
    # the truth's range is the distance between the satellite and the antenna of gnss.txt
    # (its 2-4 cm noise) to within the light-time geometry
    from ins.io.gnss import read_gnss
    from ins.nav.earth import lla_to_ecef
    g = read_gnss(flight / "gnss.txt")
    k = np.searchsorted(g.time, np.round(tr["time_rx_s"]))
    ant = lla_to_ecef(g.lla[k, 0], g.lla[k, 1], g.lla[k, 2])
    sat = np.column_stack([tr["x_sat_m"], tr["y_sat_m"], tr["z_sat_m"]])
    dist = np.linalg.norm(sat - ant, axis=1)
    # gnss.txt is stamped in GPS time, the truth at time_gps (1e-4 s earlier: 6 mm at 60 m/s)
    assert np.max(np.abs(dist - tr["range_m"])) < 0.25
    assert np.sqrt(np.mean((dist - tr["range_m"]) ** 2)) < 0.06
    nav = (flight / "rover.nav").read_text()
    assert nav.startswith("     2.10") and nav.count("\n") < NAV.read_text().count("\n")


def test_flight_read_by_rtklib_and_code_residuals(flight):
    rtk = pytest.importorskip("pyrtklib5")
    tr = np.genfromtxt(flight / "gnss_raw_truth.csv", delimiter=",", names=True)
    clock = np.loadtxt(flight / "receiver_clock.txt")
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    assert rtk.readrnx(str(flight / "rover.obs"), 1, "", obs, nav, sta) == 1
    assert rtk.readrnx(str(flight / "rover.nav"), 1, "", rtk.obs_t(), nav, sta) == 1
    assert obs.n == len(tr) and nav.n > 10
    P = np.array([obs.data[k].P[0] for k in range(obs.n)])
    sats = np.array([obs.data[k].sat for k in range(obs.n)])
    lli = np.array([obs.data[k].LLI[0] for k in range(obs.n)])
    order = np.lexsort((tr["prn"], tr["time_rx_s"]))
    tr = tr[order]
    assert np.all(sats == tr["prn"]) and np.all(lli == tr["lli"])
    bias = np.interp(tr["time_rx_s"], clock[:, 0], clock[:, 2])
    res = P - (tr["range_m"] + C_LIGHT * bias - tr["sat_clock_m"] + tr["iono_m"] + tr["tropo_m"]
               + tr["multipath_code_m"])
    z = res / (0.3 / np.sin(np.deg2rad(tr["elevation_deg"])))     # the white noise
    assert 0.85 < np.std(z) < 1.15 and abs(np.mean(z)) < 0.15


def test_flight_single_point_positions_by_rtklib(flight, tmp_path):
    """RTKLIB's own orbits, clocks, Sagnac, Klobuchar and Saastamoinen on the simulated
    pseudoranges give the antenna within the noise (0.3 m white + 0.3 m multipath)."""
    pytest.importorskip("pyrtklib5")
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.gnss import read_gnss
    from ins.nav.earth import ned_offset
    sol = solve(flight / "rover.obs", flight / "rover.nav", tmp_path / "spp.pos",
                options=RtklibOptions(mode="single", direction="forward", systems=("gps",),
                                      elevation_mask_deg=10.0))
    g = read_gnss(flight / "gnss.txt")
    t, ia, ib = np.intersect1d(np.round(sol.log.time, 3), g.time, return_indices=True)
    assert len(t) > 0.7 * len(g.time)
    d = ned_offset(g.lla[ib], sol.log.lla[ia])
    rms = np.sqrt(np.mean(d ** 2, axis=0))
    assert np.all(rms[:2] < 1.5) and rms[2] < 3.0


def test_flight_outside_the_ephemerides_is_refused(tmp_path):
    if not NAV.is_file():
        pytest.skip("../shared/real is absent")
    from ins.simulate.folder import simulate_flight
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.format(start=100000.0, nav=NAV))
    with pytest.raises(InputError, match=r"07590920\.05n: the flight \(\[flight\] gps_week, "
                                         r"start_time_s\).*not covered"):
        simulate_flight(plan, tmp_path / "f", seed=1)
    assert not (tmp_path / "f").exists()


@pytest.mark.parametrize("line, message", [
    ('slips = [[20.0, 40, 4]]', r"\[gnss_raw\] slips: expected"),
    ('masks = [[20.0, -1.0, 3]]', r"\[gnss_raw\] masks: expected"),
    ('rate_hz = 0', r"\[gnss_raw\] rate_hz: must be > 0"),
    ('elevation_mask_rad = 5', r"\[gnss_raw\] elevation_mask_rad: unknown key"),
])
def test_plan_section_errors(tmp_path, line, message):
    from ins.simulate.plan_read import load_plan
    plan = tmp_path / "plan.toml"
    key = line.split()[0]
    text = "\n".join(r for r in PLAN.format(start=T0, nav="x.n").splitlines()
                     if not r.startswith(key + " "))
    plan.write_text(text.replace('[gnss_raw]\n', f'[gnss_raw]\n{line}\n'))
    with pytest.raises(InputError, match=message):
        load_plan(plan)


def test_plan_nav_file_is_relative_to_the_plan(tmp_path):
    from ins.simulate.plan_read import load_plan
    (tmp_path / "sub").mkdir()
    plan = tmp_path / "sub" / "plan.toml"
    plan.write_text(PLAN.format(start=T0, nav="../nav/brdc.05n"))
    raw = load_plan(plan).gnss_raw
    assert raw.nav_file == str(tmp_path / "nav" / "brdc.05n")
    assert raw.slips == ((20.0, 0, 4),) and raw.masks == ((40.0, 10.0, 3),)
    assert raw.elevation_mask_rad == pytest.approx(np.deg2rad(10.0)) and raw.base_lla is None


def test_plan_without_nav_file_names_the_key(tmp_path):
    from ins.simulate.folder import simulate_flight
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.format(start=T0, nav="").replace('nav_file = ""\n', ""))
    with pytest.raises(InputError, match=r"plan\.toml: \[gnss_raw\] nav_file"):
        simulate_flight(plan, tmp_path / "f", seed=1)


def test_multipath_process_statistics():
    """The multipath-like error: unit variance, autocorrelation exp(-lag / tau)."""
    from ins.simulate.gnss_raw import _gauss_markov
    x = _gauss_markov(200_000, 1.0, 60.0, np.random.default_rng(0))
    assert x.std() == pytest.approx(1.0, abs=0.03)
    for lag in (30, 60, 120):
        assert np.corrcoef(x[:-lag], x[lag:])[0, 1] == pytest.approx(np.exp(-lag / 60.0),
                                                                      abs=0.04)


def test_az_el_of_the_zenith():
    lla = _station_lla()[None, :]
    from ins.nav.earth import dcm_en
    up = -dcm_en(lla[0, 0], lla[0, 1])[:, 2]
    az, el = az_el(lla, STATION[None, :], (STATION + 2e7 * up)[None, :])
    assert el[0] == pytest.approx(np.pi / 2, abs=1e-9)


def test_cli_gnss_raw_option(tmp_path, capsys):
    """``ins simulate --gnss-raw``: a missing file and a plan outside the file's ephemerides
    are refused with exit 2 naming the file, no output; the rawsim plan writes rover.obs."""
    from ins.cli.main import main
    plan = ROOT / "data" / "flights" / "rawsim.toml"
    out = tmp_path / "f"
    assert main(["simulate", str(plan), "-o", str(out), "-q", "--gnss-raw",
                 str(tmp_path / "none.n")]) == 2
    assert "none.n: --gnss-raw: no such RINEX navigation file" in capsys.readouterr().err
    if not NAV.is_file():
        return
    demo = ROOT / "data" / "flights" / "demo.toml"            # GPS week 2300
    assert main(["simulate", str(demo), "-o", str(out), "-q", "--gnss-raw", str(NAV)]) == 2
    assert "not covered by the broadcast ephemerides" in capsys.readouterr().err
    assert not out.exists()
    assert main(["simulate", str(plan), "-o", str(out), "-q", "--gnss-raw", str(NAV)]) == 0
    text = (out / "rover.obs").read_text()
    assert text.startswith("     3.04           OBSERVATION DATA    G")
    assert "G    4 C1C L1C D1C S1C" in text


def _rinex3_nav(text2):
    """The GPS records of a RINEX 2.10 nav text rewritten as RINEX 3.04 (and a Galileo
    record, which the reader skips)."""
    lines = text2.splitlines()
    k = next(i for i, r in enumerate(lines) if "END OF HEADER" in r) + 1
    out = ["     3.04           N: GNSS NAV DATA    M: Mixed            RINEX VERSION / TYPE",
           "GPSA   1.1180E-08  1.4900E-08 -5.9600E-08 -5.9600E-08       IONOSPHERIC CORR",
           "GPSB   8.8060E+04  1.6380E+04 -1.9660E+05 -1.3110E+05       IONOSPHERIC CORR",
           "    13                                                      LEAP SECONDS",
           "                                                            END OF HEADER"]
    gal = ["E11 2005 04 02 02 00 00" + " 1.000000000000E-04" * 3] + \
        ["    " + " 1.000000000000E+00" * 4] * 7
    out += gal
    while k < len(lines):
        first = lines[k]
        yy, rest = int(first[3:5]), first[6:].split()[:4]
        date = f"G{int(first[:2]):02d} {2000 + yy:04d} " + " ".join(f"{int(x):02d}"
                                                                     for x in rest)
        out.append(f"{date} {int(float(first[17:22])):02d}{first[22:]}")
        out += ["    " + r[3:] for r in lines[k + 1:k + 8]]
        k += 8
    return "\n".join(out) + "\n"


@needs_nav
def test_rinex3_nav_reads_the_same(tmp_path):
    from ins.io.rinex_nav import read_gps_nav
    path = tmp_path / "brdc.rnx"
    path.write_text(_rinex3_nav(NAV.read_text()))
    a, b = read_gps_nav(NAV), read_gps_nav(path)
    assert b.version == 3.04 and b.ephemerides == a.ephemerides
    assert (b.ion_alpha, b.ion_beta, b.leap_seconds) == (a.ion_alpha, a.ion_beta, 13)


@needs_nav
def test_nav_reader_names_the_bad_line(tmp_path):
    from ins.io.rinex_nav import read_gps_nav
    lines = NAV.read_text().splitlines()
    lines[14] = lines[14][:25] + "x.xx" + lines[14][29:]
    path = tmp_path / "bad.05n"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"bad\.05n:15: expected a number \(D19\.12\)"):
        read_gps_nav(path)
    path.write_text("\n".join(lines[:12]) + "\n")
    with pytest.raises(InputError, match="no GPS ephemeris"):
        read_gps_nav(path)


@pytest.fixture(scope="module")
def flight_with_base(tmp_path_factory):
    if not NAV.is_file():
        pytest.skip("../shared/real is absent")
    from ins.simulate.folder import simulate_flight
    d = tmp_path_factory.mktemp("rawbase")
    plan = d / "plan.toml"
    text = PLAN.format(start=T0, nav=NAV).replace("masks = [[40.0, 10.0, 3]]\n", "")
    # 170 s (L1-only ambiguities take a while); a dry atmosphere: RTKLIB's relative mode
    # leaves the wet delay out, which differs between a base at 62 m and the aircraft at
    # 460 m (with 70 % humidity its float solution is 10 cm low and its fixes wrong); no
    # multipath (with 0.3 m of it on the code RTKLIB's float does not converge to a fix
    # within minutes)
    text = text.replace("stationary_s = 20.0", "stationary_s = 150.0")
    text = text.replace("[gnss_raw]\n", "[gnss_raw]\nhumidity_percent = 0.0\n"
                        "multipath_code_m = 0.0\nmultipath_phase_m = 0.0\n"
                        "base_lla_deg = [35.165, 139.61, 62.0]\n")
    plan.write_text(text)
    return simulate_flight(plan, d / "flight", seed=8)


def test_base_station_rtk_fixes_to_the_truth(flight_with_base, tmp_path):
    """RTKLIB's kinematic RTK with the simulated base: the carrier phases (ambiguities,
    the slip at 20 s flagged by LLI) give the antenna within the 2-4 cm noise of gnss.txt,
    ambiguities fixed."""
    pytest.importorskip("pyrtklib5")
    import tomllib

    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.gnss import read_gnss
    from ins.nav.earth import lla_to_ecef, ned_offset
    f = flight_with_base
    m = tomllib.loads((f / "manifest.toml").read_text())["gnss_raw"]
    lat, lon, h = m["base_lla_deg"]
    np.testing.assert_allclose(lla_to_ecef(np.deg2rad(lat), np.deg2rad(lon), h),
                               m["base_ecef_m"], atol=1e-6)
    sol = solve(f / "rover.obs", f / "rover.nav", tmp_path / "rtk.pos", base=f / "base.obs",
                options=RtklibOptions(mode="kinematic", direction="forward", systems=("gps",),
                                      elevation_mask_deg=10.0))
    g = read_gnss(f / "gnss.txt")
    t, ia, ib = np.intersect1d(np.round(sol.log.time, 3), g.time, return_indices=True)
    fixed = sol.log.quality[ia] == 1
    assert fixed.mean() > 0.5
    d = ned_offset(g.lla[ib[fixed]], sol.log.lla[ia[fixed]])
    rms = np.sqrt(np.mean(d ** 2, axis=0))
    assert np.all(rms < [0.04, 0.04, 0.07]), rms


def test_the_banked_aircraft_hides_the_low_satellites_on_the_outside(orbits):
    """Rolled 30 deg right wing down (heading north): the antenna's horizon tilts down to
    the east and up to the west.  The elevation above the aircraft's plane from the
    azimuth and elevation (an independent formula: the line of sight on the aircraft's
    up axis) decides what is hidden; the lost satellites are in the west."""
    from scipy.spatial.transform import Rotation
    lla = _station_lla()
    C_na = Rotation.from_euler("x", 30.0, degrees=True).as_matrix()

    def banked(t):
        return np.tile(lla, (len(t), 1)), np.tile(STATION, (len(t), 1)), \
            np.tile(C_na, (len(t), 1, 1))
    level = _simulate(orbits, RawSettings(**QUIET), n=5)
    obs = simulate_raw(orbits, WEEK, T0 + np.arange(5.0), banked, RawSettings(**QUIET),
                       np.random.default_rng(1))
    el, az = obs.elevation, obs.azimuth
    los_n = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), -np.sin(el)], axis=2)
    up_a = C_na @ np.array([0.0, 0.0, -1.0])
    el_a = np.arcsin(los_n @ up_a)
    np.testing.assert_allclose(obs.elevation_antenna[np.isfinite(el)], el_a[np.isfinite(el)],
                               atol=1e-9)
    np.testing.assert_array_equal(obs.observed, level.observed & (el_a >= 0.0))
    lost = level.observed & ~obs.observed
    assert lost.sum() >= 5 and np.all(np.sin(az[lost]) < 0)        # in the west
    assert np.all(np.isnan(level.elevation_antenna))                # no attitude given


@pytest.mark.skipif(not NAV.is_file(), reason="../shared/real is absent")
def test_a_flight_far_from_the_nav_files_station_is_warned(tmp_path, capsys):
    """The pair's navigation file holds the ephemerides its Japanese station received:
    a flight in Chile at the same time sees 1-2 of those satellites.  The folder is
    written (a simulation may want that), with a warning that says why no GNSS solution
    will come of it; the plan near the station gives no warning."""
    import warnings

    from ins.cli.main import main
    from ins.common.errors import QualityWarning
    text = (ROOT / "data" / "flights" / "rawsim.toml").read_text()
    south = (text.replace("origin_lat_deg = 35.17", "origin_lat_deg = -33.87")
             .replace("origin_lon_deg = 139.60", "origin_lon_deg = -70.65")
             .replace("base_lla_deg = [35.165, 139.61, 62.0]",
                      "base_lla_deg = [-33.865, -70.64, 62.0]"))
    assert south.count("-33.8") == 2 and "-70.65" in south
    plan = tmp_path / "south.toml"
    plan.write_text(south)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert main(["simulate", str(plan), "-o", str(tmp_path / "s"), "-q", "--gnss-raw",
                     str(NAV)]) == 0
    msgs = [str(w.message) for w in seen if issubclass(w.category, QualityWarning)]
    err = capsys.readouterr().err
    assert any("satellites in view" in m for m in msgs) or "satellites in view" in err
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert main(["simulate", str(ROOT / "data" / "flights" / "rawsim.toml"), "-o",
                     str(tmp_path / "n"), "-q", "--gnss-raw", str(NAV)]) == 0
    assert "satellites in view" not in capsys.readouterr().err
    assert not any("satellites in view" in str(w.message) for w in seen)
