"""Raw GNSS logs of the surveyors' receiver formats beyond RTCM3 / NovAtel / UBX, encoded
by the tests from the public format descriptions (tests/receiver_frames_*.py) and
decoded by RTKLIB's convrnx (ins.gnss.receiver_formats): detection from the content,
the observations equal to the simulated truth to each format's resolution, and the
real GEONET pair re-encoded giving RTKLIB's solution of the RINEX files."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import receiver_frames_sbf as sbf  # noqa: E402
from receiver_frames import assert_same_solution  # noqa: E402
from test_receiver_formats import BASE, NAV, ROVER, TOW0, WEEK, _compare, _rtk, \
    _sim, needs_pair  # noqa: E402
from ubx_frames import read_rinex2_obs, read_rinex3_obs  # noqa: E402


# ---------------------------------------------------------------------------------------
# Septentrio SBF

def test_crc16_is_the_ccitt_spec():
    """The library's table CRC-16 (SBF, SBP) = the bitwise CCITT definition, whose
    check value of "123456789" is the catalogue's CRC-16/XMODEM 0x31C3; RTKLIB's own
    rtk_crc16 agrees; an SBF block of the test's encoder counts as one frame, a block
    with one bit flipped as none."""
    from ins.gnss.framing import count_frames, crc16_ccitt
    assert sbf.crc16_ccitt_spec(b"123456789") == 0x31C3
    data = np.random.default_rng(2).integers(0, 256, 611, dtype=np.uint8).tobytes()
    assert crc16_ccitt(data) == sbf.crc16_ccitt_spec(data)
    rtk = _rtk()
    arr = getattr(rtk, "Arr1Dunsigned char")(len(data))
    for i, b in enumerate(data):
        arr[i] = b
    assert rtk.rtk_crc16(arr, len(data)) == crc16_ccitt(data)
    block = sbf.measepoch_end(WEEK, TOW0)
    assert len(block) == 16 and count_frames(block) == {"sbf": 1}
    assert count_frames(block[:10] + bytes([block[10] ^ 4]) + block[11:]) == {}


def test_sbf_measepoch_decodes_to_the_simulation(tmp_path):
    """MeasEpoch (L1 C/A Type 1 + L2 P(Y) Type 2) + MeasEpochEnd: pseudoranges in mm,
    carrier offsets in 0.001 cycle, Doppler 1e-4 Hz (L2's an offset from L1's scaled),
    C/N0 0.25 dB-Hz; the RINEX rounding (1 mm, 0.001 cycle, 0.001 Hz) on top.  The
    format, and the log's complete week, are taken from the content."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw, detect_format, first_epoch
    log = tmp_path / "sim.bin"
    log.write_bytes(sbf.simulation_log(_sim()))
    assert detect_format(log) == "sbf"
    assert first_epoch(log, "sbf") == (WEEK, TOW0)
    obs, nav = convert_raw(log, str(tmp_path), rtk)
    assert nav is None
    err = _compare(obs, {"L1": "1C", "L2": "2W"},
                   {"C": 1e-3, "L": 1e-3 + 1e-6, "D": 1.5e-3, "S": 0.125 + 1e-6})
    print("SBF worst |RINEX - truth|:", err)


def test_sbf_l2c_is_dropped_by_rtklib_without_an_option(tmp_path):
    """RTKLIB's SBF decoder (NEXOBS 0 in the binding) keeps GPS L2 P(Y) (2W) and drops
    L2C (2L) unless given -GL2L: an L2C-only log converts with L1 alone (a limitation
    of the decoder, documented in docs/interfaces.md)."""
    rtk = _rtk()
    from ins.gnss.receiver_formats import convert_raw
    log = tmp_path / "l2c.sbf"
    log.write_bytes(sbf.simulation_log(_sim(), l2_sig=sbf.SIG_L2C))
    obs, _ = convert_raw(log, str(tmp_path), rtk)
    conv = read_rinex3_obs(obs)
    assert len(conv) == 5
    assert set(conv[0][1]["G03"]) == {"C1C", "L1C", "D1C", "S1C"}


