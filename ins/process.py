"""GNSS/INS post-processing pipeline: configuration or flight manifest -> files -> forward
filter -> RTS smoother -> results (and the output files).

The configuration (TOML keys, the flight manifest) is read by :mod:`ins.process_config`;
the output files are written by :mod:`ins.process_outputs`.
Library code: nothing is printed; progress goes to ``progress(done, total)``.

Trust
-----
The start position is checked against the first GNSS fix at or after the start time
(within :data:`START_FIX_WINDOW_S`): the start state is moved along its velocity to the
fix time and carried to the antenna through the lever arm.  Farther from the fix than
``START_SIGMAS`` (5) times the combined sigma (fix, start position, start velocity times
the time to the fix) plus :data:`START_SLACK_M` (300 m) is an ``InputError`` naming the
config key and the distance (a start of another flight, a wrong ``time_s``); between 5
sigma and that bound the start position sigma is widened to the distance, with a
warning.  Without ``lat_deg, lon_deg, h_m`` in ``[initial]`` (method ``given``) the
start position is taken from that fix, less the lever arm; the static and in-air
alignments take it from the fixes the same way.

After the run (:func:`assess_quality`): more than :data:`REJECT_WARN_FRACTION` (5 %)
of the GNSS measurements rejected by the innovation test is a
:class:`~ins.errors.QualityWarning`; more than :data:`REJECT_ERROR_FRACTION` (50 %), no
accepted measurement at all, or a written solution (smoothed, or forward with
``smooth = false``) farther than :data:`DEPART_SIGMAS` (10) fix sigmas from every fix
for :data:`DEPART_SPAN_S` (30 s) or more is a :class:`~ins.errors.QualityError` naming
the likely cause (start state, IMU noise settings, lever arm, time base), unless
``accept_poor`` (then a warning).  A negative variance beyond rounding, or a covariance
the smoother cannot factor, is a ``QualityError`` naming the time and the state.
"""
import itertools
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from . import _filter_kernels, earth
from .alignment import align_gnss_heading, align_static, check_static_heading
from .error_model import NAV, STATE
from .errors import InputError, QualityError, QualityWarning
from .filter import filterpy_functions, run_forward
from .filter_settings import FilterSettings
from .imu import ImuLog
from .imu_blocks import iter_imu, prefetch
from .gnss import read_gnss
from .lever_arm import LeverArm, antenna_lla
from .mechanization import NavState
from .mount import read_mount
# the configuration and the output files, importable from here as before
from .process_config import (METHODS, POSITION_KEYS, ProcessConfig,  # noqa: F401
                             config_from_manifest, load_config)
from .process_outputs import euler_std_deg, write_outputs  # noqa: F401
from .smoother import iter_smoothed, rts_errors
from .trajectory import Trajectory


#: Start-position check (module notes): refused beyond START_SIGMAS x sigma + START_SLACK_M.
START_SIGMAS = 5.0
START_SLACK_M = 300.0
#: The GNSS fix that checks (or gives) the start position lies at most this long after it, s.
START_FIX_WINDOW_S = 10.0
#: Fraction of GNSS measurements rejected by the innovation test: warning above the first,
#: QualityError above the second.
REJECT_WARN_FRACTION = 0.05
REJECT_ERROR_FRACTION = 0.5
#: A fix "departs" when the written solution is more than DEPART_SIGMAS fix sigmas (RMS
#: over north, east, down of residual / sigma) from it; consecutive departing fixes over
#: DEPART_SPAN_S or more are a QualityError (the error grew and stayed: not a blunder).
DEPART_SIGMAS = 10.0
DEPART_SPAN_S = 30.0
#: Naming the cause: an estimated sensor error beyond this many stated sigmas, or a mean
#: NIS of the accepted fixes beyond this many times its expectation (3), points at the
#: IMU noise settings (healthy test and benchmark runs: at most 2.8 sigma, NIS 2.8-3.0).
SENSOR_SIGMAS = 3.0
NIS_FACTOR = 2.0


