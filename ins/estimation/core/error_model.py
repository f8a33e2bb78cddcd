"""Error-state model of the GNSS/INS filter: state layout, F, G, Q and their discretization.

State layout (21 states, SI units inside)
-----------------------------------------
======  ==========  =======================================================  ========
index   name        meaning                                                  unit
======  ==========  =======================================================  ========
0-2     ``POS``     position error N, E, D, estimate minus truth             m
3-5     ``VEL``     velocity error N, E, D, estimate minus truth             m/s
6-8     ``ATT``     attitude error phi (phi-angle, n frame):                 rad
                    ``C_nb_est = (I - [phi x]) C_nb_true``
9-11    ``BG``      gyro bias error, truth minus estimate                    rad/s
12-14   ``BA``      accelerometer bias error, truth minus estimate           m/s^2
15-17   ``SG``      gyro scale-factor error, truth minus estimate            1
18-20   ``SA``      accelerometer scale-factor error, truth minus estimate   1
======  ==========  =======================================================  ========

Optional groups (``[states]`` of the processing config, :class:`StateLayout`) follow the
21 in this order: gyro non-orthogonality (3, rad), accelerometer non-orthogonality (3,
rad), lever-arm correction (3, m, b frame), IMU-GNSS time offset (1, s).  The IMU model
then reads ``w_meas = (I + diag(s_g) + N(m_g)) w + b_g + noise`` with the simulator's
symmetric ``N(m) = [[0, m_z, m_y], [m_z, 0, m_x], [m_y, m_x, 0]]``, compensated as
``w = (I - N(m_g)) (w_meas - b_g) / (1 + s_g)`` (first order in ``m``); since
``N(m) w = N(w) m`` the attitude rows get ``F_phi,mg = -C_nb N(w_ib_b)`` and the velocity
rows ``F_v,ma = C_nb N(f_b)`` (integrated as ``S_CNw``, ``S_CNf``).  The four groups are
random constants (no process noise); the lever arm and the time offset enter only the
GNSS measurements (:mod:`ins.estimation.core.measurements`).  ``layout = "kfgins"`` gives the 21 states
and the figures of KF-GINS.

The sign rules are those of KF-GINS (Shin's thesis): the navigation errors are removed
(``r -= D^-1 dr``, ``v -= dv``, ``C_nb <- Rot(phi) C_nb``) and the sensor errors added to
the estimates (``b += db``).  The IMU model is ``w_meas = (1 + s_g) w + b_g + noise``,
compensated as ``w = (w_meas - b_g) / (1 + s_g)``; the same for the accelerometers.
Biases and scale factors are first-order Gauss-Markov processes
``x' = -x / T + w`` with ``E[w w] = 2 sigma^2 / T`` (``sigma`` the prior), unless the
bias instabilities are given (:class:`ImuNoise`): the sensor states are then a random
constant plus a Gauss-Markov bias instability, as the simulator and a datasheet describe
an IMU; over a flight much shorter than ``T`` this is a random walk: no decay, the
biases driven by ``2 sigma_instability^2 / T``, the scale factors random constants
(no noise).  The prior keeps the total bias sigma.  (On a flight longer than ``T`` the
random walk's added variance ``2 sigma_inst^2 t / T`` passes the instability's ``sigma^2``:
conservative, not overconfident.)  A single Gauss-Markov of the total
sigma forgets a constant bias within ``T`` and drives it by ``2 sigma_total^2 / T``:
on the demo flight (tactical, bias 1 deg/h, instability 0.5 deg/h, scale 150 ppm)
the constant model brings the smoothed stated tilt sigmas from 49/38 to 40/29 arcsec.

Continuous model ``x' = F x + G w`` with ``w = [gyro white noise (ARW), accel white
noise (VRW), bias and scale driving noises]`` (18 inputs); the navigation rows follow
Shin (2001) / KF-GINS: position ``F_rr``, ``F_rv = I``; velocity ``F_vr``, ``F_vv``,
``F_vphi = [f_n x]``, ``F_v,ba = C_nb``, ``F_v,sa = C_nb diag(f_b)``; attitude
``F_phir``, ``F_phiv``, ``F_phiphi = -[w_in_n x]``, ``F_phi,bg = -C_nb``,
``F_phi,sg = -C_nb diag(w_ib_b)``.

Discretization over a node interval ``dt`` (the covariance runs at the node rate, not
at the IMU rate): with the IMU-rate integrals ``S_C = int C_nb dt``,
``S_Cw = int C_nb diag(w_ib_b) dt``, ``S_Cf = int C_nb diag(f_b) dt`` and the mean
specific force ``f_n`` accumulated by the mechanization between the nodes,
``A = int F dt`` (navigation blocks at the mid-interval state) and

    Phi = I + A + A^2 / 2 + A^3 / 6,
    Q_d = (Phi G Q G^T Phi^T + G Q G^T) dt / 2      (trapezoidal rule).

The cubic term carries a gyro bias into position within one interval (bias -> tilt ->
velocity -> position); without it a 1 s step misses ``g b_g dt^3 / 6``.
Since ``C_nb`` is orthogonal and the white noises are isotropic, ``G Q G^T`` does not
depend on the attitude.
"""
from dataclasses import dataclass

