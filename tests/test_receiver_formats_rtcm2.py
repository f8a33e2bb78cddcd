"""RTCM 2 logs encoded by the tests from RTCM 10402.3 (tests/receiver_frames_rtcm2.py:
types 3, 18 and 19 in 30-bit words with the GPS parity, 6-of-8 bytes) and decoded by
RTKLIB's convrnx: the parity against RTKLIB's own, detection from the content (the
log had to be named before), the observations equal to the simulated truth to the
format's resolution, and the real GEONET pair's base re-encoded giving RTKLIB's
solution of the RINEX files."""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import receiver_frames_rtcm2 as r2  # noqa: E402
from receiver_frames import assert_same_solution  # noqa: E402
from test_receiver_formats import BASE, BASE_XYZ, NAV, ROVER, TOW0, WEEK, _compare, \
    _rtk, _sim, needs_pair  # noqa: E402
from test_receiver_formats_survey import _check_rinex_values  # noqa: E402
from ubx_frames import read_rinex2_obs, read_rinex3_obs  # noqa: E402

_TYPES = (("C1", "C1C", "L1"), ("P2", "C2P", "L2"), ("L1", "L1C", "L1"),
          ("L2", "L2P", "L2"))                      # P-code indicator set on L2: 2P


def _approx_position(obs):
    with open(obs) as f:
        line = next(x for x in f if "APPROX POSITION XYZ" in x)
    return tuple(float(v) for v in line[:42].split())


def test_rtcm2_parity_and_detection(tmp_path):
    """The test's parity (IS-GPS-200 table 20-XIV, chained over the words) is what
    RTKLIB's decode_word accepts, one bit flipped what it refuses; the library's
    recogniser finds every message of an encoded log (type 3 + four 18/19 an
    epoch), none in a message with a bit flipped, and skips bytes not of the 6-of-8
    form as RTKLIB does; the format told from the content (it had to be named)."""
    rtk = _rtk()
    from ins.gnss.framing import count_frames
    from ins.gnss.receiver_formats import detect_format
    rng = np.random.default_rng(5)
    data = [int(x) for x in rng.integers(0, 1 << 24, 300)]
    arr = getattr(rtk, "Arr1Dunsigned char")(3)
    prev = 0
    for i, (d, w) in enumerate(zip(data, r2.words30(data))):
        word = ((prev & 3) << 30) | w
        assert rtk.decode_word(word, arr) == 1
        assert (arr[0] << 16) | (arr[1] << 8) | arr[2] == d
        assert rtk.decode_word(word ^ (1 << (i % 30)), arr) == 0
        prev = w
    log = r2.simulation_log(_sim())
    assert count_frames(log) == {"rtcm2": 21}
    k = 100 * 5 + 7                                    # a byte of the 2nd message
    flipped = log[:k] + bytes([log[k] ^ 0x04]) + log[k + 1:]
    assert count_frames(flipped) == {"rtcm2": 20}
    spaced = b"".join(log[i:i + 60] + b"\r\n" for i in range(0, len(log), 60))
    assert count_frames(spaced) == {"rtcm2": 21}
    noise = np.random.default_rng(6).integers(0x40, 0x80, 1 << 16, dtype=np.uint8)
    assert count_frames(noise.tobytes()) == {}
    (tmp_path / "base.dat").write_bytes(log)
    assert detect_format(tmp_path / "base.dat") == "rtcm2"


