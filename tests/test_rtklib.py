"""RTKLIB .pos reader: files written by hand in RTKLIB's documented layouts (outsolheads /
outpos / outecef / outenu of RTKLIB 2.4), every time and position variant, the signed
square-root covariance columns, the quality policy and line-numbered errors."""
import warnings

import numpy as np
import pytest

from ins.common.errors import InputError, InputWarning
from ins.io.gnss import read_gnss, sniff_format
from ins.io.gnss_quality import apply_quality
from ins.io.rtklib import LEAP_SECONDS, looks_like_pos, read_pos
from ins.nav import earth

HEAD_LLH = """\
% program   : RTKPOST ver.2.4.3 b34
% inp file  : rover.obs
% obs start : 2020/01/01 00:00:00.0 GPST (week2086 259200.0s)
% pos mode  : Kinematic
% ref pos   :  35.000000000  139.000000000    40.0000
%
% (lat/lon/height=WGS84/ellipsoidal,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,ns=# of satellites)
%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio
"""
ROWS_LLH = [
    "2086 259200.000   35.000100000  139.000200000    50.1234   1   8   0.0030   0.0020   0.0080  -0.0010   0.0020  -0.0030   0.00    5.2",
    "2086 259200.200   35.000100100  139.000200100    50.1240   2   7   0.0300   0.0200   0.0800   0.0100   0.0000  -0.0300   0.20    1.2",
    "2086 259200.400   35.000100200  139.000200200    50.1250   5   6   1.5000   1.2000   3.0000   0.3000  -0.2000   0.1000   0.00    0.0",
]


def write(tmp_path, text, name="rover.pos"):
    p = tmp_path / name
    p.write_text(text)
    return p


def signed_var(s):
    return s * abs(s)


