"""Raw GNSS through RTKLIB's engine (ins.gnss): strict [rtklib] options, and solutions
of the real GEONET pair 0759 (rover) / 3040 (base) against a static truth: the rover's
position from RTKLIB's static mode over the hour (a different estimator: one position
for the hour), and, loosely and independently, the stations' RINEX header positions
(GEONET's coordinates, which the solutions miss by about 0.17 m)."""
import os
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from ins.common.errors import InputError, InputWarning
from ins.gnss.rtklib_options import RtklibOptions, read_rtklib_options

ROOT = Path(__file__).resolve().parents[1]
PAIR = ROOT.parent / "shared" / "real" / "rtklib_static_pair"
ROVER, BASE, NAV = (str(PAIR / n) for n in ("07590920.05o", "30400920.05o", "07590920.05n"))
#: APPROX POSITION XYZ of the two headers, m (ECEF)
ROVER_HDR = np.array([-3976219.5082, 3382372.5671, 3652512.9849])
BASE_HDR = np.array([-3978242.4348, 3382841.1715, 3649902.7667])
needs_pair = pytest.mark.skipif(not PAIR.is_dir(), reason="../shared/real is absent")


def test_options_strict_keys():
    with pytest.raises(InputError, match=r"cfg\.toml: \[rtklib\] elevation_mask: unknown key "
                                         r"\(did you mean elevation_mask_deg\?\)"):
        read_rtklib_options({"elevation_mask": 10}, "cfg.toml")
    with pytest.raises(InputError, match=r"\[rtklib\] mode: expected one of"):
        read_rtklib_options({"mode": "ppk"}, "cfg.toml")
    with pytest.raises(InputError, match=r"systems: expected a non-empty list"):
        read_rtklib_options({"systems": ["gps", "glonas"]}, "cfg.toml")
    with pytest.raises(InputError, match="either base_position or base_lla_deg"):
        read_rtklib_options({"base_position": "rinex", "base_lla_deg": [35, 139, 70]})
    o = read_rtklib_options({"mode": "static", "elevation_mask_deg": 10, "systems": ["GPS"]},
                            mode="single")
    assert o == RtklibOptions(mode="single", elevation_mask_deg=10.0, systems=("gps",))


def test_prcopt_default_is_never_written():
    rtk = pytest.importorskip("pyrtklib5")
    from ins.gnss.rtklib_options import fill_prcopt
    before = (rtk.prcopt_default.mode, rtk.prcopt_default.elmin, rtk.prcopt_default.navsys,
              rtk.prcopt_default.thresar[0], rtk.prcopt_default.dynamics)
    po, _, _ = fill_prcopt(RtklibOptions(mode="static", elevation_mask_deg=30,
                                         systems=("gps",), ar_ratio=2.5), rtk)
    assert (po.mode, po.navsys, po.thresar[0]) == (rtk.PMODE_STATIC, rtk.SYS_GPS, 2.5)
    assert po.elmin == pytest.approx(np.radians(30))
    after = (rtk.prcopt_default.mode, rtk.prcopt_default.elmin, rtk.prcopt_default.navsys,
             rtk.prcopt_default.thresar[0], rtk.prcopt_default.dynamics)
    assert after == before


def test_missing_binding_names_the_extra(monkeypatch):
    from ins.gnss import rtklib_engine
    monkeypatch.setitem(sys.modules, "pyrtklib5", None)
    with pytest.raises(InputError, match=r"pip install 'insphoto\[gnss\]'"):
        rtklib_engine.binding()


def _enu(lla_rad, ref_ecef):
    import pymap3d
    lat0, lon0, h0 = pymap3d.ecef2geodetic(*ref_ecef)
    x, y, z = (np.asarray(v) for v in pymap3d.geodetic2ecef(lla_rad[..., 0], lla_rad[..., 1],
                                                             lla_rad[..., 2], deg=False))
    return np.stack(pymap3d.ecef2enu(x, y, z, lat0, lon0, h0), axis=-1)


@pytest.fixture(scope="module")
def solutions(tmp_path_factory):
    pytest.importorskip("pyrtklib5")
    if not PAIR.is_dir():
        pytest.skip("../shared/real is absent")
    from ins.gnss.rtklib_engine import solve
    d = tmp_path_factory.mktemp("pair")
    gps = ("gps",)
    runs = {
        "static": RtklibOptions(mode="static", direction="forward", systems=gps),
        "kinematic": RtklibOptions(mode="kinematic", direction="combined", systems=gps),
        "forward": RtklibOptions(mode="kinematic", direction="forward", systems=gps),
        "backward": RtklibOptions(mode="kinematic", direction="backward", systems=gps),
        "single": RtklibOptions(mode="single", systems=gps),
        "dgnss": RtklibOptions(mode="dgnss", systems=gps),
    }
    out = {}
    for name, opts in runs.items():
        out[name] = solve(ROVER, NAV, d / f"{name}.pos", base=BASE, options=opts)
    return out, d