def test_rtcm2_18_19_decodes_to_the_simulation(tmp_path):
    """Types 18/19: pseudoranges in 0.02 m, carrier phases in 1/256 cycle (their full
    cycles rolling over at 2^24 and restored by RTKLIB from the pseudorange), no
    Doppler nor C/N0; L1 C/A as 1C, L2 P as 2P; type 3's position to 0.01 m in the
    RINEX header; the week from the epoch given (RTCM 2 has the hour's time only)."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    log = tmp_path / "sim.bin"
    log.write_bytes(r2.simulation_log(_sim()))
    obs, nav = convert_raw(log, str(tmp_path), rtk, epoch=(WEEK, TOW0))
    assert nav is None
    err = _compare(obs, {"L1": "1C", "L2": "2P"},
                   {"C": 0.01 + 5e-4 + 1e-6, "L": 1 / 512 + 5e-4 + 1e-6})
    assert set(err) == set("CL")
    assert max(abs(phase) for _, _, s in _sim() for v in s.values()
               for phase in (v["L1"][1], v["L2"][1])) > 2 ** 24    # rolled over
    assert np.allclose(_approx_position(obs), np.round(BASE_XYZ, 2), atol=1e-6)
    print("RTCM 2 worst |RINEX - truth|:", err)


def _phases_modulo(obs, path):
    """The L1/L2 phases of the RINEX 2 file ``path`` in the converted ``obs`` to 1/256
    cycle (and the RINEX 0.001), modulo 2^23 cycles: RTKLIB restores the rolled-over
    full cycles to within 2^22 cycles of the pseudorange's, which a real receiver's
    phase (its ambiguity arbitrary) need not be; the number compared."""
    orig = {round(tow, 3): rows for _, tow, rows in read_rinex2_obs(path)}
    compared = 0
    for ymdhms, rows in read_rinex3_obs(obs):
        epoch = orig[round(518400.0 + 3600 * ymdhms[3] + 60 * ymdhms[4] + ymdhms[5], 3)]
        for sat, v in epoch.items():
            for t2, t3 in (("L1", "L1C"), ("L2", "L2P")):
                if not sat.startswith("G") or np.isnan(v[t2][0]):
                    continue
                d = (rows[sat][t3] - v[t2][0] + 2.0 ** 22) % 2.0 ** 23 - 2.0 ** 22
                assert abs(d) < 1 / 512 + 5e-4 + 1e-6, (ymdhms, sat, t2, d)
                compared += 1
    return compared


@needs_pair
def test_pair_with_an_rtcm2_base_gives_the_rinex_solution(tmp_path):
    """The base's C1/P2/L1/L2 as types 18/19 come back to their resolution (0.02 m, 1/256
    cycle; the phases modulo 2^23 cycles) and its position (type 3) to 0.01 m, its date
    from the rover's week; kinematic PPK of the RINEX rover against the RTCM 2 base
    (format from the content, week from the rover, position from the log) = that against
    the RINEX base at type 3's position: epochs, Q, and positions to 1 mm."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    base = tmp_path / "base.dat"
    base.write_bytes(r2.rinex2_to_rtcm2(BASE, BASE_XYZ))
    obs, _ = convert_raw(base, str(tmp_path), rtk, stem="b", epoch=(1316, 518400.0))
    tol = {"C1": 0.01 + 5e-4, "P2": 0.01 + 5e-4}
    assert _check_rinex_values(obs, BASE, {}, _TYPES[:2], tol=tol) > 1500
    assert _phases_modulo(obs, BASE) > 1500
    assert read_rinex3_obs(obs)[0][0] == (2005, 4, 2, 0, 0, 0.0)     # week 1316
    assert np.allclose(_approx_position(obs), np.round(BASE_XYZ, 2), atol=1e-6)
    lla = _type3_lla(obs, rtk)
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE,
              options=RtklibOptions(systems=("gps",), base_lla_deg=lla))
    b = solve(ROVER, NAV, tmp_path / "raw.pos", base=base,
              options=RtklibOptions(systems=("gps",)))
    assert_same_solution(a, b, 1e-3, 1e-3)


def _type3_lla(obs, rtk):
    """(lat deg, lon deg, h m) of the converted base's header position (type 3)."""
    xyz = _approx_position(obs)
    pos, x = rtk.Arr1Ddouble(3), rtk.Arr1Ddouble(3)
    for i in range(3):
        x[i] = xyz[i]
    rtk.ecef2pos(x, pos)
    return np.degrees(pos[0]), np.degrees(pos[1]), pos[2]


