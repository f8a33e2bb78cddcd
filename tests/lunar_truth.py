"""An independent renderer of phased Moons for measuring the centre fit's bias.

Not the fit's model (``photogrammetry.lunar._limb_model``: 4x supersampled basis disks
with anti-aliased edges and a Gaussian core + wing PSF) and not the toolkit's renderer
(``photogrammetry.lunar.render``: 8x point-sampled disk, hard edges): here each pixel is
the integral of the law over the disk, computed cell by cell with the disk's edges found
analytically.

- The image plane is cut into cells of ``1 / n`` px.  In each cell the brightness is
  integrated by Gauss-Legendre quadrature in ``u`` (3 nodes) and, along ``v``, piecewise
  between the exact crossings of the limb (``Y = +-sqrt(1 - X^2)``) and of the terminator
  (the roots of ``mu0 = 0``), 4 nodes per piece: the discontinuities of every law sit on
  piece boundaries, so each cell's integral is exact to the quadrature's smooth-function
  error (``test_lunar_truth`` checks it against closed-form totals and centroids).
- Blur: a Gaussian PSF of sigma ``s`` convolved with the pixel's box, i.e. the pixel at
  ``(u_i, v_j)`` is ``sum_cells F_cell K(u_cell - u_i) K(v_cell - v_j)`` with
  ``K(t) = Phi((t + 1/2) / s) - Phi((t - 1/2) / s)`` (continuous, not a kernel sampled
  on the pixel grid); ``s = 0`` gives the pure area integral.

Laws (``mu0``, ``mu``: cosines of incidence and emission, ``g``: phase angle):
``flat`` 1, ``lambert`` mu0, ``lommel-seeliger`` mu0 / (mu0 + mu), ``hapke`` (the
isotropic-multiple-scattering form with Hapke's H-function approximation, w = 0.25,
an opposition surge B0 = 1, h = 0.06, a Henyey-Greenstein phase function b = -0.3),
``minnaert`` mu0^0.7 mu^-0.3 (k = 0.7; not in the fit's span of laws); 0 on the night
side (``mu0 <= 0``).
"""
import numpy as np
from scipy.special import ndtr

LAWS = ("lambert", "lommel-seeliger", "flat", "hapke", "minnaert")

_GL3 = np.polynomial.legendre.leggauss(3)
_GL4 = np.polynomial.legendre.leggauss(4)


def brightness(law, mu0, mu, phase):
    """Reflectance of ``law`` (arbitrary scale) at cosines ``mu0, mu`` (arrays), phase rad."""
    lit = mu0 > 0
    m0 = np.where(lit, mu0, 0.0)
    m = np.maximum(mu, 1e-12)
    if law == "flat":
        out = np.ones_like(m0)
    elif law == "lambert":
        out = m0
    elif law == "lommel-seeliger":
        out = m0 / (m0 + m)
    elif law == "hapke":
        w, b0, h, b = 0.25, 1.0, 0.06, -0.3
        gamma = np.sqrt(1 - w)

        def H(x):
            return (1 + 2 * x) / (1 + 2 * gamma * x)
        p = (1 - b * b) / (1 + 2 * b * np.cos(phase) + b * b) ** 1.5
        surge = b0 / (1 + np.tan(phase / 2) / h)
        out = w / 4 * m0 / (m0 + m) * ((1 + surge) * p + H(m0) * H(m) - 1)
    elif law == "minnaert":
        out = m0 ** 0.7 * m ** -0.3
    else:
        raise ValueError(f"unknown law {law!r}")
    return np.where(lit, out, 0.0)


def _terminator_roots(X, sun):
    """``Y`` where ``mu0 = 0`` on the columns ``X`` (NaN where none): shape (2, ...)."""
    s0, s1, s2 = sun
    a = s1 * s1 + s2 * s2
    b = 2 * X * s0 * s1
    c = X * X * s0 * s0 - s2 * s2 * (1 - X * X)
    disc = b * b - 4 * a * c
    if a < 1e-15:
        return np.full((2,) + np.shape(X), np.nan)
    with np.errstate(invalid="ignore"):
        r = np.stack([(-b - np.sqrt(disc)) / (2 * a), (-b + np.sqrt(disc)) / (2 * a)])
    # squaring added the roots of X s0 + Y s1 = +s2 mu: keep the true ones
    mu = np.sqrt(np.clip(1 - X * X - r * r, 0, None))
    true = np.abs(X * s0 + r * s1 + s2 * mu) < 1e-7
    return np.where(true & (disc >= 0) & (X * X + r * r <= 1), r, np.nan)