import numpy as np

from ins.estimation.core._kalman_kernels import fill_interval, fill_navigation

N_STATES = 21
POS, VEL, ATT = slice(0, 3), slice(3, 6), slice(6, 9)
BG, BA, SG, SA = slice(9, 12), slice(12, 15), slice(15, 18), slice(18, 21)
NAV_ERRORS, SENSOR_ERRORS = slice(0, 9), slice(9, 21)


@dataclass(frozen=True)
class _Layout:
    """Named slices of one vector layout (read-only)."""

    def __init__(self, **slices):
        for name, value in slices.items():
            object.__setattr__(self, name, value)

    def __repr__(self):
        return "Layout(" + ", ".join(f"{k}={v.start}:{v.stop}" for k, v in vars(self).items()) + ")"


#: The 21-state error vector and covariance by name: ``x[STATE.att]``,
#: ``P[STATE.gyro_bias, STATE.gyro_bias]``, ``std[:, STATE.pos]``; ``nav`` (0:9) and
#: ``sensors`` (9:21) are the two groups.
STATE = _Layout(pos=POS, vel=VEL, att=ATT, gyro_bias=BG, accel_bias=BA, gyro_scale=SG,
                accel_scale=SA, nav=NAV_ERRORS, sensors=SENSOR_ERRORS)
#: The 12 sensor estimates (``ForwardResult.sensors``, ``imu_errors.txt``), SI: the
#: sensor states ``STATE.sensors`` in the same order, so ``sensors += x[STATE.sensors]``.
SENSORS = _Layout(gyro_bias=slice(0, 3), accel_bias=slice(3, 6), gyro_scale=slice(6, 9),
                  accel_scale=slice(9, 12))
#: The 10-element navigation state of the mechanization (``NavState.as_vector``, the
#: filter's ``node_states``): latitude, longitude (rad), height (m); ``v_n`` (m/s);
#: ``q_nb`` as ``[qx, qy, qz, qw]``.
NAV = _Layout(lla=slice(0, 3), vel=slice(3, 6), q_nb=slice(6, 10))
#: Index arrays of the attitude block's three cross covariances in a state covariance,
#: ``P[ATT_CROSS]`` = (P_NE, P_ND, P_ED) of the phi angles (rad^2); the stores keep them
#: beside the sigmas so that the roll/pitch/yaw sigmas use the whole 3 x 3 block
#: (:func:`attitude_block`).
ATT_CROSS = (np.array([6, 6, 7]), np.array([7, 8, 8]))
#: Last index of the attitude block: a covariance of ``n > ATT_STOP`` states has one
#: (the stores give NaN cross covariances for smaller, non-navigation problems).
ATT_STOP = 8


def attitude_block(std_att, cross):
    """The phi-angle covariances (m, 3, 3) (rad^2, N/E/D) from the attitude sigmas
    ``std_att`` (m, 3) (rad) and the cross covariances ``cross`` (m, 3) (rad^2, the order
    of :data:`ATT_CROSS`)."""
    std_att, cross = np.asarray(std_att, dtype=float), np.asarray(cross, dtype=float)
    P = np.empty((len(std_att), 3, 3))
    k = np.arange(3)
    P[:, k, k] = std_att ** 2
    i, j = ATT_CROSS[0] - ATT.start, ATT_CROSS[1] - ATT.start
    P[:, i, j] = P[:, j, i] = cross
    return P


STATE_NAMES = tuple(f"{q}_{a}" for q, axes in (("pos", "NED"), ("vel", "NED"), ("att", "NED"),
                                               ("gyro_bias", "xyz"), ("accel_bias", "xyz"),
                                               ("gyro_scale", "xyz"), ("accel_scale", "xyz"))
                    for a in axes)

