"""The boresight's total sigma (adjustment + INS attitude common to the exposures):
the camera-frame sigma against exact rotation algebra (Monte Carlo of a body-fixed INS
error absorbed by a boresight), and ``photogrammetry refine`` stating both sigmas in
its report and CSV, with the sigma file from --ins-std or the EO file's header."""
import numpy as np
import pytest
import scenario as sc
from scipy.spatial.transform import Rotation

from ins.common.errors import InputError
from photogrammetry.cli.main import main
from photogrammetry.orientation.boresight_sigma import (
    BoresightSigma,
    boresight_sigma,
    ins_common_sigma,
)
from photogrammetry.orientation.camera import NADIR_AXES
from photogrammetry.orientation.exposure import read_eo_header

AS = np.pi / 180 / 3600


def _std_rows(t, rpy_as):
    """solution_std.txt rows: time, N E D m, vN vE vD m/s, roll pitch yaw deg."""
    rpy = np.broadcast_to(np.asarray(rpy_as, float) / 3600, (len(t), 3))
    return np.column_stack([t, np.full((len(t), 3), 0.01), np.full((len(t), 3), 0.001), rpy])


def test_nadir_axes_map_roll_pitch_yaw_to_rx_ry_rz():
    # the nadir camera's x is the body's forward axis, y its left, z up: rx, ry, rz take
    # the roll, pitch and yaw sigmas; constant sigmas are their own mean
    t = np.linspace(0.0, 100.0, 11)
    s = ins_common_sigma(t, np.tile([10.0, 20.0, 30.0], (11, 1)) * AS, [5.0, 50.0],
                         np.array(NADIR_AXES))
    np.testing.assert_allclose(s / AS, [10, 20, 30], rtol=1e-12)
    # a camera turned 90 deg about the body's down axis (x right): rx takes the pitch
    axes = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) @ np.array(NADIR_AXES)
    s = ins_common_sigma(t, np.tile([10.0, 20.0, 30.0], (11, 1)) * AS, [5.0], axes)
    np.testing.assert_allclose(s / AS, [20, 10, 30], rtol=1e-12)
    # sigmas linear in time: the mean of the interpolated values
    sd = np.column_stack([t, 2 * t, 3 * t]) * AS
    s = ins_common_sigma(t, sd, [10.0, 30.0], np.array(NADIR_AXES))
    np.testing.assert_allclose(s / AS, [20, 40, 60], rtol=1e-12)
    bs = boresight_sigma([3 * AS, 4 * AS, 0.0], (t, np.tile([4.0, 3.0, 7.0], (11, 1)) * AS),
                         [5.0], np.array(NADIR_AXES))
    np.testing.assert_allclose(bs.total / AS, [5, 5, 7], rtol=1e-12)
    assert BoresightSigma(np.ones(3)).total.tolist() == [1, 1, 1]


def test_outside_the_sigma_file_is_an_input_error():
    t = np.linspace(0.0, 10.0, 3)
    with pytest.raises(InputError, match=r"std\.txt: exposure b at t = 11\.0 s is outside"):
        ins_common_sigma(t, np.ones((3, 3)), [1.0, 11.0], np.eye(3), names=["a", "b"],
                         path="std.txt")


def _apparent_boresight(C_nb, delta_b, axes, b_true):
    """What a calibration sees: mean over the exposures of the rotation taking the INS
    camera attitude (no boresight) onto the true one, as Rx Ry Rz angles (exact)."""
    B = Rotation.from_euler("XYZ", b_true).as_matrix()
    R_true = C_nb @ axes @ B
    R_ins = C_nb @ Rotation.from_rotvec(delta_b).as_matrix() @ axes
    C_rel = np.einsum("nji,njk->nik", R_ins, R_true)
    return Rotation.from_matrix(C_rel).as_euler("XYZ").mean(axis=0)


