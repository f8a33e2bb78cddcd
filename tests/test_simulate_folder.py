"""The flight folder of ``ins simulate``: files of the manifest, same seed -> same bytes,
true EO against an independent pymap3d computation, tie points re-intersected from the
written files, refusal of bad arguments and of non-empty folders, atomic output."""
import csv
from pathlib import Path

import numpy as np
import pymap3d
import pytest
import tomllib
from test_simulate_tiepoints import intersect

from ins.cli.main import main
from ins.common.errors import InputError
from ins.io.navfiles import read_nav
from ins.nav.rotation import quat_to_dcm
from photogrammetry.orientation.camera import read_camera
from photogrammetry.orientation.rotation import angles_to_matrix
from photogrammetry.simulate.folder import FILES, simulate_flight

PLAN = Path(__file__).parent / "data" / "flights" / "short.toml"


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    calls = []
    out = simulate_flight(PLAN, tmp_path_factory.mktemp("sim") / "flight", seed=11,
                          progress=lambda d, n: calls.append((d, n)))
    return out, calls


@pytest.fixture(scope="module")
def truth():
    from ins.simulate.plan_read import load_plan
    from ins.simulate.truth import build_truth
    return build_truth(load_plan(PLAN))


def _rows(path):
    with open(path, newline="") as f:
        return [r for r in csv.reader(f) if r and not r[0].startswith("#")]


def _eo(path):
    rows = _rows(path)
    header, rows = rows[0], rows[1:]
    ids = [r[0] for r in rows]
    values = np.array([[float(x) for x in r[1:]] for r in rows])
    return header, ids, values


def test_manifest_names_every_file(flight):
    folder, calls = flight
    manifest = tomllib.loads((folder / "manifest.toml").read_text())
    assert manifest["format"] == "insphoto-flight/1"
    assert set(manifest["files"]) == set(FILES)
    for name in manifest["files"].values():
        assert (folder / name).stat().st_size > 0
    assert (folder / "plan.toml").read_bytes() == PLAN.read_bytes()
    assert manifest["mapping_frame"]["origin_lat_deg"] == 30.5
    assert manifest["lever_arm"]["platform_centre_to_antenna_a_m"] == [0.4, 0.2, -1.5]
    assert manifest["imu"]["gyro_bias_dph"] == [1.0, -0.8, 0.6]       # tactical preset
    # [initial] is the first row of truth.nav
    nav = read_nav(folder / "truth.nav")
    ini = manifest["initial"]
    assert ini["lat_deg"] == pytest.approx(np.rad2deg(nav.lla[0, 0]), abs=1e-11)
    assert ini["rpy_deg"] == pytest.approx(nav.rpy(degrees=True)[0], abs=1e-8)
    # no hidden temporary folders left beside the flight folder
    assert [p.name for p in folder.parent.iterdir()] == [folder.name]
    # progress: non-decreasing, ends at its total
    done = [d for d, _ in calls]
    assert done == sorted(done) and calls[-1][0] == calls[-1][1]


def test_same_seed_same_bytes(flight, tmp_path):
    folder, _ = flight
    again = simulate_flight(PLAN, tmp_path / "again", seed=11)
    names = sorted(p.name for p in folder.iterdir())
    assert names == sorted(p.name for p in again.iterdir())
    for name in names:
        assert (folder / name).read_bytes() == (again / name).read_bytes(), name
    other = simulate_flight(PLAN, tmp_path / "other", seed=12)
    for name in ("imu.txt", "gnss.txt", "tiepoints.csv", "ground_points.csv"):
        assert (folder / name).read_bytes() != (other / name).read_bytes(), name
    for name in ("truth.nav", "eo_true.csv", "events.csv", "mount.txt"):   # not random
        assert (folder / name).read_bytes() == (other / name).read_bytes(), name


def test_products_have_their_own_random_streams(flight, tmp_path):
    """Another GNSS rate changes gnss.txt only: the IMU noise and the tie points stay."""
    folder, _ = flight
    plan = tmp_path / "plan.toml"
    plan.write_text(PLAN.read_text().replace("[gnss]\nrate_hz = 2.0", "[gnss]\nrate_hz = 5.0"))
    other = simulate_flight(plan, tmp_path / "f", seed=11)
    assert (folder / "gnss.txt").read_bytes() != (other / "gnss.txt").read_bytes()
    for name in ("imu.txt", "tiepoints.csv", "ground_points.csv", "truth.nav"):
        assert (folder / name).read_bytes() == (other / name).read_bytes(), name


