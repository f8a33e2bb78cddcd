"""The sections of a flight plan as frozen dataclasses (SI units inside) and the derived
quantities of the photo block (footprints, exposure interval, strip spacing).

The file format, its geometry and its feasibility rules are described in
:mod:`ins.simulate.plan_read`, which reads it.
"""
import math
from dataclasses import dataclass, field
from types import MappingProxyType

__all__ = ["FlightPlan", "Block", "Flight", "Wind", "Turbulence", "Mount", "ImuSettings",
           "GnssSettings", "CameraSettings", "Terrain", "TiePoints", "ScannerSettings", "G_TURN", "MOUNT_KNEE",
           "NADIR_AXES"]

D2R = math.pi / 180.0
#: Gravity used to relate bank and turn rate of a coordinated turn, m/s^2.
G_TURN = 9.80665
#: The mount's soft limit is the identity up to this fraction of each limit (then a
#: tanh knee); on the strips the mount must stay below it (it follows exactly there).
MOUNT_KNEE = 0.8
#: Nominal camera axes (rows of ``C_bc``): nadir, image x along the body x axis.
NADIR_AXES = ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0))


@dataclass(frozen=True)
class Block:
    """Photo block: origin (lat, lon rad; ground height m), strip azimuth (rad), strips."""
    origin_lat: float
    origin_lon: float
    origin_h: float
    strip_azimuth: float
    strip_length: float
    n_strips: int
    side_overlap: float | None          # fraction, or None when strip_spacing is given
    strip_spacing: float | None         # m
    forward_overlap: float | None       # fraction
    exposure_interval: float | None     # s


@dataclass(frozen=True)
class Flight:
    """Flight parameters (m, m/s, rad/s, s)."""
    height_agl: float
    ground_speed: float
    turn_rate: float                    # rad/s of the coordinated turns
    max_bank: float                     # rad, largest bank the aircraft may fly
    climb_rate: float                   # m/s (0: no climb; start in the air at height)
    start: str                          # "ground" or "air"
    stationary: float                   # s
    run_in: float                       # m
    takeoff_accel: float                # m/s^2, peak acceleration of the ground roll
    gps_week: int
    start_time: float                   # GPS s of week

    @property
    def bank(self):
        """Bank angle of the coordinated turns, rad: ``atan(V * turn_rate / g)``."""
        return math.atan(self.ground_speed * self.turn_rate / G_TURN)


@dataclass(frozen=True)
class Wind:
    """Constant wind: speed (m/s), direction it blows FROM (rad, clockwise from north)."""
    speed: float = 0.0
    from_azimuth: float = 0.0

    @property
    def w_n(self):
        """Wind velocity (toward), north and east components, m/s."""
        return (-self.speed * math.cos(self.from_azimuth),
                -self.speed * math.sin(self.from_azimuth))


@dataclass(frozen=True)
class Turbulence:
    """Sums of sinusoids: amplitudes (rad, m) and frequencies (Hz); phases from ``seed``."""
    roll_amp: tuple = ()
    roll_freq: tuple = ()
    pitch_amp: tuple = ()
    pitch_freq: tuple = ()
    yaw_amp: tuple = ()
    yaw_freq: tuple = ()
    heave_amp: tuple = ()
    heave_freq: tuple = ()
    seed: int = 0


@dataclass(frozen=True)
class Mount:
    """Stabilized mount: limits (rad), servo lag (s), log rate (Hz), lever arms (m)."""
    enabled: bool = True
    level_limit: float = 5.0 * D2R
    azimuth_limit: float = 30.0 * D2R
    servo_lag: float = 0.1
    log_rate_hz: float = 50.0
    l_bp: tuple = (0.0, 0.0, 0.0)       # IMU to platform centre, b, m
    l_ap: tuple = (0.0, 0.0, -1.5)      # platform centre to antenna, a, m


@dataclass(frozen=True)
class ImuSettings:
    """IMU grade, output rate and per-item overrides (manifest key names and units)."""
    grade: str = "tactical"
    rate_hz: float = 200.0
    overrides: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))


@dataclass(frozen=True)
class GnssSettings:
    """GNSS antenna log settings."""
    rate_hz: float = 1.0
    sigma_ned_m: tuple = (0.02, 0.02, 0.04)   # m
    velocity: bool = False
    sigma_vel_mps: float = 0.01               # m/s
    outages: tuple = ()                       # ((start s from flight start, duration s), ...)


