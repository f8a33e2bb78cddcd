"""Tight GNSS/INS coupling: pseudoranges and Doppler range rates as measurements of the
error-state filter, with the receiver clock's bias and drift as states.

What comes in
-------------
:class:`ins.gnss.raw_epochs.RawEpochs` (or any object with its attributes) holds, per
GNSS epoch, plain arrays that the satellite side (RTKLIB through the ``pyrtklib5``
binding, or a simulation) has computed: satellite positions and velocities (ECEF at the signal's transmit time, m
and m/s), and the observations already corrected for everything that does not depend
on the receiver's state:

* ``range_m = P - c TGD + c dt_s - I - T`` (pseudorange less the broadcast group delay,
  plus the satellite clock bias, minus the ionospheric and tropospheric delays), m;
* ``range_rate_mps = -lambda D + c ddt_s`` (Doppler as a range rate, plus the satellite
  clock drift), m/s.

Nothing here knows RINEX or RTKLIB, and nothing is imported from :mod:`ins.gnss`.

Measurement model
-----------------
With the antenna ``r`` (ECEF, from the INS position, the lever arm and the record's
time, as :class:`~ins.estimation.core.measurements.GnssPosition` predicts it), the unit
line of sight ``e = (r_s - r) / |r_s - r|`` and ``omega_ie`` the Earth rate::

    range      = |r_s - r| + omega_ie (x_s y - y_s x) / c + b
    range rate = e . (v_s - v) + omega_ie (v_s,x y + x_s v_y - v_s,y x - y_s v_x) / c + d

(the Sagnac terms are the Earth's rotation during the signal's travel, to first order:
below 1 mm against the exact rotation); ``b`` (m) and ``d`` (m/s) are the receiver clock
bias ``c dt_r`` and drift ``c ddt_r``, states of the layout's ``clock`` group
(:mod:`ins.estimation.core.error_model`: ``b' = d``, white noise on both; truth minus
estimate, fed back as ``estimate += dx``).  The rows of ``H`` are those of the antenna
position (velocity) measurement projected on the line of sight in n: ``-e_n^T H_pos``
(``-e_n^T H_vel``, plus the line of sight's turn with the antenna position,
``-(v_rel - e (e . v_rel))^T / |r_s - r|`` times ``H_pos``), and ``-1`` in the clock
column.  Between two updates the clock
estimate is advanced by ``b += d dt`` (:meth:`TightUpdater.update`); the filter's stored
clock estimate at fill-in nodes without GNSS is the last updated one.

Weights, mask, screening
------------------------
A satellite below ``elevation_mask_deg`` (seen from the INS antenna position) is not
used.  Pseudorange sigma ``sigma^2 = a^2 + b^2 / sin^2(el)`` (RTKLIB's form), plus
``c_snr^2 10^(0.1 max(snr_ref - snr, 0))`` when SNR weighting is on; the range rate's
likewise with its own ``a``, ``b``.  Each satellite's pseudorange and range rate are
tested on their own (``z^2 / S`` against the chi-square quantile of one degree of
freedom at the filter's ``reject_probability``, ``S`` from the epoch's prior
covariance), so one bad satellite does not reject the epoch; the accepted rows are then
applied in one update.  One, two or three satellites are used as they come: each is a
scalar constraint on position along its line of sight and on the clock.

Several constellations: the receiver clock is the first system's (GPS when there is
one); each other system's pseudoranges carry its inter-system bias, the layout's
``isb`` group (:data:`ISB_SYSTEMS`; random constants, initialized from the first epoch
by :meth:`TightUpdater._init_clock`).  GLONASS's inter-frequency code biases between
channels (decimetres on some receivers) are not modelled.
"""
from dataclasses import dataclass, field

import numpy as np

from ins.estimation.core import _filter_kernels
from ins.estimation.core.measurements import (
    GnssPosition,
    GnssVelocity,
    NavPoint,
    UpdateRecord,
    kalman_update,
    node_acceleration,
)
from ins.estimation.core.updates import Updater
from ins.nav import earth

__all__ = ["CLOCK_JUMP_SIGMAS", "CLOCKS", "apply_rows", "satellites_used", "clock_psd", "TightOptions", "TightUpdater", "line_of_sight", "range_rows",
           "sagnac_range", "sagnac_range_rate", "CLIGHT", "ISB_SYSTEMS"]

CLIGHT = 299792458.0
#: The systems of the layout's ``isb`` group, in its order (GPS is the clock's).
ISB_SYSTEMS = "RECJ"


