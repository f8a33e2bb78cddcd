"""BINEX logs encoded by the tests from UNAVCO's description
(tests/receiver_frames_binex.py: records 0x00 site position, 0x01-01 GPS ephemeris,
0x7f-05 observables) and decoded by RTKLIB's convrnx: the ubnxi and checksums, the
detection from the content, the observations equal to the simulated truth to the
format's resolution, the real GEONET pair re-encoded giving RTKLIB's solution of the
RINEX files, and the BINEX kinds RTKLIB does not decode refused clearly."""
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from ins.common.errors import InputError

sys.path.insert(0, str(Path(__file__).resolve().parent))
import receiver_frames_binex as bnx  # noqa: E402
from receiver_frames_sbf import crc16_ccitt_spec  # noqa: E402
from receiver_frames import assert_same_solution  # noqa: E402
from test_receiver_formats import BASE, BASE_XYZ, NAV, ROVER, _compare, _rtk, _sim, \
    needs_pair  # noqa: E402
from test_receiver_formats_survey import _TYPES, _check_rinex_values, \
    _ephemerides  # noqa: E402


def _sbp_frame(msg_type, payload, sender=0x42):
    """A Swift SBP frame (``55``, type U2, sender U2, length U1, payload, CRC-16 CCITT
    of type..payload, little-endian)."""
    body = struct.pack("<HHB", msg_type, sender, len(payload)) + payload
    return b"\x55" + body + struct.pack("<H", crc16_ccitt_spec(body))


def test_ubnxi_and_binex_checksums():
    """The library's ubnxi reader inverts the test's writer at each length boundary; a
    short record carries the XOR of its bytes, a long one the CRC-16; both count as
    frames, and not with one bit flipped."""
    from ins.gnss.framing import count_frames, ubnxi
    for v in (0, 1, 127, 128, 16383, 16384, 2 ** 21 - 1, 2 ** 21, 2 ** 29 - 1):
        b = bnx.ubnxi_spec(v)
        assert len(b) == 1 + (v >= 128) + (v >= 2 ** 14) + (v >= 2 ** 21)
        assert ubnxi(b + b"\x00", 0) == (v, len(b))
    short = bnx.binex_record(0x7E, b"\x01\x02\x03")
    assert short == bytes([0xE2, 0x7E, 0x03, 1, 2, 3, 0x7E ^ 0x03 ^ 1 ^ 2 ^ 3])
    long_ = bnx.binex_record(0x7E, bytes(range(200)))
    assert long_[2:4] == bytes([0x81, 0x48]) and len(long_) == 1 + 3 + 200 + 2
    for rec in (short, long_):
        assert count_frames(rec) == {"binex": 1}
        assert count_frames(rec[:5] + bytes([rec[5] ^ 1]) + rec[6:]) == {}


def test_binex_decodes_to_the_simulation(tmp_path):
    """Records 0x7f-05: ranges in mm (the L2 one as a difference), phase ranges in
    0.1 mm from them, Doppler 1/256 Hz, C/N0 0.1 dB-Hz; detected from the content, also
    after leading bytes (a cut record) and with a chance frame of another format in
    the log (the detector once read BINEX only from the file's first byte, after the
    frame counts), but not from a lone chance record in another format's log."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw, detect_format
    data = bnx.simulation_log(_sim())
    noise = np.random.default_rng(3).integers(0, 256, 3000, dtype=np.uint8).tobytes()
    lone = bnx.binex_record(0x7E, b"\x01\x02") + b"\x00"    # a chance record, alone
    for name, content, want in (
            ("sim.bin", data, "binex"), ("cut.bin", data[7:] + data, "binex"),
            ("chance.bin", data[:40] + _sbp_frame(74, b"\x00" * 9) + data, "binex"),
            ("log.jps", noise.replace(b"\xe2", b"\xe3") + 3 * (lone + noise[:99]),
             "javad")):        # records not end to end: not BINEX (the extension)
        (tmp_path / name).write_bytes(content)
        assert detect_format(tmp_path / name) == want, name
    obs, nav = convert_raw(tmp_path / "sim.bin", str(tmp_path), rtk)
    assert nav is None
    lam = {"L1": 299792458.0 / 1575.42e6, "L2": 299792458.0 / 1227.6e6}
    err = _compare(obs, {"L1": "1C", "L2": "2W"},
                   {"C": 1e-3, "L": 0.5e-4 / lam["L2"] + 5e-4 + 1e-6,
                    "D": 1 / 512 + 5e-4 + 1e-6, "S": 0.05 + 1e-6})
    assert set(err) == set("CLDS")
    print("BINEX worst |RINEX - truth|:", err)


def test_binex_kinds_rtklib_does_not_decode_are_refused(tmp_path):
    """A little-endian (sync C2) or enhanced-CRC (E8) BINEX log is recognised as BINEX
    but RTKLIB reads only big-endian regular-CRC forward records: the error says so
    (not only "no observation")."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw, detect_format
    data = bnx.simulation_log(_sim())
    for sync, kind in ((0xC2, "little-endian"), (0xE8, "big-endian, enhanced CRC")):
        log = tmp_path / f"{sync:02x}.bnx"
        log.write_bytes(data.replace(b"\xe2\x7f", bytes([sync, 0x7F])))
        assert detect_format(log) == "binex"
        with pytest.raises(InputError, match=rf"{sync:02x}\.bnx.*only big-endian, regular"
                                             rf"-CRC, forward records.*{kind} \(sync byte "
                                             rf"0x{sync:02X}\)"):
            convert_raw(log, str(tmp_path), rtk)


