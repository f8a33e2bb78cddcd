"""Tiled refinement of one block (photogrammetry.adjustment.tiling): the partition, the datum rule,
and on a simulated 500-image block with known truth the tiled angles against the
whole-block adjustment and both against the truth; the combined boresight against the
simulated one; the CLI; the Dask path equal to the in-process one; a tile's flag."""
from collections import deque

import numpy as np
import pytest
import scenario as sc

from ins.common.errors import InputError, QualityError
from photogrammetry.adjustment.batch import refine
from photogrammetry.adjustment.tiling import partition, refine_tiled, tile_tasks
from photogrammetry.cli.main import main
from photogrammetry.imagery.tiepoints import read_tiepoints
from photogrammetry.orientation.camera import read_camera
from photogrammetry.orientation.exposure import read_eo_csv
from photogrammetry.orientation.rotation import angles_to_matrix


def _bfs_hops(pairs, m, start, hops):
    """Images within `hops` pair-hops of `start` (plain breadth-first search)."""
    nb = [[] for _ in range(m)]
    for i, j in pairs:
        nb[i].append(j)
        nb[j].append(i)
    dist = {int(i): 0 for i in start}
    q = deque(dist)
    while q:
        i = q.popleft()
        if dist[i] == hops:
            continue
        for j in nb[i]:
            if j not in dist:
                dist[j] = dist[i] + 1
                q.append(j)
    return set(dist)


@pytest.fixture(scope="module")
def small():
    """A 240-image block (5 strips of 50, the last shorter) as files, read back."""
    import tempfile
    B = sc.make_large_block(240, seed=5)
    d = tempfile.mkdtemp(prefix="tiling_")
    eo, tp, cam = sc.write_block_files(B, d)
    camera, _ = read_camera(cam)
    return B, read_eo_csv(eo), read_tiepoints(tp, camera), camera, (eo, tp, cam)


