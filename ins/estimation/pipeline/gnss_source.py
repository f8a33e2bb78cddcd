"""Raw GNSS for ``ins process``: the rover's (and base station's) observations run
through RTKLIB's engine (:mod:`ins.gnss`) before the filter, instead of a ready GNSS
solution.

Configuration (TOML, in place of ``[files] gnss``; paths relative to the file)::

    [files]   rover = "rover.obs" | "rover.ubx"   (RINEX 2/3 or a receiver log:
                                                   ins.gnss.receiver_formats)
              base  = "base.obs"                  (required by every mode but single)
              nav   = "brdc.nav" or ["a.nav", "b.nav"]   (broadcast, RINEX nav)
              sp3   = "orbits.sp3" or a list      (optional: precise ephemeris)
              clk   = "clocks.clk" or a list      (optional; both needed by PPP)
              atx   = "igs20.atx"                 (optional: antenna phase centres)
              dcb   = "P1C12104.DCB"              (optional: code biases)
    [rtklib]  RTKLIB's settings, strict keys (:mod:`ins.gnss.rtklib_options`; mode =
              "ppp-kinematic" for precise point positioning, no base)

The solution is written into the output folder as ``gnss.pos`` (RTKLIB's llh layout),
read back through the covariance screen (:mod:`ins.io.pos_screen`), and filtered by
``[gnss] quality`` / ``quality_scale`` and shifted by ``[gnss] time_shift_s`` as a
``.pos`` file given in ``[files] gnss`` would be.  In kinematic mode the forward and
backward runs are compared as well (:mod:`ins.gnss.separation`:
``fwd_bwd_separation.txt`` and ``.png`` beside it).  What was done is returned as a
dict for the summary (:func:`run_raw_gnss`).
"""
import os
import warnings
from dataclasses import dataclass

from ins.common.errors import InputError, QualityWarning

__all__ = ["RawGnss", "RAW_KEYS", "raw_gnss_config", "run_raw_gnss", "GNSS_POS",
           "SEPARATION_TXT", "SEPARATION_PNG", "source_lines"]

#: ``[files]`` keys of raw GNSS input.
RAW_KEYS = ("rover", "base", "nav", "sp3", "clk", "atx", "dcb")
GNSS_POS = "gnss.pos"
SEPARATION_TXT = "fwd_bwd_separation.txt"
SEPARATION_PNG = "fwd_bwd_separation.png"


@dataclass(frozen=True)
class RawGnss:
    """Raw GNSS inputs of a run (paths) and RTKLIB's settings
    (:class:`~ins.gnss.rtklib_options.RtklibOptions`)."""

    rover: str
    base: str = None
    nav: tuple = ()
    sp3: tuple = ()
    clk: tuple = ()
    options: object = None
    atx: str = None
    dcb: str = None


def _paths(value, where, many):
    if value is None:
        return () if many else None
    if isinstance(value, (str, os.PathLike)):
        return (os.fspath(value),) if many else os.fspath(value)
    if many and isinstance(value, (list, tuple)) and value and all(
            isinstance(v, (str, os.PathLike)) for v in value):
        return tuple(os.fspath(v) for v in value)
    raise InputError(f"{where}: expected a path" + (" or a list of paths" if many else "")
                     + f", got {value!r}")


def raw_gnss_config(files, rtklib_table, path=None):
    """The :class:`RawGnss` of the ``[files]`` entries (paths already resolved) and the
    ``[rtklib]`` table, or None when ``[files]`` has no raw GNSS key.

    Raises
    ------
    InputError
        Naming the file and key: both ``gnss`` and ``rover``, raw keys without
        ``rover``, a value that is no path, bad ``[rtklib]`` keys.
    """
    from ins.gnss.rtklib_options import mode_without_base, read_rtklib_options
    where = (lambda key: f"{path}: [files] {key}") if path else (lambda key: f"[files] {key}")
    given = [k for k in RAW_KEYS if files.get(k) not in (None, [], ())]
    if not given:
        if rtklib_table is not None:
            raise InputError(f"{path + ': ' if path else ''}[rtklib]: RTKLIB's settings "
                             f"without raw GNSS input ([files] rover, base, nav)")
        return None
    if "rover" not in given:
        raise InputError(f"{where('rover')}: missing (the rover's RINEX observations or "
                         f"u-blox log; {', '.join(given)} given without it)")
    if files.get("gnss") is not None:
        raise InputError(f"{where('gnss')}: give either a GNSS solution (gnss) or raw "
                         f"observations (rover, base, nav), not both")
    options = read_rtklib_options(rtklib_table, path, mode=mode_without_base(
        rtklib_table, files.get("base") or None))
    return RawGnss(rover=_paths(files["rover"], where("rover"), False),
                   base=_paths(files.get("base"), where("base"), False),
                   nav=_paths(files.get("nav"), where("nav"), True),
                   sp3=_paths(files.get("sp3"), where("sp3"), True),
                   clk=_paths(files.get("clk"), where("clk"), True),
                   atx=_paths(files.get("atx"), where("atx"), False),
                   dcb=_paths(files.get("dcb"), where("dcb"), False),
                   options=options)


