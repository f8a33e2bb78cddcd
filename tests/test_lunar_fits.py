"""FITS Moon images: times from hand-written headers (DATE-AVG, DATE-OBS with TIME-OBS,
EXPTIME, the old dd/mm/yy form, a local time zone), the clipping level (SATURATE,
DATAMAX), the error without astropy naming the extra, and lunar-heading on a session of
FITS frames whose headers hold China standard time (+08:00) and no --times."""
import sys

import numpy as np
import pytest

from ins.common.errors import InputError
from photogrammetry.lunar.io import (
    fits_saturation,
    fits_time,
    load_image,
    load_image_meta,
    parse_time_zone,
)

fits = pytest.importorskip("astropy.io.fits")


def _header(**cards):
    h = fits.Header()
    for k, v in cards.items():
        h[k.replace("_", "-")] = v
    return h


@pytest.mark.parametrize("cards,expect", [
    (dict(DATE_OBS="2017-05-12T15:00:00.250"), "2017-05-12T15:00:00.250"),
    (dict(DATE_OBS="2017-05-12T15:00:00", EXPTIME=0.5), "2017-05-12T15:00:00.250"),
    (dict(DATE_OBS="2017-05-12T15:00:00", EXPOSURE=2.0), "2017-05-12T15:00:01"),
    (dict(DATE_OBS="2017-05-12", TIME_OBS="15:00:00.5"), "2017-05-12T15:00:00.5"),
    (dict(DATE_OBS="12/05/97", UT="01:02:03"), "1997-05-12T01:02:03"),
    (dict(DATE_OBS="2017-05-12T15:00:00", EXPTIME=4.0, DATE_AVG="2017-05-12T15:00:01.5"),
     "2017-05-12T15:00:01.5"),
    (dict(DATE_OBS="2017-05-12T15:00:00Z", TIMESYS="UTC"), "2017-05-12T15:00:00"),
])
def test_fits_time_rules(cards, expect):
    assert fits_time(_header(**cards), "x.fits") == np.datetime64(expect, "ns")


def test_fits_time_errors():
    assert fits_time(_header(OBJECT="Moon"), "x.fits") is None
    with pytest.raises(InputError, match="TIMESYS"):
        fits_time(_header(DATE_OBS="2017-05-12T15:00:00", TIMESYS="TT"), "x.fits")
    with pytest.raises(InputError, match="x.fits: DATE-OBS: expected an ISO 8601"):
        fits_time(_header(DATE_OBS="yesterday"), "x.fits")


def test_time_zone_option():
    assert parse_time_zone("+08:00") == np.timedelta64(8 * 3600, "s")
    assert parse_time_zone("-0530") == -np.timedelta64(5 * 3600 + 1800, "s")
    assert parse_time_zone("UTC") == np.timedelta64(0, "s")
    for bad in ("8", "+8:00", "CST", "+15:00", "+08:60"):
        with pytest.raises(InputError, match="--time-zone"):
            parse_time_zone(bad)


def test_saturation_keys_and_data(tmp_path):
    assert fits_saturation(_header(SATURATE=60000, DATAMAX=65535)) == 60000
    assert fits_saturation(_header(DATAMAX=4095)) == 4095
    assert fits_saturation(_header(OBJECT="Moon")) is None
    data = (np.arange(12, dtype=">i2").reshape(3, 4) * 100)       # FITS is big-endian
    fits.PrimaryHDU(data, _header(SATURATE=1000, DATE_OBS="2017-05-12T15:00:00")).writeto(
        tmp_path / "a.fits")
    img, meta = load_image_meta(tmp_path / "a.fits")
    assert img.dtype == np.int16 and img.dtype.byteorder in ("=", "|")
    np.testing.assert_array_equal(img, np.arange(12).reshape(3, 4) * 100)
    assert meta == {"saturation": 1000.0, "time": np.datetime64("2017-05-12T15:00:00", "ns")}
    np.testing.assert_array_equal(load_image(str(tmp_path / "a.fits")), img.astype(float))


