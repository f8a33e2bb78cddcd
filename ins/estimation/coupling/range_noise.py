"""Pseudorange and Doppler noise of a real receiver, estimated from the data, and the
robust (IGG-III) down-weighting of heavy-tailed code and Doppler errors.

Why
---
The default weights of tight coupling (RTKLIB's ``a^2 + b^2 / sin^2 el``, 0.3 m + 0.3 m)
suit a geodetic receiver with white noise.  A u-blox patch antenna has multipath of
metres correlated over tens of seconds, C/N0 swings of 10 dB and more, and occasional
blunders of tens of metres on weak satellites: taken at face value those pull the
solution (worse than RTKLIB's own loose solution, whose least squares averages over
all satellites of an epoch).

Noise model
-----------
Per receiver and observation (code m, Doppler range rate m/s)::

    sigma^2 = a^2 + b^2 / sin^2(el) + c^2 10^(-(C/N0 - ref) / 10)

(:class:`NoiseModel`; ``ref`` dB-Hz, ``c`` the sigma at C/N0 = ref of the term that
follows the tracking loop's thermal noise).

Estimation (:func:`fit_model`)
------------------------------
From samples of innovations (predicted minus measured, one satellite each) with the
part of their variance that is not the measurement's (``H P H^T`` of the filter's prior,
and for single differences the other receiver's model) known: the samples are binned
by elevation and C/N0, the variance of each bin estimated robustly as
``(1.4826 MAD)^2`` less the median known part (an outlier of 50 m moves a median by one
sample, a mean of squares by 2500 m^2 / n), but at least :data:`MIN_SHARE` of it, and
the three coefficients fitted to the bins' variances by non-negative least squares
weighted by ``n_bin / var_bin^2`` (floored; a
variance from ``n`` samples has a relative error of about ``sqrt(2 / n)``).  Terms the
data do not support come out 0.  Where the innovations come from is the caller's
choice: a first tight pass (:attr:`ins.estimation.coupling.pseudorange.TightUpdater.samples`),
or residuals against a known position (a static base,
:func:`ins.estimation.coupling.base_residuals.static_residuals`).

Robust weighting (:func:`igg3_inflation`)
-----------------------------------------
IGG-III (Yang Yuanxi's three-segment equivalent weight) on the standardized innovation
``t = |z| / sqrt(H P H^T + R)``: weight 1 for ``t <= k0``, ``k0 / t ((k1 - t) / (k1 -
k0))^2`` between ``k0`` and ``k1``, and beyond ``k1`` the existing chi-square test
rejects.  The weight is applied as ``R / w`` (the variance inflated, never the state
edited), so the error-state filter's covariance and the RTS smoother that reads it stay
consistent with what was applied.
"""
from dataclasses import dataclass

import numpy as np

__all__ = ["NoiseModel", "RangeNoise", "fit_model", "fit_receiver", "igg3_inflation",
           "centre", "epoch_samples", "samples_by_kind", "MAD_TO_SIGMA", "IGG_K0"]

#: ``1.4826``: the standard deviation of a normal distribution per median absolute
#: deviation.
MAD_TO_SIGMA = 1.482602218505602
#: IGG-III: standardized innovations up to this are taken at face value.
IGG_K0 = 2.0
#: Elevation bin edges of the fit, deg; C/N0 bins are ``CN0_BIN_DBHZ`` wide.
EL_EDGES_DEG = (0.0, 15.0, 20.0, 25.0, 30.0, 40.0, 50.0, 60.0, 75.0, 90.1)
CN0_BIN_DBHZ = 3.0
#: Fewest samples of a bin used in the fit.
MIN_BIN = 20
#: A bin's noise variance is at least this share of its samples' spread: a first pass
#: with pessimistic sigmas has a pessimistic ``H P H^T`` that can exceed what the
#: innovations show, and a receiver left with no noise would be trusted without bound.
MIN_SHARE = 0.25


