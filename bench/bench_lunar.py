"""Lunar heading: accuracy against the Cramer-Rao bound, and the image pipeline's speed.

Simulates the paper's session (72 images over 15 min, equisolid fisheye f = 800 px
looking up with a small unknown tilt, centre noise 0.1 px) at several headings; prints
the heading RMS and bias over many trials, the CRB of that geometry, and the paper's
Rodrigues least squares for comparison; then times the whole pipeline from 72 rendered
PNG images to the heading.
"""
import os
import sys
import tempfile
import time

import numpy as np
from PIL import Image
from scipy.stats import chi2

from ins.nav.rotation import euler_to_dcm
from photogrammetry.lunar import centre_directions, heading_from_images
from photogrammetry.lunar.ephemeris import moon_sun_directions
from photogrammetry.lunar.fisheye import FisheyeCamera
from photogrammetry.lunar.render import render_moon_fisheye
from photogrammetry.lunar.solve import solve_heading

ARCSEC = np.rad2deg(1) * 3600
CAM = FisheyeCamera(800.0, 1600, 1600, (799.5, 799.5), (0.002, -0.001, 0.0005))
LAT, LON, H = np.deg2rad(40.0), np.deg2rad(116.0), 50.0
UTC = np.datetime64("2017-05-12T15:00:00") + np.arange(72) * np.timedelta64(12500, "ms")


def accuracy(trials, sigma_px=0.1):
    sky = moon_sun_directions(UTC, LAT, LON, H, pressure_hpa=1000.0)
    print(f"session: 72 images over 15 min, Moon alt {np.rad2deg(sky.alt[0]):.1f} deg, "
          f"centre noise {sigma_px} px, {trials} trials")
    print("heading_deg  RMS_arcsec  bias_arcsec  +-  CRB_arcsec  RMS/CRB  Rodrigues_RMS_arcsec")
    rng = np.random.default_rng(1)
    for hdg in (0.5, 90.0, 179.5, 250.0):
        C = euler_to_dcm([0.03, -0.02, np.deg2rad(hdg)])
        uv0 = CAM.direction_to_image(sky.moon_h @ C)
        cov_uv = np.tile(sigma_px ** 2 * np.eye(2), (72, 1, 1))
        err, err_r, crb = [], [], None
        for _ in range(trials):
            S_c, cov_c = centre_directions(CAM, uv0 + sigma_px * rng.standard_normal(uv0.shape),
                                           cov_uv)
            sol = solve_heading(sky.moon_h, S_c, cov_c)
            err.append(np.angle(np.exp(1j * (sol.heading - np.deg2rad(hdg)))))
            err_r.append(np.angle(np.exp(1j * (sol.heading_rodrigues - np.deg2rad(hdg)))))
        S_c, cov_c = centre_directions(CAM, uv0, cov_uv)            # CRB at the truth
        crb = solve_heading(sky.moon_h, S_c, cov_c).heading_sigma
        e = np.array(err) * ARCSEC
        rms = np.sqrt(np.mean(e ** 2))
        print(f"{hdg:>8.1f}{rms:>9.1f}{e.mean():>8.1f}{rms / np.sqrt(trials):>6.1f}"
              f"{crb * ARCSEC:>8.1f}{rms / (crb * ARCSEC):>9.3f}"
              f"{np.sqrt(np.nanmean(np.square(err_r))) * ARCSEC:>16.1f}")


def centre_bias(trials=16):
    """Lit-limb centre vs the lit-area centroid on Moffat-blurred rendered Moons."""
    from photogrammetry.lunar.moon_centre import extract_centre, lit_centroid
    from photogrammetry.lunar.render import render_moon
    rng = np.random.default_rng(7)
    print(f"centre error along the Sun (px), {trials} images each, Moffat PSF, noise 5/3000:")
    print("radius_px  phase_deg  bias  +-  rms  mean_z2  centroid_bias")
    for radius in (7.5, 10.0, 20.0, 30.0):
        for phase in (0, 45, 90, 120):
            a, z2, cen = [], [], []
            for _ in range(trials):
                c, b = radius + 20 + rng.random(2), rng.uniform(0, 2 * np.pi)
                s = np.array([np.cos(b), np.sin(b)])
                size = int(2 * radius + 40)
                img = render_moon((size, size), c, radius, phase, np.rad2deg(b),
                                  noise_sigma=5, rng=rng, psf="moffat")
                m = extract_centre(img, sun_angle=b, phase_angle=np.deg2rad(phase))
                e = m.uv - c
                a.append(e @ s)
                z2.append(e @ np.linalg.solve(m.cov_uv, e) / 2)
                cen.append((lit_centroid(img) - c) @ s)
            a = np.array(a)
            print(f"{radius:>8.1f}{phase:>10d}{a.mean():>8.4f}{a.std() / np.sqrt(trials):>7.4f}"
                  f"{np.sqrt(np.mean(a ** 2)):>7.4f}{np.mean(z2):>7.2f}{np.mean(cen):>10.3f}")


