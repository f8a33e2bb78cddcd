"""Trimble RT-17 logs encoded by the tests from Trimble's Serial Reference
Specification (tests/receiver_frames_rt17.py: RAWDATA type 17, concise; RETSVDATA GPS
ephemerides) and decoded by RTKLIB's convrnx: detection from the content, the
observations equal to the simulated truth to the format's resolution (the record has
no GPS week: it comes from the log's ephemerides, else the epoch or navigation given),
and the real GEONET pair re-encoded giving RTKLIB's solution of the RINEX files."""
import sys
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parent))
import receiver_frames_rt17 as rt  # noqa: E402
from receiver_frames import assert_same_solution  # noqa: E402
from test_receiver_formats import BASE, NAV, ROVER, TOW0, WEEK, _compare, _rtk, _sim, \
    needs_pair  # noqa: E402
from test_receiver_formats_survey import _TYPES, _base_lla, _check_rinex_values, \
    _ephemeris_list  # noqa: E402
from ubx_frames import read_rinex3_obs  # noqa: E402


def test_rt17_type17_decodes_to_the_simulation(tmp_path):
    """Concise type 17: double ranges and phases (to the RINEX millimetre / 0.001
    cycle; the record's phases of opposite sign), float L1 Doppler (no L2 Doppler in
    the concise format), signal strength 0.25 dB; multi-page records; the week from
    the epoch given."""
    rtk = _rtk()
    from ins.gnss.framing import count_frames
    from ins.gnss.receiver_formats import convert_raw, detect_format
    log = tmp_path / "sim.bin"
    data = rt.simulation_log(_sim())
    log.write_bytes(data)
    assert count_frames(data) == {"rt17": 10}                  # 2 pages an epoch
    assert detect_format(log) == "rt17"
    obs, nav = convert_raw(log, str(tmp_path), rtk, epoch=(WEEK, TOW0))
    assert nav is None
    err = _compare(obs, {"L1": "1C", "L2": "2W"},
                   {"C": 5e-4 + 1e-6, "L": 5e-4 + 1e-6, "D": 1e-3, "S": 0.125 + 1e-6})
    assert set(err) == set("CLDS")
    print("RT17 worst |RINEX - truth|:", err)


@needs_pair
def test_pair_as_rt17_gives_the_rinex_solution(tmp_path):
    """Rover and base as RT-17 (weeks from the navigation file; the base's position as
    base_lla_deg: the record has none): the rover's values come back to the RINEX
    millimetre, and kinematic PPK = that of the RINEX files (epochs, Q, positions to
    0.1 mm)."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    data, shifts, left = rt.rinex2_to_rt17(ROVER)
    rover = tmp_path / "rover.dat"
    rover.write_bytes(data)
    base = tmp_path / "base.dat"
    base.write_bytes(rt.rinex2_to_rt17(BASE)[0])
    obs, nav = convert_raw(rover, str(tmp_path), rtk, stem="r", navs=[NAV])
    assert nav is None and not left
    assert _check_rinex_values(obs, ROVER, shifts, _TYPES) > 3000
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE,
              options=RtklibOptions(systems=("gps",)))
    b = solve(rover, NAV, tmp_path / "raw.pos", base=base,
              options=RtklibOptions(systems=("gps",), base_lla_deg=_base_lla(rtk)))
    assert_same_solution(a, b, 1e-4, 1e-4)


@needs_pair
def test_an_rt17_rover_with_its_ephemerides_needs_no_nav_file(tmp_path):
    """RETSVDATA GPS ephemerides sent as a receiver sends them (each before the first
    epoch after its transmission) give the type 17 records their week (RTKLIB takes
    it from the ephemerides: no nav file, no epoch given) and the broadcast
    ephemerides again (of two with one IODE, one); kinematic PPK with them alone =
    that of the RINEX files (epochs, Q; 0.5 mm horizontally, 2 mm up: no Klobuchar
    coefficients)."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    data, shifts, _ = rt.rinex2_to_rt17(ROVER, rt.nav_to_rt17(NAV, rtk))
    rover = tmp_path / "rover.dat"
    rover.write_bytes(data)
    obs, nav = convert_raw(rover, str(tmp_path), rtk, stem="r")
    assert read_rinex3_obs(obs)[0][0] == (2005, 4, 2, 0, 0, 0.0)
    assert _check_rinex_values(obs, ROVER, shifts, _TYPES) > 3000
    a, b = _ephemeris_list(NAV, rtk), _ephemeris_list(nav, rtk)
    assert {x[0] for x in a} == {x[0] for x in b}
    assert all(x in a for x in b)
    opts = RtklibOptions(systems=("gps",))
    ref = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE, options=opts)
    got = solve(rover, None, tmp_path / "raw.pos", base=BASE, options=opts)
    assert_same_solution(ref, got, 5e-4, 2e-3)
