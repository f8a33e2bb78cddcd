"""Swift SBP logs encoded by the tests from Swift's SBP specification
(tests/receiver_frames_sbp.py: MSG_OBS, MSG_EPHEMERIS_GPS) and decoded by RTKLIB's
convrnx: detection from the content, the observations equal to the simulated truth to
the format's resolution, a log older than 2009 kept in its GPS week era, and the real
GEONET pair's rover re-encoded giving RTKLIB's solution of the RINEX files."""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import receiver_frames as rf  # noqa: E402
import receiver_frames_sbp as sbp  # noqa: E402
from receiver_frames import assert_same_solution  # noqa: E402
from test_receiver_formats import BASE, NAV, ROVER, TOW0, WEEK, _compare, _rtk, \
    _sim, needs_pair  # noqa: E402
from test_receiver_formats_survey import _check_rinex_values, _ephemerides  # noqa: E402
from ubx_frames import read_rinex3_obs  # noqa: E402


def test_sbp_msg_obs_decodes_to_the_simulation(tmp_path):
    """MSG_OBS: pseudoranges in 2 cm, carrier phases and Doppler in 1/256, C/N0 0.25
    dB-Hz; L2 P as 2P; the format and its week from the content."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw, detect_format, first_epoch
    log = tmp_path / "sim.bin"
    log.write_bytes(sbp.simulation_log(_sim()))
    assert detect_format(log) == "swift"
    assert first_epoch(log, "swift") == (WEEK, TOW0)
    obs, nav = convert_raw(log, str(tmp_path), rtk)
    assert nav is None
    err = _compare(obs, {"L1": "1C", "L2": "2P"},
                   {"C": 0.01 + 1e-6, "L": 1 / 512 + 5e-4 + 1e-6, "D": 1 / 512 + 5e-4 + 1e-6,
                    "S": 0.125 + 1e-6})
    assert set(err) == set("CLDS")
    print("SBP worst |RINEX - truth|:", err)


def test_an_old_sbp_log_keeps_its_week(tmp_path):
    """RTKLIB's SBP decoder passes MSG_OBS's full week through adjgpsweek, which with
    the computer's clock moved a 2005 log 1024 weeks on (to 2024); the conversion now
    sets RTKLIB's clock to the log's first epoch (fails without)."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    epochs = rf.simulated_epochs(1316, 518400.0, n_epochs=3)
    log = tmp_path / "old.sbp"
    log.write_bytes(sbp.simulation_log(epochs))
    obs, _ = convert_raw(log, str(tmp_path), rtk)
    assert [e[0] for e in read_rinex3_obs(obs)] == [(2005, 4, 2, 0, 0, float(s))
                                                    for s in range(3)]


@needs_pair
def test_pair_with_an_sbp_rover_gives_the_rinex_solution(tmp_path):
    """The rover's phases come back to 1/256 cycle and its ranges to 1 cm (the 2 cm
    unit), its MSG_EPHEMERIS_GPS the broadcast orbits (to float32 where the message has
    F4); kinematic PPK of the SBP rover against the RINEX base: the same epochs and
    fixes as the RINEX files', positions within 1 mm horizontally and 3 mm up (the 2 cm
    ranges; measured 0.6 mm N, 1.8 mm U)."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    data, shifts = sbp.rinex2_to_sbp(ROVER)
    eph, _ = sbp.nav_to_sbp(NAV, rtk)
    k = 8 + data[5]                                      # after the first MSG_OBS
    rover = tmp_path / "rover.sbp"
    rover.write_bytes(data[:k] + eph + data[k:])
    obs, nav = convert_raw(rover, str(tmp_path), rtk, stem="r")
    tol = {"C1": 0.01 + 1e-6, "P2": 0.01 + 1e-6, "L1": 1 / 512 + 5e-4, "L2": 1 / 512 + 5e-4}
    types = (("C1", "C1C", "L1"), ("P2", "C2P", "L2"), ("L1", "L1C", "L1"),
             ("L2", "L2P", "L2"))                    # SBP's GPS L2 P: RINEX 2P
    assert _check_rinex_values(obs, ROVER, shifts, types, tol=tol) > 3000
    conv, orig = _ephemerides(nav, rtk), _ephemerides(NAV, rtk)
    assert set(conv) == set(orig)
    for key, v in orig.items():
        np.testing.assert_allclose(conv[key], v, rtol=1e-7, atol=1e-15)
    opts = RtklibOptions(systems=("gps",))
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE, options=opts)
    b = solve(rover, NAV, tmp_path / "raw.pos", base=BASE, options=opts)
    d = assert_same_solution(a, b, 1e-3, 3e-3)
    print("SBP rover: max |d| N/E/D m", d)