@dataclass
class ProcessResult:
    """Results of :func:`process` (SI units).

    The trajectories at every IMU epoch are streamed: :meth:`iter_forward` and
    :meth:`iter_smoothed` yield :class:`~ins.trajectory.Trajectory` pieces in time order
    (from the forward pass's store, in memory or a temporary file); :attr:`forward` and
    :attr:`smoothed` give them whole (in memory).  ``node_time`` holds the filter nodes
    with ``forward_std``/``smoothed_std`` (m, 21) and ``forward_sensors``/
    ``smoothed_sensors`` (m, 12: gyro bias rad/s, accel bias m/s^2, scales);
    ``errors_forward``/``errors_smoothed`` (:class:`ins.accuracy.TrajectoryErrors`) when
    a truth file was given; ``quality`` the assessment of :func:`assess_quality` and
    ``start_check`` that of :func:`check_start` (when the run made them).
    """

    fwd: object
    xs: object
    node_time: np.ndarray
    forward_std: np.ndarray
    smoothed_std: np.ndarray
    forward_sensors: np.ndarray
    smoothed_sensors: np.ndarray
    alignment: object
    counts: dict
    errors_forward: object = None
    errors_smoothed: object = None
    quality: dict = None
    start_check: dict = None

    def iter_forward(self):
        for _, time, states in self.fwd.trajectory.chunks():
            yield _trajectory(time, states)

    def iter_smoothed(self):
        if self.xs is None:
            yield from self.iter_forward()
            return
        for time, states in iter_smoothed(self.fwd, self.xs):
            yield _trajectory(time, states)

    @cached_property
    def forward(self):
        return Trajectory.concatenate(self.iter_forward())

    @cached_property
    def smoothed(self):
        return Trajectory.concatenate(self.iter_smoothed())

    def node_solution(self):
        """The written solution (smoothed, else forward) at the nodes (after their
        updates), shape (m, 10) in the ``ins._kernels`` layout."""
        states = self.fwd.node_states.copy()
        if self.xs is not None:
            for j in range(len(states)):
                _filter_kernels.correct_state(states[j], self.xs[j, STATE.nav])
        return states

    def node_attitude(self):
        """Smoothed attitude quaternions at the nodes, shape (m, 4)."""
        return self.node_solution()[:, NAV.q_nb]


def _initial(cfg, imu, gnss):
    """Initial state, its time and the alignment (``None`` for a given state) for a
    whole :class:`~ins.imu.ImuLog`."""
    st = _start(cfg, [imu], gnss)
    return st.state, st.time, st.alignment


@dataclass
class _Start:
    """The start of a run: state, its time, the alignment (or None), the IMU blocks to
    process, ``initial_time`` for :func:`ins.filter.run_forward` (the state's exact time
    when it is not an IMU epoch), sigmas implied by a position taken from GNSS, and the
    name of what gave the position (for messages)."""

    state: NavState
    time: float
    alignment: object
    blocks: object
    initial_time: float = None
    std: dict = field(default_factory=dict)
    position_source: str = None


def _lever(cfg, mount=None):
    return LeverArm(cfg.lever_bp, cfg.lever_ap, mount)


def _config_position(cfg):
    """Name of the config keys that gave the start position (for messages)."""
    keys = "[initial] lat_deg, lon_deg, h_m"
    return f"{cfg.initial_source}: {keys}" if cfg.initial_source else keys


def _fix_at(gnss, t0):
    """Index of the first GNSS record at or after ``t0`` (s), or None."""
    k = int(np.searchsorted(gnss.time, t0 - 1e-9))
    return k if k < len(gnss) else None


def _less_lever_arm(lla_ant, q_nb, lever, t):
    """IMU position (lat, lon rad, h m) of an antenna position, through the arm at ``t``."""
    from .rotation import quat_to_dcm
    l_b = lever.at(t)[0][0]
    return earth.offset_lla(lla_ant, -(quat_to_dcm(q_nb) @ l_b))[0]


def _peek(blocks):
    """The first IMU block and an iterator giving all of them."""
    blocks = iter(blocks)
    first = next(blocks, None)
    if first is None:
        raise InputError("the IMU log is empty")
    return first, itertools.chain([first], blocks)


