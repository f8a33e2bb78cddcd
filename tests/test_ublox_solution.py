"""A u-blox receiver's own solution (ins.io.ublox): NAV-PVT messages and NMEA sentences
encoded here by hand (the u-blox protocol's field layout; NMEA 0183 GGA/RMC/GST with
their XOR checksums), read back through read_gnss.

Independent truths: the values packed; GPS time against astropy's UTC -> GPS; a GGA
without geoid separation at NGA's EGM96 test point 38.6281550 N 269.7791550 E, where NGA
publishes N = -31.628 m, so h = altitude - 31.628 m.
"""
import struct

import numpy as np
import pytest

from ins.common.errors import InputError, InputWarning
from ins.io.gnss import read_gnss, sniff_format


def _ubx(cls_id, payload):
    body = cls_id + struct.pack("<H", len(payload)) + payload
    a = b = 0
    for byte in body:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return b"\xb5\x62" + body + bytes((a, b))


def _pvt(itow_ms, lat, lon, height_mm, hmsl_mm, carr=2, fix=3, flags_ok=1, hacc=14, vacc=20,
         vel=(1000, -2000, 300), sacc=50, date=(2024, 2, 8, 0, 0, 0), valid=3):
    flags = flags_ok | 2 | (carr << 6)
    p = struct.pack("<IHBBBBBBIiBBBBiiiiIIiiiiiIIHH", itow_ms, *date, valid, 10, 0, fix,
                    flags, 0, 17, int(round(lon * 1e7)), int(round(lat * 1e7)), height_mm,
                    hmsl_mm, hacc, vacc, *vel, 2236, 0, sacc, 100000, 120, 0)
    return _ubx(b"\x01\x07", p + bytes(92 - len(p)))


def test_nav_pvt(tmp_path):
    from astropy.time import Time
    tow0 = int((Time("2024-02-08T00:00:00", scale="utc").gps % 604800) * 1000)
    msgs = [_pvt(tow0 + 200 * k, 30.5 + 1e-6 * k, 114.3, 35_000 + k, 49_000 + k,
                 carr=(2, 1, 0, 2)[k]) for k in range(4)]
    msgs.insert(2, _pvt(tow0 + 300, 30.5, 114.3, 35_000, 49_000, flags_ok=0))  # dropped
    other = _ubx(b"\x02\x15", bytes(16))                     # RXM-RAWX: skipped
    p = tmp_path / "receiver.ubx"
    p.write_bytes(other + b"".join(msgs) + b"\xb5\x62\x01\x07junk")
    assert sniff_format(p) == "ubx"
    log = read_gnss(p)
    assert len(log) == 4 and list(log.quality) == [1, 2, 4, 1]      # diffSoln set: DGPS
    np.testing.assert_allclose(log.time, tow0 / 1000.0 + 0.2 * np.arange(4))
    np.testing.assert_allclose(np.rad2deg(log.lla[:, 0]), 30.5 + 1e-6 * np.arange(4),
                               atol=1e-9)
    np.testing.assert_allclose(log.lla[:, 2], 35.0 + 1e-3 * np.arange(4))   # height, not hMSL
    np.testing.assert_allclose(log.sigma_ned_m[0], [0.014 / np.sqrt(2)] * 2 + [0.020])
    np.testing.assert_allclose(log.v_n[0], [1.0, -2.0, 0.3])
    np.testing.assert_allclose(log.sigma_vel_ned_mps[0], [0.05] * 3)
    bad = tmp_path / "bad.ubx"
    bad.write_bytes(_pvt(tow0, 30.5, 114.3, 35_000, 300_000))           # N = -265 m
    with pytest.raises(InputError, match=r"bad.ubx: record 1: height - hMSL"):
        read_gnss(bad)
    none = tmp_path / "none.ubx"
    none.write_bytes(other)
    with pytest.raises(InputError, match="no NAV-PVT"):
        read_gnss(none)


def _nmea(body):
    c = 0
    for ch in body.encode():
        c ^= ch
    return f"${body}*{c:02X}"


def _ddmm(v, deg_digits):
    a = abs(v)
    d = int(a)
    return f"{d:0{deg_digits}d}{(a - d) * 60:09.6f}"


def _gga(tod, lat, lon, q, alt, sep, hdop=0.8):
    ns, ew = ("N" if lat >= 0 else "S"), ("E" if lon >= 0 else "W")
    s = "" if sep is None else f"{sep:.3f}"
    return _nmea(f"GNGGA,{tod},{_ddmm(lat, 2)},{ns},{_ddmm(lon, 3)},{ew},{q},12,{hdop},"
                 f"{alt:.3f},M,{s},M,,")


def test_nmea_gga_with_separation_and_gst(tmp_path):
    from astropy.time import Time
    lines = [_nmea("GNRMC,235959.00,A,3030.0000,N,11418.0000,E,0.0,0.0,070224,,,A"),
             _gga("235959.00", 30.5, 114.3, 4, 20.0, -14.1),
             _nmea("GNGST,235959.00,0.5,0.02,0.01,0.0,0.012,0.011,0.025"),
             _gga("235959.50", 30.5, 114.3, 5, 20.1, -14.1),
             _gga("235959.80", 30.5, 114.3, 0, 0.0, -14.1)]          # invalid: dropped
    p = tmp_path / "rover.nmea"
    p.write_text("\n".join(lines) + "\n")
    assert sniff_format(p) == "nmea"
    with pytest.warns(InputWarning, match="1 of 2 GGA epochs without a GST"):
        log = read_gnss(p)
    assert list(log.quality) == [1, 2] and list(log.line) == [2, 4]
    np.testing.assert_allclose(log.lla[:, 2], [20.0 - 14.1, 20.1 - 14.1], atol=1e-9)
    np.testing.assert_allclose(log.sigma_ned_m[0], [0.012, 0.011, 0.025])
    np.testing.assert_allclose(log.sigma_ned_m[1], [0.8 * 0.3, 0.8 * 0.3, 1.6 * 0.3])
    gps = Time("2024-02-07T23:59:59", scale="utc").gps % 604800
    np.testing.assert_allclose(log.time, [gps, gps + 0.5], atol=1e-6)
    np.testing.assert_allclose(np.rad2deg(log.lla[0, :2]), [30.5, 114.3], atol=1e-9)


def test_nmea_without_separation_takes_the_geoid(tmp_path):
    from ins.io.geoid import load_geoid
    try:
        load_geoid("EGM96")
    except InputError as exc:
        pytest.skip(f"no EGM96 grid: {exc}")
    lat, lon = 38.6281550, 269.7791550 - 360.0
    p = tmp_path / "msl.nmea"
    p.write_text("\n".join([_nmea("GPRMC,120000.00,A,,,,,,,010324,,,A"),
                            _gga("120000.00", lat, lon, 1, 100.0, None),
                            _nmea("GPGST,120000.00,1,1,1,0,1.5,1.2,3.0")]) + "\n")
    with pytest.warns(InputWarning, match="converted to ellipsoidal with EGM96"):
        log = read_gnss(p)
    assert abs(log.lla[0, 2] - (100.0 - 31.628)) < 0.06


@pytest.mark.parametrize("text, match", [
    (_gga("120000.00", 30.5, 114.3, 1, 10.0, 1.0), ":1: GGA before any RMC"),
    ("$GPRMC,120000.00,A,,,,,,,010324,,,A*00", ":1: NMEA checksum"),
])
def test_nmea_errors_name_the_line(tmp_path, text, match):
    p = tmp_path / "x.nmea"
    p.write_text(text + "\n")
    with pytest.raises(InputError, match=match):
        read_gnss(p, format="nmea")
