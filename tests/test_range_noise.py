"""Code and Doppler noise estimated from the data and the IGG-III down-weighting
(ins.estimation.coupling.range_noise): the robust fit against a known model with
blunders, the weight function, the per-epoch centring, the real GEONET stations'
residuals, and on what a u-blox shows (tests/ublox_scenario.py: C/N0 fades, multipath
correlated over 30 s, C/N0-dependent noise, NLOS bursts of 10-50 m) tight coupling
with the fitted model and the robust weighting against loose coupling on a single-point
solution with fault exclusion, over the run and in a 20 s window of 3 satellites."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import tight_scenario as ts
import ublox_scenario as us

from ins.estimation.coupling.pseudorange import TightOptions
from ins.estimation.coupling.range_noise import (
    MAD_TO_SIGMA,
    NoiseModel,
    RangeNoise,
    epoch_samples,
    fit_receiver,
    igg3_inflation,
    samples_by_kind,
)
from ins.nav import earth

PAIR = Path(__file__).resolve().parents[1].parent / "shared" / "real" / "rtklib_static_pair"


def test_fit_recovers_a_known_model_despite_blunders():
    rng = np.random.default_rng(0)
    n = 20000
    el = rng.uniform(np.deg2rad(10), np.pi / 2, n)
    snr = 30 + 18 * np.sin(el) + rng.normal(0, 4, n)
    truth = NoiseModel((0.5, 0.8, 1.5), (0.02, 0.01, 0.08))
    vr, vd = truth.variances(el, snr)
    z, zd = rng.normal(size=n) * np.sqrt(vr), rng.normal(size=n) * np.sqrt(vd)
    bad = rng.random(n) < 0.03
    z[bad] += rng.choice([-1, 1], bad.sum()) * rng.uniform(10, 50, bad.sum())
    hph = np.full(n, 0.25)                      # a known part of the variance, m^2
    z += rng.normal(size=n) * 0.5
    s = ([(0, *r, 0.25) for r in zip(el, snr, z)]
         + [(1, *r, 0.0) for r in zip(el, snr, zd)])
    m = fit_receiver(s)
    for e, c in ((15, 32), (30, 40), (60, 45), (85, 48)):
        fr, fd = m.variances(np.deg2rad(e), c)
        tr, td = truth.variances(np.deg2rad(e), c)
        assert np.sqrt(fr / tr) == pytest.approx(1.0, abs=0.12), (e, c, fr, tr)
        assert np.sqrt(fd / td) == pytest.approx(1.0, abs=0.12), (e, c, fd, td)
    # the blunders would dominate a fit on squares: their share of the mean square
    assert np.mean(z[bad] ** 2) * bad.mean() > 2 * np.mean(vr + hph)
    assert min(m.samples) > 0.98 * n          # the sparse bins left out


def test_igg3_inflation():
    k1 = 4.42
    t = np.array([0.0, 1.0, 2.0, 2.0001, 3.0, 4.0, 4.42, 9.0])
    f = igg3_inflation(t, k1, k0=2.0)
    assert np.all(f[:3] == 1.0) and f[3] == pytest.approx(1.0, abs=1e-3)  # continuous
    assert np.all(np.diff(f) >= 0) and f[-2] == f[-1] == 1e6
    # the weight 1 / f is k0 / t ((k1 - t) / (k1 - k0))^2
    assert 1 / f[4] == pytest.approx(2.0 / 3.0 * ((k1 - 3.0) / (k1 - 2.0)) ** 2)


def test_epoch_samples_drop_what_is_common_to_the_epoch():
    rng = np.random.default_rng(2)
    k, n = 7, 9
    H, P = rng.normal(size=(k, n)), np.eye(n) * 0.1
    el, z = np.full(k, 0.7), rng.normal(size=k)
    a = epoch_samples(0, el, None, z, H, P)
    b = epoch_samples(0, el, None, z + 123.0, H + 1.0 * 0, P)
    np.testing.assert_allclose([r[3] for r in a], [r[3] for r in b])
    # a row common to all satellites (the clock column) leaves the known variance
    Hc = H.copy()
    Hc[:, -1] = -1.0
    P2 = P.copy()
    P2[-1, -1] = 1e6
    c1 = epoch_samples(0, el, None, z, Hc, P)
    c2 = epoch_samples(0, el, None, z, Hc, P2)
    np.testing.assert_allclose([r[4] for r in c1], [r[4] for r in c2], rtol=1e-6)
    assert epoch_samples(0, el[:2], None, z[:2], H[:2], P) == []


def test_real_geonet_stations_code_noise():
    """The two GEONET stations at their header positions: code residuals per epoch
    less their median; the fit's zenith sigma is what the MAD of the residuals says
    (about 0.3 m), not the blunder-inflated standard deviation (0.8-0.9 m)."""
    pytest.importorskip("pyrtklib5")
    if not PAIR.is_dir():
        pytest.skip("../shared/real is absent")
    from ins.estimation.coupling.base_residuals import static_residuals
    from ins.gnss.raw_epochs import read_raw_epochs
    for name in ("0759", "3040"):
        obs = PAIR / f"{name}0920.05o"
        xyz = next(np.array(line.split()[:3], float) for line in open(obs)
                   if "APPROX POSITION XYZ" in line)
        s = static_residuals(read_raw_epochs(obs, PAIR / f"{name}0920.05n", xyz), xyz)
        m = fit_receiver(s)
        el, _, z, _ = samples_by_kind(s, 0)
        assert len(z) > 700 and m.samples[0] == len(z)
        zen = np.sqrt(m.variances(np.pi / 2)[0])
        mad = MAD_TO_SIGMA * np.median(np.abs(z))
        assert 0.15 < zen < 0.6, (name, m.describe())
        assert zen < mad < np.std(z)             # heavy tails: std above the MAD's sigma
        assert m.samples[1] == 0                 # no Doppler in these files: the fallback
        assert m.rate == NoiseModel().rate


# ---------------------------------------------------------------------------------------
# the u-blox-like scenario

RUN_S, WIN = 200.0, (120.0, 140.0)


@pytest.fixture(scope="module")
def ublox():
    imu, truth, noise, t0 = ts.flight()
    times = np.arange(t0 + 1.0, t0 + RUN_S + 5.0, 1.0)
    epochs, _, _ = us.make_ublox_epochs(truth, times, ts.L_B, seed=4)
    span = (t0 + WIN[0], t0 + WIN[1])
    win = ts.masked(epochs, span, 3, truth.lla[np.searchsorted(truth.time, span[0])])
    first = replace(TightOptions(), keep_samples=True, noise=RangeNoise(
        NoiseModel((1.0, 1.0, 0.0), (0.1, 0.1, 0.0)), robust=False))
    fwd, _ = ts.run(imu, truth, noise, t0, t0 + RUN_S, win, True, options=first,
                    clock_psd=us.TCXO)
    model = fit_receiver(fwd.updater.samples)
    lo = us.spp_fde(win, truth.lla[0])
    fl, sl = ts.run(imu, truth, noise, t0, t0 + RUN_S, lo, False, smooth=True)
    return imu, truth, noise, t0, win, span, model, _errors(fl, sl, truth, t0, span)


def _errors(fwd, states, truth, t0, span):
    """Smoothed horizontal RMS over the run (after 30 s) and inside ``span``, m."""
    j = np.searchsorted(truth.time, fwd.time - 1e-6)
    d = earth.ned_offset(truth.lla[j], states[:, :3])
    h = np.hypot(d[:, 0], d[:, 1])
    m, w = fwd.time > t0 + 30, (fwd.time >= span[0]) & (fwd.time <= span[1])
    return float(np.sqrt(np.mean(h[m] ** 2))), float(np.sqrt(np.mean(h[w] ** 2)))


def _tight(ublox, epochs, noise_opt):
    imu, truth, noise, t0, _, span, _, _ = ublox
    fwd, st = ts.run(imu, truth, noise, t0, t0 + RUN_S, epochs, True, smooth=True,
                     options=replace(TightOptions(), noise=noise_opt), clock_psd=us.TCXO)
    return _errors(fwd, st, truth, t0, span)


def test_fitted_model_near_the_simulated_one(ublox):
    """The C/N0 terms (the simulation: code 1.5 m, range rate 0.08 m/s at 45 dB-Hz) come
    out of the first pass's innovations; the correlated multipath is partly taken up by
    the filter's states (so the elevation term comes out below its 1 m)."""
    m = ublox[6]
    assert 1.0 < m.code[2] < 2.0, m.describe()
    assert 0.035 < m.rate[2] < 0.12, m.describe()
    zen = np.sqrt(m.variances(np.pi / 2, 48.0)[0])
    assert 0.5 < zen < 2.0, m.describe()


