"""Synthetic stereo pairs with known truth, and the Cramer-Rao bound of their angles.

Test scaffolding, not part of the library: used by the tests (small sizes) and by
``bench/refine_scenario.py`` and ``bench/bench_refine.py`` (the full scenario of issue 6;
they put ``tests/`` on ``sys.path``).  A frame camera (f = 10 000 px), near-nadir images
at flying height ``H`` over a terrain of relief +-``relief_m``, 60 % forward overlap
along the mapping x axis, true angles within +-3 deg, photo-coordinate noise, INS priors
with noise.  Image 1 of every pair carries its TRUE angles (the known image of the
paper); image 2's prior is noisy.  The mapping frame is ENU-like: a ray ``(x, y, -f)``
of a level camera points down.
"""
import numpy as np

from ins.nav.rotation import dcm_to_rotvec, rotvec_to_dcm
from photogrammetry.orientation.rotation import angles_to_matrix

SYSTEM = "phi-omega-kappa"


def project(R, C, X, f_mm):
    """Photo coordinates (mm) of ground points X (P, n, 3) in cameras (R (P,3,3), C (P,3))."""
    d = np.einsum("pji,pnj->pni", R, X - C[:, None, :])
    return -f_mm * d[..., :2] / d[..., 2:3]


def make_pairs(n_pairs, n_points, seed=0, f_px=10000.0, pixel_mm=0.01, width_px=8000,
               height_px=6000, height_m=1000.0, relief_m=50.0, max_angle_deg=3.0,
               noise_px=0.5, ins_sigma_rad=0.005, overlap=0.6, system=SYSTEM):
    """Random independent pairs with their truth.

    Returns
    -------
    dict with ``u1``, ``u2`` (P, n, 3) noisy rays (x, y, -f) mm, ``mask`` (P, n),
    ``ang1``/``ang2`` true angles (P, 3) rad, ``R1``/``R2`` true matrices, ``prior1``/
    ``prior2`` INS angles (true + noise), ``C1``/``C2`` positions (P, 3) m, ``X`` ground
    points (P, n, 3) m, ``xy1_true``/``xy2_true`` noise-free photo coordinates (mm),
    ``f_mm``, ``sigma_mm``, ``system``.
    """
    rng = np.random.default_rng(seed)
    f_mm = f_px * pixel_mm
    w_mm, h_mm = width_px * pixel_mm, height_px * pixel_mm
    scale = height_m / f_mm
    base = (1.0 - overlap) * w_mm * scale
    P = n_pairs
    lim = np.deg2rad(max_angle_deg)
    ang1 = rng.uniform(-lim, lim, (P, 3))
    ang2 = rng.uniform(-lim, lim, (P, 3))
    R1, R2 = angles_to_matrix(ang1, system), angles_to_matrix(ang2, system)
    C1 = np.column_stack([np.zeros(P), np.zeros(P), np.full(P, height_m)])
    C2 = C1 + np.column_stack([base + rng.normal(0, 0.02 * base, P),
                               rng.normal(0, 0.03 * base, P), rng.normal(0, 5.0, P)])
    m = 8 * n_points
    gx = rng.uniform(base - 0.5 * w_mm * scale, 0.5 * w_mm * scale, (P, m))
    gy = rng.uniform(-0.5 * h_mm * scale, 0.5 * h_mm * scale, (P, m))
    gz = rng.uniform(-relief_m, relief_m, (P, m))
    X = np.stack([gx, gy, gz], axis=2)
    xy1, xy2 = project(R1, C1, X, f_mm), project(R2, C2, X, f_mm)
    half = np.array([0.5 * w_mm, 0.5 * h_mm])
    inside = np.all(np.abs(xy1) < half, axis=2) & np.all(np.abs(xy2) < half, axis=2)
    if not inside.sum(axis=1).min() >= n_points:
        raise RuntimeError("too few points inside both frames; enlarge the oversampling")
    pick = np.argsort(~inside, axis=1, kind="stable")[:, :n_points]
    X = np.take_along_axis(X, pick[:, :, None], axis=1)
    xy1 = np.take_along_axis(xy1, pick[:, :, None], axis=1)
    xy2 = np.take_along_axis(xy2, pick[:, :, None], axis=1)
    sigma_mm = noise_px * pixel_mm
    obs1 = xy1 + rng.normal(0, sigma_mm, xy1.shape)
    obs2 = xy2 + rng.normal(0, sigma_mm, xy2.shape)
    fcol = np.full(obs1.shape[:2] + (1,), -f_mm)
    return {"u1": np.concatenate([obs1, fcol], axis=2), "u2": np.concatenate([obs2, fcol], axis=2),
            "mask": np.ones((P, n_points), dtype=bool), "ang1": ang1, "ang2": ang2,
            "R1": R1, "R2": R2, "prior1": ang1 + rng.normal(0, ins_sigma_rad, (P, 3)),
            "prior2": ang2 + rng.normal(0, ins_sigma_rad, (P, 3)), "C1": C1, "C2": C2,
            "X": X, "xy1_true": xy1, "xy2_true": xy2, "f_mm": f_mm, "sigma_mm": sigma_mm,
            "pixel_mm": pixel_mm, "system": system}


