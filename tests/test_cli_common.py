"""Command-line behaviour every command shares (issue 12): negative numbers in options as
a user types them, one line naming the user's path for every OSError (never a hidden
temporary), a closed stdout (``| head``) handled quietly, the exit codes."""
import argparse
import errno
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pymap3d
import pytest

from ins.cli import main as ins_cli
from ins.cli.main import user_path
from ins.cli.util import NEGATIVE_VALUE, triplet
from ins.common.errors import QualityError
from ins.nav import earth
from photogrammetry.cli import main as pg_cli

ROOT = Path(__file__).resolve().parents[1]
SHORT = ROOT / "tests" / "data" / "flights" / "short.toml"


def _run(main, argv, capsys):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


# ---------------------------------------------------------------------------------------
# negative numbers

@pytest.mark.parametrize("text", ["-5", "-.5", "-5.", "-1.5e-3", "-2E+4", "-33.9,151.2,50",
                                  "-60,0,0", "-1,-2,-3", "-0.1,2e-3,+4", "-7,8"])
def test_negative_value_pattern_accepts(text):
    assert NEGATIVE_VALUE.match(text)


@pytest.mark.parametrize("text", ["-o", "--output", "-x,1,2", "-1,a", "-1,,2", "-", "-e5",
                                  "-1 ,2", "-1e", "-q5"])
def test_negative_value_pattern_refuses(text):
    assert not NEGATIVE_VALUE.match(text)


# a minimal argv per sub-command that has numeric options (the option under test replaces
# or extends it); a new sub-command with numeric options must be added here
BASE = {
    ("ins", "mechanize"): ["imu.txt", "--init-lla", "1,2,3", "--init-vel", "0,0,0",
                           "--init-att", "0,0,0", "-o", "o.nav"],
    ("ins", "allan"): ["imu.txt"],
    ("ins", "align"): ["imu.txt", "--lla", "1,2,3"],
    ("ins", "simulate"): ["plan.toml", "-o", "out"],
    ("ins", "simulate-phone"): ["out", "--nav", "n.nav"],
    ("ins", "process"): ["flight", "-o", "out"],
    ("ins", "compare"): ["a.nav", "b.nav"],
    ("ins", "gnss"): ["rover.obs", "-o", "rover.pos"],
    ("ins", "import-bag"): ["drive.bag", "-o", "out"],
    ("ins", "time-offset"): ["--imu", "imu.txt", "--gnss", "gnss.txt"],
    ("ins", "vehicle-mounting"): ["solution.nav"],
    ("ins", "strip-check"): ["points.laz", "--trajectory", "t.nav", "--scanner", "s.toml"],
    ("photogrammetry", "eo"): ["flight", "-o", "eo.csv"],
    ("photogrammetry", "refine"): ["eo.csv", "tp.csv"],
    ("photogrammetry", "tiepoints"): ["a.png", "--eo", "eo.csv", "--camera", "cam.toml",
                                      "--ground-height-m", "0", "-o", "tp.csv"],
    ("photogrammetry", "sfm-import"): ["reconstruction.json", "-o", "out"],
    ("photogrammetry", "lunar-heading"): ["--centres", "c.csv", "--times", "t.csv",
                                          "--station", "1,2,3", "--camera", "cam.toml"],
    ("photogrammetry", "lunar-simulate"): ["--station", "1,2,3", "--start",
                                           "2017-05-02T23:00:00Z", "-o", "moon"],
}
NEGATIVE_TRIPLET = ("-33.9,1.5e-1,-5E2", [-33.9, 0.15, -500.0])
NEGATIVE_SCALAR = ("-2.5e-1", -0.25)


def _numeric_options():
    """(prog, command, option, kind) of every option of both command-line interfaces
    whose type is a number or a triplet of numbers."""
    found = []
    for prog, build in (("ins", ins_cli.build_parser), ("photogrammetry", pg_cli.build_parser)):
        parser = build()
        sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        for command, p in sub.choices.items():
            for action in p._actions:
                if not action.option_strings:
                    continue
                if action.type is triplet:
                    found.append((prog, command, action.option_strings[-1], "triplet"))
                elif action.type is float:
                    found.append((prog, command, action.option_strings[-1], "float"))
    return found


NUMERIC = _numeric_options()