@needs_pair
def test_gnss_tight_and_process_take_an_nvs_rover_and_an_rtcm2_base(tmp_path, capsys):
    """Both formats told from the content: ``ins gnss`` with the NVS rover and the
    RTCM 2 base = RTKLIB's L1 solution of the RINEX files (base at type 3's position)
    to 1 mm; tight coupling's epochs from the RTCM 2 base = those from the RINEX
    base (the satellites, the base's pseudoranges to 0.01 m); ``ins process`` (loose)
    with the NVS rover and the RTCM 2 base writes that solution as gnss.pos."""
    rtk = _rtk()
    import receiver_frames_nvs as nvs
    from test_rawgnss import _config

    from ins.cli.main import main
    from ins.estimation.pipeline.gnss_source import RawGnss
    from ins.estimation.pipeline.tight import _read
    from ins.gnss.framing import RECOGNISERS
    from ins.gnss.receiver_formats import convert_raw
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.rtklib import read_pos
    from ins.nav.earth import ned_offset
    base = tmp_path / "base.log"
    base.write_bytes(r2.rinex2_to_rtcm2(BASE, BASE_XYZ))
    data, _ = nvs.rinex2_to_nvs(ROVER)
    k = RECOGNISERS["nvs"][1](data, 0)
    rover = tmp_path / "rover.log"
    rover.write_bytes(nvs.raw_f5(1316, 518399.0, []) + data[:k] + data[k:])
    obs, _ = convert_raw(base, str(tmp_path), rtk, stem="b", epoch=(1316, 518400.0))
    lla = _type3_lla(obs, rtk)
    ref = solve(ROVER, NAV, tmp_path / "ref.pos", base=BASE,
                options=RtklibOptions(systems=("gps",), frequencies=1,
                                      base_lla_deg=lla)).log
    cfg = tmp_path / "l1.toml"
    cfg.write_text('[rtklib]\nsystems = ["gps"]\nfrequencies = 1\n')
    assert main(["gnss", "--rover", str(rover), "--base", str(base), "--nav", NAV,
                 "--config", str(cfg), "--no-separation", "-o",
                 str(tmp_path / "cli.pos")]) == 0
    cli = read_pos(tmp_path / "cli.pos")
    assert np.array_equal(cli.time, ref.time) and np.array_equal(cli.quality, ref.quality)
    assert np.max(np.abs(ned_offset(ref.lla, cli.lla))) < 1e-3
    hdr = np.array([-3976219.5082, 3382372.5671, 3652512.9849])
    a = _read(RawGnss(rover=ROVER, base=BASE, nav=(NAV,)), lambda t: hdr)
    b = _read(RawGnss(rover=ROVER, base=str(base), nav=(NAV,)), lambda t: hdr)
    assert len(a) == len(b) == 120
    np.testing.assert_array_equal(a.base.time, b.base.time)
    for i in range(len(a)):
        np.testing.assert_array_equal(a.sats[i], b.sats[i])
        np.testing.assert_allclose(a.base.range_m[i], b.base.range_m[i], atol=0.0105)
    cfg = _config(tmp_path, files=f'nav = ["{NAV}"]', rtklib="frequencies = 1")
    out = tmp_path / "out"
    assert main(["process", "--config", str(cfg), "--rover", str(rover), "--base",
                 str(base), "--nav", NAV, "--no-plots", "-o", str(out)]) == 0
    assert "of 120 rover epochs solved" in capsys.readouterr().out
    got = read_pos(out / "gnss.pos")
    loose = solve(ROVER, NAV, tmp_path / "ref2.pos", base=BASE,
                  options=RtklibOptions(frequencies=1, base_lla_deg=lla)).log
    assert np.array_equal(got.quality, loose.quality)
    assert np.max(np.abs(ned_offset(loose.lla, got.lla))) < 1e-3
