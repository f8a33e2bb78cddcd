"""IMU sensor-error model: biases, Gauss-Markov bias instability, random walks, scale
factors, non-orthogonality, quantization; presets by grade; reproducible by seed.

Model, per axis ``i`` of the gyro (``x`` = angular rate, rad/s) and of the accelerometer
(``x`` = specific force, m/s^2), over the interval ``(t[k-1], t[k]]`` of length ``dt``::

    y_k = (I + diag(scale) + N) x_k  +  (bias + g_k) dt  +  rw * sqrt(dt) * w_k

with ``x_k`` the error-free increment, ``w_k`` unit white Gaussian noise, ``rw`` the
angle/velocity random walk (rad/sqrt(s), m/s/sqrt(s)) and ``g_k`` a first-order
Gauss-Markov process (steady-state standard deviation ``bias_instability``, correlation
time ``corr_time``; exact discrete recursion ``g_k = e^{-dt/T} g_{k-1} +
sigma sqrt(1 - e^{-2 dt/T}) w'_k``; ``g_0`` drawn from the steady state).  ``N`` is the
symmetric non-orthogonality matrix ``[[0, m_z, m_y], [m_z, 0, m_x], [m_y, m_x, 0]]``
(rad): the sensor axes y and z are each tilted toward the other by ``m_x``, and so on.
Quantization ``q`` (rad, m/s) is applied to the running sum, so the residue carries over
to the next increment (as in a real IMU's pulse counter): ``Y_k = q round(S_k / q)``,
``y_k = Y_k - Y_{k-1}`` with ``S_k`` the cumulative sum of the unquantized increments.

At the edges (files, plan, manifest) the units are those of the KF-GINS configuration:
deg/sqrt(h), m/s/sqrt(h), deg/h, mGal (1e-5 m/s^2), ppm, arcsec, h, rad, m/s.  The
bias-instability value is the Gauss-Markov sigma (KF-GINS ``gyrbias_std``); its Allan
deviation peaks at about ``0.437 sigma`` near ``tau = 1.89 T``.
"""
import math
from dataclasses import dataclass, fields

import numpy as np

from ins.nav.imu import DPH, MGAL, PPM, ImuLog

__all__ = ["ImuErrorModel", "PRESETS", "MANIFEST_KEYS", "apply_errors"]

ARCSEC = math.pi / 180.0 / 3600.0
#: rad/sqrt(s) per deg/sqrt(h).
DEG_SQRTH = math.pi / 180.0 / 60.0
#: m/s/sqrt(s) per m/s/sqrt(h).
MPS_SQRTH = 1.0 / 60.0

#: Manifest key -> unit text.
MANIFEST_KEYS = {
    "arw_deg_sqrth": "deg/sqrt(h)", "vrw_mps_sqrth": "m/s/sqrt(h)",
    "gyro_bias_dph": "deg/h", "accel_bias_mgal": "mGal",
    "gyro_bias_instability_dph": "deg/h", "accel_bias_instability_mgal": "mGal",
    "corr_time_h": "h", "gyro_scale_ppm": "ppm", "accel_scale_ppm": "ppm",
    "gyro_misalignment_arcsec": "arcsec", "accel_misalignment_arcsec": "arcsec",
    "gyro_quantization_rad": "rad", "accel_quantization_mps": "m/s",
}
# manifest key -> (field, SI per unit)
_FIELDS = {
    "arw_deg_sqrth": ("arw", DEG_SQRTH), "vrw_mps_sqrth": ("vrw", MPS_SQRTH),
    "gyro_bias_dph": ("gyro_bias", DPH), "accel_bias_mgal": ("accel_bias", MGAL),
    "gyro_bias_instability_dph": ("gyro_bias_instability", DPH),
    "accel_bias_instability_mgal": ("accel_bias_instability", MGAL),
    "corr_time_h": ("corr_time", 3600.0),
    "gyro_scale_ppm": ("gyro_scale", PPM), "accel_scale_ppm": ("accel_scale", PPM),
    "gyro_misalignment_arcsec": ("gyro_misalignment", ARCSEC),
    "accel_misalignment_arcsec": ("accel_misalignment", ARCSEC),
    "gyro_quantization_rad": ("gyro_quantization", 1.0),
    "accel_quantization_mps": ("accel_quantization", 1.0),
}

