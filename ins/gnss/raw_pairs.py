"""Rover and base station epochs paired for double differences (tight coupling against a
base, :mod:`ins.estimation.coupling.double_difference`).

Both receivers' observations go through :func:`ins.gnss.raw_epochs.read_raw_epochs`
(RTKLIB through ``pyrtklib5``: satellite positions and clocks at each receiver's own
transmit times, the broadcast group delay, Klobuchar and Saastamoinen at each
receiver's position), so the base's corrected ranges are exactly what the rover's are.
A rover epoch is paired with the base epoch nearest in receiver time, within
``tolerance_s`` (the receiver clocks' offsets cancel in the double differences: the
tolerance only bounds how far apart in time the satellite-dependent errors are taken);
a rover epoch without a base epoch keeps its place with no base satellites (no update).

The base antenna's position (ECEF, m) is the ``APPROX POSITION XYZ`` of the base file's
RINEX header, or ``[rtklib] base_lla_deg`` when given, or with ``[rtklib] base_position
= "single"`` the least-squares position from all the base's pseudoranges (one clock per
epoch; starting from the header's); an error in it moves the rover
by about the same amount (the double differences are relative), and at 1 km it leaves
double-difference range errors of about ``|baseline| 1 km / 20 000 km`` (metres at
most).
"""
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError
from ins.gnss.raw_epochs import RawEpochs

__all__ = ["BaseEpochs", "PairedEpochs", "header_position", "base_position",
           "static_position", "pair_epochs",
           "read_pair", "DEFAULT_TOLERANCE_S"]

#: Largest difference of the rover's and base's epoch times (receiver clocks), s.
DEFAULT_TOLERANCE_S = 0.5


def header_position(obs_path):
    """The ``APPROX POSITION XYZ`` of a RINEX observation header, ECEF m.

    Raises
    ------
    InputError
        No such line, or a zero/unreadable position (naming the file and line).
    """
    with open(obs_path, encoding="ascii", errors="replace") as f:
        for n, line in enumerate(f, 1):
            label = line[60:].strip()
            if label == "APPROX POSITION XYZ":
                try:
                    xyz = np.array([float(v) for v in line[:60].split()])
                    if xyz.shape != (3,):
                        raise ValueError
                except ValueError:
                    raise InputError("APPROX POSITION XYZ: expected three numbers (ECEF, m)",
                                     path=str(obs_path), line=n) from None
                if not np.all(np.isfinite(xyz)) or np.linalg.norm(xyz) < 6.0e6:
                    raise InputError("APPROX POSITION XYZ: no usable base position (ECEF, "
                                     "m; give [rtklib] base_lla_deg)", path=str(obs_path),
                                     line=n)
                return xyz
            if label == "END OF HEADER":
                break
    raise InputError("no APPROX POSITION XYZ in the header: the base antenna's position is "
                     "needed (give [rtklib] base_lla_deg = [lat deg, lon deg, h m])",
                     path=str(obs_path))


def base_position(base_path, options=None):
    """The base antenna, ECEF m: ``options.base_lla_deg`` (:class:`~ins.gnss.
    rtklib_options.RtklibOptions`) when set, else the base file's header (also the
    start of ``base_position = "single"``, :func:`static_position`)."""
    lla = getattr(options, "base_lla_deg", None)
    if lla is not None:
        from ins.nav import earth
        return earth.lla_to_ecef(np.deg2rad(lla[0]), np.deg2rad(lla[1]), float(lla[2]))
    return header_position(base_path)


def static_position(epochs, r0_e, elevation_min_deg=10.0, iterations=6):
    """Least-squares position of a static receiver from all its corrected pseudoranges
    (:class:`RawEpochs`), one clock bias per epoch eliminated (each epoch's residuals
    and rows less their mean; equal weights), satellites below ``elevation_min_deg``
    (deg, seen from ``r0_e``) left out: ``[rtklib] base_position = "single"`` for the
    double differences.  ``r0_e``: the start (the header's position), ECEF m.
    Returns ECEF m."""
    import pymap3d

    from ins.nav import earth
    x = np.asarray(r0_e, float).copy()
    lat, lon, _ = pymap3d.ecef2geodetic(*x, deg=False)
    up_e = earth.dcm_en(lat, lon)[:, 2] * -1.0
    for _ in range(iterations):
        N, rhs = np.zeros((3, 3)), np.zeros(3)
        for r_s, y in zip(epochs.sat_pos_e, epochs.range_m):
            d = np.asarray(r_s, float) - x
            rho = np.linalg.norm(d, axis=1)
            e = d / rho[:, None]
            ok = np.isfinite(y) & (e @ up_e >= np.sin(np.deg2rad(elevation_min_deg)))
            if np.count_nonzero(ok) < 2:
                continue
            rho = rho + 7.292115e-5 * (r_s[:, 0] * x[1] - r_s[:, 1] * x[0]) / 299792458.0
            A, r = -e[ok], (np.asarray(y, float) - rho)[ok]
            A, r = A - A.mean(axis=0), r - r.mean()
            N += A.T @ A
            rhs += A.T @ r
        dx = np.linalg.solve(N, rhs)
        x += dx
        if np.linalg.norm(dx) < 1e-4:
            break
    return x


