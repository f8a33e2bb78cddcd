"""Final centre of the Moon: least-squares fit of a blurred, phased disk to the lit limb,
with the photometric law fitted too.

The half-peak crossing of the bright rim is not the limb: how the brightness runs up to
the lit limb depends on the surface's photometric law (Lommel-Seeliger rises to the
limb like ``1 - sqrt(2 (R - r) / R) / mu0``, Lambert falls to ``mu0`` at it, a flat
disk is a step), and the blur moves the half-peak point by an amount that depends on
that profile and on ``mu0`` along the limb, so on a phased Moon the ray centre is pulled
along the Sun's direction (0.03-0.7 px).  Here the pixels of a band around the lit limb
(``|r - R| < w``, within ``half_width`` of the Sun's direction; saturated pixels left
out) are fitted by the model

    I = B + sum_l (A_l1 G_sigma + A_l2 G_(WING sigma)) * disk_l(centre, R; Sun, phase),

where ``disk_l`` are the phased disks of four basis laws (`_limb_kernels.LAWS`: flat,
Lambert ``mu0``, Lommel-Seeliger ``LS = mu0 / (mu0 + mu)`` and Hapke's isotropic
multiple scattering ``LS (H(mu0) H(mu) - 1)`` with ``H(x) = (1 + 2 x) / (1 + 2 gamma
x)``, ``gamma = sqrt(1 - w)``, ``w = _limb_kernels.HAPKE_W`` = 0.25) with free, linear
weights: the law is fitted, not assumed.  The span holds the lunar-Lambert (McEwen)
family ``(1 - L) mu0 + 2 L mu0 / (mu0 + mu)`` exactly, and Hapke's law
``w/4 LS ((1 + B(g)) p(g) + H(mu0) H(mu) - 1)`` of that albedo exactly whatever its
phase function ``p`` and opposition surge ``B`` (constants within one image), as a
non-negative mix (other albedos: to first order in ``H - 1``, which ``LS`` and ``mu0``
span).  The geometry (limb circle, the terminator from the known phase) is the same for
every law, so the centre is measured by the lit limb's position whatever the shading
(bench/bench_lunar_bias.py: under 0.01 px for those laws, Hapke-like included, on an
independent renderer; the three-law basis left 0.021-0.030 px on a Hapke-like 40 px
Moon at phase 120-140 deg).  The
model is binned to pixels, with the Sun's direction and the phase angle known
(ephemeris) and centre, radius, blur ``sigma``, the amplitudes ``A`` (non-negative) and
sky ``B`` unknown: separable least squares, the amplitudes by NNLS at each step and
Gauss-Newton on the rest with their effect projected out (variable projection), from the
best start of a scan along the Sun's direction and over the blur (a thin crescent's
limb circle can be 1 px off); analytic Jacobian of the discretized model, compiled kernels
in `_limb_kernels`.  The disk is computed on a ``SUPERSAMPLE``-times finer grid with an
anti-aliased edge (linear coverage ramp one sub-pixel wide; 4 sub-pixels left a
0.01 px bias on the Lommel-Seeliger limb's cusp, 8 do not), so the model is smooth in
the centre.  With a camera the disk is the cone of the semidiameter around the Moon's
direction (exact off-axis in a fisheye), flattened by refraction when asked (an
ellipse on the sky with axes along the horizon and the vertical).

With one limb only, the centre along the Sun and the radius are nearly degenerate: a
PSF-form mismatch moves both (0.04 px on a 3.7 px Moon).  The ephemeris knows the
semidiameter; with a camera it enters as a prior on ``R`` (``radius_prior``), which
removes that error and makes the centre's sigma honest.

The PSF is a Gaussian core plus a Gaussian wing ``WING`` times wider, with free
amplitudes: enough to follow a Moffat-like PSF (tests render with a Moffat, which this
model does not contain).  The centre's covariance is ``s^2 (J^T J)^-1`` with ``s^2``
the residual variance per pixel (white pixel noise), plus ``FLOOR_PX^2`` per axis for
the PSF-form mismatch and pixel phase (0.01-0.02 px RMS on Moffat-rendered Moons).
"""
import numpy as np
from scipy.optimize import nnls

