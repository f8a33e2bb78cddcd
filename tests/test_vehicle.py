"""Land vehicles: the IMU's mounting rotation for the non-holonomic constraint
(``[vehicle] mounting_rpy_deg``, ins.estimation.tools.vehicle, ``ins vehicle-mounting``) and dual-antenna
headings (``[files] heading``, ins.estimation.pipeline.heading_files) on a simulated car
(tests/land_vehicle.py: an analytic drive, its truth written from its definition) with
a consumer-MEMS IMU mounted askew and 1 Hz GNSS positions with a 60 s outage."""
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ins.common.errors import InputError
from ins.estimation.tools.vehicle import estimate_mounting, mounting_dcm
from ins.io.gnss import write_gnss
from ins.io.gnss_log import GnssLog
from ins.io.imu_files import write_kfgins_text
from ins.nav import earth

sys.path.insert(0, str(Path(__file__).parent))
from land_vehicle import CarTruth  # noqa: E402

MOUNT_RPY_DEG = (1.0, 3.9, -1.5)      # the IMU in the car: roll, pitch, yaw
OUTAGE_S = (120.0, 60.0)              # start after the drive's start, length
GNSS_SIGMA_M = (0.5, 0.5, 1.0)


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def test_mounting_dcm_convention_by_hand():
    r, p, y = np.deg2rad(MOUNT_RPY_DEG)
    np.testing.assert_allclose(mounting_dcm(MOUNT_RPY_DEG), _rz(y) @ _ry(p) @ _rx(r),
                               atol=1e-15)
    # positive pitch = the IMU's nose up: its x axis has an upward (negative down)
    # component in the vehicle axes, and the forward velocity a downward one in b
    C = mounting_dcm([0.0, 5.0, 0.0])
    assert (C @ [1, 0, 0])[2] < 0 and (C.T @ [1, 0, 0])[2] > 0
    for bad in ([1.0, 2.0], [0, float("nan"), 0], "x"):
        with pytest.raises(InputError, match=r"\[roll, pitch, yaw\] in deg"):
            mounting_dcm(bad, "c.toml: [vehicle] mounting_rpy_deg")


def test_car_truth_is_consistent_and_holonomic():
    """The helper's truth: its IMU mechanized from its start stays on it (0.3 mm over
    240 s) and its velocity is along the vehicle's forward axis, not the IMU's."""
    from ins.nav.mechanization import NavState, mechanize
    from ins.simulate.imu_synth import synthesize_imu
    car = CarTruth(MOUNT_RPY_DEG)
    imu = synthesize_imu(car, 100.0)
    s = car.evaluate(imu.time[0])
    traj = mechanize(imu, NavState(s.lla[0], s.v_n[0], s.q_nb[0]))
    tr = car.evaluate(traj.time)
    assert np.max(np.abs(earth.ned_offset(tr.lla, traj.lla))) < 2e-3
    v_b = Rotation.from_quat(tr.q_nb).inv().apply(tr.v_n)
    v_v = v_b @ car.C_vb.T
    assert np.max(np.abs(v_v[:, 1:])) < 1e-9
    assert np.sqrt(np.mean(v_b[:, 2] ** 2)) > 0.5          # 3.9 deg of ~15 m/s


