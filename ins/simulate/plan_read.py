"""Flight plan of a photogrammetric survey flight (TOML), validated, SI units inside.

The file has the sections ``[block] [flight] [wind] [turbulence] [mount] [imu] [gnss]
[camera] [terrain] [tie_points]`` and the optional ``[scanner]`` (a simulated laser
scanner: without it the flight has no LiDAR products) and ``[gnss_raw]`` (raw GPS
observations from broadcast orbits: :mod:`ins.simulate.gnss_raw_plan`); key names carry
their unit (``_deg``, ``_m``,
``_mps``, ``_hz``, ``_s``, ``_percent``).  ``data/flights/demo.toml`` is the documented
example.  Every key has a default except the block origin; unknown keys and sections are
errors (:mod:`ins.common.tomlschema`: the message lists the known keys of the section, with
"did you mean" for a near miss; :data:`PLAN_KEYS` holds them).  :func:`load_plan` and
:func:`parse_plan` raise :class:`~ins.common.errors.InputError` as
``"plan.toml: [section] key: message (expected unit)"``.

Geometry of the photo block
---------------------------
The strips are straight lines of azimuth ``strip_azimuth_deg`` (clockwise from north)
and length ``strip_length_m``; strip 0 starts at the block origin, the next strips lie to
the right of the first (looking along the azimuth), ``strip_spacing`` apart, flown
alternately back and forth.  With the nominal camera axes (``[camera] axes``, rows of
``C_bc``) the body x axis (forward, along track) is the image axis whose row of ``axes``
has the larger entry: for the default nadir axes ``[[1,0,0],[0,-1,0],[0,0,-1]]`` the
camera x axis (image columns, ``width_px``) is along track and the image rows
(``height_px``) across track.  Then::

    footprint_along  = height_agl * n_px_along  * pixel_size / focal_length
    footprint_across = height_agl * n_px_across * pixel_size / focal_length
    exposure_interval = (1 - forward_overlap) * footprint_along / ground_speed
    strip_spacing     = (1 - side_overlap) * footprint_across

Feasibility
-----------
The turns are coordinated turns at ``turn_rate_deg_s`` or ``bank_deg`` (typically 15-25
deg bank), up to ``[flight] max_bank_deg`` (default 30).  In the turns the stabilized
mount runs into its level limit and saturates smoothly (normal in a survey); on the
strips it must follow: the crab of the wind plus the yaw turbulence, and the roll and
pitch turbulence, must stay below :data:`MOUNT_KNEE` (80 %) of the azimuth and level
limits ("the mount cannot follow" otherwise), and ``run_in_m`` must give the servos 3
lags to recover from the turn.

This module reads it (the keys of every section, one reader per section, units converted
to SI, :func:`parse_plan` and :func:`load_plan`); the sections are the dataclasses of
:mod:`~ins.simulate.plan_model`, the feasibility rules :mod:`~ins.simulate.plan_checks`.
Messages: ``"plan.toml: [section] key: message (expected unit)"``
(:mod:`ins.common.tomlschema`).
"""
import math
from types import MappingProxyType

import numpy as np

from ins.common.errors import InputError
from ins.common.limits import MAX_LEVER_ARM_M, MAX_SIGMA_M
from ins.common.textfiles import read_toml
from ins.common.tomlschema import REQUIRED, Table, check_keys
from ins.simulate.gnss_raw_plan import GNSS_RAW_KEYS, parse_gnss_raw
from ins.simulate.plan_checks import check_feasible
from ins.simulate.plan_model import (
    D2R,
    G_TURN,
    NADIR_AXES,
    Block,
    CameraSettings,
    Flight,
    FlightPlan,
    GnssSettings,
    ImuSettings,
    Mount,
    ScannerSettings,
    Terrain,
    TiePoints,
    Turbulence,
    Wind,
)
from ins.simulate.sensor_errors import MANIFEST_KEYS, PRESETS

__all__ = ["PLAN_KEYS", "parse_plan", "load_plan"]