def cell_integrals(shape, centre_uv, radius_px, sun, law, phase, n):
    """Integrals of the law over cells of 1/n px: array (rows n, cols n), in px^2."""
    rows, cols = shape
    uc, vc = centre_uv
    R = radius_px
    cu = (np.arange(cols * n) + 0.5) / n - 0.5            # cell centres
    cv = (np.arange(rows * n) + 0.5) / n - 0.5
    h = 1.0 / n
    out = np.zeros((rows * n, cols * n))
    # only the columns and rows that meet the disk
    jc = np.nonzero(np.abs(cu - uc) < R + h)[0]
    ir = np.nonzero(np.abs(cv - vc) < R + h)[0]
    va, vb = cv[ir] - h / 2, cv[ir] + h / 2                 # cell edges (m,)
    xg, wg = _GL3
    tg, tw = _GL4
    for k in range(3):
        u = cu[jc] + xg[k] * h / 2                           # (p,) u-nodes of the cells
        X = (u - uc) / R
        half = np.sqrt(np.clip(1 - X * X, 0, None))
        br = np.concatenate([np.stack([-half, half]), _terminator_roots(X, sun)])  # (4, p)
        vbr = vc + R * br                                    # breakpoints in v
        lo = np.broadcast_to(va[:, None], (len(ir), len(jc)))
        hi = np.broadcast_to(vb[:, None], (len(ir), len(jc)))
        pts = np.concatenate([lo[None], np.clip(np.nan_to_num(vbr, nan=-1e30)[:, None, :],
                                                lo, hi), hi[None]])
        pts = np.sort(pts, axis=0)                           # (6, m, p): 5 pieces
        acc = np.zeros((len(ir), len(jc)))
        for a, b in zip(pts[:-1], pts[1:]):
            L = b - a
            for t, wt in zip(tg, tw):
                v = a + (t + 1) / 2 * L
                Y = (v - vc) / R
                rho2 = X[None, :] ** 2 + Y * Y
                inside = rho2 < 1
                mu = np.sqrt(np.where(inside, 1 - rho2, 0.0))
                mu0 = X[None, :] * sun[0] + Y * sun[1] + mu * sun[2]
                f = np.where(inside, brightness(law, mu0, mu, phase), 0.0)
                acc += wt * L / 2 * f
        out[np.ix_(ir, jc)] += wg[k] * h / 2 * acc
    return out


def _psf_matrix(n_px, n, sigma):
    """K (n_px, n_px n): weight of each cell centre on each pixel (Gaussian PSF (x) box)."""
    centres = (np.arange(n_px * n) + 0.5) / n - 0.5
    t = centres[None, :] - np.arange(n_px)[:, None]
    if sigma <= 0:
        return (np.abs(t) < 0.5).astype(float)
    return ndtr((t + 0.5) / sigma) - ndtr((t - 0.5) / sigma)


def render(shape, centre_uv, radius_px, phase_deg, sun_angle_deg, law="lommel-seeliger",
           sigma_px=0.7, peak=3000.0, background=100.0, noise_sigma=0.0, rng=None,
           saturation=None, n=None):
    """An image of a phased Moon of known centre, per-pixel integrated (see module).

    ``peak`` is the brightest pixel of the blurred Moon above the sky before clipping
    (None: no scaling, the pixels hold the law's integral in px^2);
    ``saturation`` (counts) clips the image (after the noise); ``n`` cells per px
    (default 8 for radii under 15 px, else 4).  Returns float64 (rows, cols).
    """
    a, b = np.deg2rad(phase_deg), np.deg2rad(sun_angle_deg)
    sun = (np.sin(a) * np.cos(b), np.sin(a) * np.sin(b), np.cos(a))
    n = n or (8 if radius_px < 15 else 4)
    F = cell_integrals(shape, centre_uv, radius_px, sun, law, a, n)
    img = _psf_matrix(shape[0], n, sigma_px) @ F @ _psf_matrix(shape[1], n, sigma_px).T
    if peak is not None:
        img *= peak / img.max()
    img += background
    if noise_sigma > 0:
        img += np.random.default_rng(rng).normal(0, noise_sigma, shape)
    if saturation is not None:
        img = np.minimum(img, saturation)
    return img
