"""Forward/backward separation of a carrier-phase (kinematic) RTKLIB solution: the
rover's position from RTKLIB's forward filter minus that of its backward filter at each
epoch both solved, in the local north/east/up axes at the backward position.

Where the two directions disagree by more than their sigmas, one of them holds a wrong
integer fix or a float stretch: the combined solution there is no better than the
worse of the two.  The two runs are independent filters over the same data (the
combined solution is their weighted mean), so the separation is a check of the
ambiguity resolution, not an error against a truth.

:func:`forward_backward` runs both directions (:func:`ins.gnss.rtklib_engine.solve`),
:func:`separation` compares two solutions, :func:`write_separation` and
:func:`plot_separation` write the table and the figure.
"""
import os
import shutil
import tempfile
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["Separation", "separation", "forward_backward", "write_separation",
           "plot_separation", "TIME_TOLERANCE_S", "FIX_DISAGREE_M", "summary_lines"]

#: Epochs of the two solutions closer than this are the same epoch, s.
TIME_TOLERANCE_S = 1e-3
#: Both directions fixed yet farther apart than this (m, 3D): different integers.  In
#: kinematic mode the fixed position of an epoch depends only on that epoch's data and
#: the integer ambiguities (the position is re-estimated every epoch), so two fixes
#: with the same integers print the same position (0.1 mm); a wrong fix in one
#: direction moves it by centimetres to decimetres (the L1 wavelength is 0.19 m).
FIX_DISAGREE_M = 0.005


@dataclass(frozen=True)
class Separation:
    """Forward minus backward at the epochs both directions solved.

    Attributes
    ----------
    time : ndarray, shape (n,)
        GPS seconds of week.
    d_neu_m : ndarray, shape (n, 3)
        Forward minus backward position, north, east, up (m), in the local level frame
        at the backward position.
    q_forward, q_backward : ndarray of int, shape (n,)
        RTKLIB's quality flags (1 fix, 2 float, ...) of each direction.
    forward_epochs, backward_epochs : int
        Epochs each direction solved.
    """

    time: np.ndarray
    d_neu_m: np.ndarray
    q_forward: np.ndarray
    q_backward: np.ndarray
    forward_epochs: int = 0
    backward_epochs: int = 0

    @property
    def both_fixed(self):
        """Boolean (n,): both directions fixed (Q = 1)."""
        return (self.q_forward == 1) & (self.q_backward == 1)

    @property
    def fixed_disagreements(self):
        """Number of epochs both fixed but more than :data:`FIX_DISAGREE_M` apart."""
        return int(np.sum(self.both_fixed
                          & (np.linalg.norm(self.d_neu_m, axis=1) > FIX_DISAGREE_M)))

    def stats(self, fixed_only=False):
        """``(n, rms_neu_m (3,), max_neu_m (3,), max_3d_m)`` of the epochs (both fixed
        with ``fixed_only``); NaN when there is none."""
        keep = self.both_fixed if fixed_only else np.ones(len(self.time), bool)
        d = self.d_neu_m[keep]
        if not len(d):
            nan3 = np.full(3, np.nan)
            return 0, nan3, nan3, np.nan
        return (len(d), np.sqrt(np.mean(d ** 2, axis=0)), np.max(np.abs(d), axis=0),
                float(np.max(np.linalg.norm(d, axis=1))))


def separation(forward_log, backward_log):
    """:class:`Separation` of two :class:`~ins.io.gnss_log.GnssLog` of the same rover
    (epochs matched within :data:`TIME_TOLERANCE_S`)."""
    from ins.nav.earth import ned_offset
    tf, tb = forward_log.time, backward_log.time
    k = np.clip(np.searchsorted(tb, tf), 0, max(len(tb) - 1, 0))
    if len(tb):
        k_prev = np.clip(k - 1, 0, None)
        k = np.where(np.abs(tb[k_prev] - tf) < np.abs(tb[k] - tf), k_prev, k)
        match = np.abs(tb[k] - tf) < TIME_TOLERANCE_S
    else:
        match = np.zeros(len(tf), bool)
    i_f, i_b = np.flatnonzero(match), k[match]
    ned = ned_offset(backward_log.lla[i_b], forward_log.lla[i_f]).reshape(-1, 3)
    neu = np.column_stack([ned[:, 0], ned[:, 1], -ned[:, 2]])
    return Separation(tf[i_f].copy(), neu, forward_log.quality[i_f].astype(int),
                      backward_log.quality[i_b].astype(int), len(tf), len(tb))


