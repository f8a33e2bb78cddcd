"""Processing configuration of ``ins process``: :class:`ProcessConfig`, read from a TOML
config (:func:`load_config`) or from a flight folder's manifest (:func:`config_from_manifest`).

Configuration (TOML; ``data/configs/kfgins_like.toml``), keys named like KF-GINS's YAML
with the unit in the name::

    [files]      imu, gnss, mount (optional), truth (optional): paths relative to the file;
                 instead of gnss, raw observations run through RTKLIB first: rover,
                 base, nav (one or a list), sp3, clk (ins.estimation.pipeline.gnss_source)
    [rtklib]     RTKLIB's settings with raw observations (ins.gnss.rtklib_options)
    [imu]        format = "kfgins"|"kfgins-bin"|"csv", rates = false, axes = "FRD",
                 time_shift_s = 0 (added to the IMU's stamps at read time)
    [initial]    lat_deg, lon_deg, h_m, vel_ned_mps, rpy_deg, time_s (optional),
                 pos_std_ned_m, vel_std_ned_mps, att_std_deg
    [imu_noise]  arw_deg_sqrth, vrw_mps_sqrth, gyro_bias_std_dph, accel_bias_std_mgal,
                 gyro_scale_std_ppm, accel_scale_std_ppm, corr_time_h,
                 gyro_bias_instability_dph, accel_bias_instability_mgal (optional: the
                 sensor states are then random constants plus this instability, see
                 ins.estimation.core.error_model; a flight folder's manifest gives them)
    [gnss]       lever_arm_b_m, use_velocity = true, reject_probability = 1e-5,
                 format = "kfgins"|"rtklib" (default: sniffed), time_shift_s = 0,
                 velocity_time_shift_s (default: time_shift_s; added to the epochs of
                 the velocities instead, when they are stamped differently from the
                 positions), quality = "fix,float" (RTKLIB Q kept),
                 quality_scale = "float=3,single=10", geoid = "EGM96"|"EGM2008" (the
                 model of an RTKLIB solution written with geodetic heights, converted
                 to ellipsoidal; default EGM96, with a warning)
    [mount]      imu_to_platform_centre_b_m, platform_centre_to_antenna_a_m
    [alignment]  method = "auto"|"given"|"static"|"gnss-heading"|"anywhere",
                 static_window_s = [t0, t1]; "auto" (the default) is "given" when
                 [initial] has rpy_deg and vel_ned_mps, "static" with a static window,
                 else "anywhere" (ins.estimation.alignment.motion: level and gyro
                 biases from a rest at the start, heading by velocity matching; a log
                 that never moves: the gyrocompass heading with a broad prior; an IMU
                 that starts before the first fix: the run starts at the fix or at
                 the IMU's rest before it)
    [filter]     start_s, end_s, node_interval_s = 1.0, smooth = true, recover = true,
                 identify = true (with no noise given, or a preset: the IMU noise, the
                 land-vehicle constraint and the GNSS velocity lag are identified from
                 the log, ins.estimation.pipeline.identify)
                 (recover: a run of rejected position fixes ends in a recovery: the navigation
                 covariance is inflated; ins.estimation.core.updates.RECOVER_AFTER_S)
    [states]     layout = "survey"|"kfgins"; gyro_misalignment, accel_misalignment,
                 lever_arm, time_offset (true/false: add or drop a group of the layout);
                 gyro_misalignment_std_arcsec, accel_misalignment_std_arcsec (default:
                 the scale-factor sigma, 1 arcsec per ppm, at least 1 arcsec:
                 ins.estimation.core.filter_settings.default_misalignment_std_arcsec),
                 lever_arm_std_m = 0.05, time_offset_std_ms = 5 (priors)
    [measurements] zupt = false, zupt_sigma_mps = 0.005, zupt_accel_std_mps2 = 0.05,
                 zupt_gyro_dps = 0.5, zupt_windows_s = [[t0, t1], ...],
                 nhc = false, nhc_sigma_mps = 0.1
    [vehicle]    mounting_rpy_deg = [roll, pitch, yaw] (the IMU in the vehicle's
                 forward-right-down axes, C_vb = Rz(yaw) Ry(pitch) Rx(roll); the
                 non-holonomic constraint holds in the vehicle axes; ins.estimation.tools.vehicle)
    [heading]    baseline_b_m = [x, y, z] (primary-to-secondary antenna, b frame),
                 sigma_deg (when the file has no sigma column): the dual-antenna
                 headings of [files] heading (ins.estimation.pipeline.heading_files; on the GNSS clock:
                 [gnss] time_shift_s applies)

With a mount, ``[mount]`` replaces ``[gnss] lever_arm_b_m``.  A flight folder's
``manifest.toml`` (``docs/interfaces.md``) gives the files, lever arms, IMU error values
and the stationary segment; the manifest's true initial state is NOT used (it would be
cheating): the alignment is static when there is a stationary segment, else in-air.
"""
import os
from dataclasses import dataclass, field