def sagnac_range(r_sat_e, r_e):
    """Geometric range with the Sagnac correction, m: ``|r_s - r| + omega_ie (x_s y -
    y_s x) / c``; ``r_sat_e`` (k, 3), ``r_e`` (3,) ECEF, m."""
    d = np.asarray(r_sat_e, float) - r_e
    return (np.linalg.norm(d, axis=-1)
            + earth.OMEGA_IE * (r_sat_e[..., 0] * r_e[1] - r_sat_e[..., 1] * r_e[0]) / CLIGHT)


def sagnac_range_rate(r_sat_e, v_sat_e, r_e, v_e):
    """Range rate with the Sagnac term, m/s: ``e . (v_s - v) + omega_ie (v_s,x y + x_s
    v_y - v_s,y x - y_s v_x) / c``, the time derivative of :func:`sagnac_range`; ECEF,
    m and m/s.  (The term with the opposite sign, as some RTKLIB versions' ``resdop``
    write it, is about 9 mm/s off for a GPS satellite; the test checks the sign against
    the exact rotation of the Earth during the travel.)"""
    d = np.asarray(r_sat_e, float) - r_e
    e = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return (np.sum(e * (v_sat_e - v_e), axis=-1)
            + earth.OMEGA_IE / CLIGHT * (v_sat_e[..., 0] * r_e[1] + r_sat_e[..., 0] * v_e[1]
                                         - v_sat_e[..., 1] * r_e[0] - r_sat_e[..., 1] * v_e[0]))


def line_of_sight(r_sat_e, lla):
    """Unit lines of sight from ``lla`` (lat, lon rad, h m) to the satellites, in n
    (NED), shape (k, 3), and their elevations, rad."""
    r_e = earth.lla_to_ecef(*lla)
    d = np.asarray(r_sat_e, float) - r_e
    e_e = d / np.linalg.norm(d, axis=-1, keepdims=True)
    e_n = e_e @ earth.dcm_en(lla[0], lla[1])
    return e_n, np.arcsin(np.clip(-e_n[:, 2], -1.0, 1.0))


_C = 299792458.0


def clock_psd(h0, h_2):
    """Spectral densities ``(S_bias m^2/s, S_drift m^2/s^3)`` of the two-state clock
    model from the Allan-variance coefficients ``h0`` (white frequency, s) and ``h_-2``
    (random-walk frequency, 1/s): ``S_b = c^2 h0 / 2``, ``S_d = 2 pi^2 c^2 h_-2``
    (Brown and Hwang, the two-state clock model, flicker noise left out)."""
    return (0.5 * _C ** 2 * h0, 2.0 * np.pi ** 2 * _C ** 2 * h_2)


#: Receiver clocks of ``[gnss] receiver_clock`` (tight coupling): ``(h0, h_-2)``.  The
#: TCXO of a u-blox or phone receiver (h0 2e-19, h-2 2e-20: its drift wanders about
#: 0.2 m/s per sqrt(s), which leaves one or two satellites weak) and an OCXO (h0 8e-20,
#: h-2 4e-23) of a geodetic receiver.
CLOCKS = {"tcxo": (2e-19, 2e-20), "ocxo": (8e-20, 4e-23)}


@dataclass(frozen=True)
class TightOptions:
    """Options of tight coupling (SI unless the name says so).

    Parameters
    ----------
    elevation_mask_deg : float
        Satellites below are not used, deg.
    range_sigma_m : (float, float)
        ``(a, b)`` of the pseudorange sigma ``sqrt(a^2 + b^2 / sin^2 el)``, m.
    range_rate_sigma_mps : (float, float)
        The same for the range rate, m/s.
    snr_ref_dbhz, snr_sigma_m : float
        SNR weighting: ``snr_sigma_m^2 10^(0.1 max(snr_ref - snr, 0))`` added to the
        pseudorange variance (0: off), m.
    use_doppler : bool
        Use the range rates.
    noise : ins.estimation.coupling.range_noise.RangeNoise, optional
        Noise models per receiver (estimated from the data) in place of the sigmas
        above, and the IGG-III down-weighting of the accepted rows
        (:mod:`ins.estimation.coupling.range_noise`).
    keep_samples : bool
        Keep every tested row's innovation for the noise fit (``updater.samples``).
    """

    elevation_mask_deg: float = 10.0
    range_sigma_m: tuple = (0.3, 0.3)
    range_rate_sigma_mps: tuple = (0.05, 0.05)
    snr_ref_dbhz: float = 45.0
    snr_sigma_m: float = 0.0
    use_doppler: bool = True
    noise: object = None
    keep_samples: bool = False