#: Optional state groups after the 21 KF-GINS states, in this order, with their sizes:
#: gyro and accelerometer non-orthogonality (rad, the symmetric model
#: ``N(m) = [[0, m_z, m_y], [m_z, 0, m_x], [m_y, m_x, 0]]`` of the simulator), the GNSS lever
#: arm correction (m, b frame, added to the configured arm) and the IMU-GNSS time offset
#: (s: a GNSS record stamped ``t`` holds the antenna at IMU time ``t + offset``).  All four
#: are random constants (no process noise), truth minus estimate, fed back like the sensor
#: errors (``estimate += dx``).  The receiver clock (tight coupling,
#: :mod:`ins.estimation.coupling.pseudorange`) is the exception: bias (m, ``c dt_r``) and drift
#: (m/s) with ``bias' = drift`` and white noise on both (:func:`noise_matrix`'s
#: ``clock_psd``), truth minus estimate like the sensor states.
#: The inter-system biases ``isb`` (tight coupling with several constellations): the
#: clock offsets of GLONASS, Galileo, BeiDou and QZSS less the receiver clock's bias (of
#: GPS), m, random constants like the other groups.
OPTIONAL_GROUPS = {"gyro_misalignment": 3, "accel_misalignment": 3, "lever_arm": 3,
                   "time_offset": 1, "clock": 2, "isb": 4}
_OPTIONAL_AXES = {"gyro_misalignment": "xyz", "accel_misalignment": "xyz", "lever_arm": "xyz",
                  "time_offset": ("",), "clock": ("bias", "drift"), "isb": "RECJ"}


class StateLayout:
    """The error-state layout of one run: the 21 KF-GINS states, then the optional groups
    (:data:`OPTIONAL_GROUPS`) that are switched on, in the order of that table.

    Attributes
    ----------
    n : int
        Number of states.
    groups : tuple of str
        The optional groups present.
    names : tuple of str
        One name per state (``pos_N`` .. ``accel_scale_z``, ``gyro_misalignment_x`` ..).
    pos, vel, att, gyro_bias, accel_bias, gyro_scale, accel_scale : slice
        As in :data:`STATE`.
    nav : slice
        0:9.
    sensors : slice
        9:n, the states fed back into the sensor estimates (``sensors += x[sensors]``):
        the estimate vector of a run has ``n - 9`` elements in this order.
    gyro_misalignment, accel_misalignment, lever_arm, time_offset : slice or None
        The optional groups (``None`` when absent).
    ambiguity : slice or None
        After the groups: ``n_ambiguities`` carrier-phase ambiguity slots (cycles, single
        differences rover minus base; :mod:`ins.estimation.coupling.carrier_phase`),
        random constants re-initialized by their updater when a satellite rises or
        slips; ``None`` without.
    groups_stop : int
        End of the optional groups (the start of the ambiguity slots).
    """

    def __init__(self, groups=(), n_ambiguities=0):
        unknown = [g for g in groups if g not in OPTIONAL_GROUPS]
        if unknown:
            raise ValueError(f"unknown state group(s) {unknown} (known: "
                             f"{', '.join(OPTIONAL_GROUPS)})")
        self.groups = tuple(g for g in OPTIONAL_GROUPS if g in groups)
        for name, value in vars(STATE).items():
            setattr(self, name, value)
        names = list(STATE_NAMES)
        k = 21
        for g in OPTIONAL_GROUPS:
            if g in self.groups:
                setattr(self, g, slice(k, k + OPTIONAL_GROUPS[g]))
                names += [f"{g}_{a}" if a else g for a in _OPTIONAL_AXES[g]]
                k += OPTIONAL_GROUPS[g]
            else:
                setattr(self, g, None)
        self.groups_stop = k
        self.n_ambiguities = int(n_ambiguities)
        if self.n_ambiguities < 0:
            raise ValueError(f"n_ambiguities must be >= 0, got {n_ambiguities}")
        self.ambiguity = slice(k, k + self.n_ambiguities) if self.n_ambiguities else None
        names += [f"ambiguity_{i}" for i in range(self.n_ambiguities)]
        k += self.n_ambiguities
        self.n = k
        self.sensors = slice(9, k)
        self.names = tuple(names)

    def estimate(self, sensors, group):
        """The estimate of an optional ``group`` in a sensor-estimate vector (zeros when
        the group is absent)."""
        sl = getattr(self, group)
        sensors = np.asarray(sensors)
        if sl is None:
            return np.zeros(sensors.shape[:-1] + (OPTIONAL_GROUPS[group],))
        return sensors[..., sl.start - 9:sl.stop - 9]

    def __eq__(self, other):
        return (isinstance(other, StateLayout) and other.groups == self.groups
                and other.n_ambiguities == self.n_ambiguities)

    def __hash__(self):
        return hash((self.groups, self.n_ambiguities))

    def __repr__(self):
        amb = f", n_ambiguities={self.n_ambiguities}" if self.n_ambiguities else ""
        return f"StateLayout({list(self.groups)!r}{amb}, n={self.n})"


