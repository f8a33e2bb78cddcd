"""Tie points from images and their prior exterior orientation.

The steps (each in its module): read every image at a reduced level in bounded memory
(:mod:`photogrammetry.imagery.images`), detect SIFT features on tiles (:mod:`.features`), choose
the overlapping pairs from the prior footprints on the ground, match each pair inside
the epipolar bands of the prior, verify with an essential matrix and join the matches
into tracks (:mod:`.matching`).  The observations are the keypoints' photo coordinates in
mm through the camera model (observed, i.e. distorted, as the tie-point CSV holds them);
the image ids are the EO's.

The ground is given as a height ``z_m`` of the mapping frame and a relief ``relief_m``
(the band runs over ``z_m - relief_m .. z_m + relief_m``), or from a DEM
(:func:`dem_height_range`).
"""
import os
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from photogrammetry.imagery.feature_cache import FeatureStore, feature_key
from photogrammetry.imagery.features import detect_features
from photogrammetry.imagery.images import image_size, read_grey
from photogrammetry.imagery.matching import (
    PairMatches,
    PriorView,
    band_tolerance_mm,
    build_tracks,
    guided_matches,
    ideal_photo_mm,
    select_pairs,
    verify_pair,
)

__all__ = ["ImageTiePoints", "MatchSettings", "match_images", "image_ids_of",
           "dem_height_range"]


@dataclass(frozen=True)
class MatchSettings:
    """Options of :func:`match_images` (units in the names).

    max_side_px : longer side of the level the features are found on (px)
    max_features : keypoints per image
    angle_sigma_rad, position_sigma_m : prior sigmas when the EO has none
    n_sigma : width of the epipolar band in sigmas
    ratio : Lowe's ratio test
    min_overlap : smallest footprint overlap of a pair (fraction of the frame)
    min_inliers : fewest verified matches of a pair kept
    ransac_px : MAGSAC threshold in level pixels
    """
    max_side_px: int = 3000
    max_features: int = 4000
    angle_sigma_rad: float = np.deg2rad(1.0)
    position_sigma_m: float = 1.0
    n_sigma: float = 3.0
    ratio: float = 0.8
    min_overlap: float = 0.1
    min_inliers: int = 15
    ransac_px: float = 1.5


@dataclass
class ImageTiePoints:
    """Result of :func:`match_images`.

    Attributes
    ----------
    image_id, point_id : list of str (k,)
    xy_mm : ndarray (k, 2)
        Observed photo coordinates, mm.
    sigma_px : float
        Photo-coordinate sigma estimated from the verified matches (full-frame px).
    pairs : list of dict
        Per pair: ``i``, ``j`` (image ids), ``overlap``, ``candidates``, ``guided``,
        ``inliers``, ``kept``.
    n_features : list of int
    n_tracks : int
    n_conflicting : int
    track_lengths : ndarray
        Images per track.
    """
    image_id: list
    point_id: list
    xy_mm: np.ndarray
    sigma_px: float
    pairs: list
    n_features: list
    n_tracks: int
    n_conflicting: int
    track_lengths: np.ndarray


def image_ids_of(paths, eo_ids, eo_path="the EO file"):
    """The EO id of each image: its file name without the extension (or with it).

    Raises
    ------
    InputError
        An image whose name is not an EO id, or two images with one id.
    """
    known = set(eo_ids)
    ids, seen = [], {}
    for p in paths:
        base = os.path.basename(str(p))
        stem = os.path.splitext(base)[0]
        iid = stem if stem in known else base if base in known else None
        if iid is None:
            sample = ", ".join(sorted(known)[:3])
            raise InputError(f"image {stem!r} is not in {eo_path} (its ids: {sample}"
                             f"{', ...' if len(known) > 3 else ''}); image ids are the file "
                             "names without extension", path=str(p))
        if iid in seen:
            raise InputError(f"image id {iid!r} given twice (also {seen[iid]})", path=str(p))
        seen[iid] = str(p)
        ids.append(iid)
    return ids


def _frame_origin_h(frame):
    for part in str(frame).split(";"):
        if "=" in part:
            k, v = part.split("=", 1)
            if k.strip() == "origin_h_m":
                return float(v)
    return 0.0


