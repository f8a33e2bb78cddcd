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
import os
import tomllib
from dataclasses import dataclass, field, replace

import numpy as np

from . import imu as imu_mod
from .alignment import align_gnss_heading, align_static
from .error_model import ImuNoise
from .errors import InputError
from .filter import FilterSettings, run_forward, std_of
from .gnss import read_gnss
from .lever_arm import LeverArm
from .mechanization import NavState
from .mount import read_mount
from .smoother import smooth
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


def _read_toml(path):
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}", path=str(path)) from None


def _noise(section, where):
    kw = {}
    for key in _NOISE_KEYS:
        if key in section:
            kw[key] = (_number(section[key], f"{where} {key}", positive=True)
                       if key == "corr_time_h" else _vector(section[key], f"{where} {key}"))
            if key != "corr_time_h" and np.any(kw[key] < 0):
                raise InputError(f"{where} {key}: expected values >= 0, got {section[key]!r}")
    return ImuNoise(**kw)


def load_config(path, base=None):
    """Read a processing config (TOML).  Paths in ``[files]`` are relative to the file.

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
    files = data.get("files", {})
    for key in ("imu", "gnss"):
        if key not in files:
            raise InputError(f"{where('files', key)}: missing (path of the {key} log)")
    rel = {k: os.path.join(base, v) for k, v in files.items()}
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
    if isinstance(segments, list) and segments and len(segments[0]) == 2:
        cfg.method = "static"
        cfg.static_window_s = (float(segments[0][0]), float(segments[0][1]))
    else:
        cfg.method = "gnss-heading"
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

    ``forward`` and ``smoothed`` are trajectories at every IMU epoch; ``node_time`` the
    filter nodes with ``forward_std``/``smoothed_std`` (m, 21) and ``forward_sensors``/
    ``smoothed_sensors`` (m, 12: gyro bias rad/s, accel bias m/s^2, scales);
    ``errors_forward``/``errors_smoothed`` (:class:`ins.accuracy.TrajectoryErrors`) when
    a truth file was given.
    """

    forward: Trajectory
    smoothed: Trajectory
    node_time: np.ndarray
    forward_std: np.ndarray
    smoothed_std: np.ndarray
    forward_sensors: np.ndarray
    smoothed_sensors: np.ndarray
    alignment: object
    counts: dict
    errors_forward: object = None
    errors_smoothed: object = None


def _initial(cfg, imu, gnss):
    init = cfg.initial
    if cfg.method == "given":
        need = ("lat_deg", "lon_deg", "h_m", "vel_ned_mps", "rpy_deg")
        missing = [k for k in need if k not in init]
        if missing:
            raise InputError(f"[initial] {', '.join(missing)}: needed with alignment method "
                             f"'given'")
        state = NavState.from_degrees(init["lat_deg"], init["lon_deg"], init["h_m"],
                                      init["vel_ned_mps"], init["rpy_deg"])
        return state, init.get("time_s", cfg.start_s), None
    if cfg.method == "static":
        if cfg.static_window_s is None:
            raise InputError("[alignment] static_window_s: needed with method 'static'")
        t_a, t_b = cfg.static_window_s
        if "lat_deg" in init:
            lla = np.array([np.deg2rad(init["lat_deg"]), np.deg2rad(init["lon_deg"]),
                            init.get("h_m", 0.0)])
        else:
            k = int(np.searchsorted(gnss.time, t_a))
            if k >= len(gnss) or gnss.time[k] > t_b:
                raise InputError(f"no GNSS epoch in the stationary window {t_a} .. {t_b} s "
                                 f"to position the static alignment")
            lla = gnss.lla[k]
        al = align_static(imu, t_a, t_b, lla, cfg.noise)
        return al.state, al.time, al
    al = align_gnss_heading(gnss, cfg.start_s if cfg.start_s is not None else imu.time[0])
    return al.state, al.time, al