#: The KF-GINS layout (21 states) and the named layouts of ``[states] layout``: ``survey``
#: adds the two non-orthogonality groups (the default of ``ins process``).
KFGINS = StateLayout(())
LAYOUTS = {"kfgins": (), "survey": ("gyro_misalignment", "accel_misalignment")}

#: Unit conversions from the edge units to SI.
DEG = np.pi / 180.0
DPH = DEG / 3600.0             # deg/h -> rad/s
DEG_SQRTH = DEG / 60.0         # deg/sqrt(h) -> rad/sqrt(s)
MPS_SQRTH = 1.0 / 60.0         # m/s/sqrt(h) -> m/s/sqrt(s)
MGAL = 1e-5                    # mGal -> m/s^2
PPM = 1e-6
HOUR = 3600.0


def _triple(value, name):
    v = np.broadcast_to(np.asarray(value, dtype=float), (3,)).copy()
    if not np.all(np.isfinite(v)) or np.any(v < 0):
        raise ValueError(f"{name} must be finite and >= 0 (one value or three), got {value}")
    return v


@dataclass(frozen=True)
class ImuNoise:
    """IMU noise and error statistics, in the KF-GINS units (one value or x, y, z).

    Parameters
    ----------
    arw_deg_sqrth : angle random walk, deg/sqrt(h)
    vrw_mps_sqrth : velocity random walk, m/s/sqrt(h)
    gyro_bias_std_dph : gyro bias (Gauss-Markov) standard deviation, deg/h
    accel_bias_std_mgal : accelerometer bias standard deviation, mGal
    gyro_scale_std_ppm, accel_scale_std_ppm : scale-factor standard deviations, ppm
    corr_time_h : correlation time of the Gauss-Markov processes, h
    gyro_bias_instability_dph : gyro bias instability (Gauss-Markov sigma), deg/h, or None
    accel_bias_instability_mgal : accelerometer bias instability, mGal, or None
        Given (both or one, the other then 0): the sensor states are random constants
        plus the instability (module notes, :attr:`constant_sensors`); ``None`` (both):
        every sensor state a Gauss-Markov process of its prior sigma (KF-GINS).
    """

    arw_deg_sqrth: object = 0.003
    vrw_mps_sqrth: object = 0.03
    gyro_bias_std_dph: object = 0.5
    accel_bias_std_mgal: object = 50.0
    gyro_scale_std_ppm: object = 1.0
    accel_scale_std_ppm: object = 1.0
    corr_time_h: float = 4.0
    gyro_bias_instability_dph: object = None
    accel_bias_instability_mgal: object = None

    def __post_init__(self):
        for name in ("arw_deg_sqrth", "vrw_mps_sqrth", "gyro_bias_std_dph",
                     "accel_bias_std_mgal", "gyro_scale_std_ppm", "accel_scale_std_ppm"):
            object.__setattr__(self, name, _triple(getattr(self, name), name))
        if self.constant_sensors:
            for name in ("gyro_bias_instability_dph", "accel_bias_instability_mgal"):
                value = getattr(self, name)
                object.__setattr__(self, name, _triple(0.0 if value is None else value, name))
        if not (np.isfinite(self.corr_time_h) and self.corr_time_h > 0):
            raise ValueError(f"corr_time_h must be > 0, got {self.corr_time_h}")

    @property
    def sensor_std(self):
        """Standard deviations of the 12 sensor states (bg, ba, sg, sa), SI."""
        return np.concatenate([self.gyro_bias_std_dph * DPH, self.accel_bias_std_mgal * MGAL,
                               self.gyro_scale_std_ppm * PPM, self.accel_scale_std_ppm * PPM])

    @property
    def constant_sensors(self):
        """True when a bias instability is given: sensor states random constants plus
        the instability as a random walk (module notes)."""
        return (self.gyro_bias_instability_dph is not None
                or self.accel_bias_instability_mgal is not None)

    @property
    def corr_time_s(self):
        return float(self.corr_time_h) * HOUR

    @property
    def decay_time_s(self):
        """Time constant of the sensor states' decay in F, s (``inf``: none)."""
        return np.inf if self.constant_sensors else self.corr_time_s

    def q_continuous(self):
        """Spectral densities of the 18 noise inputs (diagonal of Q), SI."""
        tau = self.corr_time_s
        if self.constant_sensors:
            driving = np.concatenate([2.0 * (self.gyro_bias_instability_dph * DPH) ** 2 / tau,
                                      2.0 * (self.accel_bias_instability_mgal * MGAL) ** 2
                                      / tau, np.zeros(6)])
        else:
            driving = 2.0 * self.sensor_std ** 2 / tau
        return np.concatenate([(self.arw_deg_sqrth * DEG_SQRTH) ** 2,
                               (self.vrw_mps_sqrth * MPS_SQRTH) ** 2, driving])