def _window(utc, C):
    """Sky, true centres (px) and a camera on a window of CAM's frame around the track."""
    sky = moon_sun_directions(utc, LAT, LON, H, pressure_hpa=1000.0)
    truth = CAM.direction_to_image(sky.moon_h @ C)
    lo = np.floor(truth.min(0)).astype(int) - 20
    cam = FisheyeCamera(CAM.focal_length_px, int(np.ptp(truth[:, 0])) + 41,
                        int(np.ptp(truth[:, 1])) + 41,
                        tuple(np.array(CAM.principal_point_px) - lo), CAM.radial_k)
    return sky, truth, lo, cam


def _render(sky, C, cam, k, seed):
    return render_moon_fisheye(cam, sky.moon_h[k] @ C, sky.sun_h[k] @ C, sky.semidiameter[k],
                               noise_sigma=5, rng=seed)


def pipeline(repeats=3):
    """72 full-frame PNGs (the Moon rendered on a window, pasted into a noisy frame)."""
    utc = np.datetime64("2017-05-02T14:00:00") + np.arange(72) * np.timedelta64(12500, "ms")
    C = euler_to_dcm([0.03, 0.02, np.deg2rad(123.4)])
    sky, truth, lo, cam = _window(utc, C)
    rng = np.random.default_rng(5)
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for k in range(72):
            frame = np.clip(np.rint(rng.normal(100.0, 5.0, (CAM.height_px, CAM.width_px))),
                            0, 65535).astype(np.uint16)
            win = _render(sky, C, cam, k, k)
            frame[lo[1]:lo[1] + win.shape[0], lo[0]:lo[0] + win.shape[1]] = win
            paths.append(os.path.join(tmp, f"m{k:03d}.png"))
            Image.fromarray(frame).save(paths[-1])
        heading_from_images(CAM, paths[:2], utc[:2], LAT, LON, H)        # warm (imports)
        wall, cpu = [], []
        for _ in range(repeats):
            t0, c0 = time.perf_counter(), time.process_time()
            res = heading_from_images(CAM, paths, utc, LAT, LON, H, pressure_hpa=1000.0)
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
    s = res.solution
    d = res.uv - truth
    print(f"pipeline: 72 PNG images 1600x1600 (Moon diameter {2 * 800 * sky.semidiameter[0]:.1f} "
          f"px along the cone, phase angle {np.rad2deg(sky.phase_angle[0]):.0f} deg) -> heading "
          f"in {np.median(wall):.2f} s (median of {repeats}; user CPU {np.median(cpu):.2f} s, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f})")
    print(f"  heading error {(np.rad2deg(s.heading) - 123.4) * 3600:.1f} arcsec, sigma "
          f"{s.heading_sigma * ARCSEC:.1f} arcsec, variance factor {s.variance_factor:.2f}; "
          f"centre error mean {d.mean(0).round(3)} px, RMS {np.sqrt((d ** 2).mean(0)).round(3)} px")


def pipeline_sigmas(trials=8):
    """Honesty of the pipeline's sigmas over sessions starting 397 s apart."""
    C = euler_to_dcm([0.03, 0.02, np.deg2rad(123.4)])
    vf, z2, err, sig = [], [], [], []
    for t in range(trials):
        utc = (np.datetime64("2017-05-02T14:00:00") + np.timedelta64(397 * t, "s")
               + np.arange(72) * np.timedelta64(12500, "ms"))
        sky, truth, lo, cam = _window(utc, C)
        imgs = [_render(sky, C, cam, k, 1000 * t + k) for k in range(72)]
        res = heading_from_images(cam, imgs, utc, LAT, LON, H, pressure_hpa=1000.0)
        d = res.uv - (truth - lo)
        z2.append(np.mean([e @ np.linalg.solve(c, e) / 2 for e, c in zip(d, res.cov_uv)]))
        vf.append(res.solution.variance_factor)
        err.append((np.rad2deg(res.solution.heading) - 123.4) * 3600)
        sig.append(res.solution.heading_sigma * ARCSEC)
    err = np.array(err)
    print(f"pipeline sigmas over {trials} sessions: variance factor mean {np.mean(vf):.2f} "
          f"(range {min(vf):.2f}-{max(vf):.2f}; 99.8% band of one session "
          f"{chi2.ppf(0.001, 141) / 141:.2f}-{chi2.ppf(0.999, 141) / 141:.2f}), centre z^2 per "
          f"axis against the truth {np.mean(z2):.2f}; heading error mean {err.mean():.1f} "
          f"+- {err.std() / np.sqrt(trials):.1f}, RMS {np.sqrt(np.mean(err ** 2)):.1f} arcsec, "
          f"mean sigma {np.mean(sig):.1f} arcsec")


if __name__ == "__main__":
    accuracy(int(sys.argv[1]) if len(sys.argv) > 1 else 1000)
    centre_bias()
    pipeline()
    pipeline_sigmas()
