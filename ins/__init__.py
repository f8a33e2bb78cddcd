"""Strapdown inertial navigation and GNSS/INS post-processing.

Frames (see ``conventions.md``): ``n`` local-level North-East-Down, ``b`` IMU body
forward-right-down, ``e`` ECEF WGS84.  ``C_nb`` takes a vector from ``b`` to ``n``;
quaternions are scalar-last ``[x, y, z, w]``.  SI units inside: rad, m, s, m/s.
Geodetic position is ``(lat, lon, h)`` in rad, rad, m (ellipsoidal height).
IMU logs hold increments ``dtheta_b`` (rad) and ``dvel_b`` (m/s) stamped at the END
of their integration interval.
"""

__version__ = "0.1.0"

from .errors import InputError, InputWarning  # noqa: E402

# The rest is imported on first use (PEP 562): ``import ins.cli`` stays light, so that
# the command-line tools install their Ctrl-C handler before numpy and numba load.
_LAZY = {"ImuLog": "imu", "compensate": "imu", "read_imu": "imu_files",
         "NavState": "mechanization", "iter_mechanize": "mechanization",
         "mechanize": "mechanization",
         "Trajectory": "trajectory", "read_nav": "trajectory", "write_nav": "trajectory"}


def __getattr__(name):
    if name in _LAZY:
        import importlib
        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = ["ImuLog", "InputError", "InputWarning", "NavState", "Trajectory", "compensate",
           "iter_mechanize", "mechanize", "read_imu", "read_nav", "write_nav"]
