"""Error-free IMU increments from the truth: ``dtheta_k = int w_ib_b dt`` and
``dvel_k = int f_b dt`` over ``(t[k-1], t[k]]`` by Gauss-Legendre quadrature of the
analytic rates of :class:`~ins.simulate.truth.FlightTruth` (not by differencing sampled
attitudes), which is what a real IMU outputs and what the two-sample mechanization of
:mod:`ins.nav.mechanization` expects.  The truth is evaluated in chunks of
:data:`CHUNK_ROWS` intervals (bounded memory, ~2 s per hour of flight at 200 Hz).

The first row
-------------
``time[0] = t_start`` is the epoch of the initial state of :func:`ins.nav.mechanization.mechanize`
(``truth.evaluate(t_start)``).  Its increment only serves as the "previous sample" of the
coning and sculling corrections: it is the true increment over ``(t_start - dt, t_start]``
when that lies inside the flight, otherwise (at the very start of the flight) a copy of
row 1.
"""
import numpy as np

from ins.nav.imu import ImuLog

__all__ = ["synthesize_imu", "GL_NODES", "CHUNK_ROWS"]

#: Gauss-Legendre nodes per interval (exact for polynomials of degree 3).  The rates are
#: smooth on the scale of an IMU interval (turbulence below a few Hz, C1 ramps), so 2
#: nodes leave ~1e-14 rad per interval: on a 30 min flight with 20-deg-bank turns the
#: mechanization round trip is 1.3 mm / 3e-4 arcsec with 2 nodes, 1.4 mm / 8e-5 arcsec
#: with 4 (the mechanization dominates), 168 mm / 0.13 arcsec with 1 (midpoint).
GL_NODES = 2
#: Intervals evaluated per call of the truth (bounds memory).
CHUNK_ROWS = 1 << 15


def _integrate(truth, t_a, t_b, nodes):
    """Integrals of w_ib_b and f_b over [t_a[k], t_b[k]] (rad, m/s), shape (n, 3) each."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    half = 0.5 * (t_b - t_a)
    mid = 0.5 * (t_b + t_a)
    t = (mid[:, None] + half[:, None] * x).ravel()
    w_ib_b, f_b = truth.rates(np.clip(t, truth.t_start, truth.t_end))
    wt = (half[:, None] * w)[:, :, None]
    n = len(t_a)
    return ((w_ib_b.reshape(n, nodes, 3) * wt).sum(1),
            (f_b.reshape(n, nodes, 3) * wt).sum(1))


def synthesize_imu(truth, rate_hz, t_start=None, t_end=None, progress=None, nodes=GL_NODES):
    """Error-free increments of the IMU (body FRD, stamped at the end of the interval).

    Parameters
    ----------
    truth : ins.simulate.truth.FlightTruth
    rate_hz : float
        Output rate, Hz; epochs ``t_start + k / rate_hz``.
    t_start, t_end : float, optional
        GPS s (default: the whole flight).
    progress : callable, optional
        ``progress(done_rows, total_rows)``.
    nodes : int
        Gauss-Legendre nodes per interval.

    Returns
    -------
    ins.nav.imu.ImuLog
        Row 0 at ``t_start`` (see the module docstring), rows k >= 1 cover
        ``(time[k-1], time[k]]``.
    """
    t0 = truth.t_start if t_start is None else float(t_start)
    t1 = truth.t_end if t_end is None else float(t_end)
    if not (truth.t_start - 1e-9 <= t0 < t1 <= truth.t_end + 1e-9):
        raise ValueError(f"window [{t0}, {t1}] s is not inside the flight "
                         f"[{truth.t_start}, {truth.t_end}] s")
    dt = 1.0 / float(rate_hz)
    n = int(np.floor((t1 - t0) / dt + 1e-9)) + 1
    if n < 2:
        raise ValueError(f"fewer than 2 epochs at {rate_hz} Hz in [{t0}, {t1}] s")
    time = t0 + dt * np.arange(n)
    dtheta = np.empty((n, 3))
    dvel = np.empty((n, 3))
    for k0 in range(1, n, CHUNK_ROWS):
        k1 = min(k0 + CHUNK_ROWS, n)
        dtheta[k0:k1], dvel[k0:k1] = _integrate(truth, time[k0 - 1:k1 - 1], time[k0:k1], nodes)
        if progress is not None:
            progress(k1 - 1, n - 1)
    if t0 - dt >= truth.t_start - 1e-9:
        dtheta[:1], dvel[:1] = _integrate(truth, np.array([t0 - dt]), time[:1], nodes)
    else:
        dtheta[0], dvel[0] = dtheta[1], dvel[1]
    return ImuLog.adopt(time, dtheta, dvel)