import numpy as np

from ins.common import limits
from ins.common.errors import InputError
from ins.common.tomlschema import check_keys
from ins.estimation.core.error_model import LAYOUTS, OPTIONAL_GROUPS, ImuNoise, StateLayout
from ins.estimation.pipeline.gnss_source import RAW_KEYS
from ins.gnss.rtklib_options import KEYS as RTKLIB_KEYS

_NOISE_KEYS = ("arw_deg_sqrth", "vrw_mps_sqrth", "gyro_bias_std_dph", "accel_bias_std_mgal",
               "gyro_scale_std_ppm", "accel_scale_std_ppm", "corr_time_h",
               "gyro_bias_instability_dph", "accel_bias_instability_mgal")
_SECTIONS = {
    "files": {"imu", "gnss", "mount", "truth", "heading", *RAW_KEYS},
    "rtklib": set(RTKLIB_KEYS),
    "imu": {"format", "rates", "axes", "time_shift_s"},
    "initial": {"lat_deg", "lon_deg", "h_m", "vel_ned_mps", "rpy_deg", "time_s",
                "pos_std_ned_m", "vel_std_ned_mps", "att_std_deg"},
    "imu_noise": set(_NOISE_KEYS),
    "gnss": {"lever_arm_b_m", "use_velocity", "reject_probability", "format",
             "time_shift_s", "velocity_time_shift_s", "quality", "quality_scale",
             "coupling", "elevation_mask_deg", "range_sigma_m", "range_rate_sigma_mps",
             "receiver_clock", "geoid", "carrier_phase", "carrier_sigma_m",
             "ambiguity_ratio", "ambiguity_success_rate", "range_noise",
             "robust_weighting"},
    "mount": {"imu_to_platform_centre_b_m", "platform_centre_to_antenna_a_m"},
    "alignment": {"method", "static_window_s"},
    "filter": {"start_s", "end_s", "node_interval_s", "smooth", "recover", "identify"},
    "states": {"layout", *OPTIONAL_GROUPS, "gyro_misalignment_std_arcsec",
               "accel_misalignment_std_arcsec", "lever_arm_std_m", "time_offset_std_ms"},
    "measurements": {"zupt", "zupt_sigma_mps", "zupt_accel_std_mps2", "zupt_gyro_dps",
                     "zupt_windows_s", "nhc", "nhc_sigma_mps"},
    "vehicle": {"mounting_rpy_deg"},
    "heading": {"baseline_b_m", "sigma_deg"},
}
#: The layout of ``ins process`` when ``[states] layout`` is not given.
DEFAULT_LAYOUT = "survey"
#: ``[states]`` prior keys -> number of values (one value or one per axis).
_PRIOR_KEYS = {"gyro_misalignment_std_arcsec": 3, "accel_misalignment_std_arcsec": 3,
               "lever_arm_std_m": 3, "time_offset_std_ms": 1}
_MEAS_NUMBERS = ("zupt_sigma_mps", "zupt_accel_std_mps2", "zupt_gyro_dps", "nhc_sigma_mps")
METHODS = ("auto", "given", "static", "gnss-heading", "anywhere")
POSITION_KEYS = ("lat_deg", "lon_deg", "h_m")