def test_partition_cores_once_halo_by_hops_deterministic(small):
    B = small[0]
    pos, pairs = B["positions"], B["pairs"]
    m = len(pos)
    tiles = partition(pos, pairs, 70, halo_hops=2)
    assert len(tiles) == -(-m // 70)
    count = np.zeros(m, int)
    for t in tiles:
        count[t.images[t.core]] += 1
        assert t.n_core <= 70
        # halo: exactly the images within 2 pair-hops of the core (independent BFS)
        assert set(t.images.tolist()) == _bfs_hops(pairs, m, t.images[t.core], 2)
        # the tile's pairs: all pairs with both images inside, and every pair of a core
        # image is among them
        inside = np.isin(pairs[:, 0], t.images) & np.isin(pairs[:, 1], t.images)
        np.testing.assert_array_equal(t.pairs, np.flatnonzero(inside))
        touches = np.isin(pairs, t.images[t.core]).any(axis=1)
        assert set(np.flatnonzero(touches)) <= set(t.pairs.tolist())
    np.testing.assert_array_equal(count, 1)             # every image core exactly once
    again = partition(pos, pairs, 70, halo_hops=2)
    for a, b in zip(tiles, again):
        np.testing.assert_array_equal(a.images, b.images)
        np.testing.assert_array_equal(a.core, b.core)
    # compact: fewer cut pairs than a partition of the same sizes in file order
    owner = np.empty(m, int)
    for t in tiles:
        owner[t.images[t.core]] = t.index
    cut = np.mean(owner[pairs[:, 0]] != owner[pairs[:, 1]])
    naive = np.repeat(np.arange(len(tiles)), [t.n_core for t in tiles])
    assert cut < 0.6 * np.mean(naive[pairs[:, 0]] != naive[pairs[:, 1]])
    # one tile holding everything, no halo
    (whole,) = partition(pos, pairs, m, halo_hops=0)
    assert whole.core.all() and len(whole.pairs) == len(pairs)
    with pytest.raises(InputError, match="tile-images"):
        partition(pos, pairs, 0)


def test_tasks_carry_only_their_tile(small):
    B, eo, tp, camera, _ = small
    pairs, points, ids = tp.pairs(list(eo.image_id), camera, min_common=3)
    tiles = partition(eo.position, pairs, 80)
    for t, task in zip(tiles, tile_tasks(tiles, eo, pairs, points, ids, camera.focal_length_mm,
                                          eo.system, "known-base", "none", 0.005, 0.005, None,
                                          True)):
        n = len(t.images)
        assert task["prior"].shape == (n, 3) and task["positions"].shape == (n, 3)
        assert len(task["pair_points"]) == len(t.pairs) == len(task["pairs"])
        assert task["pairs"].min() >= 0 and task["pairs"].max() < n
        np.testing.assert_array_equal(t.images[task["pairs"]], pairs[t.pairs])
        assert task["image_ids"] == [eo.image_id[i] for i in t.images]


def test_datum_first_refused(small):
    _, eo, tp, camera, _ = small
    with pytest.raises(InputError, match="datum first.*known-base --datum none.*datum ins"):
        refine_tiled(eo, tp, camera, tile_images=100, method="base-free", datum="first",
                     workers=1)
    with pytest.raises(InputError, match="datum none needs --method known-base"):
        refine_tiled(eo, tp, camera, tile_images=100, method="relative", datum="none",
                     workers=1)


@pytest.fixture(scope="module")
def block500():
    """500 images (10 strips of 50): whole-block and tiled (tiles of 150 core images)
    known-base refinements, datum none."""
    import tempfile
    import warnings
    B = sc.make_large_block(500, seed=3)
    d = tempfile.mkdtemp(prefix="tiling500_")
    eo, tp, cam = sc.write_block_files(B, d)
    camera, _ = read_camera(cam)
    E, T = read_eo_csv(eo), read_tiepoints(tp, camera)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole = refine(E, T, camera, method="known-base", datum="none")
        tiled = refine_tiled(E, T, camera, tile_images=150, method="known-base",
                             datum="none", workers=1)
    return B, whole, tiled


def _chi2_per_angle(B, res):
    err = sc.rotation_error(angles_to_matrix(res.block.angles, B["system"]),
                            angles_to_matrix(B["angles"], B["system"]))
    # the rotation error is in the model frame; the sigmas are per angle: compare the
    # angle differences (small angles, wrapped)
    d = np.angle(np.exp(1j * (res.block.angles - B["angles"])))
    assert np.max(np.abs(err)) < 1e-3
    return np.mean((d / res.block.sigma) ** 2, axis=0)


@pytest.mark.slow
def test_tiled_angles_agree_with_whole_block_and_truth(block500):
    B, whole, tiled = block500
    assert tiled.settings["n_tiles"] == 4
    for t, r in zip(tiled.tiles, tiled.tile_results):          # each image from its core
        np.testing.assert_array_equal(tiled.block.angles[t.images[t.core]], r.angles[t.core])
        np.testing.assert_array_equal(tiled.block.sigma[t.images[t.core]], r.sigma[t.core])
    assert not tiled.block.quality.poor and not whole.block.quality.poor
    assert tiled.block.adjusted.all()
    s = whole.block.sigma
    z = np.angle(np.exp(1j * (tiled.block.angles - whole.block.angles))) / s
    # the tiles miss only the pull of pairs beyond the halo (measured 0.09-0.20 sigma RMS,
    # 0.8 sigma at most, with 3 hops)
    assert np.all(np.sqrt(np.mean(z ** 2, axis=0)) < 0.3)
    assert np.max(np.abs(z)) < 1.2
    # the tiles' sigmas: about the whole block's, never smaller by more than rounding
    ratio = tiled.block.sigma / s
    assert np.all(ratio > 0.98) and np.all(np.median(ratio, axis=0) < 1.1)
    for res in (whole, tiled):
        chi = _chi2_per_angle(B, res)
        assert np.all((chi > 0.5) & (chi < 1.8)), chi


@pytest.mark.slow
def test_combined_assessment_against_simulation(block500):
    B, whole, tiled = block500
    a, w = tiled.assessment, whole.assessment
    assert a.boresight_observable
    assert a.used.all()
    err = (a.boresight - B["boresight"]) / a.boresight_sigma
    assert np.all(np.abs(err) < 3), err
    # the combined sigma is the whole block's (the INS noise dominates: ~s / sqrt(m))
    np.testing.assert_allclose(a.boresight_sigma, w.boresight_sigma, rtol=0.1)
    np.testing.assert_allclose(a.boresight_sigma, 0.005 / np.sqrt(500), rtol=0.15)
    # the INS noise against the injected one (0.005 rad) within 3 of its sigmas
    injected = np.std(B["ins_noise"], axis=0)
    assert np.all(np.abs(a.ins_noise - injected) < 3 * a.ins_noise_sigma + 1e-5)
    np.testing.assert_allclose(a.ins_noise, w.ins_noise, rtol=0.03)
    assert a.dof == sum(r.assessment.dof for r in tiled.tile_results)


@pytest.mark.slow
def test_dask_tiles_equal_in_process_and_cli(small, tmp_path):
    import warnings
    B, eo, tp, camera, (eo_p, tp_p, cam_p) = small
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        one = refine_tiled(eo, tp, camera, tile_images=100, datum="ins", workers=1)
        seen = []
        par = refine_tiled(eo, tp, camera, tile_images=100, datum="ins", workers=2,
                           processes=False, progress=lambda *a: seen.append(a))
    np.testing.assert_array_equal(one.block.angles, par.block.angles)
    np.testing.assert_array_equal(one.block.sigma, par.block.sigma)
    assert [s[0] for s in seen] == [1, 2, 3] and seen[-1][2:] == (240, 240)
    out, rep = tmp_path / "refined.csv", tmp_path / "report.md"
    code = main(["refine", eo_p, tp_p, "--camera", cam_p, "--method", "known-base",
                 "--datum", "ins", "--tile-images", "100", "--workers", "1", "-q",
                 "-o", str(out), "--report", str(rep)])
    assert code == 0
    got = read_eo_csv(str(out))
    assert "# tiled: 3 tiles of <= 100 core images, halo 3 pair-hops" in out.read_text()
    np.testing.assert_allclose(got.angles, np.angle(np.exp(1j * one.block.angles)),
                               atol=1e-8)
    assert "sigma0" in rep.read_text()
    assert "adjusted in **3 tiles** of at most 100 core images" in rep.read_text()
    assert main(["refine", eo_p, tp_p, "--camera", cam_p, "--datum", "first",
                 "--tile-images", "100", "--workers", "1", "-q",
                 "-o", str(tmp_path / "x.csv")]) == 2
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.slow
def test_tile_flag_carried_once(small):
    """An image whose INS prior is 3 deg off is flagged by the tile where it is core
    (once, named), the result is poor: QualityError unless accept_poor."""
    import warnings
    from dataclasses import replace
    B, eo, tp, camera, _ = small
    tiles = partition(eo.position, tp.pairs(list(eo.image_id), camera, 3)[0], 100)
    # an image in the halo of another tile
    halo_any = set()
    for t in tiles:
        halo_any |= set(t.images[~t.core].tolist())
    k = sorted(halo_any)[len(halo_any) // 2]
    angles = eo.angles.copy()
    angles[k, 0] += np.deg2rad(3.0)
    bad = replace(eo, angles=angles)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(QualityError, match="tile"):
            refine_tiled(bad, tp, camera, tile_images=100, workers=1)
        res = refine_tiled(bad, tp, camera, tile_images=100, workers=1, accept_poor=True)
    q = res.block.quality
    assert q.poor
    name = eo.image_id[k]
    mine = [r for r in q.reasons if f"image {name}:" in r]
    assert len(mine) == 1 and mine[0].startswith("tile ")
    assert q.image_flags[k] and q.image_flags.sum() == 1


def test_dense_tiles_exact_core_covariance(tmp_path):
    """Small tiles (dense algebra: the exact covariance of the core images in the
    assessment): the tiled block against the whole one and the simulated boresight."""
    import warnings
    B = sc.make_block(n_strips=4, n_per_strip=12, seed=12)
    eo_p, tp_p, cam_p = sc.write_block_files(B, str(tmp_path))
    camera, _ = read_camera(cam_p)
    eo, tp = read_eo_csv(eo_p), read_tiepoints(tp_p, camera)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole = refine(eo, tp, camera, method="known-base", datum="none")
        tiled = refine_tiled(eo, tp, camera, tile_images=16, halo_hops=3, workers=1)
    assert tiled.settings["n_tiles"] == 3
    assert all(len(t.images) < 100 for t in tiled.tiles)     # dense tiles
    assert all(r.assessment.used.sum() == t.n_core for t, r in zip(tiled.tiles,
                                                                     tiled.tile_results))
    z = np.angle(np.exp(1j * (tiled.block.angles - whole.block.angles))) / whole.block.sigma
    assert np.all(np.sqrt(np.mean(z ** 2, axis=0)) < 0.5) and np.max(np.abs(z)) < 2.0
    a = tiled.assessment
    err = (a.boresight - B["boresight"]) / a.boresight_sigma
    assert np.all(np.abs(err) < 3), err
    np.testing.assert_allclose(a.boresight_sigma, whole.assessment.boresight_sigma, rtol=0.15)
    # the combined sigma is the inverse-variance one of the tiles'
    s = np.array([r.assessment.boresight_sigma for r in tiled.tile_results])
    np.testing.assert_allclose(a.boresight_sigma, 1 / np.sqrt(np.sum(s ** -2, axis=0)))


def test_warnings_once_in_block_names(small):
    """A pair left out is warned of once (by the tile of its first image), named by the
    block's image ids, and the same pairs as in the whole block."""
    import re
    import warnings
    B, eo, tp, camera, _ = small
    with warnings.catch_warnings(record=True) as whole_w:
        warnings.simplefilter("always")
        refine(eo, tp, camera, method="known-base", datum="none", accept_poor=True)
    with warnings.catch_warnings(record=True) as tiled_w:
        warnings.simplefilter("always")
        refine_tiled(eo, tp, camera, tile_images=80, workers=1, accept_poor=True)
    whole = {(eo.image_id[int(a)], eo.image_id[int(b)]) for a, b in
             (re.match(r"pair (\d+)-(\d+) left out", str(w.message)).groups()
              for w in whole_w if re.match(r"pair \d+-\d+ left out", str(w.message)))}
    texts = [str(w.message) for w in tiled_w if str(w.message).startswith("pair ")]
    tiled = [re.match(r"pair (\S+)-(\S+) left out", t).groups() for t in texts]
    assert len(whole) > 0
    assert len(tiled) == len(set(tiled))                       # once each
    assert set(tiled) == whole


def test_one_tile_is_the_whole_block(small):
    """A tile as large as the block (no halo): the block adjustment and assessment of
    refine itself."""
    import warnings
    B, eo, tp, camera, _ = small
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole = refine(eo, tp, camera, method="known-base", datum="none")
        one = refine_tiled(eo, tp, camera, tile_images=len(eo), workers=1)
    assert one.settings["n_tiles"] == 1
    np.testing.assert_array_equal(one.block.angles, whole.block.angles)
    np.testing.assert_array_equal(one.block.sigma, whole.block.sigma)
    np.testing.assert_allclose(one.assessment.boresight, whole.assessment.boresight,
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(one.assessment.ins_noise, whole.assessment.ins_noise,
                               rtol=1e-9)
