"""``ins process`` with tight coupling (``[gnss] coupling = "tight"``, ``--coupling
tight``): the rover's RINEX observations and the broadcast navigation file(s) of the raw
GNSS input (``[files] rover``, ``nav``; :mod:`ins.estimation.pipeline.gnss_source`) through
RTKLIB (:func:`ins.gnss.raw_epochs.read_raw_epochs`) into the filter's pseudorange and
range-rate updates (:class:`ins.estimation.coupling.pseudorange.TightUpdater`).

RTKLIB's solution of the same input (run first, as for loose coupling) still gives the
start (alignment, start check), the receiver positions for the atmospheric delays
(interpolated in time; the nearest fix outside its span) and the trust checks'
reference.  With a base station (``[files] base``) the updates are double differences
against it (:class:`ins.estimation.coupling.double_difference.DoubleDifferenceUpdater`, the
base's epochs paired by :func:`ins.gnss.raw_pairs.read_pair`, its position from its
RINEX header or ``[rtklib] base_lla_deg``): the receiver clocks cancel and the layout
has no clock states.  When both receivers have the L1 carrier (``[gnss] carrier_phase``,
default true) the carrier double differences join them with float ambiguities as
states, fixed by LAMBDA and held (:class:`ins.estimation.coupling.carrier_phase.
CarrierPhaseUpdater`; ``carrier_sigma_m``, ``ambiguity_ratio``,
``ambiguity_success_rate``).  A receiver log (any format RTKLIB
decodes, :mod:`ins.gnss.receiver_formats`) is converted on the way, the base's too.
``[gnss] range_sigma_m``, ``range_rate_sigma_mps`` and ``receiver_clock`` set the
weights and the clock model (:class:`ins.estimation.coupling.pseudorange.TightOptions`,
:data:`ins.estimation.coupling.pseudorange.CLOCKS`): the defaults (RTKLIB's 0.3 m + 0.3 m /
sin(el)) suit a geodetic receiver; a range error correlated over a minute (multipath)
is not white noise, and on the simulated flight with 0.3 m of it the smoothed
trajectory within 60 s of 3, 2 and 1 satellites is 1.45 m off with them, 0.97 m with
``range_sigma_m = [1, 1]`` (``bench/bench_tight_rawsim.py``).

``[gnss] range_noise = "auto"`` (the default) replaces those weights by each receiver's
noise fitted from the data (:func:`fitted_noise`, :mod:`ins.estimation.coupling.
range_noise`): a first forward pass with the sigmas above gives the rover's innovations,
the base's residuals at its known position give its own; the run then uses the fitted
``a^2 + b^2 / sin^2 el + c^2 10^(-(C/N0 - 45)/10)`` with the IGG-III down-weighting of
``robust_weighting``.  On rawsim.toml with u-blox-like code errors (1 m white, 1.5 m
multipath over 30 s, 0.3 Hz Doppler; seeds 2 and 3) the smoothed horizontal RMS is
1.04 / 2.01 m against 2.01 / 3.39 m with the fixed weights and 1.95 / 2.94 m for loose
coupling on RTKLIB's single point, and 0.32 / 0.91 m against 1.63 / 3.21 m (loose) in
the 20 s of 3 satellites (``bench/bench_robust_gnss.py`` for the synthetic scenario).

Double differences against the base (same bench): on ``data/flights/rawsim_dd.toml``
(the ionosphere twice Klobuchar, the troposphere 1.1 Saastamoinen, white code noise)
the smoothed horizontal/vertical RMS is 0.31/0.36 m against single point's 0.78/6.14
m (the ionosphere's residual is a height error for one receiver).  With the 0.3 m
multipath of ``rawsim.toml`` at both receivers (equal antennas; the models exact) DD is
worse horizontally, 1.36 m against 0.87 m: the multipath of two receivers adds up and
there is no common error to cancel.  One satellite gives no DD: a 1-satellite span is
free inertial.
"""
import functools

import numpy as np

