"""Hemisphere ``$BIN`` logs encoded by the tests from Hemisphere's GPS Technical
Reference (tests/receiver_frames_hemisphere.py: Bin 76 dual-frequency observations,
Bin 95 ephemerides) and decoded by RTKLIB's convrnx: detection from the content (also
against chance frames of another format), the observations equal to the simulated
truth to the format's resolution, and the real GEONET pair's rover re-encoded giving
RTKLIB's solution of the RINEX files."""
import sys
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parent))
import receiver_frames_hemisphere as hem  # noqa: E402
from receiver_frames import assert_same_solution  # noqa: E402
from test_receiver_formats import BASE, NAV, ROVER, _compare, _rtk, _sim, \
    needs_pair  # noqa: E402
from test_receiver_formats_survey import _check_rinex_values, _ephemeris_list  # noqa: E402

_TYPES = (("C1", "C1C", "L1"), ("P2", "C2P", "L2"), ("L1", "L1C", "L1"),
          ("L2", "L2P", "L2"))                            # Bin 76's L2 P: RINEX 2P


def test_bin76_decodes_to_the_simulation(tmp_path):
    """Bin 76: code in 1/256 m (the L2 one its low 16 bits), phase in 1/1024 cycle
    modulo 8192 cycles, Doppler 1/512 Hz, C/N0 from the SNR count; the $BIN frames
    (16-bit sum) counted by the detector."""
    rtk = _rtk()
    from ins.gnss.framing import count_frames
    from ins.gnss.receiver_formats import convert_raw, detect_format
    data = hem.simulation_log(_sim())
    assert count_frames(data) == {"hemisphere": 5}
    assert count_frames(data[:100] + bytes([data[100] ^ 1]) + data[101:]) == \
        {"hemisphere": 4}
    log = tmp_path / "sim.bin"
    log.write_bytes(data)
    assert detect_format(log) == "hemisphere"
    obs, nav = convert_raw(log, str(tmp_path), rtk)
    assert nav is None
    err = _compare(obs, {"L1": "1C", "L2": "2P"},
                   {"C": 1 / 512 + 5e-4 + 1e-6, "L": 1 / 2048 + 5e-4 + 1e-6,
                    "D": 1 / 1024 + 5e-4 + 1e-4, "S": 0.05})
    assert set(err) == set("CLDS")
    print("Hemisphere worst |RINEX - truth|:", err)


@needs_pair
def test_pair_with_a_hemisphere_rover_gives_the_rinex_solution(tmp_path):
    """The real rover as Bin 76 + Bin 95 holds chance SBP frames (3 of them), which
    once made it a "swift" log (the $BIN check came after the frame counts): now
    detected as Hemisphere; its values come back to the format's resolution, its Bin
    95 the broadcast ephemerides (in their week era: the subframes' 10-bit week needs
    RTKLIB's clock set from Bin 76; RTKLIB's Bin 95 decoder keeps the first of two
    ephemerides with one IODE); kinematic PPK against the RINEX base: the RINEX
    files' epochs, fixes and positions (to 0.1 mm; the code's 1/256 m does not move
    the fixed solution)."""
    rtk = _rtk()
    from ins.gnss.framing import count_frames
    from ins.gnss.receiver_formats import convert_raw, detect_format
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    data, shifts, left = hem.rinex2_to_bin76(ROVER)
    eph, _ = hem.nav_to_bin95(NAV, rtk)
    k = data.find(b"$BIN", 4)                              # after the first epoch
    rover = tmp_path / "rover.bin"
    rover.write_bytes(data[:k] + eph + data[k:])
    counts = count_frames(rover.read_bytes())
    assert counts["hemisphere"] == 120 + len(eph) // 140 and 0 < counts.get("swift", 0)
    assert detect_format(rover) == "hemisphere"
    obs, nav = convert_raw(rover, str(tmp_path), rtk, stem="r")
    tol = {"C1": 1 / 512 + 5e-4, "P2": 1 / 512 + 5e-4, "L1": 1 / 2048 + 5e-4,
           "L2": 1 / 2048 + 5e-4}
    assert _check_rinex_values(obs, ROVER, shifts, _TYPES, left, tol) > 3000
    conv, orig = _ephemeris_list(nav, rtk), _ephemeris_list(NAV, rtk)
    assert set(conv) <= set(orig) and {k for k, _ in conv} == {k for k, _ in orig}
    assert len(orig) - len(conv) == 1     # RTKLIB keeps one of a satellite's two IODE 239
    opts = RtklibOptions(systems=("gps",))
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE, options=opts)
    b = solve(rover, NAV, tmp_path / "raw.pos", base=BASE, options=opts)
    d = assert_same_solution(a, b, 1e-4, 1e-4)
    print("Hemisphere rover: max |d| N/E/D m", d)
