"""GNSS/INS post-processing pipeline: configuration or flight manifest -> files -> forward
filter -> RTS smoother -> results (and the output files).

The configuration (TOML keys, the flight manifest) is read by :mod:`ins.estimation.pipeline.config`;
the output files are written by :mod:`ins.estimation.pipeline.outputs`.
Library code: nothing is printed; progress goes to ``progress(done, total)``.

The trust checks (the start position against the first GNSS fix; the assessment after the
run) are in :mod:`ins.estimation.pipeline.trust`.
"""
import itertools
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ins.common.errors import InputError, QualityError, QualityWarning
from ins.estimation.core import _filter_kernels
from ins.estimation.pipeline import identify as process_identify
from ins.estimation.alignment.initial import (
    align_gnss_heading,
    align_static,
    check_static_heading,
    gnss_heading_epoch,
)
from ins.estimation.core.error_model import NAV, STATE
from ins.estimation.core.filter import run_forward
from ins.estimation.core.filter_settings import FilterSettings
from ins.estimation.core.filter_stores import as_array, read_rows
from ins.estimation.core.lever_arm import LeverArm
from ins.estimation.pipeline.config import POSITION_KEYS, filter_options
from ins.estimation.pipeline.trust import (START_FIX_WINDOW_S, START_SIGMAS, assess_quality,
                                           check_start, first_fix_at, fix_name, start_report)
from ins.estimation.core.smoother import iter_smoothed, rts_errors
from ins.io.gnss import read_gnss
from ins.io.imu_blocks import iter_imu, prefetch, with_location
from ins.io.imu_files import shifted_blocks
from ins.io.mount import read_mount
from ins.nav import earth
from ins.nav.imu import ImuLog
from ins.nav.mechanization import NavState
from ins.nav.trajectory import Trajectory


@dataclass
class ProcessResult:
    """Results of :func:`process` (SI units).

    The trajectories at every IMU epoch are streamed: :meth:`iter_forward` and
    :meth:`iter_smoothed` yield :class:`~ins.nav.trajectory.Trajectory` pieces in time order
    (from the forward pass's store, in memory or a temporary file); :attr:`forward` and
    :attr:`smoothed` give them whole (in memory).  ``node_time`` holds the filter nodes
    with ``forward_std``/``smoothed_std`` (m, 21), ``forward_att_cross``/
    ``smoothed_att_cross`` (m, 3: the attitude cross covariances, rad^2,
    :data:`ins.estimation.core.error_model.ATT_CROSS`) and ``forward_sensors``/
    ``smoothed_sensors`` (m, 12: gyro bias rad/s, accel bias m/s^2, scales), arrays
    read whole when asked for (from temporary files with a work folder);
    :meth:`node_chunks` gives them block by block (bounded memory);
    ``errors_forward``/``errors_smoothed`` (:class:`ins.nav.accuracy.TrajectoryErrors`) when
    a truth file was given; ``quality`` the assessment of :func:`assess_quality` and
    ``start_check`` that of :func:`check_start` (when the run made them); ``gnss`` the
    GNSS log the filter took (times, sigmas and quality flags: the report).
    """

    fwd: object
    xs: object                # smoothed errors (m, n): array or filter_stores.Table; or None
    s_std: object             # smoothed sigmas (m, n): array or Table; or None
    alignment: object
    counts: dict
    errors_forward: object = None
    errors_smoothed: object = None
    quality: dict = None
    start_check: dict = None
    start_how: str = None
    gnss_source: dict = None
    identified: object = None     # ins.estimation.tools.noise_identification.Identified or None
    gnss: object = None           # the GNSS log the filter took (ins.io.gnss_log.GnssLog)
    s_att: object = None          # smoothed attitude cross covariances (m, 3): array or Table

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

    node_time = property(lambda self: self.fwd.node_time)
    forward_std = property(lambda self: self.fwd.nodes.post_std)
    forward_sensors = property(lambda self: self.fwd.sensors)

    @property
    def smoothed_std(self):
        return self.forward_std if self.s_std is None else as_array(self.s_std)

    @property
    def smoothed_sensors(self):
        if self.xs is None:
            return self.forward_sensors
        return self.fwd.sensors + as_array(self.xs)[:, self.fwd.layout.sensors]

    def node_chunks(self, size=1 << 13):
        """The per-node results block by block (bounded memory): namespaces with ``j0``
        (first node), ``time``, ``forward_std``, ``smoothed_std``, ``forward_att_cross``,
        ``smoothed_att_cross`` (the forward ones without a smoother; ``None`` for a result
        smoothed without them), ``forward_sensors``, ``smoothed_sensors`` and
        ``solution`` (:meth:`node_solution`) of the block."""
        from types import SimpleNamespace
        fwd = self.fwd
        for j0 in range(0, fwd.node_count, size):
            j1 = min(j0 + size, fwd.node_count)
            f_std = read_rows(fwd.nodes.post_std_rows, j0, j1)
            f_att = read_rows(fwd.nodes.post_att_cross_rows, j0, j1)
            f_sens = fwd.node_rows_of("sensors", j0, j1)
            states = fwd.node_rows_of("node_states", j0, j1)
            if self.xs is None:
                s_std, s_att, s_sens = f_std, f_att, f_sens
            else:
                xs = read_rows(self.xs, j0, j1)
                s_std = read_rows(self.s_std, j0, j1)
                s_att = None if self.s_att is None else read_rows(self.s_att, j0, j1)
                s_sens = f_sens + xs[:, fwd.layout.sensors]
                for j in range(len(states)):
                    _filter_kernels.correct_state(states[j], xs[j, STATE.nav])
            yield SimpleNamespace(j0=j0, time=fwd.node_rows_of("node_time", j0, j1),
                                  forward_std=f_std, smoothed_std=s_std,
                                  forward_att_cross=f_att, smoothed_att_cross=s_att,
                                  forward_sensors=f_sens, smoothed_sensors=s_sens,
                                  solution=states)

    def node_solution(self):
        """The written solution (smoothed, else forward) at the nodes (after their
        updates), shape (m, 10) in the ``ins.nav._kernels`` layout."""
        parts = [c.solution for c in self.node_chunks()]
        return np.concatenate(parts) if parts else np.empty((0, 10))

    def node_attitude(self):
        """Smoothed attitude quaternions at the nodes, shape (m, 4)."""
        return self.node_solution()[:, NAV.q_nb]


