"""Strict TOML files (issue 12): one helper (ins.common.tomlschema), the same messages for the
camera file, the lunar fisheye camera file and the flight plan; a misspelt key is an
error naming the file, the [section] key and the known keys, never a silent default."""
import copy
import re
from pathlib import Path

import numpy as np
import pytest
import tomli_w
import tomllib

from ins.common.errors import InputError
from ins.common.tomlschema import REQUIRED, Table, check_keys
from ins.simulate.plan_read import PLAN_KEYS, load_plan, parse_plan
from photogrammetry.cli.main import main as pg_main
from photogrammetry.lunar.fisheye import FISHEYE_KEYS
from photogrammetry.lunar.fisheye import read_camera as read_fisheye
from photogrammetry.orientation.camera import CAMERA_KEYS, NADIR_AXES, read_camera

ROOT = Path(__file__).resolve().parents[1]
CAMERA = """[camera]
model = "frame"
focal_length_mm = 100.0
pixel_size_mm = 0.01
width_px = 8000
height_px = 6000
principal_point_px = [3999.5, 2999.5]
[mounting]
axes = [[1, 0, 0], [0, -1, 0], [0, 0, -1]]
lever_arm_m = [0.05, 0.0, 0.2]
boresight_deg = [0.01, -0.02, 0.05]
"""


def _error(tmp_path, text, reader=read_camera, name="cam.toml"):
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(InputError) as exc:
        reader(p)
    msg = str(exc.value)
    assert msg.startswith(f"{p}: ") and "\n" not in msg
    return msg


# ---------------------------------------------------------------------------------------
# the helper's messages

def test_check_keys_messages():
    known = {"camera": {"focal_length_mm", "pixel_size_mm"},
             "mounting": {"axes", "lever_arm_m", "boresight_deg"}, "notes": None}
    check_keys({"camera": {"focal_length_mm": 1}, "notes": {"anything": 1}}, known, "f.toml")
    cases = [
        ({"mounting": {"lever_arm": 1}},
         "f.toml: [mounting] lever_arm: unknown key (did you mean lever_arm_m?); known keys "
         "of [mounting]: axes, boresight_deg, lever_arm_m"),
        ({"mounting": {"boresight": 1}}, "(did you mean boresight_deg?)"),
        ({"mount": {"axes": 1}},
         "f.toml: [mount]: unknown section (did you mean [mounting]?); known sections: "
         "[camera], [mounting], [notes]"),
        ({"camera": {"lever_arm_m": 1}}, "[camera] lever_arm_m: unknown key (it belongs in "
                                         "[mounting])"),
        ({"lever_arm_m": [0, 0, 0]}, "f.toml: lever_arm_m: unknown key outside any section "
                                     "(it belongs in [mounting])"),
        ({"lever_arm": [0, 0, 0]}, "lever_arm: unknown key outside any section (did you "
                                   "mean [mounting] lever_arm_m?)"),
        ({"camera": 3}, "f.toml: [camera]: expected a section (table), got int 3"),
        ({"camera": {"colour": "red"}}, "[camera] colour: unknown key; known keys of "
                                        "[camera]: focal_length_mm, pixel_size_mm"),
    ]
    for doc, message in cases:
        with pytest.raises(InputError) as exc:
            check_keys(doc, known, "f.toml")
        assert message in str(exc.value), str(exc.value)
    with pytest.raises(InputError, match=r"\[camera\] pixel_size_mm: missing required key"):
        check_keys({"camera": {}}, known, "f.toml", required=[("camera", "pixel_size_mm")])
    with pytest.raises(InputError, match=r"\[mounting\]: missing required section"):
        check_keys({}, known, "f.toml", required=["mounting"])
    check_keys({"format": "x"}, known, "f.toml", top_keys=["format"])