#: Error values of the three grades, in manifest units (typical datasheet classes):
#: ``navigation`` - ring-laser/fibre-optic navigation grade (Honeywell HG9900, iXblue
#: class: ARW ~0.002 deg/sqrt(h), bias ~0.003-0.005 deg/h, 25 ug accelerometers);
#: ``tactical`` - tactical grade (Honeywell HG1700, KVH 1750 class: ARW ~0.1 deg/sqrt(h),
#: bias ~1 deg/h, 1 mg); ``mems`` - industrial MEMS (ADIS16488, Xsens MTi class:
#: ARW ~0.3 deg/sqrt(h), in-run stability ~5 deg/h, bias ~10 mg); ``consumer`` - phone
#: and automotive MEMS (Bosch BMI160/BMI270, TDK ICM-20602/42688, ST LSM6DS3 class:
#: gyro noise 0.004-0.008 deg/s/sqrt(Hz) = 0.25-0.5 deg/sqrt(h), zero-rate offset up to
#: +-1 deg/s untrimmed (0.17-0.6 deg/s seen after power-up), accelerometer noise
#: 70-180 ug/sqrt(Hz) = 0.04-0.1 m/s/sqrt(h), offset up to +-30 mg (14 mg seen), 0.5-1 %
#: sensitivity error, ~0.5 deg cross-axis).  Biases are per-axis constants with
#: alternating signs so that no axis is error-free.
PRESETS = {
    "navigation": {
        "arw_deg_sqrth": 0.002, "vrw_mps_sqrth": 0.002,
        "gyro_bias_dph": [0.005, -0.004, 0.003], "accel_bias_mgal": [25.0, -20.0, 30.0],
        "gyro_bias_instability_dph": 0.003, "accel_bias_instability_mgal": 10.0,
        "corr_time_h": 1.0, "gyro_scale_ppm": [5.0, -5.0, 5.0],
        "accel_scale_ppm": [50.0, -50.0, 50.0], "gyro_misalignment_arcsec": [5.0, -5.0, 5.0],
        "accel_misalignment_arcsec": [10.0, -10.0, 10.0], "gyro_quantization_rad": 1e-7,
        "accel_quantization_mps": 1e-5,
    },
    "tactical": {
        "arw_deg_sqrth": 0.12, "vrw_mps_sqrth": 0.05,
        "gyro_bias_dph": [1.0, -0.8, 0.6], "accel_bias_mgal": [1000.0, -800.0, 600.0],
        "gyro_bias_instability_dph": 0.5, "accel_bias_instability_mgal": 100.0,
        "corr_time_h": 1.0, "gyro_scale_ppm": [150.0, -150.0, 150.0],
        "accel_scale_ppm": [300.0, -300.0, 300.0],
        "gyro_misalignment_arcsec": [50.0, -50.0, 50.0],
        "accel_misalignment_arcsec": [100.0, -100.0, 100.0], "gyro_quantization_rad": 1e-6,
        "accel_quantization_mps": 1e-4,
    },
    "mems": {
        "arw_deg_sqrth": 0.3, "vrw_mps_sqrth": 0.06,
        "gyro_bias_dph": [10.0, -8.0, 6.0], "accel_bias_mgal": [10000.0, -8000.0, 6000.0],
        "gyro_bias_instability_dph": 5.0, "accel_bias_instability_mgal": 100.0,
        "corr_time_h": 0.5, "gyro_scale_ppm": [1000.0, -1000.0, 1000.0],
        "accel_scale_ppm": [1000.0, -1000.0, 1000.0],
        "gyro_misalignment_arcsec": [180.0, -180.0, 180.0],
        "accel_misalignment_arcsec": [180.0, -180.0, 180.0], "gyro_quantization_rad": 0.0,
        "accel_quantization_mps": 0.0,
    },
    "consumer": {
        "arw_deg_sqrth": 0.4, "vrw_mps_sqrth": 0.1,
        "gyro_bias_dph": [400.0, -300.0, -612.0],
        "accel_bias_mgal": [14000.0, -9000.0, 12000.0],
        "gyro_bias_instability_dph": 20.0, "accel_bias_instability_mgal": 300.0,
        "corr_time_h": 0.2, "gyro_scale_ppm": [5000.0, -5000.0, 5000.0],
        "accel_scale_ppm": [5000.0, -5000.0, 5000.0],
        "gyro_misalignment_arcsec": [1800.0, -1800.0, 1800.0],
        "accel_misalignment_arcsec": [1800.0, -1800.0, 1800.0], "gyro_quantization_rad": 0.0,
        "accel_quantization_mps": 0.0,
    },
}


