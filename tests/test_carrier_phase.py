"""RTK/INS (issue 33 items 1-2): LAMBDA's validation and partial fixing against
independent computations (brute-force integer least squares, a Monte Carlo of integer
bootstrapping), and the carrier-phase double differences in the filter and smoother on
the raw-simulated flight with a base, whose truth is known (its slips at 60 s on G08 and
at 100 s on every satellite, its masks of 3, 2 and 1 satellites)."""
import itertools
import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pyrtklib5")

from ins.estimation.coupling.ambiguity import (  # noqa: E402
    bootstrap_success_rate,
    lambda_search,
    resolve,
)

ROOT = Path(__file__).resolve().parents[1]
PAIR = ROOT.parent / "shared" / "real" / "rtklib_static_pair"


def _random_q(n, scale, seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T) + 0.2 * scale * np.eye(n)


def test_lambda_is_the_integer_least_squares_minimum():
    """The two best candidates and their squared norms equal a brute-force search over
    every integer vector within 3 of the rounded float."""
    rng = np.random.default_rng(3)
    for trial in range(5):
        Q = _random_q(3, 0.1, trial)
        a = rng.normal(scale=5.0, size=3)
        Qi = np.linalg.inv(Q)
        best = sorted(((float((a - np.array(c)) @ Qi @ (a - np.array(c))), c) for c in
                       itertools.product(*[range(int(round(x)) - 3, int(round(x)) + 4)
                                           for x in a])))[:2]
        F, s = lambda_search(a, Q)
        np.testing.assert_allclose(s, [best[0][0], best[1][0]], rtol=1e-9)
        np.testing.assert_array_equal(F[0], best[0][1])


def _bootstrap(a, Q):
    """Integer bootstrapping from the last ambiguity to the first, conditioned on those
    already fixed (written here from its definition)."""
    n = len(a)
    out = np.zeros(n)
    for i in range(n - 1, -1, -1):
        J = list(range(i + 1, n))
        ai = a[i]
        if J:
            ai -= Q[i, J] @ np.linalg.solve(Q[np.ix_(J, J)], a[J] - out[J])
        out[i] = np.round(ai)
    return out


@pytest.mark.parametrize("scale", [0.03, 0.08])
def test_bootstrapped_success_rate_against_monte_carlo(scale):
    """The closed form (without decorrelation: in the order written) against the rate
    of a Monte Carlo of bootstrapping; with decorrelation it is larger, and ILS (LAMBDA)
    succeeds at least as often (the bound it is used as)."""
    n, trials = 4, 4000
    Q = _random_q(n, scale, 11)
    rng = np.random.default_rng(5)
    C = np.linalg.cholesky(Q)
    N = rng.integers(-50, 50, n).astype(float)
    draws = N + (C @ rng.normal(size=(n, trials))).T
    boot = np.mean([np.all(_bootstrap(a, Q) == N) for a in draws])
    p = bootstrap_success_rate(Q, decorrelate=False)
    assert abs(boot - p) < 3.5 * np.sqrt(p * (1 - p) / trials) + 1e-3
    p_z = bootstrap_success_rate(Q)
    ils = np.mean([np.all(lambda_search(a, Q)[0][0] == N) for a in draws[:1500]])
    assert p_z >= p - 1e-12
    assert ils >= p_z - 3.5 * np.sqrt(p_z * (1 - p_z) / 1500) - 1e-3


def test_partial_fixing_leaves_out_the_weakest_and_keeps_the_held():
    """Four well-determined ambiguities and one of 1 cycle sigma: the whole set fails
    the success rate, the four pass; an ambiguity named in ``keep`` is never dropped."""
    Q = np.diag([0.002, 0.003, 0.002, 0.004, 1.0])
    a = np.array([3.01, -7.02, 12.0, 1.97, 4.4])
    fix = resolve(a, Q, ratio=3.0, min_success=0.99, min_count=3)
    assert fix.fixed and list(fix.index) == [0, 1, 2, 3] and fix.tried == 2
    np.testing.assert_array_equal(fix.integers, [3, -7, 12, 2])
    none = resolve(a, Q, ratio=3.0, min_success=0.99, min_count=3, keep=[4])
    assert not none.fixed


# ---------------------------------------------------------------------------------------
# the raw-simulated flight with a base (RINEX through RTKLIB)