def _start(cfg, blocks, gnss, lever=None):
    """The start of a run (:class:`_Start`); the IMU blocks read for a static window (or
    peeked at for the start time) are given back in ``blocks``."""
    lever = _lever(cfg) if lever is None else lever
    init = cfg.initial
    if cfg.method == "given":
        need = ("vel_ned_mps", "rpy_deg")
        missing = [k for k in need if k not in init]
        have = [k for k in POSITION_KEYS if k in init]
        if 0 < len(have) < 3:
            missing += [k for k in POSITION_KEYS if k not in init]
        if missing:
            where = f"{cfg.initial_source}: " if cfg.initial_source else ""
            raise InputError(f"{where}[initial] {', '.join(missing)}: needed with alignment "
                             f"method 'given' (lat_deg, lon_deg, h_m all three or none: "
                             f"without them the start position is taken from the first "
                             f"GNSS fix, less the lever arm)")
        t0 = init.get("time_s", cfg.start_s)
        if t0 is None:
            first, blocks = _peek(blocks)
            t0 = float(first.time[0])
        if have:
            state = NavState.from_degrees(init["lat_deg"], init["lon_deg"], init["h_m"],
                                          init["vel_ned_mps"], init["rpy_deg"])
            return _Start(state, t0, None, blocks, position_source=_config_position(cfg))
        k = _fix_at(gnss, t0)
        if k is None or gnss.time[k] - t0 > START_FIX_WINDOW_S:
            raise InputError(f"[initial] lat_deg, lon_deg, h_m: not given and no GNSS fix "
                             f"within {START_FIX_WINDOW_S:g} s after the start {t0!r} s to "
                             f"take the start position from (give them, or check time_s "
                             f"and the time scales of the logs)")
        v_n = np.asarray(init["vel_ned_mps"], dtype=float)
        q = NavState.from_degrees(0.0, 0.0, 0.0, v_n, init["rpy_deg"]).q_nb
        dt = float(gnss.time[k] - t0)
        lla = _less_lever_arm(gnss.lla[k], q, lever, gnss.time[k])
        lla = lla - earth.lla_rate(lla[0], lla[2], v_n) * dt           # back to t0
        vel_std = np.broadcast_to(np.asarray(init.get("vel_std_ned_mps", 0.02), float), 3)
        std = {"pos_std_ned_m": np.hypot(np.hypot(gnss.std_ned[k], 0.01), vel_std * dt)}
        return _Start(NavState(lla, v_n, q), t0, None, blocks, initial_time=t0, std=std,
                      position_source=f"the start position from {_fix_name(gnss, k)}")
    if cfg.method == "static":
        if cfg.static_window_s is None:
            raise InputError("[alignment] static_window_s: needed with method 'static'")
        t_a, t_b = cfg.static_window_s
        lla_w, k = _window_lla(cfg, gnss, t_a, t_b)
        if not check_static_heading(cfg.noise, float(lla_w[0]), t_b - t_a, gnss):
            return _in_air(cfg, gnss, t_b, lever, blocks)
        head, blocks = _read_until(blocks, t_b)
        imu = ImuLog.adopt(*(np.concatenate([getattr(b, k_) for b in head])
                             for k_ in ("time", "dtheta_b", "dvel_b")))
        al = align_static(imu, t_a, t_b, lla_w, cfg.noise)
        blocks = itertools.chain(head, blocks)
        if k is None:                                   # the config gave the position
            return _Start(al.state, al.time, al, blocks,
                          position_source=_config_position(cfg))
        lla = _less_lever_arm(gnss.lla[k], al.state.q_nb, lever, gnss.time[k])
        al = replace(al, state=NavState(lla, al.state.v_n, al.state.q_nb))
        return _Start(al.state, al.time, al, blocks,
                      position_source=f"the static alignment's position ({_fix_name(gnss, k)})")
    t_start = cfg.start_s
    if t_start is None and cfg.static_window_s is not None:
        t_start = cfg.static_window_s[0]
    return _in_air(cfg, gnss, t_start, lever, blocks)


def _in_air(cfg, gnss, t_start, lever, blocks):
    al = align_gnss_heading(gnss, t_start, stabilized=cfg.mount is not None)
    lla = _less_lever_arm(al.state.lla, al.state.q_nb, lever, al.time)
    al = replace(al, state=NavState(lla, al.state.v_n, al.state.q_nb))
    return _Start(al.state, al.time, al, blocks, initial_time=al.time,
                  position_source="the in-air alignment's position (GNSS)")


def _fix_name(gnss, k):
    line = (f":{int(gnss.line[k])}" if gnss.line is not None and gnss.path is not None
            and gnss.line[k] > 0 else "")
    where = f" ({gnss.path}{line})" if gnss.path else ""
    return f"the GNSS fix at t = {gnss.time[k]:.3f} s{where}"


