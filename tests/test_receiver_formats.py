"""Raw GNSS logs of every receiver format RTKLIB decodes (ins.gnss.receiver_formats):
checksums against published test vectors, detection from the content, and logs the
tests encode themselves (tests/receiver_frames.py: RTCM3 MSM4/MSM7 + 1005, NovAtel
OEM4 RANGEB + RAWEPHEMB) decoded by RTKLIB's convrnx back to the simulated truth (to
the resolution each format keeps), and the real GEONET pair re-encoded giving RTKLIB's
RINEX solution through ``solve`` and ``ins gnss``."""
import os
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

from ins.common.errors import InputError

sys.path.insert(0, str(Path(__file__).resolve().parent))
import receiver_frames as rf  # noqa: E402
from receiver_frames import assert_same_solution  # noqa: E402
from ubx_frames import read_rinex2_obs, read_rinex3_obs  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PAIR = ROOT.parent / "shared" / "real" / "rtklib_static_pair"
ROVER, BASE, NAV = (str(PAIR / n) for n in ("07590920.05o", "30400920.05o", "07590920.05n"))
BASE_XYZ = (-3978242.4348, 3382841.1715, 3649902.7667)    # 3040's RINEX header
needs_pair = pytest.mark.skipif(not PAIR.is_dir(), reason="../shared/real is absent")
WEEK, TOW0 = 2300, 345600.0
#: the published RTCM 1005 example (RTCM 10403, station 2003): its last 3 bytes the CRC
RTCM_1005_EXAMPLE = bytes.fromhex("D300133ED7D30202980EDEEF34B4BD62AC0941986F33360B98")


def _rtk():
    return pytest.importorskip("pyrtklib5")


# ---------------------------------------------------------------------------------------
# checksums

def test_crc24q_is_the_published_example():
    from ins.gnss.framing import count_frames, crc24q
    body, crc = RTCM_1005_EXAMPLE[:-3], int.from_bytes(RTCM_1005_EXAMPLE[-3:], "big")
    assert rf.crc24q_spec(body) == crc == 0x360B98
    assert crc24q(body) == crc
    assert crc24q(b"123456789") == rf.crc24q_spec(b"123456789") == 0xCDE703  # catalogue
    data = np.random.default_rng(0).integers(0, 256, 500, dtype=np.uint8).tobytes()
    assert crc24q(data) == rf.crc24q_spec(data)
    # the test's 1005 encoder gives the published frame for its values
    assert rf.rtcm1005(2003, (1114104.5999, -4850729.7108, 3975521.4643)) == \
        RTCM_1005_EXAMPLE
    assert count_frames(RTCM_1005_EXAMPLE) == {"rtcm3": 1}
    assert count_frames(RTCM_1005_EXAMPLE[:-1] + b"\x99") == {}


def test_crc32_is_the_novatel_manual_algorithm():
    """The library's (zlib with the inversions undone) = the manual's bitwise
    CRC32Value loop; that loop with the usual inversions gives the published CRC-32
    check value of "123456789", 0xCBF43926."""
    from ins.gnss.framing import crc16_ccitt, crc32_novatel
    data = np.random.default_rng(1).integers(0, 256, 777, dtype=np.uint8).tobytes()
    assert crc32_novatel(data) == rf.crc32_novatel_spec(data)

    def standard(d):        # the same loop, seeded with ~0 and inverted at the end
        crc = 0xFFFFFFFF
        for byte in d:
            c = (crc ^ byte) & 0xFF
            for _ in range(8):
                c = (c >> 1) ^ 0xEDB88320 if c & 1 else c >> 1
            crc = ((crc >> 8) & 0x00FFFFFF) ^ c
        return crc ^ 0xFFFFFFFF
    assert standard(b"123456789") == 0xCBF43926
    assert crc16_ccitt(b"123456789") == 0x31C3                  # CRC-16/XMODEM check
    rtk = pytest.importorskip("pyrtklib5")                      # and RTKLIB's own
    arr = getattr(rtk, "Arr1Dunsigned char")(len(data))
    for i, b in enumerate(data):
        arr[i] = b
    assert rtk.rtk_crc32(arr, len(data)) == crc32_novatel(data)


# ---------------------------------------------------------------------------------------
# simulated observations through RTKLIB

def _sim():
    return rf.simulated_epochs(WEEK, TOW0, n_epochs=5)


def _msm_log(kind, station=0):
    data = b""
    for _, tow, sats in _sim():
        lock = 10.0 + tow - TOW0
        data += rf.msm_gps(kind, tow, {p: {rf.MSM_SIG_1C: v["L1"] + (lock,),
                                           rf.MSM_SIG_2L: v["L2"] + (lock,)}
                                       for p, v in sats.items()}, station=station)
    return data