def test_estimate_mounting_from_the_truth():
    """On the true trajectory the estimated forward axis is the true one (any roll with
    its pitch and yaw is the same constraint), sigma ~0; too little straight driving is
    refused."""
    from ins.nav.trajectory import Trajectory
    car = CarTruth(MOUNT_RPY_DEG)
    t = np.arange(car.t_start, car.t_end, 0.05)
    tr = car.evaluate(t)
    traj = Trajectory(t, tr.lla, tr.v_n, tr.q_nb)
    for roll in (0.0, MOUNT_RPY_DEG[0]):
        m = estimate_mounting(traj, roll_deg=roll)
        fwd_b = mounting_dcm(m.rpy_deg).T @ [1, 0, 0]
        np.testing.assert_allclose(fwd_b, car.C_vb.T @ [1, 0, 0], atol=1e-12)
        assert np.all(m.sigma_deg < 1e-9)
    np.testing.assert_allclose(m.rpy_deg, MOUNT_RPY_DEG, atol=1e-9)
    short = Trajectory(t[:60], tr.lla[:60], tr.v_n[:60], tr.q_nb[:60])
    with pytest.raises(InputError, match="two blocks of straight driving"):
        estimate_mounting(short)


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """The car's files: imu.txt (consumer MEMS errors of the simulator's ``mems`` grade,
    seed 5), gnss.txt (1 Hz positions, 0.5/0.5/1 m noise, the outage), and the common
    part of the configs (the true start, the antenna at the IMU)."""
    from ins.simulate.imu_synth import synthesize_imu
    from ins.simulate.sensor_errors import ImuErrorModel, apply_errors
    d = tmp_path_factory.mktemp("drive")
    car = CarTruth(MOUNT_RPY_DEG)
    imu = apply_errors(synthesize_imu(car, 100.0), ImuErrorModel.preset("mems"), seed=5)
    tg = car.t_start + np.arange(1.0, car.t_end - car.t_start, 1.0)
    a, n = car.t_start + OUTAGE_S[0], OUTAGE_S[1]
    tg = tg[~((tg >= a) & (tg < a + n))]
    noise = np.random.default_rng(2).standard_normal((len(tg), 3)) * GNSS_SIGMA_M
    lla = earth.offset_lla(car.evaluate(tg).lla, noise)
    write_gnss(d / "gnss.txt", GnssLog(tg, lla, np.tile(GNSS_SIGMA_M, (len(tg), 1))))
    write_kfgins_text(d / "imu.txt", imu)
    s = car.evaluate(imu.time[0])
    rpy = Rotation.from_quat(s.q_nb[0]).as_euler("ZYX", degrees=True)[::-1]
    lat, lon, h = (float(x) for x in (*np.rad2deg(s.lla[0, :2]), s.lla[0, 2]))
    base = ('[files]\nimu = "imu.txt"\ngnss = "gnss.txt"\n'
            "[gnss]\nlever_arm_b_m = [0.0, 0.0, 0.0]\n"
            f"[initial]\nlat_deg = {lat!r}\nlon_deg = {lon!r}\nh_m = {h!r}\n"
            f"vel_ned_mps = {s.v_n[0].tolist()}\nrpy_deg = {rpy.tolist()}\n"
            f"time_s = {float(imu.time[0])!r}\npos_std_ned_m = [0.5, 0.5, 1.0]\n"
            "vel_std_ned_mps = [0.1, 0.1, 0.1]\natt_std_deg = [0.5, 0.5, 1.0]\n")
    return car, d, base


def run_drive(drive, name, extra="", preset="mems"):
    """Process the drive with ``base + extra`` and the preset; the figures against the
    truth (smoothed; the forward pass's worst horizontal error in the outage)."""
    from ins.estimation.pipeline.presets import apply_preset
    from ins.estimation.pipeline.process import process
    from ins.estimation.pipeline.config import load_config
    car, d, base = drive
    path = d / f"{name}.toml"
    path.write_text(base + "[filter]\nidentify = false\n" + extra)   # the NHC's mechanics
    cfg = apply_preset(load_config(path), preset)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = process(cfg, accept_poor=True)
    out = {"result": res, "rejected": res.counts["rejected"]}
    for which, traj in (("smoothed", res.smoothed), ("forward", res.forward)):
        tr = car.evaluate(traj.time)
        dn = earth.ned_offset(tr.lla, traj.lla)
        hor = np.hypot(dn[:, 0], dn[:, 1])
        rel = traj.time - car.t_start
        gap = (rel >= OUTAGE_S[0]) & (rel < OUTAGE_S[0] + OUTAGE_S[1])
        att = (Rotation.from_quat(traj.q_nb) * Rotation.from_quat(tr.q_nb).inv()).as_rotvec()
        out[which] = {"h_rms": np.sqrt(np.mean(hor ** 2)), "gap_max": hor[gap].max(),
                      "v_rms": np.sqrt(np.mean((traj.v_n - tr.v_n) ** 2, axis=0)),
                      "att_rms_deg": np.rad2deg(np.sqrt(np.mean(att ** 2, axis=0)))}
    return out


def _vehicle(rpy):
    return f"[vehicle]\nmounting_rpy_deg = {[float(x) for x in rpy]}\n"


