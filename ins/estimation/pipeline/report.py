"""The QC report of one ``ins process`` run as one self-contained HTML file
(:mod:`ins.common.html_report`): the trust verdict and its reasons, the summary table,
the GNSS source and its quality over time, the recoveries and re-anchorings, the
forward/backward separation of a raw-GNSS run, the IMU errors (smoothed sensor
estimates against their stated sigmas), the identified IMU noise, the errors against a
truth, and every PNG the run wrote, embedded.

Library code: nothing is printed; :func:`process_report` returns the page, the command
writes it (inside its staged output folder, or atomically elsewhere).
"""
import os
from datetime import datetime, timezone

import numpy as np

from ins.common.html_report import HtmlReport
from ins.estimation.core.error_model import DPH, MGAL, PPM, SENSORS, STATE

__all__ = ["process_report", "quality_runs", "QUALITY_NAMES"]

#: RTKLIB's solution quality flags.
QUALITY_NAMES = {1: "fix", 2: "float", 3: "SBAS", 4: "DGNSS", 5: "single", 6: "PPP"}
_QUALITY_COLOURS = {1: "#2e7d32", 2: "#f9a825", 3: "#8e24aa", 4: "#1e88e5", 5: "#c62828",
                    6: "#00897b", 0: "#78909c"}
_GAP_COLOUR = "#eceff1"
#: A GNSS gap is an interval longer than this many times the median interval.
GAP_FACTOR = 3.0
_MAX_SEGMENTS = 600
_MAX_RUN_ROWS = 40

#: Where each figure of the run goes (file name -> section); others go to the end.
_FIGURE_SECTION = {"innovations.png": "gnss", "satellite_residuals.png": "gnss",
                   "fwd_bwd_separation.png": "separation", "biases.png": "imu",
                   "sigma.png": "accuracy", "errors.png": "accuracy"}
_FIGURE_CAPTION = {
    "innovations.png": "Standardized GNSS innovations of the forward filter (rejected: "
                       "crosses; recoveries red, re-anchorings green)",
    "satellite_residuals.png": "Tight coupling: innovations per satellite and the "
                               "satellites used",
    "fwd_bwd_separation.png": "RTKLIB forward minus backward solution",
    "biases.png": "Sensor bias estimates, forward and smoothed",
    "sigma.png": "Stated standard deviations of the solution, forward and smoothed",
    "errors.png": "Errors against the truth, forward and smoothed, with the smoothed "
                  "3-sigma envelope"}


def quality_runs(time, quality=None, gap_factor=GAP_FACTOR):
    """Stretches of one GNSS quality flag and the gaps between them.

    Parameters
    ----------
    time : array_like, shape (n,)
        Epochs of the GNSS positions, s (sorted here).
    quality : array_like of int, shape (n,), optional
        Their quality flags (RTKLIB Q); None: one flag 0 ("no flag in the log").
    gap_factor : float
        An interval longer than ``gap_factor`` times the median interval is a gap.

    Returns
    -------
    list of (t_from, t_to, q, epochs)
        In time order; a gap is ``q = None``, ``epochs = 0``, from the last epoch before
        it to the first after it.
    """
    t = np.asarray(time, float)
    q = np.zeros(len(t), int) if quality is None else np.asarray(quality, int)
    order = np.argsort(t, kind="stable")
    t, q = t[order], q[order]
    if len(t) == 0:
        return []
    dt = np.diff(t)
    limit = gap_factor * np.median(dt) if len(dt) else np.inf
    runs = []
    start = 0
    for k in range(1, len(t) + 1):
        gap = k < len(t) and dt[k - 1] > limit
        if k == len(t) or gap or q[k] != q[start]:
            runs.append((float(t[start]), float(t[k - 1]), int(q[start]), k - start))
            if gap:
                runs.append((float(t[k - 1]), float(t[k]), None, 0))
            start = k
    return runs


