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
from .imu import ImuLog, compensate, read_imu  # noqa: E402
from .mechanization import NavState, iter_mechanize, mechanize  # noqa: E402
from .trajectory import Trajectory, read_nav, write_nav  # noqa: E402

__all__ = ["ImuLog", "InputError", "InputWarning", "NavState", "Trajectory", "compensate",
           "iter_mechanize", "mechanize", "read_imu", "read_nav", "write_nav"]
