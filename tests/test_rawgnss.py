"""Raw GNSS in: u-blox logs through RTKLIB's convrnx (ins.gnss.ubx), precise orbits
(SP3), the forward/backward separation (ins.gnss.separation) and ``ins process`` from
raw observations (ins.estimation.pipeline.gnss_source), on the real GEONET pair 0759/3040.

Truths: the pair's own RINEX observations and navigation (a u-blox log encoded from
them frame by frame, RXM-RAWX and RXM-SFRBX, tests/ubx_frames.py, must convert back to
the same values); an SP3 synthesized
from the broadcast orbits (tests/sp3_synth.py) must give the broadcast solution, and a
shortened one is refused (RTKLIB itself would end the solution where it ends); the separation against pymap3d's
geodetic-to-ENU of the two RTKLIB runs, and against offsets put in by hand; the
processed trajectory of an IMU at rest against RTKLIB's static solution of the hour."""
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from ins.common.errors import InputError, InputWarning

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ubx_frames import (  # noqa: E402
    frame,
    read_rinex2_obs,
    read_rinex3_obs,
    rinex2_to_ubx,
    rinex2_to_ubx_with_nav,
)

ROOT = Path(__file__).resolve().parents[1]
PAIR = ROOT.parent / "shared" / "real" / "rtklib_static_pair"
ROVER, BASE, NAV = (str(PAIR / n) for n in ("07590920.05o", "30400920.05o", "07590920.05n"))
WEEK, T0, T1 = 1316, 518400.0, 521970.0       # the hour of the pair, GPS s of week
needs_pair = pytest.mark.skipif(not PAIR.is_dir(), reason="../shared/real is absent")
GPS = ("gps",)


def _rtk():
    return pytest.importorskip("pyrtklib5")


def test_ubx_checksum_is_the_spec_example():
    # UBX-ACK-ACK of CFG-PRT (class 05 id 01, length 2, payload 06 00): B5 62 05 01 02
    # 00 06 00 0E 37, the checksum printed in u-blox interface descriptions
    assert frame(0x05, 0x01, bytes([0x06, 0x00])).hex() == "b56205010200060" "00e37"
    from ins.io.ublox import ubx_checksum       # the readers' own (one for both)
    assert ubx_checksum(bytes.fromhex("050102000600")) == bytes.fromhex("0e37")


def test_separation_of_known_offsets():
    """Forward = backward moved by known N/E/U offsets (through ECEF with pymap3d);
    unmatched epochs are left out."""
    pymap3d = pytest.importorskip("pymap3d")
    from ins.gnss.separation import separation
    rng = np.random.default_rng(3)
    n = 20
    t = T0 + 30.0 * np.arange(n)
    lat0, lon0, h0 = 35.16, 139.61, 70.0
    lla_b = np.column_stack([np.radians(lat0 + 1e-5 * rng.standard_normal(n)),
                             np.radians(lon0 + 1e-5 * rng.standard_normal(n)),
                             h0 + rng.standard_normal(n)])
    d_neu = rng.normal(0, 0.5, (n, 3))
    lat, lon, h = pymap3d.enu2geodetic(d_neu[:, 1], d_neu[:, 0], d_neu[:, 2],
                                       lla_b[:, 0], lla_b[:, 1], lla_b[:, 2], deg=False)
    lla_f = np.column_stack([lat, lon, h])
    q = np.ones(n, int)
    q[3] = 2
    fwd = SimpleNamespace(time=t[1:], lla=lla_f[1:], quality=q[1:])
    bwd = SimpleNamespace(time=t[:-1] + 2e-4, lla=lla_b[:-1], quality=np.ones(n - 1, int))
    sep = separation(fwd, bwd)
    assert np.allclose(sep.time, t[1:-1])
    assert np.allclose(sep.d_neu_m, d_neu[1:-1], atol=1e-6)
    assert sep.both_fixed.sum() == n - 3
    assert sep.fixed_disagreements == np.sum(np.linalg.norm(d_neu[1:-1], axis=1)[
        q[1:-1] == 1] > 0.005)
    nn, rms, mx, _ = sep.stats()
    assert nn == n - 2 and np.allclose(rms, np.sqrt(np.mean(d_neu[1:-1] ** 2, axis=0)))