#: Every key of every section of a flight plan (the reader refuses the others).
PLAN_KEYS = {
    "block": ("origin_lat_deg", "origin_lon_deg", "origin_h_m", "strip_azimuth_deg",
              "strip_length_m", "n_strips", "side_overlap_percent", "strip_spacing_m",
              "forward_overlap_percent", "exposure_interval_s"),
    "flight": ("height_agl_m", "ground_speed_mps", "turn_rate_deg_s", "bank_deg",
               "max_bank_deg", "climb_rate_mps", "start", "stationary_s", "run_in_m",
               "takeoff_accel_mps2", "gps_week", "start_time_s"),
    "wind": ("speed_mps", "from_deg"),
    "turbulence": ("roll_amp_deg", "roll_freq_hz", "pitch_amp_deg", "pitch_freq_hz",
                   "yaw_amp_deg", "yaw_freq_hz", "heave_amp_m", "heave_freq_hz", "seed"),
    "mount": ("enabled", "level_limit_deg", "azimuth_limit_deg", "servo_lag_s", "log_rate_hz",
              "imu_to_platform_centre_b_m", "platform_centre_to_antenna_a_m"),
    "imu": ("grade", "rate_hz") + tuple(MANIFEST_KEYS),
    "gnss": ("rate_hz", "sigma_ned_m", "velocity", "sigma_vel_mps", "outages"),
    "camera": ("focal_length_mm", "pixel_size_mm", "width_px", "height_px",
               "principal_point_px", "radial_k", "tangential_p", "axes", "lever_arm_m",
               "boresight_deg"),
    "terrain": ("relief_m", "wavelength_m", "seed_offset"),
    "tie_points": ("per_image", "sigma_px"),
    "scanner": ("model", "pulse_rate_hz", "scan_rate_hz", "field_of_view_deg",
                "forward_tilt_deg", "range_sigma_m", "scan_angle_sigma_deg", "lever_arm_m",
                "boresight_deg", "lever_arm_sigma_m", "boresight_sigma_deg"),
    "gnss_raw": GNSS_RAW_KEYS,
}


def _either(sec, a, b):
    sec.either(a, b)


def _block(sec):
    _either(sec, "side_overlap_percent", "strip_spacing_m")
    _either(sec, "forward_overlap_percent", "exposure_interval_s")
    spacing = sec.number("strip_spacing_m", 0.0, "m", lo=0.0, lo_open=True) \
        if sec.has("strip_spacing_m") else None
    interval = sec.number("exposure_interval_s", 0.0, "s", lo=0.0, lo_open=True) \
        if sec.has("exposure_interval_s") else None
    side = None if spacing is not None else sec.number(
        "side_overlap_percent", 30.0, "percent in [0, 100)", lo=0.0) / 100.0
    fwd = None if interval is not None else sec.number(
        "forward_overlap_percent", 60.0, "percent in [0, 100)", lo=0.0) / 100.0
    for key, v in (("side_overlap_percent", side), ("forward_overlap_percent", fwd)):
        if v is not None and v >= 1.0:
            raise sec.error(key, f"must be below 100, got {100 * v:g}", "percent in [0, 100)")
    return Block(
        origin_lat=sec.number("origin_lat_deg", REQUIRED, "deg in [-85, 85]", -85.0, 85.0) * D2R,
        origin_lon=sec.number("origin_lon_deg", REQUIRED, "deg in [-180, 360]", -180.0,
                              360.0) * D2R,
        origin_h=sec.number("origin_h_m", 0.0, "m (ellipsoidal)", -500.0, 9000.0),
        strip_azimuth=sec.number("strip_azimuth_deg", 0.0, "deg", -360.0, 360.0) * D2R,
        strip_length=sec.number("strip_length_m", 3000.0, "m > 0", 0.0, 200e3, lo_open=True),
        n_strips=sec.number("n_strips", 4, "integer >= 1", 1, 1000, integer=True),
        side_overlap=side, strip_spacing=spacing, forward_overlap=fwd,
        exposure_interval=interval)