from photogrammetry.lunar import _limb_kernels as _k

SUPERSAMPLE = 8
BAND_PX = 3.0          # half width of the limb band beyond 2.5 blur sigmas, px
WING = 3.0             # sigma of the PSF's wing component / core sigma
FLOOR_PX = 0.012       # centre error of the PSF-form mismatch (Moffat vs the fit), px
MARGIN_PX = 5          # model computed this far beyond the band, px (blur support)
TRUNCATE = 3.5         # Gaussian kernels cut at this many sigmas


def _grid(shape, n):
    """Sub-pixel positions (u, v), each shape (rows*n, cols*n), of a crop's pixels."""
    off = (np.arange(n) + 0.5) / n - 0.5
    u = (np.arange(shape[1])[:, None] + off[None, :]).ravel()
    v = (np.arange(shape[0])[:, None] + off[None, :]).ravel()
    return np.meshgrid(u, v)


def _gauss(sd):
    """Normalized sampled Gaussian of sigma ``sd`` (samples), its derivative in ``sd``, half
    length (as ``scipy.ndimage.gaussian_filter`` with ``truncate=TRUNCATE``)."""
    h = int(TRUNCATE * sd + 0.5)
    j2 = np.arange(-h, h + 1.0) ** 2
    g = np.exp(-0.5 * j2 / sd ** 2)
    g /= g.sum()
    return g, g * (j2 - g @ j2) / sd ** 3, h