from ins.common.errors import InputError
from ins.estimation.core.error_model import StateLayout
from ins.estimation.coupling.pseudorange import CLOCKS, TightOptions, TightUpdater, clock_psd
from ins.nav import earth

__all__ = ["COUPLINGS", "tight_inputs", "tight_counts", "fitted_noise", "noise_summary"]

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
    cfg : ins.estimation.pipeline.config.ProcessConfig
        With raw GNSS input (``cfg.gnss_raw``: rover and nav).
    gnss : ins.io.gnss_log.GnssLog
        The loose log (receiver positions for the delays).
    settings : ins.estimation.core.filter_settings.FilterSettings
        The loose run's settings; the layout gains the ``clock`` group.

    Returns
    -------
    raw : ins.gnss.raw_epochs.RawEpochs
    settings : FilterSettings
    """
    from dataclasses import replace

    from ins.gnss.receiver_formats import detect_format
    raw_in = getattr(cfg, "gnss_raw", None)
    if raw_in is None or not (raw_in.nav or _rover_format(raw_in, detect_format) != "rinex"):
        raise InputError("[gnss] coupling = \"tight\": needs raw GNSS input, [files] rover "
                         "and nav (--rover, --nav: the rover's RINEX observations and the "
                         "broadcast navigation file; a receiver log with its own "
                         "ephemerides needs no nav), not a GNSS solution alone")
    if len(gnss) == 0:
        raise InputError("tight coupling: the GNSS log has no fix for the receiver "
                         "positions of the atmospheric delays", path=cfg.gnss)
    raw = _read(raw_in, _positions(gnss))
    if cfg.gnss_time_shift_s:
        raw.time = raw.time + cfg.gnss_time_shift_s
    options = _options(cfg)
    if raw_in.base:
        from ins.estimation.coupling.double_difference import DoubleDifferenceUpdater
        slots = _ambiguity_slots(raw) if getattr(cfg, "carrier_phase", True) else 0
        if slots:
            from ins.estimation.coupling.carrier_phase import (
                CarrierOptions,
                CarrierPhaseUpdater,
            )
            carrier = CarrierOptions(cfg.carrier_sigma_m, cfg.ambiguity_ratio,
                                     cfg.ambiguity_success_rate)
            layout = StateLayout(tuple(settings.layout.groups), n_ambiguities=slots)
            return raw, replace(settings, layout=layout, updater=functools.partial(
                CarrierPhaseUpdater, options=options, carrier=carrier))
        return raw, replace(settings, updater=functools.partial(DoubleDifferenceUpdater,
                                                                options=options))
    groups = tuple(settings.layout.groups) + ("clock",)
    if len(observed_systems(raw)) > 1:     # a clock offset per other constellation
        groups += ("isb",)
    layout = StateLayout(groups)
    return raw, replace(settings, layout=layout, clock_psd=clock_psd(*CLOCKS[cfg.receiver_clock]),
                        updater=functools.partial(TightUpdater, options=options))


#: The base's residuals less their running median over this window, s
#: (:func:`ins.estimation.coupling.base_residuals.static_residuals`): the atmosphere's
#: model errors, which cancel in the double differences, out of the base's noise.
BASE_DETREND_S = 300.0


def _options(cfg):
    """The tight options of ``cfg``: ``range_sigma_m``, ``range_rate_sigma_mps`` (with
    ``range_noise = "auto"`` the first pass's, not robust-weighted), and with ``"fixed"``
    and ``robust_weighting`` that model with the IGG-III weighting."""
    from ins.estimation.coupling.range_noise import NoiseModel, RangeNoise
    noise = None
    if getattr(cfg, "range_noise", "auto") == "fixed" and getattr(cfg, "robust_weighting",
                                                                  None) is True:
        noise = RangeNoise(NoiseModel((*cfg.range_sigma_m, 0.0),
                                      (*cfg.range_rate_sigma_mps, 0.0)), robust=True)
    return TightOptions(elevation_mask_deg=cfg.elevation_mask_deg,
                        range_sigma_m=tuple(cfg.range_sigma_m),
                        range_rate_sigma_mps=tuple(cfg.range_rate_sigma_mps), noise=noise)


def fitted_noise(cfg, raw, settings, first_pass):
    """``[gnss] range_noise = "auto"``: the receivers' noise models
    (:mod:`ins.estimation.coupling.range_noise`) fitted to the innovations of a first
    tight pass (the rover) and to the residuals of the base at its known position, and
    the settings of the run with them (``robust_weighting``: with IGG-III).  The
    variances are at least those of ``range_sigma_m`` and ``range_rate_sigma_mps``
    (:class:`NoiseModel`'s ``code_floor``, ``rate_floor``: slowly varying errors hide
    from the innovations; the fit can only add to the configured weights).

    Parameters
    ----------
    cfg : ProcessConfig
    raw : RawEpochs
        The tight input (:func:`tight_inputs`), its ``base`` for double differences.
    settings : FilterSettings
        :func:`tight_inputs`' settings (the first pass's).
    first_pass : callable
        ``first_pass(settings) -> ForwardResult``: the forward filter on these settings.

    Returns
    -------
    FilterSettings
        With the fitted models in the updater's ``TightOptions.noise``.
    """
    from dataclasses import replace

    from ins.estimation.coupling.base_residuals import static_residuals
    from ins.estimation.coupling.range_noise import NoiseModel, RangeNoise, fit_receiver
    part = settings.updater
    opt = part.keywords["options"]
    part = functools.partial(part.func, *part.args, **{**part.keywords, "options": replace(
        opt, keep_samples=True)})
    fallback = NoiseModel((*cfg.range_sigma_m, 0.0), (*cfg.range_rate_sigma_mps, 0.0))
    base = getattr(raw, "base", None)
    base_model = None
    if base is not None:
        base_model = fit_receiver(static_residuals(base, base.r_e, cfg.elevation_mask_deg,
                                                   BASE_DETREND_S), fallback=fallback,
                                  code_floor=tuple(cfg.range_sigma_m),
                                  rate_floor=tuple(cfg.range_rate_sigma_mps))
        part = functools.partial(part.func, *part.args, **{**part.keywords, "options": replace(
            opt, keep_samples=True, noise=RangeNoise(fallback, base_model, robust=False))})
    fwd = first_pass(replace(settings, updater=part))
    rover = fit_receiver(fwd.updater.samples, fallback=fallback,
                         code_floor=tuple(cfg.range_sigma_m),
                         rate_floor=tuple(cfg.range_rate_sigma_mps))
    robust = getattr(cfg, "robust_weighting", None)
    noise = RangeNoise(rover, base_model, robust=True if robust is None else robust)
    new = functools.partial(part.func, *part.args,
                            **{**part.keywords, "options": replace(opt, noise=noise)})
    return replace(settings, updater=new)


def noise_summary(cfg, updater):
    """The summary's ``range_noise`` entry: the mode, the robust weighting and each
    receiver's model (:meth:`NoiseModel.as_dict`); ``None`` without a model."""
    opt = getattr(updater, "opt", None)
    noise = getattr(opt, "noise", None)
    if noise is None:
        return None
    out = {"mode": getattr(cfg, "range_noise", "auto"), "robust": bool(noise.robust),
           "rover": noise.rover.as_dict(), "rover_text": noise.rover.describe()}
    if noise.base is not None:
        out.update(base=noise.base.as_dict(), base_text=noise.base.describe())
    return out


