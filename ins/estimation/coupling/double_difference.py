"""Tight GNSS/INS coupling against a base station: double-differenced pseudoranges and
range rates as measurements of the error-state filter (and so of the RTS smoother).

What comes in
-------------
The rover's :class:`ins.gnss.raw_epochs.RawEpochs` with the paired base epochs in its
``base`` attribute (:class:`ins.gnss.raw_pairs.PairedEpochs`: the base antenna ``r_e``
and, per rover epoch, the base's corrected ranges and range rates with the satellite
positions and velocities at the base's own transmit times), or any object with these
attributes.  Nothing is imported from :mod:`ins.gnss`.

Measurement model
-----------------
For a satellite ``i`` seen by both receivers, the single difference of the corrected
observations (rover minus base, :mod:`ins.estimation.coupling.pseudorange`'s model at each)

    SD_i = (rho_r,i + b_r) - (rho_b,i + b_b)

with ``rho`` the Sagnac ranges (rates) at each receiver; the base's ``rho_b,i`` is known
(static base at ``r_e``).  The double difference against a reference satellite ``k``,
``DD_i = SD_i - SD_k``, cancels both receiver clocks: **no clock states** are carried in
this mode (the layout has no ``clock`` group; the rows have no clock column).  The
satellite clocks cancel already in each SD; for a short baseline most of the broadcast
orbit error (``|baseline| / range`` of it: below 1 mm per metre of orbit error at 3 km)
and most of the ionospheric and tropospheric delays cancel too, what the models of each
receiver leave differing between the two sites: the ionosphere's decorrelation (a few
mm to cm per 10 km), the troposphere's wet part between two heights (cm for hundreds of
metres, not modelled beyond Saastamoinen), and the multipath and noise of both
receivers, which do not cancel.

A base without Doppler (RINEX 2 files of a reference station often have none): the
static base's range rate is known but for the satellite clock drift's error (mm/s), so
its predicted value stands in for the measurement, with no variance; the range-rate
"DDs" are then the rover's between-satellite differences, which still cancel its clock
drift.

Rows: ``H_DD,i = H_i - H_k``, ``H_i`` the rover's row of
:func:`ins.estimation.coupling.pseudorange.range_rows` (line of sight projected on the antenna
position / velocity); innovation ``predicted - measured`` of the DD.  Covariance: with
per satellite ``s_i = sigma_r,i^2 + sigma_b,i^2`` (``a^2 + b^2 / sin^2 el`` at the rover
and at the base, each with its own elevation), the SD covariance is ``Sigma =
diag(s)`` and the DDs' is ``D Sigma D^T = diag(s_i) + s_k 1 1^T``: not diagonal (the
reference's error is in every DD).  With this covariance the update does not depend on
which satellite is the reference (the DDs of one reference are an invertible linear map
of another's): a change of the reference when it sets needs no care for codes and
Doppler; it is kept while it is usable (fewer changes in the innovation file) and
otherwise the highest common satellite is taken.  Two common satellites give one DD,
which is used; three give two, four give three.

Screening
---------
Per satellite, not per DD row: a blunder on satellite ``j`` shifts the DDs by ``c_j =
D e_j`` (``e_j`` in the SD space: one DD for a satellite, every DD with the opposite sign
for the reference).  Baarda's w-test ``w_j = (c_j^T S^-1 z)^2 / (c_j^T S^-1 c_j)`` (chi-square of one degree of
freedom, the filter's ``reject_probability``) with ``S = H P H^T + D Sigma D^T``; the
satellite with the largest ``w`` beyond the threshold is dropped and the test redone on
the others (a new reference if it was the reference).  With two satellites a failed DD
cannot name its satellite: both are dropped.  Pseudoranges and range rates are screened
on their own; the accepted rows of both are applied in one update.  The records (the
innovation file) name a DD ``G07-G28`` (satellite, reference) and a rejected satellite
alone, with its w as the NIS and no innovation.
"""
from dataclasses import dataclass

import numpy as np

from ins.estimation.core.measurements import NavPoint, UpdateRecord, node_acceleration
from ins.estimation.coupling.pseudorange import (
    TightOptions,
    _Epoch,
    apply_rows,
    line_of_sight,
    range_rows,
    sagnac_range,
    sagnac_range_rate,
    satellites_used,
)
from ins.estimation.core.updates import Updater

