"""Camera exposures of a simulated flight: event times on the strips and the true
exterior orientation (EO).

Event times are mid-exposure, GPS seconds of week, spaced by the plan's exposure
interval (the forward overlap) and centred on each straight photo line; they are rounded
to 1 us, the precision of ``events.csv``, before the truth is evaluated, so the file and
the EO agree exactly.

True EO (``docs/interfaces.md``, ``conventions.md``): the perspective centre is
``r_cam = r_imu + C_nb lever_b`` (exact, through ECEF), its mapping-frame coordinates
are the ENU of ``r_cam`` at the block origin (``pymap3d.ecef2enu``), and the attitude is
``C_mc = C_mn C_nb C_bc`` with the exact ``C_mn`` of :func:`photogrammetry.orientation.rotation.
dcm_mn_enu`.  Angles are extracted from ``C_mc`` in both named systems
(:func:`photogrammetry.orientation.rotation.matrix_to_angles`: ``eo_true.csv`` holds
``phi-omega-kappa`` with the textbooks' sign of phi, ``R = Ry(-phi) Rx(omega) Rz(kappa)``),
wrapped to (-pi, pi].
"""
from dataclasses import dataclass

import numpy as np
import pymap3d

from ins.nav.earth import offset_ecef
from ins.nav.rotation import quat_to_dcm
from photogrammetry.orientation.rotation import camera_attitude, dcm_mn_enu, matrix_to_angles

__all__ = ["TrueExposures", "event_times", "true_exposures", "enu_of_ecef"]

#: Decimals of event times in events.csv (1 us).
TIME_DECIMALS = 6


@dataclass(frozen=True)
class TrueExposures:
    """True exterior orientation of every exposure.

    Attributes
    ----------
    image_id : tuple of str
        ``"S{strip:02d}_{k:03d}"`` (1-based strip and image number on the strip).
    strip : ndarray of int, shape (n,)
        0-based strip index.
    time : ndarray, shape (n,)
        Mid-exposure event time, GPS s of week.
    X_m : ndarray, shape (n, 3)
        Perspective centre in the mapping frame (ENU at the origin), m.
    C_mc : ndarray, shape (n, 3, 3)
        Camera frame to mapping frame.
    origin_lla : ndarray, shape (3,)
        Block origin: latitude, longitude (rad), ellipsoidal height (m).
    """

    image_id: tuple
    strip: np.ndarray
    time: np.ndarray
    X_m: np.ndarray
    C_mc: np.ndarray
    origin_lla: np.ndarray

    def __len__(self):
        return len(self.time)

    def angles(self, system, degrees=False):
        """Angles of ``C_mc`` in a named system (order of its name), shape (n, 3)."""
        return matrix_to_angles(self.C_mc, system, degrees=degrees)


def event_times(strips, interval_s):
    """Exposure times on the photo lines, centred on each line.

    Parameters
    ----------
    strips : sequence of Strip
        Straight photo lines with ``index``, ``t_start``, ``t_end`` (GPS s).
    interval_s : float
        Exposure interval, s.

    Returns
    -------
    image_id : tuple of str
    strip : ndarray of int, shape (n,)
    time : ndarray, shape (n,)
        Rounded to 1 us.
    """
    if not interval_s > 0:
        raise ValueError(f"interval_s must be > 0 (s), got {interval_s!r}")
    ids, strip_of, times = [], [], []
    for s in strips:
        span = s.t_end - s.t_start
        n = int(np.floor(span / interval_s + 1e-9)) + 1
        t0 = s.t_start + 0.5 * (span - (n - 1) * interval_s)
        t = np.round(t0 + interval_s * np.arange(n), TIME_DECIMALS)
        ids += [f"S{s.index + 1:02d}_{k + 1:03d}" for k in range(n)]
        strip_of += [s.index] * n
        times.append(t)
    time = np.concatenate(times) if times else np.empty(0)
    return tuple(ids), np.asarray(strip_of, dtype=np.int64), time


def enu_of_ecef(r_e, origin_lla):
    """ENU coordinates (m) at the origin (rad, rad, m) of ECEF points ``r_e`` (n, 3)."""
    lat0, lon0, h0 = origin_lla
    e, n, u = pymap3d.ecef2enu(r_e[:, 0], r_e[:, 1], r_e[:, 2], lat0, lon0, h0, deg=False)
    return np.column_stack([e, n, u])


def true_exposures(truth, image_id, strip, time, C_bc, lever_b, origin_lla):
    """True EO at the event times.

    Parameters
    ----------
    truth : ins.simulate.truth.FlightTruth
        The true trajectory (evaluated at ``time``).
    image_id, strip, time
        From :func:`event_times`.
    C_bc : array_like, shape (3, 3)
        Camera frame to IMU body (axes with the boresight).
    lever_b : array_like, shape (3,)
        IMU centre to perspective centre in ``b`` (FRD), m.
    origin_lla : array_like, shape (3,)
        Mapping-frame origin: latitude, longitude (rad), ellipsoidal height (m).

    Returns
    -------
    TrueExposures
    """
    origin_lla = np.asarray(origin_lla, dtype=float)
    sample = truth.evaluate(np.asarray(time, dtype=float))
    lla = np.atleast_2d(sample.lla)
    C_nb = quat_to_dcm(np.atleast_2d(sample.q_nb))
    arm_n = C_nb @ np.asarray(lever_b, dtype=float)
    X_m = enu_of_ecef(offset_ecef(lla, arm_n), origin_lla)
    C_mn = dcm_mn_enu(lla[:, 0], lla[:, 1], origin_lla[0], origin_lla[1])
    C_mc = camera_attitude(C_nb, np.asarray(C_bc, dtype=float), C_mn)
    return TrueExposures(tuple(image_id), np.asarray(strip), np.asarray(time, dtype=float),
                         X_m, C_mc, origin_lla)