def test_the_walk_finds_the_coordinate_options():
    names = {(c, o) for _, c, o, _ in NUMERIC}
    for expected in [("mechanize", "--init-lla"), ("mechanize", "--init-vel"),
                     ("mechanize", "--init-att"), ("mechanize", "--start"),
                     ("eo", "--origin"), ("eo", "--geoid-undulation"),
                     ("lunar-heading", "--station"), ("lunar-heading", "--temperature"),
                     ("allan", "--start"), ("allan", "--end")]:
        assert expected in names


@pytest.mark.parametrize("prog, command, option, kind", NUMERIC,
                         ids=[f"{c}{o}" for _, c, o, _ in NUMERIC])
@pytest.mark.parametrize("form", ["separate", "equals"])
def test_negative_values_parse_in_both_forms(prog, command, option, kind, form):
    """``--opt -1,2,3`` and ``--opt=-1,2,3`` (and a negative scalar) reach the option."""
    assert (prog, command) in BASE, f"add a minimal argv for {prog} {command} to BASE"
    text, value = NEGATIVE_TRIPLET if kind == "triplet" else NEGATIVE_SCALAR
    argv = list(BASE[(prog, command)])
    if option in argv:                        # a required option: replace its value
        i = argv.index(option)
        del argv[i:i + 2]
    extra = [option, text] if form == "separate" else [f"{option}={text}"]
    build = ins_cli.build_parser if prog == "ins" else pg_cli.build_parser
    args = build().parse_args([command, *extra, *argv])
    got = getattr(args, option.lstrip("-").replace("-", "_"))
    assert np.allclose(got, value, rtol=0, atol=1e-12)


def _static_rows(lat_deg, n=401, dt=0.005):
    lat = np.deg2rad(lat_deg)
    t = 100.0 + dt * np.arange(n)
    w = earth.earth_rate_n(lat) * dt
    f = -earth.gravity_n(lat, 50.0) * dt
    return np.column_stack([t, np.tile(w, (n, 1)), np.tile(f, (n, 1))])


@pytest.mark.parametrize("form", ["separate", "equals"])
def test_mechanize_south_and_west(tmp_path, capsys, form):
    """An IMU at rest in Sydney-by-the-dateline (-33.9, -151.2, 50 m) stays there: the
    negative start reaches the integration (independent truth: rest)."""
    src = tmp_path / "imu.txt"
    np.savetxt(src, _static_rows(-33.9), fmt="%.17g")
    out = tmp_path / "o.nav"
    opts = {"--init-lla": "-33.9,-151.2,50", "--init-vel": "-0,0,-0",
            "--init-att": "-0.0,0,-180", "--start": "-5"}
    flat = [x for k, v in opts.items() for x in ((k, v) if form == "separate" else (f"{k}={v}",))]
    code, _, err = _run(ins_cli.main, ["mechanize", src, *flat, "-q", "-o", out], capsys)
    assert code == 0, err
    nav = np.loadtxt(out)
    assert np.allclose(nav[:, 2], -33.9, atol=1e-9) and np.allclose(nav[:, 3], -151.2, atol=1e-9)
    assert np.allclose(nav[:, 4], 50.0, atol=1e-4)
    assert np.allclose(nav[:, 10], 180.0, atol=1e-6)


@pytest.fixture(scope="module")
def southern_flight(tmp_path_factory):
    """The short test flight moved to the southern and western hemispheres."""
    from photogrammetry.simulate.folder import simulate_flight
    tmp = tmp_path_factory.mktemp("south")
    text = SHORT.read_text()
    assert "origin_lat_deg = 30.5" in text and "origin_lon_deg = 114.3" in text
    plan = tmp / "south.toml"
    plan.write_text(text.replace("origin_lat_deg = 30.5", "origin_lat_deg = -33.9")
                    .replace("origin_lon_deg = 114.3", "origin_lon_deg = -70.7"))
    return simulate_flight(plan, tmp / "flight", seed=2)


