"""Integer ambiguity resolution: RTKLIB's LAMBDA (through ``pyrtklib5``; the search is not
written again here), its validation, and partial fixing.

Validation
----------
Two tests, both must pass:

- the ratio test: the squared norm of the second-best integer candidate over the best's,
  ``s2 / s1 >= ratio`` (RTKLIB's default 3);
- the success rate of integer bootstrapping (Teunissen 1998) on the decorrelated
  float ambiguities, ``P_s = prod_i (2 Phi(1 / (2 sigma_i)) - 1)``, ``sigma_i`` the
  conditional standard deviations of the Z-transformed ambiguities (RTKLIB's
  ``lambda_reduction`` gives ``Z``; the conditional variances are the diagonal of the
  LDL^T factor taken in LAMBDA's order, from the last to the first); it is a lower
  bound of the integer least-squares success rate, ``>= min_success``.

Partial fixing
--------------
When the whole set fails, the ambiguity with the largest float variance is left out
(never one that ``keep`` names, e.g. those already held) and the test is redone, while
at least ``min_count`` ambiguities remain.

Units: ambiguities in cycles, their covariance in cycles^2.
"""
from dataclasses import dataclass

import numpy as np
from scipy.special import erf

__all__ = ["AmbiguityFix", "lambda_search", "bootstrap_success_rate", "resolve"]


@dataclass
class AmbiguityFix:
    """The outcome of :func:`resolve`.

    Attributes
    ----------
    index : ndarray of int
        The ambiguities fixed (indices into the input), empty when none.
    integers : ndarray of float
        Their integer values (cycles).
    ratio : float
        The ratio test's value of the set tried last (``nan``: no search).
    success_rate : float
        The bootstrapped success rate of that set.
    tried : int
        Sets tried (1: the whole set passed).
    """

    index: np.ndarray
    integers: np.ndarray
    ratio: float
    success_rate: float
    tried: int

    @property
    def fixed(self):
        return len(self.index) > 0


def _rtk():
    from ins.common.errors import InputError
    try:
        import pyrtklib5
    except ImportError:
        raise InputError("ambiguity resolution needs RTKLIB's LAMBDA from pyrtklib5 "
                         "(pip install pyrtklib5)") from None
    return pyrtklib5


def _arr(rtk, values):
    values = np.asarray(values, float).ravel(order="F")
    a = rtk.Arr1Ddouble(len(values))
    for i, v in enumerate(values.tolist()):
        a[i] = v
    return a


def lambda_search(a, Q, m=2):
    """The ``m`` best integer vectors for float ambiguities ``a`` (n,) with covariance
    ``Q`` (n, n), by RTKLIB's ``lambda``.

    Returns
    -------
    F : ndarray (m, n)
        Candidates, best first.
    s : ndarray (m,)
        Their squared norms ``(a - F_i)^T Q^-1 (a - F_i)``.

    Raises
    ------
    ValueError
        RTKLIB's lambda failed (``Q`` not positive definite).
    """
    rtk = _rtk()
    a = np.asarray(a, float)
    n = len(a)
    F, s = rtk.Arr1Ddouble(n * m), rtk.Arr1Ddouble(m)
    info = getattr(rtk, "lambda")(n, m, _arr(rtk, a), _arr(rtk, Q), F, s)
    if info != 0:
        raise ValueError(f"RTKLIB lambda failed (info {info}): Q not positive definite")
    return (np.array([F[i] for i in range(n * m)]).reshape(m, n),
            np.array([s[i] for i in range(m)]))


def _normal_cdf(x):
    return 0.5 * (1.0 + erf(np.asarray(x, float) / np.sqrt(2.0)))


def bootstrap_success_rate(Q, decorrelate=True):
    """Success rate of integer bootstrapping for ambiguities of covariance ``Q`` (n, n),
    cycles^2: ``prod (2 Phi(1 / (2 sigma_i)) - 1)`` over the conditional standard
    deviations (module notes), after RTKLIB's Z-decorrelation when ``decorrelate``."""
    Q = 0.5 * (np.asarray(Q, float) + np.asarray(Q, float).T)
    n = len(Q)
    if decorrelate:
        rtk = _rtk()
        Z = rtk.Arr1Ddouble(n * n)
        if rtk.lambda_reduction(n, _arr(rtk, Q), Z) != 0:
            raise ValueError("RTKLIB lambda_reduction failed: Q not positive definite")
        Zm = np.array([Z[i] for i in range(n * n)]).reshape(n, n, order="F")
        Q = Zm.T @ Q @ Zm
    # LDL^T conditioned from the last ambiguity to the first (LAMBDA's order): the
    # Cholesky factor of the reversed matrix holds the conditional deviations
    C = np.linalg.cholesky(Q[::-1, ::-1])
    sigma = np.abs(np.diag(C))
    return float(np.prod(2.0 * _normal_cdf(0.5 / sigma) - 1.0))


def resolve(a, Q, ratio=3.0, min_success=0.999, min_count=3, keep=()):
    """Fix what can be fixed of the float ambiguities ``a`` (n,) with covariance ``Q``
    (module notes).

    Parameters
    ----------
    a : array_like (n,)
        Float ambiguities, cycles.
    Q : array_like (n, n)
        Their covariance, cycles^2.
    ratio : float
        Threshold of the ratio test.
    min_success : float
        Threshold of the bootstrapped success rate.
    min_count : int
        Fewest ambiguities in a partial set.
    keep : sequence of int
        Indices never left out by the partial fixing.

    Returns
    -------
    AmbiguityFix
    """
    a = np.asarray(a, float)
    Q = 0.5 * (np.asarray(Q, float) + np.asarray(Q, float).T)
    idx = np.arange(len(a))
    keep = set(int(k) for k in keep)
    last_ratio, last_ps, tried = np.nan, np.nan, 0
    while len(idx) >= max(min_count, 1):
        sub = np.ix_(idx, idx)
        tried += 1
        try:
            F, s = lambda_search(a[idx], Q[sub])
            ps = bootstrap_success_rate(Q[sub])
        except (ValueError, np.linalg.LinAlgError):
            break
        last_ratio = float(s[1] / s[0]) if s[0] > 0 else np.inf
        last_ps = ps
        if last_ratio >= ratio and ps >= min_success:
            return AmbiguityFix(idx.copy(), F[0], last_ratio, ps, tried)
        free = [i for i in range(len(idx)) if int(idx[i]) not in keep]
        if not free:
            break
        worst = max(free, key=lambda i: Q[idx[i], idx[i]])
        idx = np.delete(idx, worst)
    return AmbiguityFix(np.zeros(0, int), np.zeros(0), last_ratio, last_ps, tried)