@dataclass(frozen=True)
class NoiseModel:
    """``sigma^2 = a^2 + b^2 / sin^2 el + c^2 10^(-(snr - snr_ref) / 10)`` of the code (m)
    and the range rate (m/s) of one receiver (module notes).

    Parameters
    ----------
    code : (float, float, float)
        ``(a, b, c)`` of the pseudorange, m.
    rate : (float, float, float)
        ``(a, b, c)`` of the range rate, m/s.
    snr_ref_dbhz : float
        C/N0 of the ``c`` term, dB-Hz; without C/N0 the term is taken at the reference.
    samples : (int, int)
        Samples the fit used (code, range rate); 0 for a model given by hand.
    code_floor : (float, float), optional
        ``(a, b)``: the code variance is at least ``a^2 + b^2 / sin^2 el``, m.  Code
        errors that vary slowly (multipath, the atmosphere's and the orbits' model
        errors) are partly taken up by the filter's states and so missing from its
        innovations: a fit can come out below what the solution should assume (on
        PSINS's real car log 2 cm at zenith, where RTKLIB's fixes scatter 0.36 m).
    rate_floor : (float, float), optional
        The same for the range rate, m/s (on that log the fitted 0.01 m/s left the
        heading less consistent with the course over ground: 1.36 deg of spread
        against 1.08 deg with 0.05 + 0.05 / sin el).
    """

    code: tuple = (0.3, 0.3, 0.0)
    rate: tuple = (0.05, 0.05, 0.0)
    snr_ref_dbhz: float = 45.0
    samples: tuple = (0, 0)
    code_floor: tuple = None
    rate_floor: tuple = None

    def variances(self, el, snr=None):
        """Code (m^2) and range-rate ((m/s)^2) variances at elevations ``el`` (rad) and
        C/N0 ``snr`` (dB-Hz, or ``None``)."""
        el = np.asarray(el, float)
        s2 = np.maximum(np.sin(el), 1e-3) ** 2
        if snr is None:
            g = np.ones_like(el)
        else:
            snr = np.asarray(snr, float)
            g = np.where(np.isfinite(snr), 10.0 ** (-0.1 * (snr - self.snr_ref_dbhz)), 1.0)
            g = np.minimum(g, 1e3)
        out = []
        for a, b, c in (self.code, self.rate):
            out.append(a * a + b * b / s2 + c * c * g)
        for i, f in enumerate((self.code_floor, self.rate_floor)):
            if f is not None:
                out[i] = np.maximum(out[i], f[0] ** 2 + f[1] ** 2 / s2)
        return out[0], out[1]

    def describe(self):
        """One line: ``code a/b/c m, range rate a/b/c m/s (ref dB-Hz, n samples)``."""
        c, r, f, g = self.code, self.rate, self.code_floor, self.rate_floor
        fl = "" if f is None else f" (at least {f[0]:.2f}^2 + {f[1]:.2f}^2/sin^2 el)"
        gl = "" if g is None else f" (at least {g[0]:.3f}^2 + {g[1]:.3f}^2/sin^2 el)"
        return (f"code sigma^2 = {c[0]:.2f}^2 + {c[1]:.2f}^2/sin^2 el + {c[2]:.2f}^2 "
                f"10^(-(C/N0-{self.snr_ref_dbhz:g})/10) m^2{fl}, range rate {r[0]:.3f}^2 + "
                f"{r[1]:.3f}^2/sin^2 el + {r[2]:.3f}^2 10^(..) (m/s)^2{gl} "
                f"({self.samples[0]}/{self.samples[1]} samples)")

    def as_dict(self):
        """The model for a summary (JSON-ready)."""
        return {"code_abc_m": [round(float(v), 4) for v in self.code],
                "code_floor_ab_m": None if self.code_floor is None else
                [float(v) for v in self.code_floor],
                "rate_floor_ab_mps": None if self.rate_floor is None else
                [float(v) for v in self.rate_floor],
                "rate_abc_mps": [round(float(v), 5) for v in self.rate],
                "snr_ref_dbhz": float(self.snr_ref_dbhz),
                "samples": [int(v) for v in self.samples]}


