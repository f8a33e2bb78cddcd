"""Synthetic Moon images with phase and a sharp lit limb: ``photogrammetry lunar-simulate``
(a session of images to try ``lunar-heading`` on), the tests and the benchmarks.

Photometry: Lommel-Seeliger by default, ``I = mu0 / (mu0 + mu)`` on the lit part of the
visible hemisphere (``mu0``, ``mu`` the cosines of incidence and emission): the lit limb
stays bright, the terminator fades to zero, as on the real Moon; Lambert, flat and a
Hapke-like law on request (`SHADING_LAWS`).  The disk is point-sampled on a
supersampled grid with hard edges, blurred there by a point-spread function (a Gaussian,
or a Moffat profile: a PSF form the centre fit does not assume), binned to pixels and
given Gaussian read noise.  (The bias of the centre fit is measured on the per-pixel
integrating renderer of ``tests/lunar_truth.py``, which shares no code with this one.)

Two geometries share the shading: a flat disk of given centre and radius in pixels
(``render_moon``), and the Moon seen through a fisheye camera, where the disk is the cone
of the apparent semidiameter around the Moon's direction (``render_moon_fisheye``).
A session is a series of the latter at the ephemeris' directions for a camera of known
orientation (``camera_attitude``, ``render_session``).
"""
import numpy as np
from scipy import ndimage, signal

__all__ = ["render_moon", "render_moon_fisheye", "render_session", "session_image",
           "camera_attitude", "shade", "SHADING_LAWS"]


#: Shading laws of the renderer (``shade``): Lommel-Seeliger ``mu0 / (mu0 + mu)`` (the
#: default: a bright lit limb, close to the real Moon), Lambert ``mu0`` (limb-darkened),
#: flat (1 on the lit part) and a Hapke-like law (Lommel-Seeliger times
#: ``(1 + B) P - 1 + H(mu0) H(mu)`` with single-scattering albedo 0.25, Hapke's
#: H-function approximation, an opposition surge ``B`` of amplitude 1 and width 0.06 and a
#: Henyey-Greenstein phase function ``P`` of asymmetry -0.3).
SHADING_LAWS = ("lommel-seeliger", "lambert", "flat", "hapke")


def shade(X, Y, sun3, law="lommel-seeliger"):
    """Brightness of the disk at normalized coordinates.

    Parameters
    ----------
    X, Y : ndarray
        Sky-plane coordinates in units of the disk radius (limb at ``X**2 + Y**2 = 1``).
    sun3 : array_like, shape (3,)
        Unit vector from the Moon to the Sun in the basis (X axis, Y axis, towards the
        observer); its angle to the third axis is the phase angle.
    law : str
        One of `SHADING_LAWS`.

    Returns
    -------
    ndarray
        Brightness (1 for the full lit limb of Lommel-Seeliger and flat); 0 outside the
        disk and on the night side.
    """
    rho2 = X * X + Y * Y
    inside = rho2 < 1.0
    mu = np.sqrt(np.where(inside, 1.0 - rho2, 0.0))
    mu0 = X * sun3[0] + Y * sun3[1] + mu * sun3[2]
    lit = inside & (mu0 > 0)
    m0 = np.where(lit, mu0, 0.0)
    ls = m0 / np.where(lit, m0 + mu, 1.0)
    if law == "lommel-seeliger":
        out = ls
    elif law == "lambert":
        out = m0
    elif law == "flat":
        out = np.ones_like(m0)
    elif law == "hapke":
        gamma = np.sqrt(1 - 0.25)
        g = np.arccos(np.clip(sun3[2], -1.0, 1.0))

        def H(x):
            return (1 + 2 * x) / (1 + 2 * gamma * x)
        p = (1 - 0.09) / (1 - 0.6 * np.cos(g) + 0.09) ** 1.5
        surge = 1.0 / (1 + np.tan(g / 2) / 0.06)
        out = ls * ((1 + surge) * p - 1 + H(m0) * H(mu)) / ((1 + surge) * p)
    else:
        raise ValueError(f"law must be one of {', '.join(SHADING_LAWS)}, not {law!r}")
    return np.where(lit, out, 0.0)


MOFFAT_BETA = 3.0


def _moffat_kernel(sigma_px, n):
    """Moffat PSF (beta 3) of the FWHM of a Gaussian of ``sigma_px``, sampled n per px."""
    fwhm = 2 * np.sqrt(2 * np.log(2)) * sigma_px
    alpha = fwhm / (2 * np.sqrt(2 ** (1 / MOFFAT_BETA) - 1))
    half = int(np.ceil(5 * fwhm * n))
    x = (np.arange(-half, half + 1)) / n
    k = (1 + (x[:, None] ** 2 + x[None, :] ** 2) / alpha ** 2) ** -MOFFAT_BETA
    return k / k.sum()