@dataclass
class ProcessConfig:
    """Everything a run needs (paths and settings); see the module notes for the keys."""

    imu: str
    gnss: str
    gnss_raw: object = None       # ins.estimation.pipeline.gnss_source.RawGnss instead of gnss
    gnss_raw_plot: bool = True    # raw GNSS, kinematic: fwd_bwd_separation.png
    mount: str = None
    truth: str = None
    heading: str = None
    heading_baseline_b_m: np.ndarray = None
    heading_sigma_deg: float = None
    imu_format: str = None
    imu_rates: bool = False
    imu_axes: str = "FRD"
    imu_time_shift_s: float = 0.0
    gnss_format: str = None
    gnss_time_shift_s: float = 0.0
    gnss_velocity_time_shift_s: float = None
    gnss_quality: object = None
    gnss_quality_scale: object = None
    gnss_geoid: str = None
    noise: ImuNoise = field(default_factory=ImuNoise)
    lever_bp: np.ndarray = field(default_factory=lambda: np.zeros(3))
    lever_ap: np.ndarray = field(default_factory=lambda: np.zeros(3))
    initial: dict = field(default_factory=dict)
    method: str = "auto"
    static_window_s: tuple = None
    start_s: float = None
    end_s: float = None
    node_interval_s: float = 1.0
    use_velocity: bool = True
    reject_probability: float = 1e-5
    smooth: bool = True
    recover: bool = True
    # noise identified from the log when none is given: a TOML config's default (true);
    # a ProcessConfig built in Python runs with the noise it holds unless it sets this
    identify: bool = False
    noise_source: str = None      # "config", "manifest", "preset NAME"; None: the defaults
    source: str = "config"
    initial_source: str = None
    coupling: str = "loose"       # "tight": raw GNSS input, ins.estimation.pipeline.tight
    elevation_mask_deg: float = 10.0
    range_sigma_m: tuple = (0.3, 0.3)          # tight: (a, b) of sqrt(a^2 + b^2 / sin^2 el)
    range_rate_sigma_mps: tuple = (0.05, 0.05)
    receiver_clock: str = "tcxo"               # tight: the clock states' noise
    range_noise: str = "auto"                  # tight: "auto" (fitted, two passes) or "fixed"
    robust_weighting: bool = None              # tight: IGG-III on code and Doppler rows
    #                                            (None: with range_noise = "auto" only)
    carrier_phase: bool = True                 # tight with a base: RTK (carrier DDs)
    carrier_sigma_m: tuple = (0.003, 0.003)
    ambiguity_ratio: float = 3.0
    ambiguity_success_rate: float = 0.99
    layout: StateLayout = field(default_factory=lambda: StateLayout(LAYOUTS[DEFAULT_LAYOUT]))
    priors: dict = field(default_factory=dict)
    measurements: dict = field(default_factory=dict)


def _vector(value, where, n=3, bound=None, unit=""):
    """``n`` finite numbers (a scalar is repeated), each within ``+-bound`` (``unit``)."""
    try:
        v = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{where}: expected {n} numbers, got {value!r}") from None
    if v.ndim == 0:
        v = np.full(n, float(v))
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise InputError(f"{where}: expected {n} finite numbers, got {value!r}")
    if bound is not None:
        msg = limits.check_vector(v, bound, where, unit)
        if msg is not None:
            raise InputError(msg)
    return v


def _number(value, where, positive=False, lo=None, hi=None, unit=""):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise InputError(f"{where}: expected a number, got {value!r}")
    if positive and value <= 0:
        raise InputError(f"{where}: expected a number > 0, got {value!r}")
    if limits.out_of_bounds(value, lo, hi):
        raise InputError(f"{where}: {float(value):g} {unit} is outside {lo:g} .. {hi:g} {unit}")
    return float(value)