def _rangeb_log():
    return b"".join(rf.rangeb(w, tow, [(p, b, *v[b], 10.0 + tow - TOW0)
                                        for p, v in sats.items() for b in ("L1", "L2")])
                    for w, tow, sats in _sim())


def _compare(obs_path, codes, tol):
    """Max |decoded - truth| per quantity over every epoch and satellite."""
    conv = read_rinex3_obs(obs_path)
    truth = _sim()
    assert len(conv) == len(truth)
    err = {}
    for (_, tow, sats), (ymdhms, rows) in zip(truth, conv):
        assert abs(ymdhms[3] * 3600 + ymdhms[4] * 60 + ymdhms[5] - tow % 86400) < 1e-6
        assert set(rows) == {f"G{p:02d}" for p in sats}
        for p, v in sats.items():
            for band, code in codes.items():
                for i, q in enumerate("CLDS"):
                    name = q + code
                    if name in rows[f"G{p:02d}"]:
                        d = abs(rows[f"G{p:02d}"][name] - v[band][i])
                        err[q] = max(err.get(q, 0.0), d)
    for q, t in tol.items():
        assert err[q] <= t, (q, err[q], t)
    return err


@pytest.mark.parametrize("kind", [4, 7])
def test_rtcm3_msm_decodes_to_the_simulation(tmp_path, kind):
    """MSM4: pseudorange in units of 2^-24 ms (17.9 mm: within 9 mm after rounding),
    phase range 2^-29 ms, C/N0 1 dB-Hz, no Doppler; MSM7: 2^-29 ms (0.56 mm) and 2^-31
    ms, Doppler from the rough (1 m/s) plus fine (0.1 mm/s) phase-range rate, C/N0
    2^-4 dB-Hz; RINEX keeps 1 mm / 0.001 cycle / 0.001 Hz."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw, detect_format
    log = tmp_path / "sim.bin"                 # no telling extension: the content
    log.write_bytes(_msm_log(kind))
    assert detect_format(log) == "rtcm3"
    obs, nav = convert_raw(log, str(tmp_path), rtk, epoch=(WEEK, TOW0))
    assert nav is None
    res_pr = 299792.458 * (2.0 ** -24 if kind == 4 else 2.0 ** -29)
    tol = {"C": res_pr / 2 + 5e-4 + 1e-4, "L": 0.004 if kind == 4 else 0.0015,
           "S": 0.5 if kind == 4 else 0.032}
    if kind == 7:
        tol["D"] = 0.0015
    err = _compare(obs, {"L1": "1C", "L2": "2L"}, tol)
    print(f"MSM{kind} worst |RINEX - truth|:", err)
    assert (kind == 4) == ("D" not in err)


def test_oem4_rangeb_decodes_to_the_simulation(tmp_path):
    """RANGEB keeps double pseudoranges and phases: equal to the RINEX millimetre;
    Doppler and C/N0 are floats."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw, detect_format, first_epoch
    log = tmp_path / "sim.bin"
    log.write_bytes(_rangeb_log())
    assert detect_format(log) == "oem4"
    assert first_epoch(log, "oem4") == (WEEK, TOW0)          # the header's full week
    obs, _ = convert_raw(log, str(tmp_path), rtk)
    err = _compare(obs, {"L1": "1C", "L2": "2W"}, {"C": 5e-4 + 1e-6, "L": 5e-4 + 1e-6,
                                             "D": 1e-3, "S": 0.005})
    print("RANGEB worst |RINEX - truth|:", err)


