"""Noise identification from the log (ins.estimation.tools.noise_identification), the GNSS
velocity lag (ins.estimation.coupling.velocity_lag) and the GNSS track's self-consistency
(ins.estimation.core.gnss_consistency): each against an independent truth (an analytic track,
scipy's multivariate normal, a quadratic likelihood with a known minimum, the
simulator's truth), and the real car of ../shared/real/rtklibexplorer_drive as its
README runs it (skipped when ../shared/real is absent)."""
import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from ins.estimation.core.error_model import ImuNoise
from ins.estimation.core.gnss_consistency import track_consistency
from ins.estimation.core.measurements import NLL_HUBER_NIS, innovation_nll
from ins.estimation.tools.noise_identification import UNRESOLVED_FACTOR, identify
from ins.estimation.coupling.velocity_lag import velocity_lag
from ins.io.gnss_log import GnssLog
from ins.nav import earth

ROOT = Path(__file__).resolve().parents[1]
DRIVE = ROOT.parent / "shared" / "real" / "rtklibexplorer_drive"
needs_drive = pytest.mark.skipif(not DRIVE.is_dir(), reason="../shared/real is absent")


def _track(lag_s=0.0, rate_hz=4.0, duration_s=120.0, noise_m=0.01, noise_mps=0.02, seed=0):
    """An analytic car track (NED metres about a point): speed 10 m/s with a sinusoidal
    heading, fixes with white noise; the velocity stamped t is the truth of t - lag."""
    rng = np.random.default_rng(seed)
    t = 1000.0 + np.arange(0.0, duration_s, 1.0 / rate_hz)

    def pos(s):
        s = s - 1000.0
        return np.column_stack([10.0 * s + 40.0 * np.sin(0.2 * s), 60.0 * np.cos(0.1 * s),
                                0.2 * np.sin(0.05 * s)])

    def vel(s):
        s = s - 1000.0
        return np.column_stack([10.0 + 8.0 * np.cos(0.2 * s), -6.0 * np.sin(0.1 * s),
                                0.01 * np.cos(0.05 * s)])
    ref = np.array([np.deg2rad(40.0), np.deg2rad(-105.0), 1600.0])
    lla = earth.offset_lla(np.tile(ref, (len(t), 1)),
                           pos(t) + noise_m * rng.standard_normal((len(t), 3)))
    v = vel(t - lag_s) + noise_mps * rng.standard_normal((len(t), 3))
    return GnssLog(t, lla, np.full((len(t), 3), noise_m), v, np.full((len(t), 3), noise_mps))


# --- the GNSS velocity lag -----------------------------------------------------------

@pytest.mark.parametrize("lag_s", [0.0, 0.125, -0.08, 0.3])
def test_velocity_lag_of_an_analytic_track(lag_s):
    """Velocities lagging by ``lag`` need the shift -lag; found within 4 sigma and 5 ms."""
    est = velocity_lag(_track(lag_s))
    assert est is not None
    assert abs(est.shift_s + lag_s) < max(4 * est.sigma_s, 0.005), est
    assert est.significant == (lag_s != 0.0)


def test_velocity_lag_needs_velocities_and_motion():
    g = _track()
    assert velocity_lag(replace(g, v_n=None, sigma_vel_ned_mps=None)) is None
    assert velocity_lag(g.select(np.arange(len(g)) < 10)) is None


def test_velocity_lag_is_not_estimated_again_on_shifted_velocities():
    """Velocities with their own epochs (already shifted by the user) are left alone."""
    g = _track(0.125)
    assert velocity_lag(g.shifted(0.0, -0.125)) is None


# --- the GNSS track's consistency -----------------------------------------------------

def test_track_consistency_flags_a_step_and_gaps_only():
    g = _track()
    c = track_consistency(g)
    assert c.gap_before[0] and not c.gap_before[1:].any()
    assert not c.step.any()
    lla = g.lla.copy()
    lla[200:, 1] += 0.5 / (earth.radii(lla[0, 0])[1] * np.cos(lla[0, 0]))  # 0.5 m east
    c2 = track_consistency(replace(g, lla=lla))
    assert np.flatnonzero(c2.step).tolist() == [200]
    keep = np.ones(len(g), bool)
    keep[300:360] = False                                   # a 15 s outage
    c3 = track_consistency(g.select(keep))
    assert np.flatnonzero(c3.gap_before).tolist() == [0, 300]