@dataclass
class BaseEpochs:
    """The base's observations paired with the rover's epochs (ragged like
    :class:`RawEpochs`; an epoch without base data has empty arrays).

    Attributes
    ----------
    r_e : ndarray (3,)
        Base antenna, ECEF m.
    time : ndarray (m,)
        Base epoch time paired with each rover epoch, s (nan: none).
    sats, sat_pos_e, sat_vel_e, range_m, range_rate_mps, snr_dbhz, phase_m, lli
        As in :class:`RawEpochs`, the base's (``phase_m``, ``lli``: ``None`` when the
        base has no carrier phase).
    name : str
        The base, for the summary (its file's name).
    """

    r_e: np.ndarray
    time: np.ndarray
    sats: list
    sat_pos_e: list
    sat_vel_e: list
    range_m: list
    range_rate_mps: list
    snr_dbhz: list
    name: str = "base"
    phase_m: list = None
    lli: list = None
    phase2_m: list = None
    lli2: list = None
    lam_m: list = None
    lam2_m: list = None


class PairedEpochs(RawEpochs):
    """Rover epochs (:class:`RawEpochs`) with the paired base epochs in ``base``
    (:class:`BaseEpochs`)."""

    def __init__(self, rover, base):
        super().__init__(rover.time, rover.sats, rover.sat_pos_e, rover.sat_vel_e,
                         rover.range_m, rover.range_rate_mps, rover.snr_dbhz, rover.names,
                         rover.phase_m, rover.lli, rover.wavelength_m, rover.phase2_m,
                         rover.lli2, rover.wavelength2_m, rover.lam_m, rover.lam2_m)
        self.base = base

    def select(self, keep):
        """The rover's satellites masked by ``keep`` (:meth:`RawEpochs.select`), the base
        unchanged."""
        return PairedEpochs(super().select(keep), self.base)


def pair_epochs(rover, base, base_r_e, tolerance_s=DEFAULT_TOLERANCE_S, name="base"):
    """Pair each rover epoch with the nearest base epoch within ``tolerance_s``.

    Parameters
    ----------
    rover, base : RawEpochs
    base_r_e : array_like (3,)
        Base antenna, ECEF m.
    tolerance_s : float
        s.

    Returns
    -------
    PairedEpochs
    """
    tb = np.asarray(base.time, float)
    hi = np.clip(np.searchsorted(tb, rover.time), 0, len(tb) - 1)
    lo = np.clip(hi - 1, 0, len(tb) - 1)
    j = np.where(np.abs(tb[lo] - rover.time) <= np.abs(tb[hi] - rover.time), lo, hi)
    ok = np.abs(tb[j] - rover.time) <= tolerance_s
    empty3 = np.zeros((0, 3))
    out = {k: [] for k in ("sats", "sat_pos_e", "sat_vel_e", "range_m", "range_rate_mps",
                           "snr_dbhz", "phase_m", "lli", "phase2_m", "lli2", "lam_m",
                           "lam2_m")}
    for i, (jj, good) in enumerate(zip(j, ok)):
        for k in out:
            if good:
                v = getattr(base, k)
                out[k].append(v[jj] if v is not None else np.full(len(base.sats[jj]), np.nan))
            else:
                out[k].append(empty3 if k in ("sat_pos_e", "sat_vel_e") else
                              np.zeros(0, dtype=int if k in ("sats", "lli", "lli2") else float))
    return PairedEpochs(rover, BaseEpochs(np.asarray(base_r_e, float),
                                          np.where(ok, tb[j], np.nan), name=name, **out))


def read_pair(rover_path, base_path, nav_paths, rover_ecef, options=None,
              tolerance_s=DEFAULT_TOLERANCE_S, rtk=None, systems=("G",)):
    """Read the rover and the base (:func:`ins.gnss.raw_epochs.read_raw_epochs`) and pair
    them (:func:`pair_epochs`); the base's position from :func:`base_position`.

    Parameters
    ----------
    rover_path, base_path : str
        RINEX observation files.
    nav_paths : str or sequence of str
        Broadcast navigation file(s).
    rover_ecef : array_like (3,) or callable
        The rover's position for its atmospheric delays (ECEF m, or of time).
    options : RtklibOptions, optional
        ``base_lla_deg``.
    systems : sequence of str
        Constellations (:data:`ins.gnss.raw_epochs.SYSTEMS`).

    Raises
    ------
    InputError
        Unreadable files, no base position, or no rover epoch with a base epoch within
        ``tolerance_s`` (naming the base file).
    """
    import os

    from ins.gnss.raw_epochs import read_raw_epochs
    r_b = base_position(base_path, options)
    rover = read_raw_epochs(rover_path, nav_paths, rover_ecef, rtk=rtk, systems=systems)
    base = read_raw_epochs(base_path, nav_paths, r_b, rtk=rtk, systems=systems)
    if getattr(options, "base_lla_deg", None) is None and getattr(
            options, "base_position", "rinex") == "single":
        r_b = static_position(base, r_b)
    pairs = pair_epochs(rover, base, r_b, tolerance_s, name=os.path.basename(str(base_path)))
    if not np.any(np.isfinite(pairs.base.time)):
        raise InputError(f"no base epoch within {tolerance_s:g} s of a rover epoch (rover "
                         f"{rover.time[0]:.1f}-{rover.time[-1]:.1f} s, base "
                         f"{base.time[0]:.1f}-{base.time[-1]:.1f} s, GPS s of week)",
                         path=str(base_path))
    return pairs
