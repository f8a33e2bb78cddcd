"""Named processing presets for ``ins process --preset NAME``: default values of the
processing config's keys (``ins.estimation.pipeline.config``) for a class of IMU.

A preset fills only what the config (or the flight folder's manifest) does not give:
the user's own values always win.  Each preset is a table of TOML tables, in the
config's key names and units::

    tactical   a tactical-grade IMU (fibre-optic or good MEMS gyros, ~1 deg/h)
    mems       a consumer / phone MEMS IMU (~100 deg/h, ~5 mg; values that process the
               comma2k19 phone at 104 Hz: tools/comma2k19.py, docs/real-data.md)
    consumer   phone / automotive MEMS (Bosch BMI160/BMI270, TDK ICM-20602/42688, ST
               LSM6DS3 class): datasheet noise 0.004-0.008 deg/s/sqrt(Hz) (ARW up to
               0.5 deg/sqrt(h)) and 70-180 ug/sqrt(Hz) (VRW up to 0.1 m/s/sqrt(h));
               zero-rate offsets up to 1 deg/s and accelerometer offsets up to 30 mg
               (the datasheets' untrimmed limits: a phone's gyro reads 0.1-0.6 deg/s at
               rest), 1 % sensitivity, 0.5 deg cross-axis; those offsets are turn-on
               values, stable in a run: random constants with the datasheets' in-run
               instability (about 20 deg/h, 0.3 mg) on top; zero-velocity updates at rest
    land       mems for a land vehicle: ``[measurements] nhc = true`` (lateral and
               vertical velocity 0 in the VEHICLE axes: give the IMU's mounting as
               ``[vehicle] mounting_rpy_deg`` unless its axes are the vehicle's;
               ``ins vehicle-mounting`` estimates it from a first solution) and
               ``zupt = true`` (zero-velocity updates where the IMU is found at rest)

The values are 1-sigma statistics in KF-GINS's units (deg/sqrt(h), m/s/sqrt(h), deg/h,
mGal, ppm, h).  The non-orthogonality priors of the survey layout follow the grade
through the scale-factor sigmas (1 arcsec per ppm,
:func:`ins.estimation.core.filter_settings.default_misalignment_std_arcsec`): 100 arcsec for
``tactical``; ``mems`` and ``land`` give the datasheets' 0.1 deg (360 arcsec: the rule's
1000 arcsec cost the simulated car's mounting estimate 35 %), ``consumer`` 2000 arcsec.
"""
from dataclasses import replace

import numpy as np

from ins.common.errors import InputError

_MEMS_NOISE = {"arw_deg_sqrth": 0.3, "vrw_mps_sqrth": 0.1, "gyro_bias_std_dph": 100.0,
               "accel_bias_std_mgal": 5000.0, "gyro_scale_std_ppm": 1000.0,
               "accel_scale_std_ppm": 1000.0, "corr_time_h": 1.0}
#: Axis non-orthogonality of industrial MEMS units (ADIS16488: +-0.05 deg axis to axis;
#: Xsens MTi: 0.05 deg): 0.1 deg as the 1-sigma prior.
_MEMS_STATES = {"gyro_misalignment_std_arcsec": 360.0, "accel_misalignment_std_arcsec": 360.0}

#: The presets: name -> {table: {key: value}} in the processing config's names and units.
PRESETS = {
    "tactical": {"imu_noise": {"arw_deg_sqrth": 0.05, "vrw_mps_sqrth": 0.05,
                               "gyro_bias_std_dph": 1.0, "accel_bias_std_mgal": 200.0,
                               "gyro_scale_std_ppm": 100.0, "accel_scale_std_ppm": 100.0,
                               "corr_time_h": 1.0}},
    "mems": {"imu_noise": dict(_MEMS_NOISE), "states": dict(_MEMS_STATES)},
    "consumer": {"imu_noise": {"arw_deg_sqrth": 0.5, "vrw_mps_sqrth": 0.15,
                               "gyro_bias_std_dph": 3600.0, "accel_bias_std_mgal": 30000.0,
                               "gyro_scale_std_ppm": 10000.0, "accel_scale_std_ppm": 10000.0,
                               "corr_time_h": 1.0, "gyro_bias_instability_dph": 20.0,
                               "accel_bias_instability_mgal": 300.0},
                 "states": {"gyro_misalignment_std_arcsec": 2000.0,
                            "accel_misalignment_std_arcsec": 2000.0},
                 "measurements": {"zupt": True}},
    "land": {"imu_noise": dict(_MEMS_NOISE), "states": dict(_MEMS_STATES),
             "measurements": {"nhc": True, "zupt": True}},
}