def _window_lla(cfg, gnss, t_a, t_b):
    """Position for a static window: from the config (index None) or the first GNSS fix
    in the window (the antenna's; with its index)."""
    init = cfg.initial
    if "lat_deg" in init:
        return np.array([np.deg2rad(init["lat_deg"]), np.deg2rad(init["lon_deg"]),
                         init.get("h_m", 0.0)]), None
    k = int(np.searchsorted(gnss.time, t_a))
    if k >= len(gnss) or gnss.time[k] > t_b:
        raise InputError(f"no GNSS epoch in the stationary window {t_a} .. {t_b} s "
                         f"to position the static alignment")
    return gnss.lla[k], k


def _read_until(blocks, t_end):
    """The IMU blocks up to the one holding ``t_end``, and the iterator of the rest."""
    blocks = iter(blocks)
    head = []
    for b in blocks:
        head.append(b)
        if b.time[-1] >= t_end:
            break
    if not head:
        raise InputError("the IMU log is empty")
    return head, blocks


def check_start(state, t0, gnss, lever, std, source="the start position"):
    """Check a start state against the first GNSS fix at or after ``t0`` (module notes).

    Parameters
    ----------
    state : NavState
        Start state (IMU) at ``t0`` (s).
    gnss : ins.gnss.GnssLog
    lever : ins.lever_arm.LeverArm
    std : dict
        ``pos_std_ned_m`` and ``vel_std_ned_mps`` of the start (m, m/s).
    source : str
        What gave the position (the config key), for the message.

    Returns
    -------
    dict or None
        ``distance_m``, ``bound_m``, ``sigma_m``, ``time`` of the fix; None when no fix
        lies within :data:`START_FIX_WINDOW_S` after ``t0``.

    Raises
    ------
    InputError
        Beyond ``START_SIGMAS * sigma + START_SLACK_M``, naming ``source`` and the
        distance.
    """
    from .rotation import quat_to_dcm
    k = _fix_at(gnss, t0)
    if k is None or gnss.time[k] - t0 > START_FIX_WINDOW_S:
        return None
    tg = float(gnss.time[k])
    dt = tg - t0
    lla = state.lla + earth.lla_rate(state.lla[0], state.lla[2], state.v_n) * dt
    ant = antenna_lla(lla, quat_to_dcm(state.q_nb), lever.at(tg)[0][0])
    offset = earth.ned_offset(gnss.lla[k], ant)
    d = float(np.linalg.norm(offset))
    pos = np.broadcast_to(np.asarray(std["pos_std_ned_m"], float), 3)
    vel = np.broadcast_to(np.asarray(std["vel_std_ned_mps"], float), 3)
    sigma = float(np.sqrt(np.sum(gnss.std_ned[k] ** 2) + np.sum(pos ** 2)
                          + np.sum(vel ** 2) * dt ** 2))
    bound = START_SIGMAS * sigma + START_SLACK_M
    if d > bound:
        n, e, dn = offset
        raise InputError(f"{source}: the start is {d:.1f} m from {_fix_name(gnss, k)} "
                         f"(antenna through the lever arm; fix minus start: N {-n:.1f} E "
                         f"{-e:.1f} D {-dn:.1f} m), more than the bound {bound:.1f} m "
                         f"({START_SIGMAS:g} sigma = {START_SIGMAS * sigma:.2f} m + "
                         f"{START_SLACK_M:g} m): a start of another flight, a wrong time_s "
                         f"or a different time scale in the logs?  Without lat_deg, "
                         f"lon_deg, h_m the start is taken from the GNSS fixes")
    return {"distance_m": d, "bound_m": bound, "sigma_m": sigma, "time": tg}


