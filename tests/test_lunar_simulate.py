"""``photogrammetry lunar-simulate``: a session written as files, then ``lunar-heading`` on
them in a second command finds the true heading; the camera attitude against its
definition; the Moon below the horizon, too low or outside the image refused by name."""
import os
from pathlib import Path

import numpy as np
import pytest
import tomllib
from PIL import Image

from photogrammetry.cli.lunar_simulate import DEFAULT_LENS
from photogrammetry.cli.main import main
from photogrammetry.lunar.fisheye import FisheyeCamera, read_camera
from photogrammetry.lunar.io import read_times, write_times
from photogrammetry.lunar.render import camera_attitude
from photogrammetry.lunar.solve import heading

ROOT = Path(__file__).resolve().parents[1]
STATION = "-33.9,-70.7,500"            # south and west: negative values as typed
HEADING = -75.5                        # deg; the truth is 284.5
SESSION = ["--station", STATION, "--start", "2017-05-02T23:00:00Z", "--duration", "900",
           "--count", "36", "--heading", str(HEADING), "--tilt", "50", "--size", "1000,1000",
           "--noise", "5", "--seed", "3", "-q"]


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    out = tmp_path_factory.mktemp("lunar") / "moon"
    assert main(["lunar-simulate", *SESSION, "-o", str(out)]) == 0
    return out


def test_two_commands(session, capsys):
    capsys.readouterr()
    code = main(["lunar-heading", "--images", str(session / "images"), "--times",
                 str(session / "times.csv"), "--station", STATION, "--camera",
                 str(session / "camera.toml"), "-q"])
    out = capsys.readouterr().out
    assert code == 0
    line = next(x for x in out.splitlines() if x.startswith("heading"))
    hdg, sig = float(line.split()[6]), float(line.split()[9])
    truth = tomllib.loads((session / "truth.toml").read_text())["camera_orientation"]
    assert truth["heading_deg"] == pytest.approx(HEADING % 360)
    err_arcsec = (np.angle(np.exp(1j * np.deg2rad(hdg - truth["heading_deg"])))
                  * 180 / np.pi * 3600)
    assert 0 < sig < 120
    assert abs(err_arcsec) < 3 * sig          # within its sigma (3 sigma: a test band)
    assert "36 images" in out and "dropped" not in out


def test_files(session):
    ids, utc = read_times(session / "times.csv")
    assert ids == [f"m{k:03d}" for k in range(36)]
    assert sorted(os.listdir(session / "images")) == [f"{i}.png" for i in ids]
    step = (utc - utc[0]).astype("timedelta64[ms]").astype(np.int64)
    np.testing.assert_array_equal(step, np.rint(np.linspace(0, 900e3, 36)).astype(np.int64))
    assert str(utc[0]) == "2017-05-02T23:00:00.000000000"
    cam = read_camera(session / "camera.toml")
    assert (cam.width_px, cam.height_px) == (1000, 1000)
    assert cam.principal_point_px == (499.5, 499.5)
    assert cam.focal_length_px == 800.0 and cam.radial_k == DEFAULT_LENS["radial_k"]
    truth = tomllib.loads((session / "truth.toml").read_text())
    C = np.array(truth["camera_orientation"]["C_hc"])
    np.testing.assert_allclose(C.T @ C, np.eye(3), atol=1e-12)
    assert np.degrees(np.arccos(C[2, 2])) == pytest.approx(50.0)       # tilt from zenith
    assert truth["station"] == {"lat_deg": -33.9, "lon_deg": -70.7, "h_m": 500.0}
    # the Moon is where centres_true.csv says: its brightest pixels around it
    rows = (session / "centres_true.csv").read_text().splitlines()[1:]
    for row in rows[::7]:
        name, u, v = row.split(",")
        img = np.asarray(Image.open(session / "images" / f"{name}.png"), float)
        assert img.dtype == float and img.shape == (1000, 1000)
        r, c = np.nonzero(img > 200)             # sky 100, noise 5
        assert len(r) > 10
        assert np.hypot(c.mean() - float(u), r.mean() - float(v)) < 4.0    # 8 px Moon
        assert np.hypot(c - float(u), r - float(v)).max() < 7.0


def test_default_lens_is_the_example_file():
    cam = read_camera(ROOT / "data" / "lunar" / "fisheye.toml")
    assert cam == FisheyeCamera(**DEFAULT_LENS)


@pytest.mark.parametrize("hdg,tilt,az", [(123.4, 20, 264.8), (0.0, 0, 0), (359.0, 85, 10),
                                          (200.0, 45, 200.0), (10.0, 30, 100.0)])