@pytest.mark.slow
def test_nhc_with_the_mounting_beats_no_nhc_and_the_wrong_mounting(drive, tmp_path, capsys):
    """Measured (seed 5): forward-pass worst horizontal error in the 60 s outage / smoothed
    heading RMS: no NHC 40.1 m / 0.163 deg; NHC with the true mounting 5.8 m / 0.038;
    NHC in the IMU's axes (no mounting) 11.3 m / 0.295 deg and a smoothed horizontal RMS
    of 19 m (its fixes rejected); NHC with the mounting's sign flipped 130 m.  The
    mounting estimated from the no-NHC solution (pitch 3.915 +- 0.008, yaw -1.558 +-
    0.029 deg at roll 0, against 3.873 / -1.568 of the truth's forward axis) does as well
    as the true one: 5.9 m / 0.045 deg."""
    none = run_drive(drive, "none")
    right = run_drive(drive, "right", "[measurements]\nnhc = true\n" + _vehicle(MOUNT_RPY_DEG))
    ident = run_drive(drive, "identity", "[measurements]\nnhc = true\n")
    wrong = run_drive(drive, "wrong", "[measurements]\nnhc = true\n"
                      + _vehicle([0.0, -MOUNT_RPY_DEG[1], -MOUNT_RPY_DEG[2]]))
    f, s = "forward", "smoothed"
    assert right[f]["gap_max"] < 0.25 * none[f]["gap_max"]
    assert right[s]["att_rms_deg"][2] < 0.5 * none[s]["att_rms_deg"][2]
    assert right[s]["h_rms"] < none[s]["h_rms"] and right["rejected"] == 0
    for bad in (ident, wrong):
        assert bad[f]["gap_max"] > 1.5 * right[f]["gap_max"]
        assert bad[s]["h_rms"] > 10 * right[s]["h_rms"]
        assert bad[s]["att_rms_deg"][2] > 2 * right[s]["att_rms_deg"][2]
        assert bad["rejected"] > 50
    # the estimate from the first pass, through the command, then the land preset
    from ins.cli.main import main
    from ins.io.navfiles import write_nav
    car, d, _ = drive
    write_nav(tmp_path / "first.nav", none["result"].smoothed)
    assert main(["vehicle-mounting", str(tmp_path / "first.nav")]) == 0
    text = capsys.readouterr().out
    table = text[text.index("[vehicle]"):]
    import tomllib
    est = tomllib.loads(table)["vehicle"]["mounting_rpy_deg"]
    true_fwd = car.C_vb.T @ [1, 0, 0]
    err = np.rad2deg(np.arccos(np.clip(mounting_dcm(est).T @ [1, 0, 0] @ true_fwd, -1, 1)))
    assert est[0] == 0.0 and err < 0.1
    land = run_drive(drive, "land", table, preset="land")
    assert land[f]["gap_max"] < 0.25 * none[f]["gap_max"]
    assert land[s]["att_rms_deg"][2] < 0.5 * none[s]["att_rms_deg"][2]
    assert land["rejected"] == 0


def test_vehicle_table_in_the_config(tmp_path):
    from ins.estimation.pipeline.config import load_config
    p = tmp_path / "c.toml"
    p.write_text('[files]\nimu = "i.txt"\ngnss = "g.txt"\n[vehicle]\n'
                 "mounting_rpy_deg = [1.0, 3.9, -1.5]\n")
    cfg = load_config(p)
    np.testing.assert_allclose(cfg.measurements["nhc_C_vb"], mounting_dcm(MOUNT_RPY_DEG))
    p.write_text('[files]\nimu = "i.txt"\ngnss = "g.txt"\n[vehicle]\n'
                 "mounting_rpy_deg = [1.0, 3.9]\n")
    with pytest.raises(InputError, match=r"c.toml: \[vehicle\] mounting_rpy_deg"):
        load_config(p)
    p.write_text('[files]\nimu = "i.txt"\ngnss = "g.txt"\n[vehicle]\nmounting_rpy = [0, 0, 0]\n')
    with pytest.raises(InputError, match="mounting_rpy"):
        load_config(p)


# --- dual-antenna heading -----------------------------------------------------------------
BASELINE_B_M = (0.3, 1.2, -0.1)      # primary-to-secondary antenna, b frame
HEADING_SIGMA_DEG = 0.1


def _baseline_azimuth_deg(car, t):
    """True azimuth of the baseline (deg): C_nb from the truth, independent of the
    filter's measurement model."""
    b_n = Rotation.from_quat(car.evaluate(t).q_nb).apply(BASELINE_B_M)
    return np.rad2deg(np.arctan2(b_n[:, 1], b_n[:, 0]))