@needs_pair
def test_ubx_converts_back_to_the_rinex_observations(tmp_path):
    """The rover's RINEX 2.10 observations (C1, L1, P2, L2), encoded as UBX RXM-RAWX
    frames, come out of convrnx as RINEX 3.04 with every value of every epoch equal."""
    rtk = _rtk()
    from ins.gnss.ubx import convert_ubx, is_ubx
    ubx = tmp_path / "rover.ubx"
    ubx.write_bytes(rinex2_to_ubx(ROVER))
    assert is_ubx(ubx)
    (tmp_path / "noext").write_bytes(ubx.read_bytes()[:100])
    assert is_ubx(tmp_path / "noext") and not is_ubx(ROVER)
    obs, nav = convert_ubx(ubx, str(tmp_path), rtk)
    assert nav is None                             # no RXM-SFRBX in the log
    orig = read_rinex2_obs(ROVER)
    conv = read_rinex3_obs(obs)
    assert len(orig) == len(conv) == 120
    pairs = {"C1": "C1C", "L1": "L1C", "P2": "C2X", "L2": "L2X"}
    compared = 0
    for (week, tow, rows), (ymdhms, rows3) in zip(orig, conv):
        h, mi, s = ymdhms[3:]
        assert abs((tow - 518400.0) - (3600 * h + 60 * mi + s)) < 1e-6
        assert set(rows) == set(rows3)
        for sat, v in rows.items():
            for t2, t3 in pairs.items():
                a, b = v[t2][0], rows3[sat][t3]
                assert (np.isnan(a) and np.isnan(b)) or abs(a - b) < 5e-4, (sat, t2)
                compared += 1
    assert compared > 3000


@needs_pair
def test_ubx_rover_gives_the_rinex_solution(tmp_path):
    """Kinematic PPK from the u-blox log = from the RINEX file (same epochs, Q and
    positions); the CLI takes --rover x.ubx."""
    _rtk()
    from ins.cli.main import main
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    ubx = tmp_path / "rover.ubx"
    ubx.write_bytes(rinex2_to_ubx(ROVER))
    opts = RtklibOptions(systems=GPS)
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE, options=opts)
    b = solve(ubx, NAV, tmp_path / "ubx.pos", base=BASE, options=opts)
    assert b.rover_epochs == a.rover_epochs == 120
    assert np.array_equal(a.log.time, b.log.time)
    assert np.array_equal(a.log.quality, b.log.quality)
    from ins.nav.earth import ned_offset
    assert np.max(np.abs(ned_offset(a.log.lla, b.log.lla))) < 2e-4
    assert sorted(os.listdir(tmp_path)) == ["rinex.pos", "rover.ubx", "ubx.pos"]
    cfg = tmp_path / "gps.toml"
    cfg.write_text('[rtklib]\nsystems = ["gps"]\n')
    assert main(["gnss", "--rover", str(ubx), "--base", BASE, "--nav", NAV, "--config",
                 str(cfg), "--no-separation", "-o", str(tmp_path / "cli.pos")]) == 0


SC = 3.1415926535898 * 2.0 ** -31                 # a semicircle unit of 2^-31, rad
#: ephemeris fields and the unit of their broadcast integer (IS-GPS-200)
EPH_UNITS = {"e": 2.0 ** -33, "i0": SC, "OMG0": SC, "omg": SC, "M0": SC,
             "deln": SC * 2.0 ** -12, "OMGd": SC * 2.0 ** -12, "idot": SC * 2.0 ** -12,
             "crc": 2.0 ** -5, "crs": 2.0 ** -5, "cuc": 2.0 ** -29, "cus": 2.0 ** -29,
             "cic": 2.0 ** -29, "cis": 2.0 ** -29, "toes": 16.0, "f0": 2.0 ** -31,
             "f1": 2.0 ** -43, "f2": 2.0 ** -55}


