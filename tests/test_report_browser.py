"""The HTML reports of ``ins process --report`` and ``photogrammetry refine --report
F.html`` in a real headless Chromium (DevTools protocol on a pipe, :mod:`chromium`; the
tests skip without a chromium binary): the page loads with every host unresolvable and
reports no console message, log error, exception or failed load; it asks for nothing but
itself; its figures are the PNGs the run wrote (one decoded image per PNG file, with the
file's own width and height read from its header); the verdict is the one the command
printed.  A control page with an external image shows that the check sees a load.

``INS_REPORT_SCREENSHOTS=DIR`` also writes full-page screenshots of the reports there.
"""
import json
import os
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from chromium import Browser, find_chromium

pytestmark = pytest.mark.skipif(find_chromium() is None,
                                reason="no chromium binary (apt install chromium)")

PROBE = ("JSON.stringify({imgs: Array.from(document.images).map(i => [i.src.slice(0, 22), "
         "i.complete, i.naturalWidth, i.naturalHeight]), text: document.body.innerText})")


@pytest.fixture(scope="module")
def browser():
    with Browser() as b:
        yield b


def _load(browser, path, shot=None):
    folder = os.environ.get("INS_REPORT_SCREENSHOTS")
    screenshot = os.path.join(folder, shot) if folder and shot else None
    if screenshot:
        os.makedirs(folder, exist_ok=True)
    page = browser.load(str(path), expression=PROBE, screenshot=screenshot)
    page["value"] = json.loads(page["value"])
    return page


def _assert_clean(page, path):
    assert not page["console"] and not page["exceptions"], page
    assert not page["log"] and not page["failed"], (page["log"], page["failed"])
    own = "file://" + os.path.abspath(path)
    assert [u for u in page["requests"] if not u.startswith("data:")] == [own]


def _png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n" and head[12:16] == b"IHDR"
    return struct.unpack(">II", head[16:24])


def _assert_figures(page, pngs):
    imgs = page["value"]["imgs"]
    assert len(imgs) == len(pngs) > 0
    assert all(src == "data:image/png;base64," and done for src, done, _, _ in imgs), imgs
    assert sorted((w, h) for _, _, w, h in imgs) == sorted(_png_size(p) for p in pngs)


def test_the_check_sees_an_external_load(browser, tmp_path):
    page = tmp_path / "control.html"
    page.write_text('<!DOCTYPE html><html><head><meta charset="utf-8"></head><body>'
                    '<img src="https://example.com/x.png"></body></html>')
    got = browser.load(str(page), expression="document.images.length")
    assert "https://example.com/x.png" in got["requests"] and got["failed"] and got["log"]


#: RTKLIB quality flags written into the flight's GNSS: fix, but float and single stretches
FLOAT_S, SINGLE_S = (200.0, 260.0), (700.0, 720.0)


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """The short flight with its GNSS as an RTKLIB .pos (same positions and sigmas) whose
    quality flags say float over FLOAT_S and single over SINGLE_S (s since the first
    fix), fix elsewhere; and the number of epochs of each flag."""
    from dataclasses import replace

    from test_filter import short_flight

    from ins.io.gnss import read_gnss
    from ins.io.rtklib import write_pos
    src = short_flight()
    folder = tmp_path_factory.mktemp("flight_pos")
    for p in src.iterdir():
        if p.name not in ("manifest.toml", "gnss.txt"):
            (folder / p.name).symlink_to(p)
    text = (src / "manifest.toml").read_text()
    assert text.count('gnss = "gnss.txt"') == 1
    (folder / "manifest.toml").write_text(text.replace('gnss = "gnss.txt"',
                                                       'gnss = "gnss.pos"'))
    log = read_gnss(str(src / "gnss.txt"))
    t = log.time - log.time[0]
    q = np.ones(len(t), int)
    q[(t >= FLOAT_S[0]) & (t <= FLOAT_S[1])] = 2
    q[(t >= SINGLE_S[0]) & (t <= SINGLE_S[1])] = 5
    write_pos(str(folder / "gnss.pos"), replace(log, quality=q), week=0)
    return folder, {k: int(np.sum(q == k)) for k in (1, 2, 5)}, log.time[0]


