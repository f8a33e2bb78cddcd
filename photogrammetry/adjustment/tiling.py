"""Tiled refinement of ONE large block: tiles of about N images adjusted as Dask tasks.

A block of many thousand images does not fit one small worker (5000 images in one
process: 0.67 GB known-base, 1.75 GB base-free; ``bench/bench_block_scale.py``).  :func:`refine_tiled` cuts it into tiles and adjusts
each tile on its own (:func:`photogrammetry.adjustment.block.adjust_block`, a Dask task through
:func:`ins.common.dask_tasks.map_tasks`); a worker receives only its tile's data (priors,
positions, the pairs inside the tile and their points), never the whole block.

Partition (:func:`partition`, deterministic): the images are split by recursive
coordinate bisection of their EO positions (x, y of the mapping frame): the set is cut
across its longer horizontal extent, in the proportion of the number of tiles each side
receives, until every part has at most ``tile_images`` images.  The parts are the tiles'
CORE images (every image is core in exactly one tile; compact tiles cut few pairs).
Each tile adds a HALO: the images within ``halo_hops`` pair-hops of its core in the
block's pair graph (an edge per pair of images sharing enough tie points).  The tile
holds every pair whose two images are in it.  Rule of the default (3 hops): every core
image keeps all of its pairs (hop 1), its partners keep theirs (hop 2), and one more
ring (hop 3) keeps the partners' partners off the tile's edge.  The pull of the block
beyond the halo decays with the hops (known-base, 3000 images, tiles of 1000 cut between
strips: tiled minus whole 0.7 of the whole block's sigma RMS on the strips next to the
cut, 0.25 three hops in, 0.05 from six on; the tiles' own sigmas there are 1.2 times the
whole block's, so the tiled angles stay consistent with the truth: precision is lost,
not accuracy; docs/interfaces.md).  Each image
takes its angles, sigmas and 3x3 covariance from the tile where it is core; each pair
its status, rejected points and residuals from the tile where its first image is core.

Datum: tiles are independent only when each tile's orientation is fixed by data that
are not shared: ``known-base`` with datum ``none`` (the GNSS bases) or datum ``ins``
(every image's INS angles weighted).  Datum ``first`` (one known image) would leave all
tiles but one without a datum: refused (:class:`ins.common.errors.InputError`).

What is lost by tiling: (1) the information beyond the halo: a core image's angles miss
the pull of pairs more than ``halo_hops`` hops away (through the chain of relative
orientations; with INS priors, the common rotation of each tile is set by the priors of
its own images only, not of the whole block); (2) the correlation across tile borders:
the assembled covariance is per tile (the 3x3 block of every image, no covariance
between images of different tiles; ``BlockResult.cov`` is None and ``cov_op`` carries
the per-image blocks only); (3) the assessment is combined from the tiles (below).

INS assessment of the whole block from the tiles: each tile is assessed
(:func:`photogrammetry.adjustment.assessment.assess`) on its CORE images only.  A dense tile
(below :data:`photogrammetry.adjustment.block.BANDED_MIN_ANGLES` angles) uses the exact covariance
of its core images; a banded tile the per-image 3x3 blocks (the adjustment's
correlation between images is neglected in the weights: small when the INS noise is
well above the adjustment's sigma, as for a navigation-grade INS at block scale).  The
tiles' estimates are then combined as independent (their core images are disjoint; the
halo data they share and the adjustment's correlation across borders are neglected):
boresight and GLS mean per component by inverse variance, the INS noise variance per
angle by inverse variance of the tiles' signed REML estimates, the covariance factor
likewise; mean and RMS are those of the assembled differences.

Quality: each tile's flags are carried (prefixed with the tile), an image's flag only
from the tile where it is core; the result is poor if any tile is; the block sigma0
shown is the tiles' pooled one (``sqrt(sum r_t s0_t^2 / sum r_t)``) and the redundancy
the sum of the tiles' (halo conditions count in every tile that holds them).
"""
import re
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import sparse

from ins.common.errors import InputError
from ins.nav.rotation import wrap_to_pi
from photogrammetry.adjustment.assessment import Assessment, assess
from photogrammetry.adjustment.batch import (
    RefineResult,
    check_quality,
    map_tasks,
    prepare,
    refined_eo_and_settings,
)
from photogrammetry.adjustment.block import BlockResult, adjust_block
from photogrammetry.adjustment.block_covariance import banded_covariance
from photogrammetry.adjustment.quality import Quality