@needs_pair
def test_ubx_ephemerides_convert_back_to_the_rinex_navigation(tmp_path):
    """Every GPS ephemeris of the pair's RINEX navigation file, encoded as LNAV
    subframes 1-3 in RXM-SFRBX frames (the 10-bit week of 2005), comes out of convrnx
    with the same values, in week 1316 (not in the era of the computer's clock), and
    the log alone (no --nav) gives the RINEX solution.  "The same": within half a unit
    of each field's broadcast integer (a few values of the 2005 file are off that grid:
    G01's delta-n by 0.26 unit), sqrt(A) within half of 2^-19 m^0.5."""
    rtk = _rtk()
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.gnss.ubx import convert_ubx, first_rawx_time
    data, ephs = rinex2_to_ubx_with_nav(ROVER, NAV, rtk)
    ubx = tmp_path / "rover.ubx"
    ubx.write_bytes(data)
    assert first_rawx_time(ubx) == (WEEK, T0)
    _, nav_path = convert_ubx(ubx, str(tmp_path), rtk)
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    rtk.readrnx(nav_path, 1, "", obs, nav, sta)
    w = rtk.Arr1Dint(1)
    conv = {}
    for i in range(nav.n):
        e = nav.eph[i]
        tow = rtk.time2gpst(e.toe, w)
        conv[(e.sat, w[0], tow)] = e
    assert len(ephs) > 100
    for e in ephs:
        tow = rtk.time2gpst(e.toe, w)
        c = conv[(e.sat, w[0], tow)]             # KeyError: lost, or in another week
        for name, unit in EPH_UNITS.items():
            a, b = getattr(e, name), getattr(c, name)
            assert abs(a - b) <= 0.5 * unit * (1 + 1e-9), (e.sat, name, a, b)
        assert abs(np.sqrt(c.A) - np.sqrt(e.A)) <= 0.5 * 2.0 ** -19
        assert (c.iode, c.iodc, c.svh, c.sva) == (e.iode, e.iodc, e.svh, e.sva)
        assert abs(c.tgd[0] - e.tgd[0]) < 1e-15
    opts = RtklibOptions(systems=GPS)
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE, options=opts)
    b = solve(ubx, None, tmp_path / "ubx.pos", base=BASE, options=opts)
    assert np.array_equal(a.log.time, b.log.time)
    assert np.array_equal(a.log.quality, b.log.quality)
    from ins.nav.earth import ned_offset
    # the log's SFRBX frames hold subframes 1-3 only, not the Klobuchar coefficients of
    # subframe 4: RTKLIB takes its default ionosphere, whose difference over the 3.3 km
    # baseline is about a millimetre in height (0.2 mm here only while RTKLIB kept the
    # previous run's coefficients in its globals: each run now has a process of its own)
    d = np.abs(ned_offset(a.log.lla, b.log.lla))
    assert np.max(d[:, :2]) < 5e-4 and np.max(d[:, 2]) < 2e-3


@needs_pair
def test_ubx_errors(tmp_path):
    rtk = _rtk()
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.ubx import convert_ubx
    bad = tmp_path / "junk.ubx"
    bad.write_bytes(b"\xb5\x62" + bytes(200))
    with pytest.raises(InputError, match=r"junk\.ubx.*no observation.*RXM-RAWX"):
        convert_ubx(bad, str(tmp_path), rtk)
    ubx = tmp_path / "rover.ubx"
    ubx.write_bytes(rinex2_to_ubx(ROVER))
    with pytest.raises(InputError, match=r"rover\.ubx.*broadcast navigation.*RXM-SFRBX"):
        solve(ubx, None, tmp_path / "a.pos", base=BASE)
    with pytest.raises(InputError, match=r"junk\.ubx.*no observation"):
        solve(bad, NAV, tmp_path / "a.pos", base=BASE)
    assert sorted(os.listdir(tmp_path)) == ["junk.ubx", "rover.ubx"]