def _sbf_rover(tmp_path, rtk):
    """The rover as SBF with GPSRawCA ephemerides after the first epoch."""
    data, shifts = sbf.rinex2_to_sbf(ROVER)
    eph, ephs = sbf.nav_to_gpsrawca(NAV, rtk)
    k = data.find(b"$@", data.find(b"$@", 2) + 2)     # after MeasEpoch + MeasEpochEnd
    rover = tmp_path / "rover.dat"                    # no telling extension
    rover.write_bytes(data[:k] + eph + data[k:])
    return rover, shifts, ephs


def _check_rinex_values(obs, path, shifts, types, left=(), tol=None):
    """Every value of the RINEX 2 file ``path`` (``types``: (RINEX 2 type, RINEX 3 type,
    band)) equal in the converted ``obs`` to the RINEX millimetre, the phases shifted
    back by their arcs' integer cycles (``shifts`` empty: none), but for the signals
    ``left`` out (``{(tow, "Gnn", band)}``), within ``tol`` (``{RINEX 2 type: value}``)
    for a format coarser than the RINEX millimetre; the number of values compared."""
    orig = {round(tow, 5): (tow, rows) for _, tow, rows in read_rinex2_obs(path)}
    conv = read_rinex3_obs(obs)
    assert len(conv) == len(orig)
    arc, compared = {}, 0
    for ymdhms, rows in conv:      # (BINEX epochs come back to 0.1 us: RTKLIB's sum)
        tow, epoch = orig[round(518400.0 + 3600 * ymdhms[3] + 60 * ymdhms[4] + ymdhms[5],
                                5)]
        for sat, v in epoch.items():
            if not sat.startswith("G") or np.isnan(v["C1"][0]):
                continue
            for t2, t3, band in types:
                a, b = v[t2][0], rows.get(sat, {}).get(t3, np.nan)
                if np.isnan(a) or (tow, sat, band) in left:
                    continue
                if t2[0] == "L":
                    key = (int(sat[1:]), band)
                    if (*key, tow) in shifts:
                        arc[key] = shifts[(*key, tow)]
                    b += arc.get(key, 0.0)
                assert abs(a - b) < (tol or {}).get(t2, 5e-4) + 1e-9, (tow, sat, t2, a, b)
                compared += 1
    return compared


def _ephemeris_list(path, rtk):
    """``[((sat, iode), (toe s, toc s, sqrt A, e, M0, f0, f1)), ...]`` of the GPS
    ephemerides of a RINEX navigation file (copied out before RTKLIB's arrays are
    freed)."""
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    try:
        rtk.readrnx(str(path), 1, "", obs, nav, sta)
        out = []
        for i in range(nav.n):
            e = nav.eph[i]
            out.append(((e.sat, e.iode), (e.toe.time, e.toc.time, round(np.sqrt(e.A), 6),
                                          round(e.e, 12), round(e.M0, 12), e.f0, e.f1)))
        return out
    finally:
        rtk.freeobs(obs)
        rtk.freenav(nav, 0xFF)


def _ephemerides(path, rtk):
    """``{(sat, iode): (toe s, toc s, sqrt A, e, M0, f0, f1)}`` (:func:`_ephemeris_list`;
    of two with one IODE the later)."""
    return dict(_ephemeris_list(path, rtk))


_TYPES = (("C1", "C1C", "L1"), ("P2", "C2W", "L2"), ("L1", "L1C", "L1"), ("L2", "L2W", "L2"))