def _initial(cfg, imu, gnss):
    """Initial state, its time and the alignment (``None`` for a given state) for a
    whole :class:`~ins.nav.imu.ImuLog`."""
    st = _start(cfg, [imu], gnss)
    return st.state, st.time, st.alignment


@dataclass
class _Start:
    """The start of a run: state, its time, the alignment (or None), the IMU blocks to
    process, ``initial_time`` for :func:`ins.estimation.core.filter.run_forward` (the state's exact time
    when it is not an IMU epoch), sigmas implied by a position taken from GNSS, and the
    name of what gave the position (for messages)."""

    state: NavState
    time: float
    alignment: object
    blocks: object
    initial_time: float = None
    std: dict = field(default_factory=dict)
    position_source: str = None
    gyro_bias_b: np.ndarray = None
    how: str = None
    noise: object = None          # IMU noise settings found at the start (none given)
    rest_noise: object = None     # the noise measured over a rest at the start, if any
    heading_from: str = None      # "gyrocompass": a log that never moves (else None)
    skipped: tuple = None         # IMU span (s) before the start, skipped: no GNSS there
    heading_floor_deg: float = None   # gyrocompass: the heading sigma the rest allows
    rest_windows: tuple = ()      # known rests (s): zero-velocity updates there


def _lever(cfg, mount=None):
    return LeverArm(cfg.lever_bp, cfg.lever_ap, mount)


def _config_position(cfg):
    """Name of the config keys that gave the start position (for messages)."""
    keys = "[initial] lat_deg, lon_deg, h_m"
    return f"{cfg.initial_source}: {keys}" if cfg.initial_source else keys