def dem_height_range(path, frame):
    """Ground heights of a DEM (GeoTIFF) as mapping-frame ``Z``: ``(low, high)`` m.

    The range of the valid cells (0.5 and 99.5 percentiles; GDAL's nodata tag and
    non-finite values left out).  For an ENU mapping frame the height is taken as
    ``Z = h - origin_h_m`` (the Earth's curvature, 8 cm at 1 km from the origin, is
    inside the band); for a projected frame as it is: the DEM must then use the EO's
    height system (ellipsoidal, or orthometric with the same geoid).
    """
    import tifffile
    path = str(path)
    if not os.path.isfile(path):
        raise InputError("DEM not found", path=path)
    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages[0]
            tag = page.tags.get(42113)
            nodata = float(tag.value.strip("\x00 ")) if tag is not None else None
            z = np.asarray(page.asarray(), dtype=float)
    except Exception as exc:
        raise InputError(f"cannot read the DEM: {exc}", path=path) from None
    ok = np.isfinite(z)
    if nodata is not None:
        ok &= z != nodata
    if not ok.any():
        raise InputError("the DEM has no valid height", path=path)
    lo, hi = np.percentile(z[ok], [0.5, 99.5])
    if str(frame).strip().lower().startswith("enu"):
        h0 = _frame_origin_h(frame)
        lo, hi = lo - h0, hi - h0
    return float(lo), float(hi)


def _views(eo, settings):
    C = eo.matrices()
    s_ang = (np.sqrt(np.mean(np.square(eo.angle_sigma), axis=1)) if eo.angle_sigma is not None
             else np.full(len(eo), settings.angle_sigma_rad))
    s_pos = (np.sqrt(np.mean(np.square(eo.position_sigma), axis=1))
             if eo.position_sigma is not None
             else np.full(len(eo), settings.position_sigma_m))
    return [PriorView(np.asarray(eo.position[k], float), C[k], float(s_ang[k]),
                      float(s_pos[k])) for k in range(len(eo))]


def _detect(path, camera, settings):
    level = read_grey(path, settings.max_side_px)
    if (level.width_px, level.height_px) != (camera.width_px, camera.height_px):
        raise InputError(f"image is {level.width_px} x {level.height_px} px, the camera "
                         f"file says {camera.width_px} x {camera.height_px} px", path=path)
    return detect_features(level, settings.max_features)


def _detect_into(store, k, iid, path, camera, settings):
    """Detect image `k` into the store (or find it there): ``(n_keypoints, scale_px)``."""
    key = feature_key(path, settings.max_side_px, settings.max_features)
    found = store.lookup(k, iid, key)
    if found is not None:
        return found
    feats = _detect(path, camera, settings)
    return store.put(k, iid, key, feats.uv_px, feats.descriptors, feats.scale_px)


def _map(func, items, workers, progress, done0, total):
    """``[func(x) for x in items]``, on Dask threads when ``workers > 1``."""
    if not workers or workers <= 1:
        out = []
        for k, x in enumerate(items):
            out.append(func(x))
            if progress:
                progress(done0 + k + 1, total)
        return out
    import dask
    out = dask.compute(*[dask.delayed(func)(x) for x in items], scheduler="threads",
                       num_workers=int(workers))
    if progress:
        progress(done0 + len(items), total)
    return list(out)