def crb_rotation(pairs, base_known, h=1e-7):
    """Cramer-Rao bound of image 2's rotation (image 1 known), per pair.

    The exact observation model: the four photo coordinates of every tie point are the
    collinearity projections of an unknown ground point; unknowns are a small rotation
    of image 2 (model frame, rad), the base direction (2, unless ``base_known``; the base
    length is the datum of the scale) and all ground points.  Jacobians by central
    differences of :func:`project`, the ground points eliminated per point (Schur).

    Returns
    -------
    ndarray, shape (P, 3, 3)
        Covariance bound of the rotation vector of image 2, rad^2.
    """
    R1, R2, C1, C2, X = pairs["R1"], pairs["R2"], pairs["C1"], pairs["C2"], pairs["X"]
    f, s2 = pairs["f_mm"], pairs["sigma_mm"] ** 2
    P, n = X.shape[:2]
    b = C2 - C1
    bl = np.linalg.norm(b, axis=1)
    bu = b / bl[:, None]
    e1 = np.cross(bu, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    E = np.stack([e1, np.cross(bu, e1)], axis=2)
    k = 3 if base_known else 5

    def proj2(theta, tb):
        C = C1 + bl[:, None] * (bu + np.einsum("pij,pj->pi", E, tb))
        return project(rotvec_to_dcm(theta) @ R2, C, X, f)

    Jg = np.zeros((P, n, 4, k))
    z3, z2 = np.zeros((P, 3)), np.zeros((P, 2))
    for j in range(k):
        d3, d2 = z3.copy(), z2.copy()
        if j < 3:
            d3[:, j] = h
        else:
            d2[:, j - 3] = h
        Jg[:, :, 2:, j] = (proj2(d3, d2) - proj2(-d3, -d2)) / (2 * h)
    JX = np.zeros((P, n, 4, 3))
    for j in range(3):
        dX = np.zeros(3)
        dX[j] = 1e-3
        JX[:, :, :2, j] = (project(R1, C1, X + dX, f) - project(R1, C1, X - dX, f)) / 2e-3
        JX[:, :, 2:, j] = (project(R2, C2, X + dX, f) - project(R2, C2, X - dX, f)) / 2e-3
    XX = np.linalg.inv(np.einsum("pnai,pnaj->pnij", JX, JX))
    Xg = np.einsum("pnai,pnaj->pnij", JX, Jg)
    info = (np.einsum("pnai,pnaj->pij", Jg, Jg)
            - np.einsum("pnia,pnij,pnjb->pab", Xg, XX, Xg)) / s2
    return np.linalg.inv(info)[:, :3, :3]


def rotation_error(R_est, R_true):
    """Rotation vectors (model frame, rad) of ``R_est R_true^T``, shape (P, 3)."""
    return dcm_to_rotvec(R_est @ np.swapaxes(R_true, 1, 2))


def make_block(n_strips=5, n_per_strip=10, seed=0, f_px=10000.0, pixel_mm=0.01,
               width_px=8000, height_px=6000, height_m=1000.0, relief_m=50.0,
               forward_overlap=0.6, side_overlap=0.3, points_per_image=60, noise_px=0.5,
               max_angle_deg=3.0, ins_sigma_rad=0.005, boresight_rad=(0.002, -0.003, 0.004),
               system=SYSTEM, min_common=8, outlier_fraction=0.0, outlier_px=(10.0, 100.0)):
    """A block of strips flown back and forth along x, with tie points, INS priors, truth.

    With ``outlier_fraction`` > 0 that fraction of the observations (image, point) is
    displaced by a random shift of ``outlier_px`` (min, max) pixels in a random direction
    (gross mismatches); ``outliers`` (m, n_points) bool marks them (``obs`` and
    ``pair_points`` carry them).

    The INS angles are the true attitude times the boresight misalignment (camera frame,
    ``R_ins = R_true @ boresight_matrix(-boresight)`` so that ``R_true = R_ins @ Rx Ry Rz``
    as in the camera file) plus white noise of `ins_sigma_rad` on every angle.

    Returns
    -------
    dict with ``angles`` (m, 3) true, ``prior`` (m, 3) INS, ``positions`` (m, 3),
    ``pairs`` (P, 2), ``pair_points`` [(xy_i, xy_j)], ``point_ids`` [ground-point index
    of each pair's points], ``ins_noise`` (m, 3) injected,
    ``boresight`` (3,), ``f_mm``, ``sigma_mm``, ``system``, ``obs`` {image: (ids, xy)}.
    """
    from photogrammetry.orientation.rotation import boresight_matrix, matrix_to_angles
    rng = np.random.default_rng(seed)
    f_mm = f_px * pixel_mm
    scale = height_m / f_mm
    w_g, h_g = width_px * pixel_mm * scale, height_px * pixel_mm * scale
    base, gap = (1 - forward_overlap) * w_g, (1 - side_overlap) * h_g
    lim = np.deg2rad(max_angle_deg)
    pos, ang = [], []
    for s in range(n_strips):
        back = s % 2 == 1
        for k in range(n_per_strip):
            x = (n_per_strip - 1 - k if back else k) * base + rng.normal(0, 3.0)
            pos.append([x, s * gap + rng.normal(0, 5.0), height_m + rng.normal(0, 5.0)])
            a = rng.uniform(-lim, lim, 3)
            if back:
                a[2] += np.pi
            ang.append(a)
    pos, ang = np.array(pos), np.array(ang)
    m = len(pos)
    R = angles_to_matrix(ang, system)
    n_pts = int(points_per_image * m / 2.5)
    X = np.column_stack([rng.uniform(-0.5 * w_g, (n_per_strip - 1) * base + 0.5 * w_g, n_pts),
                         rng.uniform(-0.5 * h_g, (n_strips - 1) * gap + 0.5 * h_g, n_pts),
                         rng.uniform(-relief_m, relief_m, n_pts)])
    xy = project(R, pos, np.broadcast_to(X, (m,) + X.shape), f_mm)
    half = 0.5 * np.array([width_px, height_px]) * pixel_mm
    seen = np.all(np.abs(xy) < half, axis=2)
    sigma_mm = noise_px * pixel_mm
    xy_obs = xy + rng.normal(0, sigma_mm, xy.shape)
    orng = np.random.default_rng(seed + 7919)           # the outliers leave the rest as is
    outliers = seen & (orng.random(seen.shape) < outlier_fraction)
    size = orng.uniform(*outlier_px, seen.shape) * pixel_mm
    turn = orng.uniform(0, 2 * np.pi, seen.shape)
    xy_obs += (outliers * size)[..., None] * np.stack([np.cos(turn), np.sin(turn)], axis=2)
    pairs, pair_points, point_ids = [], [], []
    for i in range(m):
        for j in range(i + 1, m):
            common = seen[i] & seen[j]
            if common.sum() >= min_common:
                pairs.append((i, j))
                pair_points.append((xy_obs[i, common], xy_obs[j, common]))
                point_ids.append(np.flatnonzero(common))
    bs = np.asarray(boresight_rad, dtype=float)
    noise = rng.normal(0, ins_sigma_rad, (m, 3))
    prior = matrix_to_angles(R @ boresight_matrix(bs).T, system) + noise
    obs = {i: (np.flatnonzero(seen[i]), xy_obs[i, seen[i]]) for i in range(m)}
    return {"angles": ang, "prior": prior, "positions": pos, "pairs": np.array(pairs),
            "pair_points": pair_points, "point_ids": point_ids,
            "ins_noise": noise, "boresight": bs, "f_mm": f_mm,
            "sigma_mm": sigma_mm, "pixel_mm": pixel_mm, "system": system, "obs": obs,
            "X": X, "outliers": outliers}


def write_block_files(block, folder, width_px=8000, height_px=6000, outlier=None,
                      radial_k=(0.0, 0.0, 0.0), tangential_p=(0.0, 0.0)):
    """Write a :func:`make_block` block as files: ``eo.csv`` (INS priors), ``tiepoints.csv``
    and ``camera.toml`` in `folder`; ``outlier=(image, k, dy_mm)`` shifts one observation
    across the strip (y).  With distortion coefficients (Brown, mm units) the camera file
    states them and the tie points are written distorted (the block's observations are
    the ideal coordinates plus noise; the file holds ``camera.distort`` of them, so a
    reader that undistorts recovers them exactly).

    Returns the three paths.
    """
    import os

    from photogrammetry.orientation.camera import FrameCamera, write_camera
    from photogrammetry.orientation.exposure import ExposureOrientation, write_eo_csv
    m = len(block["prior"])
    ids = [f"img{i:03d}" for i in range(m)]
    pixel = block["pixel_mm"]
    cam = FrameCamera(block["f_mm"], pixel, width_px, height_px,
                      ((width_px - 1) / 2, (height_px - 1) / 2), tuple(radial_k),
                      tuple(tangential_p))
    paths = [os.path.join(folder, name) for name in ("eo.csv", "tiepoints.csv", "camera.toml")]
    write_camera(paths[2], cam)
    eo = ExposureOrientation(ids, np.arange(m, dtype=float), block["positions"],
                             block["prior"], block["system"], "enu")
    write_eo_csv(paths[0], eo)
    rows = [f"# tie points: sigma_px = {block['sigma_mm'] / pixel:g} "
            f"(sigma_mm = {block['sigma_mm']:g})", "image_id,point_id,x_mm,y_mm"]
    for i in range(m):
        pid, xy = block["obs"][i]
        xy = xy.copy()
        if outlier is not None and outlier[0] == i:
            xy[outlier[1], 1] += outlier[2]
        digits = 7
        if np.any(radial_k) or np.any(tangential_p):
            xy, digits = cam.distort(xy), 10         # the round trip to 1e-10 mm
        rows += [f"{ids[i]},{p},{x:.{digits}f},{y:.{digits}f}" for p, (x, y) in zip(pid, xy)]
    with open(paths[1], "w") as f:
        f.write("\n".join(rows) + "\n")
    return paths


def make_large_block(n_images, n_per_strip=50, seed=0, f_px=10000.0, pixel_mm=0.01,
                     width_px=8000, height_px=6000, height_m=1000.0, relief_m=50.0,
                     forward_overlap=0.6, side_overlap=0.3, points_per_image=40,
                     noise_px=0.5, max_angle_deg=3.0, ins_sigma_rad=0.005,
                     boresight_rad=(0.002, -0.003, 0.004), system=SYSTEM, min_common=8):
    """A block like :func:`make_block` for thousands of images, in memory linear in the
    images: strips of `n_per_strip` (the last one shorter), ground points projected only
    into the images near them, pairs only between neighbouring images (a different random
    stream from :func:`make_block`).  Same returned keys (``obs`` and ``X`` included)."""
    from photogrammetry.orientation.rotation import boresight_matrix, matrix_to_angles
    rng = np.random.default_rng(seed)
    f_mm = f_px * pixel_mm
    scale = height_m / f_mm
    w_g, h_g = width_px * pixel_mm * scale, height_px * pixel_mm * scale
    base, gap = (1 - forward_overlap) * w_g, (1 - side_overlap) * h_g
    n_strips = -(-n_images // n_per_strip)
    k = np.arange(n_images) % n_per_strip
    s = np.arange(n_images) // n_per_strip
    back = s % 2 == 1
    pos = np.column_stack([np.where(back, n_per_strip - 1 - k, k) * base
                           + rng.normal(0, 3.0, n_images),
                           s * gap + rng.normal(0, 5.0, n_images),
                           height_m + rng.normal(0, 5.0, n_images)])
    lim = np.deg2rad(max_angle_deg)
    ang = rng.uniform(-lim, lim, (n_images, 3))
    ang[back, 2] += np.pi
    R = angles_to_matrix(ang, system)
    x_max = (n_per_strip - 1) * base + 0.5 * w_g
    y_max = (n_strips - 1) * gap + 0.5 * h_g
    n_pts = int(points_per_image * n_images / 2.5)
    X = np.column_stack([rng.uniform(-0.5 * w_g, x_max, n_pts),
                         rng.uniform(-0.5 * h_g, y_max, n_pts),
                         rng.uniform(-relief_m, relief_m, n_pts)])
    half = 0.5 * np.array([width_px, height_px]) * pixel_mm
    sigma_mm = noise_px * pixel_mm
    # ground points near each image (a grid of cells of one footprint)
    cell = np.floor(X[:, :2] / [w_g, h_g]).astype(int)
    order = np.lexsort((cell[:, 1], cell[:, 0]))
    keys = cell[order]
    obs = {}
    for i in range(n_images):
        c = np.floor(pos[i, :2] / [w_g, h_g]).astype(int)
        near = []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                key = (c[0] + dx, c[1] + dy)
                lo = np.searchsorted(keys[:, 0] * 1_000_003 + keys[:, 1],
                                     key[0] * 1_000_003 + key[1], "left")
                hi = np.searchsorted(keys[:, 0] * 1_000_003 + keys[:, 1],
                                     key[0] * 1_000_003 + key[1], "right")
                near.append(order[lo:hi])
        near = np.sort(np.concatenate(near))
        xy = project(R[i:i + 1], pos[i:i + 1], X[near][None], f_mm)[0]
        seen = np.all(np.abs(xy) < half, axis=1)
        obs[i] = (near[seen], xy[seen] + rng.normal(0, sigma_mm, (seen.sum(), 2)))
    pairs, pair_points, point_ids = [], [], []
    reach = np.array([w_g, h_g]) * 1.2
    for i in range(n_images):
        close = np.flatnonzero(np.all(np.abs(pos[i + 1:, :2] - pos[i, :2]) < reach, axis=1))
        for j in close + i + 1:
            common, a, b = np.intersect1d(obs[i][0], obs[j][0], return_indices=True)
            if len(common) >= min_common:
                pairs.append((i, j))
                pair_points.append((obs[i][1][a], obs[j][1][b]))
                point_ids.append(common)
    bs = np.asarray(boresight_rad, dtype=float)
    noise = rng.normal(0, ins_sigma_rad, (n_images, 3))
    prior = matrix_to_angles(R @ boresight_matrix(bs).T, system) + noise
    return {"angles": ang, "prior": prior, "positions": pos, "pairs": np.array(pairs),
            "pair_points": pair_points, "point_ids": point_ids, "ins_noise": noise,
            "boresight": bs, "f_mm": f_mm, "sigma_mm": sigma_mm, "pixel_mm": pixel_mm,
            "system": system, "obs": obs, "X": X,
            "outliers": {i: np.zeros(len(obs[i][0]), bool) for i in obs}}


def make_cross_strip_pair(n_points, n_mismatches, seed=0, f_px=10000.0, pixel_mm=0.01,
                          width_px=8000, height_px=6000, height_m=1000.0, relief_m=50.0,
                          side_overlap=0.3, noise_px=0.5, prior_off_deg=0.2,
                          max_angle_deg=2.0, system=SYSTEM):
    """A cross-strip pair like the real aerial ones of issue 26 (22 and 46 SIFT matches,
    a few per cent of them mismatches, the prior 0.2 deg off): two frames of adjacent
    strips flown in opposite directions (kappa 180 deg apart), the base across the
    strip, the common points in the side overlap (30 % of the frame height) with relief.

    `n_mismatches` of the points are matched to the wrong place in image 2 (the image
    position of another ground point of the overlap, with the noise).  The prior of
    image 1 is its true attitude; that of image 2 is ``prior_off_deg`` off in every
    angle (random signs).

    Returns
    -------
    dict with ``angles`` (2, 3) true rad, ``R`` (2, 3, 3), ``positions`` (2, 3) m,
    ``xy1``, ``xy2`` (n, 2) observed mm, ``prior`` (2, 3) rad, ``mismatched`` (indices),
    ``f_mm``, ``sigma_mm``, ``pixel_mm``, ``width_px``, ``height_px``, ``system``.
    """
    rng = np.random.default_rng(seed)
    f_mm = f_px * pixel_mm
    w_mm, h_mm = width_px * pixel_mm, height_px * pixel_mm
    scale = height_m / f_mm
    w_g, h_g = w_mm * scale, h_mm * scale
    gap = (1 - side_overlap) * h_g
    lim = np.deg2rad(max_angle_deg)
    ang = rng.uniform(-lim, lim, (2, 3))
    ang[1, 2] += np.pi
    R = angles_to_matrix(ang, system)
    C = np.array([[0.0, 0.0, height_m],
                  [rng.normal(0, 30.0), gap, height_m + rng.normal(0, 5.0)]])
    X = np.column_stack([rng.uniform(-0.5 * w_g, 0.5 * w_g, 20 * n_points),
                         rng.uniform(gap - 0.5 * h_g, 0.5 * h_g, 20 * n_points),
                         rng.uniform(-relief_m, relief_m, 20 * n_points)])
    xy = [project(R[k:k + 1], C[k:k + 1], X[None], f_mm)[0] for k in range(2)]
    half = 0.5 * np.array([w_mm, h_mm]) - 20 * pixel_mm
    inside = np.flatnonzero(np.all(np.abs(xy[0]) < half, axis=1)
                            & np.all(np.abs(xy[1]) < half, axis=1))
    if len(inside) < n_points + n_mismatches:
        raise RuntimeError("too few points in the side overlap")
    idx = inside[:n_points]
    sigma_mm = noise_px * pixel_mm
    xy1 = xy[0][idx] + rng.normal(0, sigma_mm, (n_points, 2))
    xy2 = xy[1][idx] + rng.normal(0, sigma_mm, (n_points, 2))
    bad = rng.choice(n_points, n_mismatches, replace=False)
    xy2[bad] = (xy[1][inside[n_points:n_points + n_mismatches]]
                + rng.normal(0, sigma_mm, (n_mismatches, 2)))
    prior = ang + np.vstack([np.zeros(3),
                             np.deg2rad(prior_off_deg) * rng.choice([-1.0, 1.0], 3)])
    return {"angles": ang, "R": R, "positions": C, "xy1": xy1, "xy2": xy2, "prior": prior,
            "mismatched": bad, "f_mm": f_mm, "sigma_mm": sigma_mm, "pixel_mm": pixel_mm,
            "width_px": width_px, "height_px": height_px, "system": system}


def write_pair_files(p, folder):
    """EO (the priors), tie points (mm) and camera files of a :func:`make_cross_strip_pair`
    pair in ``folder`` (a pathlib.Path); their paths."""
    from photogrammetry.orientation.camera import FrameCamera, write_camera
    from photogrammetry.orientation.exposure import ExposureOrientation, write_eo_csv
    write_camera(folder / "c.toml", FrameCamera(p["f_mm"], p["pixel_mm"], p["width_px"],
                                                p["height_px"], ((p["width_px"] - 1) / 2,
                                                                 (p["height_px"] - 1) / 2)))
    write_eo_csv(folder / "eo.csv", ExposureOrientation(
        ["a", "b"], [0.0, 1.0], p["positions"], p["prior"], p["system"], "enu"))
    rows = [f"# sigma_px = {p['sigma_mm'] / p['pixel_mm']:g}", "image_id,point_id,x_mm,y_mm"]
    for iid, xy in (("a", p["xy1"]), ("b", p["xy2"])):
        rows += [f"{iid},{k},{x:.7f},{y:.7f}" for k, (x, y) in enumerate(xy)]
    (folder / "tp.csv").write_text("\n".join(rows) + "\n")
    return [str(folder / n) for n in ("eo.csv", "tp.csv", "c.toml")]
