"""Property-based hardening of the photogrammetry readers (hypothesis): random corruptions
of a valid file -- truncation at any byte, a number replaced by NaN, +-inf, a huge value
or text, two columns or values swapped, bytes that are not UTF-8 -- fed to
``photogrammetry sfm-import`` (OpenSfM reconstruction.json and tracks.csv, COLMAP
cameras/images/points3D.bin) and to the tie-point reader of ``refine``.

Every corruption must end in exit 2 with ONE stderr line that names the corrupted file,
or in a result without NaN/inf; a corrupted value the reader does not use (the colour of
a track, say) must give the clean file's result.  Never a traceback.
``INS_HYPOTHESIS_EXAMPLES`` (default 60) sets the examples per reader.
"""
import contextlib
import io
import json
import os
import re
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from ins.common.errors import InputError
from photogrammetry.cli.main import main
from photogrammetry.imagery.tiepoints import read_tiepoints
from photogrammetry.orientation.camera import FrameCamera

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_sfm import _colmap_model, _write_project  # noqa: E402

EXAMPLES = int(os.environ.get("INS_HYPOTHESIS_EXAMPLES", "60"))
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])
BAD_VALUES = ["NaN", "Infinity", "-Infinity", "1e308", "-1e308", "1e400", "abc", ""]
_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


# ---------------------------------------------------------------------------------------
# corruptions: (kind, new bytes)

@st.composite
def corruption(draw, data, columns_sep=None):
    """A corrupted copy of `data` (bytes) and its kind: "truncate", "value" (a number
    replaced by a bad value), "swap" (two fields or numbers exchanged), "bytes" (not
    UTF-8 inserted)."""
    kind = draw(st.sampled_from(["truncate", "value", "swap", "bytes"]))
    numbers = list(_NUMBER.finditer(data))
    if kind == "truncate":
        return kind, data[:draw(st.integers(0, len(data) - 1))]
    if kind == "bytes":
        at = draw(st.integers(0, len(data)))
        junk = draw(st.sampled_from([b"\xff", b"\xfe\xff", b"\xc3\x28", b"\x80abc"]))
        return kind, data[:at] + junk + data[at:]
    if kind == "value":
        m = numbers[draw(st.integers(0, len(numbers) - 1))]
        bad = draw(st.sampled_from(BAD_VALUES)).encode()
        return kind, data[:m.start()] + bad + data[m.end():]
    # swap: two columns of one line (a CSV), else two numbers of the file
    if columns_sep is not None:
        lines = data.split(b"\n")
        rows = [k for k, x in enumerate(lines) if x.count(columns_sep) >= 3
                and not x.startswith(b"#")]
        k = draw(st.sampled_from(rows))
        f = lines[k].split(columns_sep)
        a, b = draw(st.lists(st.integers(0, len(f) - 1), min_size=2, max_size=2, unique=True))
        f[a], f[b] = f[b], f[a]
        lines[k] = columns_sep.join(f)
        return kind, b"\n".join(lines)
    a, b = sorted(draw(st.lists(st.integers(0, len(numbers) - 1), min_size=2, max_size=2,
                                unique=True)))
    ma, mb = numbers[a], numbers[b]
    return kind, (data[:ma.start()] + mb.group() + data[ma.end():mb.start()] + ma.group()
                  + data[mb.end():])


def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, err.getvalue()


def _outputs(folder):
    """The output files' data lines (comments, which name the source, left out)."""
    return {p.name: [x for x in p.read_text().splitlines() if not x.startswith("#")]
            for p in sorted(Path(folder).iterdir())}


def _check(rc, err, name, kind, outputs, clean, must_differ_or_fail):
    assert "Traceback" not in err, err
    assert rc in (0, 2), (rc, err)
    if rc == 2:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and name in lines[0], err
        assert "array(" not in err and "[nan" not in err, err
        return "exit 2"
    text = "\n".join("\n".join(v) for v in outputs.values()).lower()
    assert "nan" not in text and "inf" not in text, outputs
    if kind in must_differ_or_fail:
        assert outputs == clean, (kind, err)
        return "exit 0, clean result"
    return "exit 0, finite result"