@pytest.fixture(scope="module")
def sp3_files(tmp_path_factory):
    rtk = _rtk()
    if not PAIR.is_dir():
        pytest.skip("../shared/real is absent")
    from sp3_synth import satellite_states, write_sp3
    d = tmp_path_factory.mktemp("sp3")
    tows = np.arange(T0 - 3600.0, T1 + 3600.0 + 1.0, 300.0)
    states = satellite_states(rtk, NAV, WEEK, tows, 0.5 * (T0 + T1))
    full = write_sp3(d / "brdc.sp3", rtk, states, WEEK, tows)
    short = write_sp3(d / "short.sp3", rtk, states, WEEK, tows[:20])     # to 00:35
    return full, short, tows


def test_precise_orbits_are_used(sp3_files, tmp_path):
    """An SP3 of the broadcast orbits gives the broadcast solution within a millimetre
    (measured 0.6 mm; the 3.3 km baseline differences out orbit errors); one that ends
    at 00:35 is refused, naming it (ins.gnss.products.check_coverage), and RTKLIB run
    past the check ends the solution shortly after: it took the orbits from the SP3."""
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.nav.earth import ned_offset
    full, short, tows = sp3_files
    opts = RtklibOptions(systems=GPS)
    b = solve(ROVER, NAV, tmp_path / "brdc.pos", base=BASE, options=opts)
    p = solve(ROVER, NAV, tmp_path / "prec.pos", base=BASE, options=opts, sp3=[full])
    assert (b.ephemeris, p.ephemeris) == ("broadcast", "precise")
    assert np.array_equal(b.log.time, p.log.time)
    assert np.array_equal(b.log.quality, p.log.quality)
    assert np.max(np.abs(ned_offset(b.log.lla, p.log.lla))) < 2e-3
    with pytest.raises(InputError, match=r"precise orbits \(--sp3\) .*short\.sp3 cover .* "
                                         r"not the observations'"):
        solve(ROVER, NAV, tmp_path / "short.pos", base=BASE, options=opts, sp3=[short])
    assert sorted(os.listdir(tmp_path)) == ["brdc.pos", "prec.pos"]
    # RTKLIB itself, past the check: the solution ends shortly after the orbits
    from ins.gnss.rtklib_engine import _postpos_isolated
    from ins.io.rtklib import read_pos
    out = tmp_path / "short.pos"
    _postpos_isolated(opts, True, [ROVER, BASE, NAV, str(short)], str(out))
    s = read_pos(out)
    end_sp3 = tows[19]
    assert s.time[-1] < T1 - 300.0 and s.time[-1] < end_sp3 + 1800.0
    assert len(s) < len(b.log) - 10


