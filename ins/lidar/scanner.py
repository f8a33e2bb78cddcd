"""Laser scanner: scan model, mounting on the IMU, noise; the scanner file (TOML).

The scanner frame ``s`` (``docs/interfaces.md``, "LiDAR georeferencing"): x along the
scan axis (forward for a cross-track scanner), y to the right, z down (the ray at scan
angle 0 without tilt).  A return at range ``rho`` (m) and scan angle ``theta`` (rad,
positive to the right of the flight direction, as the LAS scan angle) with the forward
tilt ``tau`` lies at::

    r_s = rho * (sin tau, cos tau sin theta, cos tau cos theta)

for both line-scanner models ("polygon": a rotating polygon, saw-tooth scan;
"oscillating": an oscillating mirror, zig-zag scan; they differ in the time pattern of
the angles, not in the ray of a given angle).  Model "points": the returns are points
already in the scanner frame (x, y, z in m, e.g. from a LAS file of the scanner's own
software).

Mounting, as the camera file's (:mod:`photogrammetry.orientation.camera`): ``axes`` the rows of the
nominal ``C_bs`` (scanner axes to IMU body FRD, default identity), ``boresight_deg``
``(rx, ry, rz)`` the small misalignment, ``C_bs = axes @ Rx(rx) @ Ry(ry) @ Rz(rz)``;
``lever_arm_m`` the IMU centre to the scanner's origin in ``b`` (m).  By default
(``on = "imu"``) the scanner sits rigidly on the IMU (on a stabilized mount: both on
the platform, ``p = b``).  With ``on = "aircraft"`` the IMU is on the stabilized
platform and the scanner on the aircraft: ``axes`` are then the rows of the nominal
``C_as`` (scanner to aircraft FRD), ``lever_arm_m`` the platform centre to the scanner
origin in ``a`` and ``imu_to_platform_centre_b_m`` the IMU to the platform centre in
``b``; with the mount angles ``C_ap(t)`` (:mod:`ins.io.mount`)::

    C_bs(t) = C_ap(t)^T C_as,     l_b(t) = l_bp + C_ap(t)^T l_a

(the varying lever arm of the lever-arm paper, as for the GNSS antenna).

A boresight calibrated from the strips of one flight (``ins strip-check
--scanner-out``) holds that flight's attitude error common to its strips
(:mod:`ins.lidar.strip_check`): its file then has a ``[calibration]`` table
(:class:`BoresightCalibration`) that tells :func:`ins.lidar.georeference.georeference`
how to count the two errors once for the points of that flight.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from ins.common import textfiles
from ins.common.errors import InputError
from ins.common.fileio import atomic_open
from ins.common.limits import MAX_LEVER_ARM_M
from ins.common.tomlschema import REQUIRED, Table, check_keys
from ins.nav.rotation import rot_x, rot_y, rot_z

__all__ = ["Scanner", "BoresightCalibration", "read_scanner", "write_scanner", "SCANNER_KEYS",
           "SCAN_MODELS", "scanner_rays", "boresight_dcm"]

#: Scan models (see the module notes).
SCAN_MODELS = ("polygon", "oscillating", "points")

#: Where the scanner sits: on the IMU (rigid) or on the aircraft (IMU on the platform).
SCANNER_PLACES = ("imu", "aircraft")

#: Sections and keys of a scanner file; any other key is refused.
SCANNER_KEYS = {
    "scanner": ("model", "forward_tilt_deg", "range_sigma_m", "scan_angle_sigma_deg"),
    "mounting": ("on", "axes", "lever_arm_m", "boresight_deg", "lever_arm_sigma_m",
                 "boresight_sigma_deg", "imu_to_platform_centre_b_m"),
    "calibration": ("time_span_s", "boresight_sigma_deg", "attitude_sigma_deg"),
}


def boresight_dcm(boresight_rad):
    """``Rx(rx) @ Ry(ry) @ Rz(rz)`` of a boresight ``(rx, ry, rz)`` (rad), shape (3, 3)."""
    b = np.asarray(boresight_rad, dtype=float)
    if b.shape != (3,):
        raise ValueError(f"boresight_rad must have shape (3,), got {b.shape}")
    return rot_x(b[0]) @ rot_y(b[1]) @ rot_z(b[2])


def _vec3(v, name, unit, nonneg=False):
    try:
        a = np.array(np.ravel(v), dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be 3 numbers ({unit}), got {v!r}") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be 3 finite numbers ({unit}), got {v!r}")
    if nonneg and np.any(a < 0):
        raise InputError(f"{name} must be >= 0 ({unit}), got {v!r}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class BoresightCalibration:
    """How a boresight estimated from the strips of one flight splits its error.

    The strip check's boresight ``b_hat = b + a + n``: ``b`` the scanner's true
    boresight, ``a`` the trajectory's attitude error common to the strips of that flight
    (in the body frame; absorbed: a boresight and a body-fixed attitude error move the
    points alike), ``n`` the adjustment's own error (the strips' noise).  For the points
    of THAT flight (times inside ``time_span_s``, the same trajectory) the absorbed part
    cancels the trajectory's common error, so their sigmas count, with the trajectory's
    sigmas, only the rotation left (``attitude_sigma_rad``, measured by the strip check:
    the trajectory's part that differs from strip to strip and ``n`` together, so no
    boresight sigma is added), without them ``n`` alone (``boresight_sigma_rad``); for
    any other flight the scanner file's ``boresight_sigma_deg`` (``n`` and
    ``a`` together) and the trajectory's whole attitude sigma hold
    (:func:`ins.lidar.georeference.georeference`).

    Attributes
    ----------
    time_span_s : ndarray (2,)
        First and last time of the calibration flight's points, s (trajectory's scale).
    boresight_sigma_rad : ndarray (3,)
        Sigma of ``n`` (rx, ry, rz), rad (used for that flight's points only without
        trajectory sigmas).
    attitude_sigma_rad : ndarray (3,)
        Roll, pitch, yaw rotation left in that flight's points after the calibration
        (the trajectory's strip-to-strip part and the boresight's error ``n``), rad.
    """

    time_span_s: np.ndarray
    boresight_sigma_rad: np.ndarray
    attitude_sigma_rad: np.ndarray

    def __post_init__(self):
        span = np.array(np.ravel(self.time_span_s), dtype=float)
        if span.shape != (2,) or not np.all(np.isfinite(span)) or span[1] < span[0]:
            raise InputError(f"time_span_s must be 2 increasing finite times (s), got "
                             f"{self.time_span_s!r}")
        span.setflags(write=False)
        object.__setattr__(self, "time_span_s", span)
        for name in ("boresight_sigma_rad", "attitude_sigma_rad"):
            object.__setattr__(self, name, _vec3(getattr(self, name), name, "rad >= 0",
                                                 True))

    def covers(self, t):
        """Which of the times ``t`` (s) lie in the calibration flight's span."""
        t = np.asarray(t, dtype=float)
        return (t >= self.time_span_s[0]) & (t <= self.time_span_s[1])