def test_track_consistency_without_velocities_and_with_lagged_ones():
    g = _track(0.125)
    lagged = track_consistency(g)                  # a lag taken at face value: steps
    shifted = track_consistency(g.shifted(0.0, -0.125))
    assert shifted.step.sum() == 0 and lagged.step_nis[1:].mean() > shifted.step_nis[1:].mean()
    none = track_consistency(replace(g, v_n=None, sigma_vel_ned_mps=None))
    assert none.gap_before[0] and np.isnan(none.step_nis[:2]).all()
    assert not none.step.any()


# --- the likelihood ------------------------------------------------------------------

def test_innovation_nll_is_the_gaussian_one_inside_and_continuous_outside():
    S = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.02], [0.0, 0.02, 0.16]])
    z = np.array([0.1, -0.2, 0.3])
    nis = float(z @ np.linalg.solve(S, z))
    assert nis < NLL_HUBER_NIS
    ref = -multivariate_normal(np.zeros(3), S).logpdf(z)
    assert innovation_nll(nis, np.linalg.slogdet(S)[1], 3) == pytest.approx(ref, rel=1e-12)
    c = NLL_HUBER_NIS
    lo, hi = innovation_nll(c * (1 - 1e-9), 0.0, 3), innovation_nll(c * (1 + 1e-9), 0.0, 3)
    assert hi == pytest.approx(lo, abs=1e-6)
    assert innovation_nll(100 * c, 0.0, 3) < 0.5 * 100 * c        # grows slower than NIS


def test_search_finds_the_minimum_of_a_known_likelihood():
    """A quadratic NLL in the logarithms of ARW and VRW with its minimum at factors 3.2
    and 0.45 and curvatures 400 and 100: found within 2 %, sigmas from the curvature
    (1/sqrt(400) = 0.05, 1/sqrt(100) = 0.1 in the logarithm); the scale priors, on which
    it does not depend, are not separable; the NHC kept when it lowers the NLL by 50."""
    base = ImuNoise(arw_deg_sqrth=1.0, vrw_mps_sqrth=0.2)

    def nll(noise, nhc, vshift, toff):
        u = np.log(noise.arw_deg_sqrth[0] / 3.2)
        w = np.log(noise.vrw_mps_sqrth[0] / (0.2 * 0.45))
        return 200.0 * u ** 2 + 50.0 * w ** 2 - (50.0 if nhc else 0.0)

    out = identify(nll, [("a start", base)], window_s=100.0)
    assert out.noise.arw_deg_sqrth[0] == pytest.approx(3.2, rel=0.02)
    assert out.noise.vrw_mps_sqrth[0] == pytest.approx(0.09, rel=0.02)
    p = {q.name: q for q in out.parameters}
    assert np.log(p["ARW"].sigma) == pytest.approx(0.05, rel=0.1)
    assert np.log(p["VRW"].sigma) == pytest.approx(0.1, rel=0.1)
    assert not p["gyro scale-factor sigma"].resolved
    assert out.noise.gyro_scale_std_ppm[0] == base.gyro_scale_std_ppm[0]
    assert out.nhc and "not separable" in out.describe()
    assert UNRESOLVED_FACTOR > 1


def test_search_starts_from_the_best_start_and_refines_the_lag():
    """Two starts (the second better); a lag with its minimum at -0.13 s."""
    def nll(noise, nhc, vshift, toff):
        return (100.0 * np.log(noise.arw_deg_sqrth[0] / 0.5) ** 2
                + 1e5 * (vshift + 0.13) ** 2 + (10.0 if nhc else 0.0))

    class Lag:
        shift_s = -0.1
    starts = [("far", ImuNoise(arw_deg_sqrth=50.0)), ("near", ImuNoise(arw_deg_sqrth=0.6))]
    out = identify(nll, starts, velocity_lag=Lag())
    assert out.start_name == "near"
    assert out.velocity_shift_s == pytest.approx(-0.13, abs=0.002)
    assert out.noise.arw_deg_sqrth[0] == pytest.approx(0.5, rel=0.02)
    assert not out.nhc