#: Bounds of the [initial] keys: (lo, hi, unit) of each component (None: unbounded).
_INITIAL_BOUNDS = {
    "lat_deg": (-90.0, 90.0, "deg"), "lon_deg": (-180.0, 360.0, "deg"),
    "h_m": (limits.MIN_HEIGHT_M, limits.MAX_HEIGHT_M, "m"),
    "vel_ned_mps": (limits.MAX_SPEED_MPS, "m/s"), "rpy_deg": (360.0, "deg"),
    "pos_std_ned_m": (limits.MAX_SIGMA_M, "m"), "vel_std_ned_mps": (limits.MAX_SPEED_MPS, "m/s"),
    "att_std_deg": (180.0, "deg"),
}


def _read_toml(path, expected="a processing config (TOML)"):
    from ins.common.textfiles import read_toml
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
    check_keys(data, _SECTIONS, path)
    base = os.path.dirname(os.path.abspath(path)) if base is None else base
    rel = {k: _relative(base, v) for k, v in data.get("files", {}).items()}
    given = {k: v for k, v in (files or {}).items() if v not in (None, [], ())}
    if given.keys() & {"gnss", "rover"}:          # the command line's GNSS input wins
        for k in ("gnss", *RAW_KEYS):
            rel.pop(k, None)
    rel.update(given)
    from ins.estimation.pipeline.gnss_source import raw_gnss_config
    raw = raw_gnss_config(rel, data.get("rtklib"), path)
    for key in ("imu", "gnss"):
        if key not in rel and not (key == "gnss" and raw is not None):
            raise InputError(f"{where('files', key)}: missing (path of the {key} log; "
                             f"or give --{key}" + ("; or raw observations: [files] rover, "
                                                   "base, nav" if key == "gnss" else "")
                             + ")")
    cfg = ProcessConfig(imu=rel["imu"], gnss=rel.get("gnss"), gnss_raw=raw,
                        mount=rel.get("mount"), truth=rel.get("truth"),
                        heading=rel.get("heading"))
    if raw is not None:
        cfg.gnss_format = "rtklib"
    return _fill(cfg, data, where, path)


def _relative(base, value):
    """A ``[files]`` path (or list of paths) relative to ``base``; other values as they
    are (checked by their reader)."""
    if isinstance(value, str):
        return os.path.join(base, value)
    if isinstance(value, list):
        return [os.path.join(base, v) if isinstance(v, str) else v for v in value]
    return value


def _fill(cfg, data, where, path=None):
    """Settings of a parsed TOML table into ``cfg`` (shared by config and overrides)."""
    imu = data.get("imu", {})
    cfg.imu_format = imu.get("format", cfg.imu_format)
    cfg.imu_rates = bool(imu.get("rates", cfg.imu_rates))
    cfg.imu_axes = imu.get("axes", cfg.imu_axes)
    if "time_shift_s" in imu:
        cfg.imu_time_shift_s = _number(imu["time_shift_s"], where("imu", "time_shift_s"),
                                       lo=-limits.MAX_TIME_SHIFT_S, hi=limits.MAX_TIME_SHIFT_S,
                                       unit="s")
    if "imu_noise" in data:
        cfg.noise = _noise(data["imu_noise"], where("imu_noise"))
        cfg.noise_source = "config"
    gnss = data.get("gnss", {})
    if "lever_arm_b_m" in gnss:
        cfg.lever_bp = _vector(gnss["lever_arm_b_m"], where("gnss", "lever_arm_b_m"),
                               bound=limits.MAX_LEVER_ARM_M, unit="m")
        cfg.lever_ap = np.zeros(3)
    cfg.use_velocity = bool(gnss.get("use_velocity", cfg.use_velocity))
    _gnss_input(cfg, gnss, where)
    _coupling(cfg, gnss, where)
    if "reject_probability" in gnss:
        p = _number(gnss["reject_probability"], where("gnss", "reject_probability"), True)
        if p >= 1:
            raise InputError(f"{where('gnss', 'reject_probability')}: expected 0 < p < 1")
        cfg.reject_probability = p
    mount = data.get("mount", {})
    for key, attr in (("imu_to_platform_centre_b_m", "lever_bp"),
                      ("platform_centre_to_antenna_a_m", "lever_ap")):
        if key in mount:
            setattr(cfg, attr, _vector(mount[key], where("mount", key),
                                       bound=limits.MAX_LEVER_ARM_M, unit="m"))
    init = data.get("initial", {})
    if any(k in init for k in POSITION_KEYS + ("time_s",)):
        cfg.initial_source = None if path is None else os.fspath(path)
    for key, value in init.items():
        n = 3 if key not in ("lat_deg", "lon_deg", "h_m", "time_s") else None
        b = _INITIAL_BOUNDS.get(key)
        if n:
            cfg.initial[key] = _vector(value, where("initial", key),
                                       *((3, *b) if b else ()))
            if key.endswith(("_std_ned_m", "_std_ned_mps", "_std_deg")) and np.any(
                    cfg.initial[key] < 0):
                raise InputError(f"{where('initial', key)}: expected values >= 0, got "
                                 f"{value!r}")
        else:
            cfg.initial[key] = _number(value, where("initial", key),
                                       *((False, *b) if b else ()))
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
    cfg.recover = bool(filt.get("recover", cfg.recover))
    cfg.identify = (_flag(filt["identify"], where("filter", "identify"))
                    if "identify" in filt else True)
    _states(cfg, data.get("states", {}), where)
    _measurements(cfg, data.get("measurements", {}), where)
    _vehicle_and_heading(cfg, data, where)
    return cfg