__all__ = ["Tile", "TileResult", "TiledRefineResult", "partition", "adjust_tile", "tile_tasks",
           "refine_tiled", "check_tiled_datum", "core_assessment", "assemble_block",
           "combine_assessments", "DEFAULT_HALO_HOPS"]

_PAIR_WARNING = re.compile(r"^pair (\d+)-(\d+)")
_IMAGE_WARNING = re.compile(r"^image (\d+)")
#: Pair-hops of the halo around a tile's core (every core image keeps its pairs and its
#: partners theirs).
DEFAULT_HALO_HOPS = 3


@dataclass
class Tile:
    """One tile of a block.

    Attributes
    ----------
    index : int
    images : ndarray of int (n_t,)
        Block indices of the tile's images (core and halo), ascending.
    core : ndarray of bool (n_t,)
        The tile's core images among `images`.
    pairs : ndarray of int (P_t,)
        Block indices of the pairs with both images in the tile.
    """
    index: int
    images: np.ndarray
    core: np.ndarray
    pairs: np.ndarray

    @property
    def n_core(self):
        return int(self.core.sum())


def _bisect(xy, idx, n_tiles, out):
    """Recursive coordinate bisection of the images `idx` into `n_tiles` parts."""
    if n_tiles <= 1:
        out.append(np.sort(idx))
        return
    p = xy[idx]
    axis = 0 if np.ptp(p[:, 0]) >= np.ptp(p[:, 1]) else 1
    order = idx[np.lexsort((idx, p[:, axis]))]          # ties broken by index
    left = n_tiles // 2
    cut = int(round(len(idx) * left / n_tiles))
    _bisect(xy, order[:cut], left, out)
    _bisect(xy, order[cut:], n_tiles - left, out)