def _qname(q):
    return "gap (no GNSS)" if q is None else QUALITY_NAMES.get(q, "no flag" if q == 0
                                                               else f"Q {q}")


def _verdict(report, result):
    q = result.quality or {}
    src = result.gnss_source or {}
    reasons = list(q.get("warnings") or [])
    if src.get("poor"):
        reasons.append(f"RTKLIB's solution: {src['poor']}")
    if q.get("error"):
        report.verdict("poor", "Untrustworthy solution: written with --accept-poor",
                       [q["error"]] + reasons)
    elif reasons:
        report.verdict("warn", "Trusted, with warnings", reasons)
    else:
        report.verdict("ok", "Trusted: every trust check passed", [
            "the GNSS measurements rejected by the innovation test, the solution's "
            "distance from the fixes and the recoveries are within the bounds of "
            "'ins process --help' (trust)"])


def _summary_rows(result, times):
    c, q = result.counts, result.quality or {}
    rows = [("IMU epochs", c["imu_epochs"]), ("filter nodes", c.get("nodes")),
            ("GNSS records", c["gnss_records"]), ("GNSS updates", c["updates"]),
            ("rejected by the innovation test", c["rejected"]),
            ("outside the processed span", c["outside_imu_span"]),
            ("with the static lever arm (no mount data)", c["mount_fallback"]),
            ("recoveries from runs of rejected fixes", c.get("recoveries", 0)),
            ("re-anchorings after GNSS gaps", c.get("reanchors", 0)),
            ("GNSS steps (rejected fixes off the GNSS track)", c.get("gnss_steps", 0))]
    if c.get("coupling") == "tight":
        rows += [("systems", "+".join(c.get("systems", ["G"]))),
                 ("satellites used per epoch, min", c.get("satellites_min")),
                 ("satellites used per epoch, mean", c.get("satellites_mean"))]
        if c.get("carrier_epochs") is not None:
            rows += [("RTK carrier epochs fixed", f"{c['fixed_epochs']} of "
                      f"{c['carrier_epochs']}"), ("cycle slips", c.get("cycle_slips")),
                     ("re-fix after total outages, s",
                      ", ".join(f"{v:g}" for v in c.get("refix_s", [])) or "none")]
    if q:
        rows += [("GNSS measurements tested", q["tested"]),
                 ("rejected fraction", f"{100 * q['rejected_fraction']:.2f} %")]
        if np.isfinite(q.get("residual_rms_m", np.nan)):
            rows += [("solution - fixes (antenna), RMS 3-D", f"{q['residual_rms_m']:.4g} m"),
                     ("solution - fixes (antenna), max 3-D", f"{q['residual_max_m']:.4g} m")]
    s = result.start_check
    if s is not None:
        rows.append(("start: distance from the first fix",
                     f"{s['distance_m']:.3g} m (bound {s['bound_m']:.4g} m)"))
    if result.alignment is not None:
        al = result.alignment
        rows.append((f"alignment ({al.method}): stated accuracy roll/pitch/yaw",
                     "/".join(f"{x:.4f}" for x in al.att_std_deg) + " deg"))
    if times:
        for key, label in (("processing_s", "processing time"),
                           ("writing_s", "writing the outputs and plots")):
            if times.get(key) is not None:
                rows.append((label, f"{times[key]:.2f} s"))
    return rows


