"""Final centre of the Moon: least-squares fit of a blurred, phased disk to the lit limb.

The half-peak crossing of the bright rim is not the limb: the Moon's brightness rises
towards the lit limb like ``1 - sqrt(2 (R - r) / R) / mu0`` (Lommel-Seeliger), and the
blur moves the half-peak point by an amount that depends on ``mu0`` along the limb, so
on a phased Moon the ray centre is pulled along the Sun's direction (0.03-0.2 px).  Here
the pixels of a band around the lit limb (``|r - R| < w``, within ``half_width`` of the
Sun's direction: the terminator is left out) are fitted by the model

    I = B + (A1 G_sigma + A2 G_(WING sigma)) * LS_disk(centre, R; Sun direction, phase),

binned to pixels, with the Sun's direction and the phase angle known (ephemeris) and
centre, radius, blur ``sigma``, amplitudes ``A1, A2`` and sky ``B`` unknown
(Gauss-Newton, forward-difference Jacobian for the non-linear parameters).  The disk is computed on a
``SUPERSAMPLE``-times finer grid with an anti-aliased edge (linear coverage ramp one
sub-pixel wide), so the model is smooth in the centre.  With a camera the disk is the
cone of the semidiameter around the Moon's direction (exact off-axis in a fisheye).

The PSF is a Gaussian core plus a Gaussian wing ``WING`` times wider, with free
amplitudes: enough to follow a Moffat-like PSF (tests render with a Moffat, which this
model does not contain).  The centre's covariance is ``s^2 (J^T J)^-1`` with ``s^2``
the residual variance per pixel (white pixel noise), plus ``FLOOR_PX^2`` per axis for
the PSF-form mismatch and pixel phase (0.01-0.02 px RMS on Moffat-rendered Moons).
"""
import numpy as np
from scipy import ndimage

from .render import shade

SUPERSAMPLE = 4
BAND_PX = 3.0          # half width of the limb band beyond 2.5 blur sigmas, px
WING = 3.0             # sigma of the PSF's wing component / core sigma
FLOOR_PX = 0.012       # centre error of the PSF-form mismatch (Moffat vs the fit), px
MARGIN_PX = 5          # model computed this far beyond the band, px (blur support)


def _grid(shape, n):
    """Sub-pixel positions (u, v), each shape (rows*n, cols*n), of a crop's pixels."""
    off = (np.arange(n) + 0.5) / n - 0.5
    u = (np.arange(shape[1])[:, None] + off[None, :]).ravel()
    v = (np.arange(shape[0])[:, None] + off[None, :]).ravel()
    return np.meshgrid(u, v)