@dataclass(frozen=True, eq=False)
class Scanner:
    """A laser scanner and its mounting on the IMU.

    Parameters
    ----------
    model : {"polygon", "oscillating", "points"}
    forward_tilt_rad : float
        Tilt ``tau`` of the scan plane towards +x_s, rad.
    range_sigma_m : float
        Range noise (1 sigma), m.
    scan_angle_sigma_rad : float
        Scan-angle encoder noise (1 sigma), rad.
    axes : array_like, shape (3, 3)
        Nominal ``C_bs`` (scanner axes to body FRD), a proper rotation.
    lever_arm_m : array_like, shape (3,)
        IMU centre to the scanner origin, in ``b`` (FRD), m.
    boresight_rad : array_like, shape (3,)
        Misalignment ``(rx, ry, rz)``, rad.
    lever_arm_sigma_m, boresight_sigma_rad : array_like, shape (3,)
        Their 1-sigma uncertainties (m; rad).
    on : {"imu", "aircraft"}
        ``"aircraft"``: ``axes`` is ``C_as``, ``lever_arm_m`` in ``a`` from the platform
        centre (module notes).
    imu_to_platform_centre_b_m : array_like, shape (3,)
        ``l_bp`` (m, body FRD), used with ``on = "aircraft"``.
    calibration : BoresightCalibration, optional
        Set by a strip-check calibration (module notes); ``boresight_sigma_rad`` is
        then the total sigma, for other flights.
    """

    model: str = "polygon"
    forward_tilt_rad: float = 0.0
    range_sigma_m: float = 0.0
    scan_angle_sigma_rad: float = 0.0
    axes: np.ndarray = field(default_factory=lambda: np.eye(3))
    lever_arm_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    boresight_rad: np.ndarray = field(default_factory=lambda: np.zeros(3))
    lever_arm_sigma_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    boresight_sigma_rad: np.ndarray = field(default_factory=lambda: np.zeros(3))
    on: str = "imu"
    imu_to_platform_centre_b_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    calibration: BoresightCalibration = None

    def __post_init__(self):
        if self.on not in SCANNER_PLACES:
            raise InputError(f"on must be one of {', '.join(SCANNER_PLACES)}, got {self.on!r}")
        if self.model not in SCAN_MODELS:
            raise InputError(f"model must be one of {', '.join(SCAN_MODELS)}, got "
                             f"{self.model!r}")
        for name, unit in (("forward_tilt_rad", "rad"), ("range_sigma_m", "m >= 0"),
                           ("scan_angle_sigma_rad", "rad >= 0")):
            v = getattr(self, name)
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise InputError(f"{name} must be a number ({unit}), got {v!r}") from None
            if not math.isfinite(v) or (name != "forward_tilt_rad" and v < 0):
                raise InputError(f"{name} must be finite ({unit}), got {v!r}")
            object.__setattr__(self, name, v)
        if abs(self.forward_tilt_rad) >= math.pi / 2:
            raise InputError(f"forward tilt {math.degrees(self.forward_tilt_rad)!r} deg must "
                             "be within +-90 deg")
        axes = np.array(self.axes, dtype=float)
        if axes.shape != (3, 3) or not np.all(np.isfinite(axes)):
            raise InputError(f"axes must be a finite 3x3 matrix, got shape {axes.shape}")
        ortho = np.abs(axes @ axes.T - np.eye(3)).max()
        if ortho > 1e-6:
            raise InputError(f"axes must be orthonormal; |A A^T - I| = {ortho:.3g}")
        if np.linalg.det(axes) < 0:
            raise InputError("axes must be a proper rotation (det = +1), got a reflection")
        axes.setflags(write=False)
        object.__setattr__(self, "axes", axes)
        for name, unit, nonneg in (("lever_arm_m", "m", False), ("boresight_rad", "rad", False),
                                   ("lever_arm_sigma_m", "m >= 0", True),
                                   ("boresight_sigma_rad", "rad >= 0", True),
                                   ("imu_to_platform_centre_b_m", "m", False)):
            object.__setattr__(self, name, _vec3(getattr(self, name), name, unit, nonneg))
        if self.calibration is not None and not isinstance(self.calibration,
                                                           BoresightCalibration):
            raise InputError(f"calibration must be a BoresightCalibration, got "
                             f"{type(self.calibration).__name__}")

    @property
    def C_bs(self):
        """Scanner frame to IMU body: ``axes @ Rx(rx) @ Ry(ry) @ Rz(rz)``, (3, 3)."""
        return self.axes @ boresight_dcm(self.boresight_rad)

    def with_boresight(self, boresight_rad):
        """A copy with another boresight (rad); a calibration record is dropped (it
        belongs to the boresight it was made with)."""
        return self.replace(boresight_rad=boresight_rad, calibration=None)

    def replace(self, **changes):
        """A copy with the given fields changed."""
        kw = {n: getattr(self, n) for n in self.__dataclass_fields__}
        kw.update(changes)
        return Scanner(**kw)