def test_heading_file_by_hand(tmp_path):
    from ins.estimation.pipeline.heading_files import read_headings, within, write_headings
    p = tmp_path / "h.txt"
    p.write_text("# time_s heading_deg sigma_deg\n100.0 350.0 0.2\n\n101.0, -10.5, 0.3\n"
                 "102.0 190.0 0.1  # comment\n")
    hs = read_headings(p, [0.0, 1.0, 0.0], time_shift_s=0.5)
    assert [h.time for h in hs] == [100.5, 101.5, 102.5]
    np.testing.assert_allclose([h.observed[0] for h in hs], np.deg2rad([350.0, -10.5, 190.0]))
    np.testing.assert_allclose([h.R[0, 0] for h in hs], np.deg2rad([0.2, 0.3, 0.1]) ** 2)
    np.testing.assert_array_equal(hs[0].baseline_b, [0.0, 1.0, 0.0])
    assert [h.time for h in within(hs, 101.0, 102.0)] == [101.5]
    # the residual wraps: 350 deg against -10.5 deg is 0.5 deg apart
    assert abs(np.rad2deg(hs[0].residual(hs[0].observed, hs[1].observed)[0]) - 0.5) < 1e-9
    two = tmp_path / "two.txt"
    two.write_text("100.0 10.0\n101.0 11.0\n")
    assert read_headings(two, [1, 0, 0], sigma_deg=0.25)[1].R[0, 0] == pytest.approx(
        np.deg2rad(0.25) ** 2)
    with pytest.raises(InputError, match="sigma_deg"):
        read_headings(two, [1, 0, 0])
    bad = tmp_path / "bad.txt"
    bad.write_text("100.0 10.0 0.1\n101.0 11.0 0.0\n")
    with pytest.raises(InputError, match=r"bad.txt:2: sigma_deg = 0.0: expected > 0"):
        read_headings(bad, [1, 0, 0])
    bad.write_text("100.0 10.0 0.1\n99.0 11.0 0.1\n")
    with pytest.raises(InputError, match="bad.txt:2: time not increasing"):
        read_headings(bad, [1, 0, 0])
    with pytest.raises(InputError, match="baseline_b_m"):
        read_headings(p, None)
    out = tmp_path / "w.txt"
    write_headings(out, [1.0, 2.0], [3.0, 4.0], 0.5)
    np.testing.assert_allclose(np.loadtxt(out), [[1, 3, 0.5], [2, 4, 0.5]])


@pytest.mark.slow
def test_dual_antenna_heading_improves_heading(drive):
    """Headings of the baseline at the GNSS epochs (0.1 deg noise, none in the outage),
    through [files] heading and [heading] baseline_b_m.  Measured (seed 5, no NHC),
    without -> with: smoothed heading error RMS 0.163 -> 0.015 deg, forward 0.534 ->
    0.031 deg, the smoothed heading sigma (RMS over the nodes) 0.251 -> 0.030 deg,
    forward worst horizontal error in the outage 40.1 -> 28.2 m (smoothed horizontal RMS
    0.50 -> 0.58 m, within the fixes' noise)."""
    from ins.estimation.pipeline.heading_files import write_headings
    car, d, _ = drive
    tg = np.loadtxt(d / "gnss.txt")[:, 0]
    head = (_baseline_azimuth_deg(car, tg)
            + np.random.default_rng(9).standard_normal(len(tg)) * HEADING_SIGMA_DEG)
    write_headings(d / "heading.txt", tg, head % 360.0, HEADING_SIGMA_DEG)
    none = run_drive(drive, "none")
    with_file = (car, d, drive[2].replace('gnss = "gnss.txt"\n',
                                          'gnss = "gnss.txt"\nheading = "heading.txt"\n'))
    dual = run_drive(with_file, "dual", "[heading]\nbaseline_b_m = [0.3, 1.2, -0.1]\n")
    for r in (none, dual):
        L = r["result"].fwd.layout
        r["head_sd"] = np.rad2deg(np.sqrt(np.mean(r["result"].smoothed_std[:, L.att][:, 2] ** 2)))
    f, s = "forward", "smoothed"
    assert dual[s]["att_rms_deg"][2] < 0.2 * none[s]["att_rms_deg"][2]
    assert dual[f]["att_rms_deg"][2] < 0.2 * none[f]["att_rms_deg"][2]
    assert dual["head_sd"] < 0.2 * none["head_sd"]
    assert dual[s]["att_rms_deg"][2] < 2 * dual["head_sd"]        # the sigma holds it
    assert dual[f]["gap_max"] < none[f]["gap_max"] and dual["rejected"] == 0
    innov = dual["result"].fwd.records
    assert sum(r.name == "heading" for r in innov) == len(tg)
