"""``ins.io.rinex_nav_write``: a written GPS navigation file reads back through our
reader (every field within the D19.12 format's 13 significant digits) and through
RTKLIB, whose satellite positions and clocks agree with the simulator's IS-GPS-200
code on the original numbers."""
import numpy as np
import pytest

from ins.io.rinex_nav import GpsEphemeris, read_gps_nav
from ins.io.rinex_nav_write import write_gps_nav
from ins.simulate.gps_orbit import eph_state

WEEK = 2183


def _eph(prn, m0):
    return GpsEphemeris(
        prn=prn, week=WEEK, toc=187200.0, toc_week=WEEK, af0=-6.04419e-05, af1=-1.25056e-12,
        af2=0.0, iode=43, crs=-108.5625, delta_n=4.320894268e-09, m0=m0,
        cuc=-5.707144737e-06, e=0.0060007086722, cus=9.629875422e-06, sqrt_a=5153.61901677,
        toe=187200.0, cic=-5.587935448e-09, omega0=0.83860246341, cis=-9.685754776e-08,
        i0=0.95822938409, crc=194.34375, omega=1.015982021, omega_dot=-7.84318384e-09,
        idot=2.078658013e-10, sv_accuracy=2.0, health=0, tgd=-1.11758709e-08, iodc=43,
        fit_interval=4.0)


def test_round_trip_and_rtklib(tmp_path):
    ephs = [_eph(5, 2.20221203), _eph(17, -1.3)]
    path = tmp_path / "brdc.nav"
    assert write_gps_nav(path, ephs, ion_alpha=(1.1e-8, 1.5e-8, -6e-8, -1.2e-7),
                         ion_beta=(9e4, 1.3e5, -6.5e4, -5.2e5), leap_seconds=18) == 2
    nav = read_gps_nav(path)
    assert nav.version == 3.04 and nav.leap_seconds == 18
    assert nav.ion_alpha == pytest.approx((1.1e-8, 1.5e-8, -6e-8, -1.2e-7), rel=1e-4)
    for a, b in zip(ephs, nav.ephemerides):
        for name in a.__dataclass_fields__:
            assert getattr(b, name) == pytest.approx(getattr(a, name), rel=1e-12,
                                                     abs=1e-300), name
    rtk = pytest.importorskip("pyrtklib5")
    obs, rnav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    assert rtk.readrnx(str(path), 1, "", obs, rnav, sta) == 1
    for eph in ephs:
        times = np.array([180000.0, 187200.0, 193000.0])
        r, _, dt, _ = eph_state(eph, WEEK, times)
        for k, ts in enumerate(times):
            t = rtk.gpst2time(WEEK, float(ts))
            rs, dts, var, svh = (rtk.Arr1Ddouble(6), rtk.Arr1Ddouble(2), rtk.Arr1Ddouble(1),
                                 rtk.Arr1Dint(1))
            assert rtk.satpos(t, t, eph.prn, rtk.EPHOPT_BRDC, rnav, rs, dts, var, svh)
            assert np.linalg.norm(np.array([rs[0], rs[1], rs[2]]) - r[k]) < 1e-3
            assert abs(dts[0] - dt[k]) < 1e-12


def test_toc_must_be_a_whole_second(tmp_path):
    from dataclasses import replace
    with pytest.raises(ValueError, match="whole second"):
        write_gps_nav(tmp_path / "x.nav", [replace(_eph(5, 0.1), toc=187200.5)])
    assert not (tmp_path / "x.nav").exists()
