"""Trimble RT-17 logs encoded by the tests from Trimble's Serial Reference
Specification (tests/receiver_frames_rt17.py: RAWDATA type 17, concise) and decoded by
RTKLIB's convrnx: detection from the content, the observations equal to the simulated
truth to the format's resolution (the record has no GPS week: it comes from the epoch
or navigation given), and the real GEONET pair re-encoded giving RTKLIB's solution of
the RINEX files."""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import receiver_frames_rt17 as rt  # noqa: E402
from test_receiver_formats import BASE, NAV, ROVER, TOW0, WEEK, _compare, _rtk, _sim, \
    needs_pair  # noqa: E402
from test_receiver_formats_survey import _TYPES, _base_lla, \
    _check_rinex_values  # noqa: E402


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
    from ins.nav.earth import ned_offset
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
    assert b.rover_epochs == a.rover_epochs == 120
    assert np.array_equal(a.log.time, b.log.time)
    assert np.array_equal(a.log.quality, b.log.quality)
    d = np.abs(ned_offset(a.log.lla, b.log.lla))
    assert np.max(d) < 1e-4, d.max(0)