def _blur(S, kern, dkern, n, off, shape, deriv=True):
    """Separable blur of the stack ``S`` (a, H, W) by ``kern`` x ``kern`` with binning by
    ``n``; returns (blurred stack, derivative of ``S[0]``'s blur via ``dkern`` or None)."""
    rows, cols = shape
    T = _k.row_pass(S, kern, n, off, cols)
    out = _k.col_pass(T, kern, n, off, rows)
    if not deriv:
        return out, None
    d = (_k.col_pass(T[:1], dkern, n, off, rows)
         + _k.col_pass(_k.row_pass(S[:1], dkern, n, off, cols), kern, n, off, rows))
    return out, d[0]


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
    sun3 : array_like, optional
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
    saturation : float, optional
        Pixels at or above this level (counts) are left out of the fit.
    flattening : (float, float, array_like), optional
        With a camera: ``(k_h, k_v, up_c)``, the refracted disk's horizontal and vertical
        semi-axes over the semidiameter (`ephemeris.refraction_flattening`) and the
        zenith's direction in the camera frame: the limb is that ellipse on the sky.
    """

    def __init__(self, crop, uv0, radius0, sun3=None, camera=None, sun_c=None,
                 sun_angle=0.0, half_width=np.deg2rad(80.0), blur0=0.8, saturation=None,
                 flattening=None):
        self.n = SUPERSAMPLE
        self.camera = camera
        rows, cols = np.mgrid[0:crop.shape[0], 0:crop.shape[1]]
        du, dv = cols - uv0[0], rows - uv0[1]
        r = np.hypot(du, dv)
        dang = np.angle(np.exp(1j * (np.arctan2(dv, du) - sun_angle)))
        mask = (np.abs(r - radius0) < BAND_PX + 2.5 * blur0) & (np.abs(dang) <= half_width)
        if saturation is not None:            # clipped pixels say only "at least this"
            mask &= np.asarray(crop) < saturation
        if mask.sum() < 12:
            raise ValueError("fewer than 12 unsaturated pixels on the lit limb")
        # compute the model on the band's bounding box plus room for the blur
        rr, cc = np.nonzero(mask)
        pad = MARGIN_PX
        r0, r1 = max(rr.min() - pad, 0), min(rr.max() + pad + 1, crop.shape[0])
        c0, c1 = max(cc.min() - pad, 0), min(cc.max() + pad + 1, crop.shape[1])
        self.shape = (r1 - r0, c1 - c0)
        self.mask = mask[r0:r1, c0:c1]
        self.data = np.asarray(crop, float)[r0:r1, c0:c1][self.mask]
        u, v = _grid(self.shape, self.n)
        u, v = u.ravel() + c0, v.ravel() + r0
        if camera is None:
            self.P = np.stack([u, v, np.zeros_like(u)], axis=-1)
            self.sun3 = np.asarray(sun3, float)
            self.scale = 1.0
        else:
            f = camera.focal_length_px
            self.d0 = camera.image_to_direction(np.asarray(uv0, float))
            self.k_xy = (1.0, 1.0)
            up = None
            if flattening is not None:
                up = np.asarray(flattening[2], float)
                up = up - (up @ self.d0) * self.d0
                self.k_xy = (1.0 / flattening[0], 1.0 / flattening[1])
            if up is not None and np.linalg.norm(up) > 1e-6:
                self.e2 = up / np.linalg.norm(up)           # vertical on the sky
                self.e1 = _k.cross3(self.e2, self.d0)       # horizontal
            else:
                a = [1.0, 0.0, 0.0] if abs(self.d0[0]) < 0.9 else [0.0, 1.0, 0.0]
                self.e1 = _k.cross3(self.d0, np.array(a))
                self.e1 /= np.linalg.norm(self.e1)
                self.e2 = _k.cross3(self.d0, self.e1)
            self.P = np.ascontiguousarray(camera.image_to_direction(np.stack([u, v], axis=-1)))
            self.sun_c = np.asarray(sun_c, float) / np.linalg.norm(sun_c)
            J = camera.direction_jacobian(np.asarray(uv0, float))[0]
            # local px per rad over f: converts the angular edge distance to px
            self.scale = 1.0 / (f * abs(np.linalg.det(J.T @ J)) ** 0.25)

    def _frame(self, c1, c2):
        """Camera case: (e1, e2, sun3) of the Moon direction offset by ``(c1, c2)`` px."""
        f = self.camera.focal_length_px
        m = self.d0 + (c1 / f) * self.e1 + (c2 / f) * self.e2
        m /= np.linalg.norm(m)
        e1 = self.e1 - (self.e1 @ m) * m
        e1 /= np.linalg.norm(e1)
        e2 = _k.cross3(m, e1)
        s = self.sun_c
        return e1, e2, np.array([s @ e1, s @ e2, -(s @ m)])

    def _disk(self, q):
        """Disks of the basis laws (L, N) at the sub-pixels and their derivatives (L, 3, N)
        in ``(c1, c2, R)``."""
        N = len(self.P)
        L = len(_k.LAWS)
        D, dD = np.empty((L, N)), np.empty((L, 3, N))
        z3, z23 = np.zeros(3), np.zeros((2, 3))
        if self.camera is None:
            _k.disk_jac(self.P, True, q[0], q[1], q[2], z3, z3, z23, z23, self.sun3, z23,
                        1.0, 1.0, 1.0, 1.0, self.n, D, dD)
            return D, dD
        f, h = self.camera.focal_length_px, 1e-3
        e1, e2, sun3 = self._frame(q[0], q[1])
        d = [np.subtract(self._frame(q[0] + h * (k == 0), q[1] + h * (k == 1)),
                         self._frame(q[0] - h * (k == 0), q[1] - h * (k == 1))) / (2 * h)
             for k in range(2)]
        de1, de2, ds = (np.array([d[0][j], d[1][j]]) for j in range(3))
        kx, ky = self.k_xy                   # the refracted disk: an ellipse on the sky
        e1, e2, de1, de2 = e1 * kx, e2 * ky, de1 * kx, de2 * ky
        _k.disk_jac(self.P, False, q[0], q[1], q[2], e1, e2, de1, de2, sun3, ds,
                    np.sin(q[2] / f), np.cos(q[2] / f), f, self.scale, self.n, D, dD)
        return D, dD

    def flux(self, q, jacobian=False):
        """Unit-amplitude models of the masked pixels, shape (m, 2 L): for each basis law
        (`_limb_kernels.LAWS`) its disk blurred by a Gaussian of sigma ``q[3]`` and by one
        of ``WING * q[3]`` (core and wings of the PSF), for ``q = (c1, c2, R, sigma)``.
        With ``jacobian``, also their derivatives in ``q``, shape (m, 2 L, 4)."""
        D, dD = self._disk(q)
        n, s = self.n, abs(q[3])
        g, dg, h = _gauss(s * n)
        box = np.full(n, 1.0 / n)
        gw, dgw, hw = _gauss(WING * s)
        m = self.mask
        cols, jacs = [], []
        for law in range(len(D)):
            S = (np.concatenate([D[law][None], dD[law]]) if jacobian
                 else D[law][None]).reshape(4 if jacobian else 1, self.shape[0] * n, -1)
            core, core_s = _blur(S, np.convolve(g, box), np.convolve(dg, box), n, h,
                                 self.shape, jacobian)
            binned = _k.col_pass(_k.row_pass(S, box, n, 0, self.shape[1]), box, n, 0,
                                 self.shape[0])
            # the wide wing is smooth on the pixel scale: blurred after binning
            wing, wing_s = _blur(binned, gw, dgw, 1, hw, self.shape, jacobian)
            cols += [core[0][m], wing[0][m]]
            if jacobian:
                jc = np.empty((m.sum(), 4))
                jw = np.empty((m.sum(), 4))
                jc[:, :3], jw[:, :3] = core[1:, m].T, wing[1:, m].T
                jc[:, 3], jw[:, 3] = n * core_s[m], WING * wing_s[m]
                jacs += [jc, jw]
        out = np.stack(cols, axis=-1)
        if not jacobian:
            return out
        return out, np.stack(jacs, axis=1)

    def centre(self, p):
        """Centre (u, v) in crop pixels of parameters ``p``."""
        if self.camera is None:
            return np.array([p[0], p[1]])
        f = self.camera.focal_length_px
        return self.camera.direction_to_image(self.d0 + (p[0] / f) * self.e1
                                              + (p[1] / f) * self.e2)


def _amplitudes(m0, y):
    """Non-negative amplitudes of the laws' PSF components (NNLS) and the free sky level:
    ``a = (A_1 .. A_2L, B)``.  Physical laws are non-negative mixes of the basis laws;
    free signs would let a thin crescent's nearly collinear columns build any profile."""
    ones = np.ones((len(y), 1))
    a, _ = nnls(np.hstack([m0, ones, -ones]), y, maxiter=50 * m0.shape[1])
    return np.append(a[:-2], a[-2] - a[-1])