@needs_pair
def test_pair_with_an_sbf_rover_gives_the_rinex_solution(tmp_path):
    """The rover's C1/P2/L1/L2 re-encoded as SBF come back equal to the RINEX millimetre;
    its GPSRawCA subframes give the broadcast ephemerides again; kinematic PPK of the
    SBF rover against the RINEX base = that of the RINEX files (epochs, Q, positions to
    0.1 mm) with the nav file, and with the log's ephemerides alone (no Klobuchar
    coefficients then: a few mm); ``ins gnss`` detects the format from the content."""
    rtk = _rtk()
    from ins.cli.main import main
    from ins.gnss.receiver_formats import convert_raw
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.rtklib import read_pos
    from ins.nav.earth import ned_offset
    rover, shifts, ephs = _sbf_rover(tmp_path, rtk)
    obs, nav = convert_raw(rover, str(tmp_path), rtk, stem="r")
    assert _check_rinex_values(obs, ROVER, shifts, _TYPES) > 3000
    assert _ephemerides(nav, rtk) == _ephemerides(NAV, rtk)
    opts = RtklibOptions(systems=("gps",))
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE, options=opts)
    for navs, tol_up in ((NAV, 1e-4), (None, 5e-3)):
        b = solve(rover, navs, tmp_path / "raw.pos", base=BASE, options=opts)
        assert_same_solution(a, b, 5e-4, tol_up, navs)
    cfg = tmp_path / "gps.toml"
    cfg.write_text('[rtklib]\nsystems = ["gps"]\n')
    assert main(["gnss", "--rover", str(rover), "--base", BASE, "--nav", NAV, "--config",
                 str(cfg), "--no-separation", "-o", str(tmp_path / "cli.pos")]) == 0
    cli = read_pos(tmp_path / "cli.pos")
    assert np.array_equal(cli.quality, a.log.quality)
    assert np.max(np.abs(ned_offset(a.log.lla, cli.lla))) < 5e-4


# ---------------------------------------------------------------------------------------
# Unicore

@pytest.mark.parametrize("l2", ["L2P", "L2C"])
def test_unicore_obsvmb_decodes_to_the_simulation(tmp_path, l2):
    """OBSVMB keeps double pseudoranges and phases (to the RINEX millimetre / 0.001
    cycle), float Doppler, C/N0 in 0.01 dB-Hz; L2 P(Y) (signal type 9) as 2W and L2C
    (17) as 2L, both kept by RTKLIB; the format and week from the content."""
    rtk = _rtk()
    import receiver_frames_unicore as unc
    from ins.gnss.receiver_formats import convert_raw, detect_format, first_epoch
    log = tmp_path / "sim.bin"
    sig, code = (unc.SIG_L2P, "2W") if l2 == "L2P" else (unc.SIG_L2C, "2L")
    log.write_bytes(unc.simulation_log(_sim(), l2_sig=sig))
    assert detect_format(log) == "unicore"
    assert first_epoch(log, "unicore") == (WEEK, TOW0)
    obs, nav = convert_raw(log, str(tmp_path), rtk)
    assert nav is None
    err = _compare(obs, {"L1": "1C", "L2": code},
                   {"C": 5e-4 + 1e-6, "L": 5e-4 + 1e-6, "D": 1e-3, "S": 0.005 + 1e-6})
    assert set(err) == set("CLDS")
    print(f"Unicore ({l2}) worst |RINEX - truth|:", err)


def _unicore_rover_sbf_base(tmp_path, rtk):
    """The rover as Unicore OBSVMB with GPSEPHB ephemerides after the first epoch, the
    base as SBF (no position in its log)."""
    import receiver_frames_unicore as unc
    data = unc.rinex2_to_obsvmb(ROVER)
    eph, ephs = unc.nav_to_gpsephb(NAV, rtk)
    k = 24 + int.from_bytes(data[6:8], "little") + 4
    rover = tmp_path / "rover.log"
    rover.write_bytes(data[:k] + eph + data[k:])
    base = tmp_path / "base.log"
    base.write_bytes(sbf.rinex2_to_sbf(BASE)[0])
    return rover, base, ephs


def _base_lla(rtk):
    """The base's RINEX header position as (lat deg, lon deg, h m), by RTKLIB's
    ecef2pos."""
    xyz, pos = rtk.Arr1Ddouble(3), rtk.Arr1Ddouble(3)
    for i, v in enumerate((-3978242.4348, 3382841.1715, 3649902.7667)):
        xyz[i] = v
    rtk.ecef2pos(xyz, pos)
    return (float(np.degrees(pos[0])), float(np.degrees(pos[1])), float(pos[2]))