def _vehicle_and_heading(cfg, data, where):
    """``[vehicle]`` (the NHC's mounting rotation, into ``cfg.measurements``) and
    ``[heading]`` (the dual-antenna baseline and sigma)."""
    from ins.estimation.tools.vehicle import mounting_dcm
    veh = data.get("vehicle", {})
    if "mounting_rpy_deg" in veh:
        cfg.measurements["nhc_C_vb"] = mounting_dcm(veh["mounting_rpy_deg"],
                                                    where("vehicle", "mounting_rpy_deg"))
    head = data.get("heading", {})
    if "baseline_b_m" in head:
        b = _vector(head["baseline_b_m"], where("heading", "baseline_b_m"),
                    bound=limits.MAX_LEVER_ARM_M, unit="m")
        if np.linalg.norm(b) < 1e-3:
            raise InputError(f"{where('heading', 'baseline_b_m')}: expected the primary-to-"
                             f"secondary antenna vector (m, b frame: forward, right, down), "
                             f"got {head['baseline_b_m']!r}")
        cfg.heading_baseline_b_m = b
    if "sigma_deg" in head:
        cfg.heading_sigma_deg = _number(head["sigma_deg"], where("heading", "sigma_deg"), True)


def _flag(value, where):
    if not isinstance(value, bool):
        raise InputError(f"{where}: expected true or false, got {value!r}")
    return value


def _states(cfg, sec, where):
    """``[states]``: the layout, groups switched on or off, priors (edge units)."""
    groups = set(cfg.layout.groups)
    if "layout" in sec:
        if sec["layout"] not in LAYOUTS:
            raise InputError(f"{where('states', 'layout')}: expected one of "
                             f"{', '.join(LAYOUTS)}, got {sec['layout']!r}")
        groups = set(LAYOUTS[sec["layout"]])
    for g in OPTIONAL_GROUPS:
        if g in sec:
            (groups.add if _flag(sec[g], where("states", g)) else groups.discard)(g)
    cfg.layout = StateLayout(tuple(groups))
    for key, n in _PRIOR_KEYS.items():
        if key in sec:
            v = (_number(sec[key], where("states", key), positive=True) if n == 1
                 else _vector(sec[key], where("states", key)))
            if np.any(np.asarray(v) <= 0):
                raise InputError(f"{where('states', key)}: expected values > 0, got "
                                 f"{sec[key]!r}")
            cfg.priors[key] = v