def test_sigma_matches_monte_carlo_of_a_body_fixed_ins_error():
    # a tilted camera mount (not a signed permutation: a transposed axes matrix would
    # show), strips flown back and forth, INS sigmas varying along the block; the INS
    # error fully correlated over the block (the stated assumption): the scatter of what
    # the calibration absorbs is the stated sigma; a tilt that is fixed in the NED frame
    # instead (changes sign in the body between opposite strips) stays below it
    rng = np.random.default_rng(5)
    n = 24
    t = np.arange(n, dtype=float)
    heading = np.where((np.arange(n) // 6) % 2 == 0, 0.3, 0.3 + np.pi)
    rpy = np.column_stack([rng.normal(0, 0.02, n), rng.normal(0, 0.02, n), heading])
    C_nb = Rotation.from_euler("ZYX", rpy[:, ::-1]).as_matrix()
    axes = Rotation.from_euler("xyz", [40.0, -20.0, 60.0], degrees=True).as_matrix() \
        @ np.array(NADIR_AXES)
    sd = np.column_stack([20 + 5 * np.sin(t / 5), 60 + t, 150 + 2 * t]) * AS
    b_true = np.array([36.0, -72.0, 180.0]) * AS
    stated = ins_common_sigma(t, sd, t, axes)
    runs = 3000
    common = np.empty((runs, 3))
    ned_tilt = np.empty((runs, 3))
    for k in range(runs):
        z = rng.standard_normal(3)
        common[k] = _apparent_boresight(C_nb, sd * z, axes, b_true) - b_true
        # the same sigmas, but a tilt fixed in NED: in the body it flips with the heading
        flip = np.where(np.cos(heading - 0.3) > 0, 1.0, -1.0)[:, None]
        d_b = sd * z * np.column_stack([flip, flip, np.ones(n)])
        ned_tilt[k] = _apparent_boresight(C_nb, d_b, axes, b_true) - b_true
    mc = common.std(axis=0)
    # 3000 runs: the sample sigma within 3 % (2.3 of its sigmas, 1.3 %)
    np.testing.assert_allclose(mc / stated, 1.0, atol=0.03)
    assert np.all(ned_tilt.std(axis=0) <= 1.03 * stated)
    assert np.min(ned_tilt.std(axis=0) / stated) < 0.8          # partly cancelled


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("bore")
    B = sc.make_block(n_strips=2, n_per_strip=6, seed=41)
    eo, tp, cam = sc.write_block_files(B, str(d))
    std = d / "solution_std.txt"
    t = np.linspace(-5.0, 20.0, 26)
    np.savetxt(std, _std_rows(t, [40.0, 30.0, 90.0]),
               header="time_s std_n_m std_e_m std_d_m std_vn_mps std_ve_mps std_vd_mps "
                      "std_roll_deg std_pitch_deg std_yaw_deg")
    return d, eo, tp, cam, std


def _refine(d, eo, tp, cam, name, *extra):
    out, rep = d / f"{name}.csv", d / f"{name}.md"
    code = main(["refine", eo, tp, "--camera", cam, "--method", "known-base", "--datum",
                 "none", "-o", str(out), "--report", str(rep), "-q", *extra])
    return code, out, rep


def _deg(meta, key):
    return np.array([float(v) for v in meta[key].split(",")])


def test_refine_states_adjustment_and_total_sigma(files):
    d, eo, tp, cam, std = files
    code, out, rep = _refine(d, eo, tp, cam, "with", "--ins-std", str(std))
    assert code == 0
    meta = read_eo_header(out)
    adj = _deg(meta, "boresight_sigma_adjustment_deg")
    ins = _deg(meta, "boresight_sigma_ins_common_deg")
    total = _deg(meta, "boresight_sigma_total_deg")
    # nadir axes: rx, ry, rz take roll, pitch, yaw (constant 40, 30, 90 arcsec)
    np.testing.assert_allclose(ins * 3600, [40, 30, 90], atol=1e-4)
    np.testing.assert_allclose(total, np.hypot(adj, ins), atol=2e-8)
    assert np.all(adj > 0)
    assert str(std) in meta["boresight sigma"]
    text = rep.read_text()
    assert "sigma, adjustment alone" in text and "**sigma, total**" in text
    assert "INS attitude common to the exposures" in text and "(total sigma)" in text

    # without a sigma file: the adjustment's sigma alone, said to understate the error
    code, out2, rep2 = _refine(d, eo, tp, cam, "without")
    assert code == 0
    meta2 = read_eo_header(out2)
    np.testing.assert_allclose(_deg(meta2, "boresight_sigma_adjustment_deg"), adj)
    assert "boresight_sigma_total_deg" not in meta2
    assert "understates" in meta2["boresight sigma"]
    text2 = rep2.read_text()
    assert "adjustment's alone" in text2 and "understates" in text2 and "--ins-std" in text2

    # the EO file names the sigma file (photogrammetry eo --sigma): found without --ins-std
    lines = open(eo).read().splitlines()
    named = d / "eo_named.csv"
    named.write_text("\n".join(lines[:3] + ["# trajectory sigma = solution_std.txt"]
                               + lines[3:]) + "\n")
    code, out3, _ = _refine(d, str(named), tp, cam, "named")
    assert code == 0
    np.testing.assert_allclose(_deg(read_eo_header(out3), "boresight_sigma_total_deg"), total)


def test_sigma_file_not_covering_the_exposures_exits_2_without_output(files, tmp_path,
                                                                     capsys):
    d, eo, tp, cam, _ = files
    short = tmp_path / "std.txt"
    np.savetxt(short, _std_rows(np.linspace(0.0, 5.0, 6), [40.0, 30.0, 90.0]))
    out = tmp_path / "r.csv"
    assert main(["refine", eo, tp, "--camera", cam, "--method", "known-base", "--datum",
                 "none", "-o", str(out), "--ins-std", str(short)]) == 2
    err = capsys.readouterr().err
    assert "std.txt" in err and "outside the sigma file" in err and not out.exists()


def test_sigma_file_ignored_when_the_boresight_is_not_estimated(files, tmp_path):
    """--datum first ties the attitudes to the INS: no boresight, so a sigma file that does
    not cover the exposures is not read (it stopped refine with exit 2 before)."""
    d, eo, tp, cam, _ = files
    short = tmp_path / "std.txt"
    np.savetxt(short, _std_rows(np.linspace(0.0, 5.0, 6), [40.0, 30.0, 90.0]))
    out = tmp_path / "r.csv"
    assert main(["refine", eo, tp, "--camera", cam, "--datum", "first", "-o", str(out),
                 "--ins-std", str(short), "-q"]) == 0
    meta = read_eo_header(out)
    assert "boresight_sigma_total_deg" not in meta