def test_tight_with_the_fitted_noise_not_worse_than_loose(ublox):
    """Over the run and in the 3-satellite window (where loose coupling has no fix) the
    fitted model with IGG-III is no worse than loose coupling; RTKLIB's white-noise
    defaults (0.3 m + 0.3 m / sin el) are worse than loose over the run."""
    loose = ublox[7]
    rob = _tight(ublox, ublox[4], RangeNoise(ublox[6]))
    default = _tight(ublox, ublox[4], None)
    assert rob[0] <= loose[0] and rob[1] <= loose[1], (rob, loose)
    assert default[0] > 1.3 * rob[0], (default, rob)


def test_robust_weighting_carries_three_satellites_through_a_reflection(ublox):
    """A 12 m reflection on one of the three satellites for 10 s (2-4 sigma: below the
    rejection threshold): with IGG-III the window stays within 0.35 m; taken at face
    value it pulls the solution beyond that (seed 4: 0.13 m against 0.63 m)."""
    imu, truth, noise, t0, win, span, model, loose = ublox
    inside = np.flatnonzero((win.time >= span[0]) & (win.time <= span[1]))
    hit = win.select(lambda k, s: np.ones(len(s), bool))
    for k in inside[2:12]:
        hit.range_m[k] = hit.range_m[k].copy()
        hit.range_m[k][0] += 12.0
    rob = _tight(ublox, hit, RangeNoise(model))
    plain = _tight(ublox, hit, RangeNoise(model, robust=False))
    assert rob[1] < 0.35 and rob[1] <= loose[1], (rob, loose)
    assert plain[1] > 0.35, plain          # the bound is what the weighting buys


