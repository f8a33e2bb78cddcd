"""``ins process`` without noise settings: the IMU noise, the land-vehicle constraint and
the GNSS velocity lag identified from the log before the run
(:mod:`ins.estimation.tools.noise_identification`).

When it runs (:func:`wanted`): loose coupling, ``[filter] identify = true`` (the default
of a TOML config; a :class:`~ins.estimation.pipeline.config.ProcessConfig` built in Python
runs with the noise it holds unless its ``identify`` is set), and no noise given by the
user's config or a flight folder's manifest (a ``--preset`` is a starting point, not a
requirement: the search starts from it).  The velocity lag
is estimated when ``[gnss] velocity_time_shift_s`` is not given and the log has
velocities; the non-holonomic constraint is tried when ``[measurements] nhc`` is not
given (by the config or the preset).  The IMU-GNSS time offset is searched when neither
``[imu] time_shift_s`` nor ``[gnss] time_shift_s`` (nor their options) is given (both 0)
and the layout has no ``time_offset`` state; the IMU's stamps are then shifted by it
(the solution stays on the GNSS's clock, GPS time) and the start found again.
"""
import itertools
from dataclasses import replace

import numpy as np

from ins.common.errors import InputError, QualityError
from ins.estimation.core.error_model import ImuNoise
from ins.estimation.core.filter import run_forward
from ins.estimation.tools.noise_identification import (
    SEARCH_RATE_HZ,
    SEARCH_WINDOW_S,
    START_GRADES,
    identify,
)
from ins.estimation.coupling.velocity_lag import velocity_lag


def wanted(cfg):
    """Whether ``cfg`` leaves the noise to be identified (module notes)."""
    if cfg.coupling != "loose" or not getattr(cfg, "identify", True):
        return False
    if cfg.source == "manifest":
        return False
    return cfg.noise_source is None or cfg.noise_source.startswith("preset")


def starts(cfg, rest_noise):
    """Starting points: the preset and the noise measured over a rest at the start
    (each that there is), else the preset grades; the best of them is refined."""
    from ins.estimation.pipeline.presets import PRESETS
    out = []
    if cfg.noise_source is not None and cfg.noise_source.startswith("preset"):
        out.append((cfg.noise_source, cfg.noise))
    if rest_noise is not None:
        out.append(("the noise measured over the rest at the start", rest_noise))
    return out or [(f"the '{g}' grade", ImuNoise(**PRESETS[g]["imu_noise"]))
                   for g in START_GRADES]


def run_identification(cfg, blocks, gnss, state, settings, start, initial_time,
                       rest_noise=None, progress=None):
    """Identify the noise over the first :data:`SEARCH_WINDOW_S` of the run.

    Returns
    -------
    (Identified or None, blocks, gnss)
        The identification, the IMU blocks (given back whole), and the GNSS log with the
        identified velocity shift applied (as it was when none); an identified IMU-GNSS
        offset (``Identified.time_offset_s``) is NOT applied: the caller shifts the IMU's
        stamps by ``-offset`` (``[imu] time_shift_s``) so that the solution stays on the
        GNSS's clock.
    """
    blocks = iter(blocks)
    head = []
    t_first = None
    for b in blocks:
        head.append(b)
        if t_first is None:
            t_first = float(b.time[0])
        if b.time[-1] >= (start if start is not None else t_first) + SEARCH_WINDOW_S:
            break
    blocks = itertools.chain(head, blocks)
    t0 = start if start is not None else t_first
    t_end = min(t0 + SEARCH_WINDOW_S, float(head[-1].time[-1]))
    if cfg.end_s is not None:
        t_end = min(t_end, cfg.end_s)
    lag = None
    if cfg.gnss_velocity_time_shift_s is None and cfg.use_velocity:
        lag = velocity_lag(gnss)
        if lag is not None and not lag.significant:
            lag = None
    test_nhc = "nhc" not in cfg.measurements
    thin = thinned(gnss, SEARCH_RATE_HZ)

    search_offset = (cfg.imu_time_shift_s == 0.0 and cfg.gnss_time_shift_s == 0.0
                     and "time_offset" not in settings.layout.groups)

    def shifted(g, vshift, toff):
        if vshift is None and not toff:
            return g
        t = toff or 0.0
        return g.shifted(t, None if vshift is None else t + vshift)

    def run_nll(noise, nhc, vshift, toff):
        g = shifted(thin, vshift, toff)
        trial = replace(settings, noise=noise, nhc=nhc or settings.nhc, recover=False)
        try:
            fwd = run_forward(head, g, state, trial, start=start, end=t_end,
                              initial_time=initial_time)
        except (InputError, QualityError):   # a diverging trial (non-finite, S not PD)
            return np.inf
        up = fwd.updater
        return float(sum(up.nll.values()))

    def note(done, total):
        if progress is not None and hasattr(progress, "note"):
            progress.note(f"identifying the IMU noise from the log: run {done} of ~{total} ...")

    ident = identify(run_nll, starts(cfg, rest_noise), velocity_lag=lag, test_nhc=test_nhc,
                     window_s=t_end - t0, progress=note, time_offset=search_offset)
    # the velocities' lag on the GNSS log; the offset goes to the IMU's stamps (the
    # caller: the solution then stays on the GNSS's clock, GPS time)
    gnss = shifted(gnss, ident.velocity_shift_s, None)
    ident.velocity_lag = lag
    return ident, blocks, gnss


def thinned(gnss, rate_hz):
    """The records of ``gnss`` at most ``rate_hz`` apart in time (the first, then each
    one at least ``1 / rate_hz`` after the last kept, less 1 %)."""
    t = np.asarray(gnss.time, float)
    keep = np.zeros(len(t), bool)
    last = -np.inf
    gap = 0.99 / rate_hz
    for k in range(len(t)):
        if t[k] - last >= gap:
            keep[k] = True
            last = t[k]
    return gnss if keep.all() else gnss.select(keep)
