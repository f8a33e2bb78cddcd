"""``ins mechanize`` / ``ins compare`` end to end: output layout, every bad input gives a
one-line error naming file and line, exit code 2 and no output file."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ins.cli import main as cli
from ins.io.imu_files import write_kfgins_binary
from ins.io.navfiles import read_nav
from ins.nav import earth
from ins.nav.imu import ImuLog

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "data" / "example"
INIT = ["--init-lla", "30.44,114.47,1000", "--init-vel", "60,0,-0.1438276615812609",
        "--init-att", "0,2.3056392336543654,0.09092974268256818"]


def _static_rows(n=400, dt=0.005, lat_deg=45.0):
    lat = np.deg2rad(lat_deg)
    t = 100.0 + dt * np.arange(n)
    w = earth.earth_rate_n(lat) * dt
    f = -earth.gravity_n(lat, 0.0) * dt
    return np.column_stack([t, np.tile(w, (n, 1)), np.tile(f, (n, 1))])


def _write(path, rows, fmt="%.17g"):
    np.savetxt(path, rows, fmt=fmt)
    return path


def _run(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


STATIC_INIT = ["--init-lla", "45,7,0", "--init-vel", "0,0,0", "--init-att", "0,0,0"]


def test_example_log_matches_truth(tmp_path, capsys):
    out = tmp_path / "example.nav"
    code, stdout, err = _run(capsys, "mechanize", EXAMPLE / "imu.txt", *INIT, "-o", out)
    assert code == 0, err
    assert "12001 epochs" in stdout
    lines = out.read_text().splitlines()
    assert len(lines) == 12001
    fields = lines[1].split()
    assert len(fields) == 11 and fields[0] == "0"
    assert len(fields[2].split(".")[1]) == 12          # 1e-12 deg = 0.1 um
    nav = np.loadtxt(out)
    assert np.all((nav[:, 10] >= 0) & (nav[:, 10] < 360))
    code, stdout, _ = _run(capsys, "compare", out, EXAMPLE / "truth.nav")
    assert code == 0 and "601 common epochs" in stdout
    from ins.nav.accuracy import compare
    err = compare(read_nav(out), read_nav(EXAMPLE / "truth.nav"))
    assert np.max(err.horizontal) < 1e-5 and np.max(np.abs(err.pos_n[:, 2])) < 1e-4


def test_every_start_end_and_compensation(tmp_path, capsys):
    rows = _static_rows(2001)
    bias_dph = np.array([1.0, -2.0, 3.0])
    biased = rows.copy()
    biased[:, 1:4] += np.deg2rad(bias_dph / 3600.0) * 0.005
    src = _write(tmp_path / "imu.txt", biased)
    out = tmp_path / "out.nav"
    code, _, err = _run(capsys, "mechanize", src, *STATIC_INIT, "--every", "100",
                        "--start", "101", "--end", "105",
                        "--gyro-bias-dph", ",".join(map(str, bias_dph)), "-o", out, "-q")
    assert code == 0, err
    nav = np.loadtxt(out, ndmin=2)
    np.testing.assert_allclose(nav[:, 1], np.arange(101.0, 105.0 + 1e-9, 0.5))
    # the bias removed, the body stays at rest: attitude within 1e-6 deg of level/north
    assert np.max(np.abs(nav[:, 8:10])) < 1e-6
    assert np.max(np.minimum(nav[:, 10], 360 - nav[:, 10])) < 1e-6


def test_binary_and_axes(tmp_path, capsys):
    rows = _static_rows()
    flu = rows.copy()
    flu[:, [2, 3, 5, 6]] *= -1.0                     # FRD -> FLU: y and z flip
    log = ImuLog(time=flu[:, 0], dtheta_b=flu[:, 1:4], dvel_b=flu[:, 4:7])
    write_kfgins_binary(tmp_path / "imu.bin", log)
    out = tmp_path / "o.nav"
    code, _, err = _run(capsys, "mechanize", tmp_path / "imu.bin", *STATIC_INIT, "--axes",
                        "FLU", "-o", out, "-q")
    assert code == 0, err
    nav = np.loadtxt(out)
    assert np.max(np.abs(nav[:, 5:8])) < 1e-6        # at rest


def test_rates_option(tmp_path, capsys):
    rows = _static_rows()
    rates = rows.copy()
    rates[:, 1:] /= 0.005
    src = _write(tmp_path / "rates.txt", rates)
    out = tmp_path / "o.nav"
    code, _, err = _run(capsys, "mechanize", src, *STATIC_INIT, "-o", out, "-q")
    assert code == 2 and "--rates" in err and not out.exists()
    code, _, err = _run(capsys, "mechanize", src, *STATIC_INIT, "--rates", "-o", out, "-q")
    assert code == 0, err
    assert np.max(np.abs(np.loadtxt(out)[:, 5:8])) < 1e-6


def _bad_files(tmp_path):
    good = _static_rows(50)
    text = [" ".join(f"{v:.17g}" for v in r) for r in good]

    def write(name, lines):
        p = tmp_path / name
        p.write_text("\n".join(lines) + "\n")
        return p

    cases = {
        "missing column": (write("short.txt", text[:9] + [" ".join(text[9].split()[:6])] + text[10:]), 10),
        "extra column": (write("extra.txt", text[:4] + [text[4] + " 1.0"] + text[5:]), 5),
        "text in number": (write("text.txt", text[:6] + [text[6].replace(text[6].split()[3], "abc", 1)] + text[7:]), 7),
        "nan": (write("nan.txt", text[:11] + [text[11].replace(text[11].split()[2], "nan", 1)] + text[12:]), 12),
        "inf": (write("inf.txt", text[:3] + [text[3].replace(text[3].split()[5], "inf", 1)] + text[4:]), 4),
        "time not increasing": (write("back.txt", text[:20] + [text[25]] + text[21:25] + [text[20]] + text[26:]), 22),
        "duplicated epoch": (write("dup.txt", text[:30] + [text[29]] + text[30:]), 31),
        "empty": (write("empty.txt", []), None),
    }
    return cases


@pytest.mark.parametrize("case", ["missing column", "extra column", "text in number", "nan",
                                  "inf", "time not increasing", "duplicated epoch", "empty"])
def test_bad_input_one_line_error_exit_2_no_output(tmp_path, capsys, case):
    path, line = _bad_files(tmp_path)[case]
    before = (path.read_bytes(), path.stat().st_mtime_ns)
    out = tmp_path / "out.nav"
    code, stdout, err = _run(capsys, "mechanize", path, *STATIC_INIT, "-o", out)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("ins mechanize: error: ")
    assert str(path) in err
    if line is not None:
        assert f"{path}:{line}:" in err
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out.nav")]
    assert (path.read_bytes(), path.stat().st_mtime_ns) == before


def test_truncated_binary(tmp_path, capsys):
    rows = _static_rows()
    p = tmp_path / "imu.bin"
    p.write_bytes(rows.astype("<f8").tobytes()[:-20])
    code, _, err = _run(capsys, "mechanize", p, *STATIC_INIT, "-o", tmp_path / "o.nav")
    assert code == 2 and "record 400" in err and "56" in err
    assert not (tmp_path / "o.nav").exists()


def test_gap_warns_or_strict_refuses(tmp_path, capsys):
    rows = np.delete(_static_rows(), [100, 101, 250], axis=0)
    src = _write(tmp_path / "gap.txt", rows)
    out = tmp_path / "o.nav"
    code, _, err = _run(capsys, "mechanize", src, *STATIC_INIT, "-o", out, "-q")
    assert code == 0 and "warning: 2 gap(s)" in err and out.exists()
    out.unlink()
    code, _, err = _run(capsys, "mechanize", src, *STATIC_INIT, "--strict", "-o", out, "-q")
    assert code == 2 and "2 gap(s)" in err and not out.exists()


def test_existing_output_survives_a_failed_run(tmp_path, capsys):
    out = tmp_path / "o.nav"
    out.write_text("previous result\n")
    path, _ = _bad_files(tmp_path)["nan"]
    assert _run(capsys, "mechanize", path, *STATIC_INIT, "-o", out)[0] == 2
    assert out.read_text() == "previous result\n"


@pytest.mark.parametrize("argv, needle", [
    (["--init-lla", "45,7"], "--init-lla"),
    (["--init-lla", "95,7,0"], "latitude"),
    (["--init-att", "0,x,0"], "--init-att"),
    (["--every", "0"], "--every"),
    (["--axes", "XYZ"], "--axes"),
])
def test_bad_arguments(tmp_path, capsys, argv, needle):
    src = _write(tmp_path / "imu.txt", _static_rows())
    args = dict(zip(STATIC_INIT[::2], STATIC_INIT[1::2]))
    extra = []
    for k, v in zip(argv[::2], argv[1::2]):
        if k in args:
            args[k] = v
        else:
            extra += [k, v]
    flat = [x for kv in args.items() for x in kv]
    try:
        code = cli.main(["mechanize", str(src), *flat, *extra, "-o", str(tmp_path / "o.nav")])
    except SystemExit as exc:          # argparse's own errors
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and needle in err, err
    assert not (tmp_path / "o.nav").exists()


def test_missing_file(tmp_path, capsys):
    code, _, err = _run(capsys, "mechanize", tmp_path / "nope.txt", *STATIC_INIT, "-o",
                        tmp_path / "o.nav")
    assert code == 2 and "nope.txt" in err


def test_console_script_help_names_units():
    exe = Path(sys.executable).with_name("ins")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "ins.cli.main"]
    res = subprocess.run(cmd + ["mechanize", "--help"], capture_output=True, text=True,
                         env={**os.environ, "COLUMNS": "100"})
    assert res.returncode == 0
    for needle in ["deg", "m/s", "FRD", "rad", "END of the interval", "[0, 360)"]:
        assert needle in res.stdout


def test_compare_bad_nav_names_line(tmp_path, capsys):
    good = (EXAMPLE / "truth.nav").read_text().splitlines()
    bad = good[:5] + [good[3]] + good[6:]
    p = tmp_path / "bad.nav"
    p.write_text("\n".join(bad) + "\n")
    code, _, err = _run(capsys, "compare", p, EXAMPLE / "truth.nav")
    assert code == 2 and f"{p}:6:" in err and "not increasing" in err
    p.write_text("\n".join(good[:3] + [good[3] + "x"] + good[4:]) + "\n")
    code, _, err = _run(capsys, "compare", p, EXAMPLE / "truth.nav")
    assert code == 2 and f"{p}:4:" in err


def test_output_path_errors(tmp_path, capsys):
    src = _write(tmp_path / "imu.txt", _static_rows())
    code, _, err = _run(capsys, "mechanize", src, *STATIC_INIT, "-o", tmp_path)
    assert code == 2 and f"{tmp_path}: is a directory" in err
    code, _, err = _run(capsys, "mechanize", src, *STATIC_INIT, "-o", tmp_path / "no" / "o.nav")
    assert code == 2 and "directory does not exist" in err and str(tmp_path / "no") in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["imu.txt"]