def test_table_accessors_and_units():
    t = Table({"a_mm": 2, "b": [1, 2.5], "c": True, "m": [[1, 0], [0, 1]], "s": "x",
               "bad": "1"}, "sec", "f.toml", known={"a_mm", "b", "c", "m", "s", "bad", "z"})
    assert t.number("a_mm", unit="mm") == 2.0 and isinstance(t.number("a_mm"), float)
    assert t.numbers("b", length=2) == (1.0, 2.5)
    assert t.boolean("c") is True and t.string("s") == "x"
    assert t.matrix("m", shape=(2, 2)) == ((1.0, 0.0), (0.0, 1.0))
    assert t.number("z", 7.0) == 7.0 and t.number("z", None) is None
    with pytest.raises(InputError, match=r"f.toml: \[sec\] bad: expected a number, got '1' "
                                         r"\(expected mm > 0\)"):
        t.number("bad", unit="mm > 0")
    with pytest.raises(InputError, match=r"\[sec\] z: missing required key \(expected m\)"):
        t.number("z", REQUIRED, "m")
    with pytest.raises(InputError, match=r"\[sec\] b: expected 3 numbers, got 2"):
        t.numbers("b", length=3)
    with pytest.raises(InputError, match=r"\[sec\] a_mm: must be > 5"):
        t.number("a_mm", lo=5, lo_open=True)
    with pytest.raises(KeyError, match="not among the declared keys"):   # a reader's bug
        t.number("undeclared", 1.0)
    t2 = Table({"x": 1, "y": 2}, "sec", "f.toml")
    t2.number("x")
    with pytest.raises(InputError, match=r"\[sec\] y: unknown key; known keys of \[sec\]: x"):
        t2.finish()


# ---------------------------------------------------------------------------------------
# the camera file: the cases

@pytest.mark.parametrize("edit, words", [
    (("lever_arm_m =", "lever_arm ="), "[mounting] lever_arm: unknown key (did you mean "
                                       "lever_arm_m?); known keys of [mounting]: axes, "
                                       "boresight_deg, lever_arm_m"),
    (("boresight_deg =", "boresight ="), "[mounting] boresight: unknown key (did you mean "
                                         "boresight_deg?)"),
    (("[mounting]", "[mount]"), "[mount]: unknown section (did you mean [mounting]?)"),
    (("[mounting]\n", ""), "[camera] axes: unknown key (it belongs in [mounting])"),
    (("focal_length_mm = 100.0", "focal_length_px = 10000.0"),
     "[camera] focal_length_px: unknown key (did you mean focal_length_mm?)"),
    (("lever_arm_m = [0.05, 0.0, 0.2]", "lever_arm_m = [5, 0]"),
     "[mounting] lever_arm_m: expected 3 numbers, got 2 (expected m, body FRD)"),
    (("boresight_deg = [0.01, -0.02, 0.05]", 'boresight_deg = "0.01 -0.02 0.05"'),
     "[mounting] boresight_deg: expected 3 finite numbers"),
    (("width_px = 8000", "width_px = 8000.5"), "[camera] width_px: expected an integer"),
    (("pixel_size_mm = 0.01\n", ""), "[camera] pixel_size_mm: missing required key "
                                     "(expected mm > 0)"),
])
def test_camera_file_is_strict(tmp_path, edit, words):
    assert edit[0] in CAMERA
    msg = _error(tmp_path, CAMERA.replace(*edit, 1))
    assert words in msg, msg


def test_camera_file_defaults_are_the_documented_ones(tmp_path):
    """Without [mounting] (or any of its keys): nadir axes, zero lever arm and boresight;
    a full file gives its values (deg -> rad)."""
    p = tmp_path / "cam.toml"
    p.write_text(CAMERA)
    _, m = read_camera(p)
    assert np.array_equal(m.lever_arm_m, [0.05, 0.0, 0.2])
    assert np.allclose(m.boresight_rad, np.deg2rad([0.01, -0.02, 0.05]), rtol=1e-15)
    p.write_text(CAMERA.split("[mounting]")[0])
    cam, m = read_camera(p)
    assert np.array_equal(m.axes, NADIR_AXES) and not m.lever_arm_m.any()
    assert not m.boresight_rad.any() and not cam.has_distortion
    p.write_text(CAMERA.split("axes")[0] + "lever_arm_m = [1.0, 2.0, 3.0]\n")
    _, m = read_camera(p)
    assert np.array_equal(m.axes, NADIR_AXES) and np.array_equal(m.lever_arm_m, [1, 2, 3])