def test_true_eo_against_pymap3d(flight, truth):
    """Camera position and attitude of eo_true*.csv, recomputed independently: the lever
    arm and camera axes as NED offsets (pymap3d.ned2geodetic) mapped into the ENU frame
    at the origin (pymap3d.geodetic2enu)."""
    folder, _ = flight
    _, mounting = read_camera(folder / "camera.toml")
    lat0, lon0, h0 = np.deg2rad(30.5), np.deg2rad(114.3), 20.0
    header, ids, pok = _eo(folder / "eo_true.csv")
    assert header == ["image_id", "time_s", "X_m", "Y_m", "Z_m", "phi_deg", "omega_deg",
                      "kappa_deg"]
    _, ids2, opk = _eo(folder / "eo_true_omega-phi-kappa.csv")
    assert ids == ids2 and ids == [r[0] for r in _rows(folder / "events.csv")[1:]]
    R = angles_to_matrix(pok[:, 4:7], "phi-omega-kappa", degrees=True)
    assert np.allclose(R, angles_to_matrix(opk[:, 4:7], "omega-phi-kappa", degrees=True),
                       atol=1e-11)
    s = truth.evaluate(pok[:, 0])
    C_nb = quat_to_dcm(s.q_nb)

    def enu_of(offset_n):
        lat, lon, h = pymap3d.ned2geodetic(*offset_n.T, *s.lla.T, deg=False)
        return np.column_stack(pymap3d.geodetic2enu(lat, lon, h, lat0, lon0, h0, deg=False))

    X0 = enu_of(C_nb @ mounting.lever_arm_m)
    assert np.abs(X0 - pok[:, 1:4]).max() < 1e-5
    base = enu_of(np.zeros((len(s.time), 3)))
    for v_c in np.eye(3):
        d_n = 1000.0 * np.einsum("nij,j->ni", C_nb, mounting.C_bc @ v_c)
        assert np.abs(enu_of(d_n) - base - 1000.0 * R @ v_c).max() < 1e-5   # 1e-8 rad
    # the stabilized nadir camera looks down within the mount's residual tilt
    assert np.all((R @ [0, 0, -1.0])[:, 2] < -np.cos(np.deg2rad(3.0)))


def test_tiepoints_reintersect_from_files(flight):
    """Forward intersection of each tie point from its images with the TRUE EO (read
    from eo_true.csv) against ground_points.csv: the chi-square of the residuals with
    the propagated pixel noise has mean 3 (3 degrees of freedom)."""
    folder, _ = flight
    camera, _ = read_camera(folder / "camera.toml")
    _, ids, pok = _eo(folder / "eo_true.csv")
    eo = type("EO", (), {"X_m": pok[:, 1:4],
                         "C_mc": angles_to_matrix(pok[:, 4:7], "phi-omega-kappa",
                                                  degrees=True)})
    ground = {int(r[0]): np.array(r[1:], float) for r in _rows(folder / "ground_points.csv")[1:]}
    obs = _rows(folder / "tiepoints.csv")[1:]
    index = {name: k for k, name in enumerate(ids)}
    img = np.array([index[r[0]] for r in obs])
    pid = np.array([int(r[1]) for r in obs])
    xy = np.array([[float(r[2]), float(r[3])] for r in obs])
    manifest = tomllib.loads((folder / "manifest.toml").read_text())
    sigma_mm = manifest["tie_points"]["sigma_px"] * camera.pixel_size_mm
    chi2 = []
    for p, X_true in ground.items():
        sel = pid == p
        assert sel.sum() >= 2
        X, N = intersect(camera, eo, img[sel], xy[sel], sigma_mm)
        chi2.append((X - X_true) @ N @ (X - X_true))
    chi2 = np.array(chi2)
    assert len(chi2) > 300
    assert abs(chi2.mean() - 3.0) < 4.0 * np.sqrt(6.0 / len(chi2))


def test_mount_log_matches_truth(flight, truth):
    folder, _ = flight
    lines = (folder / "mount.txt").read_text().splitlines()
    assert lines[0].startswith("# time_s roll_deg pitch_deg yaw_deg")
    rows = np.array([[float(x) for x in ln.split()] for ln in lines[1:]])
    assert np.allclose(np.diff(rows[:, 0]), 1 / 50.0)
    k = slice(None, None, 97)
    assert np.allclose(np.deg2rad(rows[k, 1:]), truth.evaluate(rows[k, 0]).mount_rpy,
                       atol=1e-11)