def test_missing_astropy_names_the_extra(tmp_path, monkeypatch):
    fits.PrimaryHDU(np.zeros((4, 4))).writeto(tmp_path / "a.fits")
    monkeypatch.setitem(sys.modules, "astropy", None)
    monkeypatch.setitem(sys.modules, "astropy.io", None)
    with pytest.raises(InputError, match=r"a.fits.*pip install 'insphoto\[fits\]'"):
        load_image(str(tmp_path / "a.fits"))


def test_heading_from_fits_headers_in_local_time(tmp_path, capsys):
    """Frames with DATE-OBS in China standard time (start of a 0.2 s exposure), clipped at
    SATURATE; lunar-heading without --times, with --time-zone +08:00."""
    from ins.nav.rotation import euler_to_dcm
    from photogrammetry.cli.main import main
    from photogrammetry.lunar.ephemeris import moon_sun_directions
    from photogrammetry.lunar.fisheye import FisheyeCamera, camera_file_text
    from photogrammetry.lunar.render import render_moon_fisheye

    lat, lon, h, heading = 40.0, 116.0, 50.0, 123.4
    n = 16
    mid = np.datetime64("2017-05-02T14:00:00.100") + np.arange(n) * np.timedelta64(60, "s")
    sky = moon_sun_directions(mid, np.deg2rad(lat), np.deg2rad(lon), h, pressure_hpa=1000.0)
    C_hc = euler_to_dcm([0.03, 0.02, np.deg2rad(heading)])
    full = FisheyeCamera(800.0, 1600, 1600, (799.5, 799.5), model="fisheye-equidistant")
    track = full.direction_to_image(sky.moon_h @ C_hc)
    lo = np.floor(track.min(0)) - 20              # a window of the frame around the track
    cam = FisheyeCamera(800.0, int(np.ptp(track[:, 0])) + 41, int(np.ptp(track[:, 1])) + 41,
                        tuple(np.array(full.principal_point_px) - lo),
                        model="fisheye-equidistant")
    (tmp_path / "cam.toml").write_text(camera_file_text(cam))
    (tmp_path / "img").mkdir()
    for k in range(n):
        img = render_moon_fisheye(cam, sky.moon_h[k] @ C_hc, sky.sun_h[k] @ C_hc,
                                  sky.semidiameter[k], peak=3000, noise_sigma=5, rng=k,
                                  dtype=np.float64, shading="flat")
        img = np.minimum(img, 2000.0).astype(">f4")             # a clipped core
        local = mid[k] - np.timedelta64(100, "ms") + np.timedelta64(8, "h")
        hdr = _header(DATE_OBS=str(local)[:23], EXPTIME=0.2, SATURATE=2000.0)
        fits.PrimaryHDU(img, hdr).writeto(tmp_path / "img" / f"f{k:02d}.fits")
    args = ["lunar-heading", "--images", str(tmp_path / "img"), "--station",
            f"{lat},{lon},{h}", "--camera", str(tmp_path / "cam.toml"), "--pressure", "1000",
            "-q"]
    assert main(args + ["--time-zone", "+08:00"]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("heading"))
    hdg, sig = float(line.split()[6]), float(line.split()[9])
    assert "16 images, 2017-05-02T14:00:00.100" in out
    assert abs(hdg - heading) * 3600 < 4 * sig
    # the header times as read: local = UTC + 8 h; the ids in time order
    from photogrammetry.cli.lunar import header_times
    from photogrammetry.lunar.io import find_images
    folder = str(tmp_path / "img")
    ids, utc = header_times(find_images(folder), parse_time_zone("UTC"), folder)
    assert ids == [f"f{k:02d}" for k in range(n)]
    np.testing.assert_array_equal(utc, mid + np.timedelta64(8, "h"))