def scanner_rays(range_m, scan_angle_rad, forward_tilt_rad=0.0):
    """Points in the scanner frame of line-scanner returns (see the module notes).

    Parameters
    ----------
    range_m, scan_angle_rad : array_like, shape (n,)
        m; rad (positive to the right).
    forward_tilt_rad : float

    Returns
    -------
    ndarray, shape (n, 3)
        ``r_s``, m.
    """
    rho = np.asarray(range_m, dtype=float)
    th = np.asarray(scan_angle_rad, dtype=float)
    ct, st = math.cos(forward_tilt_rad), math.sin(forward_tilt_rad)
    return np.column_stack([rho * st, rho * ct * np.sin(th), rho * ct * np.cos(th)])


def read_scanner(path):
    """Read a scanner file (TOML, ``docs/interfaces.md``) into a :class:`Scanner`.

    Strict: an unknown section or key is an error naming the file, ``[section] key`` and
    the expected unit.  Every key but ``[scanner] model`` is optional (zero tilt, zero
    noise, identity axes, zero lever arm and boresight with zero sigmas).
    """
    path = str(path)
    doc = textfiles.read_toml(path, "a TOML scanner file with [scanner] and [mounting]")
    check_keys(doc, SCANNER_KEYS, path)
    if "scanner" not in doc:
        raise InputError("[scanner]: missing required section (model = "
                         + " | ".join(f'"{m}"' for m in SCAN_MODELS) + ")", path=path)
    sc = Table(doc["scanner"], "scanner", path, SCANNER_KEYS["scanner"], SCANNER_KEYS)
    model = sc.choice("model", REQUIRED, SCAN_MODELS)
    tilt = sc.number("forward_tilt_deg", 0.0, "deg in (-90, 90)", lo=-89.999, hi=89.999)
    rsig = sc.number("range_sigma_m", 0.0, "m in [0, 100]", lo=0.0, hi=100.0)
    asig = sc.number("scan_angle_sigma_deg", 0.0, "deg in [0, 90]", lo=0.0, hi=90.0)
    sc.finish()
    mnt = Table(doc.get("mounting"), "mounting", path, SCANNER_KEYS["mounting"], SCANNER_KEYS)
    on = mnt.choice("on", "imu", SCANNER_PLACES)
    l_bp = mnt.numbers("imu_to_platform_centre_b_m", (0.0, 0.0, 0.0), "m, body FRD",
                       length=3, scalar=False, bound=MAX_LEVER_ARM_M)
    if on == "imu" and mnt.has("imu_to_platform_centre_b_m"):
        raise mnt.error("imu_to_platform_centre_b_m", 'only with on = "aircraft" (a '
                        "scanner on the IMU needs no platform arm)")
    axes = mnt.matrix("axes", tuple(map(tuple, np.eye(3))), (3, 3),
                      "rows of C_bs, a rotation matrix")
    lever = mnt.numbers("lever_arm_m", (0.0, 0.0, 0.0), "m, body FRD", length=3, scalar=False,
                        bound=MAX_LEVER_ARM_M)
    bore = mnt.numbers("boresight_deg", (0.0, 0.0, 0.0), "deg (rx, ry, rz)", length=3,
                       scalar=False, bound=180.0)
    lsig = mnt.numbers("lever_arm_sigma_m", (0.0, 0.0, 0.0), "m >= 0, body FRD", length=3,
                       lo=0.0, scalar=False, bound=MAX_LEVER_ARM_M)
    bsig = mnt.numbers("boresight_sigma_deg", (0.0, 0.0, 0.0), "deg >= 0 (rx, ry, rz)",
                       length=3, lo=0.0, scalar=False, bound=180.0)
    mnt.finish()
    calibration = None
    if "calibration" in doc:
        cal = Table(doc["calibration"], "calibration", path, SCANNER_KEYS["calibration"],
                    SCANNER_KEYS)
        span = cal.numbers("time_span_s", REQUIRED, "s, first and last time", length=2,
                           scalar=False)
        csig = cal.numbers("boresight_sigma_deg", REQUIRED, "deg >= 0 (rx, ry, rz)", length=3,
                           lo=0.0, scalar=False, bound=180.0)
        att_sig = cal.numbers("attitude_sigma_deg", REQUIRED, "deg >= 0 (roll, pitch, yaw)",
                           length=3, lo=0.0, scalar=False, bound=180.0)
        cal.finish()
        if span[1] < span[0]:
            raise cal.error("time_span_s", f"expected first <= last, got {list(span)!r}",
                            "s")
        calibration = BoresightCalibration(span, np.deg2rad(csig), np.deg2rad(att_sig))
    try:
        return Scanner(model=model, forward_tilt_rad=math.radians(tilt), range_sigma_m=rsig,
                       scan_angle_sigma_rad=math.radians(asig), axes=axes, lever_arm_m=lever,
                       boresight_rad=np.deg2rad(bore), lever_arm_sigma_m=lsig,
                       boresight_sigma_rad=np.deg2rad(bsig), on=on,
                       imu_to_platform_centre_b_m=l_bp, calibration=calibration)
    except InputError as exc:
        raise InputError(f"[mounting] {exc.reason}", path=path) from None