def process(cfg, progress=None):
    """Run the whole post-processing described by ``cfg`` (a :class:`ProcessConfig`)."""
    imu = imu_mod.read_imu(cfg.imu, format=cfg.imu_format, rates=cfg.imu_rates,
                           axes=cfg.imu_axes)
    gnss = read_gnss(cfg.gnss)
    mount = read_mount(cfg.mount) if cfg.mount else None
    state, t0, al = _initial(cfg, imu, gnss)
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
    fwd = run_forward(imu, gnss, state, settings, start=start, end=cfg.end_s, progress=progress)
    del imu
    forward = _trajectory(fwd.time, fwd.states.copy() if cfg.smooth else fwd.states)
    node_time = fwd.time[fwd.node_rows]
    if cfg.smooth:
        sm = smooth(fwd, in_place=True)
        smoothed, s_std, s_sens = _trajectory(sm.time, sm.states), std_of(sm.P), sm.sensors
    else:
        smoothed, s_std, s_sens = forward, std_of(fwd.P_post), fwd.sensors
    counts = {"imu_epochs": len(fwd.time), "gnss_records": len(gnss), "nodes": len(node_time),
              "updates": fwd.n_updates, "rejected": fwd.n_rejected,
              "outside_imu_span": fwd.n_outside, "mount_fallback": fwd.n_mount_fallback}
    result = ProcessResult(forward, smoothed, node_time, std_of(fwd.P_post), s_std,
                           fwd.sensors.copy(), s_sens, al, counts)
    if cfg.truth:
        result = with_truth(result, cfg.truth)
    return result


def with_truth(result, truth_path):
    """``result`` with its errors against a truth ``.nav`` file."""
    from .accuracy import compare
    from .trajectory import read_nav
    truth = read_nav(truth_path)
    try:
        ef, es = compare(result.forward, truth), compare(result.smoothed, truth)
    except ValueError as exc:
        raise InputError(f"{truth_path}: {exc}") from None
    return replace(result, errors_forward=ef, errors_smoothed=es)


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


def write_outputs(result, out_dir, week=0):
    """Write solution.nav (smoothed), forward.nav, solution_std.txt, imu_errors.txt.

    Returns the list of written paths.  Every file is written atomically.
    """
    from . import _textio
    from .error_model import DPH, MGAL, PPM
    from .fileio import atomic_open
    from .trajectory import write_nav
    os.makedirs(out_dir, exist_ok=True)
    paths = [os.path.join(out_dir, n) for n in
             ("solution.nav", "forward.nav", "solution_std.txt", "imu_errors.txt")]
    write_nav(paths[0], result.smoothed, week=week)
    write_nav(paths[1], result.forward, week=week)
    rows = np.searchsorted(result.smoothed.time, result.node_time)
    # attitude sigma from the smoothed covariance diagonal (phi-angle block)
    P_att = np.zeros((len(rows), 3, 3))
    idx = np.arange(3)
    P_att[:, idx, idx] = result.smoothed_std[:, 6:9] ** 2
    att = euler_std_deg(result.smoothed.q_nb[rows], P_att)
    table = np.column_stack([result.node_time, result.smoothed_std[:, 0:6], att])
    header = ("# time_s std_n_m std_e_m std_d_m std_vn_mps std_ve_mps std_vd_mps "
              "std_roll_deg std_pitch_deg std_yaw_deg  (smoothed, at the filter nodes)\n")
    _write_table(paths[2], header, table, [6] + [6] * 6 + [8] * 3, _textio, atomic_open)
    s = result.smoothed_sensors
    table = np.column_stack([result.node_time, s[:, 0:3] / DPH, s[:, 3:6] / MGAL,
                             s[:, 6:9] / PPM, s[:, 9:12] / PPM])
    header = ("# time_s gyro_bias_x_dph gyro_bias_y_dph gyro_bias_z_dph accel_bias_x_mgal "
              "accel_bias_y_mgal accel_bias_z_mgal gyro_scale_x_ppm gyro_scale_y_ppm "
              "gyro_scale_z_ppm accel_scale_x_ppm accel_scale_y_ppm accel_scale_z_ppm "
              "(smoothed estimates)\n")
    _write_table(paths[3], header, table, [6] + [5] * 12, _textio, atomic_open)
    return paths


def _write_table(path, header, table, decimals, _textio, atomic_open):
    text = _textio.format_fixed(table, np.array(decimals, dtype=np.int64)).tobytes()
    with atomic_open(path, "wb") as f:
        f.write(header.encode())
        f.write(text)
