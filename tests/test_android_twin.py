"""The simulated twin of an Android phone log end to end (issue 34's Android item):
:mod:`ins.simulate.gnsslogger_writer` writes a GnssLogger log of a phone carried on a
walk (raw GPS L1, UncalGyro/UncalAccel on the boot clock, the phone's own fixes), then
the chain a user runs: ``ins import-android LOG -o DIR`` and ``ins process`` on DIR's
IMU and raw GNSS, tightly coupled on the RINEX with the navigation file and loosely on
RTKLIB's single point.  Checked against the simulator's truth, never against the
importer's formulas: the pseudoranges against the simulator's own (and against the
physics of its truth file), the IMU's time base against the boot clock the simulator
drew, the solutions against the truth trajectory."""
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

NAV = Path(__file__).resolve().parents[1] / ".." / "shared" / "real" / "rtklib_static_pair" \
    / "07590920.05n"
C = 299792458.0


# ---------------------------------------------------------------------------------------
# the truth at other epochs than the solution's (ins process --truth)

def _analytic(t, t0=300000.0):
    """A walk north at 2 m/s weaving 1 m east at 0.5 Hz and turning 0.1 rad/s: exact
    positions, velocities (to 1e-5 m/s: the radii of curvature change by 1e-5 over the
    40 m) and attitudes at ``t`` (s)."""
    from ins.nav.rotation import euler_to_quat
    from ins.nav.trajectory import Trajectory
    lat0, lon0, h = np.deg2rad(35.0), np.deg2rad(139.0), 50.0
    a, e2 = 6378137.0, 6.69437999014e-3
    M = a * (1 - e2) / (1 - e2 * np.sin(lat0) ** 2) ** 1.5
    N = a / np.sqrt(1 - e2 * np.sin(lat0) ** 2)
    w, s, n = 2 * np.pi * 0.5, t - t0, len(t)
    lla = np.column_stack([lat0 + 2.0 * s / (M + h),
                           lon0 + np.sin(w * s) / ((N + h) * np.cos(lat0)), np.full(n, h)])
    v = np.column_stack([np.full(n, 2.0), w * np.cos(w * s), np.zeros(n)])
    q = euler_to_quat(np.column_stack([np.zeros(n), np.zeros(n), 0.1 * s]))
    return Trajectory(t, lla, v, q)


@dataclass
class _Run:
    pieces: list
    errors_forward: object = None
    errors_smoothed: object = None

    def iter_forward(self):
        return iter(self.pieces)

    def iter_smoothed(self):
        return iter(self.pieces)


def test_truth_interpolated_to_a_solution_at_other_epochs(tmp_path):
    """A solution stamped at jittered 200 Hz epochs against a 10 Hz truth (the twin's
    truth.nav and a phone's sensor stamps) shares no epoch with it: the errors come from
    the truth interpolated to the solution's epochs (failed before: 'the trajectories
    share no epoch').  Against the analytic motion the interpolation leaves < 1 mm; a
    0.5 m north offset put into the solution comes out as 0.5 m."""
    from ins.estimation.pipeline.truth import with_truth
    from ins.io.navfiles import write_nav
    from ins.nav import earth
    from ins.nav.trajectory import Trajectory
    write_nav(tmp_path / "truth.nav", _analytic(300000.0 + np.arange(0, 20.01, 0.1)))
    rng = np.random.default_rng(1)
    est = _analytic(np.sort(300000.0 + 0.013 + np.arange(0, 19.9, 0.005)
                            + rng.normal(0, 2e-4, 3980)))
    out = with_truth(_Run([est]), tmp_path / "truth.nav")
    err = out.errors_forward
    assert len(err.time) == len(est.time)
    assert np.max(np.abs(err.pos_n)) < 1e-3
    assert np.max(np.abs(err.att_n)) < 1e-6
    moved = Trajectory(est.time, earth.offset_lla(est.lla, np.tile([0.5, 0.0, 0.0],
                                                                    (len(est.time), 1))),
                       est.v_n, est.q_nb)
    err = with_truth(_Run([moved]), tmp_path / "truth.nav").errors_smoothed
    assert np.allclose(err.pos_n[:, 0], 0.5, atol=1e-3)


# ---------------------------------------------------------------------------------------
# the twin

def _short_walk():
    from ins.simulate.gnsslogger_writer import ANDROID_WALK
    return replace(ANDROID_WALK, duration_s=90.0,
                   speed_steps=((6.0, 3.0, 1.5), (80.0, 2.0, -1.5)),
                   turns=((30.0, 4.0, 90.0), (55.0, 3.0, -90.0)), outages=())


