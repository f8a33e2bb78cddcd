"""Strapdown inertial navigation and GNSS/INS post-processing.

Frames (see ``conventions.md``): ``n`` local-level North-East-Down, ``b`` IMU body
forward-right-down, ``e`` ECEF WGS84.  ``C_nb`` takes a vector from ``b`` to ``n``;
quaternions are scalar-last ``[x, y, z, w]``.  SI units inside: rad, m, s, m/s.
Geodetic position is ``(lat, lon, h)`` in rad, rad, m (ellipsoidal height).
IMU logs hold increments ``dtheta_b`` (rad) and ``dvel_b`` (m/s) stamped at the END
of their integration interval.
"""

__version__ = "0.1.0"

from ins.common.errors import InputError, InputWarning, QualityError  # noqa: E402
from ins.common.lazy import lazy_api  # noqa: E402

# The public API, imported on first use (PEP 562): ``import ins.cli.main`` stays light, so
# that the command-line tools install their Ctrl-C handler before numpy loads.
_LAZY = {
    # nav: IMU model, mechanization, trajectories
    "ImuLog": "nav.imu", "compensate": "nav.imu",
    "NavState": "nav.mechanization", "iter_mechanize": "nav.mechanization",
    "mechanize": "nav.mechanization",
    "Trajectory": "nav.trajectory", "interpolate_trajectory": "nav.interpolation",
    "compare": "nav.accuracy", "TrajectoryErrors": "nav.accuracy",
    # io: files
    "read_imu": "io.imu_files", "GnssLog": "io.gnss_log", "read_gnss": "io.gnss",
    "read_nav": "io.navfiles", "write_nav": "io.navfiles", "read_trajectory": "io.navfiles",
    "read_sbet": "io.sbet", "write_sbet": "io.sbet",
    # estimation: GNSS/INS post-processing
    "ProcessConfig": "estimation.pipeline.config", "load_config": "estimation.pipeline.config",
    "config_from_manifest": "estimation.pipeline.config",
    "process": "estimation.pipeline.process", "ProcessResult": "estimation.pipeline.process",
    "write_outputs": "estimation.pipeline.outputs", "write_plots": "estimation.pipeline.plots",
    "allan_deviation": "estimation.tools.allan",
}


__getattr__, __dir__ = lazy_api(__name__, _LAZY)

__all__ = ["InputError", "InputWarning", "QualityError"] + sorted(_LAZY)