# ---------------------------------------------------------------------------------------
# command line

def _run(capsys, *argv):
    try:
        code = main(["simulate", *map(str, argv), "-q"])
    except SystemExit as exc:          # argparse rejects the arguments
        code = exc.code
    return code, capsys.readouterr().err


def test_cli_refuses_non_empty_folder_then_force(tmp_path, capsys):
    out = tmp_path / "f"
    out.mkdir()
    (out / "keep.txt").write_text("old")
    code, err = _run(capsys, PLAN, "-o", out)
    assert code == 2 and "not empty" in err and "--force" in err
    assert [p.name for p in out.iterdir()] == ["keep.txt"]
    code, err = _run(capsys, PLAN, "-o", out, "--force", "--seed", "2", "--grade", "navigation")
    assert code == 0, err
    assert not (out / "keep.txt").exists()
    manifest = tomllib.loads((out / "manifest.toml").read_text())
    assert manifest["flight"]["seed"] == 2 and manifest["flight"]["grade"] == "navigation"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


@pytest.mark.parametrize("extra, message", [
    (["--seed", "-1"], "integer >= 0"),
    (["--seed", "x"], "integer >= 0"),
    (["--grade", "toy"], "invalid choice"),
])
def test_cli_bad_arguments(tmp_path, capsys, extra, message):
    code, err = _run(capsys, PLAN, "-o", tmp_path / "f", *extra)
    assert code == 2 and message in err
    assert not (tmp_path / "f").exists()


def test_cli_bad_paths(tmp_path, capsys):
    code, err = _run(capsys, tmp_path / "none.toml", "-o", tmp_path / "f")
    assert code == 2 and "no such plan file" in err
    code, err = _run(capsys, PLAN, "-o", tmp_path / "missing" / "f")
    assert code == 2 and "parent directory does not exist" in err
    (tmp_path / "file").write_text("x")
    code, err = _run(capsys, PLAN, "-o", tmp_path / "file")
    assert code == 2 and "not a directory" in err


def test_impossible_plan_names_the_key_and_leaves_nothing(tmp_path, capsys):
    text = PLAN.read_text().replace("forward_overlap_percent = 60.0",
                                    "forward_overlap_percent = 100.0")
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    code, err = _run(capsys, bad, "-o", tmp_path / "f")
    assert code == 2 and "forward_overlap_percent" in err and "bad.toml" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]
    with pytest.raises(InputError, match="seed"):
        simulate_flight(PLAN, tmp_path / "g", seed=-3)


def test_files_read_by_the_photogrammetry_readers(flight):
    """eo_true*.csv and tiepoints.csv as photogrammetry.orientation.exposure / .tiepoints read them."""
    from photogrammetry.imagery.tiepoints import read_tiepoints
    from photogrammetry.orientation.exposure import read_eo_csv
    folder, _ = flight
    a = read_eo_csv(folder / "eo_true.csv")
    b = read_eo_csv(folder / "eo_true_omega-phi-kappa.csv")
    assert a.system == "phi-omega-kappa" and b.system == "omega-phi-kappa"
    assert np.allclose(a.matrices(), b.matrices(), atol=1e-11)
    assert np.array_equal(a.position, b.position)
    tp = read_tiepoints(folder / "tiepoints.csv")
    manifest = tomllib.loads((folder / "manifest.toml").read_text())
    camera, _ = read_camera(folder / "camera.toml")
    assert tp.sigma_mm == pytest.approx(manifest["tie_points"]["sigma_px"]
                                        * camera.pixel_size_mm)
    tp.check_images(a.image_id)
    assert len(tp) == manifest["flight"]["n_tiepoint_observations"]


def test_failure_keeps_the_old_folder(tmp_path, monkeypatch):
    """--force replaces the old folder only once the new one is complete (also when
    the image products, the last writer, fail)."""
    import photogrammetry.simulate.images as images_mod
    out = tmp_path / "f"
    out.mkdir()
    (out / "old.txt").write_text("old")

    def broken(*args):
        raise RuntimeError("disk full")

    monkeypatch.setattr(images_mod, "write_images", broken)
    with pytest.raises(RuntimeError, match="disk full"):
        simulate_flight(PLAN, out, seed=1, force=True)
    assert [p.name for p in out.iterdir()] == ["old.txt"]
    assert [p.name for p in tmp_path.iterdir()] == ["f"]