def test_search_finds_a_time_offset_when_asked():
    """An NLL with its minimum at an IMU-GNSS offset of +0.213 s (curvature 2e4 / s^2):
    found within 2 ms from 0 when the offset is searched; not touched otherwise."""
    def nll(noise, nhc, vshift, toff):
        return (100.0 * np.log(noise.arw_deg_sqrth[0] / 0.5) ** 2
                + 1e4 * ((toff or 0.0) - 0.213) ** 2)
    out = identify(nll, [("a", ImuNoise(arw_deg_sqrth=0.5))], test_nhc=False,
                   time_offset=True)
    assert out.time_offset_s == pytest.approx(0.213, abs=0.002)
    p = {q.name: q for q in out.parameters}["IMU-GNSS time offset"]
    assert p.resolved and p.sigma == pytest.approx(1 / np.sqrt(2e4), rel=0.05)
    assert identify(nll, [("a", ImuNoise(arw_deg_sqrth=0.5))]).time_offset_s is None
    # a likelihood flat in the offset: not separable, 0 kept, and said so
    flat = identify(lambda n, h, v, t: 100.0 * np.log(n.arw_deg_sqrth[0] / 0.5) ** 2,
                    [("a", ImuNoise(arw_deg_sqrth=0.5))], test_nhc=False, time_offset=True)
    assert flat.time_offset_s == 0.0
    assert "IMU-GNSS time offset 0 s: not separable by the data" in flat.describe()


def test_an_offset_found_before_the_constraint_is_weighed_against_none_with_it():
    """The PSINS car's case: without the constraint the NLL has a shallow dip of 4 at an
    offset of -0.19 s; with it, no offset is 12 lower and an offset costs (300 / s^2).
    The search meets the offset first and then rejects the constraint at it; weighed
    again against none with the constraint decided again, the offset gains nothing
    (-8, at least 10 needed): 0 kept, the constraint used, and the summary says why.
    A deep dip (40) is kept."""
    def nll_of(depth):
        def nll(noise, nhc, vshift, toff):
            t = toff or 0.0
            f = (-12.0 + 300.0 * t ** 2) if nhc else -depth * np.exp(-((t + 0.19) / 0.15) ** 2)
            return 100.0 * np.log(noise.arw_deg_sqrth[0] / 0.5) ** 2 + f
        return nll
    start = [("a", ImuNoise(arw_deg_sqrth=0.5))]
    out = identify(nll_of(4.0), start, time_offset=True)
    assert out.time_offset_s == 0.0 and out.nhc
    assert "-190 ms found, but it lowers the NLL by only" in out.describe()
    deep = identify(nll_of(40.0), start, time_offset=True)
    assert deep.time_offset_s == pytest.approx(-0.19, abs=0.005) and not deep.nhc


# --- the simulated twin of the real car ------------------------------------------------

@pytest.fixture(scope="module")
def twin(tmp_path_factory):
    sys.path.insert(0, str(ROOT / "tests"))
    from real_car_twin import write_twin
    folder = tmp_path_factory.mktemp("twin")
    return folder, write_twin(folder)


def _ins():
    return str(Path(sys.executable).parent / "ins")


def _outage_errors(truth, journey, nav):
    from ins.io.navfiles import read_nav
    traj = read_nav(nav)
    s = truth.evaluate(traj.time)
    d = earth.ned_offset(s.lla, traj.lla)
    rel = traj.time - truth.t_start
    gap = np.zeros(len(rel), bool)
    for a, n in journey.outages:
        gap |= (rel >= a) & (rel < a + n)
    return d[gap], traj.time[gap]


def test_twin_with_no_preset_identifies_the_lag_and_the_noise(twin):
    """The twin (vibration that the integration averages out, scale errors of 3 %, the
    velocities 0.125 s late and not stated) with no preset: exit 0; the lag found within
    20 ms (14 ms seen: the likelihood trades it against the noise it cannot model), the
    IMU-GNSS offset (none given, the twin's clocks agree) below the 30 ms that is applied; the ARW identified far below the rest's sample scatter (the vibration does
    not survive the integration); the outages within 10 cm smoothed against the truth."""
    import re
    folder, (truth, journey, cfg) = twin
    out = folder / "out"
    p = subprocess.run([_ins(), "process", "--config", str(cfg), "-o", str(out), "--forward",
                        "--no-plots"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    line = next(ln for ln in p.stdout.splitlines() if ln.startswith("IMU noise:"))
    lag = float(re.search(r"GNSS velocity time shift ([-0-9.e]+)", line).group(1))
    assert abs(lag + 0.125) < 0.02, line
    # the twin's clocks agree and none was given: what the likelihood finds is below
    # what it can tell, and not applied
    found = re.search(r"IMU-GNSS time offset: ([-+0-9]+) ms found, below", line)
    assert found is not None and abs(float(found.group(1))) < 30, line
    arw = float(re.search(r"ARW ([0-9.e+-]+) deg/sqrt\(h\)", line).group(1))
    rest = float(re.search(r"ARW ([0-9.e+-]+) deg/sqrt\(h\) and VRW", p.stdout).group(1))
    assert arw < rest / 3, p.stdout
    d, _ = _outage_errors(truth, journey, out / "solution.nav")
    assert np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2)) < 0.10