def _flight(sec):
    _either(sec, "turn_rate_deg_s", "bank_deg")
    speed = sec.number("ground_speed_mps", 60.0, "m/s > 5", 5.0, 400.0)
    max_bank = sec.number("max_bank_deg", 30.0, "deg in (0, 60]", 0.0, 60.0,
                          lo_open=True) * D2R
    if sec.has("bank_deg"):
        bank = sec.number("bank_deg", 0.0, "deg in (0, 60]", 0.0, 60.0, lo_open=True) * D2R
        rate = G_TURN * math.tan(bank) / speed
    else:
        rate = sec.number("turn_rate_deg_s", 3.0, "deg/s in (0, 10]", 0.0, 10.0,
                          lo_open=True) * D2R
    start = sec.choice("start", "air", ("ground", "air"))
    return Flight(
        height_agl=sec.number("height_agl_m", 1000.0, "m > 0", 0.0, 20000.0, lo_open=True),
        ground_speed=speed, turn_rate=rate, max_bank=max_bank,
        climb_rate=sec.number("climb_rate_mps", 5.0, "m/s >= 0", 0.0, 30.0),
        start=start,
        stationary=sec.number("stationary_s", 60.0, "s >= 0", 0.0, 86400.0),
        run_in=sec.number("run_in_m", 1000.0, "m >= 0", 0.0, 100e3),
        takeoff_accel=sec.number("takeoff_accel_mps2", 2.0, "m/s^2 > 0", 0.0, 20.0,
                                 lo_open=True),
        gps_week=sec.number("gps_week", 2300, "integer >= 0", 0, 10000, integer=True),
        start_time=sec.number("start_time_s", 100000.0, "GPS s of week in [0, 604800)",
                              0.0, 604800.0))


def _wind(sec):
    return Wind(speed=sec.number("speed_mps", 0.0, "m/s >= 0", 0.0, 100.0),
                from_azimuth=sec.number("from_deg", 0.0, "deg", -360.0, 360.0) * D2R)


def _turbulence(sec):
    out = {}
    for name, unit, scale in (("roll", "deg", D2R), ("pitch", "deg", D2R),
                              ("yaw", "deg", D2R), ("heave", "m", 1.0)):
        amp = sec.numbers(f"{name}_amp_{unit}", (), unit, lo=0.0)
        freq = sec.numbers(f"{name}_freq_hz", (), "Hz")
        if len(amp) != len(freq):
            raise sec.error(f"{name}_freq_hz", f"needs one frequency per amplitude of "
                            f"{name}_amp_{unit} ({len(amp)}), got {len(freq)}", "Hz")
        if any(not 0.0 < f <= 20.0 for f in freq):
            raise sec.error(f"{name}_freq_hz", f"frequencies must be in (0, 20], got {freq}",
                            "Hz")
        out[f"{name}_amp"] = tuple(a * scale for a in amp)
        out[f"{name}_freq"] = freq
    return Turbulence(**out, seed=sec.number("seed", 0, "integer >= 0", 0, integer=True))


def _mount(sec):
    return Mount(
        enabled=sec.boolean("enabled", True),
        level_limit=sec.number("level_limit_deg", 5.0, "deg in (0, 45]", 0.0, 45.0,
                               lo_open=True) * D2R,
        azimuth_limit=sec.number("azimuth_limit_deg", 30.0, "deg in (0, 90]", 0.0, 90.0,
                                 lo_open=True) * D2R,
        servo_lag=sec.number("servo_lag_s", 0.1, "s in [0, 5]", 0.0, 5.0),
        log_rate_hz=sec.number("log_rate_hz", 50.0, "Hz > 0", 0.0, 10000.0, lo_open=True),
        l_bp=sec.numbers("imu_to_platform_centre_b_m", (0.0, 0.0, 0.0), "m", length=3,
                         bound=MAX_LEVER_ARM_M),
        l_ap=sec.numbers("platform_centre_to_antenna_a_m", (0.0, 0.0, -1.5), "m", length=3,
                         bound=MAX_LEVER_ARM_M))


