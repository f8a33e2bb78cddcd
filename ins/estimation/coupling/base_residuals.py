"""Residuals of a static receiver at a known position (a base station): the samples
from which :func:`ins.estimation.coupling.range_noise.fit_receiver` fits its code and
Doppler noise (kept apart from :mod:`~ins.estimation.coupling.range_noise`, which
:mod:`~ins.estimation.coupling.pseudorange` imports)."""
import numpy as np

from ins.estimation.coupling.pseudorange import line_of_sight, sagnac_range, sagnac_range_rate
from ins.estimation.coupling.range_noise import centre

__all__ = ["static_residuals"]


def static_residuals(epochs, r_e, elevation_mask_deg=10.0, detrend_s=None):
    """Samples of a static receiver at a known ECEF position ``r_e`` (m) for
    :func:`ins.estimation.coupling.range_noise.fit_receiver`.

    Per epoch the corrected ranges (range rates) less the Sagnac range (rate), less the
    epoch's centre (:func:`ins.estimation.coupling.range_noise.centre`: the receiver
    clock bias, drift), scaled by ``sqrt(n / (n - 1))`` for the removed mean.  With
    ``detrend_s`` (s) each satellite's series is also less its running median over that
    window (scaled by ``sqrt(m / (m - 1))`` for ``m`` samples in it): what varies slowly
    (the ionosphere's and troposphere's model errors, which cancel between two close
    receivers) leaves the samples, the noise and the multipath of shorter correlation
    stay.

    Parameters
    ----------
    epochs : ins.gnss.raw_epochs.RawEpochs or ins.gnss.raw_pairs.BaseEpochs
        Or any object with their attributes.
    r_e : array_like (3,)
        ECEF, m.
    elevation_mask_deg : float
        deg.
    detrend_s : float, optional
        s; ``None``: no detrending.

    Returns
    -------
    list of ``(kind, el, snr, z, 0.0)``
        kind 0 code (m), 1 range rate (m/s); el rad; snr dB-Hz (nan: none).
    """
    import pymap3d
    r_e = np.asarray(r_e, float)
    lla = np.array(pymap3d.ecef2geodetic(*r_e, deg=False))
    rows = []                          # (kind, sat, time, el, snr, z)
    mask = np.deg2rad(elevation_mask_deg)
    for k in range(len(epochs.time)):
        r_s = np.asarray(epochs.sat_pos_e[k], float).reshape(-1, 3)
        if len(r_s) < 3:
            continue
        _, el = line_of_sight(r_s, lla)
        snr = (np.full(len(r_s), np.nan) if epochs.snr_dbhz is None
               else np.asarray(epochs.snr_dbhz[k], float))
        res = [np.asarray(epochs.range_m[k], float) - sagnac_range(r_s, r_e),
               np.asarray(epochs.range_rate_mps[k], float)
               - sagnac_range_rate(r_s, np.asarray(epochs.sat_vel_e[k], float), r_e,
                                   np.zeros(3))]
        sats = np.asarray(epochs.sats[k]).tolist()
        for kind, d in enumerate(res):
            ok = np.isfinite(d) & (el >= mask)
            n = np.count_nonzero(ok)
            if n < 3:
                continue
            d = (d - centre(d[ok])) * np.sqrt(n / (n - 1.0))
            rows += [(kind, sats[i], float(epochs.time[k]), el[i], snr[i], d[i])
                     for i in np.flatnonzero(ok)]
    if detrend_s is None:
        return [(r[0], r[3], r[4], r[5], 0.0) for r in rows]
    return _detrended(rows, detrend_s)


def _detrended(rows, window_s):
    """Each (kind, satellite) series less its running median over ``window_s``."""
    groups = {}
    for r in rows:
        groups.setdefault((r[0], r[1]), []).append(r)
    out = []
    for g in groups.values():
        t = np.array([r[2] for r in g])
        z = np.array([r[5] for r in g])
        for r, ti in zip(g, t):
            w = np.abs(t - ti) <= 0.5 * window_s
            m = np.count_nonzero(w)
            if m < 3:
                continue
            out.append((r[0], r[3], r[4], float((r[5] - np.median(z[w])) * np.sqrt(
                m / (m - 1.0))), 0.0))
    return out
