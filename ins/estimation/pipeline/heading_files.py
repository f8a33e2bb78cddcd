"""Dual-antenna heading files: read into :class:`ins.estimation.core.measurements.DualAntennaHeading`
records for ``ins process`` (``[files] heading``, ``[heading]``), and written.

Layout (text, one record per line, space or comma separated, ``#`` comments)::

    # time_s heading_deg sigma_deg
    200000.000 137.2512 0.150

``time_s``
    epoch on the GNSS receiver's clock (GPS seconds of week, as the GNSS log; the
    config's ``[gnss] time_shift_s`` applies to it too), strictly increasing;
``heading_deg``
    azimuth of the BASELINE, the vector from the primary to the secondary antenna,
    clockwise from north (deg, any range: wrapped);
``sigma_deg``
    its 1-sigma (deg, > 0).  Optional: a two-column file takes ``[heading] sigma_deg``.

The baseline's direction in the IMU body axes is the config's ``[heading] baseline_b_m``
(m, forward-right-down; only its direction matters, and of that only what shows
horizontally in ``n``).  A receiver that reports the heading of the vehicle's axes
rather than of the baseline has ``baseline_b_m = [1, 0, 0]`` when those axes are the
IMU's.  The filter applies a record at its first node at or after the record's time
(the GNSS epochs, and every ``node_interval_s``): headings at the GNSS epochs (one
receiver, one clock) are applied at their own time; off-epoch records are late by up to
the node interval.  Units: deg at the edge, rad inside.
"""
import os

import numpy as np

from ins.common.errors import InputError
from ins.estimation.core.measurements import DualAntennaHeading

__all__ = ["read_headings", "write_headings", "within", "HEADING_COLUMNS"]

HEADING_COLUMNS = ("time_s", "heading_deg", "sigma_deg")
_HINT = "time_s heading_deg [sigma_deg]: the baseline's azimuth from north and its sigma, deg"


def read_headings(path, baseline_b_m, sigma_deg=None, time_shift_s=0.0):
    """Read a heading file (module notes) into a list of
    :class:`~ins.estimation.core.measurements.DualAntennaHeading` (SI: rad, rad^2), in time order.

    Parameters
    ----------
    path : str or os.PathLike
    baseline_b_m : array_like, shape (3,)
        Primary-to-secondary antenna vector in b (m).
    sigma_deg : float, optional
        Sigma of every record of a two-column file (deg); a three-column file's own
        sigmas win.
    time_shift_s : float
        Added to every epoch (s): the GNSS clock's offset (``[gnss] time_shift_s``).

    Raises
    ------
    InputError
        Naming the file and line: a bad number of columns, a non-finite value, time not
        increasing, a sigma <= 0; a two-column file without ``sigma_deg``; no baseline.
    """
    from ins.common.textfiles import read_table
    from ins.common.textrows import check_rows
    path_s = os.fspath(path)
    if baseline_b_m is None:
        raise InputError(f"{path_s}: dual-antenna headings need [heading] baseline_b_m "
                         f"(primary-to-secondary antenna vector, m, b frame)")
    baseline = np.asarray(baseline_b_m, dtype=float)
    rows, row_line = read_table(path, ncols_min=2, ncols_max=3, column_names=HEADING_COLUMNS,
                                hint=_HINT)
    check_rows(rows, row_line, path_s)
    if rows.shape[1] == 2:
        if sigma_deg is None:
            raise InputError(f"{path_s}: two columns (time_s heading_deg) and no [heading] "
                             f"sigma_deg: give the sigma (deg) in the config or a third "
                             f"column")
        sigma = np.full(len(rows), float(sigma_deg))
    else:
        sigma = rows[:, 2]
    bad = np.flatnonzero(~(sigma > 0))
    if bad.size:
        raise InputError(f"sigma_deg = {float(sigma[bad[0]])!r}: expected > 0 (deg)",
                         path=path_s, line=int(row_line[bad[0]]))
    t = rows[:, 0] + float(time_shift_s)
    head = np.deg2rad(rows[:, 1])
    sig = np.deg2rad(sigma)
    return [DualAntennaHeading(t[k], head[k], sig[k], baseline) for k in range(len(rows))]


def within(headings, t_start=None, t_end=None):
    """The records of ``headings`` whose time is inside ``[t_start, t_end]`` (s; None:
    open), as a tuple."""
    lo = -np.inf if t_start is None else t_start - 1e-9
    hi = np.inf if t_end is None else t_end + 1e-9
    return tuple(h for h in headings if lo <= h.time <= hi)


def write_headings(path, time_s, heading_deg, sigma_deg):
    """Write a heading file (three columns, module notes) atomically; returns the number
    of records."""
    from ins.common.fileio import atomic_open
    table = np.column_stack(np.broadcast_arrays(np.asarray(time_s, float),
                                                np.asarray(heading_deg, float),
                                                np.asarray(sigma_deg, float)))
    if not np.all(np.isfinite(table)):
        raise ValueError("heading table holds a non-finite value; not written")
    with atomic_open(path, "w") as f:
        f.write("# " + " ".join(HEADING_COLUMNS) + "  (heading: azimuth of the primary-to-"
                "secondary antenna baseline, clockwise from north)\n")
        for t, h, s in table:
            f.write(f"{t:.6f} {h:.6f} {s:.6f}\n")
    return len(table)
