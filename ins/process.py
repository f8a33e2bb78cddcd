"""GNSS/INS post-processing pipeline: configuration or flight manifest -> files -> forward
filter -> RTS smoother -> results (and the output files).

Configuration (TOML; ``data/configs/kfgins_like.toml``), keys named like KF-GINS's YAML
with the unit in the name::

    [files]      imu, gnss, mount (optional), truth (optional): paths relative to the file
    [imu]        format = "kfgins"|"kfgins-bin"|"csv", rates = false, axes = "FRD"
    [initial]    lat_deg, lon_deg, h_m, vel_ned_mps, rpy_deg, time_s (optional),
                 pos_std_ned_m, vel_std_ned_mps, att_std_deg
    [imu_noise]  arw_deg_sqrth, vrw_mps_sqrth, gyro_bias_std_dph, accel_bias_std_mgal,
                 gyro_scale_std_ppm, accel_scale_std_ppm, corr_time_h
    [gnss]       lever_arm_b_m, use_velocity = true, reject_probability = 1e-5
    [mount]      imu_to_platform_centre_b_m, platform_centre_to_antenna_a_m
    [alignment]  method = "given"|"static"|"gnss-heading", static_window_s = [t0, t1]
    [filter]     start_s, end_s, node_interval_s = 1.0, smooth = true

With a mount, ``[mount]`` replaces ``[gnss] lever_arm_b_m``.  A flight folder's
``manifest.toml`` (``docs/interfaces.md``) gives the files, lever arms, IMU error values
and the stationary segment; the manifest's true initial state is NOT used (it would be
cheating): the alignment is static when there is a stationary segment, else in-air.
Library code: nothing is printed; progress goes to ``progress(done, total)``.
"""
import itertools
import os
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from . import _filter_kernels
from .alignment import align_gnss_heading, align_static, check_static_heading
from .error_model import ImuNoise
from .errors import InputError
from .filter import FilterSettings, filterpy_functions, run_forward
from .imu import ImuLog
from .imu_blocks import iter_imu, prefetch
from .gnss import read_gnss
from .lever_arm import LeverArm
from .mechanization import NavState
from .mount import read_mount
from .smoother import iter_smoothed, rts_errors
from .trajectory import Trajectory

_NOISE_KEYS = ("arw_deg_sqrth", "vrw_mps_sqrth", "gyro_bias_std_dph", "accel_bias_std_mgal",
               "gyro_scale_std_ppm", "accel_scale_std_ppm", "corr_time_h")
_SECTIONS = {
    "files": {"imu", "gnss", "mount", "truth"},
    "imu": {"format", "rates", "axes"},
    "initial": {"lat_deg", "lon_deg", "h_m", "vel_ned_mps", "rpy_deg", "time_s",
                "pos_std_ned_m", "vel_std_ned_mps", "att_std_deg"},
    "imu_noise": set(_NOISE_KEYS),
    "gnss": {"lever_arm_b_m", "use_velocity", "reject_probability"},
    "mount": {"imu_to_platform_centre_b_m", "platform_centre_to_antenna_a_m"},
    "alignment": {"method", "static_window_s"},
    "filter": {"start_s", "end_s", "node_interval_s", "smooth"},
}
METHODS = ("given", "static", "gnss-heading")


@dataclass
class ProcessConfig:
    """Everything a run needs (paths and settings); see the module notes for the keys."""

    imu: str
    gnss: str
    mount: str = None
    truth: str = None
    imu_format: str = None
    imu_rates: bool = False
    imu_axes: str = "FRD"
    noise: ImuNoise = field(default_factory=ImuNoise)
    lever_bp: np.ndarray = field(default_factory=lambda: np.zeros(3))
    lever_ap: np.ndarray = field(default_factory=lambda: np.zeros(3))
    initial: dict = field(default_factory=dict)
    method: str = "given"
    static_window_s: tuple = None
    start_s: float = None
    end_s: float = None
    node_interval_s: float = 1.0
    use_velocity: bool = True
    reject_probability: float = 1e-5
    smooth: bool = True
    source: str = "config"


def _vector(value, where, n=3):
    try:
        v = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{where}: expected {n} numbers, got {value!r}") from None
    if v.ndim == 0:
        v = np.full(n, float(v))
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise InputError(f"{where}: expected {n} finite numbers, got {value!r}")
    return v