def test_llh_week_tow(tmp_path):
    log = read_pos(write(tmp_path, HEAD_LLH + "\n".join(ROWS_LLH) + "\n"))
    assert len(log) == 3
    np.testing.assert_array_equal(log.time, [259200.0, 259200.2, 259200.4])
    np.testing.assert_allclose(np.rad2deg(log.lla[0, :2]), [35.0001, 139.0002], rtol=0,
                               atol=1e-12)
    assert log.lla[0, 2] == 50.1234
    assert list(log.quality) == [1, 2, 5]
    assert list(log.line) == [9, 10, 11]
    # covariance by hand: sdn sde sdu sdne sdeu sdun, ENU -> NED (D = -U)
    sn, se, su, sne, seu, sun = 0.003, 0.002, 0.008, -0.001, 0.002, -0.003
    want = np.array([[sn ** 2, signed_var(sne), -signed_var(sun)],
                     [signed_var(sne), se ** 2, -signed_var(seu)],
                     [-signed_var(sun), -signed_var(seu), su ** 2]])
    np.testing.assert_allclose(log.cov_ned_m2[0], want, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(log.sigma_ned_m[0], [sn, se, su], rtol=1e-12)
    # sdeu printed 0.0000 on row 2: zero correlation, the matrix stays as written
    assert log.cov_ned_m2[1, 1, 2] == 0.0
    assert log.v_n is None


def test_dispatch_by_header_and_extension(tmp_path):
    p = write(tmp_path, HEAD_LLH + "\n".join(ROWS_LLH) + "\n", name="solution.txt")
    assert looks_like_pos(p) and sniff_format(p) == "rtklib"
    log = read_gnss(p, time_shift_s=-0.25)
    np.testing.assert_allclose(log.time, [259199.75, 259199.95, 259200.15])
    kf = write(tmp_path, "300001.0 30.0 114.0 10.0 0.02 0.02 0.05\n300002.0 30.0 114.0 10.0 "
                         "0.02 0.02 0.05\n", name="g.txt")
    assert sniff_format(kf) == "kfgins"
    assert sniff_format(tmp_path / "x.pos") == "rtklib"


def test_date_format_utc_leap_seconds(tmp_path):
    head = HEAD_LLH.replace("%  GPST                 ", "%  UTC                  ")
    rows = [r.replace("2086 259200.000", "2020/01/01 00:00:00.000")
            .replace("2086 259200.200", "2020/01/01 00:00:00.200")
            .replace("2086 259200.400", "2020/01/01 00:00:00.400") for r in ROWS_LLH]
    log = read_pos(write(tmp_path, head + "\n".join(rows) + "\n"))
    # 2020-01-01 is the Wednesday of GPS week 2086 (Sunday 2019-12-29): 3 days = 259200 s,
    # plus GPS - UTC = 18 s
    np.testing.assert_allclose(log.time, [259218.0, 259218.2, 259218.4], rtol=0, atol=1e-9)
    gpst = read_pos(write(tmp_path, HEAD_LLH + "\n".join(rows) + "\n", name="g.pos"))
    np.testing.assert_allclose(gpst.time, [259200.0, 259200.2, 259200.4], rtol=0, atol=1e-9)


def test_leap_seconds_against_astropy(tmp_path):
    """UTC epochs the day before and the day of every leap second: GPS time as astropy
    computes it (its own IERS leap-second table)."""
    atime = pytest.importorskip("astropy.time")
    head = HEAD_LLH.replace("%  GPST                 ", "%  UTC                  ")
    dates = []
    for y, m, d, _ in LEAP_SECONDS:
        day = np.datetime64(f"{y:04d}-{m:02d}-{d:02d}")
        dates += [str(day - 1), str(day)]
    rows = [ROWS_LLH[0].replace("2086 259200.000", f"{dt.replace('-', '/')} 12:00:00.000")
            for dt in dates]
    log = read_pos(write(tmp_path, head + "\n".join(rows) + "\n"))
    gps = atime.Time([f"{dt}T12:00:00" for dt in dates], scale="utc").gps   # s since 1980-01-06
    week0 = np.floor(gps[0] / 604800.0)
    np.testing.assert_allclose(log.time, gps - week0 * 604800.0, rtol=0, atol=1e-6)


def test_jst_and_week_end(tmp_path):
    head = HEAD_LLH.replace("%  GPST                 ", "%  JST                  ")
    rows = [ROWS_LLH[0].replace("2086 259200.000", "2020/01/05 08:59:59.000"),
            ROWS_LLH[1].replace("2086 259200.200", "2020/01/05 09:00:01.000")]
    log = read_pos(write(tmp_path, head + "\n".join(rows) + "\n"))
    # JST 2020-01-05 09:00:00 = UTC 2020-01-05 00:00:00 (Sunday) = GPS 00:00:18 of week 2087;
    # the first epoch (17 s into week 2087) and the second stay continuous
    np.testing.assert_allclose(log.time, [17.0, 19.0])
    wk = read_pos(write(tmp_path, HEAD_LLH + "\n".join([
        ROWS_LLH[0].replace("2086 259200.000", "2086 604799.800"),
        ROWS_LLH[1].replace("2086 259200.200", "2087      0.200")]) + "\n", name="w.pos"))
    np.testing.assert_allclose(wk.time, [604799.8, 604800.2])


def test_dms_negative_zero_degrees(tmp_path):
    head = HEAD_LLH.replace("latitude(deg) longitude(deg)",
                            "latitude(d'\") longitude(d'\")").replace("sdun(m)", "sdue(m)")
    rows = ["2086 259200.000   -0 30 00.00000   -1 15 36.00000    50.1234   1   8   0.0030   "
            "0.0020   0.0080  -0.0010   0.0020  -0.0030   0.00    5.2",
            "2086 259201.000   35 07 24.44444  139 00 00.36000    50.1234   1   8   0.0030   "
            "0.0020   0.0080  -0.0010   0.0020  -0.0030   0.00    5.2"]
    log = read_pos(write(tmp_path, head + "\n".join(rows) + "\n"))
    np.testing.assert_allclose(np.rad2deg(log.lla[:, :2]),
                               [[-0.5, -(1 + 15 / 60 + 36 / 3600)],
                                [35 + 7 / 60 + 24.44444 / 3600, 139 + 0.36 / 3600]],
                               rtol=0, atol=1e-12)
    # the sixth sigma column (named sdue by RTKLIB's d'" header) is sdun: u-n
    assert log.cov_ned_m2[0, 0, 2] == pytest.approx(-signed_var(-0.003))


def lla_deg(lat, lon, h):
    return np.array([np.deg2rad(lat), np.deg2rad(lon), h])


def test_xyz_ecef_matches_llh(tmp_path):
    """The same solution as x/y/z-ecef: position and NED covariance agree with the llh
    reading; the ECEF covariance is written from the ENU one with the textbook matrix."""
    llh = read_pos(write(tmp_path, HEAD_LLH + ROWS_LLH[0] + "\n", name="a.pos"))
    lat, lon = llh.lla[0, 0], llh.lla[0, 1]
    a, f = 6378137.0, 1 / 298.257223563
    e2 = f * (2 - f)
    N = a / np.sqrt(1 - e2 * np.sin(lat) ** 2)
    h = llh.lla[0, 2]
    xyz = [(N + h) * np.cos(lat) * np.cos(lon), (N + h) * np.cos(lat) * np.sin(lon),
           (N * (1 - e2) + h) * np.sin(lat)]
    # rows of R: east, north, up unit vectors in ECEF
    R = np.array([[-np.sin(lon), np.cos(lon), 0],
                  [-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)],
                  [np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)]])
    C_ned_enu = np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1]])
    cov_enu = C_ned_enu.T @ llh.cov_ned_m2[0] @ C_ned_enu
    cov_e = R.T @ cov_enu @ R
    sq = lambda c: np.sign(c) * np.sqrt(abs(c))  # noqa: E731
    head = ("% (x/y/z-ecef=WGS84,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,ns=# of satellites)\n"
            "%  GPST                      x-ecef(m)      y-ecef(m)      z-ecef(m)   Q  ns   sdx(m)   "
            "sdy(m)   sdz(m)  sdxy(m)  sdyz(m)  sdzx(m) age(s)  ratio\n")
    row = (f"2086 259200.000 {xyz[0]:.6f} {xyz[1]:.6f} {xyz[2]:.6f}   1   8 "
           f"{sq(cov_e[0, 0]):.9f} {sq(cov_e[1, 1]):.9f} {sq(cov_e[2, 2]):.9f} "
           f"{sq(cov_e[0, 1]):.9f} {sq(cov_e[1, 2]):.9f} {sq(cov_e[2, 0]):.9f}   0.00    5.2\n")
    log = read_pos(write(tmp_path, head + row, name="x.pos"))
    np.testing.assert_allclose(log.lla[0, :2], llh.lla[0, :2], rtol=0, atol=1e-12)
    assert log.lla[0, 2] == pytest.approx(h, abs=1e-5)
    np.testing.assert_allclose(log.cov_ned_m2[0], llh.cov_ned_m2[0], rtol=0, atol=1e-10)