@dataclass(frozen=True)
class RangeNoise:
    """The noise models of the receivers of a tight run and the robust weighting
    (``TightOptions.noise``).

    Parameters
    ----------
    rover : NoiseModel
    base : NoiseModel, optional
        The base's (double differences); default the rover's.
    robust : bool
        IGG-III down-weighting (:func:`igg3_inflation`) of the accepted rows.
    k0 : float
        Its first knee (standardized innovation); the second is the rejection
        threshold of the chi-square test.
    """

    rover: NoiseModel = NoiseModel()
    base: NoiseModel = None
    robust: bool = True
    k0: float = IGG_K0

    def receiver(self, which):
        """``"rover"`` or ``"base"``'s model."""
        return self.base if which == "base" and self.base is not None else self.rover


def igg3_inflation(t, k1, k0=IGG_K0):
    """IGG-III variance inflation ``1 / w`` for standardized innovations ``t`` (module
    notes): 1 up to ``k0``, ``t / k0 ((k1 - k0) / (k1 - t))^2`` between, capped at 1e6
    (at and beyond ``k1`` the chi-square test rejects anyway)."""
    t = np.abs(np.asarray(t, float))
    k1 = max(float(k1), k0 + 1e-6)
    mid = (t > k0) & (t < k1)
    out = np.ones_like(t)
    out[mid] = t[mid] / k0 * ((k1 - k0) / (k1 - t[mid])) ** 2
    out[t >= k1] = 1e6
    return np.minimum(out, 1e6)


def _bins(el, snr):
    """Bin index of each sample (elevation x C/N0)."""
    ie = np.clip(np.searchsorted(np.deg2rad(EL_EDGES_DEG), el, side="right") - 1, 0,
                 len(EL_EDGES_DEG) - 2)
    if snr is None:
        return ie
    s = np.where(np.isfinite(snr), snr, 0.0)
    return ie * 1000 + np.floor(s / CN0_BIN_DBHZ).astype(int)


def fit_model(el, snr, z, known_var=None, snr_ref_dbhz=45.0, use_snr=True):
    """Robust fit of ``(a, b, c)`` (module notes) to innovations of one observation type.

    Parameters
    ----------
    el : ndarray (k,)
        Elevations, rad.
    snr : ndarray (k,) or None
        C/N0, dB-Hz (``None``: no C/N0 term).
    z : ndarray (k,)
        Innovations or residuals, m or m/s (nan ignored).
    known_var : ndarray (k,), optional
        The part of each sample's variance that is not this receiver's noise (``H P
        H^T``, another receiver's variance), unit squared.
    snr_ref_dbhz : float
        Reference C/N0 of the ``c`` term, dB-Hz.
    use_snr : bool
        Fit the C/N0 term.

    Returns
    -------
    abc : (float, float, float)
        Unit of ``z``; ``(nan, nan, nan)`` when no bin holds :data:`MIN_BIN` samples.
    n : int
        Samples in the bins used.
    """
    from scipy.optimize import nnls
    el, z = np.asarray(el, float), np.asarray(z, float)
    kv = np.zeros_like(z) if known_var is None else np.asarray(known_var, float)
    s = None if (snr is None or not use_snr) else np.asarray(snr, float)
    ok = np.isfinite(z) & np.isfinite(el) & np.isfinite(kv)
    el, z, kv = el[ok], z[ok], kv[ok]
    s = None if s is None else s[ok]
    b = _bins(el, s)
    rows, rhs, ns, n_used = [], [], [], 0
    for key in np.unique(b):
        m = b == key
        if np.count_nonzero(m) < MIN_BIN:
            continue
        zz = z[m]
        mad = np.median(np.abs(zz - np.median(zz)))
        spread = (MAD_TO_SIGMA * mad) ** 2
        var = max(spread - float(np.median(kv[m])), MIN_SHARE * spread)
        sin2 = float(np.median(np.maximum(np.sin(el[m]), 1e-3) ** 2))
        g = 0.0 if s is None else float(np.median(10.0 ** (-0.1 * (s[m] - snr_ref_dbhz))))
        rows.append([1.0, 1.0 / sin2, g])
        rhs.append(var)
        n = np.count_nonzero(m)
        ns.append(n)
        n_used += n
    if not rows:
        return (np.nan, np.nan, np.nan), 0
    A, y = np.array(rows), np.array(rhs)
    # weights n / var^2 (a variance's relative error is sqrt(2 / n)), the variances
    # floored at a tenth of the bins' median: a bin of (near) zero spread must not
    # take the whole fit
    floor = max(0.1 * float(np.median(y)), 1e-12)
    w = np.sqrt(np.array(ns, float)) / np.maximum(y, floor)
    cols = [0, 1, 2] if s is not None else [0, 1]
    x = np.zeros(3)
    x[cols], _ = nnls(A[:, cols] * w[:, None], y * w)
    if not np.any(x > 0):                     # all bins at zero noise: a floor
        x[0] = max(float(np.median(y)), 1e-12)
    return tuple(float(v) for v in np.sqrt(x)), n_used


