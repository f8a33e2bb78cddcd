"""RTK/INS: carrier-phase double differences against a base as measurements of the
error-state filter and smoother, with float ambiguities as states, integer resolution
by LAMBDA (:mod:`ins.estimation.coupling.ambiguity`) and the fixed ambiguities held.

Measurement model
-----------------
The corrected carrier of each receiver and frequency (:class:`ins.gnss.raw_epochs.
RawEpochs` ``phase_m`` for L1, ``phase2_m`` for L2 when both receivers have it, m) is ``rho + c dt + lambda N + e`` with the ambiguity ``N`` an integer
number of cycles plus the receiver's phase offset.  The single difference (rover minus
base) of satellite ``i``, ``y_i = rho_r,i - rho_b,i + c (dt_r - dt_b) + lambda N_i``,
keeps the receivers' clock and phase offsets, common to every satellite; the double
difference against a reference ``k`` cancels them: ``y_i - y_k = DD rho + lambda (N_i -
N_k)``, an integer combination.  The states are the single-difference ambiguities
``N_i`` (cycles), one slot of the layout's ``ambiguity`` group per satellite and
frequency (double differences are formed within one frequency)
(:class:`ins.estimation.core.error_model.StateLayout` ``n_ambiguities``); their common
part is not observable and does not need to be.  Row of ``i`` against ``k`` (innovation
predicted minus measured, error states truth minus estimate): the code rows' ``H_i -
H_k`` with ``-lambda`` at slot ``i`` and ``+lambda`` at slot ``k``;
covariance :func:`ins.estimation.coupling.double_difference.dd_covariance` of the
single-difference variances ``a^2 + b^2 / sin^2 el`` per receiver
(``carrier_sigma_m``).  Code and Doppler double differences are used beside the
carrier (:class:`~ins.estimation.coupling.double_difference.DoubleDifferenceUpdater`).

A satellite takes a slot (it rises, or comes back after a slip) by a
re-initialization (:meth:`ins.estimation.core.updates.Updater.reinitialize`): against an
anchor ``a`` (a satellite whose slot carries on, a fixed one first)
``N_i = N_a + ((y_i - y_a) - (p_i - p_a)) / lambda`` with ``p`` the predicted single
difference ranges.  Its error ``(H_i - H_a) dx / lambda + e_a + noise`` is a linear
function of the error state: that row of ``T``, so that the INS's position after an
outage gives the new ambiguities their covariance (centimetres of INS error make them
fixable at once).  With no anchor (the first epoch, after a total outage) the first
satellite takes ``(y - p) / lambda`` with an uncorrelated sigma of
:data:`INITIAL_SIGMA_CYC` and the others anchor on it.

Cycle slips
-----------
A satellite's slot is re-initialized when the loss-of-lock indicator of either receiver
says so (LLI bit 0), when it was not observed for more than :data:`MAX_GAP_S` (or 2.5
epoch intervals), or when
its carrier double differences fail the per-satellite w-test against the INS's
prediction before the update (:func:`ins.estimation.coupling.double_difference.screen`);
each re-initialization of a tracked satellite counts as a slip.  With two frequencies
the geometry-free combination of the single differences flags a jump beyond
:data:`GF_SIGMAS` of its sigma and :data:`GF_JUMP_M` (no Melbourne-Wuebbena test: the second frequency's code is not
read); the INS's prediction does the rest (a slip of one cycle is 19 or 24 cm against
centimetres of predicted range).

Ambiguity resolution and hold
-----------------------------
After each epoch's update, the double differences of the float ambiguities of the
satellites used, per frequency against a fixed reference when there is one, go together
to
:func:`ins.estimation.coupling.ambiguity.resolve` (ratio and bootstrapped success rate,
partial fixing that never leaves out a held one).  The double differences of newly fixed
satellites are then applied as measurements ``D N = integers`` with sigma
:data:`HOLD_SIGMA_CYC` (fix and hold): the filter carries the fixed solution on, the
smoother keeps it, and through outages of some satellites the held ones constrain the
INS with as few as two satellites.  An epoch is *fixed* when at least two of its
satellites are held (at least one fixed double difference).
"""
import numpy as np

from ins.estimation.core.measurements import UpdateRecord, kalman_update
from ins.estimation.coupling.ambiguity import resolve
from ins.estimation.coupling.double_difference import (
    DoubleDifferenceUpdater,
    _Kind,
)
from ins.estimation.coupling.pseudorange import apply_rows
from ins.estimation.core import _filter_kernels