def test_enu_baseline(tmp_path):
    head = ("% ref pos   :  35.000000000  139.000000000    40.0000\n"
            "% (e/n/u-baseline=WGS84,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,ns=# of satellites)\n"
            "%  GPST                  e-baseline(m)  n-baseline(m)  u-baseline(m)   Q  ns   sde(m)   "
            "sdn(m)   sdu(m)  sden(m)  sdnu(m)  sdue(m) age(s)  ratio\n")
    row = "2086 259200.000     120.0000      -35.5000        2.2500   1   9   0.0050   0.0040   0.0100   0.0020   0.0000   0.0000   1.00   12.3\n"
    log = read_pos(write(tmp_path, head + row))
    base = lla_deg(35.0, 139.0, 40.0)
    ned = earth.ned_offset(base, log.lla[0])
    np.testing.assert_allclose(ned, [-35.5, 120.0, -2.25], atol=1e-6)
    np.testing.assert_allclose(log.sigma_ned_m[0], [0.004, 0.005, 0.01], rtol=1e-12)
    assert log.cov_ned_m2[0, 0, 1] == pytest.approx(0.002 ** 2)
    with pytest.raises(InputError, match="ref pos"):
        read_pos(write(tmp_path, head.split("\n", 1)[1] + row, name="nobase.pos"))
    got = read_pos(write(tmp_path, head.split("\n", 1)[1] + row, name="b.pos"),
                   ref_lla_deg=(35.0, 139.0, 40.0))
    np.testing.assert_allclose(got.lla, log.lla, rtol=0, atol=1e-12)


def test_velocity_columns(tmp_path):
    head = HEAD_LLH.rstrip("\n") + ("    vn(m/s)    ve(m/s)    vu(m/s)      sdvn     sdve     "
                                    "sdvu    sdvne    sdveu    sdvun\n")
    row = ROWS_LLH[0] + "   10.00000   -5.00000    0.50000   0.01000  0.02000  0.03000  0.00000  0.00000  0.00000\n"
    log = read_pos(write(tmp_path, head + row))
    np.testing.assert_allclose(log.v_n[0], [10.0, -5.0, -0.5])
    np.testing.assert_allclose(log.sigma_vel_ned_mps[0], [0.01, 0.02, 0.03])


