"""How long a PPP solution takes to converge, and how good it is after.

A precise point positioning filter starts from a single-point position with metres of
error and converges as the float ambiguities settle: tens of minutes to hours.  The
convergence time here is the time after which the horizontal error STAYS below a
threshold to the end (a brief dip below it does not count).  The error is taken, in
order of preference, against:

- a reference position (a station's published coordinates): the true error;
- else the solution's own horizontal sigma, ``hypot(sigma_n, sigma_e)``: what the
  filter claims, not an error (on the SLAC station the forward static east wanders
  6 cm, standard deviation of its last 20 minutes, under a sigma of 1 cm:
  docs/real-data.md).

Measure it on a FORWARD solution: the combined forward-backward smoother is converged
from the first epoch on by construction.  Times in s from the solution's first epoch;
positions in the local north/east/up frame of the reference (or of the last epoch).
"""
import os
import shutil
import tempfile
from dataclasses import dataclass, replace

import numpy as np

from ins.common.errors import InputError

__all__ = ["Convergence", "convergence", "forward_convergence", "DEFAULT_THRESHOLD_M"]

#: Horizontal threshold of convergence, m.
DEFAULT_THRESHOLD_M = 0.1


@dataclass(frozen=True)
class Convergence:
    """Convergence of a solution (:func:`convergence`).

    Attributes
    ----------
    against : str
        ``"reference"`` or ``"sigma"``: what the horizontal error was taken against.
    threshold_m : float
        Horizontal threshold, m.
    time_s : float or None
        Time from the first epoch after which the horizontal error stays below the
        threshold, s; None when it is above it at the last epoch.
    span_s : float
        Time from the first to the last epoch, s.
    horizontal_rms_m, up_mean_m, up_rms_m : float or None
        Against a reference, after convergence (from ``time_s`` on; None without a
        reference or without convergence): horizontal RMS, mean and RMS of the up
        error, m.
    final_enu_m : ndarray, shape (3,) or None
        Against a reference: east, north, up error of the last epoch, m.
    final_sigma_h_m : float
        The last epoch's horizontal sigma, m.
    """

    against: str
    threshold_m: float
    time_s: float
    span_s: float
    horizontal_rms_m: float = None
    up_mean_m: float = None
    up_rms_m: float = None
    final_enu_m: np.ndarray = None
    final_sigma_h_m: float = None

    def line(self):
        """One line for a summary (the CLI prints it)."""
        what = ("the horizontal error against the reference" if self.against == "reference"
                else "the horizontal sigma")
        head = (f"convergence: {what} stays below {100 * self.threshold_m:.0f} cm "
                + (f"after {self.time_s / 60:.1f} min" if self.time_s is not None
                   else f"at no time ({self.span_s / 60:.0f} min processed)"))
        if self.against == "reference":
            e, n, u = self.final_enu_m
            head += f"; last epoch E/N/U {e:+.3f} / {n:+.3f} / {u:+.3f} m"
            if self.horizontal_rms_m is not None:
                head += (f"; after convergence horizontal RMS {self.horizontal_rms_m:.3f} m, "
                         f"up mean {self.up_mean_m:+.3f} m, RMS {self.up_rms_m:.3f} m")
        return head + f"; last sigma (horizontal) {self.final_sigma_h_m:.3f} m"


def _stays_below(t, value, threshold):
    """First time from which ``value`` stays below ``threshold`` to the end, or None."""
    above = np.nonzero(~(value < threshold))[0]
    if above.size == 0:
        return float(t[0])
    if above[-1] == len(t) - 1:
        return None
    return float(t[above[-1] + 1])


def convergence(log, reference_ecef=None, threshold_m=DEFAULT_THRESHOLD_M):
    """The convergence of a (forward) solution.

    Parameters
    ----------
    log : ins.io.gnss_log.GnssLog
        The solution (positions and sigmas).
    reference_ecef : array_like, shape (3,), optional
        The true antenna position, ECEF (WGS84/ITRF), m.
    threshold_m : float
        Horizontal threshold, m (> 0).

    Returns
    -------
    Convergence

    Raises
    ------
    InputError
        An empty solution, a threshold that is not positive, a reference that is not
        three finite numbers of an ECEF position (m).
    """
    if len(log) == 0:
        raise InputError("convergence: the solution has no epoch")
    if not (np.isfinite(threshold_m) and threshold_m > 0):
        raise InputError(f"convergence threshold: expected m > 0, got {threshold_m!r}")
    t = np.asarray(log.time, float) - float(log.time[0])
    sigma_h = np.hypot(log.sigma_ned_m[:, 0], log.sigma_ned_m[:, 1])
    common = dict(threshold_m=float(threshold_m), span_s=float(t[-1]),
                  final_sigma_h_m=float(sigma_h[-1]))
    if reference_ecef is None:
        return Convergence("sigma", time_s=_stays_below(t, sigma_h, threshold_m), **common)
    ref = np.asarray(reference_ecef, float)
    if ref.shape != (3,) or not np.all(np.isfinite(ref)) or not (
            6.0e6 < np.linalg.norm(ref) < 7.0e6):
        raise InputError(f"reference position: expected ECEF X, Y, Z in m (near the "
                         f"Earth's surface), got {reference_ecef!r}")
    import pymap3d
    from ins.nav.earth import ned_offset
    lat, lon, h = pymap3d.ecef2geodetic(*ref, deg=False)
    ned = ned_offset(np.array([lat, lon, h]), log.lla)
    horizontal = np.hypot(ned[:, 0], ned[:, 1])
    t_conv = _stays_below(t, horizontal, threshold_m)
    enu = np.array([ned[-1, 1], ned[-1, 0], -ned[-1, 2]])
    out = dict(final_enu_m=enu)
    if t_conv is not None:
        after = t >= t_conv
        up = -ned[after, 2]
        out.update(horizontal_rms_m=float(np.sqrt(np.mean(horizontal[after] ** 2))),
                   up_mean_m=float(np.mean(up)), up_rms_m=float(np.sqrt(np.mean(up ** 2))))
    return Convergence("reference", time_s=t_conv, **common, **out)


def forward_convergence(solution, rover, nav, folder, reference_ecef=None,
                        threshold_m=DEFAULT_THRESHOLD_M, **solve_kw):
    """:func:`convergence` of ``solution`` (a :class:`ins.gnss.rtklib_engine.GnssSolution`)
    when it was run forward, else of a forward run of the same inputs made in a
    temporary folder inside ``folder`` (nothing is left there); ``solve_kw`` are the
    other arguments of :func:`ins.gnss.rtklib_engine.solve` (base, sp3, clk, atx, dcb,
    window).  Returns ``(Convergence, forward log)``."""
    if solution.options.direction == "forward":
        log = solution.log
    else:
        from ins.gnss.rtklib_engine import solve
        tmp = tempfile.mkdtemp(prefix=".forward-", dir=folder)
        try:
            log = solve(rover, nav, os.path.join(tmp, "forward.pos"),
                        options=replace(solution.options, direction="forward"),
                        **solve_kw).log
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return convergence(log, reference_ecef, threshold_m), log