def test_camera_attitude(hdg, tilt, az):
    C = camera_attitude(*np.deg2rad([hdg, tilt, az]))
    np.testing.assert_allclose(C.T @ C, np.eye(3), atol=1e-12)
    assert np.linalg.det(C) == pytest.approx(1.0)
    axis = -C[:, 2]                                            # viewing direction, NED
    assert np.degrees(np.arccos(-axis[2])) == pytest.approx(tilt, abs=1e-9)
    if tilt:
        assert np.degrees(np.arctan2(axis[1], axis[0])) % 360 == pytest.approx(az % 360)
    assert np.degrees(heading(C)) == pytest.approx(hdg % 360, abs=1e-9)
    x = C[:, 0]                                                # azimuth of x in NED
    assert np.degrees(np.arctan2(x[1], x[0])) % 360 == pytest.approx(hdg % 360, abs=1e-9)


def test_write_times_round_trip(tmp_path):
    utc = np.array(["2017-05-02T23:00:00", "2017-05-02T23:00:00.5",
                    "2017-05-02T23:00:01.000000123"], "datetime64[ns]")
    write_times(tmp_path / "t.csv", ["a", "b", "c"], utc)
    ids, back = read_times(tmp_path / "t.csv")
    assert ids == ["a", "b", "c"]
    np.testing.assert_array_equal(back, utc)


@pytest.mark.parametrize("start,extra,words", [
    ("2017-05-03T04:30:00Z", [], ["below the horizon", "2017-05-03T04:30:00.000Z",
                                   "altitude -"]),
    ("2017-05-03T03:50:00", [], ["too low", "2017-05-03T03:50:00.000Z", "--min-altitude 10"]),
    ("2017-05-03T03:30:00Z", ["--min-altitude", "30"], ["too low", "03:30:00.000Z"]),
    ("2017-05-02T23:00:00Z", ["--tilt", "0", "--size", "600,600"],
     ["leaves the image", "23:00:00.000Z", "off the optical axis", "--tilt about 51"]),
    ("2017-05-02T23:00:00+02:00", [], ["--start", "no time-zone offset"]),
    ("2017-05-02T23:00:00Z", ["--count", "1"], ["at least 2"]),
])
def test_refused(tmp_path, capsys, start, extra, words):
    out = tmp_path / "moon"
    code = main(["lunar-simulate", "--station", STATION, "--start", start, "--duration", "600",
                 "--count", "5", "-o", str(out), "-q", *extra])
    err = capsys.readouterr().err
    assert code == 2
    for w in words:
        assert w in err
    assert os.listdir(tmp_path) == []                          # nothing written


def test_low_moon_altitude_in_message(tmp_path, capsys):
    from photogrammetry.lunar.ephemeris import moon_sun_directions, standard_pressure_hpa
    t = np.array(["2017-05-03T03:50:00"], "datetime64[ns]")
    sky = moon_sun_directions(t, np.deg2rad(-33.9), np.deg2rad(-70.7), 500,
                              pressure_hpa=standard_pressure_hpa(500.0))
    main(["lunar-simulate", "--station", STATION, "--start", "2017-05-03T03:50:00Z",
          "--count", "3", "-o", str(tmp_path / "m"), "-q"])
    err = capsys.readouterr().err
    assert f"altitude {np.degrees(sky.alt[0]):.2f} deg" in err
    assert 0 < np.degrees(sky.alt[0]) < 10


def test_existing_folder_needs_force(tmp_path, capsys):
    (tmp_path / "moon").mkdir()
    (tmp_path / "moon" / "old.txt").write_text("x")
    args = ["lunar-simulate", "--station", STATION, "--start", "2017-05-02T23:00:00Z",
            "--count", "2", "--size", "400,400", "--tilt", "50", "-q", "-o",
            str(tmp_path / "moon")]
    assert main(args) == 2
    assert (tmp_path / "moon" / "old.txt").exists()
    assert main(args + ["--force"]) == 0
    assert sorted(os.listdir(tmp_path / "moon")) == ["camera.toml", "centres_true.csv",
                                                     "images", "times.csv", "truth.toml"]


def test_help_states_units(capsys):
    with pytest.raises(SystemExit):
        main(["lunar-simulate", "--help"])
    text = capsys.readouterr().out
    for w in ("NED", "azimuth of the camera x axis", "from the zenith", "UTC", "deg", "px",
              "counts", "times.csv", "camera.toml", "truth.toml"):
        assert w in text