def test_geodetic_height_converted(tmp_path):
    """Geodetic heights (height=WGS84/geodetic) back to ellipsoidal, h = H + N, checked at
    NGA's published test points: EGM96 (OUTINTPT.DAT) 38.6281550 N 269.7791550 E,
    N = -31.628 m; EGM2008 (its 2.5' program's OUTPUT.DAT) 37 N 241 E, N = -26.151 m."""
    from ins.io.geoid import load_geoid
    head = HEAD_LLH.replace("WGS84/ellipsoidal", "WGS84/geodetic")
    row96 = ROWS_LLH[0].replace("35.000100000  139.000200000    50.1234",
                                "38.628155000  -90.220845000   100.0000")
    row08 = ROWS_LLH[0].replace("35.000100000  139.000200000    50.1234",
                                "37.000000000 -119.000000000   100.0000")
    try:
        load_geoid("EGM96")
    except InputError:
        with pytest.warns(InputWarning, match="no geoid grid"):
            log = read_pos(write(tmp_path, head + row96 + "\n"))
        assert log.lla[0, 2] == 100.0
    else:
        with pytest.warns(InputWarning, match="converted to ellipsoidal with EGM96"):
            log = read_pos(write(tmp_path, head + row96 + "\n"))
        assert abs(log.lla[0, 2] - (100.0 - 31.628)) < 0.06
    try:
        load_geoid("EGM2008")
    except InputError:
        pass
    else:
        import warnings
        with warnings.catch_warnings():
            warnings.simplefilter("error")               # a named model: no warning
            log = read_gnss(write(tmp_path, head + row08 + "\n", name="b.pos"),
                            geoid="EGM2008")
        assert abs(log.lla[0, 2] - (100.0 - 26.151)) < 0.003
        # an ellipsoidal header is left alone whatever the model
        log = read_pos(write(tmp_path, HEAD_LLH + row08 + "\n", name="c.pos"), geoid="EGM2008")
        assert log.lla[0, 2] == 100.0
    with pytest.raises(InputError, match="Tokyo"):
        read_pos(write(tmp_path, HEAD_LLH.replace("WGS84/ellipsoidal", "Tokyo/ellipsoidal")
                       + ROWS_LLH[0] + "\n", name="t.pos"))


def test_quality_policy(tmp_path):
    p = write(tmp_path, HEAD_LLH + "\n".join(ROWS_LLH) + "\n")
    log = read_gnss(p, quality="fix,float")
    assert list(log.quality) == [1, 2] and list(log.line) == [9, 10]
    scaled = read_gnss(p, quality_scale={"float": 3.0, "single": 10})
    full = read_pos(p)
    np.testing.assert_allclose(scaled.sigma_ned_m, full.sigma_ned_m * [[1], [3], [10]])
    np.testing.assert_allclose(scaled.cov_ned_m2[2], full.cov_ned_m2[2] * 100)
    with pytest.raises(InputError, match="no epoch left with quality ppp"):
        apply_quality(full, ["ppp"])
    with pytest.raises(InputError, match="unknown quality 'fixed'"):
        apply_quality(full, "fixed")
    kf = write(tmp_path, "300001.0 30.0 114.0 10.0 0.02 0.02 0.05\n", name="g.txt")
    with pytest.raises(InputError, match="only RTKLIB"):
        read_gnss(kf, quality="fix")


@pytest.mark.parametrize("bad, pattern", [
    (ROWS_LLH[1].replace("   2   7", "   9   7"), r"rover.pos:10: Q = 9:"),
    (ROWS_LLH[1].replace("259200.200", "259200.000"), r"rover.pos:10: duplicated epoch"),
    (ROWS_LLH[1].replace("35.000100100", "95.000100100"), r"rover.pos:10: latitude 95"),
    (ROWS_LLH[1].replace("50.1240", "50.12x0"), r"rover.pos:10: .*height"),
    (ROWS_LLH[1].rsplit(" ", 1)[0], r"rover.pos:10: .*fields|rover.pos:10: .*columns"),
    (ROWS_LLH[1].replace("0.0300", "-0.0300", 1), r"rover.pos:10: negative standard"),
    (ROWS_LLH[1].replace("2086 259200.200", "2086 -5.0"), r"rover.pos:10: GPS week"),
    # a corrupted week would overflow the integer seconds (a cast warning, garbage times)
    (ROWS_LLH[1].replace("2086 259200.200", "2e30 259200.200"), r"rover.pos:10: GPS week 2e\+30"),
])
def test_bad_lines_named(tmp_path, bad, pattern):
    text = HEAD_LLH + "\n".join([ROWS_LLH[0], bad, ROWS_LLH[2]]) + "\n"
    with pytest.raises(InputError, match=pattern):
        read_pos(write(tmp_path, text))


