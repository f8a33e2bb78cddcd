"""The screen of the covariances of an RTKLIB ``.pos`` solution before they weigh anything.

RTKLIB demo5 2.5.0 in kinematic mode with ``pos1-dynamics = on`` (its default) writes
sigma columns that are no covariance at all: on the GEONET pair 0759/3040 ``sdn 0.0000``
beside ``sdne -0.4266`` (a correlation of infinity), and ``sde 41.6 m`` on a float epoch
between neighbours of 0.9 and 0.4 m.  Two rules, applied in the file's own axes (ENU for
the llh and enu layouts, ECEF for xyz), on the matrix rebuilt from the printed columns
(:func:`screen`):

1. **Not a covariance.**  The printed roots carry a rounding error of half a unit of the
   last decimal (:data:`ROUNDING_M`, RTKLIB prints 4).  A record is invalid when the matrix
   with every standard deviation raised by it and every off-diagonal root lowered in
   magnitude by it still has a negative eigenvalue (smaller than ``-1e-12 m^2``): no
   rounding of a valid matrix prints that.  Repair: the off-diagonal terms are dropped and
   each variance is raised to at least the median variance, on the same axis, of the
   valid records with the same quality flag Q (a printed 0 beside large covariances says
   nothing of the variance).  With fewer than :data:`MIN_PEERS` valid records of that Q
   there is nothing to take the median of, and the record is dropped.
2. **Out of all proportion.**  A record whose largest standard deviation exceeds
   :data:`RATIO` times the median of the largest standard deviation of the valid records
   with the same Q (at least :data:`MIN_PEERS` of them) is dropped: two orders of
   magnitude beyond its peers is not a property of the epoch but of the estimator's
   bookkeeping (a fixed epoch cannot be metres uncertain; a float one of 41 m between
   0.9 and 0.4 m has lost its covariance), and neither the position nor the sigma of
   such a record is trusted.

Valid records pass unchanged (:mod:`ins.io.rtklib` then floors their rounding).  The
reader counts and reports what was repaired and dropped (:class:`CovarianceScreen`).
"""
from dataclasses import dataclass

import numpy as np

__all__ = ["screen", "CovarianceScreen", "ROUNDING_M", "RATIO", "MIN_PEERS"]

#: Half a unit of RTKLIB's last printed decimal of a standard deviation, m.
ROUNDING_M = 0.5e-4
#: A standard deviation this many times the median of its quality's is dropped.
RATIO = 100.0
#: Fewest valid records of a quality flag that make a median.
MIN_PEERS = 3
_NEG_TOL_M2 = 1e-12


@dataclass(frozen=True)
class CovarianceScreen:
    """What :func:`screen` did to a file's records.

    Attributes
    ----------
    repaired_lines : ndarray of int
        1-based file lines whose covariance was not one (rule 1): off-diagonal terms
        dropped, variances raised to their quality's median.
    dropped_lines : ndarray of int
        Lines removed from the log (rule 1 without peers, or rule 2).
    records : int
        Records screened.
    """

    repaired_lines: np.ndarray
    dropped_lines: np.ndarray
    records: int = 0

    def __bool__(self):
        return bool(self.repaired_lines.size or self.dropped_lines.size)

    def message(self, path, limit=5):
        """One line for a warning, naming the file and the first lines of each kind."""
        def lines(a):
            text = ", ".join(str(int(x)) for x in a[:limit])
            return text + (f" and {a.size - limit} more" if a.size > limit else "")
        parts = []
        if self.repaired_lines.size:
            parts.append(f"{self.repaired_lines.size} record(s) whose sigma columns are not a "
                         f"covariance (lines {lines(self.repaired_lines)}): off-diagonal "
                         f"terms dropped, variances raised to the median of their quality")
        if self.dropped_lines.size:
            parts.append(f"{self.dropped_lines.size} record(s) dropped, sigma over {RATIO:g} "
                         f"times the median of their quality or no valid peer (lines "
                         f"{lines(self.dropped_lines)})")
        text = f"{path}: RTKLIB covariance screen: " + "; ".join(parts)
        if self.repaired_lines.size + self.dropped_lines.size > 0.5 * max(self.records, 1):
            text += (f" ({self.repaired_lines.size + self.dropped_lines.size} of "
                     f"{self.records} records: RTKLIB demo5's kinematic mode with "
                     f"pos1-dynamics = on writes such columns; with [rtklib] dynamics = "
                     f"false they are a covariance)")
        return text


def invalid_covariance(cov_m2, rounding_m=ROUNDING_M):
    """Boolean (n,): the matrices that no rounding of a covariance prints (rule 1).

    ``cov_m2`` (n, 3, 3) is rebuilt from RTKLIB's signed roots ``c = s |s|``."""
    s = np.sign(cov_m2) * np.sqrt(np.abs(cov_m2))
    idx = np.arange(3)
    off = np.sign(s) * np.maximum(np.abs(s) - rounding_m, 0.0)
    off[:, idx, idx] = np.abs(s[:, idx, idx]) + rounding_m
    best = off * np.abs(off)
    return np.linalg.eigvalsh(best)[:, 0] < -_NEG_TOL_M2


def screen(cov_m2, quality, line):
    """Apply the two rules (module notes).

    Parameters
    ----------
    cov_m2 : ndarray, shape (n, 3, 3)
        Covariances in the file's axes, m^2, as printed (before any floor).
    quality : ndarray, shape (n,) of int
        RTKLIB's Q of each record.
    line : ndarray, shape (n,) of int
        1-based file line of each record.

    Returns
    -------
    cov_m2 : ndarray, shape (n, 3, 3)
        Repaired covariances (all records, the dropped ones included).
    keep : ndarray of bool, shape (n,)
    report : CovarianceScreen
    """
    n = cov_m2.shape[0]
    idx = np.arange(3)
    cov = np.array(cov_m2, dtype=float, copy=True)
    bad = invalid_covariance(cov)
    keep = np.ones(n, bool)
    var = cov[:, idx, idx]
    for q in np.unique(quality):
        rows = quality == q
        peers = rows & ~bad
        if peers.sum() < MIN_PEERS:
            keep[rows & bad] = False
            continue
        med_var = np.median(var[peers], axis=0)
        fix = np.flatnonzero(rows & bad)
        if fix.size:
            diag = np.maximum(var[fix], med_var)
            cov[fix] = 0.0
            cov[fix[:, None], idx, idx] = diag
        med_max = np.median(np.sqrt(np.max(var[peers], axis=1)))
        largest = np.sqrt(np.max(cov[rows][:, idx, idx], axis=1))
        keep[np.flatnonzero(rows)[largest > RATIO * max(med_max, ROUNDING_M)]] = False
    line = np.asarray(line, np.int64)
    report = CovarianceScreen(np.sort(line[bad & keep]), np.sort(line[~keep]), n)
    return cov, keep, report