def scanner_to_dict(scanner):
    """The scanner file's content as nested dicts (TOML-ready)."""
    doc = {
        "scanner": {"model": scanner.model,
                    "forward_tilt_deg": math.degrees(scanner.forward_tilt_rad),
                    "range_sigma_m": scanner.range_sigma_m,
                    "scan_angle_sigma_deg": math.degrees(scanner.scan_angle_sigma_rad)},
        "mounting": {"axes": [[float(v) for v in row] for row in scanner.axes],
                     "lever_arm_m": [float(v) for v in scanner.lever_arm_m],
                     "boresight_deg": [float(v) for v in np.rad2deg(scanner.boresight_rad)],
                     "lever_arm_sigma_m": [float(v) for v in scanner.lever_arm_sigma_m],
                     "boresight_sigma_deg": [float(v) for v in
                                             np.rad2deg(scanner.boresight_sigma_rad)]}}
    cal = scanner.calibration
    if cal is not None:
        doc["calibration"] = {
            "time_span_s": [float(v) for v in cal.time_span_s],
            "boresight_sigma_deg": [float(v) for v in np.rad2deg(cal.boresight_sigma_rad)],
            "attitude_sigma_deg": [float(v) for v in np.rad2deg(cal.attitude_sigma_rad)]}
    if scanner.on != "imu":
        doc["mounting"]["on"] = scanner.on
        doc["mounting"]["imu_to_platform_centre_b_m"] = [
            float(v) for v in scanner.imu_to_platform_centre_b_m]
    return doc


def write_scanner(path, scanner):
    """Write a scanner file (TOML, atomically)."""
    import tomli_w
    text = tomli_w.dumps(scanner_to_dict(scanner))
    with atomic_open(path, "wb") as f:
        f.write(text.encode("utf-8"))