def _truth(sol):
    """The rover from RTKLIB's static solution at the end of the hour, ECEF."""
    import pymap3d
    last = sol["static"].log.lla[-1]
    return np.array(pymap3d.geodetic2ecef(*last, deg=False))


def test_kinematic_against_static_truth(solutions):
    sol, folder = solutions
    from ins.gnss.rtklib_engine import poor_reason
    truth = _truth(sol)
    k = sol["kinematic"]
    assert k.rover_epochs == 120 and len(k.log) >= 110
    fixed = k.log.quality == 1
    assert fixed.mean() > 0.9 and poor_reason(k) is None
    enu = _enu(k.log.lla[fixed], truth)
    assert np.all(np.abs(enu.mean(axis=0)) < [0.005, 0.005, 0.01])     # mean of the fixes
    assert np.all(enu.std(axis=0) < [0.006, 0.008, 0.02])              # 3/5/10 mm measured
    # RTKLIB's own sigmas (dynamics off) are a covariance: nothing screened, and they
    # are not absurd against the scatter (within a factor 5 either way)
    assert not k.log.screen
    ratio = np.median(k.log.sigma_ned_m[fixed], axis=0)[[1, 0, 2]] / enu.std(axis=0)
    assert np.all((ratio > 0.2) & (ratio < 5))
    # forward and backward alone agree with the truth too, and are read in time order
    for name in ("forward", "backward"):
        log = sol[name].log
        assert np.all(np.diff(log.time) > 0)
        f = log.quality == 1
        assert f.mean() > 0.8
        assert np.all(np.abs(np.median(_enu(log.lla[f], truth), axis=0)) < [0.01, 0.01, 0.03])
    # only the solution is left in the folder: no _events.pos, no temporary folder
    assert sorted(os.listdir(folder)) == sorted(f"{n}.pos" for n in sol)


def test_baseline_against_the_headers(solutions):
    """GEONET's header coordinates: a baseline of about 3.3 km whose length the static
    and kinematic solutions match within 0.2 m (the headers are 'approximate')."""
    sol, _ = solutions
    truth = _truth(sol)
    hdr = np.linalg.norm(ROVER_HDR - BASE_HDR)
    assert 3000 < hdr < 4000
    assert abs(np.linalg.norm(truth - BASE_HDR) - hdr) < 0.2
    assert np.linalg.norm(truth - ROVER_HDR) < 0.3


def test_code_solutions(solutions):
    sol, _ = solutions
    truth = _truth(sol)
    for name, q, bias_m, spread_m in (("single", 5, 3.0, (1.5, 1.5, 4.0)),
                                      ("dgnss", 4, 1.5, (1.0, 1.0, 3.0))):
        log = sol[name].log
        assert set(np.unique(log.quality)) == {q} and len(log) >= 110
        enu = _enu(log.lla, truth)
        assert np.linalg.norm(enu.mean(axis=0)) < bias_m
        assert np.all(enu.std(axis=0) < spread_m)
    # the differential solution is better than the single one, in 3D rms
    rms = {n: np.sqrt(np.mean(np.sum(_enu(sol[n].log.lla, truth) ** 2, axis=1)))
           for n in ("single", "dgnss")}
    assert rms["dgnss"] < rms["single"]


@needs_pair
def test_dynamics_on_sigmas_are_screened(tmp_path):
    """demo5 2.5.0, kinematic combined, pos1-dynamics on: the sd columns are no
    covariance (sdn 0 with sdne -0.43 m); the reader repairs them and says so."""
    pytest.importorskip("pyrtklib5")
    from ins.gnss.rtklib_engine import solve
    opts = RtklibOptions(mode="kinematic", direction="combined", systems=("gps",),
                         dynamics=True)
    with pytest.warns(InputWarning, match=r"not a covariance.*dynamics = false"):
        s = solve(ROVER, NAV, tmp_path / "dyn.pos", base=BASE, options=opts)
    from ins.io.pos_screen import invalid_covariance
    from ins.io.rtklib import read_pos
    raw = read_pos(tmp_path / "dyn.pos", screen_covariance=False)
    assert invalid_covariance(raw.cov_ned_m2).sum() == 0     # floored: the old reader hid it
    assert s.log.screen.repaired_lines.size + s.log.screen.dropped_lines.size > 60
    assert np.all(np.linalg.eigvalsh(s.log.cov_ned_m2) > 0)
    # the printed row of the README, the first epoch: sdn 0 beside sdne -0.4266
    text = (tmp_path / "dyn.pos").read_text().splitlines()
    k = next(i for i, t in enumerate(text) if not t.startswith("%"))
    assert text[k].split()[7:11] == ["0.0000", "0.7307", "0.3348", "-0.4266"]
    assert k + 1 in s.log.screen.repaired_lines