def test_lens_shading_saturation_two_commands(tmp_path, capsys):
    """An OpenCV-fisheye lens, flat shading and a clipped core (--saturation): the camera
    file says so and lunar-heading, finding the clipping from the plateau, gets the heading
    within its sigma."""
    out = tmp_path / "moon"
    k = "0.02,-0.01,0.004,-0.0007"
    assert main(["lunar-simulate", *[("24" if a == "36" else a) for a in SESSION],
                 "--lens", "opencv-fisheye", "--opencv-k", k, "--shading", "flat",
                 "--saturation", "2000", "-o", str(out)]) == 0
    cam = read_camera(out / "camera.toml")
    assert cam.model == "opencv-fisheye" and cam.opencv_k == (0.02, -0.01, 0.004, -0.0007)
    assert cam.radial_k == (0.0, 0.0, 0.0)
    truth = tomllib.loads((out / "truth.toml").read_text())
    assert truth["images"]["shading"] == "flat"
    assert truth["images"]["saturation_counts"] == 2000.0
    img = np.asarray(Image.open(out / "images" / "m000.png"))
    assert img.max() == 2000 and np.count_nonzero(img == 2000) >= 3
    capsys.readouterr()
    assert main(["lunar-heading", "--images", str(out / "images"), "--times",
                 str(out / "times.csv"), "--station", STATION, "--camera",
                 str(out / "camera.toml"), "-q"]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("heading"))
    hdg, sig = float(line.split()[6]), float(line.split()[9])
    err = np.angle(np.exp(1j * np.deg2rad(hdg - truth["camera_orientation"]["heading_deg"])))
    assert abs(np.rad2deg(err) * 3600) < 3 * sig


def test_non_square_pixels_two_commands(tmp_path, capsys):
    """A camera file with fy = 1.0075 fx (``focal_length_y_px``): the session is rendered
    with it and written with it; lunar-heading finds the heading within its sigma with
    that file, and is biased by far more than its sigma when the file says square."""
    cam_file = tmp_path / "cam.toml"
    cam_file.write_text('[camera]\nmodel = "opencv-fisheye"\nfocal_length_px = 800.0\n'
                        'focal_length_y_px = 806.0\nwidth_px = 1000\nheight_px = 1000\n'
                        'opencv_k = [0.01, -0.002, 0.0, 0.0]\n')
    out = tmp_path / "moon"
    assert main(["lunar-simulate", *[("24" if a == "36" else a) for a in SESSION
                                     if a not in ("--size", "1000,1000")],
                 "--camera", str(cam_file), "-o", str(out)]) == 0
    assert read_camera(out / "camera.toml").focal_length_y_px == 806.0
    truth = tomllib.loads((out / "truth.toml").read_text())["camera_orientation"]
    square = out / "square.toml"
    square.write_text("\n".join(x for x in (out / "camera.toml").read_text().splitlines()
                                if not x.startswith("focal_length_y_px")) + "\n")
    errs = []
    for cam in (out / "camera.toml", square):
        capsys.readouterr()
        assert main(["lunar-heading", "--images", str(out / "images"), "--times",
                     str(out / "times.csv"), "--station", STATION, "--camera", str(cam),
                     "-q"]) == 0
        line = next(x for x in capsys.readouterr().out.splitlines()
                    if x.startswith("heading"))
        hdg, sig = float(line.split()[6]), float(line.split()[9])
        err = np.angle(np.exp(1j * np.deg2rad(hdg - truth["heading_deg"])))
        errs.append((abs(np.rad2deg(err) * 3600), sig))
    assert errs[0][0] < 3 * errs[0][1]
    assert errs[1][0] > 5 * errs[1][1]


@pytest.mark.parametrize("extra,words", [
    (["--lens", "fisheye-equidistant", "--opencv-k", "0,0,0,0"], ["--opencv-k", "opencv"]),
    (["--lens", "pinhole"], ["--lens", "fisheye-equisolid"]),
    (["--lens", "opencv-fisheye", "--radial-k", "0.1,0,0"], ["--radial-k"]),
    (["--shading", "phong"], ["--shading", "lommel-seeliger"]),
    (["--saturation", "0"], ["--saturation"]),
])
def test_lens_and_shading_refused(tmp_path, capsys, extra, words):
    code = main(["lunar-simulate", "--station", STATION, "--start", "2017-05-02T23:00:00Z",
                 "--count", "3", "--tilt", "50", "-o", str(tmp_path / "m"), "-q", *extra])
    err = capsys.readouterr().err
    assert code == 2
    for w in words:
        assert w in err
