"""Disk-backed stores of the forward filter: the node matrices (:class:`NodeStore`, read
backwards by the smoother) and the forward trajectory (:class:`TrajectoryStore`), in memory
or spilled to anonymous temporary files in a work folder (bounded memory for long logs)."""
import os
import tempfile

import numpy as np

from ins.estimation.error_model import VARIANCE_RTOL, checked_std


class Rows:
    """Rows of one shape appended one at a time into an array that doubles when full:
    no Python object per row (a 10 h log at 1 s nodes has 36 000 of them; lists of small
    arrays cost twice the memory and fragment the heap)."""

    def __init__(self, shape=None, dtype=np.float64):
        self._a, self._shape, self._dtype, self.count = None, shape, dtype, 0

    def append(self, row):
        row = np.asarray(row, dtype=self._dtype)
        if self._a is None:
            self._a = np.empty((256,) + (row.shape if self._shape is None else self._shape),
                               self._dtype)
        elif self.count == len(self._a):
            grown = np.empty((2 * len(self._a),) + self._a.shape[1:], self._dtype)
            grown[:self.count] = self._a
            self._a = grown
        self._a[self.count] = row
        self.count += 1

    def __len__(self):
        return self.count

    def array(self):
        """The rows so far (a copy), shape (count, ...)."""
        if self._a is None:
            return np.empty((0,) + (self._shape or ()), self._dtype)
        return self._a[:self.count].copy()


class NodeStore:
    """``P_prior``, ``P_post`` and ``Phi`` (n x n each, n the number of error states) of
    every node, kept for the RTS pass.

    In memory, or, with ``workdir``, appended to an anonymous temporary file there (10.6
    kB a node: 380 MB for a 10 h flight at 1 Hz, on disk, not in memory) and read back
    backwards in blocks.  They stay float64: after long GNSS tracking ``P_prior`` has
    correlations close to 1 and a condition number near 1e12, which the 1e-7 rounding of
    float32 would turn indefinite (the smoother's Cholesky step then fails).
    """

    def __init__(self, workdir=None):
        self.count = 0
        self.n = None
        self._post_std = Rows()            # sqrt(diag(P_post)) of every node (small)
        self._mem = [] if workdir is None else None
        self._file = None if workdir is None else tempfile.TemporaryFile(dir=workdir)

    def append(self, P_prior, P_post, Phi, time=None):
        """Store one node; a negative variance (beyond rounding) in either covariance
        raises :class:`~ins.common.errors.QualityError` naming ``time`` (s) and the state."""
        self.n = n = len(P_prior)
        d_prior, d_post = P_prior.ravel()[::n + 1], P_post.ravel()[::n + 1]
        scale = np.maximum(np.abs(d_prior), np.abs(d_post))
        floor = -VARIANCE_RTOL * scale
        if (d_prior >= floor).all() and (d_post >= floor).all():   # the usual case: fast
            self._post_std.append(np.sqrt(np.maximum(d_post, 0.0)))
        else:
            checked_std(d_prior, scale, time, what="forward filter's prior covariance")
            self._post_std.append(checked_std(d_post, scale, time,
                                              what="forward filter's posterior covariance"))
        if self._mem is not None:
            self._mem.append(np.stack([P_prior, P_post, Phi]))
        else:
            for a in (P_prior, P_post, Phi):
                self._file.write(np.ascontiguousarray(a, dtype=np.float64).data)
        self.count += 1

    @property
    def post_std(self):
        """``sqrt(diag(P_post))`` of every node, array (count, n)."""
        return self._post_std.array()

    def block(self, j0, j1):
        """Nodes ``j0 .. j1-1``: array (j1 - j0, 3, n, n) of P_prior, P_post, Phi."""
        n = self.n or 0
        if self._mem is not None:
            return np.array(self._mem[j0:j1]).reshape(j1 - j0, 3, n, n)
        rec = 3 * n * n
        self._file.flush()
        self._file.seek(j0 * rec * 8)
        data = np.fromfile(self._file, dtype=np.float64, count=(j1 - j0) * rec)
        self._file.seek(0, os.SEEK_END)
        return data.reshape(j1 - j0, 3, n, n)

    def blocks_reversed(self, size=512):
        """``(j0, block)`` from the last nodes to the first."""
        j1 = self.count
        while j1 > 0:
            j0 = max(0, j1 - size)
            yield j0, self.block(j0, j1)
            j1 = j0


class TrajectoryStore:
    """The forward trajectory (time and ``ins.nav._kernels`` states) in memory or spilled to
    an anonymous temporary file in ``workdir``; read back chunk by chunk in time order."""

    def __init__(self, workdir=None):
        self._mem = [] if workdir is None else None
        self._file = None if workdir is None else tempfile.TemporaryFile(dir=workdir)
        self._sizes = []

    def append(self, time, states):
        rows = np.column_stack([time, states])
        if self._mem is not None:
            self._mem.append(rows)
        else:
            self._file.write(rows.data)           # no second copy (tobytes)
        self._sizes.append(len(rows))

    def __len__(self):
        return int(sum(self._sizes))

    def chunks(self, rows=1 << 16):
        """``(row0, time, states)`` pieces in time order (copies; at most ~``rows`` rows)."""
        if self._mem is not None:
            row0 = 0
            for rows_ in self._mem:
                yield row0, rows_[:, 0].copy(), rows_[:, 1:].copy()
                row0 += len(rows_)
            return
        self._file.flush()
        self._file.seek(0)
        total, row0 = len(self), 0
        while row0 < total:
            k = min(rows, total - row0)
            data = np.fromfile(self._file, dtype=np.float64, count=11 * k).reshape(k, 11)
            yield row0, data[:, 0].copy(), data[:, 1:].copy()
            row0 += k

    def whole(self):
        """``(time, states)`` of the whole trajectory (in memory)."""
        parts = [(t, x) for _, t, x in self.chunks()]
        return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]))