def _measurements(cfg, sec, where):
    """``[measurements]``: zero-velocity and non-holonomic updates."""
    for key in ("zupt", "nhc"):
        if key in sec:
            cfg.measurements[key] = _flag(sec[key], where("measurements", key))
    for key in _MEAS_NUMBERS:
        if key in sec:
            cfg.measurements[key] = _number(sec[key], where("measurements", key), True)
    if "zupt_windows_s" in sec:
        w = sec["zupt_windows_s"]
        try:
            arr = np.array(w, dtype=float).reshape(-1, 2)
        except (TypeError, ValueError):
            raise InputError(f"{where('measurements', 'zupt_windows_s')}: expected a list "
                             f"of [start, end] pairs (GPS s), got {w!r}") from None
        if not np.all(np.isfinite(arr)) or np.any(arr[:, 1] < arr[:, 0]):
            raise InputError(f"{where('measurements', 'zupt_windows_s')}: expected finite "
                             f"[start, end] pairs with end >= start, got {w!r}")
        cfg.measurements["zupt_windows_s"] = tuple(map(tuple, arr))


def filter_options(cfg):
    """The :class:`ins.estimation.core.filter_settings.FilterSettings` keywords of ``[states]`` and
    ``[measurements]``."""
    return {"layout": cfg.layout, **cfg.priors, **cfg.measurements}


def _coupling(cfg, gnss, where):
    """``[gnss] coupling`` ("loose" or "tight") and ``elevation_mask_deg`` (tight)."""
    if "coupling" in gnss:
        if gnss["coupling"] not in ("loose", "tight"):
            raise InputError(f"{where('gnss', 'coupling')}: expected \"loose\" or \"tight\", "
                             f"got {gnss['coupling']!r}")
        cfg.coupling = gnss["coupling"]
    if "elevation_mask_deg" in gnss:
        cfg.elevation_mask_deg = _number(gnss["elevation_mask_deg"],
                                         where("gnss", "elevation_mask_deg"), lo=0.0, hi=90.0,
                                         unit="deg")
    if "carrier_phase" in gnss:
        if not isinstance(gnss["carrier_phase"], bool):
            raise InputError(f"{where('gnss', 'carrier_phase')}: expected true or false, got "
                             f"{gnss['carrier_phase']!r}")
        cfg.carrier_phase = gnss["carrier_phase"]
    if "ambiguity_ratio" in gnss:
        cfg.ambiguity_ratio = _number(gnss["ambiguity_ratio"], where("gnss", "ambiguity_ratio"),
                                      lo=1.0, hi=1000.0, unit="(ratio of squared norms)")
    if "ambiguity_success_rate" in gnss:
        cfg.ambiguity_success_rate = _number(gnss["ambiguity_success_rate"],
                                             where("gnss", "ambiguity_success_rate"), lo=0.0,
                                             hi=1.0, unit="(probability)")
    for key, unit, bound in (("range_sigma_m", "m", 1000.0),
                             ("range_rate_sigma_mps", "m/s", 100.0),
                             ("carrier_sigma_m", "m", 1.0)):
        if key in gnss:
            v = _vector(gnss[key], where("gnss", key), n=2, bound=bound, unit=unit)
            if np.any(v < 0) or not np.any(v > 0):
                raise InputError(f"{where('gnss', key)}: expected [a, b] in {unit}, a, b >= 0 "
                                 f"and not both 0 (sigma^2 = a^2 + b^2 / sin^2 elevation), "
                                 f"got {gnss[key]!r}")
            setattr(cfg, key, tuple(float(x) for x in v))
    if "range_noise" in gnss:
        if gnss["range_noise"] not in ("auto", "fixed"):
            raise InputError(f"{where('gnss', 'range_noise')}: expected \"auto\" (fitted "
                             f"from a first pass) or \"fixed\" (range_sigma_m, "
                             f"range_rate_sigma_mps), got {gnss['range_noise']!r}")
        cfg.range_noise = gnss["range_noise"]
    if "robust_weighting" in gnss:
        if not isinstance(gnss["robust_weighting"], bool):
            raise InputError(f"{where('gnss', 'robust_weighting')}: expected true or false, "
                             f"got {gnss['robust_weighting']!r}")
        cfg.robust_weighting = gnss["robust_weighting"]
    if "receiver_clock" in gnss:
        from ins.estimation.coupling.pseudorange import CLOCKS
        if gnss["receiver_clock"] not in CLOCKS:
            raise InputError(f"{where('gnss', 'receiver_clock')}: expected one of "
                             f"{', '.join(map(repr, CLOCKS))}, got {gnss['receiver_clock']!r}")
        cfg.receiver_clock = gnss["receiver_clock"]


