"""``photogrammetry refine`` end to end on files of a simulated block; tie-point reader
errors; Dask tasks giving the single-process results."""
import numpy as np
import pytest

from ins.errors import InputError
from photogrammetry import _scenario as sc
from photogrammetry.batch import refine, refine_many
from photogrammetry.camera import read_camera
from photogrammetry.cli import main
from photogrammetry.exposure import read_eo_csv
from photogrammetry.rotation import angles_to_matrix
from photogrammetry.tiepoints import read_tiepoints


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("refine")
    B = sc.make_block(n_strips=2, n_per_strip=6, seed=41)
    return B, d, sc.write_block_files(B, str(d), outlier=(3, 4, 0.06))


def _rms_error(B, angles):
    e = sc.rotation_error(angles_to_matrix(angles, B["system"]),
                          angles_to_matrix(B["angles"], B["system"]))
    return np.sqrt(np.mean(e ** 2))


def test_cli_end_to_end(files, capsys):
    B, d, (eo, tp, cam) = files
    out, rep = str(d / "refined.csv"), str(d / "report.md")
    code = main(["refine", eo, tp, "--camera", cam, "--method", "known-base", "--datum", "none",
                 "-o", out, "--report", rep, "--system", "omega-phi-kappa"])
    assert code == 0
    refined = read_eo_csv(out).in_system("phi-omega-kappa")
    assert refined.has_sigmas and np.all(refined.sigma_angles > 0)
    assert _rms_error(B, refined.angles) < 0.03 * _rms_error(B, B["prior"])
    text = open(rep).read()
    assert "sigma0" in text and "Boresight misalignment" in text and "nan" not in text.lower()
    assert "1 rejected" in text or "2 rejected" in text
    for png in ("report_residuals.png", "report_corrections.png"):
        with open(d / png, "rb") as f:
            assert f.read(8) == b"\x89PNG\r\n\x1a\n"
    assert "refined.csv" in capsys.readouterr().out


def test_cli_bad_input_no_output(files, tmp_path, capsys):
    B, d, (eo, tp, cam) = files
    bad = tmp_path / "tp.csv"
    lines = open(tp).read().splitlines()
    lines[5] = "nosuchimage," + lines[5].split(",", 1)[1]
    bad.write_text("\n".join(lines) + "\n")
    out = tmp_path / "r.csv"
    assert main(["refine", eo, str(bad), "--camera", cam, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:6:" in err and "nosuchimage" in err and not out.exists()
    assert main(["refine", eo, tp, "-o", str(out)]) == 2        # no camera
    assert "--camera" in capsys.readouterr().err and not out.exists()


def test_tiepoint_reader_errors(tmp_path):
    cam, _ = read_camera(sc.write_block_files(sc.make_block(1, 3, seed=1), str(tmp_path))[2])
    p = tmp_path / "a.csv"
    p.write_text("image_id,point,x_mm,y_mm\n")
    with pytest.raises(InputError, match=r"a\.csv:1: header"):
        read_tiepoints(p)
    p.write_text("image_id,point_id,x_mm,y_mm\na,1,0.5,0.25\na,1,0.1,0.2\n")
    with pytest.raises(InputError, match=r"a\.csv:3: point '1' observed twice"):
        read_tiepoints(p)
    p.write_text("image_id,point_id,u_px,v_px\na,1,4000.5,2999.5\n")
    with pytest.raises(InputError, match="need the camera"):
        read_tiepoints(p)
    t = read_tiepoints(p, cam)
    np.testing.assert_allclose(t.xy_mm, [[0.01, 0.0]])


def test_dask_tasks_identical_to_single_process(files):
    B, d, (eo, tp, cam) = files
    camera, _ = read_camera(cam)
    tasks = [dict(eo=read_eo_csv(eo), tiepoints=read_tiepoints(tp, camera), camera=camera,
                  method=m, datum="first") for m in ("base-free", "relative")]
    seq = [refine(**t) for t in tasks]
    par = refine_many(tasks, workers=2, processes=False)
    for a, b in zip(seq, par):
        np.testing.assert_array_equal(a.eo.angles, b.eo.angles)
        np.testing.assert_array_equal(a.block.cov, b.block.cov)