__all__ = ["CarrierOptions", "CarrierPhaseUpdater", "INITIAL_SIGMA_CYC", "HOLD_SIGMA_CYC",
           "MAX_GAP_S"]

#: Sigma of an ambiguity with no anchor, cycles (RTKLIB's 30 m initial bias sigma).
INITIAL_SIGMA_CYC = 160.0
#: Sigma of the fixed double differences applied as measurements (fix and hold), cycles.
HOLD_SIGMA_CYC = 0.01
#: A jump of the geometry-free combination between two epochs beyond this many of its
#: sigmas (from ``carrier_sigma_m``), and beyond :data:`GF_JUMP_M`, is a slip (the
#: ionosphere's change over a second is millimetres; one cycle on both GPS frequencies
#: moves it by 5.4 cm, which the INS's w-test catches when this does not).
GF_SIGMAS = 5.0
GF_JUMP_M = 0.05  # m, RTKLIB's slip threshold of the geometry-free combination
#: Constellations whose ambiguities stay float: GLONASS (FDMA: the receivers' phase
#: offsets in cycles differ per channel, so its double differences are no integers
#: without an inter-frequency bias calibration).
FLOAT_ONLY = ("R",)
#: A satellite not observed for longer than this, or than 2.5 of the receiver's epoch
#: intervals (a 30 s reference station), is taken as a new arc, s.
MAX_GAP_S = 5.0


class CarrierOptions:
    """Options of the carrier phase (SI unless the name says so).

    Parameters
    ----------
    carrier_sigma_m : (float, float)
        ``(a, b)`` of each receiver's carrier sigma ``sqrt(a^2 + b^2 / sin^2 el)``, m.
    ratio : float
        Ratio test threshold of the ambiguity validation.
    min_success : float
        Bootstrapped success rate threshold.
    min_fix : int
        Fewest double differences fixed at once (partial fixing).
    hold : bool
        Apply fixed ambiguities as measurements (fix and hold); ``False``: float only.
    """

    def __init__(self, carrier_sigma_m=(0.003, 0.003), ratio=3.0, min_success=0.99,
                 min_fix=3, hold=True):
        self.carrier_sigma_m = tuple(float(v) for v in carrier_sigma_m)
        self.ratio = float(ratio)
        self.min_success = float(min_success)
        self.min_fix = int(min_fix)
        self.hold = bool(hold)