def test_bad_date_named(tmp_path):
    rows = [ROWS_LLH[0].replace("2086 259200.000", "2020/01/01 00:00:00.000"),
            ROWS_LLH[1].replace("2086 259200.200", "2020/13/01 00:00:00.200")]
    with pytest.raises(InputError, match=r"rover.pos:10: month 13"):
        read_pos(write(tmp_path, HEAD_LLH + "\n".join(rows) + "\n"))
    rows[1] = ROWS_LLH[1].replace("2086 259200.200", "9e20/01/01 00:00:00.200")
    with pytest.raises(InputError, match=r"rover.pos:10: year 9e\+20"):
        read_pos(write(tmp_path, HEAD_LLH + "\n".join(rows) + "\n"))


def test_no_header_refused(tmp_path):
    with pytest.raises(InputError, match="no '%  GPST"):
        read_pos(write(tmp_path, "% just a comment\n" + ROWS_LLH[0] + "\n"))


def test_comma_separated(tmp_path):
    head = HEAD_LLH.splitlines()[-1].replace("  ", " ").replace(" ", ",")
    head = "%  GPST," + ",".join(HEAD_LLH.splitlines()[-1].split()[2:]) + "\n"
    row = ",".join(ROWS_LLH[0].split()) + "\n"
    log = read_pos(write(tmp_path, head + row))
    assert log.sigma_ned_m[0, 2] == pytest.approx(0.008)


def test_floor_and_psd(tmp_path):
    """sdn printed 0.0000 beside sdne 0.0001: indefinite as printed, a covariance within
    the rounding (sdn up to 0.00005): floored, not reported."""
    row = ROWS_LLH[0].replace("0.0030   0.0020   0.0080  -0.0010   0.0020  -0.0030",
                              "0.0000   0.0020   0.0080   0.0001   0.0000  -0.0000")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        log = read_pos(write(tmp_path, HEAD_LLH + row + "\n"))
    assert log.sigma_ned_m[0, 0] >= 1e-4
    assert np.all(np.linalg.eigvalsh(log.cov_ned_m2[0]) > 0)
    # sdne 0.0020 beside sdn 0: no rounding prints that (ins.io.pos_screen); alone in
    # its file, without a valid peer, the record is dropped and nothing is left
    row = ROWS_LLH[0].replace("0.0030   0.0020   0.0080  -0.0010   0.0020  -0.0030",
                              "0.0000   0.0020   0.0080   0.0020   0.0020  -0.0030")
    with pytest.raises(InputError, match="no record left"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        read_pos(write(tmp_path, HEAD_LLH + row + "\n"))


def test_write_pos_round_trip(tmp_path):
    from ins.io.rtklib import write_pos
    src = read_pos(write(tmp_path, HEAD_LLH + "\n".join(ROWS_LLH) + "\n"))
    p = tmp_path / "back.pos"
    assert write_pos(p, src, week=2086, comments=["made by a test"]) == 3
    text = p.read_text()
    assert text.startswith("% made by a test\n%") and "\n2086 259200.200000" in text
    back = read_pos(p)
    np.testing.assert_allclose(back.time, src.time, rtol=0, atol=1e-9)
    np.testing.assert_allclose(back.lla[:, :2], src.lla[:, :2], rtol=0, atol=1e-13)
    np.testing.assert_allclose(back.cov_ned_m2, src.cov_ned_m2, rtol=1e-6, atol=1e-15)
    assert list(back.quality) == [1, 2, 5]


def test_crlf_and_empty(tmp_path):
    """RTKLIB writes \\r\\n line ends (outsols); a header without solutions is named."""
    text = (HEAD_LLH + "\n".join(ROWS_LLH) + "\n").replace("\n", "\r\n")
    log = read_pos(write(tmp_path, text))
    assert len(log) == 3 and list(log.line) == [9, 10, 11]
    assert log.lla[2, 2] == 50.125
    with pytest.raises(InputError, match="no solution lines"):
        read_pos(write(tmp_path, HEAD_LLH, name="empty.pos"))