def centre(z):
    """A robust centre of one epoch's innovations that is not one of them (the median
    of an odd count is, and would leave an exact zero in every epoch): the mean of
    those within 3 MAD-sigmas of the median (all when the MAD is 0)."""
    z = np.asarray(z, float)
    med = np.median(z)
    s = MAD_TO_SIGMA * np.median(np.abs(z - med))
    keep = np.abs(z - med) <= 3.0 * s if s > 0 else np.ones(len(z), bool)
    return float(np.mean(z[keep]))


def epoch_samples(kind, el, snr, z, H, P, known_var=None):
    """Samples of one epoch's rows of one kind (0 code, 1 range rate) for
    :func:`fit_receiver`: the innovations ``z`` (k,) less their :func:`centre`, so that what is
    common to the epoch (the receiver clock's prediction error, a clock difference not
    carried as a state) leaves them, scaled by ``sqrt(k / (k - 1))`` for the removed
    mean; the known variance is the diagonal of ``C (H P H^T + diag(known_var)) C^T``
    (``C = I - 1 1^T / k``), scaled alike.  ``el`` rad, ``snr`` dB-Hz (or None), ``H``
    (k, n), ``P`` (n, n), ``known_var`` (k,) another receiver's variances.  Fewer than 3
    rows give none.  Returns a list of ``(kind, el, snr, z, known_var)``."""
    k = len(z)
    if k < 3:
        return []
    z = np.asarray(z, float)
    S = H @ P @ H.T
    if known_var is not None:
        S = S + np.diag(np.asarray(known_var, float))
    C = np.eye(k) - 1.0 / k
    f = k / (k - 1.0)
    kv = np.einsum("ij,jk,ik->i", C, S, C) * f
    zc = (z - centre(z)) * np.sqrt(f)
    snr = np.full(k, np.nan) if snr is None else np.asarray(snr, float)
    return [(int(kind), float(e), float(s), float(a), float(b))
            for e, s, a, b in zip(el, snr, zc, kv)]


def samples_by_kind(samples, kind):
    """Arrays ``(el, snr, z, known_var)`` of the samples of one kind (0 code, 1 range
    rate) from a list of ``(kind, el, snr, z, known_var)`` tuples."""
    rows = [r for r in samples if r[0] == kind]
    if not rows:
        return (np.zeros(0),) * 4
    a = np.array([r[1:] for r in rows], float)
    return a[:, 0], a[:, 1], a[:, 2], a[:, 3]


def fit_receiver(samples, snr_ref_dbhz=45.0, fallback=None, code_floor=None,
                 rate_floor=None):
    """A :class:`NoiseModel` from a receiver's samples (:func:`samples_by_kind`); a term
    that cannot be fitted (too few samples) keeps ``fallback``'s (default
    :class:`NoiseModel`); ``code_floor``, ``rate_floor`` as :class:`NoiseModel`'s."""
    fallback = fallback or NoiseModel(snr_ref_dbhz=snr_ref_dbhz)
    out, ns = [], []
    for kind, fb in ((0, fallback.code), (1, fallback.rate)):
        el, snr, z, kv = samples_by_kind(samples, kind)
        has_snr = np.any(np.isfinite(snr)) and np.ptp(snr[np.isfinite(snr)]) > 0 \
            if snr.size else False
        abc, n = fit_model(el, np.where(np.isfinite(snr), snr, np.nan) if has_snr else None,
                           z, kv, snr_ref_dbhz)
        out.append(tuple(fb) if not np.all(np.isfinite(abc)) else abc)
        ns.append(n)
    return NoiseModel(out[0], out[1], snr_ref_dbhz, tuple(ns), code_floor, rate_floor)