def _adjacency(pairs, m):
    """Sparse symmetric pair graph of `m` images."""
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    ones = np.ones(len(pairs), dtype=np.int8)
    A = sparse.coo_matrix((ones, (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    return sparse.csr_matrix(A + A.T)


def partition(positions, pairs, tile_images, halo_hops=DEFAULT_HALO_HOPS):
    """Tiles of about `tile_images` core images, each with its halo.

    Parameters
    ----------
    positions : array_like (m, 3)
        EO positions in the mapping frame, m (x, y used).
    pairs : array_like of int (P, 2)
        The block's pairs (image indices).
    tile_images : int
        Largest number of core images per tile (>= 1).
    halo_hops : int
        Pair-hops of the halo (>= 0).

    Returns
    -------
    list of Tile
        ``ceil(m / tile_images)`` tiles of nearly equal core size; every image is core
        in exactly one of them.
    """
    xy = np.asarray(positions, dtype=float)[:, :2]
    m = len(xy)
    if int(tile_images) < 1:
        raise InputError(f"--tile-images must be >= 1 image, got {tile_images}")
    if int(halo_hops) < 0:
        raise InputError(f"the halo must be >= 0 pair-hops, got {halo_hops}")
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    cores = []
    _bisect(xy, np.arange(m), -(-m // int(tile_images)), cores)
    A = _adjacency(pairs, m)
    tiles = []
    for t, core_idx in enumerate(cores):
        member = np.zeros(m, bool)
        member[core_idx] = True
        front = member.copy()
        for _ in range(int(halo_hops)):
            reach = (A @ front.astype(np.int8)) > 0
            front = reach & ~member
            if not front.any():
                break
            member |= front
        images = np.flatnonzero(member)
        core = np.isin(images, core_idx)
        inside = member[pairs[:, 0]] & member[pairs[:, 1]] if len(pairs) else np.zeros(0, bool)
        tiles.append(Tile(t, images, core, np.flatnonzero(inside)))
    return tiles


@dataclass
class TileResult:
    """What a tile's task sends back (its arrays in the tile's own order).

    Attributes
    ----------
    index : int
    angles, sigma : ndarray (n_t, 3)
        Rad.
    cov_blocks : ndarray (n_t, 3, 3)
        Rad^2.
    adjusted : ndarray of bool (n_t,)
    sigma0 : float; redundancy, iterations : int; converged : bool
    pair_status : ndarray of int (P_t,)
    rejected, residuals, mask : ndarray (P_t, n_t_max)
    quality : photogrammetry.adjustment.quality.Quality
    assessment : photogrammetry.adjustment.assessment.Assessment
        On the tile's core images only.
    warnings : list of (category, str)
    """
    index: int
    angles: np.ndarray
    sigma: np.ndarray
    cov_blocks: np.ndarray
    adjusted: np.ndarray
    sigma0: float
    redundancy: int
    iterations: int
    converged: bool
    pair_status: np.ndarray
    rejected: np.ndarray
    residuals: np.ndarray
    mask: np.ndarray
    quality: object
    assessment: object
    warnings: list = field(default_factory=list)


def _blockdiag_cov(blocks, free):
    """A covariance operator holding only the per-image 3x3 `blocks` of the `free`
    images (no correlation between images)."""
    k = len(blocks)
    inv = np.linalg.inv(blocks) if k else np.zeros((0, 3, 3))
    rows = (3 * np.arange(k)[:, None, None] + np.arange(3)[None, :, None]
            + np.zeros((1, 1, 3), int))
    cols = np.swapaxes(rows, 1, 2)
    H = sparse.csr_matrix((inv.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * k, 3 * k))
    op = banded_covariance(H, 1.0, np.asarray(free, bool))
    op.blocks = np.array(blocks, dtype=float)       # exact (not re-derived from H)
    return op


def core_assessment(block, prior, core, system, datum, method):
    """:func:`photogrammetry.adjustment.assessment.assess` of a tile on its core images only.

    A dense tile: the exact covariance of the core images; a banded tile: their 3x3
    blocks (correlation between images neglected in the weights); a tile without halo
    (the whole block): :func:`~photogrammetry.adjustment.assessment.assess` itself."""
    keep = np.asarray(core, bool) & block.adjusted
    if np.array_equal(keep, block.adjusted):            # no halo: the exact assessment
        return assess(block, prior, system, datum, method)
    if block.cov is not None:
        return assess(replace(block, adjusted=keep), prior, system, datum, method)
    free = keep & (block.sigma.max(axis=1) > 0)
    op = _blockdiag_cov(block.cov_blocks()[free], free)
    return assess(replace(block, adjusted=free, cov_op=op), prior, system, datum, method)


def _tile_warning(text, names, core, index):
    """A tile's warning in the block's image names, or None when it concerns a pair or
    an image that another tile owns (the tile where the pair's first image, or the
    image, is core warns of it)."""
    hit = _PAIR_WARNING.match(text)
    if hit:
        i, j = int(hit.group(1)), int(hit.group(2))
        if not core[i]:
            return None
        return f"pair {names[i]}-{names[j]}" + text[hit.end():]
    hit = _IMAGE_WARNING.match(text)
    if hit:
        i = int(hit.group(1))
        return None if not core[i] else f"image {names[i]}" + text[hit.end():]
    return f"tile {index}: {text}"


def adjust_tile(index, prior, pairs, pair_points, point_ids, core, f_mm, system, method,
                datum, positions=None, prior_sigma=None, sigma_mm=0.005,
                position_sigma=None, snooping=True, image_ids=None):
    """Adjust one tile and assess it on its core images (the task of :func:`refine_tiled`).

    Parameters as :func:`photogrammetry.adjustment.block.adjust_block`, all in the tile's own image
    order (`pairs` index the tile's images); `core` (n_t,) bool marks its core images.

    Returns
    -------
    TileResult
    """
    names = [str(i) for i in range(len(prior))] if image_ids is None else list(image_ids)
    core = np.asarray(core, bool)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        block = adjust_block(prior, pairs, pair_points, f_mm, system, method, datum,
                             positions=positions, prior_sigma=prior_sigma,
                             sigma_mm=sigma_mm, position_sigma=position_sigma,
                             point_ids=point_ids, snooping=snooping, image_ids=names)
    for w in caught:
        text = _tile_warning(str(w.message), names, core, index)
        if text is not None:
            warnings.warn(text, w.category, stacklevel=2)
    a = core_assessment(block, prior, core, system, datum, method)
    return TileResult(index, block.angles, block.sigma, block.cov_blocks(), block.adjusted,
                      block.sigma0, block.redundancy, block.iterations, block.converged,
                      block.pair_status, block.rejected, block.residuals, block.mask,
                      block.quality, a)


def tile_tasks(tiles, eo, pairs, points, point_ids, f_mm, system, method, datum,
                prior_sigma, sigma_mm, position_sigma, snooping):
    """One task (keyword arguments of :func:`adjust_tile`) per tile: its data only."""
    m = len(eo)
    ps = np.broadcast_to(np.asarray(prior_sigma, float), (m, 3))
    pos_s = (None if position_sigma is None
             else np.broadcast_to(np.asarray(position_sigma, float), (m, 3)))
    local = np.full(m, -1)
    for t in tiles:
        local[t.images] = np.arange(len(t.images))
        yield {"index": t.index, "prior": eo.angles[t.images].copy(),
               "pairs": local[pairs[t.pairs]], "pair_points": [points[k] for k in t.pairs],
               "point_ids": [point_ids[k] for k in t.pairs], "core": t.core.copy(),
               "f_mm": f_mm, "system": system, "method": method, "datum": datum,
               "positions": eo.position[t.images].copy(), "prior_sigma": ps[t.images].copy(),
               "sigma_mm": sigma_mm,
               "position_sigma": None if pos_s is None else pos_s[t.images].copy(),
               "snooping": snooping, "image_ids": [eo.image_id[i] for i in t.images]}
        local[t.images] = -1


def check_tiled_datum(method, datum):
    """Refuse a datum that tiles cannot share (InputError naming the alternatives)."""
    if datum == "first":
        raise InputError("--tile-images: --datum first fixes only the first image, so every "
                         "tile but one would have no datum; use --method known-base "
                         "--datum none (GNSS bases orient each tile) or --datum ins (the INS "
                         "angles of each tile's images)")
    if datum == "none" and method != "known-base":
        raise InputError("--datum none needs --method known-base (the bases orient the block)")


def refine_tiled(eo, tiepoints, camera=None, tile_images=1000, halo_hops=DEFAULT_HALO_HOPS,
                 system=None, method="known-base", datum="none", sigma_mm=None,
                 prior_sigma_rad=None, position_sigma_m=None, snooping=True,
                 accept_poor=False, workers=None, scheduler=None, progress=None,
                 processes=True):
    """Refine the angles of one block in tiles (see the module's docstring).

    Parameters
    ----------
    eo, tiepoints, camera, system, method, sigma_mm, prior_sigma_rad, position_sigma_m,
    snooping, accept_poor
        As :func:`photogrammetry.adjustment.batch.refine`.
    datum : {"none", "ins"}
        ``"first"`` is refused (InputError).
    tile_images : int
        Largest number of core images per tile.
    halo_hops : int
        Pair-hops of each tile's halo.
    workers, scheduler, processes
        As :func:`photogrammetry.adjustment.batch.refine_many` (``workers=1``: in this process).
    progress : callable(tiles_done, n_tiles, images_done, n_images), optional

    Returns
    -------
    TiledRefineResult
        Like :class:`photogrammetry.adjustment.batch.RefineResult` (refined EO, assembled block,
        combined assessment, the block's pairs), plus the tiles and their results.

    Raises
    ------
    ins.common.errors.InputError
        Datum first, a bad tile size or halo.
    ins.common.errors.QualityError
        A tile's result is flagged (without `accept_poor`).
    """
    check_tiled_datum(method, datum)
    eo, sigma_mm, prior_sigma_rad, position_sigma_m, pairs, points, point_ids = prepare(
        eo, tiepoints, camera, system, method, sigma_mm, prior_sigma_rad, position_sigma_m)
    system = eo.system
    tiles = partition(eo.position, pairs, tile_images, halo_hops)
    tasks = tile_tasks(tiles, eo, pairs, points, point_ids, camera.focal_length_mm, system,
                        method, datum, prior_sigma_rad, sigma_mm, position_sigma_m, snooping)
    n_core = [t.n_core for t in tiles]
    done_images = [0]

    def note(done, total, k):
        done_images[0] += n_core[k]
        if progress is not None:
            progress(done, total, done_images[0], len(eo))
    results = map_tasks(adjust_tile, tasks, workers, scheduler, note, processes,
                        total=len(tiles))
    block = assemble_block(tiles, results, eo, pairs, points)
    check_quality(block.quality, accept_poor)
    assessment = combine_assessments(tiles, results, eo.angles, block, system)
    result_eo, settings = refined_eo_and_settings(eo, block, camera, method, datum, sigma_mm,
                                                  snooping, position_sigma_m, pairs, tiepoints)
    settings.update({"tile_images": int(tile_images), "halo_hops": int(halo_hops),
                     "n_tiles": len(tiles), "tile_sizes": [len(t.images) for t in tiles]})
    out = TiledRefineResult(result_eo, eo, block, assessment, pairs, points, settings,
                            tiles=tiles, tile_results=results)
    return out


@dataclass
class TiledRefineResult(RefineResult):
    """:class:`photogrammetry.adjustment.batch.RefineResult` of a tiled block, with its tiles.

    Attributes
    ----------
    tiles : list of Tile
    tile_results : list of TileResult
    """
    tiles: list = None
    tile_results: list = None


def _owner(tiles, m):
    """Per image: (tile, position in the tile) of the tile where it is core."""
    tile_of, pos_of = np.full(m, -1), np.full(m, -1)
    for t in tiles:
        tile_of[t.images[t.core]] = t.index
        pos_of[t.images[t.core]] = np.flatnonzero(t.core)
    return tile_of, pos_of


def assemble_block(tiles, results, eo, pairs, points):
    """The block's BlockResult from its tiles' (each image from its core tile)."""
    m, P = len(eo), len(pairs)
    tile_of, pos_of = _owner(tiles, m)
    angles, sigma = np.zeros((m, 3)), np.zeros((m, 3))
    blocks, adjusted = np.zeros((m, 3, 3)), np.zeros(m, bool)
    for t, r in zip(tiles, results):
        g, loc = t.images[t.core], np.flatnonzero(t.core)
        angles[g], sigma[g], blocks[g] = r.angles[loc], r.sigma[loc], r.cov_blocks[loc]
        adjusted[g] = r.adjusted[loc]
    n_max = max([len(a) for a, _ in points] + [1])
    status = np.zeros(P, dtype=int)
    rejected, mask = np.zeros((P, n_max), bool), np.zeros((P, n_max), bool)
    residuals = np.zeros((P, n_max))
    pair_flags = np.zeros(P, bool)
    pair_tile = tile_of[pairs[:, 0]]
    for t, r in zip(tiles, results):
        mine = pair_tile[t.pairs] == t.index           # this tile's rows of its pairs
        g = t.pairs[mine]
        w = r.mask.shape[1]
        status[g] = r.pair_status[mine]
        rejected[g, :w], mask[g, :w] = r.rejected[mine], r.mask[mine]
        residuals[g, :w] = r.residuals[mine]
        if r.quality is not None and r.quality.pair_flags is not None:
            pair_flags[g] = r.quality.pair_flags[mine]
    quality = _assemble_quality(tiles, results, eo.image_id, adjusted, pair_flags)
    red = np.array([r.redundancy for r in results], float)
    s0 = np.array([r.sigma0 for r in results])
    sigma0 = float(np.sqrt(np.sum(red * s0 ** 2) / max(np.sum(red), 1)))
    free = adjusted & (sigma.max(axis=1) > 0)
    op = _blockdiag_cov(blocks[free], free)
    return BlockResult(angles, None, sigma, sigma0, int(red.sum()),
                       max(r.iterations for r in results), all(r.converged for r in results),
                       adjusted, status, rejected, residuals, mask, quality, op)


def _assemble_quality(tiles, results, names, adjusted, pair_flags):
    """Every tile's flags (an image's only from its core tile), deduplicated."""
    reasons, seen = [], set()
    image_flags = np.zeros(len(names), bool)
    limit = np.nan
    for t, r in zip(tiles, results):
        q = r.quality
        if q is None:
            continue
        if np.isfinite(q.sigma0_limit) and not q.sigma0_limit <= limit:
            limit = q.sigma0_limit                  # the largest of the tiles'
        halo_names = {f"image {names[i]}:" for i in t.images[~t.core]}
        if q.image_flags is not None:
            image_flags[t.images[t.core]] |= q.image_flags[t.core]
        for text in q.reasons:
            if any(text.startswith(h) for h in halo_names if text.startswith("image ")):
                continue                        # judged in the tile where it is core
            if text.startswith("block sigma0"):
                text = text.replace("block sigma0", f"tile {t.index} sigma0", 1)
            if text not in seen:
                seen.add(text)
                reasons.append(f"tile {t.index}: {text}" if not text.startswith("tile ")
                               else text)
    return Quality(bool(reasons), reasons, pair_flags, image_flags & adjusted, float(limit))


def _inverse_variance(values, sigmas):
    """Per component: the inverse-variance mean and its sigma (NaN without data)."""
    v, s = np.asarray(values, float), np.asarray(sigmas, float)
    ok = np.isfinite(v) & np.isfinite(s) & (s > 0)
    w = np.where(ok, 1.0 / np.where(ok, s, 1.0) ** 2, 0.0)
    tot = w.sum(axis=0)
    mean = np.where(tot > 0, np.sum(w * np.where(ok, v, 0.0), axis=0)
                    / np.where(tot > 0, tot, 1.0), np.nan)
    return mean, np.where(tot > 0, 1.0 / np.sqrt(np.where(tot > 0, tot, 1.0)), np.nan)


def combine_assessments(tiles, results, angles_ins, block, system):
    """The block's INS assessment from its tiles' core assessments (module docstring).

    Parameters
    ----------
    tiles : list of Tile
    results : list of TileResult
    angles_ins : ndarray (m, 3)
        INS angles, rad.
    block : BlockResult
        The assembled block (:func:`assemble_block`).
    system : str

    Returns
    -------
    photogrammetry.adjustment.assessment.Assessment
    """
    m = len(angles_ins)
    A = [r.assessment for r in results]
    used = np.zeros(m, bool)
    for t, a in zip(tiles, A):
        used[t.images[a.used]] = True
    diff = np.where(used[:, None], wrap_to_pi(np.asarray(angles_ins, float) - block.angles),
                    0.0)
    d = diff[used]
    k = len(d)
    kt = np.array([a.used.sum() for a in A], float)
    z3 = np.zeros(3)
    mean = d.mean(axis=0) if k else z3
    rms = np.sqrt(np.mean(d ** 2, axis=0)) if k else z3
    mean_sigma = (np.sqrt(np.sum((kt[:, None] * np.array([a.mean_sigma for a in A])) ** 2,
                                 axis=0)) / k if k else z3)
    gls_mean, gls_mean_sigma = _inverse_variance([a.gls_mean for a in A],
                                                 [a.gls_mean_sigma for a in A])
    observable = all(a.boresight_observable for a in A)
    if observable:
        boresight, boresight_sigma = _inverse_variance([a.boresight for a in A],
                                                       [a.boresight_sigma for a in A])
    else:
        boresight, boresight_sigma = z3.copy(), z3.copy()
    # the INS noise: the tiles' signed variance components, by inverse variance
    var = np.array([a.ins_noise_var if a.ins_noise_var is not None else a.ins_noise ** 2
                    for a in A])
    noise = np.array([a.ins_noise for a in A])
    nsig = np.array([a.ins_noise_sigma for a in A])
    var_sigma = np.where(np.isfinite(noise) & (noise > 0), 2 * noise * nsig, nsig ** 2)
    theta, theta_sigma = _inverse_variance(var, var_sigma)
    negative = ~(theta >= 0)
    ins_noise = np.where(negative, np.nan, np.sqrt(np.abs(theta)))
    pos = ins_noise > 0
    ins_noise_sigma = np.where(pos, theta_sigma / (2 * np.where(pos, ins_noise, 1.0)),
                               np.sqrt(theta_sigma))
    lam_t = np.array([a.cov_factor for a in A])
    lam_s = np.array([a.cov_factor_sigma for a in A])
    if np.any(lam_s > 0):
        lam, lam_sigma = _inverse_variance(lam_t, lam_s)
    else:
        lam, lam_sigma = 1.0, 0.0
    rr = np.array([a.residual_rms for a in A])
    residual_rms = (np.sqrt(np.sum(kt[:, None] * rr ** 2, axis=0) / max(kt.sum(), 1))
                    if k else z3)
    adj = np.sqrt(np.mean(block.sigma[used] ** 2, axis=0)) if k else z3
    blocks = block.cov_blocks()
    s = np.sqrt(np.einsum("mii->mi", blocks))
    inv = np.where(s > 0, 1.0 / np.where(s > 0, s, 1.0), 0.0)
    corr = blocks * inv[:, :, None] * inv[:, None, :]
    return Assessment(
        names=tuple(system.split("-")), used=used, diff=diff, mean=mean,
        mean_sigma=mean_sigma, gls_mean=gls_mean, gls_mean_sigma=gls_mean_sigma, rms=rms,
        boresight=boresight, boresight_sigma=boresight_sigma, boresight_observable=observable,
        ins_noise=ins_noise, ins_noise_sigma=ins_noise_sigma, residual_rms=residual_rms,
        adj_sigma_rms=adj, chi2=float(sum(a.chi2 for a in A)), dof=int(sum(a.dof for a in A)),
        cov_factor=float(lam), cov_factor_sigma=float(lam_sigma), correlations=corr,
        ins_noise_var=theta, ins_noise_negative=negative,
        boresight_iterations=max(a.boresight_iterations for a in A))