@pytest.mark.parametrize("form", ["separate", "equals"])
def test_eo_origin_south_and_west(southern_flight, tmp_path, capsys, form):
    """``--origin -33.9,-70.7,20`` (the block origin) reproduces the simulator's true EO;
    another negative origin moves the positions as pymap3d says."""
    from photogrammetry.orientation.exposure import read_eo_csv
    truth = read_eo_csv(southern_flight / "eo_true.csv")
    for origin in ("-33.9,-70.7,20", "-33.95,-70.61,-12.5"):
        out = tmp_path / f"eo{origin}.csv"
        opt = ["--origin", origin] if form == "separate" else [f"--origin={origin}"]
        code, _, err = _run(pg_cli.main, ["eo", southern_flight, *opt, "-q", "-o", out], capsys)
        assert code == 0, err
        eo = read_eo_csv(out)
        lat0, lon0, h0 = (float(v) for v in origin.split(","))
        assert f"origin_lat_deg = {lat0}" in out.read_text().replace("-33.9,", "")
        lla = np.array(pymap3d.enu2geodetic(*truth.position.T, -33.9, -70.7, 20.0)).T
        expected = np.array(pymap3d.geodetic2enu(*lla.T, lat0, lon0, h0)).T
        assert np.abs(eo.position - expected).max() < 1e-4
    code, _, err = _run(pg_cli.main, ["eo", southern_flight, "--frame", "utm",
                                      "--geoid-undulation", "-30.5", "-q", "-o",
                                      tmp_path / "utm.csv"], capsys)
    assert code == 0, err


def test_lunar_heading_south_and_west(tmp_path, capsys):
    """A station at -33.9, -70.7 (--station -33.9,-70.7,500 and --temperature -5) gives the
    heading of simulated centres back."""
    from ins.nav.rotation import euler_to_dcm
    from photogrammetry.lunar.ephemeris import moon_sun_directions
    from photogrammetry.lunar.fisheye import FisheyeCamera
    lat, lon, h, heading = -33.9, -70.7, 500.0, 211.5
    cam = FisheyeCamera(800.0, 1600, 1600, (799.5, 799.5))
    utc = np.datetime64("2017-05-12T02:00:00") + np.arange(24) * np.timedelta64(30, "s")
    sky = moon_sun_directions(utc, np.deg2rad(lat), np.deg2rad(lon), h, pressure_hpa=950.0,
                              temperature_c=-5.0)
    assert np.all(sky.alt > np.deg2rad(10))                 # the Moon is up there
    C_hc = euler_to_dcm([0.02, -0.01, np.deg2rad(heading)])
    uv = cam.direction_to_image(sky.moon_h @ C_hc)
    (tmp_path / "cam.toml").write_text(
        '[camera]\nmodel = "fisheye-equisolid"\nfocal_length_px = 800.0\nwidth_px = 1600\n'
        'height_px = 1600\n')
    (tmp_path / "t.csv").write_text("image_id,utc\n" + "".join(
        f"m{k:03d},{t}Z\n" for k, t in enumerate(utc)))
    (tmp_path / "c.csv").write_text("image_id,u_px,v_px\n" + "".join(
        f"m{k:03d},{u:.5f},{v:.5f}\n" for k, (u, v) in enumerate(uv)))
    for form in ("separate", "equals"):
        station = ["--station", "-33.9,-70.7,500"] if form == "separate" else \
            ["--station=-33.9,-70.7,500"]
        code, out, err = _run(pg_cli.main, [
            "lunar-heading", "--centres", tmp_path / "c.csv", "--times", tmp_path / "t.csv",
            *station, "--camera", tmp_path / "cam.toml", "--pressure", "950",
            "--temperature", "-5", "-q"], capsys)
        assert code == 0, err
        line = next(x for x in out.splitlines() if x.startswith("heading"))
        assert abs(float(line.split()[6]) - heading) < 0.01


# ---------------------------------------------------------------------------------------
# OSErrors: one line naming the user's path

def test_user_path_maps_hidden_temporaries():
    assert user_path("/a/b/.out.nav.k2j3x9a1.part") == "/a/b/out.nav"
    assert user_path("res/.res.ab_d1234.part/solution.nav".replace("res/", "", 1)) \
        == "res/solution.nav"
    assert user_path("/x/.flight.abcdefgh.old") == "/x/flight"
    assert user_path("/x/.hidden_file") == "/x/.hidden_file"
    assert user_path("/x/.a.b.part") == "/x/.a.b.part"          # not an 8-char temp name


