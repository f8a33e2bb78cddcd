"""Tie points of the simulator: visibility, distortion, noise; forward intersection with
the TRUE exterior orientation reproduces the ground points within the injected noise."""
import numpy as np

from photogrammetry.orientation.camera import FrameCamera
from photogrammetry.orientation.rotation import angles_to_matrix
from photogrammetry.simulate.exposures import TrueExposures
from photogrammetry.simulate.terrain import make_terrain
from photogrammetry.simulate.tiepoints import project, simulate_tiepoints

F_MM = 50.0
PIX_MM = 0.005


def _camera(distorted=True):
    return FrameCamera(F_MM, PIX_MM, 4000, 3000, (1999.5, 1499.5),
                       radial_k=(-2e-6, 1e-10, 0.0) if distorted else (0.0, 0.0, 0.0),
                       tangential_p=(3e-6, -2e-6) if distorted else (0.0, 0.0))


def _block(rng, height=800.0, n_per_strip=8):
    """Two strips along east, 60 % forward / 30 % side overlap, small random tilts."""
    along = height * 4000 * PIX_MM / F_MM          # image x (columns) along track
    across = height * 3000 * PIX_MM / F_MM
    base, spacing = 0.4 * along, 0.7 * across
    X, R, strip = [], [], []
    for s in range(2):
        for k in range(n_per_strip):
            x = k * base if s == 0 else (n_per_strip - 1 - k) * base
            X.append([x, -s * spacing, height + rng.normal(0, 3.0)])
            kappa = 0.0 if s == 0 else np.pi
            R.append(angles_to_matrix([rng.normal(0, 0.02), rng.normal(0, 0.02),
                                       kappa + rng.normal(0, 0.02)], "phi-omega-kappa"))
            strip.append(s)
    n = len(X)
    return TrueExposures(tuple(f"S{s + 1:02d}_{k:03d}" for k, s in enumerate(strip)),
                         np.array(strip), 1000.0 + np.arange(n) * 5.0, np.array(X),
                         np.array(R), np.zeros(3))


def intersect(camera, exposures, idx, xy_obs, sigma_mm):
    """Collinearity forward intersection (Gauss-Newton) of one point from its images
    ``idx`` (rows of ``exposures.X_m``, ``exposures.C_mc``); returns the point and its
    normal matrix J^T J / sigma^2 (the inverse covariance)."""
    xy = camera.undistort(xy_obs)
    X0 = exposures.X_m[idx]
    R = exposures.C_mc[idx]
    d_m = np.einsum("nij,nj->ni", R, camera.rays(xy))      # ray directions, mapping frame
    d_m /= np.linalg.norm(d_m, axis=1, keepdims=True)
    P = np.eye(3) - d_m[:, :, None] * d_m[:, None, :]
    X = np.linalg.solve(P.sum(0), np.einsum("nij,nj->i", P, X0))
    f = camera.focal_length_mm
    for _ in range(5):
        d_c = np.einsum("nji,nj->ni", R, X - X0)
        model = -f * d_c[:, :2] / d_c[:, 2:3]
        J = -f / d_c[:, 2, None, None] * (
            np.transpose(R[:, :, :2], (0, 2, 1))
            - (d_c[:, :2] / d_c[:, 2:3])[:, :, None] * R[:, None, :, 2])
        J = J.reshape(-1, 3)
        step = np.linalg.lstsq(J, (xy - model).reshape(-1), rcond=None)[0]
        X = X + step
        if np.abs(step).max() < 1e-9:
            break
    return X, J.T @ J / sigma_mm ** 2


def _tiepoints(sigma_px, distorted=True, seed=7, per_image=150):
    rng = np.random.default_rng(seed)
    exposures = _block(rng)
    terrain = make_terrain(40.0, 600.0, rng)
    camera = _camera(distorted)
    tp = simulate_tiepoints(exposures, camera, terrain, per_image, sigma_px, rng)
    return exposures, camera, terrain, tp


