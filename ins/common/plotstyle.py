"""Shared style of the PNG plots (matplotlib, Agg backend, imported lazily).

One convention for every figure of the toolkit:

- a title on every figure (``fig.suptitle``) stating what is plotted and, once, the
  time origin: "time since start, s" on the x axis with the start given as GPS
  seconds of week in the title;
- units that fit the values: positions in mm or cm (not m with ticks like 0.025),
  angles in arcsec, chosen from the data by :func:`length_unit`;
- y-limits from the data after the forward filter's start transient
  (:func:`robust_limits`), so that a sigma envelope is not squashed by the first
  minute; what lies beyond is clipped and said so in the legend;
- legends outside the data (:func:`legend_right`), saved with ``bbox_inches="tight"``;
- strips of an image block marked by vertical lines (:func:`strip_starts`,
  :func:`mark_strips`).
"""
import io

import numpy as np

__all__ = ["ARCSEC", "TRANSIENT_S", "pyplot", "save_png", "png_bytes", "length_unit", "robust_limits",
           "legend_right", "plain_log_ticks", "time_label", "exposure_axis", "strip_starts",
           "mark_strips", "with_gaps"]

ARCSEC = np.pi / 180.0 / 3600.0
TRANSIENT_S = 60.0
"""Seconds after the start left out of the y-limits (the forward filter converging)."""


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (no display needed)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def png_bytes(fig, dpi=110):
    """``fig`` as PNG bytes (tight box: outside legends kept), the figure closed (a
    figure embedded in a report, :mod:`ins.common.html_report`)."""
    plt = pyplot()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()


def save_png(fig, path, dpi=110):
    """Write ``fig`` as PNG to ``path`` atomically (tight box: outside legends kept) and
    close it; returns ``path``."""
    from ins.common.fileio import atomic_open
    data = png_bytes(fig, dpi)
    with atomic_open(path, "wb") as f:
        f.write(data)
    return path


def length_unit(values_m):
    """``(scale, unit)`` to display lengths ``values_m`` (m): mm below 0.1 m, cm below
    1 m, else m (from the 99th percentile of the magnitudes, NaN ignored)."""
    v = np.abs(np.asarray(values_m, float))
    v = v[np.isfinite(v)]
    size = np.percentile(v, 99) if v.size else 0.0
    if size < 0.1:
        return 1000.0, "mm"
    if size < 1.0:
        return 100.0, "cm"
    return 1.0, "m"


def robust_limits(t_s, series, skip_s=TRANSIENT_S, margin=0.1, symmetric=False, log=False):
    """y-limits covering ``series`` (list of arrays sampled at ``t_s`` or of their own
    length) after the first ``skip_s`` seconds.

    Parameters
    ----------
    t_s : array (n,)
        Time since start, s (series of n rows are cut; other lengths are used whole).
    series : list of array_like
        The curves that must fit.
    skip_s : float
        Start transient left out; when the record is shorter than ``3 * skip_s``, a
        third of it is left out instead.
    margin : float
        Fraction of the range added on each side (a factor on log axes).
    symmetric : bool
        Limits ``(-a, a)`` about zero.
    log : bool
        Limits for a logarithmic axis (positive values only).

    Returns
    -------
    (lo, hi) : tuple of float, or None when there is no finite value.
    """
    t = np.asarray(t_s, float)
    skip = min(skip_s, (t[-1] - t[0]) / 3.0) if t.size else 0.0
    keep = t >= t[0] + skip if t.size else t
    parts = []
    for s in series:
        s = np.asarray(s, float)
        if s.ndim and s.shape[0] == t.size:
            s = s[keep]
        s = s.ravel()
        s = s[np.isfinite(s)]
        if log:
            s = s[s > 0]
        if s.size:
            parts.append(s)
    if not parts:
        return None
    v = np.concatenate(parts)
    if log:
        lo, hi = v.min(), v.max()
        f = 1.0 + 3 * margin
        return lo / f, hi * f
    if symmetric:
        a = np.abs(v).max() * (1 + margin)
        a = a if a > 0 else 1.0
        return -a, a
    lo, hi = v.min(), v.max()
    pad = (hi - lo) * margin if hi > lo else (abs(hi) * max(margin, 0.1) or 1.0)
    return lo - pad, hi + pad