def _gnss_section(report, result, figures):
    report.heading("GNSS source and quality")
    src = result.gnss_source
    log = getattr(result, "gnss", None)
    if src is not None:
        from ins.estimation.pipeline.gnss_source import source_lines
        report.items(source_lines(src, os.path.basename(src["path"])))
    elif log is not None and getattr(log, "path", None):
        report.paragraph(f"GNSS log {log.path}: {len(log)} positions"
                         + (" with velocities" if log.has_velocity else ""))
    if log is not None and len(log):
        qual = getattr(log, "quality", None)
        runs = quality_runs(log.time, qual)
        dt = np.diff(np.sort(np.asarray(log.time, float)))
        _quality_timeline(report, runs, qual is not None,
                          float(np.median(dt)) if len(dt) else 1.0)
        counts = {}
        for _, _, q, n in runs:
            if q is not None:
                counts[q] = counts.get(q, 0) + n
        total = sum(counts.values())
        gaps = [r for r in runs if r[2] is None]
        rows = [(_qname(q), n, f"{100 * n / total:.1f} %") for q, n in sorted(counts.items())]
        if gaps:
            rows.append(("gaps (no GNSS)", len(gaps),
                         f"{sum(b - a for a, b, _, _ in gaps):.1f} s in all"))
        report.table(("quality", "epochs", "share"), rows,
                     caption="GNSS epochs the filter took, by quality flag"
                     + ("" if qual is not None else " (the log has no quality flags)"))
        med = np.nanmedian(log.sigma_ned_m, axis=0)
        report.paragraph("Stated sigma of the positions, median N/E/D: "
                         + "/".join(f"{x:.3g}" for x in med) + " m.")
        _run_table(report, runs, qual is not None)
    for name in ("innovations.png", "satellite_residuals.png"):
        if name in figures:
            report.image(figures.pop(name), _FIGURE_CAPTION[name])


_RANK = {1: 0, 6: 1, 2: 2, 3: 3, 4: 4, 5: 5, 0: 6, None: 7}     # best first; a gap last


def _quality_timeline(report, runs, flagged, step):
    """The runs as a coloured bar: each epoch covers ``step`` s (the median interval);
    more runs than :data:`_MAX_SEGMENTS`: binned, the worst flag of each bin shown."""
    t0, t1 = runs[0][0], runs[-1][1] + step
    if len(runs) > _MAX_SEGMENTS:
        edges = np.linspace(t0, t1, _MAX_SEGMENTS + 1)
        worst = [-1] * _MAX_SEGMENTS
        for a, b, q, n in runs:
            end = b if q is None else b + step
            k0 = max(int(np.searchsorted(edges, a, "right")) - 1, 0)
            k1 = min(max(int(np.searchsorted(edges, end, "left")), k0 + 1), _MAX_SEGMENTS)
            for k in range(k0, k1):
                if worst[k] == -1 or _RANK[q] > _RANK[worst[k]]:
                    worst[k] = q
        runs = [(edges[k], edges[k + 1] - step, None if worst[k] == -1 else worst[k], 0)
                for k in range(_MAX_SEGMENTS)]
    segments = []
    for a, b, q, n in runs:
        width = (b - a - step) if q is None else (b - a + step)
        colour = _GAP_COLOUR if q is None else _QUALITY_COLOURS.get(q, "#546e7a")
        segments.append((max(width, 0.0), colour, f"{a:.1f}-{b:.1f} s: {_qname(q)}"
                         + (f" ({n} epochs)" if n else "")))
    total = sum(w for w, _, _ in segments) or 1.0
    segments = [(w / total, c, t) for w, c, t in segments]
    seen = sorted({r[2] for r in runs}, key=lambda q: _RANK.get(q, 8))
    legend = [(_GAP_COLOUR if q is None else _QUALITY_COLOURS.get(q, "#546e7a"),
               _qname(q) if flagged or q is None else "GNSS position (no flag in the log)")
              for q in seen]
    report.timeline(segments, legend, f"{t0:.1f} s", f"{runs[-1][1]:.1f} s (GPS s of week)")