# ---------------------------------------------------------------------------------------
# the pipeline: [gnss] range_noise, robust_weighting

def test_config_range_noise_keys(tmp_path):
    from ins.common.errors import InputError
    from ins.estimation.pipeline.config import load_config
    from ins.estimation.pipeline.tight import _options
    p = tmp_path / "c.toml"
    base = '[files]\nimu = "imu.txt"\nrover = "r.obs"\nnav = "r.nav"\n[gnss]\ncoupling = "tight"\n'
    p.write_text(base)
    cfg = load_config(p)
    assert (cfg.range_noise, cfg.robust_weighting) == ("auto", None)   # None: with auto
    assert _options(cfg).noise is None            # the first pass: the sigmas as given
    p.write_text(base + 'range_noise = "fixed"\nrange_sigma_m = [1, 2]\n')
    assert _options(load_config(p)).noise is None  # fixed: exactly the old weighting
    p.write_text(base + 'range_noise = "fixed"\nrange_sigma_m = [1, 2]\n'
                        'robust_weighting = true\n')
    o = _options(load_config(p))                   # fixed, IGG-III asked for
    assert o.noise.robust and o.noise.rover.code == (1.0, 2.0, 0.0)
    for bad, match in (('range_noise = "fitted"', r"c\.toml: \[gnss\] range_noise: expected "
                                                  r"\"auto\""),
                       ('robust_weighting = 1', r"robust_weighting: expected true or false")):
        p.write_text(base + bad + "\n")
        with pytest.raises(InputError, match=match):
            load_config(p)