def match_images(paths, eo, camera, z_range_m, settings=MatchSettings(), workers=None,
                 progress=None, eo_path="the EO file", cache_dir=None, cache_images=None):
    """Tie points of a set of images with their prior exterior orientation.

    Parameters
    ----------
    paths : sequence of str
        Image files (JPEG, TIFF, GeoTIFF, PNG); each name (without extension) an EO id.
    eo : photogrammetry.orientation.exposure.ExposureOrientation
        Prior EO (mapping frame, m; angles rad); its sigmas set the epipolar bands
        (else ``settings.angle_sigma_rad`` and ``position_sigma_m``).
    camera : photogrammetry.orientation.camera.FrameCamera
        Full-frame camera (the images must have its size).
    z_range_m : (float, float)
        Lowest and highest ground height, mapping-frame ``Z``, m.
    settings : MatchSettings
    workers : int, optional
        Dask threads for detection and matching.
    progress : callable(done, total), optional
        Images detected plus pairs matched.
    cache_dir : str, optional
        Keep each image's features there (and reuse them on the next run:
        :mod:`photogrammetry.imagery.feature_cache`); default a temporary folder.
    cache_images : int, optional
        Images whose features are held in memory at once (default ``2 workers + 2``,
        at least 4): the features' memory is bounded by it, not by the block.

    Returns
    -------
    ImageTiePoints
    """
    paths = [str(p) for p in paths]
    ids = image_ids_of(paths, eo.image_id, eo_path)
    for p in paths:
        image_size(p)                            # a missing image: before the work
    z0, z1 = float(min(z_range_m)), float(max(z_range_m))
    index = {iid: k for k, iid in enumerate(eo.image_id)}
    all_views = _views(eo, settings)
    views = [all_views[index[i]] for i in ids]
    pairs = select_pairs(views, camera, 0.5 * (z0 + z1), settings.min_overlap)
    n_lru = cache_images or max(4, 2 * int(workers or 1) + 2)
    with FeatureStore(cache_dir, n_lru, lambda uv: ideal_photo_mm(camera, uv)) as store:
        total = len(paths) + len(pairs)
        counts = _map(lambda k: _detect_into(store, k, ids[k], paths[k], camera, settings),
                      range(len(paths)), workers, progress, 0, total)
        results = _map(lambda pair: _match_pair(store, pair, views, camera, (z0, z1),
                                                settings),
                       pairs, workers, progress, len(paths), total)
        n_feat = [c[0] for c in counts]
        kept = [m for m in results if len(m.idx_i) >= settings.min_inliers]
        tracks, conflicts = build_tracks(n_feat, kept)
        img_out, pid_out, xy_out = _observations(store, tracks, ids, camera)
    px = camera.pixel_size_mm
    samp = np.concatenate([m.sampson_mm for m in kept]) if kept else np.zeros(0)
    sigma_px = (float(1.4826 * np.median(np.abs(samp)) / px) if len(samp)
                else float("nan"))
    pair_rows = [{"i": ids[m.i], "j": ids[m.j], "overlap": p[2], "candidates": m.n_candidates,
                  "guided": m.n_guided, "inliers": len(m.idx_i),
                  "kept": len(m.idx_i) >= settings.min_inliers}
                 for m, p in zip(results, pairs)]
    return ImageTiePoints(img_out, pid_out, xy_out, sigma_px, pair_rows, n_feat,
                          len(tracks), conflicts,
                          np.array([len(t) for t in tracks], dtype=int))


def _match_pair(store, pair, views, camera, z_range, settings):
    """Verified matches of one pair, its two images' features from the store."""
    i, j, _ = pair
    z0, z1 = z_range
    (_, di, xi, si), (_, dj, xj, sj) = store.get(i), store.get(j)
    f, px = camera.focal_length_mm, camera.pixel_size_mm
    scale = max(si, sj)
    depth = 0.5 * (abs(views[i].X0_m[2] - 0.5 * (z0 + z1))
                   + abs(views[j].X0_m[2] - 0.5 * (z0 + z1)))
    tol = band_tolerance_mm(camera, views[i], views[j], depth, settings.n_sigma,
                            3.0 * scale * px)
    ii, jj, ncand = guided_matches(di, dj, xi, xj, views[i], views[j], f, (z0, z1), tol,
                                   settings.ratio)
    inl, samp = verify_pair(xi[ii], xj[jj], f, settings.ransac_px * scale * px)
    return PairMatches(i, j, ii[inl].astype(np.int32), jj[inl].astype(np.int32), ncand,
                       len(ii), samp)


def _observations(store, tracks, ids, camera):
    """The tracks' observed photo coordinates (mm), each image's keypoints read once."""
    if not tracks:
        return [], [], np.zeros((0, 2))
    lengths = np.array([len(t) for t in tracks])
    obs = np.concatenate(tracks)                  # (image index, keypoint index)
    pid = np.repeat(np.arange(1, len(tracks) + 1), lengths)
    xy = np.empty((len(obs), 2))
    for k in np.unique(obs[:, 0]):
        rows = np.flatnonzero(obs[:, 0] == k)
        xy[rows] = camera.pixel_to_photo(store.uv_px(int(k))[obs[rows, 1]])
    return [ids[k] for k in obs[:, 0]], [str(p) for p in pid], xy