# ---------------------------------------------------------------------------------------
# OpenSfM

@pytest.fixture(scope="module")
def opensfm(tmp_path_factory):
    d = tmp_path_factory.mktemp("osfm")
    rng = np.random.default_rng(5)
    pts = np.column_stack([rng.uniform(-40, 40, 6), rng.uniform(-30, 30, 6),
                           rng.uniform(-3, 3, 6)])
    R2 = np.diag([1.0, -1, -1]) @ Rotation.from_euler("xyz", [2, -3, 30], degrees=True
                                                         ).as_matrix().T
    _write_project(d, {"a.jpg": (np.diag([1.0, -1, -1]), np.array([0, 0, 100.0])),
                       "b.jpg": (R2, np.array([20.0, 5, 102]))}, pts)
    doc = json.loads((d / "reconstruction.json").read_text())
    (d / "reconstruction.json").write_text(json.dumps(doc, indent=1))
    rc, err = _run(["sfm-import", str(d / "reconstruction.json"), "-q", "-o", str(d / "out")])
    assert rc == 0, err
    return d, _outputs(d / "out")


def _opensfm_case(base, tmp, name, data):
    work = Path(tmp)
    for n in ("reconstruction.json", "tracks.csv"):
        shutil.copyfile(base / n, work / n)
    (work / name).write_bytes(data)
    return _run(["sfm-import", str(work / "reconstruction.json"), "-q", "-o",
                 str(work / "out")])


OUTCOMES = {}


def _tally(reader, outcome):
    OUTCOMES.setdefault(reader, {}).setdefault(outcome, 0)
    OUTCOMES[reader][outcome] += 1


@pytest.mark.parametrize("name", ["reconstruction.json", "tracks.csv"])
def test_opensfm_corruptions(opensfm, tmp_path_factory, name):
    base, clean = opensfm
    data = (base / name).read_bytes()
    sep = b"\t" if name == "tracks.csv" else None

    @SETTINGS
    @given(corruption(data, sep))
    def check(case):
        kind, bad = case
        tmp = tmp_path_factory.mktemp("c")
        rc, err = _opensfm_case(base, tmp, name, bad)
        out = _outputs(tmp / "out") if rc == 0 else None
        # a bad value in reconstruction.json is always read; in tracks.csv the columns
        # past y (size, colour, segmentation) are not
        _tally(name, _check(rc, err, name, kind, out, clean,
                            ("value", "bytes") if name == "tracks.csv" else ()))
        if name == "reconstruction.json" and kind in ("value", "bytes"):
            assert rc == 2 or out == clean, (kind, err)
    check()
    print(f"\n{name}: {EXAMPLES} examples: {OUTCOMES.get(name)}")


# ---------------------------------------------------------------------------------------
# COLMAP binary model

@pytest.fixture(scope="module")
def colmap(tmp_path_factory):
    pycolmap = pytest.importorskip("pycolmap")
    d = tmp_path_factory.mktemp("colmap")
    rng = np.random.default_rng(8)
    pts = np.column_stack([rng.uniform(-30, 30, 6), rng.uniform(-20, 20, 6),
                           rng.uniform(-2, 2, 6)])
    R2 = np.diag([1.0, -1, -1]) @ Rotation.from_euler("xyz", [-2, 3, -20], degrees=True
                                                         ).as_matrix().T
    params = [700.0, 700.0, 321.3, 238.9, -0.08, 0.01, 0.0005, -0.0003]
    _colmap_model(d / "txt", {"a.png": (np.diag([1.0, -1, -1]), np.array([0, 0, 80.0])),
                              "b.png": (R2, np.array([15.0, 2, 81]))}, pts, params)
    (d / "bin").mkdir()
    pycolmap.Reconstruction(str(d / "txt")).write_binary(str(d / "bin"))
    rc, err = _run(["sfm-import", str(d / "bin"), "-q", "-o", str(d / "out")])
    assert rc == 0, err
    return d / "bin", _outputs(d / "out")