def plain_log_ticks(ax):
    """Plain numbers (``5``, ``20``, ``100``) on a logarithmic y axis, not ``6 x 10^0``;
    minor ticks labelled at 2 and 5 times a power of ten only."""
    from matplotlib.ticker import FuncFormatter

    def minor(v, _):
        lead = v / 10 ** np.floor(np.log10(v) + 1e-9) if v > 0 else 0
        return f"{v:g}" if np.isclose(lead, 2) or np.isclose(lead, 5) else ""
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.yaxis.set_minor_formatter(FuncFormatter(minor))


def legend_right(ax, handles=None, labels=None, fontsize=8):
    """Legend to the right of ``ax``, outside the data."""
    kw = {} if handles is None else {"handles": handles}
    if labels is not None:
        kw["labels"] = labels
    return ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0,
                     fontsize=fontsize, **kw)


def time_label(t0_s):
    """``(x-label, title suffix)`` of the time axis convention: time since the first
    epoch, s, with that epoch given once as GPS seconds of week."""
    return "time since start, s", f"start = GPS second of week {t0_s:.3f}"


def exposure_axis(time_s):
    """x values, x-label and title suffix of a plot over exposures: the time axis
    convention (:func:`time_label`: time since the first exposure, s) when every
    exposure has a finite time, else the image number in file order."""
    t = np.asarray(time_s, dtype=float)
    if len(t) and np.all(np.isfinite(t)):
        xlabel, origin = time_label(float(t.min()))
        return t - t.min(), "exposure " + xlabel, origin
    return np.arange(len(t), dtype=float), "image number (file order)", ""


def with_gaps(x, y, starts):
    """``x``, ``y`` with a NaN point before each index of ``starts`` (the strips' first
    images), so that a line plot does not join one strip to the next across a turn."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    cut = np.asarray(sorted(starts), dtype=np.int64)
    return np.insert(x, cut, np.nan), np.insert(y, cut, np.nan)


def strip_starts(image_ids=None, time_s=None, heading_rad=None):
    """Indices (> 0) of the images that begin a new strip, in file order.

    From the image names when they carry a strip prefix (``S01_003``: the part before
    the last ``_``), else from a heading change of more than 90 deg between
    consecutive images, else from a time gap of more than 3 times the median
    interval.  Empty when none can be told.
    """
    if image_ids is not None and len(image_ids) > 1:
        ids = [str(i) for i in image_ids]
        if all("_" in i for i in ids):
            pre = [i.rsplit("_", 1)[0] for i in ids]
            if len(set(pre)) > 1:
                return [k for k in range(1, len(pre)) if pre[k] != pre[k - 1]]
    if heading_rad is not None and len(heading_rad) > 1:
        d = np.angle(np.exp(1j * np.diff(np.asarray(heading_rad, float))))
        jumps = np.nonzero(np.abs(d) > np.pi / 2)[0] + 1
        if jumps.size:
            return jumps.tolist()
    if time_s is not None and len(time_s) > 2:
        dt = np.diff(np.asarray(time_s, float))
        return (np.nonzero(dt > 3 * np.median(dt))[0] + 1).tolist()
    return []


def mark_strips(axes, starts, n, names=None, x=None):
    """Vertical lines between strips on every axis of ``axes`` and the strip numbers
    (or ``names``) along the top of the first; ``x`` the x values of the images
    (default 0..n-1)."""
    axes = list(np.atleast_1d(axes))
    x = np.arange(n) if x is None else np.asarray(x, float)
    bounds = [0, *starts, n]
    for ax in axes:
        for k in starts:
            ax.axvline(0.5 * (x[k - 1] + x[k]), color="0.4", lw=0.8, ls="--", zorder=0)
    top = axes[0]
    for j in range(len(bounds) - 1):
        mid = 0.5 * (x[bounds[j]] + x[bounds[j + 1] - 1])
        text = names[j] if names is not None else f"strip {j + 1}"
        top.text(mid, 1.02, text, transform=top.get_xaxis_transform(), ha="center",
                 va="bottom", fontsize=8, color="0.3")
