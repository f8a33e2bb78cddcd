"""A GNSS solution from raw observations with RTKLIB's engine (demo5, through the
``pyrtklib5`` binding: optional extra ``pip install 'insphoto[gnss]'``).

:func:`solve` runs RTKLIB's ``postpos`` (the engine of ``rnx2rtkp``/``rtkpost``) on a
rover's RINEX 2/3 observations (or a receiver log in any format RTKLIB decodes,
converted on the way by :mod:`ins.gnss.receiver_formats`), an optional base station's,
the broadcast navigation file(s)
and optional precise products (SP3 orbits and clocks, RINEX CLK), with the
settings of :class:`~ins.gnss.rtklib_options.RtklibOptions`, and reads the solution back
with :func:`ins.io.rtklib.read_pos` (whose covariance screen catches RTKLIB's invalid
sigmas).  Nothing of RTKLIB's algorithms is written again here.

About the binding (pyrtklib5 0.2.8, RTKLIB demo5 2.5.0 "EX"; its README calls the port
not fully tested):

- ``postpos`` returns 0 even when an input file is missing or unreadable, and then
  writes nothing: the inputs are checked here first (each observation file is read with
  RTKLIB's ``readrnx``, which also gives the number of epochs), and an empty solution is
  an error;
- it writes ``<out>_events.pos`` beside the solution: the run goes into a temporary
  folder beside the output, the solution is moved into place (``os.replace``, atomic)
  and the folder with the side file is removed;
- RTKLIB's option defaults live in C globals, and ``postpos`` is not re-entrant: runs
  are serialized by a lock; and it leaves navigation data in those globals for the next
  run (the Klobuchar coefficients), so that each run is made in a fresh child process
  (:func:`_postpos_isolated`).
"""
import os
import shutil
import tempfile
import threading
import time as wallclock
import warnings
from dataclasses import dataclass

import numpy as np

from ins.common.errors import InputError, InputWarning
from ins.gnss.rtklib_options import CARRIER_MODES, RtklibOptions, fill_prcopt

__all__ = ["solve", "GnssSolution", "binding", "count_epochs", "GNSS_EXTRA",
           "MIN_SOLVED_FRACTION", "MIN_FIXED_FRACTION", "poor_reason"]

GNSS_EXTRA = "pip install 'insphoto[gnss]'"
#: A solution with fewer solved epochs than this fraction of the rover's is poor.
MIN_SOLVED_FRACTION = 0.5
#: A carrier-phase solution (kinematic, static) with fewer fixed epochs than this
#: fraction of the solved ones is poor: its float positions are decimetres to metres.
MIN_FIXED_FRACTION = 0.1

#: Seconds in a GPS week.
WEEK_S = 604800

_LOCK = threading.Lock()


def binding():
    """The imported ``pyrtklib5`` module, or an :class:`InputError` naming the extra."""
    try:
        import pyrtklib5
    except ImportError:
        raise InputError(f"raw GNSS processing needs RTKLIB's engine (the pyrtklib5 "
                         f"binding, CPython 3.10-3.13): {GNSS_EXTRA}") from None
    return pyrtklib5


@dataclass(frozen=True)
class GnssSolution:
    """The result of :func:`solve`.

    Attributes
    ----------
    log : ins.io.gnss_log.GnssLog
        The solution as read back from the ``.pos`` file (screened covariances).
    path : str
        The ``.pos`` file written.
    rover_epochs : int
        Epochs in the rover's observation file(s) (within the time window).
    options : RtklibOptions
    run_time_s : float
        Wall time of RTKLIB's ``postpos``, s.
    ephemeris : str
        ``"broadcast"``, or ``"precise"`` when SP3/CLK files were given.
    span : tuple of float
        (first, last) epoch processed: the rover's, within ``window``; GPS seconds
        since 1980-01-06.
    unused_systems : tuple of str
        Systems of ``options.systems`` observed by the rover but without a broadcast
        ephemeris in the navigation files: RTKLIB uses none of their satellites.
    """

    log: object
    path: str
    rover_epochs: int
    options: RtklibOptions
    run_time_s: float
    ephemeris: str = "broadcast"
    span: tuple = None
    unused_systems: tuple = ()

    def counts(self):
        """``{Q: number of epochs}`` of the solution (RTKLIB's quality flags)."""
        q = self.log.quality
        return {int(k): int(np.sum(q == k)) for k in np.unique(q)}