def _rover_format(raw_in, detect):
    """The rover's format: ``[rtklib] rover_format`` or detected."""
    fmt = getattr(raw_in.options, "rover_format", None)
    return detect(raw_in.rover) if fmt is None else fmt


def _ambiguity_slots(raw):
    """Ambiguity slots for carrier phase against the base: the most satellites with
    carrier at both receivers in one epoch, plus 4 for those rising while others are
    kept through a short gap, times the frequencies both have (L1, L2); 0 when either
    receiver has no carrier."""
    b = raw.base
    if raw.phase_m is None or getattr(b, "phase_m", None) is None:
        return 0
    most = 0
    for k in range(len(raw.time)):
        rs = {int(s) for s, p in zip(raw.sats[k], raw.phase_m[k]) if np.isfinite(p)}
        bs = {int(s) for s, p in zip(b.sats[k], b.phase_m[k]) if np.isfinite(p)}
        most = max(most, len(rs & bs))
    if most < 2:
        return 0
    two = raw.phase2_m is not None and getattr(b, "phase2_m", None) is not None
    return (most + 4) * (2 if two else 1)


def _read(raw_in, positions):
    """The raw epochs of the rover (and base): RINEX as it is, a receiver log of any
    format RTKLIB decodes converted first (RTKLIB's convrnx,
    :func:`ins.gnss.receiver_formats.observations`, into a temporary folder); the log's
    own ephemerides are used when no nav file is given."""
    import tempfile

    from ins.gnss.raw_epochs import read_raw_epochs
    from ins.gnss.receiver_formats import obs_epoch, observations
    from ins.gnss.rtklib_engine import binding

    opts = raw_in.options
    with tempfile.TemporaryDirectory(prefix="ins-raw-") as tmp:
        rtk = binding()
        obs, nav = observations(raw_in.rover, tmp, rtk, "rover",
                                getattr(opts, "rover_format", None), raw_in.nav)
        navs = tuple(raw_in.nav) or ((nav,) if nav else ())
        if not navs:
            raise InputError("tight coupling: the rover's log holds no ephemeris (u-blox "
                             "RXM-SFRBX, RTCM3 1019, ...) and no nav file is given "
                             "([files] nav, --nav)", path=raw_in.rover)
        systems = tight_systems(opts)
        if not raw_in.base:
            return read_raw_epochs(obs, navs, positions, systems=systems)
        from ins.gnss.raw_pairs import read_pair
        base, _ = observations(raw_in.base, tmp, rtk, "base",
                               getattr(opts, "base_format", None), navs,
                               epoch=obs_epoch(obs, rtk))
        return read_pair(obs, base, navs, positions, opts, systems=systems)