def _one_error_line(err, prog_cmd):
    """The one error line (warnings about the data may come before it)."""
    lines = [x for x in err.splitlines() if x.strip() and not x.startswith("warning: ")]
    assert len(lines) == 1, err
    assert lines[0].startswith(f"{prog_cmd}: error: ") and "Traceback" not in err
    assert ".part" not in lines[0] and ".old" not in lines[0]
    return lines[0]


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    from photogrammetry.simulate.folder import simulate_flight
    return simulate_flight(SHORT, tmp_path_factory.mktemp("fl") / "flight", seed=4)


def _commands(flight, out):
    f = flight
    static = f.parent / "static_imu.txt"
    if not static.exists():
        from ins.io.imu_files import write_kfgins_text
        from ins.nav.imu import ImuLog
        from ins.simulate.sensor_errors import ImuErrorModel, apply_errors
        rows = _static_rows(30.5, n=4000)
        log = ImuLog(rows[:, 0], rows[:, 1:4], rows[:, 4:7])
        write_kfgins_text(static, apply_errors(log, ImuErrorModel.preset("tactical"), 1))
    return {
        "ins simulate": (ins_cli.main, ["simulate", SHORT, "-q", "-o", out]),
        "ins mechanize": (ins_cli.main, ["mechanize", f / "imu.txt", "--init-lla",
                                         "30.5,114.3,300", "--init-vel", "0,0,0",
                                         "--init-att", "0,0,0", "-q", "-o", out]),
        "ins allan": (ins_cli.main, ["allan", static, "--plot", out]),
        "photogrammetry eo": (pg_cli.main, ["eo", f, "-q", "-o", out]),
        "photogrammetry refine": (pg_cli.main, ["refine", f / "eo_true.csv",
                                                f / "tiepoints.csv", "--camera",
                                                f / "camera.toml", "-q", "-o", out]),
    }


COMMANDS = ["ins simulate", "ins mechanize", "ins allan", "photogrammetry eo",
            "photogrammetry refine"]


@pytest.mark.parametrize("name", COMMANDS)
def test_output_under_a_regular_file(flight, tmp_path, capsys, name):
    """``-o FILE/sub``: one line naming the user's path, exit 2, nothing created."""
    blocker = tmp_path / "afile"
    blocker.write_text("x")
    out = blocker / "sub"
    main, argv = _commands(flight, out)[name]
    code, _, err = _run(main, argv, capsys)
    assert code == 2
    line = _one_error_line(err, name)
    assert str(out) in line or str(blocker) in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]
    assert blocker.read_text() == "x"


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize("failure", ["ENOSPC", "EROFS"])
def test_disk_full_and_read_only(flight, tmp_path, capsys, monkeypatch, name, failure):
    """No space while writing (an OSError without a file name) or a read-only directory
    (creating the temporary): one line naming the user's output, exit 2, nothing left."""
    import ins.common.fileio as fileio
    out = tmp_path / "res"
    main, argv = _commands(flight, out)[name]
    if failure == "ENOSPC":
        real_fdopen = os.fdopen

        class Full:
            def __init__(self, f):
                self.f = f

            def write(self, data):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

            def __getattr__(self, attr):
                return getattr(self.f, attr)

            def __enter__(self):
                return self

            def __exit__(self, *exc):
                self.f.close()

        monkeypatch.setattr(fileio.os, "fdopen", lambda *a, **k: Full(real_fdopen(*a, **k)))
    else:
        def read_only(*a, dir=None, prefix="", suffix="", **k):
            name_ = os.path.join(dir or "", f"{prefix}abcd1234{suffix}")
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), name_)
        monkeypatch.setattr(fileio.tempfile, "mkstemp", read_only)
        monkeypatch.setattr(fileio.tempfile, "mkdtemp", read_only)
    code, _, err = _run(main, argv, capsys)
    assert code == 2, err
    line = _one_error_line(err, name)
    assert os.strerror(errno.ENOSPC if failure == "ENOSPC" else errno.EROFS) in line
    assert str(out) in line, line
    assert list(tmp_path.iterdir()) == []


def test_error_inside_a_folder_being_built_names_the_users_folder(tmp_path, capsys,
                                                                  monkeypatch):
    """An OSError naming a file inside the hidden staging folder of ``ins simulate``
    is reported under the user's folder name."""
    import ins.simulate.folder as folder_mod

    def broken(plan, truth, folder, seed):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(folder / "gnss.txt"))

    monkeypatch.setattr(folder_mod, "_write_gnss_and_mount", broken)
    out = tmp_path / "flight"
    code, _, err = _run(ins_cli.main, ["simulate", SHORT, "-q", "-o", out], capsys)
    assert code == 2
    line = _one_error_line(err, "ins simulate")
    assert line.endswith(f"{out / 'gnss.txt'}: Permission denied"), line
    assert list(tmp_path.iterdir()) == []


