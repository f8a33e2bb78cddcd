"""photogrammetry lunar-heading end to end: simulated centres and rendered images."""
import numpy as np
import pytest
from PIL import Image

from ins.nav.rotation import euler_to_dcm
from photogrammetry.cli.main import main
from photogrammetry.lunar.ephemeris import moon_sun_directions
from photogrammetry.lunar.fisheye import FisheyeCamera
from photogrammetry.lunar.render import render_moon_fisheye

CAM_TOML = ('[camera]\nmodel = "fisheye-equisolid"\nfocal_length_px = 800.0\nwidth_px = 1600\n'
            'height_px = 1600\nprincipal_point_px = [799.5, 799.5]\nradial_k = [0.0, 0.0, 0.0]\n')
CAM = FisheyeCamera(800.0, 1600, 1600, (799.5, 799.5))
LAT, LON, H = 40.0, 116.0, 50.0
HEADING = 123.4


def _session(tmp_path, n):
    utc = np.datetime64("2017-05-02T14:00:00") + np.arange(n) * np.timedelta64(int(9e5 / n), "ms")
    sky = moon_sun_directions(utc, np.deg2rad(LAT), np.deg2rad(LON), H, pressure_hpa=1000.0)
    C_hc = euler_to_dcm([0.03, 0.02, np.deg2rad(HEADING)])
    (tmp_path / "cam.toml").write_text(CAM_TOML)
    (tmp_path / "times.csv").write_text(
        "image_id,utc\n" + "".join(f"m{k:03d},{str(t)}Z\n" for k, t in enumerate(utc)))
    return sky, C_hc


def test_centres(tmp_path, capsys):
    sky, C_hc = _session(tmp_path, 72)
    uv = CAM.direction_to_image(sky.moon_h @ C_hc)
    uv += 0.1 * np.random.default_rng(5).standard_normal(uv.shape)
    uv[10] += 5.0                                                # one outlier
    (tmp_path / "c.csv").write_text("image_id,u_px,v_px,sigma_px\n" + "".join(
        f"m{k:03d},{u:.4f},{v:.4f},0.1\n" for k, (u, v) in enumerate(uv)))
    code = main(["lunar-heading", "--centres", str(tmp_path / "c.csv"), "--times",
                 str(tmp_path / "times.csv"), "--station", f"{LAT},{LON},{H}", "--camera",
                 str(tmp_path / "cam.toml"), "--pressure", "1000", "--plot",
                 str(tmp_path / "conv.png"), "-q"])
    out = capsys.readouterr().out
    assert code == 0
    line = next(x for x in out.splitlines() if x.startswith("heading"))
    hdg, sig = float(line.split()[6]), float(line.split()[9])
    assert abs(hdg - HEADING) * 3600 < 4 * sig + 60
    assert "*" in next(x for x in out.splitlines() if x.startswith("m010"))
    assert (tmp_path / "conv.png").stat().st_size > 1000


def test_images(tmp_path, capsys):
    sky, C_hc = _session(tmp_path, 8)
    (tmp_path / "img").mkdir()
    for k in range(8):
        img = render_moon_fisheye(CAM, sky.moon_h[k] @ C_hc, sky.sun_h[k] @ C_hc,
                                  sky.semidiameter[k], noise_sigma=3, rng=k)
        Image.fromarray(img).save(tmp_path / "img" / f"m{k:03d}.png")
    args = ["lunar-heading", "--images", str(tmp_path / "img"), "--times",
            str(tmp_path / "times.csv"), "--station", f"{LAT},{LON},{H}", "--camera",
            str(tmp_path / "cam.toml"), "--pressure", "1000", "-q"]
    assert main(args) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if x.startswith("heading"))
    assert abs(float(line.split()[6]) - HEADING) < 1.0       # 8 images over 15 min: weak
    Image.fromarray(np.full((1600, 1600), 100, np.uint16)).save(tmp_path / "img" / "m003.png")
    assert main(args) == 2
    assert "m003.png" in capsys.readouterr().err


@pytest.mark.parametrize("edit,message", [
    ("station", "latitude"), ("order", "out of order"), ("few", "at least 2"),
    (["--temperature", "-300"], "below absolute zero"),
    (["--temperature", "nan"], "--temperature: expected a finite number"),
    (["--pressure", "5000"], "--pressure: expected hPa"),
    (["--dut1", "4"], "--dut1"), (["--station", "30,120,1e9"], "height")])