def _blur_sub(flux_sub, psf, psf_sigma_px, n):
    """Blur on the supersampled grid: a continuous PSF, the same for every position of the
    Moon on the pixels (a Gaussian applied to the binned pixels would be a staircase)."""
    if psf_sigma_px <= 0:
        return flux_sub
    if psf == "gaussian":
        return ndimage.gaussian_filter(flux_sub, psf_sigma_px * n, mode="constant")
    if psf != "moffat":
        raise ValueError(f"psf must be 'gaussian' or 'moffat', not {psf!r}")
    return signal.fftconvolve(flux_sub, _moffat_kernel(psf_sigma_px, n), mode="same")


def _margin(psf, psf_sigma_px):
    return (12.0 if psf == "moffat" else 4.0) * psf_sigma_px + 3


def _finish(flux, shape, box, peak, background, psf_sigma_px, noise_sigma, rng, dtype,
            psf="gaussian"):
    img = np.full(shape, float(background))
    r0, r1, c0, c1 = box
    img[r0:r1, c0:c1] += peak * flux
    if noise_sigma > 0:
        rng = np.random.default_rng(rng)
        img += rng.normal(0.0, noise_sigma, shape)
    if np.issubdtype(np.dtype(dtype), np.integer):
        info = np.iinfo(dtype)
        img = np.clip(np.rint(img), info.min, info.max)
    return img.astype(dtype)


def _box(shape, centre_uv, half):
    c0 = max(int(np.floor(centre_uv[0] - half)), 0)
    c1 = min(int(np.ceil(centre_uv[0] + half)) + 1, shape[1])
    r0 = max(int(np.floor(centre_uv[1] - half)), 0)
    r1 = min(int(np.ceil(centre_uv[1] + half)) + 1, shape[0])
    return r0, r1, c0, c1


def _subpixels(box, n):
    """Sub-pixel sample positions of a box: (u, v) arrays of shape (rows*n, cols*n)."""
    r0, r1, c0, c1 = box
    off = (np.arange(n) + 0.5) / n - 0.5
    u = (np.arange(c0, c1)[:, None] + off[None, :]).ravel()
    v = (np.arange(r0, r1)[:, None] + off[None, :]).ravel()
    return np.meshgrid(u, v)


def _bin(a, n):
    rows, cols = a.shape[0] // n, a.shape[1] // n
    return a.reshape(rows, n, cols, n).mean(axis=(1, 3))


def render_moon(shape, centre_uv, radius_px, phase_angle_deg, sun_angle_deg, peak=3000.0,
                background=100.0, psf_sigma_px=0.7, noise_sigma=0.0, supersample=8, rng=None,
                dtype=np.uint16, psf="gaussian", shading="lommel-seeliger"):
    """A Moon disk of known centre on a flat image.

    Parameters
    ----------
    shape : tuple of int
        ``(rows, columns)``.
    centre_uv : (float, float)
        True centre, column ``u`` and row ``v``, px (pixel centres at integers).
    radius_px : float
        Disk radius, px.
    phase_angle_deg : float
        Sun-Moon-observer angle, deg (0 = full, 90 = quarter).
    sun_angle_deg : float
        Direction of the Sun on the image, deg, measured from the +u axis towards +v.
    peak, background, noise_sigma : float
        Brightness of a fully lit limb, sky level and read noise, in counts.
    psf_sigma_px : float
        Blur, px: the Gaussian's sigma (for "moffat": a Moffat of the same FWHM).
    psf : {"gaussian", "moffat"}
        PSF form; "moffat" (beta 3, wider wings) is applied on the supersampled grid.
    supersample : int
        Sub-samples per pixel and axis.
    rng : int or numpy.random.Generator, optional
    dtype : numpy dtype
        Output type (integers are rounded and clipped).
    shading : str
        Photometric law, one of `SHADING_LAWS`.

    Returns
    -------
    ndarray, shape ``shape``
    """
    a, b = np.deg2rad(phase_angle_deg), np.deg2rad(sun_angle_deg)
    sun3 = (np.sin(a) * np.cos(b), np.sin(a) * np.sin(b), np.cos(a))
    box = _box(shape, centre_uv, radius_px + _margin(psf, psf_sigma_px))
    u, v = _subpixels(box, supersample)
    flux = shade((u - centre_uv[0]) / radius_px, (v - centre_uv[1]) / radius_px, sun3,
                 shading)
    flux = _bin(_blur_sub(flux, psf, psf_sigma_px, supersample), supersample)
    return _finish(flux, shape, box, peak, background, psf_sigma_px, noise_sigma, rng, dtype,
                   psf)