class LimbModel:
    """Model of a crop of the image around the Moon.

    Parameters
    ----------
    crop : ndarray, shape (rows, cols)
        Image window (float), Moon inside with a margin of a few blur widths.
    uv0 : array_like, shape (2,)
        Initial centre in crop pixels.
    radius0 : float
        Initial radius, px.
    sun3 : callable or array_like
        Flat images: ``(sin a cos b, sin a sin b, cos a)`` for phase angle ``a`` and Sun
        position angle ``b`` on the image (basis +u, +v, towards the observer).
    camera : object, optional
        ``image_to_direction``, ``direction_to_image``, ``focal_length_px`` in crop pixels.
    sun_c : array_like, shape (3,), optional
        With a camera: direction from the Moon to the Sun in the camera frame.
    sun_angle : float
        Sun's direction on the image, rad from +u towards +v (selects the lit limb band).
    half_width : float
        Half width of the limb arc used, rad.
    """

    def __init__(self, crop, uv0, radius0, sun3=None, camera=None, sun_c=None,
                 sun_angle=0.0, half_width=np.deg2rad(80.0), blur0=0.8):
        self.n = SUPERSAMPLE
        self.camera = camera
        rows, cols = np.mgrid[0:crop.shape[0], 0:crop.shape[1]]
        du, dv = cols - uv0[0], rows - uv0[1]
        r = np.hypot(du, dv)
        dang = np.angle(np.exp(1j * (np.arctan2(dv, du) - sun_angle)))
        mask = (np.abs(r - radius0) < BAND_PX + 2.5 * blur0) & (np.abs(dang) <= half_width)
        # compute the model on the band's bounding box plus room for the blur
        rr, cc = np.nonzero(mask)
        pad = MARGIN_PX
        r0, r1 = max(rr.min() - pad, 0), min(rr.max() + pad + 1, crop.shape[0])
        c0, c1 = max(cc.min() - pad, 0), min(cc.max() + pad + 1, crop.shape[1])
        self.shape = (r1 - r0, c1 - c0)
        self.mask = mask[r0:r1, c0:c1]
        self.data = np.asarray(crop, float)[r0:r1, c0:c1][self.mask]
        u, v = _grid(self.shape, self.n)
        u, v = u + c0, v + r0
        if camera is None:
            self.u, self.v = u, v
            self.sun3 = np.asarray(sun3, float)
            self.scale = 1.0
        else:
            f = camera.focal_length_px
            self.d0 = camera.image_to_direction(np.asarray(uv0, float))
            a = [1.0, 0.0, 0.0] if abs(self.d0[0]) < 0.9 else [0.0, 1.0, 0.0]
            self.e1 = np.cross(self.d0, a)
            self.e1 /= np.linalg.norm(self.e1)
            self.e2 = np.cross(self.d0, self.e1)
            self.P = camera.image_to_direction(np.stack([u, v], axis=-1))
            self.sun_c = np.asarray(sun_c, float) / np.linalg.norm(sun_c)
            J = camera.direction_jacobian(np.asarray(uv0, float))[0]
            # local px per rad over f: converts the angular edge distance to px
            self.scale = 1.0 / (f * abs(np.linalg.det(J.T @ J)) ** 0.25)

    def _disk(self, c1, c2, R):
        """Sub-pixel brightness of the unblurred disk (anti-aliased edge)."""
        if self.camera is None:
            X, Y = (self.u - c1) / R, (self.v - c2) / R
            rho = np.hypot(X, Y)
            d_sub = (1.0 - rho) * R * self.n                # signed distance, sub-pixels
            sun3 = self.sun3
        else:
            f = self.camera.focal_length_px
            m = self.d0 + (c1 / f) * self.e1 + (c2 / f) * self.e2
            m /= np.linalg.norm(m)
            e1 = self.e1 - (self.e1 @ m) * m
            e1 /= np.linalg.norm(e1)
            e2 = np.cross(m, e1)
            sin_r = np.sin(R / f)
            X, Y = self.P @ e1 / sin_r, self.P @ e2 / sin_r
            rho = np.hypot(X, Y)
            d_sub = (1.0 - rho) * R * self.scale * self.n
            s = self.sun_c
            sun3 = np.array([s @ e1, s @ e2, -(s @ m)])
        k = np.minimum(1.0, (1.0 - 1e-9) / np.maximum(rho, 1e-12))   # clip to the limb
        cover = np.clip(0.5 + d_sub, 0.0, 1.0)
        return shade(X * k, Y * k, sun3) * cover

    def flux(self, q):
        """Unit-amplitude models of the masked pixels, shape (m, 2): the disk blurred by
        a Gaussian of sigma ``q[3]`` and by one of ``WING * q[3]`` (core and wings of the
        PSF), for ``q = (c1, c2, R, sigma)``."""
        disk = self._disk(q[0], q[1], q[2])
        rows, cols = self.shape
        core = ndimage.gaussian_filter(disk, abs(q[3]) * self.n, mode="constant", truncate=3.5)
        core = core.reshape(rows, self.n, cols, self.n).mean(axis=(1, 3))
        binned = disk.reshape(rows, self.n, cols, self.n).mean(axis=(1, 3))
        # the wide wing is smooth on the pixel scale: blurred after binning
        wing = ndimage.gaussian_filter(binned, WING * abs(q[3]), mode="constant", truncate=3.5)
        return np.stack([core[self.mask], wing[self.mask]], axis=-1)

    def centre(self, p):
        """Centre (u, v) in crop pixels of parameters ``p``."""
        if self.camera is None:
            return np.array([p[0], p[1]])
        f = self.camera.focal_length_px
        return self.camera.direction_to_image(self.d0 + (p[0] / f) * self.e1
                                              + (p[1] / f) * self.e2)


def _design(model, q, a, step=1e-3):
    """Model (m,) for linear parameters ``a = (A1, A2, B)`` and the Jacobian (m, 7) with
    respect to ``(q, a)`` (forward differences in ``q``)."""
    m0 = model.flux(q)
    cols = []
    for k in range(len(q)):
        dq = np.zeros(len(q))
        dq[k] = step
        cols.append((model.flux(q + dq) - m0) @ a[:2] / step)
    J = np.column_stack(cols + [m0, np.ones(len(m0))])
    return m0 @ a[:2] + a[2], J


def fit_limb_model(model, uv0, radius0, blur0=0.8, iterations=10, tol_px=5e-4):
    """Gauss-Newton fit; returns (centre uv, cov uv, radius, blur, rms, n_pixels).

    ``uv0`` is the initial centre (crop pixels); with a camera the centre parameters are
    offsets of the Moon's direction from it, scaled to px by the focal length.  The
    amplitudes of the two PSF components and the sky enter linearly and are solved with
    the step.  ``blur`` is the core sigma, px.
    """
    c0 = np.zeros(2) if model.camera is not None else np.asarray(uv0, float)
    q = np.array([c0[0], c0[1], radius0, blur0])
    y = model.data
    m0 = model.flux(q)
    a = np.linalg.lstsq(np.column_stack([m0, np.ones(len(y))]), y, rcond=None)[0]
    for _ in range(iterations):
        pred, J = _design(model, q, a)
        dp = np.linalg.lstsq(J, y - pred, rcond=1e-10)[0]
        big = np.max(np.abs(dp[:3]))
        if big > 1.0:                              # keep the steps within the linear range
            dp = dp / big
        q, a = q + dp[:4], a + dp[4:]
        q[3] = np.clip(abs(q[3]), 0.05, 10.0)
        if big < tol_px:
            break
    pred, J = _design(model, q, a)
    r = y - pred
    dof = max(len(r) - J.shape[1], 1)
    s2 = float(r @ r) / dof
    cov_p = s2 * np.linalg.pinv(J.T @ J, rcond=1e-10)[:2, :2]
    G = np.empty((2, 2))
    for k in range(2):                      # centre(q) Jacobian (identity for flat images)
        dq = np.zeros(4)
        dq[k] = 1e-3
        G[:, k] = (model.centre(q + dq) - model.centre(q - dq)) / 2e-3
    cov = G @ cov_p @ G.T + FLOOR_PX ** 2 * np.eye(2)
    return model.centre(q), cov, float(q[2]), float(q[3]), float(np.sqrt(s2)), len(r)
