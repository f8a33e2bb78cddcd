"""Javad GREIS logs encoded by the tests from Javad's GREIS reference
(tests/receiver_frames_javad.py: [~~] [RD] [SI] [RC]/[R2] [PC]/[P2] [DC]/[D2]
[EC]/[E2] [TC] [::], [GE] ephemerides) and decoded by RTKLIB's convrnx: the GREIS
checksum, detection from the content (the [~~] receiver-time messages), the
observations equal to the simulated truth to the format's resolution, and the real
GEONET pair's rover re-encoded giving RTKLIB's solution of the RINEX files with its
own ephemerides or the nav file."""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import receiver_frames_javad as jav  # noqa: E402
from receiver_frames import assert_same_solution  # noqa: E402
from test_receiver_formats import BASE, NAV, ROVER, _compare, _rtk, _sim, \
    needs_pair  # noqa: E402
from test_receiver_formats_survey import _TYPES, _check_rinex_values, \
    _ephemerides  # noqa: E402


def test_greis_checksum_and_detection(tmp_path):
    """The library's GREIS checksum = the test's (written from the reference); a
    Javad log is told from its content whatever its name (it needed the .jps
    extension before), not from a [~~] with a wrong checksum."""
    from ins.gnss.framing import count_frames, greis_checksum
    data = np.random.default_rng(4).integers(0, 256, 300, dtype=np.uint8).tobytes()
    assert greis_checksum(data) == jav.greis_checksum(data)
    log = jav.simulation_log(_sim())
    assert count_frames(log) == {"javad": 5}
    bad = jav.greis_message("~~", b"\x00\x00\x00\x00")
    assert count_frames(bad[:9] + bytes([bad[9] ^ 1])) == {}
    from ins.gnss.receiver_formats import detect_format
    (tmp_path / "log.dat").write_bytes(log)
    assert detect_format(tmp_path / "log.dat") == "javad"


def test_javad_greis_decodes_to_the_simulation(tmp_path):
    """Pseudoranges (F8 s) and phases (F8 cycles) to the RINEX millimetre / 0.001
    cycle, Doppler 1e-4 Hz, C/N0 whole dB-Hz; CA/L1 as 1C and P/L2 as 2W; the date of
    [RD] gives the week."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    log = tmp_path / "sim.jps"
    log.write_bytes(jav.simulation_log(_sim()))
    obs, nav = convert_raw(log, str(tmp_path), rtk)
    assert nav is None
    err = _compare(obs, {"L1": "1C", "L2": "2W"},
                   {"C": 5e-4 + 1e-6, "L": 5e-4 + 1e-6, "D": 1e-3, "S": 0.5 + 1e-6})
    assert set(err) == set("CLDS")
    print("Javad worst |RINEX - truth|:", err)


@needs_pair
def test_pair_with_a_javad_rover_gives_the_rinex_solution(tmp_path):
    """The rover's values come back to the RINEX millimetre (phases as they are), its
    [GE] messages give the broadcast ephemerides again, in their week (RTKLIB's [GE]
    decoder passes the full week through adjgpsweek: the clock set from [~~] + [RD],
    without which a 2005 log's ephemerides came out 1024 weeks on); kinematic PPK of
    the Javad rover against the RINEX base = that of the RINEX files (epochs, Q,
    positions to 0.1 mm) with the nav file, and with the log's ephemerides alone (no
    Klobuchar coefficients: 2 mm up), the format detected."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw, first_epoch
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    data = jav.rinex2_to_javad(ROVER)
    eph, _ = jav.nav_to_javad(NAV, rtk)
    k = data.find(b"~~005", data.find(b"~~005") + 5)        # after the first epoch
    rover = tmp_path / "rover.log"
    rover.write_bytes(data[:k] + eph + data[k:])
    assert first_epoch(rover, "javad") == (1316, 518400.0)
    obs, nav = convert_raw(rover, str(tmp_path), rtk, stem="r")
    assert _check_rinex_values(obs, ROVER, {}, _TYPES) > 3000
    assert _ephemerides(nav, rtk) == _ephemerides(NAV, rtk)
    opts = RtklibOptions(systems=("gps",))
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE, options=opts)
    for navs, tol_up in ((NAV, 1e-4), (None, 2e-3)):
        b = solve(rover, navs, tmp_path / "raw.pos", base=BASE, options=opts)
        assert_same_solution(a, b, 5e-4, tol_up, navs)