def _imu(sec):
    grade = sec.choice("grade", "tactical", tuple(PRESETS))
    rate = sec.number("rate_hz", 200.0, "Hz in [1, 5000]", 1.0, 5000.0)
    over = {}
    for key in MANIFEST_KEYS:
        if not sec.has(key):
            continue
        if key == "corr_time_h":
            over[key] = sec.number(key, 1.0, "h > 0", 0.0, lo_open=True)
            continue
        v = sec.table[key]
        per_axis = isinstance(v, list)
        vals = sec.numbers(key, (), MANIFEST_KEYS[key], length=3 if per_axis else None)
        if key.endswith(("_sqrth", "_instability_dph", "_instability_mgal", "_quantization_rad",
                         "_quantization_mps")) and min(vals) < 0:
            raise sec.error(key, f"must be >= 0, got {v!r}", MANIFEST_KEYS[key])
        over[key] = vals if per_axis else vals[0]
    return ImuSettings(grade=grade, rate_hz=rate, overrides=MappingProxyType(over))


def _gnss(sec):
    outages = []
    raw = sec.raw("outages", [])
    if not isinstance(raw, list) or not all(
            isinstance(o, list) and len(o) == 2 and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) for x in o)
            and o[0] >= 0 and o[1] > 0 for o in raw):
        raise sec.error("outages", f"expected [[start_s, duration_s], ...] with start >= 0 "
                        f"and duration > 0, got {raw!r}", "s")
    outages = tuple((float(a), float(b)) for a, b in raw)
    sigma = sec.numbers("sigma_ned_m", (0.02, 0.02, 0.04), "m", lo=0.0, bound=MAX_SIGMA_M)
    if len(sigma) == 1:
        sigma = sigma * 3
    if len(sigma) != 3:
        raise sec.error("sigma_ned_m", f"expected 1 or 3 numbers, got {len(sigma)}", "m")
    return GnssSettings(
        rate_hz=sec.number("rate_hz", 1.0, "Hz in (0, 100]", 0.0, 100.0, lo_open=True),
        sigma_ned_m=sigma, velocity=sec.boolean("velocity", False),
        sigma_vel_mps=sec.number("sigma_vel_mps", 0.01, "m/s >= 0", 0.0),
        outages=outages)


def _camera(sec):
    axes = sec.raw("axes", [list(r) for r in NADIR_AXES])
    a = np.asarray(axes, dtype=float) if isinstance(axes, list) else np.zeros(0)
    if a.shape != (3, 3) or not np.allclose(a @ a.T, np.eye(3), atol=1e-9) \
            or np.linalg.det(a) < 0:
        raise sec.error("axes", f"expected a 3x3 rotation matrix (rows), got {axes!r}",
                        "rows of C_bc")
    w = sec.number("width_px", 8000, "integer px > 0", 1, integer=True)
    h = sec.number("height_px", 6000, "integer px > 0", 1, integer=True)
    return CameraSettings(
        focal_length_mm=sec.number("focal_length_mm", 100.0, "mm > 0", 0.0, lo_open=True),
        pixel_size_mm=sec.number("pixel_size_mm", 0.01, "mm > 0", 0.0, lo_open=True),
        width_px=w, height_px=h,
        principal_point_px=sec.numbers("principal_point_px", ((w - 1) / 2, (h - 1) / 2),
                                       "px", length=2),
        radial_k=sec.numbers("radial_k", (0.0, 0.0, 0.0), "mm^-2, mm^-4, mm^-6", length=3),
        tangential_p=sec.numbers("tangential_p", (0.0, 0.0), "mm^-1", length=2),
        axes=tuple(tuple(float(x) for x in row) for row in a),
        lever_arm_m=sec.numbers("lever_arm_m", (0.0, 0.0, 0.0), "m", length=3,
                                bound=MAX_LEVER_ARM_M),
        boresight_deg=sec.numbers("boresight_deg", (0.0, 0.0, 0.0), "deg", length=3))


def _terrain(sec):
    return Terrain(relief_m=sec.number("relief_m", 0.0, "m >= 0", 0.0, 5000.0),
                   wavelength_m=sec.number("wavelength_m", 2000.0, "m > 0", 0.0, lo_open=True),
                   seed_offset=sec.number("seed_offset", 0, "integer", integer=True))


def _tie_points(sec):
    return TiePoints(per_image=sec.number("per_image", 100, "integer >= 0", 0, integer=True),
                     sigma_px=sec.number("sigma_px", 0.5, "px >= 0", 0.0))