def _check_file(path, what):
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"{what}: no such file", path=path)
    return path


def count_epochs(path, rtk=None, shown=None):
    """Number of observation epochs in a RINEX observation file (RTKLIB's ``readrnx``
    and ``sortobs``); ``shown`` is the file named in the message (the u-blox log a
    RINEX file was converted from).

    Raises
    ------
    InputError
        The file is missing or RTKLIB reads no observation from it.
    """
    return _epochs_and_span(path, rtk, shown)[0]


def observation_span(path, rtk=None, shown=None):
    """(first, last) observation epoch of a RINEX observation file, GPS seconds since
    1980-01-06 (as :func:`count_epochs` reads it)."""
    return _epochs_and_span(path, rtk, shown)[1]


def _epochs_and_span(path, rtk=None, shown=None, window=None, systems=None):
    """(epochs, (first, last) GPS s since 1980) of a RINEX observation file; with a
    ``window`` (first, last, GPS s), the epochs within it (the span is the file's);
    ``systems``, a set, gets RTKLIB's system bits of the satellites observed."""
    rtk = binding() if rtk is None else rtk
    path = _check_file(path, "RINEX observations")
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    span = None
    try:
        ok = rtk.readrnx(path, 1, "", obs, nav, sta)
        n = rtk.sortobs(obs) if ok and obs.n > 0 else 0
        if n > 0:
            week = rtk.Arr1Dint(1)
            span = tuple(rtk.time2gpst(obs.data[i].time, week) + WEEK_S * week[0]
                         for i in (0, obs.n - 1))
            if systems is not None:
                prn = rtk.Arr1Dint(1)
                systems.update({rtk.satsys(obs.data[i].sat, prn) for i in range(obs.n)})
            if window is not None:
                times = set()
                for i in range(obs.n):
                    t = rtk.time2gpst(obs.data[i].time, week) + WEEK_S * week[0]
                    if window[0] - 1e-3 <= t <= window[1] + 1e-3:
                        times.add(round(t, 3))
                n = len(times)
    finally:
        rtk.freeobs(obs)
        rtk.freenav(nav, 0xFF)
    if span is None:
        raise InputError("RTKLIB reads no observation epoch from this file (expected RINEX "
                         "2.x/3.x observations or a receiver log: --gnss-format)",
                         path=path if shown is None else os.fspath(shown))
    if _ends_inside_a_line(path):
        warnings.warn(f"{path if shown is None else os.fspath(shown)}: the file ends inside a "
                      f"line: cut short (an interrupted download or copy?); RTKLIB read "
                      f"the {int(n)} epochs before the cut",
                      InputWarning, stacklevel=3)
    return int(n), span


def _ends_inside_a_line(path):
    """Whether a text file's last byte is not a newline (RINEX lines all end with one)."""
    with open(path, "rb") as f:
        f.seek(0, os.SEEK_END)
        if f.tell() == 0:
            return False
        f.seek(-1, os.SEEK_END)
        return f.read(1) not in (b"\n", b"\r")