def _run_table(report, runs, flagged):
    best = min((q for _, _, q, _ in runs if q is not None), default=None,
               key=lambda q: _RANK.get(q, 8))
    odd = [r for r in runs if r[2] is None or (flagged and r[2] != best)]
    if not odd:
        return
    shown = odd
    note = ""
    if len(odd) > _MAX_RUN_ROWS:
        shown = sorted(sorted(odd, key=lambda r: r[0] - r[1])[:_MAX_RUN_ROWS])
        note = f" (the {_MAX_RUN_ROWS} longest of {len(odd)})"
    report.table(("from, s", "to, s", "duration, s", "quality", "epochs"),
                 [(f"{a:.2f}", f"{b:.2f}", f"{b - a:.2f}", _qname(q), n)
                  for a, b, q, n in shown],
                 caption="Stretches with no GNSS or below the best quality" + note)


def _events_section(report, result):
    report.heading("Recoveries and re-anchorings")
    fwd = result.fwd
    rows = [("recovery", f"{a:.2f}", f"{b:.2f}", n, f"x{f:.3g}",
             "a run of rejected fixes; the navigation covariance inflated and the last "
             "fix taken") for a, b, n, f in getattr(fwd, "recoveries", [])]
    rows += [("re-anchoring", f"{a:.2f}", f"{b:.2f}", n, f"x{f:.3g}",
              "after a GNSS gap, mutually consistent fixes rejected (the INS drifted); "
              "the covariance inflated and the last fix taken")
             for a, b, n, f in getattr(fwd, "reanchors", [])]
    if not rows:
        report.paragraph("None: the filter accepted the GNSS without having to recover or "
                         "re-anchor.")
        return
    report.table(("event", "from, s", "to, s", "fixes rejected", "covariance", "what"),
                 rows, numeric={1, 2, 3})


def _separation_section(report, result, figures):
    sep = (result.gnss_source or {}).get("separation")
    if sep is None and "fwd_bwd_separation.png" not in figures:
        return
    report.heading("Forward/backward separation (RTKLIB)")
    if sep is not None:
        from ins.gnss.separation import FIX_DISAGREE_M
        rows = []
        for label, fixed in (("all epochs both solved", False), ("both fixed", True)):
            n, rms, mx, mx3 = sep.stats(fixed_only=fixed)
            if n:
                rows.append((label, n, *(f"{1e3 * x:.1f}" for x in rms),
                             *(f"{1e3 * x:.1f}" for x in mx), f"{1e3 * mx3:.1f}"))
        report.table(("epochs", "n", "RMS N mm", "RMS E mm", "RMS U mm", "max N mm",
                      "max E mm", "max U mm", "max 3-D mm"), rows)
        report.paragraph(f"{sep.fixed_disagreements} epochs fixed in both directions lie "
                         f"more than {1e3 * FIX_DISAGREE_M:g} mm apart (different integers).")
    if "fwd_bwd_separation.png" in figures:
        report.image(figures.pop("fwd_bwd_separation.png"),
                     _FIGURE_CAPTION["fwd_bwd_separation.png"])


def _imu_section(report, result, cfg, injected, figures):
    report.heading("IMU errors (smoothed sensor estimates)")
    est = np.asarray(result.smoothed_sensors)
    std = np.asarray(result.smoothed_std)
    stated = cfg.noise.sensor_std if cfg is not None and getattr(cfg, "noise", None) else None
    groups = (("gyro bias", SENSORS.gyro_bias, STATE.gyro_bias, DPH, "deg/h", "gyro_bias_dph"),
              ("accel bias", SENSORS.accel_bias, STATE.accel_bias, MGAL, "mGal",
               "accel_bias_mgal"),
              ("gyro scale", SENSORS.gyro_scale, STATE.gyro_scale, PPM, "ppm", None),
              ("accel scale", SENSORS.accel_scale, STATE.accel_scale, PPM, "ppm", None))
    rows = []
    for name, sl, st, unit, label, key in groups:
        for k, axis in enumerate("xyz"):
            v = est[:, sl][:, k] / unit
            row = [f"{name} {axis}, {label}", f"{np.mean(v):.4g}", f"{np.min(v):.4g}",
                   f"{np.max(v):.4g}", f"{v[-1]:.4g}", f"{std[-1, st][k] / unit:.3g}",
                   "" if stated is None else f"{stated[sl][k] / unit:.3g}"]
            if injected is not None:
                row.append(f"{injected[key][k]:.4g}" if key in injected else "")
            rows.append(row)
    header = ["sensor error", "mean", "min", "max", "at the end", "sigma at the end",
              "stated sigma (settings)"] + (["injected (simulation)"] if injected else [])
    report.table(header, rows, caption="Smoothed estimates over the run (imu_errors.txt)")
    ratios = (result.quality or {}).get("sensor_ratio") or {}
    if ratios:
        report.paragraph("Largest estimate over its stated sigma: " + "; ".join(
            f"{n} {r:.2f} ({e:.3g} {u} on {a}, sigma {s:.3g} {u})"
            for n, (r, e, s, u, a) in ratios.items()) + ".")
    ident = getattr(result, "identified", None)
    if ident is not None:
        report.heading("IMU noise identified from the log", 3)
        report.paragraph(ident.describe())
    if "biases.png" in figures:
        report.image(figures.pop("biases.png"), _FIGURE_CAPTION["biases.png"])