def render_moon_fisheye(camera, moon_c, sun_c, semidiameter, peak=3000.0, background=100.0,
                        psf_sigma_px=0.7, noise_sigma=0.0, supersample=8, rng=None,
                        dtype=np.uint16, psf="gaussian", shading="lommel-seeliger",
                        flattening=None):
    """The Moon imaged by a fisheye camera (the disk follows the lens distortion).

    Parameters
    ----------
    camera : photogrammetry.lunar.fisheye.FisheyeCamera
    moon_c : array_like, shape (3,)
        Direction of the Moon's centre in the camera frame.
    sun_c : array_like, shape (3,)
        Direction from the Moon to the Sun in the camera frame (the direction to the Sun
        from the station is close enough).
    semidiameter : float
        Apparent semidiameter, rad.
    flattening : (float, float, array_like), optional
        ``(k_h, k_v, up_c)``: the disk's horizontal and vertical semi-axes over the
        semidiameter (refraction, ``ephemeris.refraction_flattening``) and the zenith's
        direction in the camera frame.
    Other parameters as for `render_moon`.

    Returns
    -------
    ndarray, shape ``(camera.height_px, camera.width_px)``
    """
    m = np.asarray(moon_c, float) / np.linalg.norm(moon_c)
    s = np.asarray(sun_c, float) / np.linalg.norm(sun_c)
    k_h = k_v = 1.0
    if flattening is not None:                 # e2 up the sky, e1 along the horizon
        k_h, k_v, up = flattening
        e2 = np.asarray(up, float) - (np.asarray(up, float) @ m) * m
        e2 /= np.linalg.norm(e2)
        e1 = np.cross(e2, m)
    else:
        e1 = np.cross(m, [0.0, 0.0, 1.0] if abs(m[2]) < 0.9 else [1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(m, e1)
    sun3 = np.array([s @ e1, s @ e2, -(s @ m)])
    shape = (camera.height_px, camera.width_px)
    centre = camera.direction_to_image(m)
    half = 1.5 * 2 * camera.focal_length_px * semidiameter + _margin(psf, psf_sigma_px)
    box = _box(shape, centre, half)
    u, v = _subpixels(box, supersample)
    p = camera.image_to_direction(np.stack([u, v], axis=-1))
    sin_rho = np.sin(semidiameter)
    flux = shade(p @ e1 / (k_h * sin_rho), p @ e2 / (k_v * sin_rho), sun3, shading) \
        * (p @ m > 0)
    flux = _bin(_blur_sub(flux, psf, psf_sigma_px, supersample), supersample)
    return _finish(flux, shape, box, peak, background, psf_sigma_px, noise_sigma, rng, dtype,
                   psf)


def camera_attitude(heading, tilt, tilt_azimuth):
    """Orientation ``C_hc`` (camera -> horizon NED) of a camera looking up.

    The optical axis (the camera's ``-z``) makes the angle `tilt` with the zenith and
    leans towards the azimuth `tilt_azimuth`; the camera x axis has the azimuth
    `heading` (the heading of ``lunar.solve.heading``) and lies in the plane normal to
    the optical axis.  Frames as in ``lunar.fisheye``: ``S_h = C_hc S_c``.

    Parameters
    ----------
    heading, tilt, tilt_azimuth : float
        rad; azimuths from north, clockwise; ``0 <= tilt < pi / 2``.

    Returns
    -------
    ndarray, shape (3, 3)
        ``C_hc``, columns the camera axes x, y, z in NED.
    """
    if not 0.0 <= tilt < np.pi / 2:
        raise ValueError(f"tilt must be in [0, 90) deg, got {np.rad2deg(tilt)} deg")
    axis = np.array([np.sin(tilt) * np.cos(tilt_azimuth), np.sin(tilt) * np.sin(tilt_azimuth),
                     -np.cos(tilt)])                                  # optical axis, up
    # x: azimuth `heading`, its vertical part making it normal to the optical axis
    x = np.array([np.cos(heading), np.sin(heading),
                  np.tan(tilt) * np.cos(heading - tilt_azimuth)])
    x /= np.linalg.norm(x)
    z = -axis
    return np.column_stack([x, np.cross(z, x), z])


def session_image(camera, C_hc, sky, k, seed=0, **options):
    """Image ``k`` of a session (see `render_session`); its noise from
    ``numpy.random.default_rng([seed, k])``, the same whatever the order of rendering."""
    C_hc = np.asarray(C_hc, float)
    return render_moon_fisheye(camera, sky.moon_h[k] @ C_hc, sky.sun_h[k] @ C_hc,
                               sky.semidiameter[k], rng=np.random.default_rng([seed, k]),
                               **options)


def render_session(camera, C_hc, sky, seed=0, **options):
    """The images of a session: the Moon of each epoch of `sky` through `camera`.

    Parameters
    ----------
    camera : photogrammetry.lunar.fisheye.FisheyeCamera
    C_hc : array_like, shape (3, 3)
        Camera -> horizon (NED), fixed over the session (`camera_attitude`).
    sky : photogrammetry.lunar.ephemeris.SkyDirections
        The Moon's and the Sun's directions (NED) and the semidiameter per epoch.
    seed : int
        Noise of image ``k`` from ``numpy.random.default_rng([seed, k])``: the same
        images whatever the order or the number rendered (`session_image`).
    **options
        Passed to `render_moon_fisheye` (peak, background, psf_sigma_px, noise_sigma,
        supersample, dtype, psf, shading).

    Yields
    ------
    ndarray, shape ``(camera.height_px, camera.width_px)``
        One image per epoch, in order.
    """
    for k in range(len(sky.moon_h)):
        yield session_image(camera, C_hc, sky, k, seed, **options)
