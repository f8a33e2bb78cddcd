"""Rotation solvers (paper's Rodrigues LSQ, q-method, ML) and the heading sigma."""
import numpy as np
from scipy.spatial.transform import Rotation

from ins.nav.rotation import euler_to_dcm
from photogrammetry.lunar.solve import (
    cayley,
    heading,
    solve_heading,
    solve_qmethod,
    solve_rodrigues,
)


def _arc(n=30, span_deg=4.0):
    """Moon-like directions in NED: an arc at ~30 deg altitude."""
    az = np.deg2rad(140 + np.linspace(0, span_deg, n))
    alt = np.deg2rad(30 + np.linspace(0, span_deg / 2, n))
    return np.stack([np.cos(alt) * np.cos(az), np.cos(alt) * np.sin(az), -np.sin(alt)], -1)


def test_cayley_is_rotation_of_gibbs_vector():
    g = np.array([0.3, -0.2, 0.5])
    angle = 2 * np.arctan(np.linalg.norm(g))
    ref = Rotation.from_rotvec(angle * g / np.linalg.norm(g)).as_matrix()
    assert np.allclose(cayley(g), ref, atol=1e-12)


def test_exact_and_near_180():
    S_h = _arc()
    for hdg in (10.0, 90.0, 179.9):
        C = euler_to_dcm([0.02, -0.03, np.deg2rad(hdg)])
        S_c = S_h @ C
        assert np.allclose(solve_qmethod(S_h, S_c), C, atol=1e-10)
        C_r, g = solve_rodrigues(S_h, S_c)
        assert np.allclose(C_r, C, atol=1e-6)
        assert np.isclose(heading(C), np.deg2rad(hdg))
    # with noise, near 180 deg the Rodrigues normal equations are ill-conditioned
    rng = np.random.default_rng(3)
    C = euler_to_dcm([0.0, 0.0, np.deg2rad(179.99)])
    S_c = S_h @ C + 1e-4 * rng.standard_normal(S_h.shape)
    S_c /= np.linalg.norm(S_c, axis=1, keepdims=True)
    err_q = abs(heading(solve_qmethod(S_h, S_c)) - heading(C))
    err_r = abs(np.angle(np.exp(1j * (heading(solve_rodrigues(S_h, S_c)[0]) - heading(C)))))
    assert err_q < 0.05 and err_r > 10 * err_q


def test_heading_sigma_matches_monte_carlo():
    rng = np.random.default_rng(11)
    S_h = _arc(40)
    C = euler_to_dcm([0.03, 0.01, np.deg2rad(123.0)])
    sigma = 1e-4
    T = np.eye(3)[None] - np.einsum("ni,nj->nij", S_h @ C, S_h @ C)
    cov = sigma ** 2 * T
    errs, sig = [], []
    for _ in range(300):
        S_c = S_h @ C + sigma * np.einsum("nij,nj->ni", T, rng.standard_normal(S_h.shape))
        S_c /= np.linalg.norm(S_c, axis=1, keepdims=True)
        sol = solve_heading(S_h, S_c, cov)
        errs.append(np.angle(np.exp(1j * (sol.heading - np.deg2rad(123.0)))))
        sig.append(sol.heading_sigma)
    rms = np.sqrt(np.mean(np.square(errs)))
    assert 0.85 < rms / np.mean(sig) < 1.15
    assert abs(np.mean(errs)) < 4 * rms / np.sqrt(300)