def test_process_auto_noise_two_passes(monkeypatch):
    """``process`` with coupling = "tight" and the default range_noise = "auto" on the
    simulated flight with u-blox-like raw epochs (the RINEX reading replaced, RTKLIB's
    solution by the flight's GNSS log): the summary names the fitted rover model, whose
    C/N0 term is the simulation's, and the run uses it with IGG-III.  (The flight's
    GNSS log is far more precise than these ranges: the trust checks against it
    complain, hence ``accept_poor``.)"""
    from test_filter import PLAN, given_config, short_flight

    from ins.estimation.pipeline import process as process_module
    from ins.estimation.pipeline import tight
    from ins.estimation.pipeline.gnss_source import RawGnss
    from ins.estimation.pipeline.process import process
    from ins.io.gnss import read_gnss
    folder = short_flight(3, PLAN.replace('grade = "navigation"', 'grade = "tactical"'))
    cfg = given_config(folder, varying=False)
    imu, truth, noise, t0 = ts.flight()
    cfg.end_s = t0 + 200.0
    cfg.coupling = "tight"
    cfg.gnss_raw = RawGnss(rover="rover.obs", nav=("brdc.nav",))
    times = np.arange(t0 + 1.0, t0 + 200.0, 1.0)
    synth, _, _ = us.make_ublox_epochs(truth, times, cfg.lever_bp + cfg.lever_ap, seed=4)
    monkeypatch.setattr(tight, "_read", lambda raw_in, positions: synth)
    monkeypatch.setattr(process_module, "_gnss", lambda c, folder: (read_gnss(c.gnss), None))
    result = process(cfg, accept_poor=True)
    rn = result.counts["range_noise"]
    assert rn["mode"] == "auto" and rn["robust"] and "base" not in rn
    assert 1.0 < rn["rover"]["code_abc_m"][2] < 2.0, rn
    assert rn["rover"]["samples"][0] > 1000
    np.testing.assert_allclose(result.fwd.updater.opt.noise.rover.code,
                               rn["rover"]["code_abc_m"], atol=1e-4)
    assert result.fwd.updater.opt.noise.robust


def test_double_differences_with_the_fitted_noise(tmp_path):
    """rawsim_dd.toml through RTKLIB (white 0.3 m / sin el code at both receivers): the
    base's model fitted from its residuals at its known position, the rover's from the
    first pass's single differences; the smoothed DD solution with them is no worse than
    with the fixed 0.3 m + 0.3 m / sin el (seed 1: 0.30 against 0.31 m horizontal; the
    configured sigmas are the fit's floors, without them 0.21 m: the simulated Doppler,
    0.01 m/s, is far below the 0.05 + 0.05 / sin el floor)."""
    pytest.importorskip("pyrtklib5")
    if not PAIR.is_dir():
        pytest.skip("../shared/real is absent")
    import warnings

    from ins.cli.main import main
    from ins.estimation.pipeline.config import config_from_manifest
    from ins.estimation.pipeline.gnss_source import RawGnss
    from ins.estimation.pipeline.process import process
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.navfiles import read_nav
    root = Path(__file__).resolve().parents[1]
    folder = tmp_path / "flight"
    assert main(["simulate", str(root / "data" / "flights" / "rawsim_dd.toml"), "-o",
                 str(folder), "--gnss-raw", str(PAIR / "07590920.05n"), "--seed", "1",
                 "-q"]) in (0, None)
    truth = read_nav(str(folder / "truth.nav"))
    rms, rn = {}, None
    for mode in ("fixed", "auto"):
        cfg = config_from_manifest(str(folder))
        cfg.gnss = None
        cfg.gnss_raw = RawGnss(rover=str(folder / "rover.obs"),
                               nav=(str(folder / "rover.nav"),), base=str(folder / "base.obs"),
                               options=RtklibOptions(mode="single", systems=("gps",),
                                                     frequencies=1, elevation_mask_deg=10.0))
        cfg.coupling, cfg.carrier_phase = "tight", False
        cfg.range_noise, cfg.robust_weighting = mode, mode == "auto"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = process(cfg, accept_poor=True)
        sm = res.smoothed
        j = np.clip(np.searchsorted(truth.time, sm.time - 1e-6), 0, len(truth.time) - 1)
        d = earth.ned_offset(truth.lla[j], sm.lla)
        rms[mode] = float(np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2)))
        if mode == "auto":
            rn = res.counts["range_noise"]
    assert rms["auto"] <= rms["fixed"], rms
    base = NoiseModel(tuple(rn["base"]["code_abc_m"]), tuple(rn["base"]["rate_abc_mps"]))
    # the simulation's base: 0.3 m / sin el of white code noise (and what is left of the
    # atmosphere's models after the detrending)
    for e in (20.0, 45.0, 80.0):
        want = 0.3 / np.sin(np.deg2rad(e))
        assert 0.7 * want < np.sqrt(base.variances(np.deg2rad(e))[0]) < 2.0 * want, rn
    assert rn["base"]["samples"][0] > 1000 and rn["rover"]["samples"][0] > 1000