def _less_lever_arm(lla_ant, q_nb, lever, t):
    """IMU position (lat, lon rad, h m) of an antenna position, through the arm at ``t``."""
    from ins.nav.rotation import quat_to_dcm
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
    method = _method(cfg)
    if method == "anywhere":
        return _anywhere(cfg, gnss, lever, blocks)
    if method == "given":
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
        k = first_fix_at(gnss, t0)
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
        std = {"pos_std_ned_m": np.hypot(np.hypot(gnss.sigma_ned_m[k], 0.01), vel_std * dt)}
        return _Start(NavState(lla, v_n, q), t0, None, blocks, initial_time=t0, std=std,
                      position_source=f"the start position from {fix_name(gnss, k)}")
    if method == "static":
        if cfg.static_window_s is None:
            raise InputError("[alignment] static_window_s: needed with method 'static'")
        t_a, t_b = cfg.static_window_s
        lla_w, k = _window_lla(cfg, gnss, t_a, t_b)
        moves = gnss_heading_epoch(gnss, t_b) is not None
        if not check_static_heading(cfg.noise, float(lla_w[0]), t_b - t_a, gnss,
                                    fallback="gnss-heading" if moves else "anywhere"):
            if moves:
                return _in_air(cfg, gnss, t_b, lever, blocks)
            return _anywhere(cfg, gnss, lever, blocks, t_a)     # slow, or never moves
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
                      position_source=f"the static alignment's position ({fix_name(gnss, k)})")
    t_start = cfg.start_s
    if t_start is None and cfg.static_window_s is not None:
        t_start = cfg.static_window_s[0]
    return _in_air(cfg, gnss, t_start, lever, blocks)


def _method(cfg):
    """The alignment method of ``cfg``, ``"auto"`` resolved (module notes of
    :mod:`ins.estimation.pipeline.config`)."""
    if cfg.method != "auto":
        return cfg.method
    if "rpy_deg" in cfg.initial and "vel_ned_mps" in cfg.initial:
        return "given"
    return "static" if cfg.static_window_s is not None else "anywhere"