@pytest.fixture(scope="module")
def twin(tmp_path_factory):
    pytest.importorskip("pyrtklib5", reason="RTKLIB's binding (extra 'gnss')")
    if not NAV.is_file():
        pytest.skip(f"{NAV}: the shared real data are not here")
    from ins.cli.main import main
    from ins.simulate.gnsslogger_writer import write_android_journey
    d = tmp_path_factory.mktemp("twin")
    facts = write_android_journey(d / "phone", NAV, journey=_short_walk(), seed=3)
    assert main(["import-android", str(d / "phone" / "gnss_log.txt"), "-o",
                 str(d / "imp"), "-q"]) == 0
    (d / "hw.toml").write_text("[gnss]\nlever_arm_b_m = [0.0, 0.0, 0.0]\n")
    return d, facts


def _epochs_of(truth_rows):
    t = truth_rows["time_gps_s"]
    return np.unique(t), t


@pytest.mark.slow
def test_twin_pseudoranges_are_the_simulators(twin):
    """The RINEX of import-android holds the simulator's pseudoranges (its truth file's
    ``pseudorange_m``) to the 0.5 mm of the RINEX's 3 decimals, each at the epoch the
    phone's clock estimates (true GPS time + the chip clock's bias, to the 100 ns of a
    RINEX epoch); and those are the physics of the truth file: pseudorange - (range +
    clock - satellite clock + iono + tropo + multipath) is the white code noise,
    2 m / sin(el) (standardized RMS measured ~1)."""
    from ubx_frames import read_rinex3_obs
    d, facts = twin
    tr = np.genfromtxt(d / "phone" / "android_truth.csv", delimiter=",", names=True)
    conv = read_rinex3_obs(d / "imp" / "gnss.obs")
    t_gps, t_row = _epochs_of(tr)
    assert len(conv) == len(t_gps)
    worst = 0.0
    for k, (ymdhms, rows) in enumerate(conv):
        sel = t_row == t_gps[k]
        bias_s = tr["clock_bias_m"][sel][0] / C
        sod = ymdhms[3] * 3600 + ymdhms[4] * 60 + ymdhms[5]
        assert abs(sod - ((t_gps[k] + bias_s) % 86400)) < 1e-7
        for svid, pr in zip(tr["svid"][sel], tr["pseudorange_m"][sel]):
            worst = max(worst, abs(rows[f"G{int(svid):02d}"]["C1C"] - pr))
    assert worst <= 0.5e-3 + 1e-6           # the RINEX rounds to 1 mm, the CSV to 1 um
    model = (tr["range_m"] + tr["clock_bias_m"] - tr["sat_clock_m"] + tr["iono_m"]
             + tr["tropo_m"] + tr["multipath_m"])
    z = (tr["pseudorange_m"] - model) / (facts["raw"]["sigma_code_m"]
                                         / np.sin(np.deg2rad(tr["elevation_deg"])))
    assert 0.8 < np.sqrt(np.mean(z ** 2)) < 1.2 and abs(np.mean(z)) < 0.2


@pytest.mark.slow
def test_twin_imu_on_gps_time(twin):
    """imu.csv's times are the sensors' boot-clock stamps on GPS time: against the boot
    clock the simulator drew (offset at the start, 3.7 ppm), each stamp lands within
    the chip clock's bias (the phone's GPS time is t_gps + bias, at most
    ``clock_bias_abs_max_s``: ~8 us here) plus 2 us (the line's fit through 300 ns of
    ChipsetElapsedRealtimeNanos noise, the CSV's 1 us) of its true GPS time; the
    gyro's 200 Hz samples all come through (but for the ends outside the accelerometer's
    span), in the FRD axes of the walk's body."""
    from ins.io.gnsslogger import read_gnsslogger
    d, facts = twin
    a = np.loadtxt(d / "imp" / "imu.csv", delimiter=",", skiprows=2)
    log = read_gnsslogger(d / "phone" / "gnss_log.txt")
    e = np.array(log.tables["UncalGyro"]["elapsedRealtimeNanos"], dtype=np.int64)
    bc = facts["boot_clock"]
    t_true = facts["journey_start_gps_s"] + (e - bc["elapsed_at_start_ns"]) * 1e-9 / (
        1 + bc["rate_ppm"] * 1e-6)
    t_true = np.sort(t_true)
    k = np.clip(np.searchsorted(t_true, a[:, 0]), 1, len(t_true) - 1)
    near = np.where(np.abs(t_true[k] - a[:, 0]) < np.abs(t_true[k - 1] - a[:, 0]),
                    t_true[k], t_true[k - 1])
    off = a[:, 0] - near
    bound = facts["chip_clock"]["clock_bias_abs_max_s"] + 2e-6
    assert np.max(np.abs(off)) <= bound
    assert len(a) >= facts["sensors"]["n_gyro"] - 3
    # the clock bias is the phone's GPS time minus the truth: the offsets follow it
    assert facts["chip_clock"]["clock_bias_s_first"] - 2e-6 < np.median(off[:200]) < \
        facts["chip_clock"]["clock_bias_s_first"] + 2e-6
    # at rest (the first 4 s) the specific force is gravity in the body, ~ -g along z
    # tilted by the walk's -20 deg pitch: f_x = -g sin 20 deg, biases ~0.2 m/s^2
    rest = a[:, 0] < facts["journey_start_gps_s"] + 4.0
    f = a[rest, 4:7].mean(axis=0)
    assert abs(np.linalg.norm(f) - 9.8) < 0.4 and abs(f[0] + 9.8 * np.sin(np.deg2rad(20))) < 0.5


