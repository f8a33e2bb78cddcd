"""Residuals of a static receiver at a known position (a base station): the samples
from which :func:`ins.estimation.coupling.range_noise.fit_receiver` fits its code and
Doppler noise (kept apart from :mod:`~ins.estimation.coupling.range_noise`, which
:mod:`~ins.estimation.coupling.pseudorange` imports)."""
import numpy as np

from ins.estimation.coupling.pseudorange import line_of_sight, sagnac_range, sagnac_range_rate
from ins.estimation.coupling.range_noise import centre

__all__ = ["static_residuals"]


def static_residuals(epochs, r_e, elevation_mask_deg=10.0):
    """Samples of a static receiver at a known ECEF position ``r_e`` (m): per epoch the
    corrected ranges (range rates) less the Sagnac range (rate), less the epoch's centre
    (:func:`ins.estimation.coupling.range_noise.centre`)
    (the receiver clock bias, drift), scaled by ``sqrt(n / (n - 1))`` for the removed
    mean; ``epochs`` has the attributes of :class:`ins.gnss.raw_epochs.RawEpochs`.
    Returns ``(kind, el, snr, z, 0)`` tuples for
    :func:`ins.estimation.coupling.range_noise.fit_receiver`."""
    import pymap3d
    r_e = np.asarray(r_e, float)
    lla = np.array(pymap3d.ecef2geodetic(*r_e, deg=False))
    out = []
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
        for kind, d in enumerate(res):
            ok = np.isfinite(d) & (el >= mask)
            n = np.count_nonzero(ok)
            if n < 3:
                continue
            d = (d - centre(d[ok])) * np.sqrt(n / (n - 1.0))
            out += [(kind, el[i], snr[i], d[i], 0.0) for i in np.flatnonzero(ok)]
    return out