@st.composite
def binary_corruption(draw, data):
    """Truncation at any byte, or 8 bytes at any offset overwritten by a NaN, an inf or
    a huge double (a count, an id, a size or a parameter, whichever is there)."""
    if draw(st.booleans()):
        return "truncate", data[:draw(st.integers(0, len(data) - 1))]
    at = draw(st.integers(0, len(data) - 8))
    v = draw(st.sampled_from([np.nan, np.inf, -np.inf, 1e308, -1e308]))
    return "value", data[:at] + np.float64(v).tobytes() + data[at + 8:]


@pytest.mark.parametrize("name", ["cameras.bin", "images.bin", "points3D.bin"])
def test_colmap_binary_corruptions(colmap, tmp_path_factory, name):
    base, clean = colmap
    data = (base / name).read_bytes()

    @SETTINGS
    @given(binary_corruption(data))
    def check(case):
        kind, bad = case
        tmp = tmp_path_factory.mktemp("c")
        shutil.copytree(base, tmp / "m")
        (tmp / "m" / name).write_bytes(bad)
        rc, err = _run(["sfm-import", str(tmp / "m"), "-q", "-o", str(tmp / "out")])
        out = _outputs(tmp / "out") if rc == 0 else None
        # the error names the model folder (pycolmap's own messages) or the file
        _tally(name, _check(rc, err, str(tmp / "m"), kind, out, clean, ()))
    check()
    print(f"\n{name}: {EXAMPLES} examples: {OUTCOMES.get(name)}")


# ---------------------------------------------------------------------------------------
# tie-point CSV (the reader of refine)

CAMERA = FrameCamera(100.0, 0.01, 8000, 6000, (3999.5, 2999.5))


@pytest.fixture(scope="module")
def tiepoints(tmp_path_factory):
    d = tmp_path_factory.mktemp("tp")
    rng = np.random.default_rng(3)
    rows = ["# sigma_px = 0.5", "image_id,point_id,x_mm,y_mm"]
    for img in ("a", "b", "c"):
        rows += [f"{img},{k},{x:.7f},{y:.7f}" for k, (x, y) in
                 enumerate(rng.uniform(-25, 25, (8, 2)))]
    (d / "tiepoints.csv").write_text("\n".join(rows) + "\n")
    return d / "tiepoints.csv", read_tiepoints(d / "tiepoints.csv", CAMERA)


def test_tiepoint_corruptions(tiepoints, tmp_path_factory):
    path, clean = tiepoints
    data = path.read_bytes()

    @SETTINGS
    @given(corruption(data, b","))
    def check(case):
        kind, bad = case
        p = tmp_path_factory.mktemp("c") / "tiepoints.csv"
        p.write_bytes(bad)
        try:
            tp = read_tiepoints(p, CAMERA)
        except InputError as exc:
            msg = str(exc)
            assert "\n" not in msg and msg.startswith(str(p)), msg
            assert "array(" not in msg and "[nan" not in msg, msg
            _tally("tiepoints.csv", "exit 2")
            return
        assert np.all(np.isfinite(tp.xy_mm))
        if kind in ("value", "bytes"):
            # only the sigma comment can take a bad value unseen: it is refused too
            assert tp.image_id == clean.image_id and tp.sigma_mm == clean.sigma_mm
            np.testing.assert_array_equal(tp.xy_mm, clean.xy_mm)
        _tally("tiepoints.csv", "exit 0, finite result")
    check()
    print(f"\ntiepoints.csv: {EXAMPLES} examples: {OUTCOMES.get('tiepoints.csv')}")
