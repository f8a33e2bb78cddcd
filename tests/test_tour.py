"""docs/tour.md, "The toolkit from Python", run as a test: its ```python blocks in order in
one namespace in an empty folder.  Each block's printout must match the ```text block
shown under it (words exactly, numbers within a few percent), so that the page shows
what the code does; and the results must be what the page says they are, against the
simulator's truth."""
import contextlib
import io
import re
from pathlib import Path

import numpy as np
import pytest

TOUR = Path(__file__).resolve().parents[1] / "docs" / "tour.md"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```\s*$", re.MULTILINE | re.DOTALL)
NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def blocks(text):
    """``[(code, expected printout or None)]`` of the page's python blocks, in order."""
    fences = [(m.group(1), m.group(2)) for m in FENCE.finditer(text)]
    out = []
    for k, (lang, body) in enumerate(fences):
        if lang == "python":
            after = fences[k + 1] if k + 1 < len(fences) else None
            out.append((body, after[1] if after and after[0] == "text" else None))
    return out


def same_printout(got, expected, rel=0.05):
    """Words equal; each number within ``rel`` or 2 units of its last printed digit."""
    if NUMBER.sub("#", got.strip()) != NUMBER.sub("#", expected.strip()):
        return False
    for g, e in zip(NUMBER.findall(got), NUMBER.findall(expected)):
        decimals = len(e.split(".")[1].split("e")[0]) if "." in e else 0
        if abs(float(g) - float(e)) > max(rel * abs(float(e)), 2 * 10.0 ** -decimals):
            return False
    return True


def test_printout_comparison_rejects_a_different_printout():
    assert same_printout("RMS 0.68 cm, 62 arcsec", "RMS 0.69 cm, 63 arcsec")
    assert not same_printout("RMS 0.98 cm, 62 arcsec", "RMS 0.68 cm, 62 arcsec")
    assert not same_printout("RMS 0.68 mm, 62 arcsec", "RMS 0.68 cm, 62 arcsec")


def test_blocks_are_found():
    found = blocks("a\n```python\nx = 1\n```\n\n```text\n1\n```\n```python\ny = 2\n```\n")
    assert found == [("x = 1\n", "1\n"), ("y = 2\n", None)]


@pytest.fixture(scope="module")
def tour(tmp_path_factory):
    """The namespace after the whole page, and each block's printout."""
    import os
    folder = tmp_path_factory.mktemp("tour")
    namespace = {"__name__": "__tour__"}
    printed = []
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        for k, (code, expected) in enumerate(blocks(TOUR.read_text())):
            buf = io.StringIO()
            with contextlib.redirect_stdout(buf):
                exec(compile(code, f"{TOUR.name} python block {k + 1}", "exec"), namespace)
            printed.append((k + 1, buf.getvalue(), expected))
    finally:
        os.chdir(cwd)
    namespace["_folder"] = folder
    return namespace, printed


def test_every_block_prints_what_the_page_shows(tour):
    _, printed = tour
    assert len(printed) >= 7
    for k, got, expected in printed:
        if expected is None:
            assert got == "", f"block {k} prints but the page shows no output:\n{got}"
        else:
            assert same_printout(got, expected), (
                f"block {k} of docs/tour.md printed\n{got}\nbut the page shows\n{expected}")


def test_smoothed_trajectory_within_centimetres_of_the_truth(tour):
    ns, _ = tour
    rms = ns["rms"]
    smoothed, forward = ns["errors"]["smoothed"], ns["errors"]["forward"]
    assert np.all(rms(smoothed.pos_n) < 0.02)                        # m, each of N/E/D
    assert np.all(rms(smoothed.pos_n) < rms(forward.pos_n))
    assert np.all(rms(smoothed.att_n[:, :2]) < 100 * ns["ARCSEC"])   # tilt
    # the .nav written by write_outputs is the smoothed trajectory (to the file's digits)
    written = ns["ins"].read_nav(ns["_folder"] / "processed" / "solution.nav")
    again = ns["ins"].compare(written, ns["truth"])
    assert np.allclose(rms(again.pos_n), rms(smoothed.pos_n), atol=1e-4)


def test_refined_angles_closer_to_the_truth_than_the_ins_ones(tour):
    ns, _ = tour
    rms, err = ns["rms"], ns["angle_error"]
    before, after = rms(err(ns["eo_ins"])), rms(err(ns["refined"].eo))
    assert np.linalg.norm(after) < 0.2 * np.linalg.norm(before)
    assert after[1] < before[1] and after[2] < before[2]             # omega, kappa
    # the boresight estimate is the simulated boresight plus the INS attitude error
    a = ns["refined"].assessment
    assert np.all(np.abs(a.boresight - ns["apparent"]) < 15 * ns["ARCSEC"])
    assert np.all(np.abs(ns["true_mounting"].boresight_rad - ns["apparent"])
                  < 150 * ns["ARCSEC"])


def test_the_page_leaves_its_files(tour):
    ns, _ = tour
    folder = ns["_folder"]
    for name in ("plan.toml", "eo_ins.csv", "eo_refined.csv", "refine_report.md",
                 "trajectory_errors.png", "angles.png"):
        assert (folder / name).stat().st_size > 0, name
    assert (folder / "trajectory_errors.png").read_bytes()[:4] == b"\x89PNG"