@dataclass(frozen=True)
class CameraSettings:
    """Frame camera (mm, px) and its mounting on the platform (see docs/interfaces.md)."""
    focal_length_mm: float = 100.0
    pixel_size_mm: float = 0.01
    width_px: int = 8000
    height_px: int = 6000
    principal_point_px: tuple = (3999.5, 2999.5)
    radial_k: tuple = (0.0, 0.0, 0.0)
    tangential_p: tuple = (0.0, 0.0)
    axes: tuple = NADIR_AXES
    lever_arm_m: tuple = (0.0, 0.0, 0.0)
    boresight_deg: tuple = (0.0, 0.0, 0.0)

    @property
    def width_along_track(self):
        """True when the image x axis (columns, width) is along track (body x)."""
        return abs(self.axes[0][0]) >= abs(self.axes[0][1])


@dataclass(frozen=True)
class Terrain:
    relief_m: float = 0.0
    wavelength_m: float = 2000.0
    seed_offset: int = 0


@dataclass(frozen=True)
class TiePoints:
    per_image: int = 100
    sigma_px: float = 0.5


@dataclass(frozen=True)
class ScannerSettings:
    """A simulated laser line scanner rigid on the IMU (``[scanner]``; SI inside).

    The pulses, scan pattern and noise of :func:`ins.simulate.lidar.simulate_returns`;
    the mounting as in the scanner file (:mod:`ins.lidar.scanner`): ``lever_arm_m``
    from the IMU centre to the scanner origin in ``b`` (m), ``C_bs = Rx Ry Rz`` of the
    TRUE ``boresight`` (rad) with the identity axes.  The scanner file given to the user
    has the boresight zero (unknown) and the sigmas ``lever_arm_sigma_m``,
    ``boresight_sigma`` (rad).
    """
    model: str = "polygon"                       # "polygon" | "oscillating"
    pulse_rate_hz: float = 2000.0
    scan_rate_hz: float = 20.0
    field_of_view: float = 60.0 * D2R            # rad, full width
    forward_tilt: float = 0.0                    # rad
    range_sigma_m: float = 0.02
    scan_angle_sigma: float = 0.001 * D2R        # rad
    lever_arm_m: tuple = (0.0, 0.0, 0.0)
    boresight: tuple = (0.0, 0.0, 0.0)           # rad (rx, ry, rz), the truth
    lever_arm_sigma_m: tuple = (0.0, 0.0, 0.0)
    boresight_sigma: tuple = (0.0, 0.0, 0.0)     # rad, stated in the user's scanner file


@dataclass(frozen=True)
class FlightPlan:
    """A validated flight plan (SI units inside; see the module docstring)."""
    block: Block
    flight: Flight
    wind: Wind
    turbulence: Turbulence
    mount: Mount
    imu: ImuSettings
    gnss: GnssSettings
    camera: CameraSettings
    terrain: Terrain
    tie_points: TiePoints
    scanner: ScannerSettings | None = None      # no [scanner] table: no LiDAR products
    source: str = "<string>"
    #: ``[gnss_raw]``: :class:`ins.simulate.gnss_raw.RawSettings`, or None (no raw GPS).
    gnss_raw: object = None

    def _footprint(self, along):
        c = self.camera
        n_px = c.width_px if c.width_along_track == along else c.height_px
        return self.flight.height_agl * n_px * c.pixel_size_mm / c.focal_length_mm

    @property
    def footprint_along_m(self):
        """Ground footprint of an image along track, m (flat terrain at block height)."""
        return self._footprint(True)

    @property
    def footprint_across_m(self):
        """Ground footprint of an image across track, m."""
        return self._footprint(False)

    @property
    def exposure_interval_s(self):
        """Time between exposures on a strip, s."""
        b = self.block
        if b.exposure_interval is not None:
            return b.exposure_interval
        return (1.0 - b.forward_overlap) * self.footprint_along_m / self.flight.ground_speed

    @property
    def strip_spacing_m(self):
        """Distance between neighbouring strips, m."""
        b = self.block
        if b.strip_spacing is not None:
            return b.strip_spacing
        return (1.0 - b.side_overlap) * self.footprint_across_m

    @property
    def flying_height_m(self):
        """Ellipsoidal height of the photo flight, m."""
        return self.block.origin_h + self.flight.height_agl