def _anywhere(cfg, gnss, lever, blocks, t_start=None):
    """Start from the IMU and the GNSS alone (:func:`align_anywhere`): the IMU blocks up
    to the end of the matching window are read ahead and given back.  An IMU log that
    starts long before the first GNSS fix starts at the fix, or at the IMU's rest before
    it (:func:`~ins.estimation.alignment.motion.rest_before_fix`); the IMU before is
    skipped (``_Start.skipped``)."""
    from ins.estimation.alignment.motion import (
        FIX_DELAY_S,
        MAX_PRE_FIX_REST_S,
        MAX_WINDOW_S,
        align_anywhere,
        rest_before_fix,
    )
    from ins.estimation.pipeline.presets import noise_from_rest
    first, blocks = _peek(blocks)
    if t_start is None:
        t_start = cfg.start_s if cfg.start_s is not None else float(first.time[0])
    k_fix = first_fix_at(gnss, t_start)
    late = k_fix is not None and gnss.time[k_fix] - t_start > FIX_DELAY_S
    t_ref = float(gnss.time[k_fix]) if late else t_start
    head, rest, t_log = [], iter(blocks), float(first.time[0])
    for b in rest:                                # enough IMU for any matching window
        if late and b.time[-1] < t_ref - MAX_PRE_FIX_REST_S:
            head = [b]                            # long before the fix: not kept
            continue
        head.append(b)
        if b.time[-1] >= t_ref + MAX_WINDOW_S + 1.0 + _rest_length(gnss, t_ref):
            break
    imu = ImuLog.adopt(*(np.concatenate([getattr(b, k_) for b in head])
                         for k_ in ("time", "dtheta_b", "dvel_b")))
    skipped, delay, rest_windows = None, FIX_DELAY_S, ()
    t_origin = max(t_log, t_start)
    if late and imu.time[-1] < t_ref:
        raise InputError(f"{cfg.imu}: the IMU log ends at {float(imu.time[-1]):.3f} s, before "
                         f"the first GNSS fix ({fix_name(gnss, k_fix)}): nothing to process "
                         f"(check the time scales of the two logs)")
    if late:
        t_rest = rest_before_fix(imu, gnss, k_fix, cfg.noise)
        t_run = t_ref if t_rest is None else max(t_rest, t_start)
        if t_run < t_ref:                 # no GNSS there: the filter is told it is at rest
            rest_windows = ((t_run, t_ref),)
        skipped = (t_origin, t_run)
        delay += t_ref - t_run
        t_start = t_run
    ms = align_anywhere(imu, gnss, t_start, cfg.noise, fix_delay_s=delay)
    al = ms.alignment
    noise, how, rest_noise = None, ms.how, None
    if (cfg.noise_source is not None and ms.gyro_bias_b is not None
            and process_identify.wanted(cfg)):     # a starting point beside the preset
        rest_noise = noise_from_rest(imu, al.time, al.time + ms.rest_s, ms.gyro_bias_b)[0]
    if skipped is not None:
        skipped = (skipped[0], al.time) if al.time - skipped[0] > 1e-6 else None
        text = (f"the IMU log starts {t_ref - t_origin:.1f} s before the first GNSS fix "
                f"({fix_name(gnss, k_fix)}): the run starts ")
        if t_start >= t_ref:
            text += "at the fix (the IMU is not at rest before it)"
        else:
            text += (f"with the IMU's rest {t_ref - al.time:.1f} s before it (zero-velocity "
                     f"updates over it)")
        if skipped is not None:
            text += (f"; the IMU span {skipped[0]:.3f} .. {skipped[1]:.3f} s "
                     f"({skipped[1] - skipped[0]:.1f} s) is skipped")
        how = text + "; " + how
    if cfg.noise_source is None and ms.gyro_bias_b is not None:
        noise, text = noise_from_rest(imu, al.time, al.time + ms.rest_s, ms.gyro_bias_b)
        how += "; " + text
        from ins.estimation.core.error_model import MGAL  # the level sigma of that grade
        tilt = np.rad2deg(float(np.max(noise.accel_bias_std_mgal)) * MGAL
                          / float(earth.normal_gravity(al.state.lla[0], al.state.lla[2])))
        al = replace(al, att_std_deg=np.array([tilt, tilt, al.att_std_deg[2]]))
    lla = _less_lever_arm(al.state.lla, al.state.q_nb, lever, al.time)
    al = replace(al, state=NavState(lla, al.state.v_n, al.state.q_nb))
    return _Start(al.state, al.time, al, itertools.chain(head, rest), initial_time=al.time,
                  position_source="the start position from the GNSS (anywhere alignment)",
                  gyro_bias_b=ms.gyro_bias_b, how=how, noise=noise,
                  rest_noise=noise if rest_noise is None else rest_noise,
                  heading_from=ms.heading_from, skipped=skipped,
                  heading_floor_deg=ms.heading_floor_deg, rest_windows=rest_windows)


def _rest_length(gnss, t_start):
    """Length of the rest at ``t_start`` seen by the GNSS, s (0 when moving; for a log
    that never moves, what a gyrocompass start reads: at most ``MAX_STATIC_S``)."""
    from ins.estimation.alignment.motion import MAX_STATIC_S, REST_SPEED_MPS, gnss_velocities
    v = gnss_velocities(gnss)
    k0 = int(np.searchsorted(gnss.time, t_start - 1e-9))
    moving = np.flatnonzero(np.hypot(v[k0:, 0], v[k0:, 1]) >= REST_SPEED_MPS)
    if not len(moving):
        return MAX_STATIC_S if k0 < len(gnss) else 0.0
    return float(gnss.time[k0 + moving[0]] - t_start)


def _in_air(cfg, gnss, t_start, lever, blocks):
    al = align_gnss_heading(gnss, t_start, stabilized=cfg.mount is not None)
    lla = _less_lever_arm(al.state.lla, al.state.q_nb, lever, al.time)
    al = replace(al, state=NavState(lla, al.state.v_n, al.state.q_nb))
    return _Start(al.state, al.time, al, blocks, initial_time=al.time,
                  position_source="the in-air alignment's position (GNSS)")


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