def _accuracy_section(report, result, figures):
    es = result.errors_smoothed
    if es is None and not ({"sigma.png", "errors.png"} & set(figures)):
        return
    report.heading("Accuracy")
    if es is not None:
        rows = []
        for name, e in (("forward", result.errors_forward), ("smoothed", es)):
            if e is None:
                continue
            p = 1e3 * np.sqrt(np.mean(e.pos_n ** 2, axis=0))
            a = np.sqrt(np.mean(e.att_n ** 2, axis=0)) * 180 / np.pi * 3600
            rows.append((name, *(f"{x:.1f}" for x in p), *(f"{x:.1f}" for x in a)))
        report.table(("RMS against the truth", "N mm", "E mm", "D mm", "tilt N arcsec",
                      "tilt E arcsec", "heading arcsec"), rows)
    for name in ("errors.png", "sigma.png"):
        if name in figures:
            report.image(figures.pop(name), _FIGURE_CAPTION[name])


def process_report(result, cfg=None, plots=(), files=(), times=None, inputs=None,
                   injected=None, title=None):
    """The report of a run: an :class:`~ins.common.html_report.HtmlReport` (its
    ``html()`` the page, ``write(path)`` the file).

    Parameters
    ----------
    result : ins.estimation.pipeline.process.ProcessResult
    cfg : ins.estimation.pipeline.config.ProcessConfig, optional
        The settings (the stated sensor sigmas).
    plots : sequence of str
        PNG files to embed (every figure the run wrote), each once.
    files : sequence of str
        The output files, as the user will find them (listed).
    times : dict, optional
        ``processing_s``, ``writing_s``.
    inputs : sequence of (str, str), optional
        (role, path) of the input files.
    injected : dict, optional
        The simulator's injected biases (:func:`ins.estimation.pipeline.plots.injected_biases`).
    """
    report = HtmlReport(title or "GNSS/INS post-processing report",
                        "ins process, " + datetime.now(timezone.utc).strftime(
                            "%Y-%m-%d %H:%M UTC"))
    figures = {}
    for p in plots:
        figures.setdefault(os.path.basename(p), p)
    report.heading("Trust verdict")
    _verdict(report, result)
    report.heading("Summary")
    report.table(("", "value"), _summary_rows(result, times), numeric={1})
    if inputs:
        report.table(("input", "file"), [(r, p) for r, p in inputs if p])
    _gnss_section(report, result, figures)
    _events_section(report, result)
    _separation_section(report, result, figures)
    _imu_section(report, result, cfg, injected, figures)
    _accuracy_section(report, result, figures)
    if figures:
        report.heading("Other figures")
        for name, path in figures.items():
            report.image(path, name)
    if files:
        report.heading("Files written")
        report.items(files)
    return report
