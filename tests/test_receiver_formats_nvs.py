"""NVS BINR logs encoded by the tests from NVS's BINR protocol description
(tests/receiver_frames_nvs.py: 0xF5 raw data, 0xF7 GPS ephemeris, DLE framing with
DLE stuffing) and decoded by RTKLIB's convrnx: detection from the content (the log
had to be named before), the observations equal to the simulated truth to the
format's resolution, a log older than 2009 kept in its week era, and the real GEONET
pair's rover re-encoded giving RTKLIB's solution of the RINEX files."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import receiver_frames as rf  # noqa: E402
import receiver_frames_nvs as nvs  # noqa: E402
from receiver_frames import assert_same_solution  # noqa: E402
from test_receiver_formats import BASE, NAV, ROVER, TOW0, WEEK, _compare, _rtk, _sim, \
    needs_pair  # noqa: E402
from test_receiver_formats_survey import _ephemeris_list  # noqa: E402
from ubx_frames import read_rinex2_obs, read_rinex3_obs  # noqa: E402


def _log(epochs):
    """The epochs' 0xF5 after one with no channel a second before, as a receiver
    starting to track sends it: RTKLIB's convrnx loses a log's first 0xF5."""
    return nvs.raw_f5(epochs[0][0], epochs[0][1] - 1.0, []) + nvs.simulation_log(epochs)


def test_binr_framing_and_detection(tmp_path):
    """DLE stuffing undone (the data's DLE bytes doubled on the wire); the 0xF5
    messages counted by the detector (it needed --gnss-format before), not one whose
    length breaks the 27 + 30 n layout nor one with a lone DLE inside; the log's
    first epoch from 0xF5 (UTC time of measurement + GPS-UTC shift)."""
    from ins.common.errors import InputError
    from ins.gnss.framing import count_frames, unstuff_binr
    from ins.gnss.receiver_formats import detect_format, first_epoch
    data = b"\x01\x10\x02\x10\x10\x03"
    msg = nvs.binr_message(0xF5, data)
    assert msg == b"\x10\xf5\x01\x10\x10\x02\x10\x10\x10\x10\x03\x10\x03"
    assert unstuff_binr(msg, 0) == (0xF5, data, len(msg))
    assert unstuff_binr(b"\x10\xf5\x01\x10\x02\x10\x03", 0) is None   # lone DLE
    log = nvs.simulation_log(_sim())
    assert count_frames(log) == {"nvs": 5}
    assert count_frames(log + nvs.binr_message(0xF5, bytes(27 + 29))) == {"nvs": 5}
    path = tmp_path / "log.dat"                  # no telling extension
    path.write_bytes(log)
    assert detect_format(path) == "nvs"
    assert first_epoch(path, "nvs") == (WEEK, TOW0)
    path.write_bytes(log[:-1] + b"\x04")         # the last message's ETX broken
    assert count_frames(path.read_bytes()) == {"nvs": 4}
    path.write_bytes(bytes(1000))
    with pytest.raises(InputError, match="nvs"):
        detect_format(path)


def test_nvs_f5_decodes_to_the_simulation(tmp_path):
    """0xF5: F8 pseudoranges (ms), carrier phases (cycles) and Doppler (Hz) to the
    RINEX millimetre / 0.001 cycle / 0.001 Hz, S/N in whole dB-Hz; GPS L1 C/A only
    (the message's single signal); format and week from the content.  Without a
    message before it the log's first epoch is lost (RTKLIB's convrnx)."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    log = tmp_path / "sim.bin"
    log.write_bytes(_log(_sim()))
    obs, nav = convert_raw(log, str(tmp_path), rtk)
    assert nav is None
    err = _compare(obs, {"L1": "1C"},
                   {"C": 5e-4 + 1e-6, "L": 5e-4 + 1e-6, "D": 5e-4 + 1e-6, "S": 0.5 + 1e-6})
    assert set(err) == set("CLDS")
    assert set(read_rinex3_obs(obs)[0][1]["G03"]) == {"C1C", "L1C", "D1C", "S1C"}
    print("NVS worst |RINEX - truth|:", err)
    log.write_bytes(nvs.simulation_log(_sim()))
    obs, _ = convert_raw(log, str(tmp_path), rtk)
    assert [e[0][5] for e in read_rinex3_obs(obs)] == [1.0, 2.0, 3.0, 4.0]


def test_an_old_nvs_log_keeps_its_week(tmp_path):
    """RTKLIB's NVS decoder passes 0xF5's full week through adjgpsweek: without
    RTKLIB's clock set to the log's first epoch a 2005 log came out in 2024 (fails
    without the fix)."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    log = tmp_path / "old.dat"
    log.write_bytes(_log(rf.simulated_epochs(1316, 518400.0, n_epochs=3)))
    obs, _ = convert_raw(log, str(tmp_path), rtk)
    assert [e[0] for e in read_rinex3_obs(obs)] == [(2005, 4, 2, 0, 0, float(s))
                                                    for s in range(3)]


def _check_rover_values(obs, left):
    """The rover's C1 and L1 in the converted file: RTKLIB puts each epoch on the
    10 ms (the pair's are 1-5 ms past the second) and takes the offset out of the
    pseudorange, not the phase, in ms of the week: to a few units in the last place
    of an F8 of 5e8 ms (6e-8 ms, 1.8 cm of range, the same for every satellite of an
    epoch); the number of values compared."""
    tol = 3 * np.spacing(604800e3) * 1e-3 * rf.CLIGHT
    orig = read_rinex2_obs(ROVER)
    conv = read_rinex3_obs(obs)
    assert len(conv) == len(orig) and conv[0][0] == (2005, 4, 2, 0, 0, 0.0)
    compared = 0
    for (_, tow, rows), (ymdhms, got) in zip(orig, conv):
        tag = 518400.0 + 3600 * ymdhms[3] + 60 * ymdhms[4] + ymdhms[5]
        assert abs(tag - np.floor(tow * 100.0 + 0.5) / 100.0) < 1e-6
        for sat, v in rows.items():
            if not sat.startswith("G") or np.isnan(v["C1"][0]):
                continue
            c = got[sat]["C1C"] + rf.CLIGHT * (tow - tag)
            assert abs(c - v["C1"][0]) < 5e-4 + tol, (tow, sat, c, v["C1"][0])
            compared += 1
            if not np.isnan(v["L1"][0]) and (tow, sat, "L1") not in left:
                assert abs(got[sat]["L1C"] - v["L1"][0]) < 5e-4 + 1e-9, (tow, sat)
                compared += 1
    return compared


@needs_pair
def test_pair_with_an_nvs_rover_gives_the_rinex_solution(tmp_path):
    """The rover's C1/L1 come back to the RINEX millimetre (the pseudorange moved to
    the 10 ms tag, the phases as they are but at the L1 slips, sent as absent); its
    0xF7 give the broadcast ephemerides (a_f0 as an F4 in ms: within 2e-11 s; of two
    with one IODE one); L1
    kinematic PPK of the NVS rover against the RINEX base = that of the RINEX files
    (epochs, Q, positions to 0.2 mm with the nav file; 2 mm with the log's
    ephemerides alone, which have no Klobuchar coefficients)."""
    rtk = _rtk()
    from ins.gnss.framing import RECOGNISERS
    from ins.gnss.receiver_formats import convert_raw
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    data, left = nvs.rinex2_to_nvs(ROVER)
    eph, _ = nvs.nav_to_nvs(NAV, rtk)
    k = RECOGNISERS["nvs"][1](data, 0)                   # after the first epoch
    rover = tmp_path / "rover.dat"
    rover.write_bytes(nvs.raw_f5(1316, 518399.0, []) + data[:k] + eph + data[k:])
    obs, nav = convert_raw(rover, str(tmp_path), rtk, stem="r")
    assert _check_rover_values(obs, left) > 1500 and len(left) == 10
    a, b = _ephemeris_list(NAV, rtk), _ephemeris_list(nav, rtk)
    assert {x[0] for x in a} == {x[0] for x in b} and len(b) == len(a) - 1
    for key, q in b:             # of two with one IODE RTKLIB keeps one
        assert any(p[:5] == q[:5] and abs(p[5] - q[5]) < 2e-11 and p[6] == q[6]
                   for k_, p in a if k_ == key), key
    opts = RtklibOptions(systems=("gps",), frequencies=1)
    ref = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE, options=opts)
    for navs, tol in ((NAV, 2e-4), (None, 2e-3)):
        got = solve(rover, navs, tmp_path / "raw.pos", base=BASE, options=opts)
        assert_same_solution(ref, got, tol, tol, navs)
