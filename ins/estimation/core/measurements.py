"""Measurements of the GNSS/INS filter: a small protocol and its implementations, and the
Kalman update by Cholesky.

Protocol
--------
A measurement is an object with

``name`` (str) and ``axes`` (tuple of str)
    what it is (``gnss_position``) and the names of its components (``N``, ``E``, ``D``);
``unit`` (str)
    the unit of its innovations in the innovation file (``m``, ``m/s``, ``deg``);
``time`` (float)
    its epoch, s;
``observed``
    the measured value (in the measurement's own form: lat, lon, h for a position);
``R`` (m x m)
    its noise covariance, SI;
``predict(point)``
    its predicted value from a :class:`NavPoint` (the filter's state at a node);
``residual(a, b)``
    ``a - b`` of two values as an m-vector in SI (NED metres for positions, wrapped
    radians for a heading);
``jacobian(point)``
    ``H`` (m x n) with ``residual(predict(point), predict(true point)) ~ H dx`` for an
    error state ``dx`` (:mod:`ins.estimation.core.error_model`: navigation errors estimate minus truth,
    sensor errors truth minus estimate; :func:`corrected` applies ``dx``).

``innovation(point)`` (optional)
    ``(z, H)`` at once, the terms shared by the two computed once (:class:`GnssPosition`:
    the filter's per-epoch path); the same values as the three calls.

The innovation is ``z = residual(predict(point), observed)`` (predicted minus measured);
:func:`kalman_update` gives the standardized innovation of each axis
``z_i / sqrt(S_ii)`` and the normalized innovation squared ``z^T S^-1 z`` (NIS) from one
Cholesky factorization of ``S = H P H^T + R``.

Implementations: :class:`GnssPosition` (full 3 x 3 covariance when given),
:class:`GnssVelocity`, :class:`DualAntennaHeading`, :class:`ZeroVelocity` and
:class:`NonHolonomic` (lateral and vertical body velocity zero).  The lever-arm and
time-offset states enter the GNSS measurements when the layout has them.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from ins.common.errors import QualityError
from ins.estimation.core import _filter_kernels
from ins.estimation.core import _kalman_kernels
from ins.estimation.core.error_model import KFGINS, SENSORS, StateLayout, sym_matrix
from ins.estimation.core.lever_arm import antenna_lla_one, antenna_velocity
from ins.nav import earth
from ins.nav.rotation import quat_to_dcm, skew

__all__ = ["NavPoint", "node_acceleration", "GnssPosition", "GnssVelocity",
           "DualAntennaHeading", "ZeroVelocity", "NonHolonomic", "UpdateRecord",
           "kalman_update", "chi2_upper_quantile", "corrected", "write_innovations",
           "INNOVATION_COLUMNS"]


_EYE3, _ZERO3 = np.eye(3), np.zeros(3)
_EYE3.flags.writeable = _ZERO3.flags.writeable = False


@dataclass
class NavPoint:
    """The filter's state at one epoch, as the measurements see it.

    Attributes
    ----------
    time : float
        Epoch of ``state``, s.
    state : ndarray, shape (10,)
        Navigation state (:data:`ins.estimation.core.error_model.NAV`: lat, lon rad, h m, ``v_n`` m/s,
        ``q_nb``).
    sensors : ndarray, shape (n - 9,)
        Sensor estimates in the order of ``layout.sensors``.
    layout : StateLayout
    w_meas_b : ndarray, shape (3,)
        Raw (uncompensated) angular rate of the gyros, rad/s, body FRD.
    l_b, dl_b : ndarray, shape (3,)
        Configured IMU-to-antenna arm (m, b) and its rate (m/s), without the estimated
        lever-arm correction.
    a_n : ndarray, shape (3,), optional
        The IMU's acceleration at the node, m/s^2, NED (:func:`node_acceleration`), held
        constant by the measurements: it carries the GNSS predictions over the few ms
        from the node to the record's time plus the time offset.  ``None``: 0.
    """

    time: float
    state: np.ndarray
    sensors: np.ndarray
    layout: StateLayout = KFGINS
    w_meas_b: np.ndarray = None
    l_b: np.ndarray = None
    dl_b: np.ndarray = None
    a_n: np.ndarray = None
    _C: tuple = field(default=None, init=False, repr=False, compare=False)

    @property
    def C_nb(self):
        """``C_nb`` of ``state`` (computed once per value of its quaternion: the filter
        corrects ``state`` in place after each accepted update)."""
        q = self.state[6:10]
        key = q.tobytes()
        if self._C is None or self._C[0] != key:
            self._C = (key, quat_to_dcm(q))
        return self._C[1]

    @property
    def w_ib_b(self):
        """Compensated angular rate, rad/s (bias, scale, non-orthogonality removed)."""
        w = np.zeros(3) if self.w_meas_b is None else np.asarray(self.w_meas_b, float)
        s = self.sensors
        w = (w - s[SENSORS.gyro_bias]) / (1.0 + s[SENSORS.gyro_scale])
        return w - sym_matrix(self.layout.estimate(s, "gyro_misalignment")) @ w

    @property
    def w_in_n(self):
        s = self.state
        return earth.earth_rate_n(s[0]) + earth.transport_rate_n(s[0], s[2], s[3:6])

    def arm(self):
        """``(l_b, dl_b)``: the arm with the estimated correction, m and m/s."""
        l_b = _ZERO3 if self.l_b is None else np.asarray(self.l_b, float)
        dl_b = np.zeros(3) if self.dl_b is None else np.asarray(self.dl_b, float)
        sl = self.layout.lever_arm               # (layout.estimate, without its cost)
        est = _ZERO3 if sl is None else np.asarray(self.sensors)[sl.start - 9:sl.stop - 9]
        return l_b + est, dl_b

    @property
    def time_offset(self):
        sl = self.layout.time_offset
        return 0.0 if sl is None else float(np.asarray(self.sensors)[sl.start - 9])


def corrected(point, dx):
    """The point with the error state ``dx`` removed (the filter's feedback rule): the
    navigation errors subtracted, the sensor errors added to the estimates."""
    state = np.array(point.state, dtype=float)
    _filter_kernels.correct_state(state, np.asarray(dx[:9], dtype=float))
    return NavPoint(point.time, state, point.sensors + dx[point.layout.sensors],
                    point.layout, point.w_meas_b, point.l_b, point.dl_b, point.a_n)


def node_acceleration(state, f_meas_b, C_nb=None):
    """The IMU's acceleration ``dv_n/dt`` (m/s^2, NED) at a node from its state
    (:data:`ins.estimation.core.error_model.NAV`) and the raw specific force of its last IMU interval
    (m/s^2, b): ``C_nb f_b + g_n - (2 w_ie + w_en) x v_n`` (sensor errors not removed:
    a 5 mg bias moves the prediction by 0.05 mm/s over 1 ms).  ``C_nb``: the state's
    attitude matrix when the caller has it (else computed from the quaternion)."""
    s = np.asarray(state, dtype=float)
    if C_nb is None:
        C_nb = quat_to_dcm(s[6:10])
    lat, _, h, v0, v1, v2 = s[:6].tolist()       # the scalar formulas of ins.nav.earth
    ie, tr = earth.earth_rate_kernel(lat), earth.transport_rate_kernel(lat, h, v0, v1)
    w0, w1, w2 = 2.0 * ie[0] + tr[0], 2.0 * ie[1] + tr[1], 2.0 * ie[2] + tr[2]
    w_x_v = np.array([w1 * v2 - w2 * v1, w2 * v0 - w0 * v2,
                      w0 * v1 - w1 * v0])                      # np.cross, without its cost
    return (C_nb @ np.asarray(f_meas_b, dtype=float)
            + np.array([0.0, 0.0, earth.gravity_kernel(lat, h)]) - w_x_v)


def _skew3(x, y, z):
    """:func:`ins.nav.rotation.skew` of one vector given as three floats (no stacking)."""
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _check_cov(cov, m, what):
    cov = np.asarray(cov, dtype=float)
    if cov.shape == (m,):
        cov = np.diag(cov)
    if cov.shape != (m, m) or not np.isfinite(cov).all():
        raise ValueError(f"{what}: expected a ({m}, {m}) covariance, got shape {cov.shape}")
    return cov


class GnssPosition:
    """Antenna position fix: ``observed`` = lat, lon (rad), h (m); ``R`` NED, m^2.

    The prediction moves the node state to the record's time plus the estimated time
    offset (``dt``) along its velocity and acceleration (``v dt + a dt^2 / 2``), then
    adds the arm ``C_nb l_b``.
    """

    name, axes, unit = "gnss_position", ("N", "E", "D"), "m"

    def __init__(self, time, lla, cov_ned_m2):
        self.time = float(time)
        self.observed = np.asarray(lla, dtype=float)
        self.R = _check_cov(cov_ned_m2, 3, self.name)

    def _dt(self, p):
        return self.time + p.time_offset - p.time

    def _terms(self, p):
        """What :meth:`predict` and :meth:`jacobian` share: ``dt`` (s), ``a_n``, ``C_nb``
        and the arm in n, ``C_nb l_b`` (m)."""
        a_n = _ZERO3 if p.a_n is None else np.asarray(p.a_n, dtype=float)
        C = p.C_nb
        return self._dt(p), a_n, C, C @ p.arm()[0]

    def predict(self, p, terms=None):
        dt, a_n, _, arm_n = self._terms(p) if terms is None else terms
        s = p.state
        v = (s[3:6] + 0.5 * a_n * dt).tolist()          # earth.lla_rate of one point
        lla = s[0:3] + np.array(earth.lla_rate_kernel(s[0], s[2], *v)) * dt
        return antenna_lla_one(lla, arm_n)

    def residual(self, a, b):
        return earth.ned_offset(b, a)

    def jacobian(self, p, terms=None):
        dt, a_n, C, arm_n = self._terms(p) if terms is None else terms
        L = p.layout
        H = np.zeros((3, L.n))
        H[:, L.pos] = _EYE3
        H[:, L.vel] = dt * _EYE3
        H[:, L.att] = _skew3(*arm_n.tolist())
        if L.lever_arm is not None:
            H[:, L.lever_arm] = -C
        if L.time_offset is not None:
            H[:, L.time_offset] = -(p.state[3:6] + a_n * dt)[:, None]
        return H

    def innovation(self, p):
        """``(z, H)``: :meth:`residual` of :meth:`predict` and the observation, and
        :meth:`jacobian`, with their shared terms computed once (the filter's path)."""
        terms = self._terms(p)
        return self.residual(self.predict(p, terms), self.observed), self.jacobian(p, terms)


class GnssVelocity:
    """Antenna velocity: ``observed`` = ``v_n`` (m/s); ``R`` NED, (m/s)^2.

    The prediction is the node's antenna velocity carried to the record's time plus the
    estimated time offset by the node's acceleration (``a_n dt``; without ``a_n`` the
    node's velocity as it is).
    """

    name, axes, unit = "gnss_velocity", ("N", "E", "D"), "m/s"

    def __init__(self, time, v_n, cov_ned_m2ps2):
        self.time = float(time)
        self.observed = np.asarray(v_n, dtype=float)
        self.R = _check_cov(cov_ned_m2ps2, 3, self.name)

    def _dt(self, p):
        return self.time + p.time_offset - p.time

    def predict(self, p):
        l_b, dl_b = p.arm()
        v = antenna_velocity(p.state[3:6], p.C_nb, p.w_ib_b, p.w_in_n, l_b, dl_b)
        return v if p.a_n is None else v + np.asarray(p.a_n, dtype=float) * self._dt(p)

    def residual(self, a, b):
        return np.asarray(a) - np.asarray(b)

    def jacobian(self, p):
        L, C, w = p.layout, p.C_nb, p.w_ib_b
        l_b, dl_b = p.arm()
        w_in = p.w_in_n
        H = np.zeros((3, L.n))
        H[:, L.vel] = np.eye(3)
        H[:, L.att] = skew(C @ (np.cross(w, l_b) + dl_b)) - skew(w_in) @ skew(C @ l_b)
        # w = (I - N(m)) (w_meas - b) / (1 + s): its change for a sensor error dx
        s = p.sensors
        J = ((np.eye(3) - sym_matrix(L.estimate(s, "gyro_misalignment")))
             / (1.0 + s[SENSORS.gyro_scale]))
        w1 = (p.w_meas_b - s[SENSORS.gyro_bias]) / (1.0 + s[SENSORS.gyro_scale])
        Cl = -C @ skew(l_b)
        H[:, L.gyro_bias] = Cl @ J
        H[:, L.gyro_scale] = Cl @ J @ np.diag(w1)
        if L.gyro_misalignment is not None:
            H[:, L.gyro_misalignment] = Cl @ sym_matrix(w1)
        if L.lever_arm is not None:
            H[:, L.lever_arm] = -(C @ skew(w) - skew(w_in) @ C)
        if L.time_offset is not None and p.a_n is not None:
            H[:, L.time_offset] = -np.asarray(p.a_n, dtype=float)[:, None]
        return H


class DualAntennaHeading:
    """Heading of a dual-antenna baseline: ``observed`` = azimuth of the baseline (rad,
    clockwise from north); ``baseline_b`` its direction in b (the primary-to-secondary
    antenna vector; only its horizontal direction in n matters); ``R`` rad^2."""

    name, axes, unit = "heading", ("psi",), "deg"

    def __init__(self, time, heading_rad, sigma_rad, baseline_b=(1.0, 0.0, 0.0)):
        self.time = float(time)
        self.observed = np.array([float(heading_rad)])
        self.R = np.array([[float(sigma_rad) ** 2]])
        self.baseline_b = np.asarray(baseline_b, dtype=float)

    def predict(self, p):
        b = p.C_nb @ self.baseline_b
        return np.array([np.arctan2(b[1], b[0])])

    def residual(self, a, b):
        return (np.asarray(a) - np.asarray(b) + np.pi) % (2 * np.pi) - np.pi

    def jacobian(self, p):
        b = p.C_nb @ self.baseline_b
        h2 = b[0] ** 2 + b[1] ** 2
        if h2 < 1e-12 * float(b @ b):
            raise ValueError("heading: the baseline is vertical (no azimuth)")
        H = np.zeros((1, p.layout.n))
        H[0, p.layout.att] = np.array([-b[1], b[0], 0.0]) / h2 @ skew(b)
        return H


class ZeroVelocity:
    """Zero-velocity update: the IMU's ``v_n`` is zero; ``R`` (m/s)^2 per axis."""

    name, axes, unit = "zero_velocity", ("N", "E", "D"), "m/s"

    def __init__(self, time, sigma_mps):
        self.time = float(time)
        self.observed = np.zeros(3)
        self.R = np.diag(np.broadcast_to(np.asarray(sigma_mps, float), 3) ** 2)

    def predict(self, p):
        return np.array(p.state[3:6], dtype=float)

    def residual(self, a, b):
        return np.asarray(a) - np.asarray(b)

    def jacobian(self, p):
        H = np.zeros((3, p.layout.n))
        H[:, p.layout.vel] = np.eye(3)
        return H


class NonHolonomic:
    """Non-holonomic constraint of a land vehicle: the lateral and vertical velocity in
    the VEHICLE axes ``v`` (forward, right, down of the vehicle's direction of travel),
    ``C_vb C_nb^T v_n`` (y and z), are zero; ``R`` (m/s)^2 per axis.

    ``C_vb`` (3 x 3) takes IMU body vectors into the vehicle frame (``v_v = C_vb v_b``):
    the IMU's mounting, ``C_vb = Rz(yaw) Ry(pitch) Rx(roll)`` of the config's
    ``[vehicle] mounting_rpy_deg`` (the IMU's roll, pitch, yaw in the vehicle frame, the
    Euler convention of ``C_nb``; :func:`ins.estimation.tools.vehicle.mounting_dcm`).  ``None`` (the
    default) is the identity: the IMU's axes are the vehicle's.
    """

    name, axes, unit = "nonholonomic", ("y", "z"), "m/s"

    def __init__(self, time, sigma_mps, C_vb=None):
        self.time = float(time)
        self.observed = np.zeros(2)
        self.R = np.diag(np.broadcast_to(np.asarray(sigma_mps, float), 2) ** 2)
        self.C_vb = np.eye(3) if C_vb is None else _check_dcm(C_vb, self.name)

    def predict(self, p):
        return (self.C_vb @ (p.C_nb.T @ p.state[3:6]))[1:3]

    def residual(self, a, b):
        return np.asarray(a) - np.asarray(b)

    def jacobian(self, p):
        C_vn = self.C_vb @ p.C_nb.T
        H = np.zeros((2, p.layout.n))
        H[:, p.layout.vel] = C_vn[1:3]
        H[:, p.layout.att] = -(C_vn @ skew(p.state[3:6]))[1:3]
        return H


def _check_dcm(C, what):
    C = np.asarray(C, dtype=float)
    if (C.shape != (3, 3) or not np.all(np.isfinite(C))
            or not np.allclose(C @ C.T, np.eye(3), atol=1e-9) or np.linalg.det(C) < 0):
        raise ValueError(f"{what}: expected a (3, 3) rotation matrix, got {C!r}")
    return C


@dataclass
class UpdateRecord:
    """One tested measurement: its name, axes and unit, time (s), innovation (SI),
    ``sqrt(S_ii)`` (SI), NIS, whether it was accepted."""

    name: str
    axes: tuple
    unit: str
    time: float
    innovation: np.ndarray
    sigma: np.ndarray
    nis: float
    accepted: bool

    @property
    def standardized(self):
        """Per-axis standardized innovations ``z_i / sqrt(S_ii)``."""
        return self.innovation / self.sigma


def kalman_update(P, H, R, z, threshold, meas=None, logdet=False):
    """One Kalman update by a single Cholesky factorization of ``S = H P H^T + R``
    (compiled: :func:`ins.estimation.core._kalman_kernels.joseph_update`; filterpy's
    ``update`` is the tests' reference).

    Parameters
    ----------
    P : ndarray, shape (n, n)
    H : ndarray, shape (m, n)
    R : ndarray, shape (m, m)
    z : ndarray, shape (m,)
        Innovation, predicted minus measured.
    threshold : float
        Innovation test: the update is skipped when ``z^T S^-1 z`` exceeds it.
    meas : object, optional
        The measurement (``name``, ``time``), for the error message.

    Returns
    -------
    dx : ndarray (n,) or None
        The error-state estimate (None when rejected).
    P : ndarray (n, n)
        Posterior covariance (Joseph form), or ``P`` when rejected.
    nis : float
    sigma : ndarray (m,)
        ``sqrt(diag(S))``.
    log_det_S : float
        Only with ``logdet=True``: ``log det S`` (for the innovation likelihood,
        :mod:`ins.estimation.tools.noise_identification`).

    Raises
    ------
    ins.common.errors.QualityError
        ``S`` not positive definite: names the measurement and its epoch.
    """
    f8 = np.float64
    if not all(type(a) is np.ndarray and a.dtype == f8 and a.flags.c_contiguous
               and a.ndim == d for a, d in ((P, 2), (H, 2), (R, 2), (z, 1))):
        P, H, R = (np.ascontiguousarray(np.atleast_2d(a), f8) for a in (P, H, R))
        z = np.ascontiguousarray(z, f8).ravel()
    status, dx, P_post, nis, S = _kalman_kernels.joseph_update(P, H, R, z, float(threshold))
    if status == 2:
        name = getattr(meas, "name", "measurement")
        t = getattr(meas, "time", None)
        when = "" if t is None else f" at t = {t:.3f} s"
        raise QualityError(f"{name}{when}: the innovation covariance S = H P H^T + R is "
                           f"not positive definite (diagonal {np.diag(S)!r}; its Cholesky "
                           f"factorization failed); check the measurement's sigmas and the "
                           f"filter's noise settings")
    sigma = np.sqrt(S.diagonal())
    out = (None, P, float(nis), sigma) if status == 1 else (dx, P_post, float(nis), sigma)
    if logdet:
        return out + (float(np.linalg.slogdet(S)[1]),)
    return out


#: Beyond this NIS an innovation's contribution to :func:`innovation_nll` grows with the
#: Mahalanobis distance, not its square (Huber's rule on ``sqrt(NIS)``): a few wrong
#: fixes do not decide a likelihood search.  The chi-square 99 % point of 3 dof.
NLL_HUBER_NIS = 11.345


def innovation_nll(nis, log_det_S, m):
    """Negative log-likelihood of one innovation of ``m`` axes with Mahalanobis square
    ``nis`` and ``log det S``: ``(rho(nis) + log det S + m log 2 pi) / 2``, ``rho`` the
    square up to :data:`NLL_HUBER_NIS` and linear in ``sqrt(nis)`` beyond (continuous
    with its slope): Gaussian for the innovations the model explains, robust to the
    few it does not."""
    c = NLL_HUBER_NIS
    rho = nis if nis <= c else c + 2.0 * np.sqrt(c) * (np.sqrt(nis) - np.sqrt(c))
    return 0.5 * (rho + log_det_S + m * 1.8378770664093453)


def chi2_upper_quantile(q, dof):
    """The chi-square quantile with upper-tail probability ``q``: ``x`` with
    ``P(X > x) = q`` for ``X`` chi-square with ``dof`` (a positive integer) degrees of
    freedom (scipy's ``chi2.isf``, the tests' reference; without importing scipy.stats).

    ``q <= 0`` gives ``inf``, ``q >= 1`` gives 0.  Relative accuracy about 1e-13.
    """
    dof = int(dof)
    if dof < 1:
        raise ValueError(f"dof must be a positive integer, got {dof}")
    if not q > 0.0:
        return float("inf")
    if q >= 1.0:
        return 0.0

    def upper(x):               # P(X > x): the closed forms for integer dof
        h = 0.5 * x
        if dof % 2 == 0:
            term, total = 1.0, 1.0
            for k in range(1, dof // 2):
                term *= h / k
                total += term
            return math.exp(-h) * total
        total = math.erfc(math.sqrt(h))
        term = math.sqrt(h) / math.gamma(1.5) * math.exp(-h)
        for k in range(1, (dof - 1) // 2 + 1):
            total += term
            term *= h / (k + 0.5)
        return total

    lo, hi = 0.0, max(float(dof), 1.0)
    while upper(hi) > q:
        lo, hi = hi, 2.0 * hi
    for _ in range(200):        # bisection to the last bits
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if upper(mid) > q:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


#: Columns of ``innovations.txt`` (units in the names; ``value`` and ``sigma`` in the
#: unit of the ``unit`` column).
INNOVATION_COLUMNS = ("time_s", "measurement", "axis", "innovation", "sigma",
                      "standardized", "nis", "accepted", "unit")
_UNIT_SCALE = {"deg": 180.0 / np.pi}


def write_innovations(path, records):
    """Write ``innovations.txt``: one line per axis of every tested measurement
    (:data:`INNOVATION_COLUMNS`, space separated; headings in deg), atomically."""
    from ins.common.fileio import atomic_open
    with atomic_open(path, "w") as f:
        f.write("# " + " ".join(INNOVATION_COLUMNS) + "\n")
        f.write("# innovation = predicted - measured; sigma = sqrt(S_ii), S = H P H^T + R; "
                "standardized = innovation / sigma; nis = z^T S^-1 z of the whole record; "
                "accepted = 1 when it passed the innovation test\n")
        for r in records:
            k = _UNIT_SCALE.get(r.unit, 1.0)
            zs = np.asarray(r.innovation, dtype=float).tolist()      # floats: faster
            ss = np.asarray(r.sigma, dtype=float).tolist()
            for a, z, s in zip(r.axes, zs, ss):
                f.write(f"{r.time:.3f} {r.name} {a} {z * k:.6e} {s * k:.6e} {z / s:.4f} "
                        f"{r.nis:.4f} {int(r.accepted)} {r.unit}\n")


def read_innovations(path):
    """Read ``innovations.txt`` back: a dict of columns (numpy arrays)."""
    rows = [ln.split() for ln in open(path, encoding="utf-8") if not ln.startswith("#")]
    cols = list(zip(*rows)) if rows else [()] * len(INNOVATION_COLUMNS)
    out = {}
    for name, col in zip(INNOVATION_COLUMNS, cols):
        out[name] = (np.array(col) if name in ("measurement", "axis", "unit")
                     else np.array(col, dtype=float))
    return out