def test_detection_and_errors(tmp_path):
    """RINEX by its header, the binary formats by their valid frames (also after
    leading garbage, and a file of two formats by the one with more frames), BINEX by
    its sync byte, else the extension; otherwise an error naming the formats."""
    from ins.gnss.receiver_formats import check_format, detect_format
    cases = {"a.obs": b"     3.04           OBSERVATION DATA    M                   "
                      b"RINEX VERSION / TYPE\n",
             "b.dat": b"\x00garbage" + _msm_log(7),
             "c.dat": _rangeb_log()[5:] + _rangeb_log(),     # a cut first frame
             "d.dat": rinex2_to_ubx_sim(),
             "e.dat": bytes([0xE2, 0x7F, 0x05]) + b"\x00" * 40,
             "f.jps": b"no frames here",
             "g.dat": _msm_log(7) + _rangeb_log() + _rangeb_log()}
    want = {"a.obs": "rinex", "b.dat": "rtcm3", "c.dat": "oem4", "d.dat": "ubx",
            "e.dat": "binex", "f.jps": "javad", "g.dat": "oem4"}
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
        assert detect_format(tmp_path / name) == want[name], name
    (tmp_path / "h.dat").write_bytes(b"\x01\x02 nothing")
    with pytest.raises(InputError, match=r"h\.dat.*cannot tell the receiver format.*"
                                         r"--gnss-format.*rinex, rtcm2, rtcm3, oem4, ubx"):
        detect_format(tmp_path / "h.dat")
    assert check_format("RTCM3", "--gnss-format") == "rtcm3"
    with pytest.raises(InputError, match=r"--gnss-format: unknown .*'rtcm4'.*rtcm3"):
        check_format("rtcm4", "--gnss-format")
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    with pytest.raises(InputError, match=r"h\.dat.*no observation.*RTCM 3.*MSM4"):
        convert_raw(tmp_path / "h.dat", str(tmp_path), rtk, fmt="rtcm3")
    src = (tmp_path / "c.dat").read_bytes()
    convert_raw(tmp_path / "c.dat", str(tmp_path), rtk, stem="c")
    assert (tmp_path / "c.dat").read_bytes() == src                 # input untouched


def rinex2_to_ubx_sim():
    """A short UBX log of the simulation (RXM-RAWX frames)."""
    from ubx_frames import rawx
    return b"".join(rawx(w, tow, [(v["L1"][0], v["L1"][1], 0, p, 0, 1000.0, 45)
                                  for p, v in sats.items()]) for w, tow, sats in _sim())


# ---------------------------------------------------------------------------------------
# the real pair, re-encoded

def _pair_logs(tmp_path, rtk):
    """The rover as NovAtel RANGEB with RAWEPHEMB ephemerides (after the first epoch),
    the base as RTCM3 1005 + MSM7 (station 3040, its header position)."""
    rb = rf.rinex2_to_rangeb(ROVER)
    eph, ephs = rf.nav_to_rawephemb(NAV, rtk)
    k = 28 + struct.unpack("<H", rb[8:10])[0] + 4
    rover = tmp_path / "rover.gps"
    rover.write_bytes(rb[:k] + eph + rb[k:])
    msm, shifts = rf.rinex2_to_msm(BASE, 7, station=3040)
    base = tmp_path / "base.rtcm3"
    base.write_bytes(rf.rtcm1005(3040, BASE_XYZ) + msm)
    return rover, base, ephs, shifts


@needs_pair
def test_pair_as_novatel_and_rtcm3_gives_the_rinex_solution(tmp_path):
    """Every C1/P2 and L1/L2 value of the base re-encoded as MSM7 comes back equal to the
    RINEX millimetre (the phases shifted by the integer cycles a receiver aligns a new
    arc with); kinematic PPK of the NovAtel rover against the RTCM3 base = that of the
    RINEX files (same epochs, Q, positions to 0.1 mm), with the nav file and with the
    rover's RAWEPHEMB alone (then without Klobuchar coefficients: about a millimetre);
    the base's 1005 position replaces the RINEX header's; the CLI takes them."""
    rtk = _rtk()
    from ins.cli.main import main
    from ins.gnss.receiver_formats import convert_raw
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    rover, base, ephs, shifts = _pair_logs(tmp_path, rtk)
    obs, _ = convert_raw(base, str(tmp_path), rtk, stem="b", navs=[NAV])
    orig = {tow: rows for _, tow, rows in read_rinex2_obs(BASE)}
    conv = read_rinex3_obs(obs)
    assert len(conv) == len(orig) == 120
    arc = {}
    compared = 0
    for ymdhms, rows in conv:
        tow = 518400.0 + 3600 * ymdhms[3] + 60 * ymdhms[4] + ymdhms[5]
        for sat, v in orig[tow].items():
            for t2, t3, band in (("C1", "C1C", "L1"), ("P2", "C2W", "L2"),
                                 ("L1", "L1C", "L1"), ("L2", "L2W", "L2")):
                a, b = v[t2][0], rows.get(sat, {}).get(t3, np.nan)
                if np.isnan(a):
                    continue
                if t2[0] == "L":
                    key = (int(sat[1:]), band)
                    if (*key, tow) in shifts:
                        arc[key] = shifts[(*key, tow)]
                    b += arc[key]
                assert abs(a - b) < 5e-4, (tow, sat, t2, a, b)
                compared += 1
    assert compared > 3000
    opts = RtklibOptions(systems=("gps",))
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE, options=opts)
    for nav, tol_up in ((NAV, 1e-4), (None, 2e-3)):
        b = solve(rover, nav, tmp_path / "raw.pos", base=base, options=opts)
        assert_same_solution(a, b, 5e-4, tol_up, nav)
    cfg = tmp_path / "gps.toml"
    cfg.write_text('[rtklib]\nsystems = ["gps"]\nbase_format = "rtcm3"\n')
    assert main(["gnss", "--rover", str(rover), "--gnss-format", "oem4", "--base",
                 str(base), "--nav", NAV, "--config", str(cfg), "--no-separation", "-o",
                 str(tmp_path / "cli.pos")]) == 0
    assert sorted(p for p in os.listdir(tmp_path) if p.endswith(".pos")) == \
        ["cli.pos", "raw.pos", "rinex.pos"]