@needs_pair
def test_pair_as_unicore_and_sbf_gives_the_rinex_solution(tmp_path):
    """The Unicore rover's values come back equal to the RINEX file's (phases unshifted:
    adr is a double), its GPSEPHB logs give the broadcast orbits again; kinematic PPK of
    the Unicore rover against the SBF base (its position given as base_lla_deg, the
    RINEX header's: an SBF log has none) = that of the RINEX files, also with the
    rover's ephemerides alone; a base log without a position is refused."""
    rtk = _rtk()
    from ins.common.errors import InputError
    from ins.gnss.receiver_formats import convert_raw
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    rover, base, ephs = _unicore_rover_sbf_base(tmp_path, rtk)
    obs, nav = convert_raw(rover, str(tmp_path), rtk, stem="r")
    assert _check_rinex_values(obs, ROVER, {}, _TYPES) > 3000
    conv, orig = _ephemerides(nav, rtk), _ephemerides(NAV, rtk)
    assert set(conv) == set(orig)
    for key, v in orig.items():               # toe, toc, sqrt A, e, M0, f0, f1
        np.testing.assert_allclose(conv[key], v, rtol=1e-14, atol=0)
    opts = RtklibOptions(systems=("gps",), base_lla_deg=_base_lla(rtk))
    a = solve(ROVER, NAV, tmp_path / "rinex.pos", base=BASE,
              options=RtklibOptions(systems=("gps",)))
    for navs, tol_up in ((NAV, 1e-4), (None, 5e-3)):
        b = solve(rover, navs, tmp_path / "raw.pos", base=base, options=opts)
        assert_same_solution(a, b, 5e-4, tol_up, navs)
    with pytest.raises(InputError, match=r"base\.log.*no antenna position"):
        solve(rover, NAV, tmp_path / "x.pos", base=base,
              options=RtklibOptions(systems=("gps",)))


@needs_pair
def test_tight_coupling_and_process_take_unicore_and_sbf(tmp_path, capsys):
    """Tight coupling's double differences from the Unicore rover and the SBF base (the
    formats detected) = those from the RINEX files; ``ins process`` (loose) with them
    gives RTKLIB's solution of the RINEX files as gnss.pos."""
    rtk = _rtk()
    from test_rawgnss import _config

    from ins.cli.main import main
    from ins.estimation.pipeline.gnss_source import RawGnss
    from ins.estimation.pipeline.tight import _read
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    from ins.io.rtklib import read_pos
    hdr = np.array([-3976219.5082, 3382372.5671, 3652512.9849])
    rover, base, _ = _unicore_rover_sbf_base(tmp_path, rtk)
    lla = _base_lla(rtk)
    a = _read(RawGnss(rover=ROVER, base=BASE, nav=(NAV,)), lambda t: hdr)
    b = _read(RawGnss(rover=str(rover), base=str(base), nav=(NAV,),
                      options=RtklibOptions(base_lla_deg=lla)), lambda t: hdr)
    assert len(a) == len(b) == 120
    np.testing.assert_array_equal(a.base.time, b.base.time)
    for k in range(len(a)):
        np.testing.assert_array_equal(a.sats[k], b.sats[k])
        np.testing.assert_allclose(a.range_m[k], b.range_m[k], atol=1e-3)
        np.testing.assert_allclose(a.base.range_m[k], b.base.range_m[k], atol=1e-3)
    cfg = _config(tmp_path, files=f'nav = ["{NAV}"]',
                  rtklib=f"base_lla_deg = [{lla[0]!r}, {lla[1]!r}, {lla[2]!r}]")
    out = tmp_path / "out"
    assert main(["process", "--config", str(cfg), "--rover", str(rover), "--base",
                 str(base), "--nav", NAV, "--no-plots", "-o", str(out)]) == 0
    assert "115 of 120 rover epochs solved (fix 115)" in capsys.readouterr().out
    ref = solve(ROVER, NAV, tmp_path / "ref.pos", base=BASE,
                options=RtklibOptions(systems=("gps",))).log
    got = read_pos(out / "gnss.pos")
    assert np.array_equal(got.quality, ref.quality)
    assert np.max(np.abs(got.lla[:, 2] - ref.lla[:, 2])) < 1e-4