def test_quality_error_exits_3(tmp_path, capsys, monkeypatch):
    import ins.cli.allan as cli_allan

    def untrustworthy(args):
        raise QualityError("the solution is 308 km from the GNSS fixes")

    monkeypatch.setattr(cli_allan, "_cmd_allan", untrustworthy)
    parser_args = ins_cli.build_parser().parse_args(["allan", str(tmp_path / "x.txt")])
    parser_args.func = untrustworthy
    assert ins_cli.run_command(parser_args, "ins") == 3
    err = capsys.readouterr().err
    assert err == "ins allan: error: the solution is 308 km from the GNSS fixes\n"


def test_a_bug_still_shows_its_traceback(capsys):
    """run_command maps input, file-system, quality and interrupt failures; anything else
    is a bug and propagates."""
    args = argparse.Namespace(command="x", func=lambda a: 1 / 0)
    with pytest.raises(ZeroDivisionError):
        ins_cli.run_command(args, "ins")


# ---------------------------------------------------------------------------------------
# a closed stdout (| head, | true)

def _cli(module):
    return [sys.executable, "-m", module]


@pytest.mark.parametrize("module, argv, output", [
    ("photogrammetry.cli.main", ["eo", "{flight}", "-o", "{tmp}/eo.csv"], "eo.csv"),
    ("ins.cli.main", ["compare", "{flight}/truth.nav", "{flight}/truth.nav"], None),
    ("ins.cli.main", ["simulate", str(SHORT), "-o", "{tmp}/sim"], "sim"),
    ("ins.cli.main", ["--help"], None),
])
def test_closed_stdout_is_quiet(flight, tmp_path, module, argv, output):
    """The reader of stdout goes away before the command writes (``| true``): no
    BrokenPipeError, no 'Exception ignored', exit 0, the files written."""
    argv = [a.format(flight=flight, tmp=tmp_path) for a in argv]
    proc = subprocess.Popen(_cli(module) + argv, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, cwd=tmp_path)
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=300) == 0, err
    assert err == ""
    if output:
        assert (tmp_path / output).exists()