def test_eo_refuses_a_camera_with_a_misspelt_lever_arm(tmp_path, capsys):
    """The issue's case end to end: the EO was computed with a zero lever arm."""
    from photogrammetry.simulate.folder import simulate_flight
    flight = simulate_flight(ROOT / "tests" / "data" / "flights" / "short.toml",
                             tmp_path / "flight", seed=3)
    text = (flight / "camera.toml").read_text()
    assert "lever_arm_m" in text
    bad = tmp_path / "bad_camera.toml"
    bad.write_text(text.replace("lever_arm_m", "lever_arm"))
    out = tmp_path / "eo.csv"
    code = pg_main(["eo", str(flight), "--camera", str(bad), "-q", "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert err.strip() == (f"photogrammetry eo: error: {bad}: [mounting] lever_arm: unknown "
                           "key (did you mean lever_arm_m?); known keys of [mounting]: axes, "
                           "boresight_deg, lever_arm_m")


# ---------------------------------------------------------------------------------------
# the lunar fisheye camera file and the flight plan

FISHEYE = ('[camera]\nmodel = "fisheye-equisolid"\nfocal_length_px = 800.0\nwidth_px = 1600\n'
           'height_px = 1200\n')


def test_fisheye_file_is_strict_and_defaults(tmp_path):
    p = tmp_path / "fe.toml"
    p.write_text(FISHEYE)
    cam = read_fisheye(p)
    assert cam.principal_point_px == (799.5, 599.5) and cam.radial_k == (0.0, 0.0, 0.0)
    assert cam.pixel_size_mm is None
    p.write_text(FISHEYE.replace("focal_length_px = 800.0", "focal_length_mm = 4.4\n"
                                 "pixel_size_mm = 0.0055"))
    assert read_fisheye(p).focal_length_px == pytest.approx(800.0, rel=1e-12)
    for text, words in [
        (FISHEYE + "radial_k_rad = [0.1, 0, 0]\n", "[camera] radial_k_rad: unknown key (did "
                                                  "you mean radial_k?)"),
        (FISHEYE + "[mounting]\naxes = 1\n", "[mounting]: unknown section; known sections: "
                                             "[camera]"),
        (FISHEYE.replace("800.0", '"800"'), "[camera] focal_length_px: expected a number, "
                                            "got '800' (expected px > 0)"),
        (FISHEYE + "focal_length_mm = 4.4\npixel_size_mm = 0.0055\n",
         "give either focal_length_px or focal_length_mm"),
        (FISHEYE.replace("focal_length_px = 800.0\n", "focal_length_mm = 4.4\n"),
         "[camera] pixel_size_mm: missing: needed with focal_length_mm"),
    ]:
        msg = _error(tmp_path, text, read_fisheye, "fe.toml")
        assert words in msg, msg


@pytest.fixture(scope="module")
def demo_plan():
    return tomllib.loads((ROOT / "data" / "flights" / "demo.toml").read_text())


def test_plan_unknown_keys_say_what_is_known(tmp_path, demo_plan):
    d = copy.deepcopy(demo_plan)
    d["flight"]["ground_speed_mps_"] = 60.0
    with pytest.raises(InputError) as exc:
        parse_plan(d, "plan.toml")
    assert str(exc.value).startswith("plan.toml: [flight] ground_speed_mps_: unknown key "
                                     "(did you mean ground_speed_mps?); known keys of [flight]: "
                                     + ", ".join(sorted(PLAN_KEYS["flight"])))
    d = copy.deepcopy(demo_plan)
    d["camera"]["lever_arm"] = [0.0, 0.0, 0.2]
    with pytest.raises(InputError, match=r"\[camera\] lever_arm: unknown key \(did you mean "
                                         r"lever_arm_m\?\)"):
        parse_plan(d)
    d = copy.deepcopy(demo_plan)
    d["mount"]["lever_arm_m"] = [0.0, 0.0, 0.2]           # a key of another section
    with pytest.raises(InputError, match=r"\[mount\] lever_arm_m: unknown key \(it belongs "
                                         r"in \[camera\]\)"):
        parse_plan(d)
    d = copy.deepcopy(demo_plan)
    d["tiepoints"] = d.pop("tie_points")
    with pytest.raises(InputError, match=r"\[tiepoints\]: unknown section \(did you mean "
                                         r"\[tie_points\]\?\)"):
        parse_plan(d)
    p = tmp_path / "plan.toml"
    p.write_bytes(b"\x00\x01binary")
    with pytest.raises(InputError, match="binary data"):
        load_plan(p)


def test_plan_keys_are_the_keys_the_reader_reads(demo_plan, monkeypatch):
    """PLAN_KEYS is the truth of the messages and the docs, and the reader's: reading an
    undeclared key is a bug the Table catches (KeyError), and every declared key is
    looked at by the reader (a declared key nobody reads would be accepted and ignored:
    the silent default this issue is about)."""
    import ins.simulate.plan_read as plan_mod
    tables = []

    class Recording(Table):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            tables.append(self)

    monkeypatch.setattr(plan_mod, "Table", Recording)
    parse_plan({**copy.deepcopy(demo_plan), "scanner": {}})    # [scanner] is optional
    assert {t.name for t in tables} == set(PLAN_KEYS)
    for t in tables:
        assert t.used == set(PLAN_KEYS[t.name]), (t.name, set(PLAN_KEYS[t.name]) - t.used)


# ---------------------------------------------------------------------------------------
# the documentation names every key

def _doc():
    return (ROOT / "docs" / "interfaces.md").read_text()


@pytest.mark.parametrize("keys", [CAMERA_KEYS, FISHEYE_KEYS], ids=["camera", "fisheye"])
def test_docs_name_every_camera_key(keys):
    doc = _doc()
    for section, names in keys.items():
        assert f"[{section}]" in doc
        for key in names:
            assert re.search(rf"\b{key}\b", doc), key


def test_docs_name_the_process_config_keys():
    """docs/interfaces.md lists every key the processing config accepts (ins/estimation/pipeline/process.py,
    another part's file: read its table of known keys, now in ins/estimation/pipeline/config.py)."""
    from ins.estimation.pipeline import config as process_config
    sections = process_config._SECTIONS
    assert isinstance(sections, dict)
    doc = _doc()
    for section, names in sections.items():
        assert f"[{section}]" in doc, section
        for key in names:
            assert re.search(rf"\b{key}\b", doc), (section, key)


def test_help_states_the_optional_camera_tables(capsys):
    for argv in (["eo", "--help"], ["refine", "--help"], ["lunar-heading", "--help"]):
        with pytest.raises(SystemExit):
            pg_main(argv)
        out = capsys.readouterr().out
        assert "optional" in out and "[camera]" in out, argv
        assert "error" in out
    with pytest.raises(SystemExit):
        pg_main(["eo", "--help"])
    out = capsys.readouterr().out
    for key in CAMERA_KEYS["mounting"]:
        assert key in out


def test_roundtrip_of_written_camera_files_stays_strict(tmp_path):
    """The simulator's camera.toml (write_camera) is read back under the strict rules."""
    from photogrammetry.orientation.camera import camera_to_dict
    cam, m = read_camera(_write(tmp_path, CAMERA))
    doc = camera_to_dict(cam, m)
    check_keys(doc, CAMERA_KEYS, "written")
    (tmp_path / "w.toml").write_bytes(tomli_w.dumps(doc).encode())
    assert read_camera(tmp_path / "w.toml")[0] == cam


def _write(tmp_path, text):
    p = tmp_path / "c.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("module, keys, text, reader", [
    ("photogrammetry.orientation.camera", CAMERA_KEYS, CAMERA + "", "read_camera"),
    ("photogrammetry.lunar.fisheye", FISHEYE_KEYS, FISHEYE, "read_camera"),
], ids=["camera", "fisheye"])
def test_camera_readers_read_every_declared_key(tmp_path, monkeypatch, module, keys, text,
                                                reader):
    import importlib
    mod = importlib.import_module(module)
    tables = []

    class Recording(Table):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            tables.append(self)

    monkeypatch.setattr(mod, "Table", Recording)
    getattr(mod, reader)(_write(tmp_path, text))
    assert {t.name for t in tables} == set(keys)
    for t in tables:
        assert t.used == set(keys[t.name]), (t.name, set(keys[t.name]) - t.used)