#: Tables of a preset whose keys go into the ``ProcessConfig`` dictionary of that name
#: (``[measurements]`` -> ``cfg.measurements``, the ``[states]`` priors -> ``cfg.priors``).
_DICT_TABLES = {"measurements": "measurements", "states": "priors"}


def names():
    """The preset names, sorted."""
    return sorted(PRESETS)


def preset(name):
    """A copy of preset ``name`` ({table: {key: value}}).

    Raises
    ------
    InputError
        An unknown name (the known ones listed).
    """
    if name not in PRESETS:
        raise InputError(f"--preset {name!r}: unknown preset; known presets: "
                         f"{', '.join(names())}")
    return {table: dict(keys) for table, keys in PRESETS[name].items()}


def apply_preset(cfg, name, given=None):
    """``cfg`` (an ``ins.estimation.pipeline.config.ProcessConfig``) with the preset's values for
    every key NOT in ``given`` (a parsed config TOML, {table: {key: value}}: the user's
    own values).  A config built from a flight folder's manifest keeps the manifest's
    IMU noise (``cfg.source == "manifest"``).  Returns a new config; ``cfg`` is not
    modified.
    """
    from copy import copy
    values = preset(name)
    given = given or {}
    out = copy(cfg)
    noise = {k: v for k, v in values.get("imu_noise", {}).items()
             if k not in given.get("imu_noise", {})}
    if noise and cfg.source != "manifest":
        out.noise = replace(cfg.noise, **noise)
        out.noise_source = f"preset {name}"
    for table, attr in _DICT_TABLES.items():
        fill = {k: v for k, v in values.get(table, {}).items()
                if k not in given.get(table, {})}
        if fill:
            setattr(out, attr, {**getattr(cfg, attr), **fill})
    return out


def noise_from_rest(imu, t_start, t_end, gyro_bias_b):
    """IMU noise settings from a rest, for a user who gave none.

    The white noise is measured: ARW and VRW from the scatter of the rates and specific
    forces over ``[t_start, t_end]`` (s; ``std * sqrt(dt)``; an idling engine's vibration
    counts as noise, which errs on the safe side).  The bias and scale priors, which a
    rest cannot measure, are those of the preset (:data:`PRESETS`) of the
    smallest grade whose gyro bias sigma is at least a third of the rest's gyro offset
    ``|gyro_bias_b|`` (rad/s; a grade is known by its offsets).

    Returns
    -------
    (ins.estimation.core.error_model.ImuNoise, str)
        The settings and a sentence saying where they came from.
    """
    from dataclasses import replace

    from ins.estimation.core.error_model import ImuNoise
    i0 = int(np.searchsorted(imu.time, t_start - 1e-9))
    i1 = int(np.searchsorted(imu.time, t_end, side="right")) - 1
    dt = np.diff(imu.time[i0:i1 + 1])
    w = imu.dtheta_b[i0 + 1:i1 + 1] / dt[:, None]
    f = imu.dvel_b[i0 + 1:i1 + 1] / dt[:, None]
    root_dt = np.sqrt(np.median(dt))
    arw = float(np.max(np.std(w, axis=0)) * root_dt) * 180.0 / np.pi * 60.0   # deg/sqrt(h)
    vrw = float(np.max(np.std(f, axis=0)) * root_dt) * 60.0                  # m/s/sqrt(h)
    offset_dph = float(np.linalg.norm(gyro_bias_b)) * 180.0 / np.pi * 3600.0
    grades = sorted(("tactical", "mems", "consumer"),
                    key=lambda g: PRESETS[g]["imu_noise"]["gyro_bias_std_dph"])
    grade = next((g for g in grades if PRESETS[g]["imu_noise"]["gyro_bias_std_dph"]
                  >= offset_dph / 3.0), grades[-1])
    noise = replace(ImuNoise(**PRESETS[grade]["imu_noise"]), arw_deg_sqrth=arw,
                    vrw_mps_sqrth=vrw)
    text = (f"IMU noise from the rest (none given): ARW {arw:.3g} deg/sqrt(h) and VRW "
            f"{vrw:.3g} m/s/sqrt(h) measured over {t_end - t_start:.1f} s; bias and scale "
            f"priors of the '{grade}' preset (the rest's gyro offset {offset_dph:.0f} deg/h)")
    return noise, text
