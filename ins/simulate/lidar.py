"""A simulated laser scanner over an analytic terrain, driven by a trajectory (the truth
of a simulated flight).

The scanner sits rigidly on the IMU (on the stabilized platform of the simulated flights,
``b = p``).  Pulses at ``pulse_rate_hz``; the scan angle follows a saw-tooth (model
``"polygon"``: every line left to right) or a triangle wave (``"oscillating"``) across
``field_of_view_deg`` at ``scan_rate_hz`` lines per second.  Each ray
``r_imu + C_nb (l_b + C_bs rho u(theta))`` (:mod:`ins.lidar.georeference`) is intersected with
the terrain; the recorded range and angle carry the scanner's noise
(``range_sigma_m``, ``scan_angle_sigma_rad``), the true points are returned beside them.

The terrain lives here, not in :mod:`photogrammetry.simulate.terrain` (``ins`` never
imports ``photogrammetry``): :class:`SineTerrain`, an ellipsoidal height that is a sum of
sine waves over the north/east coordinates of a local tangent plane.  Any object with
``height(lat_rad, lon_rad)`` (m, ellipsoidal) can be passed instead.

:func:`write_lidar` is the product writer of a flight plan's ``[scanner]`` table
(:mod:`ins.simulate.folder`): it scans the plan's strips over a :class:`SineTerrain` of
the plan's ``[terrain]`` relief and wavelength (its own draw: not the camera's terrain of
:mod:`photogrammetry.simulate.terrain`) and writes into the flight folder

* ``returns.csv``: the returns CSV of ``ins georeference`` (time_s, range_m,
  scan_angle_deg, intensity, return_number, strip = the plan's strip index + 1);
* ``scanner.toml``: the scanner file a user would have (boresight zero: unknown; the
  plan's lever arm and sigmas), and ``scanner_true.toml`` with the true boresight;
* ``points_true.csv``: ``time_s,x_ecef_m,y_ecef_m,z_ecef_m,strip``, the terrain point of
  each return (WGS84 ECEF, m).
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.lidar.georeference import ecef_to_lla
from ins.lidar.scanner import scanner_rays
from ins.nav.earth import dcm_en, lla_to_ecef, ned_offset
from ins.nav.interpolation import interpolate_trajectory
from ins.nav.rotation import quat_to_dcm, quat_to_euler, wrap_to_pi

__all__ = ["SineTerrain", "SimulatedReturns", "simulate_returns", "strip_windows",
           "write_lidar", "LIDAR_FILES"]

#: Manifest ``[files]`` key -> file name of the LiDAR products.
LIDAR_FILES = {"returns": "returns.csv", "scanner": "scanner.toml",
               "scanner_true": "scanner_true.toml", "points_true": "points_true.csv"}


@dataclass(frozen=True)
class SineTerrain:
    """``h = h0_m + sum_i amp_m[i] sin(k_i . (N, E) + phase_i)`` (ellipsoidal, m) with
    N, E the local tangent-plane coordinates (m) at ``origin_lla`` (rad, rad, m)."""

    origin_lla: tuple
    h0_m: float
    amp_m: np.ndarray
    k_ne: np.ndarray         # (w, 2) rad/m
    phase: np.ndarray

    @classmethod
    def random(cls, origin_lla, h0_m, relief_m, wavelength_m, rng, n_waves=5):
        """Waves of random direction and phase, wavelengths 0.5..1.5 ``wavelength_m``, total
        amplitude ``relief_m``."""
        az = rng.uniform(0, 2 * np.pi, n_waves)
        lam = wavelength_m * rng.uniform(0.5, 1.5, n_waves)
        k = (2 * np.pi / lam)[:, None] * np.column_stack([np.cos(az), np.sin(az)])
        amp = rng.uniform(0.5, 1.0, n_waves)
        return cls(tuple(origin_lla), float(h0_m), relief_m * amp / amp.sum(), k,
                   rng.uniform(0, 2 * np.pi, n_waves))

    def _ne(self, lat, lon):
        lla = np.column_stack([lat, lon, np.zeros_like(lat)])
        o = np.array([self.origin_lla[0], self.origin_lla[1], 0.0])
        d = ned_offset(np.broadcast_to(o, lla.shape), lla)
        return d[:, 0], d[:, 1]

    def height(self, lat, lon):
        """Ellipsoidal height (m) at latitude, longitude (rad)."""
        n, e = self._ne(np.asarray(lat, float), np.asarray(lon, float))
        arg = n[:, None] * self.k_ne[:, 0] + e[:, None] * self.k_ne[:, 1] + self.phase
        return self.h0_m + np.sin(arg) @ self.amp_m


@dataclass(frozen=True)
class SimulatedReturns:
    """Returns of the simulated scanner.

    Attributes
    ----------
    time : ndarray (n,)
        s.
    range_m, scan_angle_rad : ndarray (n,)
        As recorded (with noise).
    true_xyz_ecef_m : ndarray (n, 3)
        The terrain points hit, m.
    strip : ndarray (n,) of int
    """

    time: np.ndarray
    range_m: np.ndarray
    scan_angle_rad: np.ndarray
    true_xyz_ecef_m: np.ndarray
    strip: np.ndarray

    def write_csv(self, path):
        """Write the returns CSV of ``ins georeference`` (atomically)."""
        from ins.common.fileio import atomic_open
        with atomic_open(path, "w") as f:
            f.write("time_s,range_m,scan_angle_deg,intensity,return_number,strip\n")
            for t, r, a, s in zip(self.time, self.range_m, np.rad2deg(self.scan_angle_rad),
                                  self.strip):
                f.write(f"{t:.7f},{r:.5f},{a:.7f},100,1,{int(s)}\n")


def scan_angles(time, model, scan_rate_hz, field_of_view_deg):
    """Scan angle (rad) at ``time`` (s): saw-tooth ("polygon") or triangle ("oscillating")
    across ``field_of_view_deg``."""
    frac = np.mod(np.asarray(time, float) * scan_rate_hz, 1.0)
    half = np.deg2rad(field_of_view_deg) / 2
    if model == "polygon":
        return -half + 2 * half * frac
    if model == "oscillating":
        return -half + 4 * half * np.minimum(frac, 1.0 - frac)
    raise InputError(f"scan model {model!r} cannot be simulated (polygon or oscillating)")


def simulate_returns(truth, scanner, terrain, windows, rng, pulse_rate_hz=2000.0,
                     scan_rate_hz=20.0, field_of_view_deg=60.0, tol_m=1e-5, max_iter=50,
                     mount=None):
    """Simulate the returns of ``scanner`` over ``terrain`` along ``truth``.

    Parameters
    ----------
    truth : ins.nav.trajectory.Trajectory
        True IMU trajectory.
    scanner : ins.lidar.scanner.Scanner
        The TRUE scanner (its boresight and lever arm make the rays); model polygon or
        oscillating.
    terrain : object with ``height(lat_rad, lon_rad)``
    windows : sequence of (t_start, t_end, strip_id)
        Scanning intervals, s.
    rng : numpy.random.Generator
        Range and scan-angle noise.
    pulse_rate_hz, scan_rate_hz, field_of_view_deg : float
    mount : ins.io.mount.MountLog, optional
        The mount angles ``C_ap(t)`` of a scanner on the aircraft (``on = "aircraft"``;
        the IMU on the platform): rays ``C_ap^T C_as u``, arm ``l_bp + C_ap^T l_a``.

    Returns
    -------
    SimulatedReturns
    """
    times, strips = [], []
    for t0, t1, sid in windows:
        t = np.arange(np.ceil(t0 * pulse_rate_hz), np.floor(t1 * pulse_rate_hz) + 1)
        t = t / pulse_rate_hz
        times.append(t)
        strips.append(np.full(len(t), int(sid)))
    t = np.concatenate(times)
    strip = np.concatenate(strips)
    theta = scan_angles(t, scanner.model, scan_rate_hz, field_of_view_deg)
    at = interpolate_trajectory(truth, t)
    C_nb = quat_to_dcm(at.q_nb)
    u_b = scanner_rays(np.ones(len(t)), theta, scanner.forward_tilt_rad) @ scanner.C_bs.T
    l_b = np.broadcast_to(scanner.lever_arm_m, u_b.shape)
    if scanner.on == "aircraft":
        if mount is None:
            raise InputError('a scanner on the aircraft needs the mount angles (mount=)')
        C_ap, valid = mount.C_ap(t)
        if not valid.all():
            raise InputError("scanning windows outside the mount log or in its gaps")
        C_pa = np.swapaxes(C_ap, 1, 2)
        u_b = np.einsum("nij,nj->ni", C_pa, u_b)
        l_b = scanner.imu_to_platform_centre_b_m + np.einsum("nij,j->ni", C_pa,
                                                             scanner.lever_arm_m)
    o_n = np.einsum("nij,nj->ni", C_nb, l_b)
    d_n = np.einsum("nij,nj->ni", C_nb, u_b)
    if np.any(d_n[:, 2] < 0.05):
        raise InputError("a simulated ray points less than 3 deg below the horizon")
    r_imu = lla_to_ecef(at.lla[:, 0], at.lla[:, 1], at.lla[:, 2])
    C_en = dcm_en(at.lla[:, 0], at.lla[:, 1])
    rho = (at.lla[:, 2] - terrain.height(at.lla[:, 0], at.lla[:, 1])) / d_n[:, 2]
    for _ in range(max_iter):
        p = r_imu + np.einsum("nij,nj->ni", C_en, o_n + rho[:, None] * d_n)
        lla = ecef_to_lla(p)
        g = lla[:, 2] - terrain.height(lla[:, 0], lla[:, 1])    # height above the terrain
        rho = rho + g / d_n[:, 2]
        if np.abs(g).max() < tol_m:
            break
    else:
        raise InputError("the ray-terrain intersection did not converge (terrain too steep "
                         "for the scan angles)")
    p = r_imu + np.einsum("nij,nj->ni", C_en, o_n + rho[:, None] * d_n)
    noisy_rho = rho + rng.normal(0.0, scanner.range_sigma_m, len(t))
    noisy_theta = theta + rng.normal(0.0, scanner.scan_angle_sigma_rad, len(t))
    return SimulatedReturns(t, noisy_rho, noisy_theta, p, strip)


def strip_windows(truth, azimuth_deg, tol_deg=3.0, min_s=5.0, trim_s=1.0):
    """Time windows (t0, t1, strip_id) where the heading is within ``tol_deg`` of the strip
    azimuth or its reverse (a flight's straight lines), ids 1, 2, ... in time order."""
    yaw = quat_to_euler(truth.q_nb)[:, 2]
    az = np.deg2rad(azimuth_deg)
    off = np.minimum(np.abs(wrap_to_pi(yaw - az)), np.abs(wrap_to_pi(yaw - az - np.pi)))
    on = off < np.deg2rad(tol_deg)
    edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
    out = []
    for a, b in zip(edges[::2], edges[1::2]):
        t0, t1 = truth.time[a] + trim_s, truth.time[b - 1] - trim_s
        if t1 - t0 >= min_s:
            out.append((t0, t1, len(out) + 1))
    return out


def write_lidar(flight):
    """Product writer of the plan's ``[scanner]`` (module notes): the returns of every
    strip, the scanner files and the true points; returns the manifest tables
    (``[files]`` and ``[scanner]``).

    Parameters
    ----------
    flight : ins.simulate.folder.FlightProducts
        Its ``plan.scanner`` must be set.
    """
    from ins.common.fileio import atomic_open
    from ins.lidar.scanner import Scanner, write_scanner
    from ins.nav.trajectory import Trajectory

    plan, cfg = flight.plan, flight.plan.scanner
    b = plan.block
    true = Scanner(model=cfg.model, forward_tilt_rad=cfg.forward_tilt,
                   range_sigma_m=cfg.range_sigma_m, scan_angle_sigma_rad=cfg.scan_angle_sigma,
                   lever_arm_m=cfg.lever_arm_m, boresight_rad=cfg.boresight,
                   lever_arm_sigma_m=cfg.lever_arm_sigma_m,
                   boresight_sigma_rad=cfg.boresight_sigma)
    windows = [(s.t_start, s.t_end, s.index + 1) for s in flight.truth.strips]
    rate = cfg.pulse_rate_hz
    # the truth at the pulse times themselves (the interpolation then returns it exactly)
    t = np.concatenate([np.arange(np.ceil(t0 * rate), np.floor(t1 * rate) + 1) / rate
                        for t0, t1, _ in windows])
    if len(t) > 20_000_000:
        raise InputError(f"[scanner] pulse_rate_hz: {len(t)} returns over the strips; at "
                         "most 20 million (expected a lower rate, Hz)", path=plan.source)
    chunks = [flight.truth.evaluate(t[k:k + 200_000]) for k in range(0, len(t), 200_000)]
    truth = Trajectory(t, *(np.concatenate([getattr(c, n) for c in chunks])
                            for n in ("lla", "v_n", "q_nb")))
    flight.progress(0.3)
    terrain = SineTerrain.random((b.origin_lat, b.origin_lon, b.origin_h), b.origin_h,
                                 plan.terrain.relief_m, plan.terrain.wavelength_m,
                                 flight.rng(f"lidar/terrain/{plan.terrain.seed_offset}"))
    sim = simulate_returns(truth, true, terrain, windows, flight.rng("lidar"),
                           pulse_rate_hz=rate, scan_rate_hz=cfg.scan_rate_hz,
                           field_of_view_deg=np.rad2deg(cfg.field_of_view))
    flight.progress(0.7)
    folder = flight.folder
    sim.write_csv(folder / LIDAR_FILES["returns"])
    write_scanner(folder / LIDAR_FILES["scanner"], true.with_boresight(np.zeros(3)))
    write_scanner(folder / LIDAR_FILES["scanner_true"], true)
    with atomic_open(folder / LIDAR_FILES["points_true"], "w") as f:
        f.write("time_s,x_ecef_m,y_ecef_m,z_ecef_m,strip\n")
        np.savetxt(f, np.column_stack([sim.time, sim.true_xyz_ecef_m, sim.strip]),
                   fmt=["%.7f", "%.4f", "%.4f", "%.4f", "%d"], delimiter=",")
    flight.progress(1.0)
    return {"files": dict(LIDAR_FILES),
            "scanner": {"n_returns": int(len(sim.time)), "pulse_rate_hz": float(rate),
                        "strips": [int(w[2]) for w in windows],
                        "boresight_true_deg": [float(v) for v in np.rad2deg(cfg.boresight)],
                        "terrain": "SineTerrain of ins.simulate.lidar (own draw)"}}