def process(cfg, progress=None, workdir=None, accept_poor=False, gnss_dir=None):
    """Run the whole post-processing described by ``cfg`` (a :class:`ProcessConfig`).

    The IMU log is read block by block (in a reader thread) and streamed through the
    forward filter.  With ``workdir`` (a folder), the forward trajectory and the node
    matrices go to temporary files there, so that memory does not grow with the length
    of the log; the result's trajectories are then read back piece by piece (the folder
    must live as long as the result).  ``progress(done_s, total_s)`` is called as the
    forward pass advances.

    The start is checked against the GNSS fixes and the result assessed
    (:func:`assess_quality`, module notes); the assessment is ``result.quality``.

    With raw GNSS (``cfg.gnss_raw``), RTKLIB runs first (:mod:`ins.estimation.pipeline.gnss_source`)
    and writes ``gnss.pos`` (and the forward/backward separation) into ``gnss_dir``
    (default ``workdir``, else a temporary folder); ``result.gnss_source`` says what
    it did.

    Raises
    ------
    InputError
        Bad inputs; a start position far from the first GNSS fix.
    ins.common.errors.QualityError
        A result not to be trusted (most measurements rejected, the solution departing
        from the fixes, a numerical failure); with ``accept_poor=True`` the assessment's
        failure is a :class:`~ins.common.errors.QualityWarning` instead (numerical failures
        still raise).
    """
    import warnings
    gnss, gnss_source = _gnss(cfg, gnss_dir if gnss_dir is not None else workdir)
    mount = read_mount(cfg.mount) if cfg.mount else None
    lever = _lever(cfg, mount)
    st, start_check, settings, start = _prepare(cfg, gnss, lever)
    ident = None
    if process_identify.wanted(cfg):
        ident, blocks, gnss = process_identify.run_identification(
            cfg, st.blocks, gnss, st.state, settings, start, st.initial_time, st.rest_noise,
            progress)
        if ident.time_offset_s:           # the IMU onto the GNSS's clock, and a new start
            from copy import copy
            cfg = copy(cfg)
            cfg.imu_time_shift_s = -ident.time_offset_s
            st, start_check, settings, start = _prepare(cfg, gnss, lever)
            blocks = st.blocks
        settings = replace(settings, noise=ident.noise, nhc=settings.nhc or ident.nhc)
        st = replace(st, blocks=blocks)
    state, t0, al, blocks = st.state, st.time, st.alignment, st.blocks
    gnss_in = gnss
    if cfg.coupling == "tight":
        from ins.estimation.pipeline.tight import tight_inputs
        gnss_in, settings = tight_inputs(cfg, gnss, settings)
        if getattr(cfg, "range_noise", "auto") == "auto":      # a first pass: the noise
            from ins.estimation.pipeline.tight import fitted_noise
            settings = fitted_noise(cfg, gnss_in, settings, lambda s: run_forward(
                _imu_blocks(cfg), gnss_in, state, s, start=start, end=cfg.end_s,
                initial_time=st.initial_time))
    try:
        fwd = run_forward(blocks, gnss_in, state, settings, start=start, end=cfg.end_s,
                          progress=progress, workdir=workdir, initial_time=st.initial_time)
    except InputError as exc:
        if getattr(exc, "time_s", None) is None:
            raise
        raise with_location(exc, cfg.imu, cfg.imu_format, cfg.imu_time_shift_s) from None
    if cfg.smooth:
        xs, s_std, s_att = rts_errors(fwd, full=False, workdir=workdir, att_cross=True)
    else:
        xs, s_std, s_att = None, None, None
    counts = {"imu_epochs": len(fwd.trajectory), "gnss_records": len(gnss),
              "nodes": fwd.node_count, "updates": fwd.n_updates,
              "rejected": fwd.n_rejected, "outside_imu_span": fwd.n_outside,
              "mount_fallback": fwd.n_mount_fallback, "recoveries": len(fwd.recoveries),
              "reanchors": len(fwd.reanchors), "gnss_steps": fwd.n_gnss_steps}
    from ins.estimation.pipeline.tight import tight_counts
    counts.update(tight_counts(fwd))
    if cfg.coupling == "tight":
        from ins.estimation.pipeline.tight import noise_summary
        counts["range_noise"] = noise_summary(cfg, fwd.updater)
    result = ProcessResult(fwd, xs, s_std, al, counts, s_att=s_att)
    result.start_check = start_check
    result.start_how = st.how
    result.gnss_source = gnss_source
    result.identified = ident
    result.gnss = gnss
    if st.noise is not None or ident is not None:   # judged against the settings it ran with
        from copy import copy
        cfg = copy(cfg)
        cfg.noise = settings.noise
    result.quality = assess_quality(result, gnss, lever, cfg)
    q = result.quality
    q["start"] = start_report(result, st.heading_from, st.skipped, st.heading_floor_deg)
    for msg in q["warnings"]:
        warnings.warn(msg, QualityWarning, stacklevel=2)
    if q["error"] is not None:
        if not accept_poor:
            raise QualityError(q["error"])
        warnings.warn(q["error"] + " (written anyway: accept_poor)", QualityWarning,
                      stacklevel=2)
    if cfg.truth:
        from ins.estimation.pipeline.truth import with_truth
        result = with_truth(result, cfg.truth)
    return result


