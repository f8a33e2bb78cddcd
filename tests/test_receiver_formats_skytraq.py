"""SkyTraq logs encoded by the tests from SkyTraq's application notes
(tests/receiver_frames_skytraq.py: 0xE5 extended raw measurements, 0xE0 GPS
subframes) and decoded by RTKLIB's convrnx: detection from the content, the
observations equal to the simulated truth to the format's resolution, a log older
than 2009 kept in its week era, and the real GEONET pair's rover re-encoded giving
RTKLIB's solution of the RINEX files."""
import sys
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parent))
import receiver_frames as rf  # noqa: E402
import receiver_frames_skytraq as stq  # noqa: E402
from receiver_frames import assert_same_solution  # noqa: E402
from test_receiver_formats import BASE, NAV, ROVER, TOW0, WEEK, _compare, _rtk, _sim, \
    needs_pair  # noqa: E402
from test_receiver_formats_survey import _check_rinex_values, _ephemerides  # noqa: E402
from ubx_frames import read_rinex3_obs  # noqa: E402


def test_skytraq_e5_decodes_to_the_simulation(tmp_path):
    """0xE5: double pseudoranges and carrier phases (to the RINEX millimetre / 0.001
    cycle), float Doppler, C/N0 in whole dB-Hz; GPS L2 as 2X; format and week from the
    content."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw, detect_format, first_epoch
    log = tmp_path / "sim.bin"
    log.write_bytes(stq.simulation_log(_sim()))
    assert detect_format(log) == "skytraq"
    assert first_epoch(log, "skytraq") == (WEEK, TOW0)
    obs, nav = convert_raw(log, str(tmp_path), rtk)
    assert nav is None
    err = _compare(obs, {"L1": "1C", "L2": "2X"},
                   {"C": 5e-4 + 1e-6, "L": 5e-4 + 1e-6, "D": 1e-3, "S": 0.5 + 1e-6})
    assert set(err) == set("CLDS")
    print("SkyTraq worst |RINEX - truth|:", err)


def test_an_old_skytraq_log_keeps_its_week(tmp_path):
    """RTKLIB's SkyTraq decoder passes 0xE5's full week through adjgpsweek: without
    RTKLIB's clock set to the log's first epoch a 2005 log came out in 2024 (fails
    without the fix)."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    log = tmp_path / "old.stq"
    log.write_bytes(stq.simulation_log(rf.simulated_epochs(1316, 518400.0, n_epochs=3)))
    obs, _ = convert_raw(log, str(tmp_path), rtk)
    assert [e[0] for e in read_rinex3_obs(obs)] == [(2005, 4, 2, 0, 0, float(s))
                                                    for s in range(3)]


@needs_pair
def test_pair_with_a_skytraq_rover_gives_the_rinex_solution(tmp_path):
    """The rover's values come back to the RINEX millimetre, its 0xE0 subframes give
    the broadcast ephemerides again; kinematic PPK of the SkyTraq rover against the
    RINEX base, with the log's ephemerides alone (no Klobuchar coefficients: a few mm
    up) and with the nav file (0.1 mm), = that of the RINEX files."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    data = stq.rinex2_to_skytraq(ROVER)
    eph, _ = stq.nav_to_skytraq(NAV, rtk)
    k = data.find(b"\xa0\xa1", 4)                        # after the first epoch
    rover = tmp_path / "rover.dat"
    rover.write_bytes(data[:k] + eph + data[k:])
    obs, nav = convert_raw(rover, str(tmp_path), rtk, stem="r")
    types = (("C1", "C1C", "L1"), ("P2", "C2X", "L2"), ("L1", "L1C", "L1"),
             ("L2", "L2X", "L2"))
    assert _check_rinex_values(obs, ROVER, {}, types) > 3000
    assert _ephemerides(nav, rtk) == _ephemerides(NAV, rtk)
    opts = RtklibOptions(systems=("gps",))
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE, options=opts)
    for navs, tol_up in ((NAV, 1e-4), (None, 5e-3)):
        b = solve(rover, navs, tmp_path / "raw.pos", base=BASE, options=opts)
        assert_same_solution(a, b, 5e-4, tol_up, navs)