def _scanner(sec):
    """``[scanner]`` (the table is optional: absent, the plan has no scanner)."""
    d = ScannerSettings()
    fov = sec.number("field_of_view_deg", 60.0, "deg in (0, 150]", 0.0, 150.0, lo_open=True)
    return ScannerSettings(
        model=sec.choice("model", d.model, ("polygon", "oscillating")),
        pulse_rate_hz=sec.number("pulse_rate_hz", d.pulse_rate_hz, "Hz in (0, 1e6]", 0.0,
                                 1e6, lo_open=True),
        scan_rate_hz=sec.number("scan_rate_hz", d.scan_rate_hz, "Hz in (0, 1000]", 0.0,
                                1000.0, lo_open=True),
        field_of_view=fov * D2R,
        forward_tilt=sec.number("forward_tilt_deg", 0.0, "deg in [-30, 30]", -30.0,
                                30.0) * D2R,
        range_sigma_m=sec.number("range_sigma_m", d.range_sigma_m, "m in [0, 10]", 0.0, 10.0),
        scan_angle_sigma=sec.number("scan_angle_sigma_deg", 0.001, "deg in [0, 1]", 0.0,
                                    1.0) * D2R,
        lever_arm_m=sec.numbers("lever_arm_m", (0.0, 0.0, 0.0), "m, body FRD", length=3,
                                bound=MAX_LEVER_ARM_M),
        boresight=tuple(v * D2R for v in sec.numbers(
            "boresight_deg", (0.0, 0.0, 0.0), "deg (rx, ry, rz)", length=3, bound=5.0)),
        lever_arm_sigma_m=sec.numbers("lever_arm_sigma_m", (0.0, 0.0, 0.0), "m >= 0",
                                      length=3, lo=0.0, bound=MAX_LEVER_ARM_M),
        boresight_sigma=tuple(v * D2R for v in sec.numbers(
            "boresight_sigma_deg", (0.0, 0.0, 0.0), "deg >= 0", length=3, lo=0.0,
            bound=5.0)))


#: Sections whose absence means "none" rather than their defaults.
OPTIONAL_SECTIONS = ("scanner",)

_SECTIONS = {"block": _block, "flight": _flight, "wind": _wind, "turbulence": _turbulence,
             "mount": _mount, "imu": _imu, "gnss": _gnss, "camera": _camera,
             "terrain": _terrain, "tie_points": _tie_points, "scanner": _scanner}


def parse_plan(data, source="<string>"):
    """Validate a flight plan given as a dict (the parsed TOML); the dict is not modified.

    Parameters
    ----------
    data : dict
        Sections as in the module docstring.
    source : str
        Name used in error messages (the file path).

    Returns
    -------
    FlightPlan

    Raises
    ------
    InputError
        ``"{source}: [section] key: message (expected unit)"``.
    """
    if not isinstance(data, dict):
        raise InputError("expected a table of sections", path=source)
    check_keys(data, PLAN_KEYS, source)
    if "block" not in data:
        raise InputError("[block]: missing section (origin_lat_deg, origin_lon_deg, ...)",
                         path=source)
    parts = {}
    for name, parse in _SECTIONS.items():
        if name in OPTIONAL_SECTIONS and name not in data:
            parts[name] = None
            continue
        sec = Table(data.get(name), name, source, known=PLAN_KEYS[name], sections=PLAN_KEYS)
        parts[name] = parse(sec)
        sec.finish()
    # optional: raw GPS observations (rover.obs); read (and checked) in any case
    sec = Table(data.get("gnss_raw"), "gnss_raw", source, known=GNSS_RAW_KEYS,
                sections=PLAN_KEYS)
    raw = parse_gnss_raw(sec, source)
    sec.finish()
    if "gnss_raw" in data:
        parts["gnss_raw"] = raw
    plan = FlightPlan(**parts, source=str(source))
    check_feasible(plan, data)
    return plan


def load_plan(path):
    """Read and validate a TOML flight plan (see :func:`parse_plan`)."""
    data = read_toml(path, "a TOML flight plan")
    return parse_plan(data, source=str(path))

