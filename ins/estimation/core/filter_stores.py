"""Disk-backed stores of the forward filter: the node matrices (:class:`NodeStore`, read
backwards by the smoother) and the forward trajectory (:class:`TrajectoryStore`), in memory
or spilled to anonymous temporary files in a work folder (bounded memory for long logs)."""
import os
import tempfile

import numpy as np

from ins.estimation.core import _kalman_kernels
from ins.estimation.core.error_model import ATT_CROSS, ATT_STOP, VARIANCE_RTOL, checked_std
from ins.estimation.core.measurements import UpdateRecord

#: Rows of a trajectory piece read back from disk (and of the pieces formatted into the
#: output files): 16 384 rows are 1.4 MB of states and about 2.5 MB of .nav text, small
#: beside the run's fixed memory, and large enough that the per-piece cost is nothing.
PIECE_ROWS = 1 << 14


class Rows:
    """Rows of one shape appended one at a time: no Python object per row (a 10 h log at
    1 s nodes has 36 000 of them; lists of small arrays cost twice the memory and
    fragment the heap).

    In memory (an array that doubles when full), or, with ``workdir``, through a buffer
    of ``buffer`` rows appended to an anonymous temporary file there: memory does not
    grow with the number of rows; :meth:`read` and :meth:`chunks` read them back.
    """

    def __init__(self, shape=None, dtype=np.float64, workdir=None, buffer=4096):
        self._a, self._shape, self._dtype, self.count = None, shape, np.dtype(dtype), 0
        self._file = None if workdir is None else tempfile.TemporaryFile(dir=workdir)
        self._buffer, self._on_disk = buffer, 0          # rows in the file

    def _alloc(self, n, row_shape):
        return np.empty((n,) + row_shape, self._dtype)

    def append(self, row):
        a = self._a
        if a is not None and self.count - self._on_disk < len(a):   # room in the buffer
            a[self.count - self._on_disk] = row
            self.count += 1
            return
        row = np.asarray(row, dtype=self._dtype)
        if self._a is None:
            if self._shape is None:
                self._shape = row.shape
            self._a = self._alloc(self._buffer if self._file is not None else 256, self._shape)
        n = self.count - self._on_disk                 # rows in self._a
        if n == len(self._a):
            if self._file is not None:                 # spill the buffer
                self._file.write(self._a.data)
                self._on_disk, n = self.count, 0
            else:
                grown = self._alloc(2 * len(self._a), self._a.shape[1:])
                grown[:n] = self._a
                self._a = grown
        self._a[n] = row
        self.count += 1

    def pop(self):
        """Remove the last row and return it."""
        if self.count == 0:
            raise IndexError("pop from empty Rows")
        if self.count == self._on_disk:                # the buffer is empty: read back
            k = min(self._buffer, self._on_disk)
            self._a[:k] = self.read(self._on_disk - k, self._on_disk)
            self._on_disk -= k
            self._file.truncate(self._on_disk * self._row_bytes)
            self._file.seek(0, os.SEEK_END)
        self.count -= 1
        return self._a[self.count - self._on_disk].copy()

    @property
    def _row_bytes(self):
        return int(np.prod(self._shape, dtype=np.int64)) * self._dtype.itemsize

    def __len__(self):
        return self.count

    def read(self, j0, j1):
        """Rows ``j0 .. j1-1`` (a copy), shape (j1 - j0, ...)."""
        j0, j1 = max(j0, 0), min(j1, self.count)
        if self._a is None or j1 <= j0:
            return np.empty((0,) + (self._shape or ()), self._dtype)
        if self._file is None:
            return self._a[j0:j1].copy()
        out = self._alloc(j1 - j0, self._shape)
        k = min(j1, self._on_disk) - j0                # rows from the file
        if k > 0:
            self._file.flush()
            self._file.seek(j0 * self._row_bytes)
            n_items = k * (self._row_bytes // self._dtype.itemsize)
            out[:k] = np.fromfile(self._file, self._dtype, n_items).reshape(
                (k,) + self._shape)
            self._file.seek(0, os.SEEK_END)
        k = max(k, 0)
        out[k:] = self._a[j0 + k - self._on_disk:j1 - self._on_disk]
        return out

    def chunks(self, size=1 << 14):
        """``(j0, rows)`` pieces in order, at most ``size`` rows each."""
        for j0 in range(0, self.count, size):
            yield j0, self.read(j0, j0 + size)

    def __getitem__(self, j):
        """Row ``j`` (negative from the end)."""
        j = j + self.count if j < 0 else j
        if not 0 <= j < self.count:
            raise IndexError(j)
        return self.read(j, j + 1)[0]

    def array(self):
        """The rows so far (a copy), shape (count, ...)."""
        return self.read(0, self.count)


class Table:
    """``count`` rows of ``width`` float64 written in blocks in any order (the smoother
    writes backwards) and read in blocks: in memory, or with ``workdir`` in an anonymous
    temporary file there."""

    def __init__(self, count, width, workdir=None):
        self.count, self.width = count, width
        self._file = None if workdir is None else tempfile.TemporaryFile(dir=workdir)
        self._a = np.zeros((count, width)) if workdir is None else None

    def __len__(self):
        return self.count

    def put(self, j0, rows):
        rows = np.ascontiguousarray(rows, dtype=np.float64)
        if self._file is None:
            self._a[j0:j0 + len(rows)] = rows
        else:
            self._file.seek(j0 * self.width * 8)
            self._file.write(rows.data)

    def read(self, j0, j1):
        """Rows ``j0 .. j1-1`` (a copy)."""
        j0, j1 = max(j0, 0), min(j1, self.count)
        if self._file is None:
            return self._a[j0:j1].copy()
        self._file.flush()
        self._file.seek(j0 * self.width * 8)
        return np.fromfile(self._file, np.float64, max(j1 - j0, 0) * self.width).reshape(
            -1, self.width)

    def array(self):
        """All rows: the array itself in memory, else read whole."""
        return self._a if self._file is None else self.read(0, self.count)


def read_rows(x, j0, j1):
    """Rows ``j0 .. j1-1`` (a copy) of an array, :class:`Rows` or :class:`Table`."""
    return np.array(x[j0:j1]) if isinstance(x, np.ndarray) else x.read(j0, j1)


def as_array(x):
    """An array, :class:`Rows` or :class:`Table` as an array (read whole)."""
    return x if isinstance(x, np.ndarray) else x.array()


#: Innovation axes kept in one row of :class:`RecordStore` (more: continuation rows).
RECORD_AXES = 3


class RecordStore:
    """The tested measurements (:class:`ins.estimation.core.measurements.UpdateRecord`) as
    fixed-size numeric rows: time, codes of the name, axes and unit (tables of the
    strings seen), NIS, accepted, then up to :data:`RECORD_AXES` innovations and sigmas
    (a record with more axes continues on rows whose name code is -1).  In memory or,
    with ``workdir``, in a temporary file (:class:`Rows`).  ``append(UpdateRecord)``,
    ``pop()``, ``len`` and iteration (yielding UpdateRecords) as for a list."""

    def __init__(self, workdir=None):
        self._rows = Rows((6 + 2 * RECORD_AXES,), workdir=workdir)
        self._row = np.empty(6 + 2 * RECORD_AXES)           # scratch of append
        self._codes = {}
        self._strings = []
        self._n = 0

    def _code(self, value):
        c = self._codes.get(value)
        if c is None:
            c = self._codes[value] = len(self._strings)
            self._strings.append(value)
        return c

    def append(self, rec):
        axes = tuple(rec.axes)
        z = np.ravel(rec.innovation)
        s = np.ravel(rec.sigma)
        if len(axes) == RECORD_AXES == len(z) == len(s):       # the usual case: one row
            self._row[:6] = (rec.time, self._code(rec.name), self._code(axes),
                             self._code(rec.unit), rec.nis, bool(rec.accepted))
            self._row[6:6 + RECORD_AXES] = z
            self._row[6 + RECORD_AXES:] = s
            self._rows.append(self._row)
            self._n += 1
            return
        head = True
        for a in range(0, max(len(axes), 1), RECORD_AXES):
            row = np.full(6 + 2 * RECORD_AXES, np.nan)
            row[:6] = (rec.time, self._code(rec.name) if head else -1, self._code(axes),
                       self._code(rec.unit), rec.nis, bool(rec.accepted))
            k = len(z[a:a + RECORD_AXES])
            row[6:6 + k] = z[a:a + RECORD_AXES]
            row[6 + RECORD_AXES:6 + RECORD_AXES + k] = s[a:a + RECORD_AXES]
            self._rows.append(row)
            head = False
        self._n += 1

    def __len__(self):
        return self._n

    def _record(self, parts):
        r0 = parts[0]
        axes = self._strings[int(r0[2])]
        m = len(axes)
        if len(parts) == 1:
            z, s = r0[6:6 + m].copy(), r0[6 + RECORD_AXES:6 + RECORD_AXES + m].copy()
        else:
            z = np.concatenate([p[6:6 + RECORD_AXES] for p in parts])[:m]
            s = np.concatenate([p[6 + RECORD_AXES:] for p in parts])[:m]
        return UpdateRecord(self._strings[int(r0[1])], axes, self._strings[int(r0[3])],
                            float(r0[0]), z, s, float(r0[4]), bool(r0[5]))

    def pop(self):
        """Remove the last record and return it."""
        parts = [self._rows.pop()]
        while parts[0][1] < 0:
            parts.insert(0, self._rows.pop())
        self._n -= 1
        return self._record(parts)

    def __iter__(self):
        parts = []
        for _, rows in self._rows.chunks():
            for row in rows:
                if row[1] >= 0 and parts:
                    yield self._record(parts)
                    parts = []
                parts.append(row)
        if parts:
            yield self._record(parts)


def measurement_stores(workdir=None):
    """The stores an updater keeps per tested measurement: ``(records, nis,
    nis_record, innovation)`` (:class:`RecordStore`, :class:`Rows` of the position
    records' NIS, GNSS record index and NED innovation m)."""
    return (RecordStore(workdir), Rows((), workdir=workdir),
            Rows((), np.int64, workdir=workdir), Rows((3,), workdir=workdir))


#: The attitude cross covariances of a node store of fewer states than the attitude's.
_NO_ATT = np.full(len(ATT_CROSS[0]), np.nan)

#: Bytes of node matrices a :class:`NodeStore` on disk buffers between writes (the
#: file is the same as with a write per node; 45 000 small writes cost 0.4 s).
NODE_BUFFER_BYTES = 1 << 20


class NodeStore:
    """``P_prior``, ``P_post`` and ``Phi`` (n x n each, n the number of error states) of
    every node, kept for the RTS pass, with the posterior sigmas ``sqrt(diag(P_post))``
    (:attr:`post_std`) and the posterior attitude cross covariances (:attr:`post_att_cross`,
    :data:`ins.estimation.core.error_model.ATT_CROSS`) of every node.

    In memory, or, with ``workdir``, appended to an anonymous temporary file there (10.6
    kB a node: 380 MB for a 10 h flight at 1 Hz, on disk, not in memory) and read back
    backwards in blocks.  They stay float64: after long GNSS tracking ``P_prior`` has
    correlations close to 1 and a condition number near 1e12, which the 1e-7 rounding of
    float32 would turn indefinite (the smoother's Cholesky step then fails).
    """

    def __init__(self, workdir=None):
        self.count = 0
        self.n = None
        self._post_std = Rows(workdir=workdir)   # sqrt(diag(P_post)) of every node
        self._post_att = Rows((len(ATT_CROSS[0]),), workdir=workdir)  # P_post[ATT_CROSS]
        self._mem = [] if workdir is None else None
        self._file = None if workdir is None else tempfile.TemporaryFile(dir=workdir)
        self._buf, self._n_buf = None, 0         # nodes not yet written to the file
        self._std = np.empty(0)                  # scratch of append

    def append(self, P_prior, P_post, Phi, time=None):
        """Store one node; a negative variance (beyond rounding) in either covariance
        raises :class:`~ins.common.errors.QualityError` naming ``time`` (s) and the state."""
        self.n = n = len(P_prior)
        if len(self._std) != n:
            self._std = np.empty(n)
        P_prior = np.ascontiguousarray(P_prior, dtype=np.float64)
        P_post = np.ascontiguousarray(P_post, dtype=np.float64)
        if _kalman_kernels.diag_std(P_prior, P_post, VARIANCE_RTOL, self._std):  # usual
            self._post_std.append(self._std)
        else:
            d_prior, d_post = P_prior.diagonal(), P_post.diagonal()
            scale = np.maximum(np.abs(d_prior), np.abs(d_post))
            checked_std(d_prior, scale, time, what="forward filter's prior covariance")
            self._post_std.append(checked_std(d_post, scale, time,
                                              what="forward filter's posterior covariance"))
        self._post_att.append(P_post[ATT_CROSS] if n > ATT_STOP else _NO_ATT)
        if self._mem is not None:
            self._mem.append(np.stack([P_prior, P_post, Phi]))
        else:                          # buffered: one write per NODE_BUFFER_BYTES
            if self._buf is None:
                self._buf = np.empty((max(NODE_BUFFER_BYTES // (24 * n * n), 1), 3, n, n))
            b = self._buf[self._n_buf]
            b[0], b[1], b[2] = P_prior, P_post, Phi
            self._n_buf += 1
            if self._n_buf == len(self._buf):
                self._flush()
        self.count += 1

    def _flush(self):
        """Write the buffered nodes to the file (the same bytes as one write a node)."""
        if self._n_buf:
            self._file.write(self._buf[:self._n_buf].data)
            self._n_buf = 0

    @property
    def post_std(self):
        """``sqrt(diag(P_post))`` of every node, array (count, n) (read whole)."""
        return self._post_std.array()

    @property
    def post_std_rows(self):
        """``sqrt(diag(P_post))`` of every node as :class:`Rows` (read in blocks)."""
        return self._post_std

    @property
    def post_att_cross(self):
        """Posterior attitude cross covariances ``P_post[ATT_CROSS]`` of every node (rad^2:
        N-E, N-D, E-D of the phi angles), array (count, 3) (read whole)."""
        return self._post_att.array()

    @property
    def post_att_cross_rows(self):
        """:attr:`post_att_cross` as :class:`Rows` (read in blocks)."""
        return self._post_att

    def block(self, j0, j1):
        """Nodes ``j0 .. j1-1``: array (j1 - j0, 3, n, n) of P_prior, P_post, Phi."""
        n = self.n or 0
        if self._mem is not None:
            return np.array(self._mem[j0:j1]).reshape(j1 - j0, 3, n, n)
        rec = 3 * n * n
        self._flush()
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

    def chunks(self, rows=None):
        """``(row0, time, states)`` pieces in time order (copies; at most ~``rows`` rows,
        default :data:`PIECE_ROWS`)."""
        rows = PIECE_ROWS if rows is None else rows
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