@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    if not PAIR.is_dir():
        pytest.skip("../shared/real is absent (the flight's broadcast orbits)")
    from ins.cli.main import main
    out = tmp_path_factory.mktemp("rtk") / "flight"
    rc = main(["simulate", str(ROOT / "data" / "flights" / "rawsim_dd.toml"), "-o", str(out),
               "--gnss-raw", str(PAIR / "07590920.05n"), "--seed", "1", "-q"])
    assert rc in (0, None)
    return out


def _run(folder, carrier):
    from ins.estimation.pipeline.config import config_from_manifest
    from ins.estimation.pipeline.gnss_source import RawGnss
    from ins.estimation.pipeline.process import process
    from ins.gnss.rtklib_options import RtklibOptions
    cfg = config_from_manifest(str(folder))
    cfg.gnss = None
    cfg.gnss_raw = RawGnss(rover=str(folder / "rover.obs"), nav=(str(folder / "rover.nav"),),
                           base=str(folder / "base.obs"), options=RtklibOptions(
                               mode="single", systems=("gps",), frequencies=1,
                               elevation_mask_deg=10.0))
    cfg.coupling = "tight"
    cfg.carrier_phase = carrier
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return process(cfg, accept_poor=True)


@pytest.fixture(scope="module")
def runs(flight):
    return _run(flight, True), _run(flight, False)


def _horizontal(folder, traj):
    from ins.io.navfiles import read_nav
    from ins.nav import earth
    truth = read_nav(str(folder / "truth.nav"))
    j = np.clip(np.searchsorted(truth.time, traj.time - 1e-6), 0, len(truth.time) - 1)
    d = earth.ned_offset(truth.lla[j], traj.lla)
    return traj.time, np.hypot(d[:, 0], d[:, 1]), d[:, 2]


def test_rtk_fixes_and_beats_the_code_double_differences(flight, runs):
    """Smoothed horizontal RMS at the centimetre (code DDs: decimetres), the forward
    solution at the end of the 3-satellite span held by the fixed ambiguities."""
    import tomllib
    rtk, code = runs
    t0 = tomllib.loads((flight / "manifest.toml").read_text())["flight"]["start_time_s"]
    c = rtk.counts
    assert c["fix_rate"] > 0.4 and c["fixed_epochs"] > 80
    _, h_rtk, v_rtk = _horizontal(flight, rtk.smoothed)
    _, h_code, _ = _horizontal(flight, code.smoothed)
    rms = lambda x: float(np.sqrt(np.mean(x ** 2)))       # noqa: E731
    assert rms(h_rtk) < 0.03 and rms(h_rtk) < 0.2 * rms(h_code)
    assert rms(v_rtk) < 0.08
    t, h_fwd, _ = _horizontal(flight, rtk.forward)
    end_3 = int(np.argmin(np.abs(t - (t0 + 130.0 + 20.0 - 1.0))))     # masks: 3, 2, 1 sats
    assert h_fwd[end_3] < 0.02


def test_the_simulated_slips_are_found_and_refixed(flight, runs):
    """The slips of the plan (G08 at 60 s; every satellite at 100 s, flagged by LLI) are
    counted where they happen, and the ambiguities are fixed again within 10 s."""
    import tomllib
    rtk, _ = runs
    up = rtk.fwd.updater
    t0 = tomllib.loads((flight / "manifest.toml").read_text())["flight"]["start_time_s"]
    at = {}
    for t, s in up.slips:
        at.setdefault(round(t - t0), set()).add(s)
    assert "G08 L1" in at.get(60, set())
    assert len(at.get(100, set())) >= 5
    fixed = np.array(up.fixed_at) - t0
    assert np.any((fixed > 100.0) & (fixed <= 110.0))


def test_a_slip_without_its_flag_is_found_by_the_ins(flight, monkeypatch):
    """The loss-of-lock flags removed from both receivers: the 5-cycle slip of G08 at
    60 s is found by the w-test against the INS's prediction alone, and the solution
    stays at the centimetre."""
    import tomllib

    from ins.estimation.pipeline import tight
    read = tight._read

    def no_flags(raw_in, positions):
        raw = read(raw_in, positions)
        raw.lli = None
        raw.base.lli = None
        return raw
    monkeypatch.setattr(tight, "_read", no_flags)
    res = _run(flight, True)
    t0 = tomllib.loads((flight / "manifest.toml").read_text())["flight"]["start_time_s"]
    slips = {(round(t - t0), s) for t, s in res.fwd.updater.slips}
    assert (60, "G08 L1") in slips
    _, h, _ = _horizontal(flight, res.smoothed)
    assert float(np.sqrt(np.mean(h ** 2))) < 0.03