def process(cfg, progress=None, workdir=None, accept_poor=False):
    """Run the whole post-processing described by ``cfg`` (a :class:`ProcessConfig`).

    The IMU log is read block by block (in a reader thread) and streamed through the
    forward filter.  With ``workdir`` (a folder), the forward trajectory and the node
    matrices go to temporary files there, so that memory does not grow with the length
    of the log; the result's trajectories are then read back piece by piece (the folder
    must live as long as the result).  ``progress(done_s, total_s)`` is called as the
    forward pass advances.

    The start is checked against the GNSS fixes and the result assessed
    (:func:`assess_quality`, module notes); the assessment is ``result.quality``.

    Raises
    ------
    InputError
        Bad inputs; a start position far from the first GNSS fix.
    ins.errors.QualityError
        A result not to be trusted (most measurements rejected, the solution departing
        from the fixes, a numerical failure); with ``accept_poor=True`` the assessment's
        failure is a :class:`~ins.errors.QualityWarning` instead (numerical failures
        still raise).
    """
    import warnings
    blocks = prefetch(iter_imu(cfg.imu, format=cfg.imu_format, rates=cfg.imu_rates,
                               axes=cfg.imu_axes))
    filterpy_functions()           # the imports overlap the reader thread's parsing
    gnss = read_gnss(cfg.gnss)
    mount = read_mount(cfg.mount) if cfg.mount else None
    lever = _lever(cfg, mount)
    st = _start(cfg, blocks, gnss, lever)
    state, t0, al, blocks = st.state, st.time, st.alignment, st.blocks
    std = {"pos_std_ned_m": (0.05, 0.05, 0.05), "vel_std_ned_mps": (0.02, 0.02, 0.02),
           "att_std_deg": (0.01, 0.01, 0.1)}
    if al is not None:
        std = {"pos_std_ned_m": al.pos_std_ned_m, "vel_std_ned_mps": al.vel_std_ned_mps,
               "att_std_deg": al.att_std_deg}
    std.update(st.std)
    std.update({k: cfg.initial[k] for k in std if k in cfg.initial})
    start_check = check_start(state, t0, gnss, lever, std, st.position_source)
    if start_check is not None and (start_check["distance_m"]
                                    > START_SIGMAS * start_check["sigma_m"]):
        d = start_check["distance_m"]
        warnings.warn(f"{st.position_source}: the start is {d:.1f} m from the GNSS fix at "
                      f"t = {start_check['time']:.3f} s, more than {START_SIGMAS:g} sigma "
                      f"({START_SIGMAS * start_check['sigma_m']:.2f} m): its position "
                      f"sigma is widened to {d:.1f} m", QualityWarning, stacklevel=2)
        std["pos_std_ned_m"] = np.maximum(np.broadcast_to(
            np.asarray(std["pos_std_ned_m"], float), 3), d)
    settings = FilterSettings(noise=cfg.noise, lever=lever, use_velocity=cfg.use_velocity,
                              reject_probability=cfg.reject_probability,
                              node_interval_s=cfg.node_interval_s, **std)
    start = t0 if t0 is not None else cfg.start_s
    fwd = run_forward(blocks, gnss, state, settings, start=start, end=cfg.end_s,
                      progress=progress, workdir=workdir, initial_time=st.initial_time)
    f_std = np.array(fwd.nodes.post_std)
    if cfg.smooth:
        xs, s_std = rts_errors(fwd, full=False)
        s_sens = fwd.sensors + xs[:, STATE.sensors]
    else:
        xs, s_std, s_sens = None, f_std, fwd.sensors
    counts = {"imu_epochs": len(fwd.trajectory), "gnss_records": len(gnss),
              "nodes": len(fwd.node_time), "updates": fwd.n_updates,
              "rejected": fwd.n_rejected, "outside_imu_span": fwd.n_outside,
              "mount_fallback": fwd.n_mount_fallback}
    result = ProcessResult(fwd, xs, fwd.node_time, f_std, s_std, fwd.sensors.copy(), s_sens,
                           al, counts)
    result.start_check = start_check
    result.quality = assess_quality(result, gnss, lever, cfg)
    q = result.quality
    for msg in q["warnings"]:
        warnings.warn(msg, QualityWarning, stacklevel=2)
    if q["error"] is not None:
        if not accept_poor:
            raise QualityError(q["error"])
        warnings.warn(q["error"] + " (written anyway: accept_poor)", QualityWarning,
                      stacklevel=2)
    if cfg.truth:
        result = with_truth(result, cfg.truth)
    return result


