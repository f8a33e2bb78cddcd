"""PNG plots of a processing result (matplotlib, Agg backend, imported lazily).

Style shared with the other figures of the toolkit (:mod:`ins.common.plotstyle`): titles,
"time since start, s" with the start as GPS second of week in the title, positions
in mm/cm as the values need, angles in arcsec, y-limits from the data after the
forward filter's first minute, legends outside the data, the simulator's injected
biases beside the estimates when known.
"""
import os

import numpy as np

from ins.common.plotstyle import (
    ARCSEC,
    TRANSIENT_S,
    legend_right,
    length_unit,
    plain_log_ticks,
    pyplot,
    robust_limits,
    save_png,
    time_label,
)
from ins.estimation.core.error_model import SENSORS, STATE

__all__ = ["plot_errors", "plot_sigma", "plot_biases", "plot_innovations",
           "plot_satellite_residuals", "satellites_used", "injected_biases",
           "write_plots"]

_DPH = np.pi / 180.0 / 3600.0          # rad/s per deg/h
_MGAL = 1e-5                           # m/s^2 per mGal
_POS = ("north", "east", "down")
_ATT = ("tilt N", "tilt E", "heading")


def _decimate(time, values, limit=20000):
    step = max(1, len(time) // limit)
    return time[::step], values[::step]


def _transient_s(t_end):
    """The start left out of the y-limits (:func:`ins.common.plotstyle.robust_limits`):
    the first minute, or the first third of a shorter record, s."""
    return min(TRANSIENT_S, t_end / 3.0)


def _shade_transient(ax, t_end):
    ax.axvspan(0.0, _transient_s(t_end), color="0.92", zorder=0, lw=0)


def _transient_note(t_end):
    s = _transient_s(t_end)
    first = "first minute" if s >= TRANSIENT_S else f"first {s:.3g} s"
    return f"  (grey: {first}, left out of the y-limits)"


def plot_errors(result, path):
    """Position (mm or cm) and attitude (arcsec) errors against the truth, forward and
    smoothed, with the smoothed 3-sigma envelope; y-limits from the smoothed curve and
    its envelope after the first minute (the forward curve beyond them is clipped and
    its largest value given in the legend)."""
    plt = pyplot()
    fig, axes = plt.subplots(6, 1, figsize=(10, 13), sharex=True)
    t0 = result.node_time[0]
    tn = result.node_time - t0
    xlabel, origin = time_label(t0)
    es, ef = result.errors_smoothed, result.errors_forward
    pos_scale, pos_unit = length_unit(3 * result.smoothed_std[:, STATE.pos])
    for i, ax in enumerate(axes):
        att = i >= 3
        scale, unit = (1.0 / ARCSEC, "arcsec") if att else (pos_scale, pos_unit)
        name = _ATT[i - 3] if att else _POS[i]
        sig = 3 * scale * result.smoothed_std[:, STATE.att.start + i - 3 if att
                                                  else STATE.pos.start + i]
        curves = {}
        for label, e, style, lw in (("forward", ef, "C1", 0.6), ("smoothed", es, "C0", 0.9)):
            if e is None:
                continue
            series = e.att_n[:, i - 3] if att else e.pos_n[:, i]
            t, v = _decimate(e.time - t0, scale * series)
            curves[label] = (t, v)
            ax.plot(t, v, style, lw=lw, label=label)
        ax.plot(tn, sig, "k:", lw=0.8, label="smoothed 3 sigma")
        ax.plot(tn, -sig, "k:", lw=0.8)
        fit = [sig] + ([curves["smoothed"][1]] if "smoothed" in curves else [])
        lims = robust_limits(tn, fit, symmetric=True, margin=0.3)
        if "smoothed" in curves:       # the smoothed curve has its own time axis
            ts, vs = curves["smoothed"]
            more = robust_limits(ts, [vs], symmetric=True, margin=0.3)
            lims = (min(lims[0], more[0]), max(lims[1], more[1]))
        ax.set_ylim(*lims)
        handles, labels = ax.get_legend_handles_labels()
        if "forward" in curves:
            peak = np.nanmax(np.abs(curves["forward"][1]))
            if peak > lims[1]:
                labels[0] = f"forward (clipped;\nmax |error| {peak:.0f} {unit})"
        legend_right(ax, handles, labels, fontsize=7)
        _shade_transient(ax, tn[-1])
        ax.set_ylabel(f"{name} error, {unit}")
        ax.axhline(0, color="k", lw=0.4)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel(xlabel + _transient_note(tn[-1]))
    fig.suptitle(f"Trajectory errors against the truth (position {pos_unit}, attitude arcsec)"
                 f"\n{origin}")
    fig.tight_layout()
    return save_png(fig, path)


def plot_sigma(result, path):
    """Forward and smoothed 1-sigma of position (mm or cm), velocity (mm/s or cm/s) and
    attitude (arcsec: tilt N, tilt E, heading); log axes limited to the values after
    the first minute."""
    plt = pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    t0 = result.node_time[0]
    t = result.node_time - t0
    xlabel, origin = time_label(t0)
    ps, pu = length_unit(result.smoothed_std[:, STATE.pos])
    vs, vu = length_unit(result.smoothed_std[:, STATE.vel])
    for ax, sl, scale, label, comps in (
            (axes[0], STATE.pos, ps, f"position sigma, {pu}", _POS),
            (axes[1], STATE.vel, vs, f"velocity sigma, {vu}/s", _POS),
            (axes[2], STATE.att, 1 / ARCSEC, "attitude sigma, arcsec", _ATT)):
        fwd, smo = scale * result.forward_std[:, sl], scale * result.smoothed_std[:, sl]
        for k, comp in enumerate(comps):
            ax.semilogy(t, fwd[:, k], f"C{k}--", lw=0.7, label=f"{comp} forward")
            ax.semilogy(t, smo[:, k], f"C{k}", lw=0.9, label=f"{comp} smoothed")
        lims = robust_limits(t, [fwd, smo], log=True)
        if lims is not None:
            ax.set_ylim(*lims)
        plain_log_ticks(ax)
        _shade_transient(ax, t[-1])
        ax.set_ylabel(label)
        ax.grid(alpha=0.3, which="both")
        legend_right(ax, fontsize=7)
    axes[-1].set_xlabel(xlabel + _transient_note(t[-1]))
    fig.suptitle(f"Standard deviations of the solution, forward filter and smoother\n{origin}")
    fig.tight_layout()
    return save_png(fig, path)


def injected_biases(flight_dir):
    """The constant biases a simulated flight injected (``manifest.toml`` ``[imu]``):
    ``{"gyro_bias_dph": (3,), "accel_bias_mgal": (3,)}``, or None when the folder has
    no manifest or the manifest no such values."""
    path = os.path.join(flight_dir, "manifest.toml")
    if not os.path.isfile(path):
        return None
    import tomllib
    try:                 # decoration only: ins process has read the manifest already
        with open(path, "rb") as f:
            imu = tomllib.load(f).get("imu", {})
        return {k: np.asarray(imu[k], float).reshape(3) for k in
                ("gyro_bias_dph", "accel_bias_mgal")}
    except (OSError, tomllib.TOMLDecodeError, KeyError, ValueError, TypeError):
        return None


def plot_biases(result, path, injected=None):
    """Gyro (deg/h) and accelerometer (mGal) bias estimates, forward and smoothed, and
    the injected constant biases of a simulation (``injected``, as returned by
    :func:`injected_biases`) beside them."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
    t0 = result.node_time[0]
    t = result.node_time - t0
    xlabel, origin = time_label(t0)
    for ax, sl, scale, label, key in (
            (axes[0], SENSORS.gyro_bias, 1 / _DPH, "gyro bias, deg/h", "gyro_bias_dph"),
            (axes[1], SENSORS.accel_bias, 1 / _MGAL, "accel bias, mGal", "accel_bias_mgal")):
        fwd = scale * result.forward_sensors[:, sl]
        smo = scale * result.smoothed_sensors[:, sl]
        fit = [fwd, smo]
        for k, axis in enumerate("xyz"):
            ax.plot(t, fwd[:, k], f"C{k}--", lw=0.7, label=f"{axis} forward")
            ax.plot(t, smo[:, k], f"C{k}", lw=1.0, label=f"{axis} smoothed")
            if injected is not None:
                ax.axhline(injected[key][k], color=f"C{k}", ls=":", lw=1.6,
                           label=f"{axis} injected (manifest)")
        if injected is not None:
            fit.append(injected[key])
        ax.set_ylim(*robust_limits(t, fit, margin=0.08))
        _shade_transient(ax, t[-1])
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        legend_right(ax, fontsize=7)
    axes[-1].set_xlabel(xlabel + _transient_note(t[-1]))
    truth = ("; dotted: the constant biases the simulator injected (its bias "
             "instability comes on top)" if injected is not None else "")
    fig.suptitle(f"Sensor bias estimates (body axes x, y, z){truth}\n{origin}", fontsize=10)
    fig.tight_layout()
    return save_png(fig, path)


def plot_innovations(result, path):
    """Standardized innovations ``z_i / sqrt(S_ii)`` of every tested measurement against
    time, one panel per measurement type, one colour per axis, the +-3 band; rejected
    records as crosses."""
    plt = pyplot()
    recs = getattr(getattr(result, "fwd", None), "records", None) or []
    kinds = list(dict.fromkeys(r.name for r in recs))
    if not kinds:
        return None
    recoveries = getattr(result.fwd, "recoveries", [])
    reanchors = getattr(result.fwd, "reanchors", [])
    t0 = float(result.node_time[0])
    fig, axes = plt.subplots(len(kinds), 1, figsize=(10, 2.6 * len(kinds) + 1), sharex=True,
                             squeeze=False)
    for ax, kind in zip(axes[:, 0], kinds):
        rms_of, handles = {}, {}
        for axis, (t, z, ok) in _series([r for r in recs if r.name == kind], t0).items():
            rms_of[axis] = np.sqrt(np.mean(z[ok] ** 2)) if np.any(ok) else np.nan
            (handles[axis],) = ax.plot(t[ok], z[ok], ".", ms=2)
            if np.any(~ok):
                ax.plot(t[~ok], np.clip(z[~ok], -10, 10), "x", ms=4, color="k")
        ax.axhline(3, color="0.5", lw=0.8, ls="--")
        ax.axhline(-3, color="0.5", lw=0.8, ls="--")
        for a, b, _, _ in recoveries:        # runs of rejected fixes, then the recovery
            ax.axvspan(a - t0, b - t0, color="tab:red", alpha=0.15, lw=0)
            ax.axvline(b - t0, color="tab:red", lw=0.8)
        for a, b, _, _ in reanchors:         # after a GNSS gap: the INS had drifted
            ax.axvspan(a - t0, b - t0, color="tab:green", alpha=0.2, lw=0)
            ax.axvline(b - t0, color="tab:green", lw=0.8)
        ax.set_ylim(-6, 6)
        ax.set_ylabel(f"{kind}\ninnovation / sigma")
        ax.grid(alpha=0.3)
        _legend_largest(ax, rms_of, handles, "{:.2f}", fontsize=7)
    xlabel, origin = time_label(t0)
    axes[-1, 0].set_xlabel(xlabel)
    red = (f"; red: {len(recoveries)} recoveries from runs of rejected fixes"
           if recoveries else "")
    if reanchors:
        red += f"; green: {len(reanchors)} re-anchorings after GNSS gaps (the INS drifted)"
    fig.suptitle("Standardized innovations (predicted - measured) / sqrt(S_ii); dashed: "
                 f"+-3; crosses: rejected (clipped at +-10){red}\n{origin}", fontsize=10)
    fig.tight_layout()
    return save_png(fig, path)


def _series(records, t0, standardized=True):
    """``{axis label: (time - t0, value, accepted)}`` of records whose axes are N/E/D
    (one label per column) or a satellite each (tight coupling: one record per
    satellite and epoch).  ``standardized``: ``z / sqrt(S)``, else the innovation."""
    out = {}
    for r in records:
        v = r.standardized if standardized else r.innovation
        for i, axis in enumerate(r.axes):
            out.setdefault(axis, []).append((r.time - t0, float(v[i]), r.accepted))
    return {k: tuple(np.array(c) for c in zip(*rows)) for k, rows in sorted(out.items())}


_SAT_KINDS = (("pseudorange", "m"), ("range_rate", "m/s"), ("dd_pseudorange", "m"),
              ("dd_range_rate", "m/s"), ("dd_carrier_L1", "m"), ("dd_carrier_L2", "m"))
#: Series named in a panel's legend at most (the largest RMS first; the others counted).
LEGEND_SERIES = 14


def satellites_used(records):
    """``{time: satellites}`` of tight coupling's pseudorange records (accepted ones), or
    of its double differences (``n - 1`` DDs of ``n`` satellites, the reference counted)."""
    used, dd_rows = {}, {}
    for r in records:
        if r.name == "pseudorange":
            used.setdefault(r.time, 0)
            used[r.time] += bool(r.accepted)
        elif r.name == "dd_pseudorange":
            dd_rows[r.time] = dd_rows.get(r.time, 0) + bool(r.accepted)
    used.update({k: n + 1 if n else 0 for k, n in dd_rows.items()})
    return used


def _legend_largest(ax, rms_of, handles, fmt, fontsize):
    """Legend right of ``ax``: every series when there are at most
    :data:`LEGEND_SERIES`, else those with the largest RMS (series with no accepted
    value last) and a count of the others."""
    named = list(rms_of)                # a few: in their order (N, E, D; the satellites)
    if len(named) > LEGEND_SERIES:
        named.sort(key=lambda k: (np.isnan(rms_of[k]), -np.nan_to_num(rms_of[k])))
    labels = [f"{k}: RMS {fmt.format(rms_of[k])}" for k in named[:LEGEND_SERIES]]
    hs = [handles[k] for k in named[:LEGEND_SERIES]]
    if len(named) > LEGEND_SERIES:
        hs.append(ax.plot([], [], " ")[0])
        labels.append(f"+{len(named) - LEGEND_SERIES} more (smaller RMS)")
    legend_right(ax, hs, labels, fontsize=fontsize)


def plot_satellite_residuals(result, path):
    """Tight coupling: each satellite's pseudorange and range-rate innovation (predicted -
    measured before the update, m and m/s) against time, one colour per satellite with its RMS, rejected
    ones as crosses, and the satellites used per epoch (double differences: one colour per
    satellite-reference pair, the satellites used counting the reference).  None without
    such records."""
    recs = getattr(getattr(result, "fwd", None), "records", None) or []
    kinds = [(k, u) for k, u in _SAT_KINDS if any(r.name == k for r in recs)]
    if not kinds:
        return None
    plt = pyplot()
    t0 = float(result.node_time[0])
    fig, axes = plt.subplots(len(kinds) + 1, 1, figsize=(10, 2.8 * len(kinds) + 3.2),
                             sharex=True, squeeze=False)
    cmap = plt.get_cmap("tab20")
    for ax, (kind, unit) in zip(axes[:, 0], kinds):
        series = _series([r for r in recs if r.name == kind], t0, standardized=False)
        lim, rms_of, handles = [], {}, {}
        for j, (sat, (t, v, ok)) in enumerate(series.items()):
            rms = np.sqrt(np.mean(v[ok] ** 2)) if np.any(ok) else np.nan
            (h,) = ax.plot(t[ok], v[ok], ".", ms=2, color=cmap(j % 20))
            if np.any(~ok):
                ax.plot(t[~ok], v[~ok], "x", ms=4, color=cmap(j % 20))
            lim.append(v[ok])
            rms_of[sat], handles[sat] = rms, h
        vals = np.concatenate(lim) if lim else np.zeros(0)
        if vals.size:                     # the accepted residuals, a blunder or two outside
            lo, hi = np.percentile(vals, [0.2, 99.8])
            pad = 0.15 * (hi - lo) if hi > lo else 1.0
            ax.set_ylim(lo - pad, hi + pad)
        ax.set_ylabel(f"{kind}\ninnovation, {unit}")
        ax.grid(alpha=0.3)
        _legend_largest(ax, rms_of, handles, "{:.3g}", fontsize=6)
    up = getattr(result.fwd, "updater", None)
    used = ({ep.time: ep.used for ep in up.epochs} if getattr(up, "epochs", None)
            else satellites_used(recs))     # the updater's: epochs with no record too
    dd_rows = any(r.name == "dd_pseudorange" for r in recs)
    t = np.array(sorted(used)) - t0
    ax = axes[-1, 0]
    ax.step(t, [used[k] for k in sorted(used)], where="post", color="k", lw=1)
    ax.axhline(4, color="tab:red", lw=0.8, ls="--")
    ax.set_ylabel("satellites used")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    xlabel, origin = time_label(t0)
    axes[-1, 0].set_xlabel(xlabel)
    what = ("double differences per satellite-reference pair" if dd_rows else
            "innovations per satellite")
    clock = "" if dd_rows else "; a shift common to an epoch is the receiver clock's"
    fig.suptitle(f"Tight coupling: {what} (predicted - measured, before "
                 f"the update{clock});\ncrosses: "
                 "rejected; dashed: 4 satellites, below which loose coupling has no fix; "
                 f"{origin}", fontsize=10)
    fig.tight_layout()
    return save_png(fig, path)


def write_plots(result, out_dir, flight_dir=None):
    """Write the PNG plots into ``out_dir``; returns their paths.  ``flight_dir``: a
    simulated flight folder whose manifest gives the injected biases (optional)."""
    injected = injected_biases(flight_dir) if flight_dir else None
    paths = [plot_sigma(result, os.path.join(out_dir, "sigma.png")),
             plot_biases(result, os.path.join(out_dir, "biases.png"), injected)]
    if result.errors_smoothed is not None:
        paths.append(plot_errors(result, os.path.join(out_dir, "errors.png")))
    for plot, name in ((plot_innovations, "innovations.png"),
                       (plot_satellite_residuals, "satellite_residuals.png")):
        p = plot(result, os.path.join(out_dir, name))
        if p is not None:
            paths.append(p)
    return paths