def test_projection_is_collinear():
    rng = np.random.default_rng(1)
    R = angles_to_matrix([0.1, -0.05, 2.0], "omega-phi-kappa")
    X0 = np.array([10.0, -20.0, 900.0])
    ground = np.column_stack([rng.uniform(-300, 300, (50, 2)), rng.uniform(-30, 30, 50)])
    xy = project(ground, X0, R, F_MM)
    ray_m = np.column_stack([xy, np.full(50, -F_MM)]) @ R.T
    lam = (ground - X0) / ray_m                      # X - X0 = lambda R (x, y, -f)
    assert np.allclose(lam, lam[:, :1], rtol=1e-10)
    assert np.all(lam > 0)


def test_coverage_and_visibility():
    exposures, camera, terrain, tp = _tiepoints(0.0)
    per_img = np.bincount(tp.image_index, minlength=len(exposures))
    assert 0.5 * 150 < np.median(per_img) < 1.5 * 150
    assert np.all(np.bincount(tp.point_id)[1:] >= 2)
    assert np.array_equal(np.unique(tp.point_id), tp.ground_id)
    assert np.all(camera.inside(camera.photo_to_pixel(tp.xy_mm), 20.0))
    assert np.allclose(tp.ground_m[:, 2], terrain.height(tp.ground_m[:, 0], tp.ground_m[:, 1]))
    # noise-free observations are the distorted projections with the true EO
    for i in (0, 5, 12):
        sel = tp.image_index == i
        xy = camera.distort(project(tp.ground_m[tp.point_id[sel] - 1], exposures.X_m[i],
                                    exposures.C_mc[i], F_MM))
        assert np.allclose(tp.xy_mm[sel], xy, atol=1e-12)


def test_forward_intersection_within_injected_noise():
    sigma_px = 0.5
    exposures, camera, _, tp = _tiepoints(sigma_px)
    sigma_mm = sigma_px * PIX_MM
    chi2, resid, var = [], [], []
    for pid, truth in zip(tp.ground_id, tp.ground_m):
        sel = tp.point_id == pid
        X, N = intersect(camera, exposures, tp.image_index[sel], tp.xy_mm[sel], sigma_mm)
        r = X - truth
        chi2.append(r @ N @ r)
        resid.append(r)
        var.append(np.diag(np.linalg.inv(N)))
    chi2, resid, var = np.array(chi2), np.array(resid), np.array(var)
    n = len(chi2)
    assert n > 500
    # chi-square with 3 degrees of freedom: mean 3, std of the mean sqrt(6 / n)
    assert abs(chi2.mean() - 3.0) < 4.0 * np.sqrt(6.0 / n)
    # per-axis RMS against the propagated pixel noise (ground sigma ~ H/f sigma_mm)
    ratio = np.sqrt(np.mean(resid ** 2, axis=0) / np.mean(var, axis=0))
    assert np.all(np.abs(ratio - 1.0) < 0.1), ratio
    # and the propagated sigma is the photo noise scaled to the ground (H / f), reduced
    # by the 2..8 rays of a point
    ground_sigma_m = 800.0 / F_MM * sigma_mm
    assert ground_sigma_m / np.sqrt(8) < np.sqrt(np.mean(var[:, 0])) < ground_sigma_m


def test_noise_free_intersection_is_exact():
    exposures, camera, _, tp = _tiepoints(0.0, per_image=40)
    for pid, truth in zip(tp.ground_id[:50], tp.ground_m[:50]):
        sel = tp.point_id == pid
        X, _ = intersect(camera, exposures, tp.image_index[sel], tp.xy_mm[sel], 1.0)
        assert np.allclose(X, truth, atol=1e-6)


def test_same_generator_state_same_points():
    a = _tiepoints(0.5, seed=3)[3]
    b = _tiepoints(0.5, seed=3)[3]
    c = _tiepoints(0.5, seed=4)[3]
    assert np.array_equal(a.xy_mm, b.xy_mm) and np.array_equal(a.ground_m, b.ground_m)
    assert not np.array_equal(a.ground_m[:10], c.ground_m[:10])