def fix_residuals(result, gnss, lever):
    """Residuals of the written solution (smoothed, else forward) at the GNSS fixes.

    The solution at the node of each fix (the last IMU epoch at or before it) is moved
    along its velocity to the fix time and carried to the antenna through the lever arm.

    Returns
    -------
    index : ndarray of int
        GNSS records within the solution's span.
    residual_m : ndarray, shape (len(index), 3)
        Solution's antenna minus fix, NED, m.
    normalized : ndarray, shape (len(index),)
        RMS over north, east, down of ``residual / std_ned`` of each fix.
    """
    from .rotation import quat_to_dcm
    nt = result.node_time
    index = np.flatnonzero((gnss.time >= nt[0] - 1e-9) & (gnss.time <= nt[-1] + 1e-9))
    if len(index) == 0:
        return index, np.zeros((0, 3)), np.zeros(0)
    j = np.searchsorted(nt, gnss.time[index] + 1e-9, side="right") - 1
    states = result.node_solution()[j]
    tg = gnss.time[index]
    lla = states[:, NAV.lla] + earth.lla_rate(states[:, 0], states[:, 2], states[:, NAV.vel]) * (
        tg - nt[j])[:, None]
    l_b = lever.at(tg)[0]
    arm = np.einsum("nij,nj->ni", quat_to_dcm(states[:, NAV.q_nb]), l_b)
    ant = lla + earth.lla_rate(lla[:, 0], lla[:, 2], arm)
    res = earth.ned_offset(gnss.lla[index], ant)
    norm = np.sqrt(np.mean((res / gnss.std_ned[index]) ** 2, axis=1))
    return index, res, norm