@needs_pair
def test_separation_cli_against_pymap3d(tmp_path, capsys):
    """``ins gnss`` kinematic: the separation file is forward minus backward of the
    two RTKLIB runs (checked with pymap3d); both fixed, the two directions print the
    same position (same integers); the figure is written."""
    _rtk()
    pymap3d = pytest.importorskip("pymap3d")
    from ins.cli.main import main
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    cfg = tmp_path / "gps.toml"
    cfg.write_text('[rtklib]\nsystems = ["gps"]\n')
    out = tmp_path / "rover.pos"
    assert main(["gnss", ROVER, "--base", BASE, "--nav", NAV, "--config", str(cfg),
                 "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "forward/backward separation N/E/U (115 epochs both solved)" in text
    assert sorted(os.listdir(tmp_path)) == ["gps.toml", "rover.pos",
                                            "rover_fwd_bwd_separation.png",
                                            "rover_fwd_bwd_separation.txt"]
    assert (tmp_path / "rover_fwd_bwd_separation.png").read_bytes()[:4] == b"\x89PNG"
    rows = np.loadtxt(tmp_path / "rover_fwd_bwd_separation.txt")
    runs = {d: solve(ROVER, NAV, tmp_path / f"{d}.pos", base=BASE,
                     options=RtklibOptions(systems=GPS, direction=d)).log
            for d in ("forward", "backward")}
    f, b = runs["forward"], runs["backward"]
    common, i_f, i_b = np.intersect1d(f.time, b.time, return_indices=True)
    assert np.array_equal(rows[:, 0], common)
    e, n, u = pymap3d.geodetic2enu(f.lla[i_f, 0], f.lla[i_f, 1], f.lla[i_f, 2],
                                   b.lla[i_b, 0], b.lla[i_b, 1], b.lla[i_b, 2], deg=False)
    assert np.allclose(rows[:, 1:4], np.column_stack([n, e, u]), atol=1e-4)
    both = (rows[:, 4] == 1) & (rows[:, 5] == 1)
    assert both.sum() > 100 and np.all(np.abs(rows[both, 1:4]) < 1e-3)
    assert np.max(np.abs(rows[~both, 1:4])) > 0.1      # the float starts of each run


# --------------------------------------------------------------------------------------
# ins process from raw observations

def _static_imu(path, duration_s=600.0):
    """Exact increments of an IMU at rest at the rover, 10 Hz from T0 (GPS s)."""
    from scipy.spatial.transform import Rotation

    from ins.io.imu_files import write_kfgins_text
    from ins.nav import earth
    from ins.nav.imu import ImuLog
    lat, h, rate = np.radians(35.160875), 70.27, 10.0
    n = int(duration_s * rate) + 1
    C_nb = Rotation.from_euler("ZYX", [40.0, -0.3, 0.5], degrees=True).as_matrix()
    f_b = C_nb.T @ (-earth.gravity_n(lat, h))
    w_b = C_nb.T @ earth.earth_rate_n(lat)
    write_kfgins_text(path, ImuLog(T0 + np.arange(n) / rate, np.tile(w_b / rate, (n, 1)),
                                   np.tile(f_b / rate, (n, 1))))


CONFIG = """
[files]
imu = "imu.txt"
{files}
[rtklib]
systems = ["gps"]
{rtklib}
[initial]
vel_ned_mps = [0, 0, 0]
rpy_deg = [0.5, -0.3, 40.0]
[imu_noise]
arw_deg_sqrth = 0.003
vrw_mps_sqrth = 0.03
gyro_bias_std_dph = 0.5
accel_bias_std_mgal = 50.0
corr_time_h = 4.0
[gnss]
lever_arm_b_m = [0, 0, 0]
[alignment]
method = "given"
"""
RAW_FILES = f'rover = "{ROVER}"\nbase = "{BASE}"\nnav = ["{NAV}"]'


def _config(folder, files=RAW_FILES, rtklib=""):
    _static_imu(folder / "imu.txt")
    cfg = folder / "cfg.toml"
    cfg.write_text(CONFIG.format(files=files, rtklib=rtklib))
    return cfg


@needs_pair
def test_process_from_raw_gnss(tmp_path, capsys):
    """``ins process`` with [files] rover/base/nav: gnss.pos in the output folder (the
    same solution as ``ins gnss``), the summary names the source, and the trajectory of
    the IMU at rest sits on RTKLIB's static position of the hour."""
    _rtk()
    from ins.cli.main import main
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.navfiles import read_trajectory
    from ins.nav.earth import ned_offset
    cfg = _config(tmp_path)
    out = tmp_path / "out"
    assert main(["process", "--config", str(cfg), "--no-plots", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert (f"GNSS source: RTKLIB kinematic, combined, broadcast ephemeris -> {out}/gnss.pos: "
            f"115 of 120 rover epochs solved (fix 115); covariance screen: 0 repaired, "
            f"0 dropped") in text
    assert "forward/backward separation" in text
    names = set(os.listdir(out))
    assert {"gnss.pos", "fwd_bwd_separation.txt", "solution.nav"} <= names
    assert "fwd_bwd_separation.png" not in names                 # --no-plots
    assert not any(n.startswith(".") for n in names)
    ref = solve(ROVER, NAV, tmp_path / "ref.pos", base=BASE,
                options=RtklibOptions(systems=GPS)).log
    static = solve(ROVER, NAV, tmp_path / "static.pos", base=BASE,
                   options=RtklibOptions(systems=GPS, mode="static",
                                         direction="forward")).log
    from ins.io.rtklib import read_pos
    got = read_pos(out / "gnss.pos")
    assert np.array_equal(got.lla, ref.lla) and np.array_equal(got.quality, ref.quality)
    traj = read_trajectory(out / "solution.nav")
    d = ned_offset(static.lla[-1], traj.lla)
    assert traj.time[0] == T0 and traj.time[-1] >= T0 + 590.0
    assert np.all(np.abs(d) < [0.02, 0.02, 0.04])        # fixes: 3/5/10 mm scatter


@needs_pair
def test_process_dynamics_on_screened_in_the_run(tmp_path, capsys):
    """[rtklib] dynamics = true: RTKLIB's invalid sd columns of the run's own gnss.pos
    are screened (repaired) and counted in the summary; the run goes through."""
    _rtk()
    from ins.cli.main import main
    cfg = _config(tmp_path, rtklib="dynamics = true")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["process", "--config", str(cfg), "--no-plots", "-o",
                     str(tmp_path / "out")]) == 0
    text = capsys.readouterr().out
    line = next(t for t in text.splitlines() if "covariance screen:" in t)
    repaired = int(line.split("covariance screen: ")[1].split(" repaired")[0])
    dropped = int(line.split("repaired, ")[1].split(" dropped")[0])
    assert repaired + dropped > 60


@needs_pair
def test_user_pos_with_invalid_covariances_is_screened(tmp_path):
    """A .pos a user brings (RTKLIB kinematic, dynamics on) read as ``ins process``
    reads [files] gnss: repaired with a warning, every covariance positive definite."""
    _rtk()
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.gnss import read_gnss
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        solve(ROVER, NAV, tmp_path / "dyn.pos", base=BASE,
              options=RtklibOptions(systems=GPS, dynamics=True))
    with pytest.warns(InputWarning, match="not a covariance"):
        log = read_gnss(tmp_path / "dyn.pos")
    assert log.screen.repaired_lines.size + log.screen.dropped_lines.size > 60
    assert np.all(np.linalg.eigvalsh(log.cov_ned_m2) > 0)


def test_raw_gnss_config_errors(tmp_path, monkeypatch):
    from ins.estimation.pipeline.config import load_config
    (tmp_path / "imu.txt").write_text("")
    cfg = tmp_path / "c.toml"
    cfg.write_text('[files]\nimu = "imu.txt"\ngnss = "g.pos"\nrover = "r.obs"\n'
                   'nav = "n.nav"\n')
    with pytest.raises(InputError, match=r"c\.toml: \[files\] gnss: give either"):
        load_config(cfg)
    cfg.write_text('[files]\nimu = "imu.txt"\nbase = "b.obs"\nnav = "n.nav"\n')
    with pytest.raises(InputError, match=r"c\.toml: \[files\] rover: missing"):
        load_config(cfg)
    cfg.write_text('[files]\nimu = "imu.txt"\nrover = "r.obs"\nnav = 3\n')
    with pytest.raises(InputError, match=r"\[files\] nav: expected a path or a list"):
        load_config(cfg)
    cfg.write_text('[files]\nimu = "imu.txt"\nrover = "r.obs"\nnav = "n"\n'
                   '[rtklib]\nelevation_mask = 10\n')
    with pytest.raises(InputError, match=r"c\.toml: \[rtklib\] elevation_mask: unknown key"):
        load_config(cfg)
    cfg.write_text('[files]\nimu = "imu.txt"\ngnss = "g.pos"\n[rtklib]\nmode = "static"\n')
    with pytest.raises(InputError, match=r"\[rtklib\]: RTKLIB's settings without raw"):
        load_config(cfg)
    cfg.write_text('[files]\nimu = "imu.txt"\nrover = "r.obs"\nnav = ["a.n", "b.n"]\n'
                   '[rtklib]\nmode = "single"\n')
    c = load_config(cfg)
    assert c.gnss is None and c.gnss_raw.rover == str(tmp_path / "r.obs")
    assert c.gnss_raw.nav == (str(tmp_path / "a.n"), str(tmp_path / "b.n"))
    assert c.gnss_raw.options.mode == "single"


def test_process_names_the_missing_extra(tmp_path, monkeypatch, capsys):
    """Without pyrtklib5: exit 2, one line naming the extra; nothing written."""
    from ins.cli.main import main
    monkeypatch.setitem(sys.modules, "pyrtklib5", None)
    _static_imu(tmp_path / "imu.txt", duration_s=10.0)
    for n in ("r.obs", "b.obs", "n.nav"):
        (tmp_path / n).write_text("x")
    cfg = tmp_path / "cfg.toml"
    cfg.write_text(CONFIG.format(files='rover = "r.obs"\nbase = "b.obs"\nnav = "n.nav"',
                                 rtklib=""))
    assert main(["process", "--config", str(cfg), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "pip install 'insphoto[gnss]'" in err
    assert not (tmp_path / "out").exists()


RNX2RTKP_CONF = """pos1-posmode=kinematic
pos1-frequency=l1+l2
pos1-soltype=combined
pos1-elmask=15
pos1-dynamics=off
pos1-ionoopt=brdc
pos1-tropopt=saas
pos1-sateph=brdc
pos1-navsys=1
pos2-armode=fix-and-hold
pos2-arthres=3
ant2-postype=rinexhead
out-solformat=llh
out-outhead=on
out-timesys=gpst
out-timeform=tow
"""


@needs_pair
@pytest.mark.skipif(shutil.which("rnx2rtkp") is None, reason="no RTKLIB rnx2rtkp on PATH")
def test_kinematic_matches_an_independent_rnx2rtkp(tmp_path):
    """The same files through another build of RTKLIB (rnx2rtkp on PATH, e.g. Debian's
    2.4.3 b34, an outside oracle; this binding is demo5 2.5.0) with the same settings:
    the same epochs and Q flags, positions within a millimetre (measured 0.2 mm)."""
    _rtk()
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.rtklib import read_pos
    from ins.nav.earth import ned_offset
    conf = tmp_path / "k.conf"
    conf.write_text(RNX2RTKP_CONF)
    ref = tmp_path / "ref.pos"
    subprocess.run(["rnx2rtkp", "-k", str(conf), "-o", str(ref), ROVER, BASE, NAV],
                   check=True, capture_output=True, timeout=120)
    a = read_pos(ref)
    b = solve(ROVER, NAV, tmp_path / "ours.pos", base=BASE,
              options=RtklibOptions(systems=GPS)).log
    assert np.array_equal(a.time, b.time) and np.array_equal(a.quality, b.quality)
    assert np.max(np.abs(ned_offset(a.lla, b.lla))) < 1e-3


def test_gnss_cli_rover_given_once(tmp_path, capsys):
    from ins.cli.main import main
    assert main(["gnss", "a.obs", "--rover", "b.obs", "--nav", "n", "-o",
                 str(tmp_path / "x.pos")]) == 2
    assert main(["gnss", "--nav", "n", "-o", str(tmp_path / "x.pos")]) == 2
    assert "give the rover's observations once" in capsys.readouterr().err
    assert os.listdir(tmp_path) == []