class CarrierPhaseUpdater(DoubleDifferenceUpdater):
    """Code, Doppler and carrier-phase double differences against a base, with the
    ambiguity slots of the layout (module notes).  Use ``functools.partial(
    CarrierPhaseUpdater, options=TightOptions(...), carrier=CarrierOptions(...))``.

    Attributes
    ----------
    frequencies : list of (str, float)
        The carriers used: name (``L1``, ``L2``) and wavelength, m.
    slips : list of (float, str)
        Re-initializations of tracked satellites: (time s, ``G07 L1``).
    fixed_epochs, carrier_epochs : int
        Epochs with a fixed solution; epochs with carrier double differences.
    refix_s : list of float
        After each total outage (epochs with fewer than two common satellites, or none
        for longer than 2.5 epoch intervals), the time from the first carrier epoch to
        the first fixed one, s (0: fixed at once).
    ratios : list of (float, float, float)
        (time s, ratio, success rate) of each resolution attempt.
    fixed_at : list of float
        Times of the fixed epochs, s.
    """

    name = "gnss_rtk"

    def __init__(self, settings, gnss, options=None, carrier=None):
        if settings.layout.ambiguity is None:
            raise ValueError("carrier phase needs ambiguity slots in the layout "
                             "(StateLayout n_ambiguities)")
        if getattr(gnss, "phase_m", None) is None or getattr(gnss.base, "phase_m",
                                                             None) is None:
            raise ValueError("carrier phase needs both receivers' carrier (phase_m)")
        super().__init__(settings, gnss, options)
        self.c = carrier or CarrierOptions()
        self.frequencies = [("L1", float(gnss.wavelength_m), "phase_m", "lli", "lam_m")]
        if (getattr(gnss, "phase2_m", None) is not None
                and getattr(gnss.base, "phase2_m", None) is not None):
            self.frequencies.append(("L2", float(gnss.wavelength2_m), "phase2_m", "lli2",
                                     "lam2_m"))
        dt = np.diff(np.asarray(gnss.time, float))
        self.max_gap_s = max(MAX_GAP_S, 2.5 * float(np.median(dt)) if len(dt) else 0.0)
        self.slot = {}                 # (satellite, frequency) -> slot (0-based)
        self.seen = {}                 # (satellite, frequency) -> last time observed
        self.held = set()              # (satellite, frequency) whose ambiguity is held
        self.slips = []
        self.fixed_epochs = self.carrier_epochs = 0
        self.refix_s, self._outage_end = [], None
        self._last_carrier = None      # time of the last epoch with carrier DDs, s
        self.gf = {}                   # satellite -> (time, geometry-free SD, m)
        self.gf_slips = 0              # slips the geometry-free combination found
        self.ratios = []
        self.fixed_at = []

    # ------------------------------------------------------------------ slots
    def _col(self, key):
        return self.layout.ambiguity.start + self.slot[key]

    def _free_slot(self, t):
        used = set(self.slot.values())
        for i in range(self.layout.n_ambiguities):
            if i not in used:
                return i
        old = min(self.slot, key=lambda s: self.seen.get(s, -np.inf))
        if self.seen.get(old, -np.inf) >= t - 1e-9:
            raise ValueError(f"more carriers at {t:.3f} s than ambiguity slots "
                             f"({self.layout.n_ambiguities})")
        self._release(old)
        return self._free_slot(t)

    def _release(self, key):
        self.slot.pop(key, None)
        self.held.discard(key)

    # ------------------------------------------------------------------ epoch
    def update(self, e, t_row, state, sensors, P, w_meas_b, f_meas_b=None):
        """Process epoch ``ev_record[e]`` (module notes); returns ``(P, dx)``."""
        L = self.layout
        c = self._epoch(e, t_row, state, sensors, w_meas_b, f_meas_b)
        if c is None:
            self._no_carrier()
            return P, np.zeros(L.n)
        obs = [self._carrier(c, f) for f in self.frequencies]
        if len(obs) == 2:
            self._geometry_free(c, obs)
        for o in obs:
            if np.count_nonzero(o["ok"]) >= 2:
                P = self._slots(c, sensors, P, o)
        kinds = list(c.kinds)
        for o in obs:
            self.used.pop(o["kind"], None)
            kinds.append((self._phase_kind(c, sensors, o), o["ok"]))
        H, z, R = self._screened(c, kinds, P)
        P, dx = self._apply(c, P, H, z, R)
        used = {o["f"]: self.used.pop(o["kind"], []) for o in obs}
        used = {f: names for f, names in used.items() if len(names) >= 2}
        if used:
            last, self._last_carrier = self._last_carrier, c.tg
            if last is not None and c.tg - last > self.max_gap_s:
                self._outage_end = c.tg    # the first carrier epoch after an outage
            self.carrier_epochs += 1
            P, dx2 = self._resolve(c, sensors, P, used)
            dx = dx + dx2
        else:
            self._no_carrier()
        return P, dx

    def _carrier(self, c, freq):
        """One frequency's single differences at the epoch: a dict (``lam`` per
        satellite, m: a GLONASS channel's own)."""
        f, lam0, attr, lli_attr, lam_attr = freq
        g, b, k = self.gnss, self.gnss.base, c.k
        lams = getattr(g, lam_attr, None)
        lam = (np.full(len(c.ir), lam0) if lams is None
               else np.asarray(lams[k], float)[c.ir])
        y = (np.asarray(getattr(g, attr)[k], float)[c.ir]
             - np.asarray(getattr(b, attr)[k], float)[c.ib])
        lli = np.zeros(len(c.ir), int)
        for src, idx in ((g, c.ir), (b, c.ib)):
            arr = getattr(src, lli_attr, None)
            if arr is not None:
                lli |= np.nan_to_num(np.asarray(arr[k], float)[idx]).astype(int) & 1
        var = (self._var(c.el, self.c.carrier_sigma_m)
               + self._var(c.el_b, self.c.carrier_sigma_m))
        return {"f": f, "lam": lam, "y": y, "lli": lli, "var": var,
                "ok": c.up & np.isfinite(y) & np.isfinite(lam), "kind": f"dd_carrier_{f}"}

    def _apply(self, c, P, H, z, R):
        if not z:
            return P, np.zeros(self.layout.n)
        from scipy.linalg import block_diag
        return apply_rows(self, c.point, P, np.vstack(H), block_diag(*R), np.concatenate(z),
                          c.k)

    def _no_carrier(self):
        if self.carrier_epochs and self._outage_end is None:
            self._outage_end = -1.0    # waiting for the next carrier epoch

    def _phase_kind(self, c, sensors, o):
        """Single-difference carrier innovations (predicted minus measured, m) and rows
        with the ambiguity columns, of one frequency."""
        H = c.H_r.copy()
        z = np.zeros(len(o["y"]))
        for i, s in enumerate(c.names):
            key = (s, o["f"])
            if key in self.slot:
                col = self._col(key)
                H[i, col] -= o["lam"][i]   # z = H dx - lambda (N - N_est)
                z[i] = c.sd_r[i] + o["lam"][i] * sensors[col - 9] - o["y"][i]
        return _Kind(o["kind"], "m", z, H, o["var"])

    def _geometry_free(self, c, obs):
        """Slips seen by the geometry-free combination of the two carriers: the single
        differences' ``y1 - y2`` (m: the ionosphere's and the ambiguities' combination,
        no geometry, no clock) moves since the satellite's last epoch (within the arc
        gap) by more than :data:`GF_SIGMAS` of its sigma and :data:`GF_JUMP_M`: both
        frequencies flagged as by a loss of lock (bit 0 of ``lli``).  A slip of the same cycles on both frequencies moves it by
        ``n (lambda1 - lambda2)``, 5.4 cm a cycle on GPS L1/L2."""
        o1, o2 = obs
        gf = o1["y"] - o2["y"]
        t = c.tg
        for i, s in enumerate(c.names):
            if not (o1["ok"][i] and o2["ok"][i]):
                self.gf.pop(s, None)
                continue
            last = self.gf.get(s)
            self.gf[s] = (t, gf[i])
            if last is None or t - last[0] > self.max_gap_s:
                continue
            # the jump's sigma: two epochs of two carriers' single differences
            sigma = np.sqrt(2.0 * (o1["var"][i] + o2["var"][i]))
            if abs(gf[i] - last[1]) > max(GF_JUMP_M, GF_SIGMAS * sigma):
                o1["lli"][i] |= 1
                o2["lli"][i] |= 1
                self.gf_slips += 1

    def _slots(self, c, sensors, P, o):
        """Slips and new satellites of one frequency: their slots re-initialized."""
        from ins.estimation.coupling.double_difference import screen
        t, names, ok, f = c.tg, c.names, o["ok"], o["f"]
        reset = set()
        for i, s in enumerate(names):
            if not ok[i]:
                continue
            key = (s, f)
            new = key not in self.slot or t - self.seen.get(key, -np.inf) > self.max_gap_s
            if new or o["lli"][i] & 1:
                if key in self.slot and not new:
                    self.slips.append((t, f"{s} {f}"))
                reset.add(i)
        phase = None
        for system in sorted(set(c.sys.tolist())):
            tracked = [i for i in range(len(names)) if ok[i] and i not in reset
                       and c.sys[i] == system]
            if len(tracked) < 2:
                continue                   # slips the INS sees: w-test before the update
            phase = phase or self._phase_kind(c, sensors, o)
            sub = np.array(tracked)
            pref = max(range(len(tracked)), key=lambda j: ((names[tracked[j]], f) in
                                                           self.held, c.el[tracked[j]]))
            _, _, rejected = screen(phase.z[sub], phase.H[sub], o["var"][sub], P, pref,
                                    self._threshold(1), c.el[sub])
            for j, _w in rejected:
                i = int(sub[j])
                if len(tracked) > 2:
                    self.slips.append((t, f"{names[i]} {f}"))
                reset.add(i)
        for i, s in enumerate(names):
            if ok[i]:
                self.seen[(s, f)] = t
        for system in sorted({c.sys[i] for i in reset}):
            P = self._reinit(c, sensors, P, o, sorted(i for i in reset if c.sys[i] == system))
        return P

    def _reinit(self, c, sensors, P, o, reset):
        """Re-initialize the slots of ``reset`` (satellites of one constellation) against
        an anchor of that constellation (module notes)."""
        L, f, y, var, lam = self.layout, o["f"], o["y"], o["var"], o["lam"]
        names, system = c.names, c.sys[reset[0]]
        for i in reset:
            self._release((names[i], f))
        anchors = [i for i in range(len(names)) if o["ok"][i] and i not in reset
                   and c.sys[i] == system and (names[i], f) in self.slot]
        if anchors:
            a = max(anchors, key=lambda i: ((names[i], f) in self.held, c.el[i]))
        else:                              # no anchor: the highest one starts, alone
            a = max(reset, key=lambda i: c.el[i])
            self.slot[(names[a], f)] = self._free_slot(c.tg)
            col = self._col((names[a], f))
            sensors[col - 9] = (y[a] - c.sd_r[a]) / lam[a]
            T, q = np.eye(L.n), np.zeros(L.n)
            T[col, :] = 0.0
            q[col] = INITIAL_SIGMA_CYC ** 2
            P = self.reinitialize(P, T, q)
            reset = [i for i in reset if i != a]
            if not reset:
                return P
        col_a = self._col((names[a], f))
        T, q = np.eye(L.n), np.zeros(L.n)
        for i in reset:                    # tied to the anchor through the INS
            self.slot[(names[i], f)] = self._free_slot(c.tg)
            col = self._col((names[i], f))
            # y_i - y_a = p_i - p_a + lam_i N_i - lam_a N_a (+ noise)
            sensors[col - 9] = ((y[i] - y[a]) - (c.sd_r[i] - c.sd_r[a])
                                + lam[a] * sensors[col_a - 9]) / lam[i]
            T[col, :] = (c.H_r[i] - c.H_r[a]) / lam[i]
            T[col, col_a] += lam[a] / lam[i]
            q[col] = (var[i] + var[a]) / lam[i] ** 2
        return self.reinitialize(P, T, q)

    # ------------------------------------------------------------------ resolution
    def _resolve(self, c, sensors, P, used):
        """LAMBDA on the double-difference ambiguities of the used satellites of every
        frequency together, then the newly fixed ones held (module notes).  Returns
        ``(P, dx)``."""
        L, t = self.layout, c.tg
        dx = np.zeros(L.n)
        el = dict(zip(c.names, c.el))
        pairs = []                         # (key, reference key) per DD
        for f, sats in used.items():
            for system in sorted({s[0] for s in sats} - set(FLOAT_ONLY)):
                of = [s for s in sats if s[0] == system]
                if len(of) < 2:
                    continue
                held = [s for s in of if (s, f) in self.held]
                ref = held[0] if held else max(of, key=lambda s: el[s])
                pairs += [((s, f), (ref, f)) for s in of if s != ref]
        if not pairs:
            return P, dx
        D = np.zeros((len(pairs), L.n))
        for j, (key, ref) in enumerate(pairs):
            D[j, self._col(key)] += 1.0
            D[j, self._col(ref)] -= 1.0
        a = D[:, 9:] @ sensors
        Q = D @ P @ D.T
        keep = [j for j, (key, ref) in enumerate(pairs) if key in self.held and ref in self.held]
        fix = resolve(a, Q, self.c.ratio, self.c.min_success,
                      min(self.c.min_fix, len(pairs)), keep)
        self.ratios.append((t, fix.ratio, fix.success_rate))
        if fix.fixed and self.c.hold:
            index = list(fix.index)
            new = [j for j in index if not (pairs[j][0] in self.held
                                            and pairs[j][1] in self.held)]
            if new:
                H = -D[new]                # z = D N_est - integers = -D (N - N_est)
                z = a[new] - fix.integers[[index.index(j) for j in new]]
                R = np.eye(len(new)) * HOLD_SIGMA_CYC ** 2
                x, P, nis, _ = kalman_update(P, H, R, z, np.inf, self)
                _filter_kernels.correct_state(c.point.state, x)
                c.point.sensors += x[L.sensors]
                dx = x
                for row, j in enumerate(new):
                    (s, f), (r, _) = pairs[j]
                    self.records.append(UpdateRecord(
                        "dd_ambiguity", (f"{s}-{r} {f}",), "cycles", t,
                        np.array([z[row]]), np.array([np.sqrt(Q[j, j])]), float(nis), True))
            for j in index:
                self.held.update(pairs[j])
        fixed = any(key in self.held and ref in self.held for key, ref in pairs)
        if fixed:
            self.fixed_epochs += 1
            self.fixed_at.append(t)
            if self._outage_end is not None and self._outage_end >= 0:
                self.refix_s.append(t - self._outage_end)
            self._outage_end = None
        elif self._outage_end == -1.0:
            self._outage_end = t       # the first carrier epoch after the outage
        return P, dx

    def fix_rate(self):
        """Fixed epochs over carrier epochs (``nan`` with none)."""
        return self.fixed_epochs / self.carrier_epochs if self.carrier_epochs else np.nan