@needs_pair
def test_a_base_log_without_a_position_is_refused(tmp_path):
    rtk = _rtk()
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    rover, base, _, _ = _pair_logs(tmp_path, rtk)
    msm, _ = rf.rinex2_to_msm(BASE, 4)
    base.write_bytes(msm)                                    # no 1005
    with pytest.raises(InputError, match=r"base\.rtcm3.*no antenna position.*1005.*"
                                         r"base_position"):
        solve(rover, NAV, tmp_path / "x.pos", base=base,
              options=RtklibOptions(systems=("gps",)))


@needs_pair
def test_tight_coupling_pairs_the_novatel_rover_with_the_rtcm3_base(tmp_path):
    """Tight coupling's double differences (ins.estimation.pipeline.tight._read) from
    the NovAtel rover and the RTCM3 base (its 1005 position, its week from the rover):
    the same pairs and ranges as from the RINEX files; the format named in [rtklib]
    rover_format / base_format is taken as it is."""
    rtk = _rtk()
    from ins.estimation.pipeline.gnss_source import RawGnss
    from ins.estimation.pipeline.tight import _read
    from ins.gnss.rtklib_options import RtklibOptions
    hdr = np.array([-3976219.5082, 3382372.5671, 3652512.9849])
    rover, base, _, _ = _pair_logs(tmp_path, rtk)
    a = _read(RawGnss(rover=ROVER, base=BASE, nav=(NAV,)), lambda t: hdr)
    opts = RtklibOptions(rover_format="oem4", base_format="rtcm3")
    b = _read(RawGnss(rover=str(rover), base=str(base), nav=(NAV,), options=opts),
              lambda t: hdr)
    assert len(a) == len(b) == 120
    np.testing.assert_array_equal(a.base.time, b.base.time)
    for k in range(len(a)):
        np.testing.assert_array_equal(a.sats[k], b.sats[k])
        np.testing.assert_allclose(a.range_m[k], b.range_m[k], atol=1e-3)
        np.testing.assert_allclose(a.base.range_m[k], b.base.range_m[k], atol=1e-3)
    assert sorted(os.listdir(tmp_path)) == ["base.rtcm3", "rover.gps"]


@needs_pair
def test_process_takes_the_logs_loose(tmp_path, capsys):
    """``ins process --rover rover.gps --base base.rtcm3 --rover-format oem4`` (loose):
    gnss.pos equal to RTKLIB's solution of the RINEX files; [rtklib] base_format in the
    config; a format for a run without raw GNSS is refused."""
    rtk = _rtk()
    from test_rawgnss import _config

    from ins.cli.main import main
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.rtklib import read_pos
    rover, base, _, _ = _pair_logs(tmp_path, rtk)
    cfg = _config(tmp_path, files=f'nav = ["{NAV}"]', rtklib='base_format = "rtcm3"')
    out = tmp_path / "out"
    assert main(["process", "--config", str(cfg), "--rover", str(rover), "--base",
                 str(base), "--nav", NAV, "--rover-format", "oem4", "--no-plots", "-o",
                 str(out)]) == 0
    assert "115 of 120 rover epochs solved (fix 115)" in capsys.readouterr().out
    ref = solve(ROVER, NAV, tmp_path / "ref.pos", base=BASE,
                options=RtklibOptions(systems=("gps",))).log
    got = read_pos(out / "gnss.pos")
    assert np.array_equal(got.quality, ref.quality)
    assert np.max(np.abs(got.lla[:, 2] - ref.lla[:, 2])) < 1e-4
    plain = tmp_path / "plain.toml"                    # no [rtklib], no raw GNSS
    plain.write_text(cfg.read_text().replace('[rtklib]\nsystems = ["gps"]\n'
                                             'base_format = "rtcm3"\n', ""))
    assert main(["process", "--config", str(plain), "--gnss", str(out / "gnss.pos"),
                 "--rover-format", "oem4", "-o", str(tmp_path / "o2")]) == 2
    assert "--rover-format / --base-format go with raw GNSS" in capsys.readouterr().err