def noise_matrix(noise, layout=KFGINS, clock_psd=None):
    """``G Q G^T`` (n x n), attitude independent (see the module notes); the optional
    groups are random constants (no noise), except the receiver clock: ``clock_psd`` =
    (bias, drift) spectral densities, m^2/s and m^2/s^3 (two-state clock model,
    ``S_bias = c^2 h0 / 2``, ``S_drift = 2 pi^2 c^2 h_-2`` from the Allan-variance
    coefficients of the oscillator; ``None``: no noise)."""
    q = noise.q_continuous()
    GQG = np.zeros((layout.n, layout.n))
    idx = np.arange(3)
    GQG[VEL.start + idx, VEL.start + idx] = q[3:6]
    GQG[ATT.start + idx, ATT.start + idx] = q[0:3]
    sensors = np.arange(9, 21)
    GQG[sensors, sensors] = q[6:18]
    if layout.clock is not None and clock_psd is not None:
        k = np.arange(layout.clock.start, layout.clock.stop)
        GQG[k, k] = np.asarray(clock_psd, dtype=float)
    return GQG


def navigation_matrix(lat, h, v_n, f_n):
    """Navigation block of F (9 x 9: position, velocity, attitude errors).

    Parameters
    ----------
    lat, h : float
        Latitude (rad), ellipsoidal height (m).
    v_n : array_like, shape (3,)
        Velocity NED, m/s.
    f_n : array_like, shape (3,)
        Specific force in n, m/s^2.
    """
    v = np.asarray(v_n, dtype=float)
    f = np.asarray(f_n, dtype=float)
    F = np.zeros((9, 9))
    fill_navigation(F, float(lat), float(h), float(v[0]), float(v[1]), float(v[2]),
                    float(f[0]), float(f[1]), float(f[2]), 1.0)
    return F


# fill_navigation and fill_interval (imported above): the formulas' one source, compiled in
# ins/estimation/core/_kalman_kernels.pyx and called from here and from the filter's kernels.


def sym_matrix(v):
    """``N(v) = [[0, v_z, v_y], [v_z, 0, v_x], [v_y, v_x, 0]]``: the non-orthogonality
    matrix of ``v`` (and ``N(m) w = N(w) m``)."""
    v = np.asarray(v, dtype=float)
    return np.array([[0.0, v[2], v[1]], [v[2], 0.0, v[0]], [v[1], v[0], 0.0]])


def system_matrix(lat, h, v_n, f_n, C_nb, f_b, w_ib_b, corr_time_s, layout=KFGINS):
    """Continuous F (n x n) at one state (the IMU-rate form, for tests and reference).

    Parameters
    ----------
    C_nb : ndarray, shape (3, 3)
    f_b, w_ib_b : array_like, shape (3,)
        Specific force (m/s^2) and angular rate (rad/s) in b.
    corr_time_s : float
        Gauss-Markov correlation time, s.
    """
    C_nb = np.asarray(C_nb)
    integrals = (C_nb, C_nb * np.asarray(w_ib_b)[None, :], C_nb * np.asarray(f_b)[None, :],
                 C_nb @ sym_matrix(w_ib_b), C_nb @ sym_matrix(f_b))
    return interval_matrix(lat, h, v_n, f_n, integrals, 1.0, corr_time_s, layout)