__all__ = ["dd_operator", "dd_covariance", "w_test", "screen", "single_difference_rows",
           "DoubleDifferenceUpdater"]


def dd_operator(n, ref):
    """The ``(n - 1, n)`` matrix ``D`` of double differences against satellite ``ref``
    (row for each other satellite ``i``: ``+1`` at ``i``, ``-1`` at ``ref``)."""
    others = [i for i in range(n) if i != ref]
    D = np.zeros((n - 1, n))
    D[np.arange(n - 1), others] = 1.0
    D[:, ref] = -1.0
    return D


def dd_covariance(var_sd, ref):
    """``D diag(var_sd) D^T`` of :func:`dd_operator` (variances of the single
    differences, any unit squared)."""
    D = dd_operator(len(var_sd), ref)
    return (D * np.asarray(var_sd, float)) @ D.T


def w_test(z, S, D):
    """Baarda's w statistics of a blunder on each satellite (columns of ``D``) for DD
    innovations ``z`` with covariance ``S``: ``(c^T S^-1 z)^2 / (c^T S^-1 c)``, shape
    (n,); each chi-square of one degree of freedom when there is none."""
    from scipy.linalg import cho_factor, cho_solve
    cf = cho_factor(0.5 * (S + S.T), lower=True)
    Siz = cho_solve(cf, z)
    SiD = cho_solve(cf, D)
    return (D.T @ Siz) ** 2 / np.maximum(np.einsum("ij,ij->j", D, SiD), 1e-300)


def single_difference_rows(point, r_sat_e, v_sat_e, r_sat_base_e, v_sat_base_e, r_base_e,
                           time):
    """Predicted single differences (rover minus base) of range and range rate and the
    rover's ``H`` rows, for satellites seen by both receivers.

    Parameters
    ----------
    point : ins.estimation.core.measurements.NavPoint
        The rover (its layout without the ``clock`` group).
    r_sat_e, v_sat_e : ndarray (k, 3)
        Satellites at the rover's transmit times, ECEF m and m/s.
    r_sat_base_e, v_sat_base_e : ndarray (k, 3)
        The same satellites at the base's transmit times.
    r_base_e : ndarray (3,)
        The static base antenna, ECEF m.
    time : float
        The epoch (s) at which the antenna position is predicted.

    Returns
    -------
    sd_range, sd_rate : ndarray (k,)
        m, m/s (no clock terms: they cancel in the double differences).
    H_range, H_rate : ndarray (k, n)
    el_rover : ndarray (k,)
        Elevations at the predicted antenna, rad.
    """
    rho, rate, H_r, H_d, el = range_rows(point, r_sat_e, v_sat_e, time)
    rho_b = sagnac_range(r_sat_base_e, r_base_e)
    rate_b = sagnac_range_rate(r_sat_base_e, v_sat_base_e, r_base_e, np.zeros(3))
    return rho - rho_b, rate - rate_b, H_r, H_d, el


def screen(z_sd, H_sd, var_sd, P, ref, threshold, el=None):
    """Per-satellite screening of double differences by the w-test (module notes).

    Parameters
    ----------
    z_sd : ndarray (k,)
        Single-difference innovations (predicted minus measured).
    H_sd : ndarray (k, n)
    var_sd : ndarray (k,)
        Single-difference variances.
    P : ndarray (n, n)
        Prior covariance.
    ref : int
        The preferred reference satellite (index into the k).
    threshold : float
        Chi-square quantile of one degree of freedom.
    el : ndarray (k,), optional
        Elevations: a new reference is the highest remaining satellite (default: the
        first).

    Returns
    -------
    kept : list of int
        Satellites kept (empty when fewer than two remain).
    ref : int or None
        The reference among them.
    rejected : list of (int, float)
        Dropped satellites with the w statistic that dropped them, in order.
    """
    el = np.zeros(len(z_sd)) if el is None else np.asarray(el, float)
    idx, rejected = list(range(len(z_sd))), []
    while len(idx) >= 2:
        if ref not in idx:
            ref = idx[int(np.argmax(el[idx]))]
        r = idx.index(ref)
        D = dd_operator(len(idx), r)
        H = D @ H_sd[idx]
        S = H @ P @ H.T + dd_covariance(var_sd[idx], r)
        w = w_test(D @ z_sd[idx], S, D)
        j = int(np.argmax(w))
        if w[j] <= threshold:
            return idx, ref, rejected
        drop = [idx[j]] if len(idx) > 2 else list(idx)   # two: which one is not known
        rejected += [(i, float(w[j])) for i in drop]
        idx = [i for i in idx if i not in drop]
    return [], None, rejected