def solve(rover, nav, out_path, base=None, sp3=(), clk=(), options=None, atx=None,
          dcb=None, window=None):
    """Run RTKLIB's post-processing and read the solution back.

    Parameters
    ----------
    rover : str or os.PathLike
        Rover observations: RINEX 2.x/3.x, or a receiver log of any format RTKLIB
        decodes (RTCM3, NovAtel, u-blox, SBF, ...: :mod:`ins.gnss.receiver_formats`;
        detected from the content unless ``options.rover_format`` names it), converted
        on the way with RTKLIB's ``convrnx``.
    nav : str or os.PathLike or sequence of them, or None
        Broadcast navigation file(s) (RINEX nav: GPS ``.n``, GLONASS ``.g``, mixed ``.p``
        / RINEX 3 ``_MN.rnx``); may be empty when a u-blox log holds the ephemerides
        (RXM-SFRBX).
    out_path : str or os.PathLike
        The ``.pos`` file to write (RTKLIB's llh layout, GPS week and seconds).
    base : str or os.PathLike, optional
        Base station observations, RINEX or a receiver log (``options.base_format``;
        required by every mode but ``single``).
    sp3, clk : sequence of paths
        Precise orbits (SP3) and clocks (RINEX CLK); given any, RTKLIB uses the precise
        ephemeris; the PPP modes need both.  They must cover the processed span
        (:func:`ins.gnss.products.check_coverage`); RINEX clock 3.04 is read through a
        3.00 copy (:func:`ins.gnss.products.readable_clock`).
    options : RtklibOptions, optional
    atx : str or os.PathLike, optional
        ANTEX antenna file: satellite and receiver (type from the rover's RINEX header)
        antenna phase centre offsets and variations.
    dcb : str or os.PathLike, optional
        Code biases as RTKLIB's ``readdcb`` reads them (CODE's ``P1C1``/``P1P2`` DCB
        files, Bias-SINEX).
    window : (float, float), optional
        Process only the epochs from ``window[0]`` to ``window[1]``, GPS seconds since
        1980-01-06 (:func:`ins.gnss.products.gps_seconds`); None: all.

    Returns
    -------
    GnssSolution

    Raises
    ------
    InputError
        The extra missing, a missing or unreadable input, a mode that needs a base
        without one, PPP without precise orbits or clocks, precise products that do not
        cover the observations, no broadcast navigation, RTKLIB writing no solution
        epoch.
    """
    rtk = binding()
    opts = RtklibOptions() if options is None else options
    navs = [] if nav is None else ([nav] if isinstance(nav, (str, os.PathLike)) else list(nav))
    navs = [_check_file(p, "RINEX navigation") for p in navs]
    precise = [_check_file(p, "precise orbit (SP3)") for p in sp3]
    clocks = [_check_file(p, "precise clock (RINEX CLK)") for p in clk]
    precise += clocks
    if opts.is_ppp and not (sp3 and clk):
        missing = [k for k, v in (("sp3", sp3), ("clk", clk)) if not v]
        raise InputError(f"RTKLIB mode {opts.mode!r} (precise point positioning) needs "
                         f"precise orbits and clocks: "
                         f"{' and '.join('--' + k for k in missing)} missing (in a config: "
                         f"[files] {' and '.join(missing)})")
    atx = None if atx is None else _check_file(atx, "antenna file (ANTEX, --atx)")
    dcb = None if dcb is None else _check_file(dcb, "code biases (DCB, --dcb)")
    for p in (atx, dcb):
        if p is not None and len(os.fsencode(p)) >= 1023:
            raise InputError("path too long for RTKLIB (1023 bytes at most)", path=p)
    if opts.uses_base and base is None:
        raise InputError(f"RTKLIB mode {opts.mode!r} needs the base station's observations "
                         f"(--base, or [files] base); mode 'single' needs none")
    rover = _check_file(rover, "rover observations (RINEX or a receiver log)")
    if opts.uses_base:
        base = _check_file(base, "base observations (RINEX or a receiver log)")
    out_path = os.fspath(out_path)
    folder = os.path.dirname(os.path.abspath(out_path))
    if os.path.isdir(out_path):
        raise InputError("is a directory, not an output file", path=out_path)
    if not os.path.isdir(folder):
        raise InputError("the output's folder does not exist", path=out_path)
    tmp = tempfile.mkdtemp(prefix=".rtklib-", dir=folder)
    try:
        rover_obs, rover_nav = _observations(rover, tmp, "rover", rtk, opts.rover_format,
                                             navs)
        observed = set()
        rover_epochs, span = _epochs_and_span(rover_obs, rtk, shown=rover, window=window,
                                              systems=observed)
        span = _within(span, window, rover)
        if atx is not None:
            _check_antenna(rover_obs, atx, rover)
        if precise:
            from ins.gnss.products import check_coverage, readable_clock
            check_coverage(span, [p for p in precise if p not in clocks], clocks)
            precise = [p for p in precise if p not in clocks] + [
                readable_clock(p, tmp) for p in clocks]
        files = [rover_obs]
        converted_navs = [rover_nav]
        if opts.uses_base:
            from ins.gnss.receiver_formats import obs_epoch
            base_obs, base_nav = _observations(base, tmp, "base", rtk, opts.base_format,
                                               navs, epoch=obs_epoch(rover_obs, rtk))
            count_epochs(base_obs, rtk, shown=base)
            if (base_obs != base and opts.base_position == "rinex"
                    and opts.base_lla_deg is None and not _header_position(base_obs)):
                raise InputError("the base log gives no antenna position (RTCM3 1005/1006 "
                                 "messages do): set [rtklib] base_position = \"single\" or "
                                 "base_lla_deg = [lat deg, lon deg, h m]", path=base)
            files.append(base_obs)
            converted_navs.append(base_nav)
        navs += [p for p in converted_navs if p]
        if not navs:
            raise InputError("RTKLIB needs the broadcast navigation (--nav, or [files] nav: "
                             "RINEX nav); a receiver log gives it only with its "
                             "ephemeris messages (u-blox RXM-SFRBX, RTCM3 1019, ...)", path=rover)
        unused = _without_broadcast(rtk, opts, observed, navs)
        if unused:
            warnings.warn(f"{os.fspath(rover)}: {', '.join(unused)} observed but without a "
                          f"broadcast ephemeris (--nav): RTKLIB drops their satellites, even "
                          f"with precise orbits and clocks", InputWarning, stacklevel=2)
        files += navs + precise
        tmp_pos = os.path.join(tmp, "solution.pos")
        with _LOCK:
            status, run_time = _postpos_isolated(opts, bool(precise), files, tmp_pos,
                                                 atx=atx, dcb=dcb, window=window)
        if status != 0 or not os.path.isfile(tmp_pos) or not _has_epoch(tmp_pos):
            shown = [rover] + ([base] if opts.uses_base else []) + navs + precise
            raise InputError(f"RTKLIB wrote no solution epoch (postpos status {status}): "
                             f"no common epochs or satellites between the observations "
                             f"and the navigation data{_precise_hint(precise)}? inputs: "
                             f"{', '.join(map(os.fspath, shown))}", path=rover)
        os.replace(tmp_pos, out_path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    from ins.io.rtklib import read_pos
    log = read_pos(out_path)
    return GnssSolution(log, out_path, rover_epochs, opts, run_time,
                        "precise" if precise else "broadcast", span, tuple(unused))


def _without_broadcast(rtk, opts, observed, navs):
    """Names of the systems of ``opts`` that the rover observed (``observed``: RTKLIB
    system bits) but that no navigation file has an ephemeris of."""
    from ins.gnss.rtklib_options import system_bits
    bits = system_bits(rtk)
    wanted = [s for s in opts.systems if bits[s] in observed]
    if not wanted:
        return []
    have = set()
    nav, obs, sta = rtk.nav_t(), rtk.obs_t(), rtk.sta_t()
    prn = rtk.Arr1Dint(1)
    try:
        for p in navs:
            rtk.readrnx(os.fspath(p), 0, "", obs, nav, sta)
        have = {rtk.satsys(nav.eph[i].sat, prn) for i in range(nav.n)}
        if nav.ng > 0:
            have.add(rtk.SYS_GLO)
        if nav.ns > 0:
            have.add(rtk.SYS_SBS)
    finally:
        rtk.freeobs(obs)
        rtk.freenav(nav, 0xFF)
    return [s for s in wanted if bits[s] not in have]


def _check_antenna(obs_path, atx, shown):
    """Warn when the rover's antenna (its RINEX header) is not in the ANTEX file: RTKLIB
    then applies no receiver phase centre, silently."""
    from ins.gnss.products import antex_antennas, rinex_antenna
    antenna = rinex_antenna(obs_path)
    known = antex_antennas(atx)
    if antenna and antenna not in known and antenna.split()[0] not in {
            k.split()[0] for k in known if k}:
        warnings.warn(f"{os.fspath(shown)}: its antenna {antenna!r} is not in the ANTEX file "
                      f"{atx}: RTKLIB applies no receiver phase centre (the solution is that "
                      f"of the antenna's mean phase centre, not of its reference point)",
                      InputWarning, stacklevel=3)


def _within(span, window, rover):
    """The observations' span cut to ``window`` (GPS s since 1980), or an error."""
    if window is None:
        return span
    from ins.gnss.products import format_gpst
    w0, w1 = (float(v) for v in window)
    first, last = max(span[0], w0), min(span[1], w1)
    if not w0 < w1 or first > last:
        raise InputError(f"the time window {format_gpst(w0)} to {format_gpst(w1)} holds no "
                         f"observation (they span {format_gpst(span[0])} to "
                         f"{format_gpst(span[1])})", path=rover)
    return first, last


def _gtime(rtk, t):
    """RTKLIB's time of GPS seconds since 1980-01-06 (the zero time for None)."""
    if t is None or not np.isfinite(t):
        return rtk.gtime_t()
    week = int(t // WEEK_S)
    return rtk.gpst2time(week, float(t - week * WEEK_S))


def _postpos(opts, precise, files, out, atx=None, dcb=None, window=None):
    """RTKLIB's ``postpos`` in this process: ``(status, wall time s)``."""
    rtk = binding()
    po, so, fo = fill_prcopt(opts, rtk, precise=precise, atx=atx, dcb=dcb)
    ts, te = (None, None) if window is None else window
    t0 = wallclock.perf_counter()
    status = rtk.postpos(_gtime(rtk, ts), _gtime(rtk, te), 0.0, 0.0, po, so, fo, files,
                         len(files), out, "", "")
    return status, wallclock.perf_counter() - t0


def _postpos_isolated(opts, precise, files, out, atx=None, dcb=None, window=None):
    """:func:`_postpos` in a fresh Python process (``python -m ins.gnss.rtklib_engine``,
    the arguments as JSON on its standard input; not multiprocessing, whose spawn would
    run an unguarded user script again).

    RTKLIB keeps its navigation data in C globals that a run does not fully reset: the
    Klobuchar coefficients of a navigation file with ``ION ALPHA``/``ION BETA`` stayed
    for the next run in the same process, whose file had none, instead of RTKLIB's
    defaults (on the PSINS set, a run after the simulated flight's came out 1.2 m lower).
    A process per run gives every run RTKLIB's fresh state, as ``rnx2rtkp`` has; it
    costs the child's start-up (a few tenths of a second)."""
    import dataclasses
    import json
    import subprocess
    import sys
    job = {"options": dataclasses.asdict(opts), "precise": precise,
           "files": [os.fspath(f) for f in files], "out": os.fspath(out), "atx": atx,
           "dcb": dcb, "window": None if window is None else [float(w) for w in window]}
    proc = subprocess.run([sys.executable, "-m", "ins.gnss.rtklib_engine"],
                          input=json.dumps(job), capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"RTKLIB's postpos process failed (exit {proc.returncode}): "
                           f"{proc.stderr.strip()[-2000:]}")
    status, run_time = json.loads(proc.stdout.strip().splitlines()[-1])
    return status, run_time


def _child():
    """Entry of :func:`_postpos_isolated`'s process: one ``postpos`` run."""
    import json
    import sys
    job = json.loads(sys.stdin.read())
    o = job["options"]
    o["systems"] = tuple(o["systems"])
    if o.get("base_lla_deg") is not None:
        o["base_lla_deg"] = tuple(o["base_lla_deg"])
    status, run_time = _postpos(RtklibOptions(**o), job["precise"], job["files"], job["out"],
                                atx=job.get("atx"), dcb=job.get("dcb"), window=job.get("window"))
    print(json.dumps([int(status), run_time]))


def _precise_hint(precise):
    return (" (the precise orbits and clocks must cover the whole span of the "
            "observations)" if precise else "")


def _observations(path, folder, stem, rtk, fmt=None, navs=(), epoch=None):
    """(RINEX observation path, converted navigation path or None) of ``path``: a
    receiver log (format ``fmt``, None: detected from the content) is converted into
    ``folder`` first (:func:`ins.gnss.receiver_formats.observations`; ``epoch`` dates
    a log without a complete week: the rover's first for the base)."""
    from ins.gnss.receiver_formats import detect_format, observations
    fmt = detect_format(path) if fmt is None else fmt
    if fmt == "rinex":
        return path, None
    with _LOCK:                                       # RTKLIB's clock is set meanwhile
        return observations(path, folder, rtk, stem, fmt, navs, epoch)


def _header_position(path):
    """The ``APPROX POSITION XYZ`` of a RINEX observation header (m), or None when it
    is absent or zero."""
    with open(path, "rb") as f:
        for line in f:
            if b"APPROX POSITION XYZ" in line:
                xyz = [float(v) for v in line[:42].split()]
                return xyz if len(xyz) == 3 and any(xyz) else None
            if b"END OF HEADER" in line:
                return None
    return None


def _has_epoch(path):
    with open(path, "rb") as f:
        return any(line.strip() and not line.startswith(b"%") for line in f)


def poor_reason(solution):
    """Why the solution is not to be trusted (one line), or ``None``: fewer than
    :data:`MIN_SOLVED_FRACTION` of the rover's epochs solved, or (kinematic, static)
    fewer than :data:`MIN_FIXED_FRACTION` of them fixed."""
    n = len(solution.log)
    solved = n / max(solution.rover_epochs, 1)
    if solved < MIN_SOLVED_FRACTION:
        return (f"only {n} of {solution.rover_epochs} rover epochs solved "
                f"({100 * solved:.0f} % < {100 * MIN_SOLVED_FRACTION:.0f} %)")
    if solution.options.mode in CARRIER_MODES:
        fixed = solution.counts().get(1, 0)
        if fixed < MIN_FIXED_FRACTION * n:
            return (f"only {fixed} of {n} epochs fixed ({100 * fixed / n:.0f} % < "
                    f"{100 * MIN_FIXED_FRACTION:.0f} %): float positions are decimetres to "
                    f"metres off")
    return None


def spread_enu_m(log, quality=None):
    """Standard deviation (m) of the east, north, up positions about their mean, of the
    epochs with ``quality`` (all when None; NaN when fewer than 2): the scatter of a
    static receiver."""
    keep = np.ones(len(log), bool) if quality is None else log.quality == quality
    if keep.sum() < 2:
        return np.full(3, np.nan)
    from ins.nav.earth import ned_offset
    lla = log.lla[keep]
    ned = ned_offset(np.mean(lla, axis=0), lla)
    return np.std(np.column_stack([ned[:, 1], ned[:, 0], -ned[:, 2]]), axis=0, ddof=1)


if __name__ == "__main__":
    _child()