def _number(value, where, positive=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise InputError(f"{where}: expected a number, got {value!r}")
    if positive and value <= 0:
        raise InputError(f"{where}: expected a number > 0, got {value!r}")
    return float(value)


def _read_toml(path, expected="a processing config (TOML)"):
    from ._textio import read_toml
    return read_toml(path, expected)


def _noise(section, where):
    kw = {}
    for key in _NOISE_KEYS:
        if key in section:
            kw[key] = (_number(section[key], f"{where} {key}", positive=True)
                       if key == "corr_time_h" else _vector(section[key], f"{where} {key}"))
            if key != "corr_time_h" and np.any(kw[key] < 0):
                raise InputError(f"{where} {key}: expected values >= 0, got {section[key]!r}")
    return ImuNoise(**kw)


def load_config(path, base=None, files=None):
    """Read a processing config (TOML).  Paths in ``[files]`` are relative to the file;
    ``files`` (e.g. ``{"imu": ..., "gnss": ...}`` from the command line) replaces them.

    Raises
    ------
    InputError
        Naming the file and the ``[section] key`` on an unknown key or a bad value.
    """
    path = os.fspath(path)
    data = _read_toml(path)
    where = lambda sec, key="": f"{path}: [{sec}]" + (f" {key}" if key else "")  # noqa: E731
    for sec, value in data.items():
        if sec not in _SECTIONS or not isinstance(value, dict):
            raise InputError(f"{path}: unknown section [{sec}] (known: "
                             f"{', '.join(_SECTIONS)})")
        unknown = set(value) - _SECTIONS[sec]
        if unknown:
            raise InputError(f"{where(sec)}: unknown key(s) {', '.join(sorted(unknown))} "
                             f"(known: {', '.join(sorted(_SECTIONS[sec]))})")
    base = os.path.dirname(os.path.abspath(path)) if base is None else base
    rel = {k: os.path.join(base, v) for k, v in data.get("files", {}).items()}
    rel.update({k: v for k, v in (files or {}).items() if v is not None})
    for key in ("imu", "gnss"):
        if key not in rel:
            raise InputError(f"{where('files', key)}: missing (path of the {key} log; "
                             f"or give --{key})")
    return _fill(ProcessConfig(imu=rel["imu"], gnss=rel["gnss"], mount=rel.get("mount"),
                               truth=rel.get("truth")), data, where)


def _fill(cfg, data, where):
    """Settings of a parsed TOML table into ``cfg`` (shared by config and overrides)."""
    imu = data.get("imu", {})
    cfg.imu_format = imu.get("format", cfg.imu_format)
    cfg.imu_rates = bool(imu.get("rates", cfg.imu_rates))
    cfg.imu_axes = imu.get("axes", cfg.imu_axes)
    if "imu_noise" in data:
        cfg.noise = _noise(data["imu_noise"], where("imu_noise"))
    gnss = data.get("gnss", {})
    if "lever_arm_b_m" in gnss:
        cfg.lever_bp = _vector(gnss["lever_arm_b_m"], where("gnss", "lever_arm_b_m"))
        cfg.lever_ap = np.zeros(3)
    cfg.use_velocity = bool(gnss.get("use_velocity", cfg.use_velocity))
    if "reject_probability" in gnss:
        p = _number(gnss["reject_probability"], where("gnss", "reject_probability"), True)
        if p >= 1:
            raise InputError(f"{where('gnss', 'reject_probability')}: expected 0 < p < 1")
        cfg.reject_probability = p
    mount = data.get("mount", {})
    for key, attr in (("imu_to_platform_centre_b_m", "lever_bp"),
                      ("platform_centre_to_antenna_a_m", "lever_ap")):
        if key in mount:
            setattr(cfg, attr, _vector(mount[key], where("mount", key)))
    init = data.get("initial", {})
    for key, value in init.items():
        n = 3 if key not in ("lat_deg", "lon_deg", "h_m", "time_s") else None
        cfg.initial[key] = (_vector(value, where("initial", key)) if n
                            else _number(value, where("initial", key)))
    align = data.get("alignment", {})
    if "method" in align:
        if align["method"] not in METHODS:
            raise InputError(f"{where('alignment', 'method')}: expected one of "
                             f"{', '.join(METHODS)}, got {align['method']!r}")
        cfg.method = align["method"]
    if "static_window_s" in align:
        cfg.static_window_s = tuple(_vector(align["static_window_s"],
                                            where("alignment", "static_window_s"), 2))
    filt = data.get("filter", {})
    for key in ("start_s", "end_s"):
        if key in filt:
            setattr(cfg, key, _number(filt[key], where("filter", key)))
    if "node_interval_s" in filt:
        cfg.node_interval_s = _number(filt["node_interval_s"], where("filter", "node_interval_s"),
                                      True)
    cfg.smooth = bool(filt.get("smooth", cfg.smooth))
    return cfg


def config_from_manifest(flight_dir, overrides=None):
    """Processing config of a simulator flight folder (``manifest.toml``).

    ``overrides`` (a config TOML path) may replace any setting.
    """
    path = os.path.join(flight_dir, "manifest.toml")
    if not os.path.isfile(path):
        raise InputError(f"{flight_dir}: no manifest.toml (a flight folder of "
                         f"'ins simulate' is expected)")
    man = _read_toml(path)
    where = lambda sec, key="": f"{path}: [{sec}]" + (f" {key}" if key else "")  # noqa: E731
    files = man.get("files", {})
    for key in ("imu", "gnss"):
        if key not in files:
            raise InputError(f"{where('files', key)}: missing")

    def rel(key):
        return os.path.join(flight_dir, files[key]) if files.get(key) else None
    mount = rel("mount")
    cfg = ProcessConfig(imu=rel("imu"), gnss=rel("gnss"),
                        mount=mount if mount and os.path.isfile(mount) else None,
                        truth=rel("truth"), source="manifest")
    arm = man.get("lever_arm", {})
    cfg.lever_bp = _vector(arm.get("imu_to_platform_centre_b_m", [0, 0, 0]),
                           where("lever_arm", "imu_to_platform_centre_b_m"))
    cfg.lever_ap = _vector(arm.get("platform_centre_to_antenna_a_m", [0, 0, 0]),
                           where("lever_arm", "platform_centre_to_antenna_a_m"))
    cfg.noise = _manifest_noise(man.get("imu", {}), where("imu"))
    stationary = man.get("stationary", {})
    segments = stationary.get("segments_s", stationary.get("segments")) \
        if isinstance(stationary, dict) else stationary
    at_rest = bool(stationary.get("static", True)) if isinstance(stationary, dict) else True
    if isinstance(segments, list) and segments and len(segments[0]) == 2:
        cfg.static_window_s = (float(segments[0][0]), float(segments[0][1]))
    # at rest: levelling + gyrocompassing on the segment; in the air (static = false, the
    # segment is a straight level line): heading from the GNSS track at its start
    cfg.method = "static" if at_rest and cfg.static_window_s is not None else "gnss-heading"
    if overrides is not None:
        data = _read_toml(overrides)
        _fill(cfg, data, lambda sec, key="": f"{overrides}: [{sec}]" + (f" {key}" if key else ""))
    return cfg


def _manifest_noise(imu, where):
    """Filter noise from the injected error values of the manifest (same units)."""
    def get(key, default):
        v = imu.get(key, default)
        return np.abs(_vector(v, f"{where} {key}"))
    bias_g = np.hypot(get("gyro_bias_dph", 0.0), get("gyro_bias_instability_dph", 0.0))
    bias_a = np.hypot(get("accel_bias_mgal", 0.0), get("accel_bias_instability_mgal", 0.0))
    return ImuNoise(
        arw_deg_sqrth=np.maximum(get("arw_deg_sqrth", 0.003), 1e-6),
        vrw_mps_sqrth=np.maximum(get("vrw_mps_sqrth", 0.03), 1e-6),
        gyro_bias_std_dph=np.maximum(bias_g, 1e-4),
        accel_bias_std_mgal=np.maximum(bias_a, 1.0),
        gyro_scale_std_ppm=np.maximum(get("gyro_scale_ppm", 1.0), 1.0),
        accel_scale_std_ppm=np.maximum(get("accel_scale_ppm", 1.0), 1.0),
        corr_time_h=float(imu.get("corr_time_h", 4.0)))


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
    a truth file was given.
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

    def node_attitude(self):
        """Smoothed attitude quaternions at the nodes, shape (m, 4)."""
        states = self.fwd.node_states.copy()
        if self.xs is not None:
            for j in range(len(states)):
                _filter_kernels.correct_state(states[j], self.xs[j, :9])
        return states[:, 6:10]


def _initial(cfg, imu, gnss):
    """Initial state, its time and the alignment (``None`` for a given state) for a
    whole :class:`~ins.imu.ImuLog`."""
    return _start(cfg, [imu], gnss)[:3]


def _start(cfg, blocks, gnss):
    """Initial state, its time and the alignment; returns them with the IMU blocks to
    process (those read for a static window are given back)."""
    init = cfg.initial
    if cfg.method == "given":
        need = ("lat_deg", "lon_deg", "h_m", "vel_ned_mps", "rpy_deg")
        missing = [k for k in need if k not in init]
        if missing:
            raise InputError(f"[initial] {', '.join(missing)}: needed with alignment method "
                             f"'given'")
        state = NavState.from_degrees(init["lat_deg"], init["lon_deg"], init["h_m"],
                                      init["vel_ned_mps"], init["rpy_deg"])
        return state, init.get("time_s", cfg.start_s), None, blocks
    if cfg.method == "static":
        if cfg.static_window_s is None:
            raise InputError("[alignment] static_window_s: needed with method 'static'")
        t_a, t_b = cfg.static_window_s
        if not check_static_heading(cfg.noise, _window_lat(cfg, gnss, t_a, t_b), t_b - t_a,
                                    gnss):
            al = align_gnss_heading(gnss, t_b, stabilized=cfg.mount is not None)
            return al.state, al.time, al, blocks
        head, blocks = _read_until(blocks, t_b)
        imu = ImuLog._adopt(*(np.concatenate([getattr(b, k) for b in head])
                              for k in ("time", "dtheta_b", "dvel_b")))
        al = align_static(imu, t_a, t_b, _window_lla(cfg, gnss, t_a, t_b), cfg.noise)
        return al.state, al.time, al, itertools.chain(head, blocks)
    t_start = cfg.start_s
    if t_start is None and cfg.static_window_s is not None:
        t_start = cfg.static_window_s[0]
    al = align_gnss_heading(gnss, t_start, stabilized=cfg.mount is not None)
    return al.state, al.time, al, blocks


def _window_lla(cfg, gnss, t_a, t_b):
    init = cfg.initial
    if "lat_deg" in init:
        return np.array([np.deg2rad(init["lat_deg"]), np.deg2rad(init["lon_deg"]),
                         init.get("h_m", 0.0)])
    k = int(np.searchsorted(gnss.time, t_a))
    if k >= len(gnss) or gnss.time[k] > t_b:
        raise InputError(f"no GNSS epoch in the stationary window {t_a} .. {t_b} s "
                         f"to position the static alignment")
    return gnss.lla[k]


def _window_lat(cfg, gnss, t_a, t_b):
    return float(_window_lla(cfg, gnss, t_a, t_b)[0])


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


def process(cfg, progress=None, workdir=None):
    """Run the whole post-processing described by ``cfg`` (a :class:`ProcessConfig`).

    The IMU log is read block by block (in a reader thread) and streamed through the
    forward filter.  With ``workdir`` (a folder), the forward trajectory and the node
    matrices go to temporary files there, so that memory does not grow with the length
    of the log; the result's trajectories are then read back piece by piece (the folder
    must live as long as the result).  ``progress(done_s, total_s)`` is called as the
    forward pass advances.
    """
    blocks = prefetch(iter_imu(cfg.imu, format=cfg.imu_format, rates=cfg.imu_rates,
                               axes=cfg.imu_axes))
    filterpy_functions()           # the imports overlap the reader thread's parsing
    gnss = read_gnss(cfg.gnss)
    mount = read_mount(cfg.mount) if cfg.mount else None
    state, t0, al, blocks = _start(cfg, blocks, gnss)
    std = {"pos_std_ned_m": (0.05, 0.05, 0.05), "vel_std_ned_mps": (0.02, 0.02, 0.02),
           "att_std_deg": (0.01, 0.01, 0.1)}
    if al is not None:
        std = {"pos_std_ned_m": al.pos_std_ned_m, "vel_std_ned_mps": al.vel_std_ned_mps,
               "att_std_deg": al.att_std_deg}
    std.update({k: cfg.initial[k] for k in std if k in cfg.initial})
    settings = FilterSettings(noise=cfg.noise, lever=LeverArm(cfg.lever_bp, cfg.lever_ap, mount),
                              use_velocity=cfg.use_velocity,
                              reject_probability=cfg.reject_probability,
                              node_interval_s=cfg.node_interval_s, **std)
    start = t0 if t0 is not None else cfg.start_s
    fwd = run_forward(blocks, gnss, state, settings, start=start, end=cfg.end_s,
                      progress=progress, workdir=workdir)
    f_std = np.array(fwd.nodes.post_std)
    if cfg.smooth:
        xs, s_std = rts_errors(fwd, full=False)
        s_sens = fwd.sensors + xs[:, 9:21]
    else:
        xs, s_std, s_sens = None, f_std, fwd.sensors
    counts = {"imu_epochs": len(fwd.trajectory), "gnss_records": len(gnss),
              "nodes": len(fwd.node_time), "updates": fwd.n_updates,
              "rejected": fwd.n_rejected, "outside_imu_span": fwd.n_outside,
              "mount_fallback": fwd.n_mount_fallback}
    result = ProcessResult(fwd, xs, fwd.node_time, f_std, s_std, fwd.sensors.copy(), s_sens,
                           al, counts)
    if cfg.truth:
        result = with_truth(result, cfg.truth)
    return result


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
    return Trajectory(time=time, lla=states[:, 0:3], v_n=states[:, 3:6], q_nb=states[:, 6:10])


def euler_std_deg(q_nb, P_att):
    """Roll, pitch, yaw standard deviations (deg) from the phi-angle covariance (rad^2).

    ``phi = E d(roll, pitch, yaw)`` with the columns of ``E`` the roll axis
    ``Rz(yaw) Ry(pitch) e_x``, the pitch axis ``Rz(yaw) e_y`` and the yaw axis ``e_z``
    (in n), so ``Cov(rpy) = E^-1 P E^-T``.
    """
    from .rotation import quat_to_euler
    rpy = quat_to_euler(q_nb)
    _, p, y = rpy.T
    E = np.zeros((len(rpy), 3, 3))
    E[:, :, 0] = np.column_stack([np.cos(y) * np.cos(p), np.sin(y) * np.cos(p), -np.sin(p)])
    E[:, :, 1] = np.column_stack([-np.sin(y), np.cos(y), np.zeros_like(y)])
    E[:, 2, 2] = 1.0
    Ei = np.linalg.inv(E)
    cov = Ei @ P_att @ np.swapaxes(Ei, 1, 2)
    return np.rad2deg(np.sqrt(np.maximum(np.einsum("mii->mi", cov), 0.0)))


def write_outputs(result, out_dir, week=0, forward=False):
    """Write solution.nav (smoothed), solution_std.txt, imu_errors.txt and, with
    ``forward=True``, forward.nav (the forward filter's trajectory, a diagnostic).

    The .nav files are written piece by piece as the trajectory is streamed (bounded
    memory).  Returns the list of written paths.  Every file is written atomically.
    """
    from . import _textio
    from .error_model import DPH, MGAL, PPM
    from .fileio import atomic_open
    from .trajectory import write_nav
    os.makedirs(out_dir, exist_ok=True)
    paths = [os.path.join(out_dir, n) for n in
             ("solution.nav", "solution_std.txt", "imu_errors.txt")]
    write_nav(paths[0], result.iter_smoothed(), week=week)
    if forward:
        paths.append(os.path.join(out_dir, "forward.nav"))
        write_nav(paths[-1], result.iter_forward(), week=week)
    rows = np.arange(len(result.node_time))
    # attitude sigma from the smoothed covariance diagonal (phi-angle block)
    P_att = np.zeros((len(rows), 3, 3))
    idx = np.arange(3)
    P_att[:, idx, idx] = result.smoothed_std[:, 6:9] ** 2
    att = euler_std_deg(result.node_attitude(), P_att)
    table = np.column_stack([result.node_time, result.smoothed_std[:, 0:6], att])
    header = ("# time_s std_n_m std_e_m std_d_m std_vn_mps std_ve_mps std_vd_mps "
              "std_roll_deg std_pitch_deg std_yaw_deg  (smoothed, at the filter nodes)\n")
    _write_table(paths[1], header, table, [6] + [6] * 6 + [8] * 3, _textio, atomic_open)
    s = result.smoothed_sensors
    table = np.column_stack([result.node_time, s[:, 0:3] / DPH, s[:, 3:6] / MGAL,
                             s[:, 6:9] / PPM, s[:, 9:12] / PPM])
    header = ("# time_s gyro_bias_x_dph gyro_bias_y_dph gyro_bias_z_dph accel_bias_x_mgal "
              "accel_bias_y_mgal accel_bias_z_mgal gyro_scale_x_ppm gyro_scale_y_ppm "
              "gyro_scale_z_ppm accel_scale_x_ppm accel_scale_y_ppm accel_scale_z_ppm "
              "(smoothed estimates)\n")
    _write_table(paths[2], header, table, [6] + [5] * 12, _textio, atomic_open)
    return paths


def _write_table(path, header, table, decimals, _textio, atomic_open):
    text = _textio.format_fixed(table, np.array(decimals, dtype=np.int64)).tobytes()
    with atomic_open(path, "wb") as f:
        f.write(header.encode())
        f.write(text)