def _imu_blocks(cfg):
    """The IMU blocks of ``cfg``, read lazily and shifted by ``[imu] time_shift_s``."""
    return prefetch(shifted_blocks(iter_imu(cfg.imu, format=cfg.imu_format,
                                            rates=cfg.imu_rates, axes=cfg.imu_axes),
                                   cfg.imu_time_shift_s))


def _prepare(cfg, gnss, lever):
    """The IMU blocks (read lazily, shifted by ``[imu] time_shift_s``), the start, its
    check against the GNSS, the filter settings and the start time of a run."""
    import warnings
    blocks = _imu_blocks(cfg)
    st = _start(cfg, blocks, gnss, lever)
    state, t0, al = st.state, st.time, st.alignment
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
                      f"sigma is widened to {d:.1f} m", QualityWarning, stacklevel=3)
        std["pos_std_ned_m"] = np.maximum(np.broadcast_to(
            np.asarray(std["pos_std_ned_m"], float), 3), d)
    start = t0 if t0 is not None else cfg.start_s
    sensors0 = None if st.gyro_bias_b is None else np.concatenate([st.gyro_bias_b,
                                                                    np.zeros(9)])
    options = filter_options(cfg)
    if st.rest_windows:                   # the rest before the first fix: known at rest
        options["zupt_windows_s"] = tuple(options.get("zupt_windows_s", ())) + st.rest_windows
    if st.heading_from == "gyrocompass":  # a log that never moves: unless the user said no,
        options.setdefault("zupt", True)  # zero-velocity updates where the IMU is at rest
    settings = FilterSettings(noise=cfg.noise if st.noise is None else st.noise, lever=lever,
                              use_velocity=cfg.use_velocity,
                              reject_probability=cfg.reject_probability,
                              node_interval_s=cfg.node_interval_s, **std,
                              initial_sensors=sensors0, recover=cfg.recover,
                              heading=_headings(cfg, start), **options)
    return st, start_check, settings, start


def _gnss(cfg, folder):
    """The GNSS log of the run and, with raw observations, what RTKLIB did (else None)."""
    if cfg.gnss_raw is None:
        return read_gnss(cfg.gnss, format=cfg.gnss_format, time_shift_s=cfg.gnss_time_shift_s,
                         quality=cfg.gnss_quality, quality_scale=cfg.gnss_quality_scale,
                         velocity_time_shift_s=cfg.gnss_velocity_time_shift_s,
                         geoid=cfg.gnss_geoid), None
    from ins.estimation.pipeline.gnss_source import run_raw_gnss
    if folder is not None:
        return run_raw_gnss(cfg, folder)
    import tempfile
    with tempfile.TemporaryDirectory(prefix="ins-gnss-") as tmp:
        return run_raw_gnss(cfg, tmp)


def _headings(cfg, start):
    """The dual-antenna headings of ``[files] heading`` inside the processed span (on
    the GNSS clock: ``[gnss] time_shift_s`` applies), or ()."""
    if not cfg.heading:
        return ()
    from ins.estimation.pipeline.heading_files import read_headings, within
    return within(read_headings(cfg.heading, cfg.heading_baseline_b_m, cfg.heading_sigma_deg,
                                cfg.gnss_time_shift_s), start, cfg.end_s)


def _trajectory(time, states):
    return Trajectory(time=time, lla=states[:, NAV.lla], v_n=states[:, NAV.vel],
                      q_nb=states[:, NAV.q_nb])