def range_rows(point, r_sat_e, v_sat_e, time, systems=None):
    """Predicted pseudoranges and range rates (without and with the clock) and their
    ``H`` rows at ``point`` (:class:`~ins.estimation.core.measurements.NavPoint`; without the
    layout's ``clock`` group, as for double differences, no clock term and column) for satellites at ``r_sat_e``, ``v_sat_e`` (k, 3) ECEF.

    With the layout's ``isb`` group and ``systems`` (one RINEX letter per satellite),
    a satellite of GLONASS, Galileo, BeiDou or QZSS has its system's inter-system bias
    added to the range (column ``-1``).

    Returns
    -------
    rho, rate : ndarray (k,)
        Predicted range (m) and range rate (m/s), clock included.
    H_rho, H_rate : ndarray (k, n)
    elevation : ndarray (k,)
        rad, at the predicted antenna.
    """
    L = point.layout
    pos = GnssPosition(time, np.zeros(3), np.eye(3))
    vel = GnssVelocity(time, np.zeros(3), np.eye(3))
    lla = pos.predict(point)
    r_e = earth.lla_to_ecef(*lla)
    C_en = earth.dcm_en(lla[0], lla[1])
    v_e = C_en @ vel.predict(point)
    e_n, el = line_of_sight(r_sat_e, lla)
    clock = (0.0, 0.0) if L.clock is None else L.estimate(point.sensors, "clock")
    rho = sagnac_range(r_sat_e, r_e) + clock[0]
    rate = sagnac_range_rate(r_sat_e, v_sat_e, r_e, v_e) + clock[1]
    H_pos = pos.jacobian(point)
    H_rho = -e_n @ H_pos
    # the range rate also moves with the antenna position through the line of sight:
    # d(e . v_rel)/dr = -(v_rel - e (e . v_rel)) / |r_s - r|, v_rel = v_s - v
    d = np.asarray(r_sat_e, float) - r_e
    dist = np.linalg.norm(d, axis=-1, keepdims=True)
    e_e = d / dist
    v_rel = np.asarray(v_sat_e, float) - v_e
    g_n = (-(v_rel - e_e * np.sum(e_e * v_rel, axis=-1, keepdims=True)) / dist) @ C_en
    H_rate = -e_n @ vel.jacobian(point) + g_n @ H_pos
    if L.clock is not None:
        H_rho[:, L.clock.start] = -1.0
        H_rate[:, L.clock.start + 1] = -1.0
    if L.isb is not None and systems is not None:
        isb = L.estimate(point.sensors, "isb")
        for i, s in enumerate(systems):
            j = ISB_SYSTEMS.find(s)
            if j >= 0:
                rho[i] += isb[j]
                H_rho[i, L.isb.start + j] = -1.0
    return rho, rate, H_rho, H_rate, el


@dataclass
class _Epoch:
    """Counts of one tight epoch, for the summary."""

    time: float
    visible: int
    used: int
    rejected: int = 0
    extra: dict = field(default_factory=dict)


#: A common offset of an epoch's pseudoranges beyond this many of the sigmas the filter
#: expects is a jump of the receiver clock (:meth:`TightUpdater._clock_jump`).
CLOCK_JUMP_SIGMAS = 20.0