#: The kinds IGG-III down-weights (code and Doppler, not the carrier).
_ROBUST_KINDS = ("dd_pseudorange", "dd_range_rate")


@dataclass
class _Kind:
    """One observation type of an epoch: SD innovations, rows, variances."""

    name: str
    unit: str
    z: np.ndarray
    H: np.ndarray
    var: np.ndarray
    var_b: np.ndarray = None       # the base's part of var (noise estimation)


class DoubleDifferenceUpdater(Updater):
    """The filter's GNSS update with double differences against a base (module notes),
    for :class:`ins.gnss.raw_pairs.PairedEpochs` (``FilterSettings.updater``; the layout
    without the ``clock`` group).

    Use ``functools.partial(DoubleDifferenceUpdater, options=TightOptions(...))``.

    Attributes
    ----------
    epochs : list
        Satellites common to both receivers (``visible``), used in the pseudorange DDs
        (reference included) and rejected, per epoch.
    reference : list of str
        The reference satellites of each epoch's pseudoranges, one per constellation,
        comma-separated ('' when none).
    ref_changes : int
        How often the reference changed.
    """

    name = "gnss_dd"

    def __init__(self, settings, gnss, options=None):
        if getattr(gnss, "base", None) is None:
            raise ValueError("double differences need the base's epochs (gnss.base)")
        super().__init__(settings, gnss)
        self.opt = options or TightOptions()
        self.base_name = getattr(gnss.base, "name", "base")
        self.epochs, self.reference = [], []
        self.ref_changes = 0
        self._refs = {}                # system letter -> reference satellite
        self.used = {}                 # kind name -> satellites in its last accepted DDs
        # rover samples (kind, el, snr, SD innovation less the epoch's centre, H P H^T +
        # the base's variance) for range_noise.fit_receiver
        self.samples = []
        import pymap3d
        self._base_lla = np.array(pymap3d.ecef2geodetic(*gnss.base.r_e, deg=False))

    # ------------------------------------------------------------------ model
    def _var(self, el, sigma, which=None, kind=0, snr=None):
        """Variances at elevations ``el`` (rad): ``a^2 + b^2 / sin^2 el`` of ``sigma``,
        or with a receiver ``which`` (``"rover"``, ``"base"``) and ``TightOptions.noise``
        its model for ``kind`` (0 code, 1 range rate)."""
        if which is not None and self.opt.noise is not None:
            return self.opt.noise.receiver(which).variances(el, snr)[kind]
        s_el = np.maximum(np.sin(el), 1e-3)
        return sigma[0] ** 2 + (sigma[1] / s_el) ** 2

    def _choose_refs(self, names, el):
        """Per constellation (the names' first letter): the previous reference if
        present and usable (``el`` finite: above the masks), else the highest satellite;
        returns ``{system: index}``, counts the changes."""
        out = {}
        for s in sorted({n[0] for n in names}):
            idx = [i for i, n in enumerate(names) if n[0] == s and np.isfinite(el[i])]
            if not idx:
                continue
            old = self._refs.get(s)
            if old in names and names.index(old) in idx:
                out[s] = names.index(old)
                continue
            k = max(idx, key=lambda i: el[i])
            if old is not None:
                self.ref_changes += 1
            self._refs[s] = names[k]
            out[s] = k
        return out

    def update(self, e, t_row, state, sensors, P, w_meas_b, f_meas_b=None):
        """Process epoch ``ev_record[e]`` at the node of time ``t_row``; returns
        ``(P, dx)`` like :meth:`Updater.update`."""
        c = self._epoch(e, t_row, state, sensors, w_meas_b, f_meas_b)
        if c is None:
            return P, np.zeros(self.layout.n)
        H, z, R = self._screened(c, c.kinds, P)
        if not z:
            return P, np.zeros(self.layout.n)
        from scipy.linalg import block_diag
        return apply_rows(self, c.point, P, np.vstack(H), block_diag(*R), np.concatenate(z),
                          c.k)

    def _epoch(self, e, t_row, state, sensors, w_meas_b, f_meas_b):
        """The epoch's common satellites, predictions and code/Doppler kinds (a
        namespace), or ``None`` when fewer than two common satellites are above the
        masks."""
        from types import SimpleNamespace
        g, L, b = self.gnss, self.layout, self.gnss.base
        k = self.ev_record[e]
        tg = g.time[k]
        a_n = None if f_meas_b is None else node_acceleration(state, f_meas_b)
        l_b, dl_b, valid = self.s.lever.at(tg)
        if not valid[0]:
            self.n_fallback += 1
        point = NavPoint(t_row, state, sensors, L, w_meas_b, l_b[0], dl_b[0], a_n)
        sats_b = list(np.asarray(b.sats[k]).tolist())
        ir, ib = [], []
        for i, s in enumerate(np.asarray(g.sats[k]).tolist()):
            if s in sats_b:
                j = sats_b.index(s)
                if np.isfinite(g.range_m[k][i]) and np.isfinite(b.range_m[k][j]):
                    ir.append(i)
                    ib.append(j)
        ep = _Epoch(tg, len(ir), 0)
        self.epochs.append(ep)
        self.reference.append("")
        if len(ir) < 2:
            return None
        ir, ib = np.array(ir), np.array(ib)
        names = [g.names[k][i] for i in ir]
        r_s, v_s = np.asarray(g.sat_pos_e[k], float)[ir], np.asarray(g.sat_vel_e[k], float)[ir]
        rs_b = np.asarray(b.sat_pos_e[k], float)[ib]
        vs_b = np.asarray(b.sat_vel_e[k], float)[ib]
        sd_r, sd_d, H_r, H_d, el = single_difference_rows(point, r_s, v_s, rs_b, vs_b,
                                                          b.r_e, tg)
        _, el_b = line_of_sight(rs_b, self._base_lla)
        mask = np.deg2rad(self.opt.elevation_mask_deg)
        up = (el >= mask) & (el_b >= mask)
        y_r, y_rb = np.asarray(g.range_m[k], float)[ir], np.asarray(b.range_m[k], float)[ib]
        snr_r = None if g.snr_dbhz is None else np.asarray(g.snr_dbhz[k], float)[ir]
        snr_b = (None if getattr(b, "snr_dbhz", None) is None
                 else np.asarray(b.snr_dbhz[k], float)[ib])
        var_b = self._var(el_b, self.opt.range_sigma_m, "base", 0, snr_b)
        kinds = [(_Kind("dd_pseudorange", "m", sd_r - (y_r - y_rb), H_r,
                        self._var(el, self.opt.range_sigma_m, "rover", 0, snr_r) + var_b,
                        var_b), up)]
        if self.opt.use_doppler:
            y_d = np.asarray(g.range_rate_mps[k], float)[ir]
            y_db = np.asarray(b.range_rate_mps[k], float)[ib]
            # no base Doppler: the static base's range rate as predicted (exact but for
            # the satellite clock drift's error, mm/s), with no variance of its own
            has_b = np.isfinite(y_db)
            y_db = np.where(has_b, y_db, sagnac_range_rate(rs_b, vs_b, b.r_e, np.zeros(3)))
            vd_b = has_b * self._var(el_b, self.opt.range_rate_sigma_mps, "base", 1, snr_b)
            kinds.append((_Kind("dd_range_rate", "m/s", sd_d - (y_d - y_db), H_d,
                                self._var(el, self.opt.range_rate_sigma_mps, "rover", 1,
                                          snr_r) + vd_b, vd_b),
                          up & np.isfinite(y_d)))
        if np.count_nonzero(up) < 2:
            return None
        refs = self._choose_refs(names, np.where(up, el, -np.inf))
        sysl = np.array([n[0] for n in names])
        return SimpleNamespace(k=k, tg=tg, point=point, ep=ep, names=names, ir=ir, ib=ib,
                               sd_r=sd_r, H_r=H_r, el=el, el_b=el_b, up=up, kinds=kinds,
                               refs=refs, sys=sysl, snr=snr_r)

    def _screened(self, c, kinds, P):
        """Screen each kind's double differences (:func:`screen`), within each
        constellation against its own reference, and record them; returns the accepted
        ``(H blocks, z blocks, R blocks)``."""
        H_all, z_all, R_blocks = [], [], []
        thr = self._threshold(1)
        names, tg, ep = c.names, c.tg, c.ep
        refs_used = []
        for n_kind, (kind, ok) in enumerate(kinds):
            used = []
            for system in sorted(set(c.sys.tolist())):
                sub = np.flatnonzero(ok & (c.sys == system))
                if len(sub) < 2:           # one satellite of a system: no DD
                    continue
                if self.opt.keep_samples:
                    self._sample(n_kind, kind, sub, c, P)
                r0 = c.refs.get(system)
                pref = int(np.searchsorted(sub, r0)) if r0 in sub else -1
                kept, ref, rejected = screen(kind.z[sub], kind.H[sub], kind.var[sub], P,
                                             pref, thr, c.el[sub])
                for i, w in rejected:
                    self.records.append(UpdateRecord(kind.name, (names[sub[i]],), kind.unit,
                                                     tg, np.array([np.nan]),
                                                     np.array([np.nan]), w, False))
                    self.n_rejected += 1
                    ep.rejected += 1
                if not kept:
                    continue
                idx, ref = [int(sub[i]) for i in kept], int(sub[ref])
                r = idx.index(ref)
                D = dd_operator(len(idx), r)
                H, z = D @ kind.H[idx], D @ kind.z[idx]
                var = self._robust_var(kind, idx, r, D, H, z, P, thr)
                R = dd_covariance(var, r)
                s = np.sqrt(np.diag(H @ P @ H.T + R))
                for row, i in enumerate(i for i in idx if i != ref):
                    self.records.append(UpdateRecord(
                        kind.name, (f"{names[i]}-{names[ref]}",), kind.unit, tg,
                        z[row:row + 1], s[row:row + 1], float((z[row] / s[row]) ** 2), True))
                H_all.append(H)
                z_all.append(z)
                R_blocks.append(R)
                used += [names[i] for i in idx]
                if n_kind == 0:
                    refs_used.append(names[ref])
            if n_kind == 0:
                ep.used = len(used)
                self.reference[-1] = ",".join(refs_used)
            if used:
                self.used[kind.name] = used
        return H_all, z_all, R_blocks

    def _sample(self, n_kind, kind, sub, c, P):
        """Keep the rover's samples of one kind (:attr:`samples`): its SD innovations
        less their centre (the receivers' clock difference), the base's model as known
        variance (:func:`ins.estimation.coupling.range_noise.epoch_samples`)."""
        if kind.var_b is None or kind.name not in _ROBUST_KINDS:
            return
        from ins.estimation.coupling.range_noise import epoch_samples
        self.samples += epoch_samples(int(n_kind == 1), c.el[sub],
                                      None if c.snr is None else c.snr[sub], kind.z[sub],
                                      kind.H[sub], P, kind.var_b[sub])

    def _robust_var(self, kind, idx, r, D, H, z, P, thr):
        """The SD variances of the kept satellites ``idx`` (reference at ``r``),
        inflated by IGG-III (:func:`ins.estimation.coupling.range_noise.igg3_inflation`)
        of each satellite's w statistic when ``TightOptions.noise.robust``."""
        var = kind.var[idx]
        nz = self.opt.noise
        if nz is None or not nz.robust or kind.name not in _ROBUST_KINDS:
            return var
        from ins.estimation.coupling.range_noise import igg3_inflation
        w = w_test(z, H @ P @ H.T + dd_covariance(var, r), D)
        return var * igg3_inflation(np.sqrt(w), np.sqrt(thr), nz.k0)

    def satellites_used(self):
        """``(min, mean, max)`` satellites in the pseudorange DDs per epoch (reference
        included; 0s included)."""
        return satellites_used(self.epochs)