def test_head_of_lunar_heading(tmp_path):
    """The issue's case: ``photogrammetry lunar-heading ... | head -n 2`` in a shell with
    pipefail: exit 0, two lines, nothing on stderr, the plot written."""
    from ins.nav.rotation import euler_to_dcm
    from photogrammetry.lunar.ephemeris import moon_sun_directions
    from photogrammetry.lunar.fisheye import FisheyeCamera
    cam = FisheyeCamera(800.0, 1600, 1600, (799.5, 799.5))
    utc = np.datetime64("2017-05-02T14:00:00") + np.arange(400) * np.timedelta64(2, "s")
    sky = moon_sun_directions(utc, np.deg2rad(40.0), np.deg2rad(116.0), 50.0)
    uv = cam.direction_to_image(sky.moon_h @ euler_to_dcm([0.01, 0.02, 1.0]))
    (tmp_path / "cam.toml").write_text(
        '[camera]\nmodel = "fisheye-equisolid"\nfocal_length_px = 800.0\nwidth_px = 1600\n'
        'height_px = 1600\n')
    (tmp_path / "t.csv").write_text("image_id,utc\n" + "".join(
        f"m{k:03d},{t}Z\n" for k, t in enumerate(utc)))
    (tmp_path / "c.csv").write_text("image_id,u_px,v_px\n" + "".join(
        f"m{k:03d},{u:.5f},{v:.5f}\n" for k, (u, v) in enumerate(uv)))
    cmd = " ".join(_cli("photogrammetry.cli.main") + [
        "lunar-heading", "--centres", "c.csv", "--times", "t.csv", "--station", "40,116,50",
        "--camera", "cam.toml", "--plot", "conv.png"])
    proc = subprocess.run(["bash", "-c", f"set -o pipefail; {cmd} | head -n 2"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == "" and len(proc.stdout.splitlines()) == 2
    assert (tmp_path / "conv.png").stat().st_size > 1000


# ---------------------------------------------------------------------------------------
# the help states the corrected phi-omega-kappa, and it is the library's

@pytest.mark.parametrize("command", ["eo", "refine"])
def test_help_states_the_textbook_phi_omega_kappa(command, capsys):
    from photogrammetry.orientation.rotation import angles_to_matrix
    with pytest.raises(SystemExit):
        pg_cli.main([command, "--help"])
    out = capsys.readouterr().out
    assert "R = Ry(-phi) Rx(omega) Rz(kappa)" in out
    assert "a3 = R[0,2] = -sin(phi) cos(omega)" in out and "Ry(phi) Rx" not in out
    # what the help says is what the library computes (random angles, element a3)
    rng = np.random.default_rng(12)
    for phi, omega, kappa in rng.uniform(-1.5, 1.5, (20, 3)):
        R = angles_to_matrix(np.array([phi, omega, kappa]), "phi-omega-kappa")
        assert R[0, 2] == pytest.approx(-np.sin(phi) * np.cos(omega), abs=1e-15)
        assert np.arctan2(-R[0, 2], R[2, 2]) == pytest.approx(phi, abs=1e-12)


# ---------------------------------------------------------------------------------------
# Ctrl-C inside the process (the subprocess campaign is tests/test_interrupt.py)

@pytest.fixture
def handler_installed():
    from ins.common import interrupts
    interrupts.reset()
    restore = interrupts.install()
    yield interrupts
    restore()
    interrupts.reset()


def _interrupt_now():
    """What the SIGINT handler does when the signal arrives at this point."""
    import signal as signal_

    from ins.common import interrupts
    interrupts.handler(signal_.SIGINT, None)


def test_wrapped_interrupts_exit_130(tmp_path, capsys, handler_installed):
    """An interrupt that surfaced as numba's SystemError (KeyboardInterrupt in its cause)
    or, after the handler ran, as any other exception (llvmlite's AttributeError) is
    reported as an interrupt, not as a traceback."""
    def numba_style(args):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise SystemError("CPUDispatcher(<function _parse_kernel>) returned a result "
                              "with an exception set") from exc

    def llvmlite_style(args):
        try:
            _interrupt_now()
        except KeyboardInterrupt:
            pass                         # swallowed by a library, then a broken object:
        raise AttributeError("'NoneType' object has no attribute '_ptr'")

    for func in (numba_style, llvmlite_style):
        handler_installed.reset()
        args = argparse.Namespace(command="simulate", func=func, output=None)
        assert ins_cli.run_command(args, "ins") == 130
        assert capsys.readouterr().err == "ins simulate: interrupted; no output written\n"


def test_an_interrupt_never_cuts_an_install(tmp_path, capsys, monkeypatch,
                                            handler_installed):
    """SIGINT while a finished output is being renamed into place: the install completes,
    the interrupt takes effect after it, and the message says the output is complete;
    SIGINT while writing: nothing left (no file, no hidden temporary)."""
    import ins.common.fileio as fileio
    real_rename, real_replace = os.rename, os.replace

    def rename_with_signal(src, dst):     # the signal lands in the middle of the swap
        _interrupt_now()
        return real_rename(src, dst)

    def replace_with_signal(src, dst):
        _interrupt_now()
        return real_replace(src, dst)

    out = tmp_path / "folder"
    out.mkdir()
    (out / "old.txt").write_text("old")

    def build_folder(args):
        with fileio.output_folder(out, force=True) as tmp:
            Path(tmp, "new.txt").write_text("new")
            monkeypatch.setattr(fileio.os, "rename", rename_with_signal)
        print("not reached")
        return 0

    args = argparse.Namespace(command="simulate", func=build_folder, output=str(out))
    assert ins_cli.run_command(args, "ins") == 130
    captured = capsys.readouterr()
    assert captured.err == f"ins simulate: interrupted after the output was complete: {out}\n"
    assert captured.out == ""
    assert sorted(os.listdir(tmp_path)) == ["folder"] and os.listdir(out) == ["new.txt"]
    monkeypatch.setattr(fileio.os, "rename", real_rename)

    handler_installed.reset()
    target = tmp_path / "file.txt"

    def write_file(args):
        with fileio.atomic_open(target, "w") as f:
            f.write("complete")
            monkeypatch.setattr(fileio.os, "replace", replace_with_signal)
        return 0

    args = argparse.Namespace(command="eo", func=write_file, output=str(target))
    assert ins_cli.run_command(args, "photogrammetry") == 130
    assert "after the output was complete" in capsys.readouterr().err
    assert target.read_text() == "complete"
    monkeypatch.setattr(fileio.os, "replace", real_replace)

    handler_installed.reset()
    target.unlink()

    def interrupted_while_writing(args):
        with fileio.atomic_open(target, "w") as f:
            f.write("half")
            _interrupt_now()
        return 0

    args.func = interrupted_while_writing
    assert ins_cli.run_command(args, "photogrammetry") == 130
    assert capsys.readouterr().err.endswith("interrupted; no output written\n")
    assert sorted(os.listdir(tmp_path)) == ["folder"]


def test_an_interrupt_inside_llvmlite_waits_until_it_is_left(handler_installed):
    """llvmlite calls back into Python from C++ (its object cache): a KeyboardInterrupt
    there is swallowed by ctypes and the process crashed (seen: SIGSEGV in 1 of 20
    interrupts of ins process).  The handler does not raise inside llvmlite or numba's
    compiler; it sends the signal again until the code has left them."""
    import signal as signal_
    import time
    path = os.sep.join(["", "venv", "site-packages", "llvmlite", "binding", "ee.py"])
    namespace = {}
    exec(compile("import sys\nframe = sys._getframe()", path, "exec"), namespace)
    assert handler_installed.handler(signal_.SIGINT, namespace["frame"]) is None
    assert handler_installed.interrupted()
    with pytest.raises(KeyboardInterrupt):          # the signal again, outside llvmlite
        time.sleep(2.0)


def test_an_interrupt_lost_in_a_finalizer_comes_back(handler_installed, capsys):
    """A KeyboardInterrupt raised inside a weakref callback is 'ignored' by Python (seen:
    'Exception ignored in: <function WeakSet...>' with a traceback, the interrupt lost):
    the hook says nothing and sends the signal again."""
    import gc
    import time
    import weakref

    class Thing:
        pass

    def callback(ref):
        _interrupt_now()                 # the signal lands inside the callback

    thing = Thing()
    ref = weakref.ref(thing, callback)
    with pytest.raises(KeyboardInterrupt):
        del thing
        gc.collect()
        time.sleep(2.0)                  # the signal again, where it can propagate
    assert ref() is None
    err = capsys.readouterr().err
    assert "Exception ignored" not in err and "Traceback" not in err


# SIGTERM like Ctrl-C (issue 35 item 5; the subprocess checks are in tests/test_interrupt.py)

def test_sigterm_inside_an_output_folder_exits_143_and_leaves_nothing(tmp_path, capsys,
                                                                      handler_installed):
    """A real SIGTERM (os.kill of this process) while an output folder is being built:
    the handler turns it into the Ctrl-C path (KeyboardInterrupt), the staging folder is
    removed, exit 143 and the one line; SIGINT still gives 130 and "interrupted"."""
    import signal as signal_

    from ins.common import fileio
    out = tmp_path / "out"

    def build(args):
        with fileio.output_folder(out) as tmp:
            Path(tmp, "half.txt").write_text("half")
            os.kill(os.getpid(), args.signum)
            time.sleep(5)                     # the handler raises before this ends
        return 0

    for signum, code, word in ((signal_.SIGTERM, 143, "terminated (SIGTERM)"),
                               (signal_.SIGINT, 130, "interrupted")):
        handler_installed.reset()
        args = argparse.Namespace(command="process", func=build, output=str(out),
                                  signum=signum)
        t0 = time.perf_counter()
        assert ins_cli.run_command(args, "ins") == code
        assert time.perf_counter() - t0 < 4
        assert capsys.readouterr().err == f"ins process: {word}; no output written\n"
        assert os.listdir(tmp_path) == []
        assert handler_installed.stop_signal() == signum


def _fake_staging(parent, name, record):
    from ins.common.fileio import OWNER_FILE
    folder = parent / name
    (folder / "sub").mkdir(parents=True)
    (folder / "sub" / "big.bin").write_bytes(b"x" * 1000)
    if record is not None:
        (folder / OWNER_FILE).write_text("".join(f"{k}={v}\n" for k, v in record.items()))
    return folder


def test_stale_staging_removed_only_when_its_owner_is_gone(tmp_path):
    """Fake staging folders beside ``out``: the one of a dead process (a child that has
    exited), of a live one (this process), of this process id with another start time
    (the id reused after the owner died), of another host, and without a record.
    output_folder removes the dead and the reused ones (a warning each, naming the
    folder and the process) and leaves the others (a warning each); another output's
    staging folder is not touched; a ``.old`` of a dead owner goes once ``out`` exists.
    The new staging folder holds this process's record during the work, not after."""
    import socket

    from ins.common import fileio
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    me = dict(pid=os.getpid(), host=socket.gethostname())
    mine = dict(me, **{k: v for k, v in (("boot", fileio._boot_id()),
                                         ("start", fileio._start_ticks(os.getpid())))
                       if v is not None})
    dead = _fake_staging(tmp_path, ".out.dead0001.part", dict(me, pid=child.pid))
    alive = _fake_staging(tmp_path, ".out.alive001.part", mine)
    reused = _fake_staging(tmp_path, ".out.reused01.part", dict(mine, start=1))
    remote = _fake_staging(tmp_path, ".out.remote01.part", dict(me, host="elsewhere.example"))
    unknown = _fake_staging(tmp_path, ".out.norec001.part", None)
    other = _fake_staging(tmp_path, ".other.dead0001.part", dict(me, pid=child.pid))
    out = tmp_path / "out"
    with pytest.warns(fileio.StagingWarning) as caught:
        with fileio.output_folder(out) as tmp:
            record = Path(tmp, fileio.OWNER_FILE).read_text()
            assert f"pid={os.getpid()}\n" in record
            Path(tmp, "result.txt").write_text("ok")
    text = [str(w.message) for w in caught]
    assert not dead.exists() and not reused.exists()
    assert alive.exists() and remote.exists() and unknown.exists() and other.exists()
    assert sorted(os.listdir(out)) == ["result.txt"]
    assert any(t.startswith(f"removed {out.parent / dead.name}, the staging folder of a run "
                            f"that was killed (process {child.pid} on ") for t in text), text
    assert any(t.startswith(f"removed {out.parent / reused.name}") for t in text), text
    assert any(f"{alive.name}: staging folder of a run still in progress (process "
               f"{os.getpid()}" in t for t in text), text
    assert any(f"{remote.name}: staging folder of another run, left alone (its owner runs "
               "on another host" in t for t in text), text
    assert any(f"{unknown.name}: staging folder of another run, left alone (it has no "
               "owner record" in t for t in text), text
    assert len(text) == 5
    old = _fake_staging(tmp_path, ".out.gone0001.old", dict(me, pid=child.pid))
    import warnings
    with warnings.catch_warnings(record=True) as again:
        warnings.simplefilter("always")
        assert fileio.clear_stale_staging(out) == [str(old)]
    assert any("the replaced out that a killed run was deleting" in str(w.message)
               for w in again) and len(again) == 4       # and the three left alone
    assert fileio.owner_state(alive)[0] == "alive"
    assert fileio.owner_state(tmp_path / "nothing-here")[0] == "unknown"


def test_an_interrupt_never_cuts_the_tempdir_probe(tmp_path, monkeypatch, handler_installed):
    """SIGINT while tempfile's first gettempdir() probes TMPDIR (it opens a file with a
    bare random name, writes and removes it): the handler sends the signal again a moment
    later instead of raising there, so no empty probe file is left; the interrupt then
    takes effect (the CI once found such a file after a Ctrl-C of refine)."""
    import signal as signal_
    import tempfile
    import time

    from ins.common import interrupts
    real_open = tempfile._os.open
    fired = []

    def open_then_interrupt(*a, **k):
        fd = real_open(*a, **k)
        if not fired:                          # the signal arrives just after the open
            fired.append(True)
            interrupts.handler(signal_.SIGINT, sys._getframe())
        return fd
    monkeypatch.setattr(tempfile._os, "open", open_then_interrupt)
    monkeypatch.setattr(tempfile, "tempdir", None)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    with pytest.raises(KeyboardInterrupt):
        tempfile.gettempdir()                  # the probe completes...
        time.sleep(1.0)                        # ...and the retried signal comes here
    assert fired and os.listdir(tmp_path) == []