def _vec3(value, name):
    a = np.broadcast_to(np.asarray(value, dtype=float), (3,)).copy()
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class ImuErrorModel:
    """IMU errors in SI units; every item a per-axis array of shape (3,) (x, y, z of b).

    Attributes: ``arw`` rad/sqrt(s), ``vrw`` m/s/sqrt(s), ``gyro_bias`` rad/s,
    ``accel_bias`` m/s^2, ``gyro_bias_instability`` rad/s, ``accel_bias_instability``
    m/s^2 (Gauss-Markov sigmas), ``corr_time`` s (scalar), ``gyro_scale``,
    ``accel_scale`` (fractions), ``gyro_misalignment``, ``accel_misalignment`` rad
    (non-orthogonality, see the module docstring), ``gyro_quantization`` rad,
    ``accel_quantization`` m/s (0: none).
    """
    arw: np.ndarray = 0.0
    vrw: np.ndarray = 0.0
    gyro_bias: np.ndarray = 0.0
    accel_bias: np.ndarray = 0.0
    gyro_bias_instability: np.ndarray = 0.0
    accel_bias_instability: np.ndarray = 0.0
    corr_time: float = 3600.0
    gyro_scale: np.ndarray = 0.0
    accel_scale: np.ndarray = 0.0
    gyro_misalignment: np.ndarray = 0.0
    accel_misalignment: np.ndarray = 0.0
    gyro_quantization: float = 0.0
    accel_quantization: float = 0.0

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in ("corr_time", "gyro_quantization", "accel_quantization"):
                v = float(np.max(v))
                if not math.isfinite(v) or v < 0 or (f.name == "corr_time" and v <= 0):
                    raise ValueError(f"{f.name} must be a finite number "
                                     f"{'> 0' if f.name == 'corr_time' else '>= 0'}, got {v}")
            else:
                v = _vec3(v, f.name)
                if f.name in ("arw", "vrw") or f.name.endswith("instability"):
                    if np.any(v < 0):
                        raise ValueError(f"{f.name} must be >= 0, got {v}")
            object.__setattr__(self, f.name, v)

    @classmethod
    def from_units(cls, **kwargs):
        """Model from manifest keys and units (``arw_deg_sqrth=0.1, ...``); a scalar
        applies to the three axes, a list of 3 gives the axes x, y, z."""
        si = {}
        for key, value in kwargs.items():
            if key not in _FIELDS:
                raise ValueError(f"unknown IMU error key {key!r} (known: "
                                 f"{', '.join(MANIFEST_KEYS)})")
            name, scale = _FIELDS[key]
            si[name] = np.asarray(value, dtype=float) * scale
        return cls(**si)

    @classmethod
    def preset(cls, grade, **overrides):
        """The model of a grade of :data:`PRESETS`, with manifest-unit overrides."""
        if grade not in PRESETS:
            raise ValueError(f"unknown IMU grade {grade!r} (known: {', '.join(PRESETS)})")
        return cls.from_units(**{**PRESETS[grade], **overrides})

    def to_units(self):
        """The manifest dict (keys of :data:`MANIFEST_KEYS`, lists of 3 per-axis values)."""
        out = {}
        for key, (name, scale) in _FIELDS.items():
            v = np.asarray(getattr(self, name)) / scale
            out[key] = float(v) if v.ndim == 0 else [float(x) for x in v]
        return out


def _nonorthogonality(m):
    return np.array([[0.0, m[2], m[1]], [m[2], 0.0, m[0]], [m[1], m[0], 0.0]])


#: Rows per chunk in :func:`apply_errors`.
CHUNK_ROWS = 1 << 16


def apply_errors(log, model, seed, chunk_rows=CHUNK_ROWS):
    """Corrupt error-free increments with the errors of ``model`` (a new log).

    Parameters
    ----------
    log : ins.nav.imu.ImuLog
        Error-free increments (rad, m/s), body FRD, stamped at the end of their interval;
        row 0's interval is ``log.dt[0]`` (the nominal interval).
    model : ImuErrorModel
    seed : int
        Seed of the random streams (``numpy.random.SeedSequence``): the same seed gives
        the same numbers, whatever ``chunk_rows``.

    Returns
    -------
    ins.nav.imu.ImuLog
    """
    n = len(log)
    dt = np.asarray(log.dt)
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(4)]
    out_th = np.empty((n, 3))
    out_dv = np.empty((n, 3))
    sensors = [
        (log.dtheta_b, out_th, model.gyro_scale, model.gyro_misalignment, model.gyro_bias,
         model.gyro_bias_instability, model.arw, model.gyro_quantization, streams[0:2]),
        (log.dvel_b, out_dv, model.accel_scale, model.accel_misalignment, model.accel_bias,
         model.accel_bias_instability, model.vrw, model.accel_quantization, streams[2:4]),
    ]
    # the compiled loops: loaded by the simulation, not by importers of the presets
    from ins.simulate import _kernels
    T = model.corr_time
    for x, out, scale, mis, bias, bi, rw, q, (rng_w, rng_g) in sensors:
        M = np.eye(3) + np.diag(scale) + _nonorthogonality(mis)
        gm = bi * rng_g.standard_normal(3)              # steady state at t[0]
        carry = np.zeros(3)                             # quantization residue
        for k0 in range(0, n, chunk_rows):
            k1 = min(k0 + chunk_rows, n)
            d = dt[k0:k1, None]
            y = x[k0:k1] @ M.T + bias * d + rw * np.sqrt(d) * rng_w.standard_normal((k1 - k0, 3))
            if np.any(bi > 0):
                white = rng_g.standard_normal((k1 - k0, 3))
                gm = _kernels.gauss_markov_add(y, d[:, 0], white, bi, T, gm)
            if q > 0:
                carry = _kernels.quantize(y, q, carry)
            out[k0:k1] = y
    return ImuLog.adopt(log.time.copy(), out_th, out_dv)