# ---------------------------------------------------------------------------------------
# the split: INS products in ins.simulate, image products in photogrammetry.simulate

def test_ins_part_alone_is_the_ins_part_of_the_whole(flight, tmp_path):
    """ins.simulate.folder.simulate_flight without product writers writes the INS files
    of the complete folder byte for byte, a manifest holding exactly its INS entries, and
    a folder that ins process reads."""
    from ins.estimation.pipeline.config import config_from_manifest
    from ins.simulate import folder as ins_folder
    folder, _ = flight
    alone = ins_folder.simulate_flight(PLAN, tmp_path / "ins", seed=11)
    names = sorted(p.name for p in alone.iterdir())
    assert names == ["gnss.txt", "imu.txt", "manifest.toml", "mount.txt", "plan.toml",
                     "truth.nav"]
    for name in names:
        if name != "manifest.toml":
            assert (alone / name).read_bytes() == (folder / name).read_bytes(), name
    part = tomllib.loads((alone / "manifest.toml").read_text())
    whole = tomllib.loads((folder / "manifest.toml").read_text())
    images = {"flight": {"n_images", "n_tiepoint_observations"},
              "files": {"events", "camera", "eo_true", "eo_true_omega_phi_kappa",
                        "tiepoints", "ground_points"},
              "frames": {"c", "m"}}
    assert set(whole) - set(part) == {"mapping_frame", "tie_points"}
    for table, value in part.items():
        if isinstance(value, dict):
            assert set(whole[table]) - set(value) == images.get(table, set()), table
            assert all(whole[table][k] == v for k, v in value.items()), table
        else:
            assert whole[table] == value
    cfg = config_from_manifest(str(alone))
    assert (cfg.imu, cfg.gnss, cfg.mount) == tuple(str(alone / n) for n in
                                                   ("imu.txt", "gnss.txt", "mount.txt"))


def test_manifest_layout_is_the_formats(flight):
    """Tables and frames in the order of the format (as written before the split)."""
    folder, _ = flight
    text = (folder / "manifest.toml").read_text()
    tables = [line.strip("[]") for line in text.splitlines() if line.startswith("[")]
    assert tables == ["flight", "files", "frames", "mapping_frame", "lever_arm", "mount",
                      "imu", "gnss", "tie_points", "initial", "stationary"]
    manifest = tomllib.loads(text)
    assert list(manifest["frames"]) == ["imu", "n", "a", "c", "m", "gnss", "truth", "mount"]
    assert list(manifest["files"]) == list(FILES)
    assert list(manifest["flight"])[-2:] == ["n_images", "n_tiepoint_observations"]


def test_manifest_merge():
    from ins.simulate.manifest import merge
    base = {"format": "f", "files": {"imu": "imu.txt"}, "frames": {"imu": "FRD", "gnss": "g"}}
    out = merge(base, {"extra": {"a": 1}},
                {"files": {"events": "events.csv"}, "frames": {"m": "ENU"},
                 "tie_points": {"sigma_px": 0.5}})
    assert list(out) == ["format", "files", "frames", "tie_points", "extra"]
    assert list(out["files"]) == ["imu", "events"]
    assert list(out["frames"]) == ["imu", "m", "gnss"]
    assert base == {"format": "f", "files": {"imu": "imu.txt"},                 # untouched
                    "frames": {"imu": "FRD", "gnss": "g"}}
    with pytest.raises(ValueError, match=r"\[files\] imu written twice"):
        merge(base, {"files": {"imu": "other.txt"}})
    with pytest.raises(ValueError, match="not a table"):
        merge(base, {"format": {"x": 1}})


def test_ins_simulate_comes_from_the_entry_point_group():
    """``ins simulate`` is photogrammetry's command, found through ``ins.commands``."""
    import argparse

    from ins.cli import main as cli
    found = {ep.name: ep.value for ep in cli.command_entry_points()}
    assert found.get("simulate") == "photogrammetry.cli.simulate:add_parser"
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    func = sub.choices["simulate"].get_default("func")
    assert func.__module__ == "photogrammetry.cli.simulate"