def run_raw_gnss(cfg, folder):
    """Run RTKLIB on ``cfg.gnss_raw`` into ``folder`` and return the GNSS log of the
    filter with what was done.

    Parameters
    ----------
    cfg : ins.estimation.pipeline.config.ProcessConfig
        With ``gnss_raw`` (:class:`RawGnss`) and ``gnss_raw_plot`` (write the
        separation figure); its ``gnss_quality``,
        ``gnss_quality_scale`` and time shifts apply to the solution.
    folder : str
        An existing folder: ``gnss.pos`` (and in kinematic mode the separation files)
        are written there, atomically.

    Returns
    -------
    log : ins.io.gnss_log.GnssLog
    source : dict
        ``path``, ``mode``, ``direction``, ``ephemeris``, ``counts`` ({Q: epochs}),
        ``rover_epochs``, ``repaired``, ``dropped`` (the covariance screen),
        ``run_time_s``, ``poor`` (:func:`ins.gnss.rtklib_engine.poor_reason` or None),
        ``separation`` (:class:`ins.gnss.separation.Separation` or None).
    """
    from ins.gnss.rtklib_engine import poor_reason, solve
    from ins.gnss.rtklib_options import CARRIER_MODES
    from ins.io.gnss_quality import apply_quality
    raw = cfg.gnss_raw
    opts = raw.options
    out = os.path.join(folder, GNSS_POS)
    kw = dict(base=raw.base, sp3=raw.sp3, clk=raw.clk, atx=raw.atx, dcb=raw.dcb)
    sol = solve(raw.rover, raw.nav or None, out, options=opts, **kw)
    screen = sol.log.screen
    poor = poor_reason(sol)
    if poor:
        # named as the user finds it (folder is the run's hidden staging folder)
        warnings.warn(f"{GNSS_POS} (the output folder's): RTKLIB's solution: {poor}",
                      QualityWarning, stacklevel=2)
    sep = None
    if opts.mode == "kinematic":
        from ins.gnss.separation import forward_backward, plot_separation, write_separation
        sep = forward_backward(raw.rover, raw.nav or None, folder, options=opts, **kw)
        write_separation(sep, os.path.join(folder, SEPARATION_TXT))
        if cfg.gnss_raw_plot:
            plot_separation(sep, os.path.join(folder, SEPARATION_PNG))
    source = {"path": out, "mode": opts.mode,
              "direction": opts.direction if opts.mode in CARRIER_MODES or opts.is_ppp
              else None,
              "ephemeris": sol.ephemeris, "counts": sol.counts(),
              "rover_epochs": sol.rover_epochs,
              "repaired": 0 if not screen else int(screen.repaired_lines.size),
              "dropped": 0 if not screen else int(screen.dropped_lines.size),
              "run_time_s": sol.run_time_s, "poor": poor, "separation": sep}
    log = apply_quality(sol.log, cfg.gnss_quality, cfg.gnss_quality_scale)
    return log.shifted(cfg.gnss_time_shift_s, cfg.gnss_velocity_time_shift_s), source


_QNAME = {1: "fix", 2: "float", 3: "sbas", 4: "dgnss", 5: "single", 6: "ppp"}


def source_lines(source, path=None):
    """Lines for a summary: the GNSS source of a run (:func:`run_raw_gnss`); ``path``
    names the solution file instead of ``source["path"]`` (a staged output folder)."""
    c = source["counts"]
    n = sum(c.values())
    how = source["mode"] + (f", {source['direction']}" if source["direction"] else "")
    parts = ", ".join(f"{_QNAME.get(q, q)} {k}" for q, k in sorted(c.items()))
    lines = [f"GNSS source: RTKLIB {how}, {source['ephemeris']} ephemeris -> "
             f"{path or source['path']}: {n} of {source['rover_epochs']} rover epochs solved "
             f"({parts}); covariance screen: {source['repaired']} repaired, "
             f"{source['dropped']} dropped"]
    if source["poor"]:
        lines.append(f"GNSS source: poor: {source['poor']}")
    if source["separation"] is not None:
        from ins.gnss.separation import summary_lines
        lines += ["GNSS source: " + line for line in summary_lines(source["separation"])]
    return lines