def test_errors(tmp_path, capsys, edit, message):
    """Bad input: exit 2 and one line naming the option (the sky options: ranges with
    their unit; a temperature below 0 K used to print a heading)."""
    sky, C_hc = _session(tmp_path, 4)
    uv = CAM.direction_to_image(sky.moon_h @ C_hc)
    rows = [f"m{k:03d},{u},{v}\n" for k, (u, v) in enumerate(uv)]
    station = f"{LAT},{LON},{H}"
    if edit == "station":
        station = f"95,{LON},{H}"
    if edit == "order":
        lines = (tmp_path / "times.csv").read_text().splitlines()
        lines[2], lines[3] = lines[3], lines[2]
        (tmp_path / "times.csv").write_text("\n".join(lines) + "\n")
    if edit == "few":
        rows = rows[:1]
    (tmp_path / "c.csv").write_text("image_id,u_px,v_px\n" + "".join(rows))
    try:                              # an option error exits from argparse (code 2)
        code = main(["lunar-heading", "--centres", str(tmp_path / "c.csv"), "--times",
                     str(tmp_path / "times.csv"), "--station", station, "--camera",
                     str(tmp_path / "cam.toml"), "-q"]
                    + (edit if isinstance(edit, list) else []))
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err


def test_thin_crescent_refused(tmp_path, capsys):
    """The rule: lit width R (1 + cos phase) < 2 px refuses the session, naming the phase,
    the radius and the width; 2 days from new Moon through an 800 px lens is refused."""
    from types import SimpleNamespace

    from ins.common.errors import InputError
    from photogrammetry.lunar import MIN_LIT_WIDTH_PX, check_crescent
    assert MIN_LIT_WIDTH_PX == 2.0
    sky = SimpleNamespace(semidiameter=np.deg2rad([0.26, 0.26]),
                          phase_angle=np.deg2rad([120.0, 140.0]))
    check_crescent(sky, FisheyeCamera(3000.0, 100, 100, (49.5, 49.5)))   # 13.6 * 0.234 px
    with pytest.raises(InputError, match=r"too thin a crescent.*phase angle 140.0 deg.*"
                                         r"radius 3.63 px.*0.85 px < 2 px \(image 2\)"):
        check_crescent(sky, CAM)
    # end to end: 2017-04-28 (new Moon 04-26), evening at 40 N 116 E
    utc = np.datetime64("2017-04-28T11:30:00") + np.arange(3) * np.timedelta64(60, "s")
    (tmp_path / "cam.toml").write_text(CAM_TOML)
    (tmp_path / "times.csv").write_text(
        "image_id,utc\n" + "".join(f"m{k:03d},{t}Z\n" for k, t in enumerate(utc)))
    (tmp_path / "img").mkdir()
    for k in range(3):
        Image.fromarray(np.full((16, 16), 100, np.uint16)).save(tmp_path / "img" / f"m{k:03d}.png")
    code = main(["lunar-heading", "--images", str(tmp_path / "img"), "--times",
                 str(tmp_path / "times.csv"), "--station", f"{LAT},{LON},{H}", "--camera",
                 str(tmp_path / "cam.toml"), "-q"])
    assert code == 2
    assert "too thin a crescent" in capsys.readouterr().err


def test_not_the_moon_named(tmp_path, capsys):
    """A bright object of the wrong size (a lamp of 15 px radius where the Moon has
    3.7 px) is refused, naming the image and both radii."""
    from photogrammetry.lunar.render import render_moon
    sky, C_hc = _session(tmp_path, 3)
    (tmp_path / "img").mkdir()
    for k in range(3):
        img = render_moon_fisheye(CAM, sky.moon_h[k] @ C_hc, sky.sun_h[k] @ C_hc,
                                  sky.semidiameter[k], noise_sigma=3, rng=k)
        if k == 1:
            img = render_moon((1600, 1600), (400.0, 300.0), 15.0, 0, 0, noise_sigma=3, rng=k)
        Image.fromarray(img).save(tmp_path / "img" / f"m{k:03d}.png")
    code = main(["lunar-heading", "--images", str(tmp_path / "img"), "--times",
                 str(tmp_path / "times.csv"), "--station", f"{LAT},{LON},{H}", "--camera",
                 str(tmp_path / "cam.toml"), "--pressure", "1000", "-q"])
    err = capsys.readouterr().err
    assert code == 2
    assert "m001.png" in err and "is 15." in err and "the Moon's is 3.7 px" in err