def _binex_pair(tmp_path, rtk):
    """The rover as BINEX 0x7f-05 with 0x01-01 ephemerides after its first epoch, the
    base as BINEX with its position (0x00, field 0x1d) first."""
    rover_obs, shifts, left = bnx.rinex2_to_binex(ROVER)
    eph, _ = bnx.nav_to_0101(NAV, rtk)
    from ins.gnss.framing import RECOGNISERS
    k = RECOGNISERS["binex"][1](rover_obs, 0)             # the end of the first record
    rover = tmp_path / "rover.bnx"
    rover.write_bytes(rover_obs[:k] + eph + rover_obs[k:])
    base_obs, _, _ = bnx.rinex2_to_binex(BASE)
    base = tmp_path / "base.bin"
    base.write_bytes(bnx.site_position(1316, 518400.0, BASE_XYZ) + base_obs)
    return rover, base, shifts, left


@needs_pair
def test_pair_as_binex_gives_the_rinex_solution(tmp_path):
    """The rover's values come back to the RINEX millimetre (all but the few signals
    without phase, which 0x7f-05 cannot carry), the 0x01-01 records give the broadcast
    orbits again (to float32 where the record has F4); the base's 0x00 position
    becomes its RINEX header's; kinematic PPK of the BINEX pair = that of the RINEX
    files (epochs, Q; positions within 0.5 mm horizontally, 2 mm up: the few code-only
    signals left out and the epochs RTKLIB's decoder times to 0.1 us move the last
    epochs by up to 0.9 mm); ``ins gnss`` takes the pair."""
    rtk = _rtk()
    from ins.cli.main import main
    from ins.gnss.receiver_formats import convert_raw
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.rtklib import read_pos
    rover, base, shifts, left = _binex_pair(tmp_path, rtk)
    assert 0 < len(left) < 10
    obs, nav = convert_raw(rover, str(tmp_path), rtk, stem="r")
    assert _check_rinex_values(obs, ROVER, shifts, _TYPES, left) > 3000
    conv, orig = _ephemerides(nav, rtk), _ephemerides(NAV, rtk)
    assert set(conv) == set(orig)
    for key, v in orig.items():               # toe, toc, sqrt A, e, M0, f0, f1
        np.testing.assert_allclose(conv[key], v, rtol=1e-9, atol=1e-15)
    bobs, _ = convert_raw(base, str(tmp_path), rtk, stem="b")
    head = open(bobs).read().split("END OF HEADER")[0]
    assert "3040" in head and " -3978242.4348  3382841.1715  3649902.7667" in head
    opts = RtklibOptions(systems=("gps",))
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE, options=opts)
    b = solve(rover, NAV, tmp_path / "raw.pos", base=base, options=opts)
    assert_same_solution(a, b, 5e-4, 2e-3)
    cfg = tmp_path / "gps.toml"
    cfg.write_text('[rtklib]\nsystems = ["gps"]\n')
    assert main(["gnss", str(rover), "--base", str(base), "--config", str(cfg),
                 "--no-separation", "-o", str(tmp_path / "cli.pos")]) == 0
    cli = read_pos(tmp_path / "cli.pos")
    assert np.array_equal(cli.quality, a.log.quality)