@needs_pair
def test_inputs_checked(tmp_path):
    pytest.importorskip("pyrtklib5")
    from ins.gnss.rtklib_engine import solve
    with pytest.raises(InputError, match="needs the base station"):
        solve(ROVER, NAV, tmp_path / "a.pos", options=RtklibOptions(mode="kinematic"))
    with pytest.raises(InputError, match="no such file"):
        solve(ROVER, str(tmp_path / "none.05n"), tmp_path / "a.pos", base=BASE)
    with pytest.raises(InputError, match="no observation epoch"):
        solve(NAV, NAV, tmp_path / "a.pos", base=BASE)
    assert os.listdir(tmp_path) == []


@needs_pair
def test_cli(tmp_path, capsys):
    pytest.importorskip("pyrtklib5")
    from ins.cli.main import main
    out = tmp_path / "rover.pos"
    assert main(["gnss", ROVER, "--base", BASE, "--nav", NAV, "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "of 120 rover epochs solved (kinematic, combined, broadcast ephemeris)" in text
    assert "fix " in text and "forward/backward separation" in text
    cfg = tmp_path / "cfg.toml"
    cfg.write_text('[rtklib]\nambiguity = "off"\nsystems = ["gps"]\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rc = main(["gnss", ROVER, "--base", BASE, "--nav", NAV, "--config", str(cfg),
                   "-o", str(tmp_path / "poor.pos")])
    assert rc == 3
    cfg.write_text('[rtklib]\nelevation_mask = 75\n')
    assert main(["gnss", ROVER, "--nav", NAV, "--config", str(cfg), "-o", str(out)]) == 2


@needs_pair
def test_a_run_does_not_inherit_the_previous_runs_navigation(tmp_path):
    """RTKLIB keeps navigation data in C globals: the Klobuchar coefficients of one run's
    file stayed for the next run, whose file had none (RTKLIB's defaults are meant).
    Single point on the rover with the nav file stripped of ION ALPHA/BETA must give the
    same positions after a run with the full file as before it."""
    pytest.importorskip("pyrtklib5")
    from ins.gnss.rtklib_engine import solve
    plain = tmp_path / "no_ion.05n"
    plain.write_text("".join(line for line in open(NAV).readlines()
                             if "ION ALPHA" not in line and "ION BETA" not in line))
    opts = RtklibOptions(mode="single", systems=("gps",), frequencies=1)
    first = solve(ROVER, str(plain), tmp_path / "a.pos", options=opts).log
    with_ion = solve(ROVER, NAV, tmp_path / "b.pos", options=opts).log
    again = solve(ROVER, str(plain), tmp_path / "c.pos", options=opts).log
    from ins.nav.earth import ned_offset
    # the two ionosphere models differ by decimetres: the check can fail
    assert np.max(np.abs(ned_offset(first.lla, with_ion.lla))) > 0.05
    np.testing.assert_array_equal(first.lla, again.lla)


def test_a_rover_alone_is_positioned_point_by_point():
    """Without a base and with no mode in [rtklib], the mode is "single" (the default
    "kinematic" needs a base: a rover alone for tight coupling was refused); a base or
    a mode given keeps the default or the choice."""
    from ins.estimation.pipeline.gnss_source import raw_gnss_config
    from ins.gnss.rtklib_options import mode_without_base
    assert raw_gnss_config({"rover": "r.obs", "nav": "n.nav"}, None).options.mode == "single"
    assert raw_gnss_config({"rover": "r.obs", "base": "b.obs", "nav": "n.nav"},
                           None).options.mode == "kinematic"
    assert raw_gnss_config({"rover": "r.obs"}, {"mode": "dgnss"}).options.mode == "dgnss"
    assert mode_without_base(None, None, "static") == "static"
    assert mode_without_base({"direction": "forward"}, None) == "single"


@needs_pair
def test_a_cut_observation_file_is_warned(tmp_path):
    """A RINEX file cut inside a line (an interrupted download) is read as far as it goes,
    with a warning naming it; the whole file gives none."""
    pytest.importorskip("pyrtklib5")
    from ins.gnss.rtklib_engine import count_epochs
    cut = tmp_path / "cut.obs"
    cut.write_bytes(open(ROVER, "rb").read()[:3000])
    with pytest.warns(InputWarning, match=r"cut\.obs: the file ends inside a line"):
        assert count_epochs(cut) == 3
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert count_epochs(ROVER) == 120