def _projected(model, q, y):
    """Residuals (m,), the Jacobian in ``q`` with the active amplitudes projected out
    (variable projection, Kaufman's form; (m, 4)) and the number of active amplitudes."""
    m0, dm = model.flux(q, jacobian=True)
    a = _amplitudes(m0, y)
    r = y - m0 @ a[:-1] - a[-1]
    Jq = np.einsum("mjk,j->mk", dm, a[:-1])
    act = np.column_stack([m0[:, a[:-1] > 0], np.ones(len(y))])
    Jq = Jq - act @ np.linalg.lstsq(act, Jq, rcond=1e-10)[0]
    return r, Jq, act.shape[1]


def _sse(model, q, y):
    """Sum of squared residuals at ``q`` with the amplitudes solved (NNLS)."""
    m0 = model.flux(q)
    a = _amplitudes(m0, y)
    r = y - m0 @ a[:-1] - a[-1]
    return float(r @ r)


SCAN_PX = np.arange(-1.5, 1.51, 0.25)     # start offsets tried along the Sun, px
SCAN_BLUR = (0.5, 0.8, 1.3, 2.0)          # start blurs tried, px


def _scan(model, q):
    """The start ``q`` moved along the Sun's direction by the offset of `SCAN_PX` (and
    with the blur of `SCAN_BLUR`) whose model fits best: the limb circle of a thin or dim
    crescent can be 1 px off, beyond the reach of Gauss-Newton."""
    sun = model.sun3[:2] if model.camera is None else model._frame(0.0, 0.0)[2][:2]
    norm = np.hypot(sun[0], sun[1])
    y = model.data
    offsets = SCAN_PX if norm > 1e-6 else [0.0]
    def moved(q, d, blur):
        qd = q.copy()
        qd[3] = blur
        if norm > 1e-6:
            qd[:2] += d * sun / norm
        return qd

    # offsets at the start blur, then the blurs at the best offset, then the offsets again
    best = min(((_sse(model, moved(q, d, q[3]), y), d) for d in offsets))
    blur = min(((_sse(model, moved(q, best[1], b), y), b) for b in SCAN_BLUR))[1]
    if blur != q[3]:
        best = min(((_sse(model, moved(q, d, blur), y), d) for d in offsets))
    return moved(q, best[1], blur)


