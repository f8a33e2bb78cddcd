"""Overlapping Allan deviation of IMU data and the noise terms read from it.

For a rate signal ``y`` sampled every ``dt`` (or increments ``y dt``), with the running
integral ``theta_k = sum_{j<=k} y_j dt`` and ``tau = m dt``::

    sigma^2(tau) = sum_k (theta_{k+2m} - 2 theta_{k+m} + theta_k)^2 / (2 tau^2 (N - 2m))

(IEEE Std 952, overlapping estimator; all k at once from the cumulative sum).  White
rate noise of density ``N`` (angle/velocity random walk, rad/sqrt(s) or m/s/sqrt(s))
gives ``sigma(tau) = N / sqrt(tau)``: ``N`` is read on the slope -1/2 at tau = 1 s.
Flicker (bias instability ``B``) gives the flat minimum ``0.664 B``.
"""
import numpy as np

__all__ = ["allan_deviation", "noise_densities"]


def _default_taus(n, dt, per_decade=10):
    m_max = max(1, (n - 1) // 4)
    m = np.unique(np.round(np.logspace(0, np.log10(m_max), int(per_decade * np.log10(m_max)) + 1)))
    return m.astype(np.int64) * dt


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
    theta = np.concatenate([np.zeros((1, y.shape[1])), np.cumsum(inc, axis=0)])
    if taus is None:
        taus = _default_taus(n, dt)
    m = np.unique(np.round(np.asarray(taus, dtype=float) / dt).astype(np.int64))
    m = m[(m >= 1) & (2 * m <= n)]
    adev = np.empty((len(m), y.shape[1]))
    for i, mi in enumerate(m):
        d = theta[2 * mi:] - 2 * theta[mi:-mi] + theta[:-2 * mi]
        adev[i] = np.sqrt(np.mean(d * d, axis=0) / 2.0) / (mi * dt)
    tau = m * dt
    return tau, (adev[:, 0] if one else adev)


def noise_densities(tau, adev):
    """White-noise density and bias instability read from an Allan deviation curve.

    Parameters
    ----------
    tau : ndarray, shape (m,)
    adev : ndarray, shape (m,) or (m, k)

    Returns
    -------
    random_walk : ndarray, shape () or (k,)
        ``sigma(1 s)`` of the slope -1/2 line fitted (in log-log) on the first run of
        points whose local slope is within -0.5 +- 0.15, units of
        adev * sqrt(s) (rad/sqrt(s), m/s/sqrt(s)).
    bias_instability : ndarray
        ``min(adev) / 0.664``, units of adev.
    """
    tau = np.asarray(tau, dtype=float)
    a = np.asarray(adev, dtype=float)
    one = a.ndim == 1
    a = a.reshape(len(a), -1)
    rw = np.empty(a.shape[1])
    for j in range(a.shape[1]):
        la, lt = np.log(a[:, j]), np.log(tau)
        slope = np.gradient(la, lt)
        ok = np.abs(slope + 0.5) < 0.15
        if not ok.any():
            raise ValueError("no part of the Allan deviation has the slope -1/2 of white noise")
        start = int(np.argmax(ok))
        run = ok[start:]
        end = start + (int(np.argmin(run)) if not run.all() else len(run))
        use = np.arange(start, end)
        rw[j] = np.exp(np.mean(la[use] + 0.5 * lt[use]))
    bi = a.min(axis=0) / 0.664
    return (rw[0], bi[0]) if one else (rw, bi)