def interval_matrix(lat, h, v_n, f_n, integrals, dt, corr_time_s, layout=KFGINS):
    """``A = int F dt`` over a node interval (n x n).

    Parameters
    ----------
    lat, h, v_n, f_n :
        Mid-interval navigation state and mean specific force in n (see
        :func:`navigation_matrix`).
    integrals : tuple of three or five (3, 3) arrays
        ``S_C = int C_nb dt``, ``S_Cw = int C_nb diag(w_ib_b) dt``,
        ``S_Cf = int C_nb diag(f_b) dt`` (s, rad, m/s) and, for the misalignment groups,
        ``S_CNw = int C_nb N(w_ib_b) dt``, ``S_CNf = int C_nb N(f_b) dt`` (rad, m/s).
    dt : float
        Interval length, s.
    corr_time_s : float
        Decay time of the sensor states, s (``ImuNoise.decay_time_s``; ``inf``: none).
    layout : StateLayout
    """
    S = np.zeros((16, 3))                  # the layout of the filter's accumulators
    S[0:3], S[3:6], S[6:9] = integrals[:3]
    if len(integrals) > 3:
        S[10:13], S[13:16] = integrals[3], integrals[4]
    f = np.asarray(f_n, dtype=float)
    v = np.asarray(v_n, dtype=float)
    A = np.zeros((layout.n, layout.n))
    fill_interval(A, float(lat), float(h), float(v[0]), float(v[1]), float(v[2]), float(f[0]),
                  float(f[1]), float(f[2]), S, float(dt), float(corr_time_s),
                  _start(layout.gyro_misalignment), _start(layout.accel_misalignment),
                  _start(layout.clock))
    return A


def _start(sl):
    return -1 if sl is None else sl.start


#: A variance below ``-VARIANCE_RTOL`` times its scale (the same state's prior or forward
#: variance) is a numerical failure, not rounding: on the test and benchmark flights the
#: smallest ratio of a posterior (or smoothed) variance to its prior is 2e-5, and float64
#: rounding of a 21 x 21 covariance is below 1e-12 of that scale.
VARIANCE_RTOL = 1e-9


def checked_std(var, scale, time=None, names=STATE_NAMES, what="covariance"):
    """Standard deviations from variances, refusing negative variances.

    Parameters
    ----------
    var : array_like, shape (..., k)
        Variances (the diagonal of a covariance, or a stack of diagonals).
    scale : array_like, broadcastable to ``var``
        The variances' natural size (e.g. the prior variance of the same state): a
        variance in ``[-VARIANCE_RTOL * scale, 0)`` is rounding and gives 0.
    time : float or array_like, optional
        Time of each row (s), for the message.
    names : sequence of str
        Names of the ``k`` states.
    what : str
        What the variances belong to, for the message.

    Raises
    ------
    ins.common.errors.QualityError
        A variance below ``-VARIANCE_RTOL * |scale|`` (or not finite): the message names
        the time, the state and the value.
    """
    var = np.asarray(var, dtype=float)
    scale = np.abs(np.broadcast_to(np.asarray(scale, dtype=float), var.shape))
    bad = ~np.isfinite(var) | (var < -VARIANCE_RTOL * scale)
    if np.any(bad):
        from ins.common.errors import QualityError
        idx = np.argwhere(bad)[0]
        row, k = tuple(idx[:-1]), int(idx[-1])
        t = None if time is None else np.asarray(time, dtype=float)
        if t is not None and t.ndim:
            t = t[row] if len(row) else t[0]
        when = "" if t is None else f" at t = {float(t):.3f} s"
        name = names[k] if k < len(names) else f"state {k}"
        raise QualityError(f"numerical failure{when}: the {what} has variance "
                           f"{float(var[tuple(idx)]):.3e} for state {name} (negative "
                           f"beyond rounding: scale {float(scale[tuple(idx)]):.3e}); the "
                           f"covariance lost positive definiteness (implausible noise "
                           f"settings or sigmas in the config?)")
    return np.sqrt(np.maximum(var, 0.0))


def discretize(A, GQG, dt):
    """Transition and process noise of an interval: ``Phi = I + A + A^2/2 + A^3/6``,
    ``Q_d = (Phi GQG Phi^T + GQG) dt / 2``."""
    A2 = A @ A
    Phi = np.eye(len(A)) + A + 0.5 * A2 + (A2 @ A) / 6.0
    Qd = 0.5 * dt * (Phi @ GQG @ Phi.T + GQG)
    return Phi, Qd