def test_twin_without_identification_is_refused_as_the_real_car_was(twin):
    """The failure this reproduces: the same twin with the noise measured over the rest
    taken at face value (``[filter] identify = false``) is refused, exit 3, with
    recoveries, as the real car was before the identification."""
    folder, (truth, journey, cfg) = twin
    plain = folder / "plain.toml"
    plain.write_text(cfg.read_text() + "[filter]\nidentify = false\n")
    p = subprocess.run([_ins(), "process", "--config", str(plain), "-o", str(folder / "o2"),
                        "--no-plots", "-q"], capture_output=True, text=True)
    assert p.returncode == 3 and "recoveries from runs of rejected" in p.stderr


# --- the real car --------------------------------------------------------------------

def _score(nav):
    p = subprocess.run([sys.executable, str(DRIVE / "score.py"), str(nav)],
                       capture_output=True, text=True, check=True)
    last = p.stdout.strip().splitlines()[-1]
    rms = float(last.split("horizontal RMS ")[1].split(" m")[0])
    covered = int(last.split(" covered")[0].split()[-1])
    return rms, covered


@needs_drive
def test_real_drive_with_no_preset_beats_its_authors_filter(tmp_path):
    """The README's protocol with the facts of the hardware only (through the library:
    a refused run raises QualityError): every one of the 652 withheld fixes covered,
    smoothed below the author's 0.295 m over the outages and the forward filter below
    his 3.09 m without velocity matching (scored by the folder's own numpy scorer); the
    forward sigmas cover its errors in the outages (mean square of error / sigma per
    horizontal axis within 0.25-2); the identified velocity lag within 15 ms of the
    hardware's 0.125 s; no recovery."""
    from ins.estimation.pipeline.process import process
    from ins.estimation.pipeline.config import load_config
    from ins.io.navfiles import write_nav
    cfg = load_config(str(DRIVE / "config.toml"),
                      files={"imu": str(DRIVE / "imu.csv"),
                             "gnss": str(DRIVE / "gnss_outages.pos")})
    cfg.gnss_quality, cfg.gnss_quality_scale = "fix,float", "float=2"
    res = process(cfg)
    assert res.counts["recoveries"] == 0
    write_nav(tmp_path / "solution.nav", res.iter_smoothed())
    write_nav(tmp_path / "forward.nav", res.iter_forward())
    rms, covered = _score(tmp_path / "solution.nav")
    assert covered == 652 and rms < 0.295
    rms_f, _ = _score(tmp_path / "forward.nav")
    assert rms_f < 3.09
    assert abs(res.identified.velocity_shift_s + 0.125) < 0.015
    # the forward sigmas against its errors at the withheld fixes (the scorer's formulas)
    sys.path.insert(0, str(DRIVE))
    import score
    tf, la, lo, h, q = score.read_fixes(str(DRIVE / "gnss_full.pos"))
    wins = json.loads((DRIVE / "outages.json").read_text())["gps_week_seconds"]
    m = np.zeros(len(tf), bool)
    for a, b in wins:
        m |= (tf >= a - 1e-6) & (tf < b - 1e-6) & (q == 1)
    nav = np.loadtxt(tmp_path / "forward.nav")
    lat, lon = np.radians(nav[:, 2]), np.radians(nav[:, 3])
    C = score.c_nb(*np.radians(nav[:, 8:11]).T)
    r = score.lla_to_ecef(lat, lon, nav[:, 4]) + np.einsum(
        "nij,ni->nj", score.ned_rows(lat, lon), C @ np.array([0.0, -0.05, 0.0]))
    ri = np.column_stack([np.interp(tf[m], nav[:, 1], r[:, j]) for j in range(3)])
    d = np.einsum("nij,nj->ni", score.ned_rows(la[m], lo[m]),
                  ri - score.lla_to_ecef(la[m], lo[m], h[m]))
    s_n = np.interp(tf[m], res.node_time, res.forward_std[:, 0])
    s_e = np.interp(tf[m], res.node_time, res.forward_std[:, 1])
    for z in (d[:, 0] / s_n, d[:, 1] / s_e):
        assert 0.25 < np.mean(z ** 2) < 2.0