def fit_limb_model(model, uv0, radius0, blur0=0.8, iterations=20, tol_px=5e-4,
                   radius_prior=None):
    """Separable least squares; returns (centre uv, cov uv, radius, blur, rms, n_pixels).

    ``uv0`` is the initial centre (crop pixels); with a camera the centre parameters are
    offsets of the Moon's direction from it, scaled to px by the focal length.  The
    amplitudes of the laws' PSF components (non-negative) and the sky enter linearly and
    are solved at each step (NNLS); Gauss-Newton on ``q = (c1, c2, R, blur)`` with their
    effect projected out (variable projection).  ``blur`` is the core sigma, px.
    ``radius_prior = (R, sigma)`` (px) adds the known radius as an observation (weighted
    against the pixel residual variance).  The start is the best of a scan along the
    Sun's direction and over the blur (`_scan`).
    """
    c0 = np.zeros(2) if model.camera is not None else np.asarray(uv0, float)
    y = model.data
    q = _scan(model, np.array([c0[0], c0[1], radius0, blur0]))

    def system(q):
        r, J, n_act = _projected(model, q, y)
        s2 = max(float(r @ r) / max(len(r) - 4 - n_act, 1), 1e-12)
        if radius_prior is None:
            return r, J, r, J, s2
        w = np.sqrt(s2) / radius_prior[1]             # prior row in pixel-noise units
        row = np.array([[0.0, 0.0, w, 0.0]])
        return (np.append(r, w * (radius_prior[0] - q[2])), np.vstack([J, row]), r, J, s2)

    for _ in range(iterations):
        rr, JJ, r, _, s2 = system(q)
        dp = np.linalg.lstsq(JJ, rr, rcond=1e-10)[0]
        big = np.max(np.abs(dp[:3]))
        if big > 1.0:                              # keep the steps within the linear range
            dp = dp / big
        q = q + dp
        q[3] = np.clip(abs(q[3]), 0.05, 10.0)
        if big < tol_px:
            break
    rr, JJ, r, J, s2 = system(q)
    N = J.T @ J
    if radius_prior is not None:
        N[2, 2] += s2 / radius_prior[1] ** 2
    cov_p = s2 * np.linalg.pinv(N, rcond=1e-10)[:2, :2]
    G = np.empty((2, 2))
    for k in range(2):                      # centre(q) Jacobian (identity for flat images)
        dq = np.zeros(4)
        dq[k] = 1e-3
        G[:, k] = (model.centre(q + dq) - model.centre(q - dq)) / 2e-3
    cov = G @ cov_p @ G.T + FLOOR_PX ** 2 * np.eye(2)
    return model.centre(q), cov, float(q[2]), float(q[3]), float(np.sqrt(s2)), len(r)