def _process(d, coupling):
    from ins.cli.main import main
    args = ["process", "--imu", str(d / "imp" / "imu.csv"), "--rover",
            str(d / "imp" / "gnss.obs"), "--nav", str(d / "phone" / "rover.nav"),
            "--config", str(d / "hw.toml"), "--preset", "consumer", "--no-plots",
            "--truth", str(d / "phone" / "truth.nav"), "-q", "-o", str(d / coupling)]
    if coupling == "tight":
        args += ["--coupling", "tight"]
    assert main(args) == 0


def _horizontal_rms(d, what):
    from ins.io.navfiles import read_nav
    from ins.io.rtklib import read_pos
    from ins.nav.interpolation import interpolate_trajectory
    truth = read_nav(d / "phone" / "truth.nav")
    s = read_pos(what) if str(what).endswith(".pos") else read_nav(what)
    t = np.asarray(s.time)
    k = (t >= truth.time[0]) & (t <= truth.time[-1])
    ref = interpolate_trajectory(truth, t[k])
    dn = (np.asarray(s.lla)[k, 0] - ref.lla[:, 0]) * 6378137.0
    de = (np.asarray(s.lla)[k, 1] - ref.lla[:, 1]) * 6378137.0 * np.cos(ref.lla[:, 0])
    return float(np.sqrt(np.mean(dn ** 2 + de ** 2)))


@pytest.mark.slow
@pytest.mark.parametrize("coupling", ["tight", "loose"])
def test_twin_chain_against_the_truth(twin, coupling):
    """``ins process`` on the imported phone log, tight (pseudoranges and Dopplers of the
    RINEX with the navigation file) and loose (RTKLIB's single point with its Doppler
    velocities), --preset consumer, against the simulator's truth (--truth: the 10 Hz
    truth interpolated to the jittered IMU epochs).  Measured on this 90 s walk (seed
    3): the phone's fixes 3.7 m horizontal RMS, RTKLIB's single point 6.7 m, tight
    1.1 m, loose 2.1 m (the 240 s walk of bench/bench_android.py: 4.5, 6.7, 3.6,
    3.4 m).  Bound: 3 m and 0.6 of the single point's own RMS (an IMU time base off
    by 50 ms, a wrong axis or a lost rest put the walk tens of metres off)."""
    d, facts = twin
    _process(d, coupling)
    h = _horizontal_rms(d, d / coupling / "solution.nav")
    spp = _horizontal_rms(d, d / coupling / "gnss.pos")
    print(f"{coupling}: solution {h:.2f} m, single point {spp:.2f} m, phone fixes "
          f"{_horizontal_rms(d, d / 'imp' / 'fix.pos'):.2f} m (horizontal RMS vs truth)")
    assert h < 3.0 and h < 0.6 * spp


def test_twin_refuses_a_journey_outside_the_ephemerides(tmp_path):
    """A journey the navigation file does not cover is refused at once, naming the file
    and the span (before the truth is integrated); settings out of range likewise."""
    from ins.common.errors import InputError
    from ins.simulate.gnsslogger_writer import ANDROID_WALK, PhoneSettings, \
        write_android_journey
    if not NAV.is_file():
        pytest.skip(f"{NAV}: the shared real data are not here")
    with pytest.raises(InputError, match="do not cover the journey.*GPS week 1316, "
                                         "100000-100240 s") as e:
        write_android_journey(tmp_path / "x", NAV, journey=replace(ANDROID_WALK, t0=1e5))
    assert "07590920.05n" in str(e.value) and not (tmp_path / "x").exists()
    with pytest.raises(ValueError, match="bias_nanos: expected ns in"):
        PhoneSettings(bias_nanos=1.5)


def test_simulate_phone_refuses_a_missing_navigation_file(tmp_path, capsys):
    """``ins simulate-phone``: a --nav that is not there is a bad input (exit 2, naming
    it), and nothing is written."""
    from ins.cli.main import main
    try:
        code = main(["simulate-phone", str(tmp_path / "out"), "--nav",
                     str(tmp_path / "none.nav")])
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    assert "none.nav: no such file" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