def forward_backward(rover, nav, folder, base=None, sp3=(), clk=(), options=None,
                     **solve_kw):
    """Run RTKLIB forward and backward (the settings of ``options`` otherwise) in a
    temporary folder inside ``folder`` and return their :class:`Separation`; nothing is
    left in ``folder``.  ``solve_kw``: the other arguments of
    :func:`ins.gnss.rtklib_engine.solve` (atx, dcb, window)."""
    from ins.gnss.rtklib_engine import solve
    from ins.gnss.rtklib_options import RtklibOptions
    opts = RtklibOptions() if options is None else options
    tmp = tempfile.mkdtemp(prefix=".fwd-bwd-", dir=folder)
    try:
        logs = [solve(rover, nav, os.path.join(tmp, f"{d}.pos"), base=base, sp3=sp3,
                      clk=clk, options=replace(opts, direction=d), **solve_kw).log
                for d in ("forward", "backward")]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return separation(*logs)


def write_separation(sep, path):
    """The separation as text, atomically: a ``#`` header, then one epoch a line
    ``time_s dn_m de_m du_m q_fwd q_bwd`` (forward minus backward, m)."""
    from ins.common.fileio import atomic_open
    n, rms, mx, mx3 = sep.stats()
    nf, rms_f, mx_f, _ = sep.stats(fixed_only=True)
    lines = ["# RTKLIB forward minus backward position (m) in north/east/up at the "
             "backward position",
             f"# {n} epochs both solved: RMS N/E/U {rms[0]:.4f} {rms[1]:.4f} {rms[2]:.4f} m,"
             f" max {mx[0]:.4f} {mx[1]:.4f} {mx[2]:.4f} m, 3D max {mx3:.4f} m",
             f"# {nf} epochs both fixed: RMS N/E/U {rms_f[0]:.4f} {rms_f[1]:.4f} "
             f"{rms_f[2]:.4f} m; {sep.fixed_disagreements} of them more than "
             f"{FIX_DISAGREE_M} m apart (different integers)",
             "# Q: 1 fix, 2 float, 4 DGNSS, 5 single",
             "# time_s dn_m de_m du_m q_fwd q_bwd"]
    lines += [f"{t:.3f} {d[0]:.4f} {d[1]:.4f} {d[2]:.4f} {a} {b}"
              for t, d, a, b in zip(sep.time, sep.d_neu_m, sep.q_forward, sep.q_backward)]
    with atomic_open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    return path


def plot_separation(sep, path, title="RTKLIB forward - backward"):
    """Forward minus backward N/E/U against time (:mod:`ins.common.plotstyle`), epochs
    not fixed in both directions marked; written atomically as PNG."""
    from ins.common import plotstyle
    plt = plotstyle.pyplot()
    t0 = float(sep.time[0]) if len(sep.time) else 0.0
    scale, unit = plotstyle.length_unit(sep.d_neu_m)
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 6.5))
    n, rms, mx, _ = sep.stats()
    xlabel, suffix = plotstyle.time_label(t0)
    fig.suptitle(f"{title}: {n} epochs, RMS N/E/U {scale * rms[0]:.1f}/{scale * rms[1]:.1f}/"
                 f"{scale * rms[2]:.1f} {unit}, max {scale * mx[0]:.1f}/{scale * mx[1]:.1f}/"
                 f"{scale * mx[2]:.1f} {unit}\n{suffix}")
    t = sep.time - t0
    fixed = sep.both_fixed
    for ax, j, name in zip(axes, range(3), ("north", "east", "up")):
        ax.plot(t, scale * sep.d_neu_m[:, j], "-", color="0.6", lw=0.8)
        ax.plot(t[fixed], scale * sep.d_neu_m[fixed, j], ".", color="C0", ms=4,
                label="both fixed")
        ax.plot(t[~fixed], scale * sep.d_neu_m[~fixed, j], "x", color="C3", ms=5,
                label="float or worse in one")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(f"{name}, {unit}")
        ax.grid(True, alpha=0.3)
    plotstyle.legend_right(axes[0])
    axes[-1].set_xlabel(xlabel)
    return plotstyle.save_png(fig, path)


def summary_lines(sep):
    """Lines for a summary: RMS and max of all epochs and of the both-fixed ones (mm),
    and the fixed epochs that disagree."""
    n, rms, mx, _ = sep.stats()
    nf, rms_f, mx_f, _ = sep.stats(fixed_only=True)
    mm = 1000.0
    out = [f"forward/backward separation N/E/U ({n} epochs both solved): RMS "
           f"{mm * rms[0]:.1f}/{mm * rms[1]:.1f}/{mm * rms[2]:.1f} mm, max "
           f"{mm * mx[0]:.1f}/{mm * mx[1]:.1f}/{mm * mx[2]:.1f} mm"]
    if nf:
        out.append(f"  both fixed ({nf} epochs): RMS {mm * rms_f[0]:.1f}/{mm * rms_f[1]:.1f}/"
                   f"{mm * rms_f[2]:.1f} mm, max {mm * mx_f[0]:.1f}/{mm * mx_f[1]:.1f}/"
                   f"{mm * mx_f[2]:.1f} mm; {sep.fixed_disagreements} apart by more than "
                   f"{1000 * FIX_DISAGREE_M:g} mm (different integers)")
    return out