class TightUpdater(Updater):
    """The filter's GNSS update for :class:`ins.gnss.raw_epochs.RawEpochs`
    (``FilterSettings.updater``):
    per epoch the pseudoranges and range rates of the satellites above the mask,
    screened one by one, then applied together (module notes).

    Use ``functools.partial(TightUpdater, options=TightOptions(...))`` as the factory.

    Attributes
    ----------
    epochs : list of _Epoch
        Satellites visible, used and rejected per epoch.
    """

    def __init__(self, settings, gnss, options=None):
        if settings.layout.clock is None:
            raise ValueError("tight coupling needs the 'clock' state group in the layout")
        super().__init__(settings, gnss)
        self.opt = options or TightOptions()
        self.t_clock = None            # epoch of the clock estimate (s)
        self._clock_set = False
        self.epochs = []
        self.clock_jumps = []          # (time s, jump m) of the receiver clock
        # (kind 0 code / 1 range rate, el rad, snr dB-Hz, innovation, H P H^T) of every
        # tested row: what range_noise.fit_receiver estimates the noise from
        self.samples = []

    def _sigmas(self, el, snr):
        o = self.opt
        if o.noise is not None:
            return o.noise.receiver("rover").variances(el, snr)
        s_el = np.maximum(np.sin(el), 1e-3)
        var_r = o.range_sigma_m[0] ** 2 + (o.range_sigma_m[1] / s_el) ** 2
        if o.snr_sigma_m > 0 and snr is not None:
            var_r = var_r + o.snr_sigma_m ** 2 * 10.0 ** (0.1 * np.maximum(
                o.snr_ref_dbhz - np.asarray(snr, float), 0.0))
        var_d = o.range_rate_sigma_mps[0] ** 2 + (o.range_rate_sigma_mps[1] / s_el) ** 2
        return var_r, var_d

    def _advance_clock(self, t, sensors):
        """``b += d (t - t_clock)``: the clock estimate carried to ``t`` (in place)."""
        k = self.layout.clock.start - 9
        if self.t_clock is not None:
            sensors[k] += sensors[k + 1] * (t - self.t_clock)
        self.t_clock = t

    def update(self, e, t_row, state, sensors, P, w_meas_b, f_meas_b=None):
        """Process epoch ``ev_record[e]`` at the node of time ``t_row``; returns
        ``(P, dx)`` like :meth:`Updater.update`."""
        g, L = self.gnss, self.layout
        k = self.ev_record[e]
        tg = g.time[k]
        dx = np.zeros(L.n)
        self._advance_clock(t_row, sensors)
        a_n = None if f_meas_b is None else node_acceleration(state, f_meas_b)
        l_b, dl_b, valid = self.s.lever.at(tg)
        if not valid[0]:
            self.n_fallback += 1
        point = NavPoint(t_row, state, sensors, L, w_meas_b, l_b[0], dl_b[0], a_n)
        r_s, v_s = np.asarray(g.sat_pos_e[k], float), np.asarray(g.sat_vel_e[k], float)
        y_r = np.asarray(g.range_m[k], float)
        y_d = np.asarray(g.range_rate_mps[k], float)
        snr = None if g.snr_dbhz is None else g.snr_dbhz[k]
        names = g.names[k]
        sysl = [n[0] for n in names]
        ep = _Epoch(tg, len(y_r), 0)
        self.epochs.append(ep)
        if len(y_r) == 0:
            return P, dx
        rho, rate, H_r, H_d, el = range_rows(point, r_s, v_s, tg, sysl)
        up = (el >= np.deg2rad(self.opt.elevation_mask_deg)) & np.isfinite(y_r)
        if not np.any(up):
            return P, dx
        if not self._clock_set:
            self._init_clock(sensors, rho, rate, y_r, y_d, up, sysl)
            rho, rate, H_r, H_d, el = range_rows(point, r_s, v_s, tg, sysl)
        var_r, var_d = self._sigmas(el, snr)
        P = self._clock_jump(tg, sensors, P, rho, y_r, var_r, up)
        if self.clock_jumps and self.clock_jumps[-1][0] == tg:
            rho, rate, H_r, H_d, el = range_rows(point, r_s, v_s, tg, sysl)
        rows, z, R = [], [], []
        thr = self._threshold(1)
        cand = [(i, "pseudorange", "m", rho[i] - y_r[i], H_r[i], var_r[i]) for i in
                np.flatnonzero(up)]
        if self.opt.use_doppler:
            cand += [(i, "range_rate", "m/s", rate[i] - y_d[i], H_d[i], var_d[i]) for i in
                     np.flatnonzero(up & np.isfinite(y_d))]
        if self.opt.keep_samples:
            self._sample(cand, el, snr, P)
        used = set()
        robust = self.opt.noise is not None and self.opt.noise.robust
        for i, name, unit, zi, h, r in cand:
            hph = float(h @ P @ h)
            s = hph + r
            nis = zi * zi / s
            ok = bool(nis <= thr)
            if ok and robust:
                from ins.estimation.coupling.range_noise import igg3_inflation
                r = r * float(igg3_inflation(np.sqrt(nis), np.sqrt(thr),
                                             self.opt.noise.k0))
            self.records.append(UpdateRecord(name, (names[i],), unit, tg, np.array([zi]),
                                             np.array([np.sqrt(s)]), nis, ok))
            if ok:
                rows.append(h)
                z.append(zi)
                R.append(r)
                if name == "pseudorange":
                    used.add(i)
            else:
                self.n_rejected += 1
                ep.rejected += 1
        ep.used = len(used)
        if not rows:
            return P, dx
        return apply_rows(self, point, P, np.array(rows), np.diag(R), np.array(z), k)

    name = "gnss_tight"

    def _sample(self, cand, el, snr, P):
        """Keep the epoch's innovations for the noise estimation (:attr:`samples`,
        :func:`ins.estimation.coupling.range_noise.epoch_samples`)."""
        from ins.estimation.coupling.range_noise import epoch_samples
        for kind, name in enumerate(("pseudorange", "range_rate")):
            c = [x for x in cand if x[1] == name]
            if len(c) >= 3:
                i = [x[0] for x in c]
                self.samples += epoch_samples(kind, el[i], None if snr is None else
                                              np.asarray(snr, float)[i],
                                              [x[3] for x in c], np.array([x[4] for x in c]), P)

    def _clock_jump(self, t, sensors, P, rho, y_r, var_r, up):
        """A receiver clock that jumped (a millisecond reset of a u-blox or phone
        receiver: 300 km in every pseudorange) would have every satellite rejected from
        then on.  When at least two satellites agree on a common offset of the ranges
        that is beyond :data:`CLOCK_JUMP_SIGMAS` of what the filter expects, and at least
        half of them agree on it within their sigmas after its removal, the clock bias is
        set again: ``b += offset``, its covariance back to the prior with no
        correlation.  The jump is recorded (:attr:`clock_jumps`); returns ``P``."""
        i = np.flatnonzero(up)
        if i.size < 2:
            return P
        c = self.layout.clock.start
        d = y_r[i] - rho[i]
        off = float(np.median(d))
        expected = np.sqrt(P[c, c] + float(np.median(var_r[i])) + np.trace(P[:3, :3]))
        if abs(off) <= CLOCK_JUMP_SIGMAS * expected:
            return P
        agree = np.abs(d - off) <= 5.0 * np.sqrt(var_r[i] + np.trace(P[:3, :3]))
        if 2 * np.count_nonzero(agree) < i.size or np.count_nonzero(agree) < 2:
            return P
        sensors[c - 9] += off
        P = P.copy()
        P[c, :] = P[:, c] = 0.0
        P[c, c] = self.s.clock_bias_std_m ** 2
        self.clock_jumps.append((t, off))
        return P

    def _init_clock(self, sensors, rho, rate, y_r, y_d, up, systems=None):
        """The clock estimate from the first epoch: the median of the measured minus
        predicted ranges (range rates) of the satellites above the mask (of the first
        system seen; each other system's inter-system bias from its own satellites, when
        the layout has them)."""
        L = self.layout
        k = L.clock.start - 9
        sysl = np.array(systems if systems is not None else ["G"] * len(y_r))
        first = next(s for s in "GRECJ" if np.any(up & (sysl == s)))
        d = y_r - rho
        clock = float(np.median(d[up & (sysl == first)]))
        sensors[k] += clock
        if L.isb is not None:
            for j, s in enumerate(ISB_SYSTEMS):
                m = up & (sysl == s)
                if np.any(m) and s != first:
                    sensors[L.isb.start - 9 + j] += float(np.median(d[m])) - clock
        ok = up & np.isfinite(y_d)
        if np.any(ok):
            sensors[k + 1] += float(np.median(y_d[ok] - rate[ok]))
        self._clock_set = True

    def satellites_used(self):
        """``(min, mean, max)`` satellites used per epoch (0s included)."""
        return satellites_used(self.epochs)


def satellites_used(epochs):
    """``(min, mean, max)`` of ``ep.used`` over the epochs (0s included)."""
    n = np.array([ep.used for ep in epochs]) if epochs else np.zeros(1)
    return int(n.min()), float(n.mean()), int(n.max())


def apply_rows(updater, point, P, H, R, z, k):
    """The accepted rows of one epoch in one update (``kalman_update`` with no test: the
    rows were screened one satellite at a time), fed back into ``point``; the summary's
    NIS is of 3-dof position records: the epoch's NIS per row times 3 (its mean stays 3
    for a consistent filter), and no NED position innovation exists.  Returns
    ``(P, dx)`` like :meth:`ins.estimation.core.updates.Updater.update`."""
    x, P, nis, _ = kalman_update(P, H, R, z, np.inf, updater)
    updater.nis.append(nis / len(z) * 3.0)
    updater.nis_record.append(k)
    updater.innovation.append(np.full(3, np.nan))
    _filter_kernels.correct_state(point.state, x)
    point.sensors += x[updater.layout.sensors]
    updater.n_updates += 1
    return P, x