def test_process_report_in_the_output_folder(browser, flight, tmp_path, capsys):
    from ins.cli.main import main
    flight, counts, t0 = flight
    out = tmp_path / "out"
    assert main(["process", str(flight), "-o", str(out), "--report",
                 str(out / "report.html")]) == 0
    printed = capsys.readouterr()
    report = out / "report.html"
    assert str(report) in printed.out                  # listed with the outputs
    assert not [p for p in out.iterdir() if p.name.startswith(".")]
    pngs = sorted(out.glob("*.png"))
    assert {p.name for p in pngs} >= {"sigma.png", "biases.png", "errors.png"}
    page = _load(browser, report, "process_report.png")
    _assert_clean(page, report)
    _assert_figures(page, pngs)
    text = page["value"]["text"]
    # the verdict the command's warnings imply
    warned = "warning:" in printed.err
    assert ("Trusted, with warnings" if warned else "Trusted: every trust check passed") \
        in text
    # the summary's figures are the printed ones; the IMU epochs are the solution's rows
    epochs = int(re.search(r"(\d+) IMU epochs", printed.out).group(1))
    rows = sum(1 for line in open(out / "solution.nav") if line.strip()
               and not line.startswith("#"))
    assert epochs == rows and re.search(rf"IMU epochs\s+{epochs}\b", text)
    rejected = int(re.search(r"(\d+) rejected by the innovation test", printed.out).group(1))
    assert re.search(rf"rejected by the innovation test\s+{rejected}\b", text)
    assert re.search(r"processing time\s+[0-9.]+ s", text)
    # the IMU errors: the last smoothed estimate of imu_errors.txt
    last = np.loadtxt(out / "imu_errors.txt")[-1]
    row = re.search(r"gyro bias x, deg/h\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)", text)
    assert float(row.group(4)) == pytest.approx(last[1], rel=1e-3, abs=1e-4)
    # the GNSS quality: the epochs of each flag written, the stretches where they were
    for name, q in (("fix", 1), ("float", 2), ("single", 5)):
        share = 100 * counts[q] / sum(counts.values())
        assert re.search(rf"^{name}\t{counts[q]}\t{share:.1f} %$", text, re.M), name
    for a, b, name in ((*FLOAT_S, "float"), (*SINGLE_S, "single")):
        assert re.search(rf"^{t0 + a:.2f}\t{t0 + b:.2f}\t{b - a:.2f}\t{name}\t", text,
                         re.M), (name, text)
    for section in ("GNSS source and quality", "Recoveries and re-anchorings",
                    "IMU errors (smoothed sensor estimates)", "Accuracy", "Files written"):
        assert section in text


@pytest.fixture(scope="module")
def tactical_flight():
    from test_filter import short_flight
    from test_process_trust import _plan
    return short_flight(seed=0, plan=_plan())


def test_process_report_of_a_poor_run_outside_the_folder(browser, tactical_flight, tmp_path,
                                                          capsys):
    """Navigation-grade noise settings on a tactical IMU (test_process_trust): exit 3
    leaves no report; with --accept-poor the report, outside OUT_DIR, says why."""
    from test_process_trust import NAVIGATION, _config

    from ins.cli.main import main
    cfg = _config(tmp_path, tactical_flight, layout="kfgins", noise=NAVIGATION)
    qc = tmp_path / "qc"
    qc.mkdir()
    report = qc / "poor.html"
    f = tactical_flight
    args = ["process", "--imu", str(f / "imu.txt"), "--gnss", str(f / "gnss.txt"),
            "--mount", str(f / "mount.txt"), "--config", str(cfg), "-o", str(tmp_path / "out"),
            "--report", str(report)]
    assert main(args) == 3
    assert not report.exists() and not list(qc.iterdir())
    capsys.readouterr()
    assert main(args + ["--accept-poor"]) == 0
    printed = capsys.readouterr()
    assert "warning: untrustworthy solution:" in printed.err
    page = _load(browser, report, "process_report_poor.png")
    _assert_clean(page, report)
    _assert_figures(page, sorted((tmp_path / "out").glob("*.png")))
    text = page["value"]["text"]
    assert "Untrustworthy solution: written with --accept-poor" in text
    assert "recoveries from runs of rejected position fixes" in text
    recoveries = printed.out.count("recovery: ")
    assert recoveries >= 2 and len(re.findall(r"^recovery\t", text, re.M)) == recoveries


@pytest.fixture(scope="module")
def block(tmp_path_factory):
    import scenario as sc
    d = tmp_path_factory.mktemp("block")
    B = sc.make_block(n_strips=2, n_per_strip=6, seed=41)
    return d, sc.write_block_files(B, str(d), outlier=(3, 4, 0.06))


@pytest.mark.parametrize("poor", [False, True])
def test_refine_html_report(browser, block, tmp_path, capsys, poor):
    from photogrammetry.cli.main import main
    _, (eo, tp, cam) = block
    out, rep = tmp_path / "refined.csv", tmp_path / "refine.html"
    args = ["refine", eo, tp, "--camera", cam, "--method", "known-base", "--datum", "none",
            "-o", str(out), "--report", str(rep)]
    if poor:
        args += ["--sigma-px", "0.1", "--accept-poor"]
    assert main(args) == 0
    capsys.readouterr()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["refine.html", "refined.csv"]
    page = _load(browser, rep, f"refine_report{'_poor' if poor else ''}.png")
    _assert_clean(page, rep)
    imgs = page["value"]["imgs"]
    assert len(imgs) == 2 and all(done and w > 100 and h > 100 for _, done, w, h in imgs)
    text = page["value"]["text"]
    sigma0 = float(re.search(r"sigma0 = ([0-9.]+)", out.read_text()).group(1))
    assert f"sigma0 = {sigma0:.3f}" in text
    assert ("Trust: POOR" in text) == poor and ("Trust: no flag" in text) != poor
    assert ("Poor: written with --accept-poor" in text) == poor
    assert ("No trust flag" in text) != poor
    assert "Boresight misalignment" in text and "INS assessment" in text


def test_refine_markdown_report_unchanged(block, tmp_path, capsys):
    """A name that does not end in .html keeps the Markdown report and its PNGs."""
    from photogrammetry.cli.main import main
    _, (eo, tp, cam) = block
    out, rep = tmp_path / "refined.csv", tmp_path / "r.md"
    assert main(["refine", eo, tp, "--camera", cam, "--method", "known-base", "--datum",
                 "none", "-o", str(out), "--report", str(rep), "-q"]) == 0
    assert rep.read_text().startswith("# Coplanarity refinement")
    assert {p.name for p in Path(tmp_path).iterdir()} == {
        "refined.csv", "r.md", "r_residuals.png", "r_corrections.png"}
