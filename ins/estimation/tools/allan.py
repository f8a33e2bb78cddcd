"""Overlapping Allan deviation of IMU data and the IEEE 952 noise model fitted to it.

For a rate signal ``y`` sampled every ``dt`` (or increments ``y dt``), with the running
integral ``theta_k = sum_{j<=k} y_j dt`` and ``tau = m dt``::

    sigma^2(tau) = sum_k (theta_{k+2m} - 2 theta_{k+m} + theta_k)^2 / (2 tau^2 (N - 2m))

(IEEE Std 952, overlapping estimator; all k at once from the cumulative sum of the
data less their mean, which the estimator does not see and which would cost digits).

The noise model (IEEE Std 952-1997, annex C), rate units ``u`` (rad/s or m/s^2)::

    sigma^2(tau) = 3 Q^2 / tau^2 + N^2 / tau + (2 ln 2 / pi) B^2 + K^2 tau / 3
                   + R^2 tau^2 / 2

with ``Q`` the quantization (u s: rad, m/s), ``N`` the angle/velocity random walk
(u sqrt(s)), ``B`` the bias instability (u; the flat floor is ``0.664 B``), ``K`` the
rate random walk (u / sqrt(s)) and ``R`` the rate ramp (u / s).  It is linear in the
squares of the coefficients: :func:`fit_noise_model` fits them by non-negative least
squares on the whole curve, at octave-spaced taus, weighted by the covariance of the
estimates: standard deviation ``sigma^2 sqrt(2 / edf)`` with the equivalent degrees of
freedom ``edf`` of the overlapping estimator for the model's mix of noises at that tau
(NIST SP 1065, table 5), and the correlation between octaves of each noise
(:data:`RHO_OCTAVES`); iterated with the fitted model in the weights.  Intervals
(95 %) come from the fit's covariance, all five terms free, scaled by the reduced
chi-square when the curve departs from the model by more than its noise.

Where the model does not describe the curve (a part's internal filter, a sinusoid's
bump; reduced chi-square far above 1), :func:`classic_reading` gives the textbook
graphical reading with chi-square intervals: N from the -1/2 slope line read at
tau = 1 s, B from the curve's minimum / 0.664.

The Allan deviation means something only for a log at rest:
:func:`ins.estimation.alignment.static_check.static_check`.
"""
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

__all__ = ["allan_deviation", "noise_densities", "fit_noise_model", "NoiseFit", "TERMS",
           "classic_reading", "ClassicReading", "octave_taus"]

#: The model's terms, in the order of :attr:`NoiseFit.value` rows.
TERMS = ("Q", "N", "B", "K", "R")
#: Two-sided normal quantile of the intervals (95 %).
Z95 = 1.959963984540054