def _runs(mask):
    """``(i0, i1)`` of every run of consecutive True in ``mask`` (i1 exclusive)."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def assess_quality(result, gnss, lever, cfg=None):
    """Whether a result can be trusted (module notes; thresholds at the module top).

    Returns
    -------
    dict
        ``tested``, ``rejected`` (GNSS measurements, positions and velocities),
        ``rejected_fraction``, ``positions_tested``, ``positions_rejected``,
        ``residual_rms_m``, ``residual_max_m`` (written solution against the fixes,
        3-D), ``departure`` (longest stretch of departing fixes: ``from_s``, ``to_s``,
        ``n``, ``max_m``; or None), ``sensor_ratio`` (largest estimated sensor error over
        its stated sigma, per group), ``warnings`` (list of str) and ``error`` (str, or
        None when the result can be trusted).
    """
    fwd = result.fwd
    c = result.counts
    tested = c["updates"] + c["rejected"]
    pos_rejected = fwd.nis > fwd.nis_threshold
    frac = c["rejected"] / tested if tested else 1.0
    index, res, norm = fix_residuals(result, gnss, lever)
    dist = np.linalg.norm(res, axis=1)
    departure = None
    for i0, i1 in _runs(norm > DEPART_SIGMAS):
        span = float(gnss.time[index[i1 - 1]] - gnss.time[index[i0]])
        if departure is None or span > departure["to_s"] - departure["from_s"]:
            departure = {"from_s": float(gnss.time[index[i0]]),
                         "to_s": float(gnss.time[index[i1 - 1]]), "n": int(i1 - i0),
                         "max_m": float(dist[i0:i1].max())}
    sensor_ratio = {}
    if cfg is not None:
        sig = cfg.noise.sensor_std
        est = np.abs(np.asarray(result.smoothed_sensors))
        for name, sl, unit, key in (("gyro bias", slice(0, 3), 180 / np.pi * 3600, "deg/h"),
                                    ("accel bias", slice(3, 6), 1e5, "mGal"),
                                    ("gyro scale", slice(6, 9), 1e6, "ppm"),
                                    ("accel scale", slice(9, 12), 1e6, "ppm")):
            r = est[:, sl] / sig[sl]
            i = np.unravel_index(int(np.argmax(r)), r.shape)
            sensor_ratio[name] = (float(r[i]), float(est[i[0], sl][i[1]] * unit),
                                  float(sig[sl][i[1]] * unit), key, "xyz"[i[1]])
    q = {"tested": tested, "rejected": c["rejected"], "rejected_fraction": frac,
         "positions_tested": len(fwd.nis), "positions_rejected": int(pos_rejected.sum()),
         "residual_rms_m": float(np.sqrt(np.mean(dist ** 2))) if len(dist) else np.nan,
         "residual_max_m": float(dist.max()) if len(dist) else np.nan,
         "departure": departure, "sensor_ratio": sensor_ratio, "warnings": [],
         "error": None}
    counts = (f"{c['rejected']} of {tested} GNSS measurements rejected by the innovation "
              f"test ({100 * frac:.1f} %)")
    problems = []
    if tested == 0:
        problems.append(f"no GNSS record within the processed span ({c['gnss_records']} "
                        f"records, {c['outside_imu_span']} outside it)")
    elif c["updates"] == 0:
        problems.append(f"no GNSS measurement accepted ({counts})")
    elif frac > REJECT_ERROR_FRACTION:
        problems.append(f"{counts}: more than {100 * REJECT_ERROR_FRACTION:g} %")
    elif frac > REJECT_WARN_FRACTION:
        q["warnings"].append(f"{counts}: more than {100 * REJECT_WARN_FRACTION:g} %; "
                             f"{_causes(result, q, cfg)}")
    if departure is not None and departure["to_s"] - departure["from_s"] >= DEPART_SPAN_S:
        problems.append(
            f"the solution is more than {DEPART_SIGMAS:g} fix sigmas from all "
            f"{departure['n']} GNSS fixes from t = {departure['from_s']:.3f} to "
            f"{departure['to_s']:.3f} s ({departure['to_s'] - departure['from_s']:.0f} s, "
            f"up to {departure['max_m']:.3g} m; bound {DEPART_SPAN_S:g} s: the solution "
            f"drifted, or those fixes are wrong)")
    if problems:
        q["error"] = ("untrustworthy solution: " + "; ".join(problems) + ". "
                      + _causes(result, q, cfg))
    return q


def _causes(result, q, cfg):
    """The likely cause of a poor result, most likely first (a sentence)."""
    fwd = result.fwd
    c = result.counts
    causes = []
    if q["tested"] == 0 or c["outside_imu_span"] > 0.5 * c["gnss_records"]:
        causes.append("time base: the GNSS and IMU times do not overlap (check that both "
                      "logs use the same time scale, e.g. GPS seconds of week)")
    early = fwd.nis[:5] > fwd.nis_threshold
    if len(early) and early.all():
        causes.append("start state: the first GNSS fixes are already rejected (check "
                      "[initial] position, velocity, rpy_deg and time_s, the lever arm "
                      "and the time base)")
    noisy = [f"the estimated {name} {est:.3g} {unit} on {axis} is {ratio:.1f} x the stated "
             f"sigma {sig:.3g} {unit}"
             for name, (ratio, est, sig, unit, axis) in q["sensor_ratio"].items()
             if ratio > SENSOR_SIGMAS]
    accepted = fwd.nis[fwd.nis <= fwd.nis_threshold]
    if len(accepted) > 10 and accepted.mean() > NIS_FACTOR * 3.0:
        noisy.append(f"the accepted fixes' mean NIS is {accepted.mean():.1f} (3 expected: "
                     f"the filter is overconfident)")
    if noisy:
        causes.append("IMU noise settings: " + "; ".join(noisy) + " (the IMU is worse "
                      "than [imu_noise] states: give its grade's values)")
    generic = ("start state ([initial] or the alignment), IMU noise settings ([imu_noise]), "
               "lever arm ([gnss] lever_arm_b_m or [mount]) and time base (same time scale "
               "in both logs)")
    if not causes:
        return f"Likely cause: one of {generic}."
    return "Likely cause: " + "; ".join(causes) + f". Also check: {generic}."


def with_truth(result, truth_path):
    """``result`` with its errors against a truth ``.nav`` file (piece by piece)."""
    from .accuracy import TrajectoryErrors, compare
    from .trajectory import read_nav
    truth = read_nav(truth_path)

    def errors(pieces):
        parts = []
        for piece in pieces:
            lo, hi = np.searchsorted(truth.time, [piece.time[0] - 1e-6, piece.time[-1] + 1e-6])
            if hi > lo:
                ref = Trajectory(truth.time[lo:hi], truth.lla[lo:hi], truth.v_n[lo:hi],
                                 truth.q_nb[lo:hi])
                try:
                    parts.append(compare(piece, ref))
                except ValueError:
                    continue
        if not parts:
            raise InputError(f"{truth_path}: the trajectories share no epoch (times must "
                             f"match within 1 us)")
        return TrajectoryErrors(*(np.concatenate([getattr(p, f) for p in parts])
                                  for f in ("time", "pos_n", "vel_n", "att_n")))
    return replace(result, errors_forward=errors(result.iter_forward()),
                   errors_smoothed=errors(result.iter_smoothed()))


def _trajectory(time, states):
    return Trajectory(time=time, lla=states[:, NAV.lla], v_n=states[:, NAV.vel],
                      q_nb=states[:, NAV.q_nb])