def observed_systems(raw):
    """The constellations (RINEX letters) with at least one satellite in ``raw``."""
    return sorted({n[0] for names in raw.names for n in names}, key="GRECJ".index)


def tight_systems(options):
    """The constellations of tight coupling: those of ``[rtklib] systems`` (RTKLIB's
    default GPS, GLONASS and Galileo) as RINEX letters, GPS first."""
    from ins.gnss.raw_epochs import SYSTEM_NAMES
    names = getattr(options, "systems", None) or ("gps",)
    out = [SYSTEM_NAMES[n] for n in names if n in SYSTEM_NAMES]
    return tuple(sorted(set(out), key="GREJC".index)) or ("G",)


def tight_counts(fwd):
    """Summary counts of a tight run: satellites used per epoch (min, mean), the
    coupling and, with double differences, the base (``base``) and the reference
    satellite's changes; ``{"coupling": "loose"}`` for a loose one."""
    up = getattr(fwd, "updater", None)
    if not hasattr(up, "satellites_used"):
        return {"coupling": "loose"}
    lo, mean, _ = up.satellites_used()
    out = {"coupling": "tight", "satellites_min": lo, "satellites_mean": round(mean, 2),
           "clock_jumps": list(getattr(up, "clock_jumps", [])),
           "systems": observed_systems(up.gnss)}
    if hasattr(up, "base_name"):
        out.update(base=up.base_name, reference_changes=up.ref_changes)
    if hasattr(up, "fix_rate"):
        rate = up.fix_rate()
        out.update(carrier_epochs=up.carrier_epochs, fixed_epochs=up.fixed_epochs,
                   fix_rate=None if not np.isfinite(rate) else round(float(rate), 4),
                   cycle_slips=len(up.slips), carriers=[f[0] for f in up.frequencies],
                   refix_s=[round(float(v), 1) for v in up.refix_s])
    return out
