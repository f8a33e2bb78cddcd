"""``ins process`` with tight coupling (``[gnss] coupling = "tight"``, ``--coupling
tight``): the rover's RINEX observations and the broadcast navigation file(s) of the raw
GNSS input (``[files] rover``, ``nav``; :mod:`ins.estimation.process_gnss`) through
RTKLIB (:func:`ins.gnss.raw_epochs.read_raw_epochs`) into the filter's pseudorange and
range-rate updates (:class:`ins.estimation.pseudorange.TightUpdater`).

RTKLIB's solution of the same input (run first, as for loose coupling) still gives the
start (alignment, start check), the receiver positions for the atmospheric delays
(interpolated in time; the nearest fix outside its span) and the trust checks'
reference.  The base station's observations (double differences) and carrier phase are
not used by the tight updates; a u-blox log as the rover is refused (convert it to
RINEX first).
"""
import functools

import numpy as np

from ins.common.errors import InputError
from ins.estimation.error_model import StateLayout
from ins.estimation.pseudorange import TightOptions, TightUpdater
from ins.nav import earth

__all__ = ["COUPLINGS", "tight_inputs", "tight_counts"]

COUPLINGS = ("loose", "tight")


def _positions(gnss):
    """``f(t) -> ECEF (3,)`` from the loose log, interpolated per axis."""
    r = earth.lla_to_ecef(gnss.lla[:, 0], gnss.lla[:, 1], gnss.lla[:, 2])
    t = np.asarray(gnss.time, dtype=float)
    return lambda s: np.array([np.interp(s, t, r[:, k]) for k in range(3)])


def tight_inputs(cfg, gnss, settings):
    """The raw epochs and the filter settings of a tight run.

    Parameters
    ----------
    cfg : ins.estimation.process_config.ProcessConfig
        With raw GNSS input (``cfg.gnss_raw``: rover and nav).
    gnss : ins.io.gnss_log.GnssLog
        The loose log (receiver positions for the delays).
    settings : ins.estimation.filter_settings.FilterSettings
        The loose run's settings; the layout gains the ``clock`` group.

    Returns
    -------
    raw : ins.gnss.raw_epochs.RawEpochs
    settings : FilterSettings
    """
    from dataclasses import replace

    from ins.gnss.raw_epochs import read_raw_epochs
    raw_in = getattr(cfg, "gnss_raw", None)
    if raw_in is None or not raw_in.nav:
        raise InputError("[gnss] coupling = \"tight\": needs raw GNSS input, [files] rover "
                         "and nav (--rover, --nav: the rover's RINEX observations and the "
                         "broadcast navigation file), not a GNSS solution alone")
    if str(raw_in.rover).lower().endswith(".ubx"):
        raise InputError("tight coupling reads RINEX observations: convert the u-blox log "
                         "first (ins gnss)", path=raw_in.rover)
    if len(gnss) == 0:
        raise InputError("tight coupling: the GNSS log has no fix for the receiver "
                         "positions of the atmospheric delays", path=cfg.gnss)
    raw = read_raw_epochs(raw_in.rover, raw_in.nav, _positions(gnss))
    if cfg.gnss_time_shift_s:
        raw.time = raw.time + cfg.gnss_time_shift_s
    layout = StateLayout(tuple(settings.layout.groups) + ("clock",))
    options = TightOptions(elevation_mask_deg=cfg.elevation_mask_deg)
    return raw, replace(settings, layout=layout,
                        updater=functools.partial(TightUpdater, options=options))


def tight_counts(fwd):
    """Summary counts of a tight run: satellites used per epoch (min, mean) and the
    coupling; ``{"coupling": "loose"}`` for a loose one."""
    up = getattr(fwd, "updater", None)
    if not hasattr(up, "satellites_used"):
        return {"coupling": "loose"}
    lo, mean, _ = up.satellites_used()
    return {"coupling": "tight", "satellites_min": lo, "satellites_mean": round(mean, 2)}