def _gnss_input(cfg, gnss, where):
    """``[gnss]`` format, time_shift_s, velocity_time_shift_s, quality, quality_scale
    (checked here, applied by :func:`ins.io.gnss.read_gnss`)."""
    from ins.io.gnss import FORMATS
    from ins.io.gnss_quality import parse_quality, parse_quality_scale
    if "format" in gnss:
        if gnss["format"] not in FORMATS:
            raise InputError(f"{where('gnss', 'format')}: expected one of {', '.join(FORMATS)}, "
                             f"got {gnss['format']!r}")
        cfg.gnss_format = gnss["format"]
    if "time_shift_s" in gnss:
        cfg.gnss_time_shift_s = _number(gnss["time_shift_s"], where("gnss", "time_shift_s"),
                                        lo=-limits.MAX_TIME_SHIFT_S,
                                        hi=limits.MAX_TIME_SHIFT_S, unit="s")
    if "velocity_time_shift_s" in gnss:
        cfg.gnss_velocity_time_shift_s = _number(
            gnss["velocity_time_shift_s"], where("gnss", "velocity_time_shift_s"),
            lo=-limits.MAX_TIME_SHIFT_S, hi=limits.MAX_TIME_SHIFT_S, unit="s")
    if "quality" in gnss:
        cfg.gnss_quality = parse_quality(gnss["quality"], where("gnss", "quality"))
    if "quality_scale" in gnss:
        cfg.gnss_quality_scale = parse_quality_scale(gnss["quality_scale"],
                                                     where("gnss", "quality_scale"))
    if "geoid" in gnss:
        from ins.io.geoid import GEOID_MODELS
        if str(gnss["geoid"]).upper() not in GEOID_MODELS:
            raise InputError(f"{where('gnss', 'geoid')}: expected one of "
                             f"{', '.join(GEOID_MODELS)}, got {gnss['geoid']!r}")
        cfg.gnss_geoid = str(gnss["geoid"]).upper()


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
                           where("lever_arm", "imu_to_platform_centre_b_m"), bound=limits.MAX_LEVER_ARM_M,
                           unit="m")
    cfg.lever_ap = _vector(arm.get("platform_centre_to_antenna_a_m", [0, 0, 0]),
                           where("lever_arm", "platform_centre_to_antenna_a_m"), bound=limits.MAX_LEVER_ARM_M,
                           unit="m")
    cfg.noise = _manifest_noise(man.get("imu", {}), where("imu"))
    cfg.noise_source = "manifest"
    cfg.priors = _manifest_priors(man.get("imu", {}), where("imu"))
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
        data = check_keys(_read_toml(overrides), _SECTIONS, overrides)
        _fill(cfg, data, lambda sec, key="": f"{overrides}: [{sec}]" + (f" {key}" if key else ""),
              overrides)
    return cfg


def _manifest_priors(imu, where):
    """Prior sigmas of the non-orthogonality states from the injected values of the
    manifest (their magnitudes, at least 1 arcsec), as the noise of the sensor states."""
    out = {}
    for key in ("gyro_misalignment", "accel_misalignment"):
        v = np.abs(_vector(imu.get(key + "_arcsec", 0.0), f"{where} {key}_arcsec"))
        out[key + "_std_arcsec"] = np.maximum(v, 1.0)
    return out


def _manifest_noise(imu, where):
    """Filter noise from the injected error values of the manifest (same units): the
    biases' prior the total of the constant and the instability, the sensor states
    random constants plus the instability (as the simulator injects them)."""
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
        corr_time_h=float(imu.get("corr_time_h", 4.0)),
        gyro_bias_instability_dph=get("gyro_bias_instability_dph", 0.0),
        accel_bias_instability_mgal=get("accel_bias_instability_mgal", 0.0))