def _default_taus(n, dt, per_decade=10):
    m_max = max(1, (n - 1) // 4)
    m = np.unique(np.round(np.logspace(0, np.log10(m_max), int(per_decade * np.log10(m_max)) + 1)))
    return m.astype(np.int64) * dt


def octave_taus(n, dt):
    """Averaging times ``2^j dt`` up to a quarter of ``n`` samples, s."""
    m_max = max(1, (n - 1) // 4)
    return (2 ** np.arange(int(np.log2(m_max)) + 1)) * dt


def allan_deviation(data, dt, taus=None, increments=True):
    """Overlapping Allan deviation.

    Parameters
    ----------
    data : array_like, shape (n,) or (n, k)
        Increments (rad, m/s) if ``increments``, else rates (rad/s, m/s^2), equally
        spaced by ``dt``.
    dt : float
        Sampling interval, s.
    taus : array_like, optional
        Averaging times, s (rounded to multiples of dt; default 10 per decade from dt to
        a quarter of the record).
    increments : bool
        Whether ``data`` are increments over ``dt`` (the deviation is of the rate).

    Returns
    -------
    tau : ndarray, shape (m,)
        s.
    adev : ndarray, shape (m,) or (m, k)
        Allan deviation of the rate, rad/s or m/s^2.
    """
    y = np.asarray(data, dtype=float)
    one = y.ndim == 1
    y = y.reshape(len(y), -1)
    n = len(y)
    if n < 3:
        raise ValueError(f"need at least 3 samples, got {n}")
    inc = y if increments else y * dt
    inc = inc - inc.mean(axis=0)          # a constant: invisible to the estimator
    theta = np.concatenate([np.zeros((1, y.shape[1])), np.cumsum(inc, axis=0)])
    if taus is None:
        taus = _default_taus(n, dt)
    m = np.unique(np.round(np.asarray(taus, dtype=float) / dt).astype(np.int64))
    m = m[(m >= 1) & (2 * m <= n)]
    adev = np.empty((len(m), y.shape[1]))
    for i, mi in enumerate(m):
        d = theta[2 * mi:] - 2 * theta[mi:-mi] + theta[:-2 * mi]
        adev[i] = np.sqrt(np.einsum("ij,ij->j", d, d) / len(d) / 2.0) / (mi * dt)
    tau = m * dt
    return tau, (adev[:, 0] if one else adev)


def _basis(tau):
    """Columns of the model in the squared coefficients (Q^2, N^2, B^2, K^2, R^2)."""
    tau = np.asarray(tau, dtype=float)
    return np.column_stack([3.0 / tau ** 2, 1.0 / tau, np.full_like(tau, 2 * np.log(2) / np.pi),
                            tau / 3.0, tau ** 2 / 2.0])


def _edf_terms(m, n_phase):
    """Equivalent degrees of freedom of the overlapping Allan variance at ``m`` for white
    PM, white FM, flicker FM, random-walk FM (NIST SP 1065 table 5), the ramp as RW FM;
    columns in the order of :data:`TERMS`.  ``n_phase`` = samples + 1."""
    m = np.asarray(m, dtype=float)
    N = float(n_phase)
    wpm = (N + 1) * (N - 2 * m) / (2 * (N - m))
    wfm = (3 * (N - 1) / (2 * m) - 2 * (N - 2) / N) * 4 * m ** 2 / (4 * m ** 2 + 5)
    ffm = np.where(m < 2, 2 * (N - 2) ** 2 / (2.3 * N - 4.9), 5 * N ** 2 / (4 * m * (N + 3 * m)))
    rwfm = (N - 2) / m * ((N - 1) ** 2 - 3 * m * (N - 1) + 4 * m ** 2) / (N - 3) ** 2
    return np.maximum(np.column_stack([wpm, wfm, ffm, rwfm, rwfm]), 1.0)


@dataclass(frozen=True)
class NoiseFit:
    """IEEE 952 noise model fitted to an Allan variance (rate units ``u``: rad/s for a
    gyro, m/s^2 for an accelerometer; per axis ``k``).

    Attributes
    ----------
    tau : ndarray, shape (m,)
        Averaging times of the fit, s.
    avar : ndarray, shape (m, k)
        Allan variance there, u^2.
    edf : ndarray, shape (m, k)
        Equivalent degrees of freedom of each point under the fitted model.
    value, lo, hi : ndarray, shape (5, k)
        Coefficients Q (u s), N (u sqrt(s)), B (u), K (u/sqrt(s)), R (u/s) in the order of
        :data:`TERMS`, and their 95 % interval (``lo`` 0 when the interval reaches 0).
    chi2 : ndarray, shape (k,)
        Reduced chi-square of the fit (about 1 when the model explains the curve; the
        intervals are widened by its square root when above 1).
    sd_sq : ndarray, shape (5, k)
        Standard deviation of the squared coefficients (u^2 s^2, ...), from the fit's
        covariance with all terms free: the intervals at other levels
        (:meth:`interval`).
    """

    tau: np.ndarray
    avar: np.ndarray
    edf: np.ndarray
    value: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    chi2: np.ndarray
    sd_sq: np.ndarray

    def interval(self, z=Z95):
        """Interval of each coefficient at ``z`` standard deviations of its square:
        ``(sqrt(max(c^2 - z sd, 0)), sqrt(c^2 + z sd))``, shapes (5, k)."""
        c2 = self.value ** 2
        return np.sqrt(np.maximum(c2 - z * self.sd_sq, 0.0)), np.sqrt(c2 + z * self.sd_sq)

    def __getattr__(self, name):
        if name in TERMS:
            return self.value[TERMS.index(name)]
        raise AttributeError(name)

    def adev(self, tau):
        """Model Allan deviation at ``tau`` (s), shape (len(tau), k), u."""
        return np.sqrt(_basis(tau) @ self.value ** 2)


#: Correlation of the overlapping Allan variance estimates at taus 2^lag apart
#: (lag = 0..8 octaves) for each term of :data:`TERMS` (white PM, white FM, flicker
#: FM, random-walk FM, the ramp as random walk), measured over 1500 simulated logs of
#: 2^15 samples each (``bench/bench_allan.py --correlation`` prints them): neighbouring
#: octaves share much of their data, so the points of a curve are not independent.
RHO_OCTAVES = np.array([
    [1.0, 0.39, 0.51, 0.50, 0.49, 0.51, 0.49, 0.50, 0.50],
    [1.0, 0.52, 0.16, 0.04, 0.02, 0.02, 0.0, 0.0, 0.0],
    [1.0, 0.69, 0.31, 0.12, 0.04, 0.02, 0.0, 0.0, 0.0],
    [1.0, 0.89, 0.68, 0.49, 0.36, 0.25, 0.17, 0.10, 0.05],
    [1.0, 0.89, 0.68, 0.49, 0.36, 0.25, 0.17, 0.10, 0.05],
])


def _correlation(m, frac):
    """Correlation matrix of the Allan variance estimates at ``m`` (samples) under the
    mix ``frac`` (points x terms) of the model's terms, made positive definite."""
    lag = np.abs(np.log2(m[:, None] / m[None, :]))
    R = np.zeros((len(m), len(m)))
    root = np.sqrt(np.maximum(frac, 0.0))
    for t in range(frac.shape[1]):
        rho = np.interp(lag, np.arange(RHO_OCTAVES.shape[1]), RHO_OCTAVES[t])
        R += np.outer(root[:, t], root[:, t]) * rho
    w, V = np.linalg.eigh(0.5 * (R + R.T))
    R = (V * np.maximum(w, 1e-3)) @ V.T
    d = np.sqrt(np.diag(R))
    return R / np.outer(d, d)


def _fit_one(A, y, m, n_phase, iterations=4):
    """Generalized non-negative least squares of ``A c = y`` (c the squared
    coefficients) with the covariance of the estimates ``y`` under the fitted model;
    returns c, its covariance (all terms free), the reduced chi-square and the edf."""
    edf_t = _edf_terms(m, n_phase)
    model = y.copy()
    frac = np.zeros_like(A)
    frac[:, 1] = 1.0                      # first pass: white noise everywhere
    for _ in range(iterations):
        edf = 1.0 / np.sum(frac / edf_t, axis=1)
        sd = np.maximum(model, 1e-300) * np.sqrt(2.0 / edf)
        L = np.linalg.cholesky(_correlation(m, frac) * np.outer(sd, sd))
        Aw = np.linalg.solve(L, A)
        yw = np.linalg.solve(L, y)
        scale = np.linalg.norm(Aw, axis=0)
        c = nnls(Aw / scale, yw)[0] / scale
        parts = A * c
        model = parts.sum(axis=1)
        frac = parts / np.maximum(model, 1e-300)[:, None]
    r = Aw @ c - yw
    dof = max(1, len(y) - int(np.count_nonzero(c)))
    chi2 = float(r @ r / dof)
    Aws = Aw / scale
    cov = np.linalg.pinv(Aws.T @ Aws) / np.outer(scale, scale) * max(1.0, chi2)
    return c, cov, chi2, edf


def fit_noise_model(data, dt, increments=True, taus=None):
    """Fit the IEEE 952 model to the Allan variance of ``data`` (module docstring).

    Parameters
    ----------
    data : array_like, shape (n,) or (n, k)
        Increments (rad, m/s) if ``increments``, else rates, equally spaced by ``dt``.
    dt : float
        Sampling interval, s.
    increments : bool
        As in :func:`allan_deviation`.
    taus : array_like, optional
        Averaging times of the fit, s (default: octaves from dt to a quarter of the
        record, whose estimates are nearly independent).

    Returns
    -------
    NoiseFit
        Per axis (k = 1 for a 1-d input).
    """
    y = np.asarray(data, dtype=float)
    n = len(y)
    tau, adev = allan_deviation(y.reshape(n, -1), dt,
                                octave_taus(n, dt) if taus is None else taus, increments)
    return _fit_curve(tau, adev, dt, n)


def _fit_curve(tau, adev, dt, n):
    if len(tau) < 3:
        raise ValueError(f"{len(tau)} averaging times are too few for the noise model "
                         f"(a log of {n} samples)")
    if not np.all(np.isfinite(adev)) or np.any(adev <= 0):
        raise ValueError("the Allan deviation is zero or not finite somewhere: the log "
                         "holds no noise (an exact synthetic log?)")
    A = _basis(tau)
    m = np.round(tau / dt)
    k = adev.shape[1]
    val, sd_sq = np.zeros((5, k)), np.zeros((5, k))
    chi2, edf = np.zeros(k), np.zeros((len(tau), k))
    for j in range(k):
        c, cov, chi2[j], edf[:, j] = _fit_one(A, adev[:, j] ** 2, m, n + 1)
        sd_sq[:, j] = np.sqrt(np.maximum(np.diag(cov), 0.0))
        val[:, j] = np.sqrt(c)
    lo, hi = np.sqrt(np.maximum(val ** 2 - Z95 * sd_sq, 0.0)), np.sqrt(val ** 2 + Z95 * sd_sq)
    return NoiseFit(tau=tau, avar=adev ** 2, edf=edf, value=val, lo=lo, hi=hi, chi2=chi2,
                    sd_sq=sd_sq)


def noise_densities(tau, adev, n_samples=None):
    """Random walk and bias instability of the IEEE 952 model fitted to a curve.

    Parameters
    ----------
    tau : ndarray, shape (m,)
        s; the smallest is taken as the sampling interval.
    adev : ndarray, shape (m,) or (m, k)
    n_samples : int, optional
        Length of the log (default: four times the largest tau, as in the default
        curve of :func:`allan_deviation`); it sets the weights of the points.

    Returns
    -------
    random_walk : ndarray, shape () or (k,)
        ``N`` of the model, units of adev * sqrt(s) (rad/sqrt(s), m/s/sqrt(s)).
    bias_instability : ndarray
        ``B`` of the model (flat floor / 0.664), units of adev.
    """
    tau = np.asarray(tau, dtype=float)
    a = np.asarray(adev, dtype=float)
    one = a.ndim == 1
    a = a.reshape(len(a), -1)
    dt = float(tau.min())
    n = int(n_samples) if n_samples is not None else int(round(4 * tau.max() / dt)) + 1
    fit = _fit_curve(tau, a, dt, n)
    rw, bi = fit.value[1], fit.value[2]
    return (rw[0], bi[0]) if one else (rw, bi)


#: Half width of the log-log window over which the local slope of the curve is fitted,
#: decades, and the largest departure of that slope from -1/2 of a point on the white
#: noise line (the classic reading, :func:`classic_reading`).
SLOPE_HALF_WIDTH, SLOPE_TOL = 0.25, 0.1
#: Half width of the neighbourhood of the reading tau whose points' intervals are
#: joined into the interval of N, decades: a bump or a filter's edge within it widens
#: the interval instead of hiding in a single point.
READ_HALF_WIDTH = 0.25
#: Shortest stretch of slope -1/2 that is read as the white noise line, decades.
MIN_RUN_DECADES = 0.3


@dataclass(frozen=True)
class ClassicReading:
    """The classic reading of an Allan deviation curve, per axis (rate units ``u``).

    Where the IEEE 952 model does not describe the curve (a part's internal filter, a
    sinusoid, a bump), the textbook graphical reading still holds where the curve has
    the slope of its term.  The random walk ``N`` is the value at tau = 1 s of the line
    of slope -1/2 laid on the curve where the curve has that slope:
    ``N = sigma(tau*) sqrt(tau*)``.  The curve's local slope (least squares over
    +-:data:`SLOPE_HALF_WIDTH` decade) must be within :data:`SLOPE_TOL` of -1/2 over a
    stretch of at least :data:`MIN_RUN_DECADES` before the curve's minimum; of several
    such stretches the one that lies lowest is read (every other noise, a sinusoid's
    bump - whose falling flank crosses the slope -1/2 above the line - and a drift lift
    the curve above ``N / sqrt(tau)``), at its point of slope nearest -1/2.  The bias
    instability ``B`` is the curve's minimum / 0.664 (the flicker floor
    ``sqrt(2 ln2 / pi) B``), at the tau of the minimum: in expectation it reads high
    (the white noise, the rate random walk and a drift add to the floor there); at the
    longest taus few clusters make its interval wide.

    Intervals (95 %): the chi-square interval of the overlapping Allan variance at a
    point, with its equivalent degrees of freedom (NIST SP 1065 table 5: white FM for
    N, flicker FM for B; for a long log about 1.5 (samples / m) and (samples / m), the
    number of clusters of m samples).  For N the hull of those intervals over the points
    of the stretch within :data:`READ_HALF_WIDTH` decade of tau*, each widened both ways
    by the share of the white noise that its slope ``s`` allows, ``w = 1 - 2 |s + 1/2|``
    (times ``w`` below, divided above, in the variance): exact for a white noise with a
    flat floor or a quantization, and to first order below a low-pass filter's edge.
    Over 90 simulated axes (ADIS16405-class noise, with and without a 0.1 s low-pass
    and a 0.4 Hz sinusoid, 1 h and 2.8 h) every axis was read and 89 of the 90 intervals
    held the truth (median width hi/lo 1.22).

    Attributes
    ----------
    found : ndarray of bool, shape (k,)
        Whether the curve has a stretch of slope -1/2 (within :data:`SLOPE_TOL`, at
        least :data:`MIN_RUN_DECADES`) before its minimum; N and its interval are NaN
        where not.
    n, n_lo, n_hi : ndarray, shape (k,)
        N (u sqrt(s)) and its 95 % interval.
    n_tau : ndarray, shape (k,)
        tau* (s).
    n_edf : ndarray, shape (k,)
        Degrees of freedom at tau*.
    b, b_lo, b_hi, b_tau, b_edf : ndarray, shape (k,)
        B (u), its interval, the tau of the minimum (s) and the degrees of freedom there.
    """

    found: np.ndarray
    n: np.ndarray
    n_lo: np.ndarray
    n_hi: np.ndarray
    n_tau: np.ndarray
    n_edf: np.ndarray
    b: np.ndarray
    b_lo: np.ndarray
    b_hi: np.ndarray
    b_tau: np.ndarray
    b_edf: np.ndarray


def _local_slope(lt, la, half):
    """Least-squares slope of ``la`` on ``lt`` within ``half`` of each point."""
    s = np.full(len(lt), np.nan)
    for i in range(len(lt)):
        sel = np.abs(lt - lt[i]) <= half + 1e-12
        if sel.sum() >= 3:
            x = lt[sel] - lt[sel].mean()
            s[i] = float(x @ (la[sel] - la[sel].mean()) / (x @ x))
    return s


def _chi2_interval(avar, edf, level=0.95):
    from scipy.stats import chi2
    a = (1 - level) / 2
    return avar * edf / chi2.ppf(1 - a, edf), avar * edf / chi2.ppf(a, edf)


def classic_reading(data, dt, increments=True, per_decade=20):
    """The classic reading of the Allan deviation of ``data`` (:class:`ClassicReading`).

    Parameters
    ----------
    data : array_like, shape (n,) or (n, k)
        Increments (rad, m/s) if ``increments``, else rates, equally spaced by ``dt``.
    dt : float
        Sampling interval, s.
    increments : bool
        As in :func:`allan_deviation`.
    per_decade : int
        Points of the curve per decade (from dt to a quarter of the record).

    Returns
    -------
    ClassicReading
        Per axis (k = 1 for a 1-d input).
    """
    y = np.asarray(data, dtype=float)
    n = len(y)
    y = y.reshape(n, -1)
    tau, adev = allan_deviation(y, dt, _default_taus(n, dt, per_decade), increments)
    if len(tau) < 5:
        raise ValueError(f"{len(tau)} averaging times are too few for a reading "
                         f"(a log of {n} samples)")
    if not np.all(np.isfinite(adev)) or np.any(adev <= 0):
        raise ValueError("the Allan deviation is zero or not finite somewhere: the log "
                         "holds no noise (an exact synthetic log?)")
    m = np.round(tau / dt)
    edf = _edf_terms(m, n + 1)
    lt = np.log10(tau)
    k = adev.shape[1]
    out = {f: np.full(k, np.nan) for f in ("n", "n_lo", "n_hi", "n_tau", "n_edf", "b",
                                           "b_lo", "b_hi", "b_tau", "b_edf")}
    found = np.zeros(k, dtype=bool)
    for j in range(k):
        a = adev[:, j]
        i_min = int(np.argmin(a))
        lo, hi = _chi2_interval(a[i_min] ** 2, edf[i_min, 2])
        scale = 1.0 / np.sqrt(2 * np.log(2) / np.pi)          # 1 / 0.664
        out["b"][j], out["b_tau"][j], out["b_edf"][j] = a[i_min] * scale, tau[i_min], \
            edf[i_min, 2]
        out["b_lo"][j], out["b_hi"][j] = np.sqrt(lo) * scale, np.sqrt(hi) * scale
        slope = _local_slope(lt, np.log10(a), SLOPE_HALF_WIDTH)
        idx = np.arange(len(tau))
        ok = (np.abs(slope + 0.5) <= SLOPE_TOL) & (idx < i_min) & (m >= 3)
        # runs of consecutive points on a -1/2 line, at least MIN_RUN_DECADES long; the
        # one that lies lowest: the other noises, a sinusoid's bump (whose falling flank
        # crosses -1/2 above the line) and a drift all lift the curve above N / sqrt(tau)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(int), [0]])))
        runs = [(r0, r1) for r0, r1 in zip(edges[::2], edges[1::2])
                if lt[r1 - 1] - lt[r0] >= MIN_RUN_DECADES - 1e-12]
        if not runs:
            continue
        line = a * np.sqrt(tau)
        r0, r1 = min(runs, key=lambda r: float(np.min(line[r[0]:r[1]])))
        i = r0 + int(np.argmin(np.abs(slope[r0:r1] + 0.5)))
        near = np.arange(r0, r1)
        near = near[np.abs(lt[near] - lt[i]) <= READ_HALF_WIDTH + 1e-12]
        lo, hi = _chi2_interval(a[near] ** 2, edf[near, 1])
        # the share of the white noise in the curve that its slope allows: 1 - 2 |s + 1/2|
        # (exact for a white noise with a flat floor, with a quantization, or below a
        # low-pass filter's edge, to first order); the interval spans it both ways
        white = np.clip(1.0 - 2.0 * np.abs(slope[near] + 0.5), 0.05, 1.0)
        found[j] = True
        out["n"][j], out["n_tau"][j], out["n_edf"][j] = line[i], tau[i], edf[i, 1]
        out["n_lo"][j] = float(np.min(np.sqrt(white * lo * tau[near])))
        out["n_hi"][j] = float(np.max(np.sqrt(hi * tau[near] / white)))
    return ClassicReading(found=found, **out)
