"""Report of a refinement: Markdown (tables) with PNG plots beside it (matplotlib, Agg,
lazy import), or the same text as one self-contained HTML page with the plots embedded
(:func:`write_html_report`, :mod:`ins.common.html_report`).

Angles in the report are arcsec (differences, sigmas) or deg (values); photo residuals
are the normalized coplanarity misclosures ``g / sigma_g`` (unitless, ~N(0, 1)).
"""
import os

import numpy as np

from ins.common.fileio import atomic_open
from ins.nav.rotation import wrap_to_pi
from photogrammetry.adjustment.coplanarity import STATUS_TEXT

__all__ = ["write_report", "write_html_report", "report_text", "boresight_lines",
           "HTML_SUFFIXES"]

#: A report file with one of these suffixes is written as HTML, any other as Markdown.
HTML_SUFFIXES = (".html", ".htm")

_AS = 180.0 / np.pi * 3600.0


def _plot_residuals(result, path=None):
    """The residual plot into ``path`` (PNG), or its PNG bytes without a path."""
    from ins.common.plotstyle import png_bytes, pyplot, save_png
    plt = pyplot()
    blk = result.block
    fig, ax = plt.subplots(figsize=(7.5, 5.5))
    xy = np.concatenate([p[1] for p in result.pair_points])
    res = np.abs(np.concatenate([blk.residuals[k, :len(p[1])]
                                 for k, p in enumerate(result.pair_points)]))
    rej = np.concatenate([blk.rejected[k, :len(p[1])] for k, p in enumerate(result.pair_points)])
    # no marker edges: stroking the edge of each of 10^5 markers was most of the
    # plot's time (1000 images: 1.5 s); the area makes up for the edge's width
    keep = _decimated(res, rej)
    sc = ax.scatter(xy[keep, 0], xy[keep, 1], c=res[keep], s=10, linewidths=0,
                    cmap="viridis", vmin=0, vmax=3)
    ax.scatter(xy[rej, 0], xy[rej, 1], marker="x", c="red", s=30,
               label=f"rejected ({int(rej.sum())})")
    fig.colorbar(sc, ax=ax, label="|normalized coplanarity misclosure| (sigma units)",
                 pad=0.02)
    ax.set_xlabel("image x, mm (second image of each pair)")
    ax.set_ylabel("image y, mm")
    ax.set_aspect("equal")
    s = result.settings
    px = blk.sigma0 * s["sigma_mm"] / s["pixel_size_mm"]
    shown = ("" if len(keep) == int((~rej).sum()) else
             f"\n{len(keep)} drawn: an even sample, and every one of 3 sigma or more")
    ax.set_title(f"Coplanarity residuals in the image\n{int(blk.mask.sum())} conditions used, "
                 f"{int(rej.sum())} rejected (red x); sigma0 {blk.sigma0:.2f} ({px:.3g} px)"
                 f"{shown}", fontsize=10)
    return png_bytes(fig) if path is None else save_png(fig, path)


#: Markers of the residual plot at most: an even stride through the used conditions
#: (their distribution kept), and every residual of 3 sigma or more (at 10 px a marker,
#: 20 000 cover the plot's image area several times over; 1000 images have 1.4 * 10^5
#: conditions, whose markers were two thirds of the report's time).
RESIDUAL_MARKERS = 20000


def _decimated(res, rej):
    """Indices of the used conditions drawn in the residual plot (in their order)."""
    used = np.flatnonzero(~rej)
    if len(used) <= RESIDUAL_MARKERS:
        return used
    step = int(np.ceil(len(used) / RESIDUAL_MARKERS))
    return np.union1d(used[::step], used[res[used] >= 3.0])


def _plot_corrections(result, path=None):
    """The angle corrections' plot into ``path`` (PNG), or its PNG bytes without a path."""
    from ins.common.plotstyle import (
        exposure_axis,
        legend_right,
        mark_strips,
        png_bytes,
        pyplot,
        save_png,
        strip_starts,
        with_gaps,
    )
    plt = pyplot()
    a = result.assessment
    fig, ax = plt.subplots(figsize=(9, 4.2))
    idx, xlabel, origin = exposure_axis(result.eo.time)
    kappa = result.eo.angles[:, 2] if result.eo.angles.ndim == 2 else None
    starts = strip_starts(list(result.eo.image_id), heading_rad=kappa)
    for k, name in enumerate(a.names):
        y = np.where(a.used, a.diff[:, k] * _AS, np.nan)
        ax.plot(*with_gaps(idx, y, starts), ".-", label=f"{name}")
        ax.axhline(a.mean[k] * _AS, color=f"C{k}", lw=0.8, ls=":",
                   label=f"{name} mean, {a.mean[k] * _AS:.0f} arcsec")
    ax.axhline(0, color="k", lw=0.5)
    mark_strips(ax, starts, len(idx), x=idx)
    ax.set_xlabel(f"{xlabel}; dashed lines: strip boundaries")
    ax.set_ylabel("INS - adjusted, arcsec")
    ax.set_title("Angle corrections along the strips (INS minus adjusted)"
                 + (f"\n{origin}" if origin else ""), pad=18, fontsize=10)
    ax.grid(alpha=0.3)
    legend_right(ax)
    return png_bytes(fig) if path is None else save_png(fig, path)


def _fmt3(v, scale=_AS, digits=1, nan_text="n/a"):
    return " | ".join(nan_text if not np.isfinite(x) else f"{x * scale:.{digits}f}" for x in v)


def _deg3(v):
    """Angles (rad) as deg with 6 decimals, wrapped to (-180, 180] after rounding."""
    d = np.round(np.rad2deg(wrap_to_pi(np.asarray(v, float))), 6)
    d = np.where(d <= -180.0, d + 360.0, d) + 0.0
    return " | ".join(f"{x:.6f}" for x in d)


def _trust_lines(q):
    """The trust section: the flags of :mod:`photogrammetry.adjustment.quality`, or none."""
    if q is None:
        return []
    rule = ("Rule: sigma0 above max(2, sqrt(chi2_q(r)/r)) at redundancy r (block: "
            "q = 0.999; each of the P pair screenings: q = 1 - 0.001/P), or an angle change "
            "from the prior above 5 sqrt(2 s_prior^2 + s_adj^2).")
    if not q.poor:
        return [f"Trust: no flag (block sigma0 limit {q.sigma0_limit:.2f}). {rule}", ""]
    return (["## Trust: POOR (written with --accept-poor)", "", rule, ""]
            + [f"- {r}" for r in q.reasons] + [""])


def boresight_lines(assessment, boresight_sigma=None, note=None, csv=False):
    """The estimated boresight with its two sigmas, as report lines (Markdown) or, with
    ``csv``, as ``key = value`` comment lines of the refined CSV (deg).

    Parameters
    ----------
    assessment : photogrammetry.adjustment.assessment.Assessment
    boresight_sigma : photogrammetry.orientation.boresight_sigma.BoresightSigma, optional
        With the INS attitude's common sigma (default: the adjustment's sigma alone).
    note : str, optional
        Why there is no INS sigma (stated with the adjustment-only sigma).
    csv : bool
    """
    from photogrammetry.orientation.boresight_sigma import BoresightSigma
    a = assessment
    if not a.boresight_observable:
        return []
    bs = boresight_sigma if boresight_sigma is not None else BoresightSigma(a.boresight_sigma)
    note = note or "no INS sigma file was given"
    why = ("the estimate also holds the INS attitude error common to the exposures "
           "(a body-fixed error cannot be told from a boresight)")
    if csv:
        def deg(v):
            return ", ".join(f"{x:.8f}" for x in np.rad2deg(v))
        out = [f"boresight_rx_ry_rz_deg = {deg(a.boresight)}",
               f"boresight_sigma_adjustment_deg = {deg(bs.adjustment)}"]
        if bs.has_ins:
            return out + [f"boresight_sigma_ins_common_deg = {deg(bs.ins_common)}",
                          f"boresight_sigma_total_deg = {deg(bs.total)}",
                          f"boresight sigma = total: sqrt(adjustment^2 + ins_common^2); "
                          f"{why}; INS sigma from {bs.source}, taken as fully correlated "
                          "over the exposures (an upper bound)"]
        return out + [f"boresight sigma = adjustment only ({note}): it understates the "
                      f"error, {why}"]
    rows = ["| boresight | rx | ry | rz |", "|---|---:|---:|---:|",
            "| estimate (deg) | " + _deg3(a.boresight) + " |",
            "| sigma, adjustment alone (arcsec) | " + _fmt3(bs.adjustment) + " |"]
    head = ["**Boresight misalignment** (rx, ry, rz of the camera file, "
            "`C_bc = axes Rx Ry Rz`, GLS): "
            + ", ".join(f"{v * 180 / np.pi:.5f} +- {e * 180 / np.pi:.5f} deg"
                        for v, e in zip(a.boresight, bs.total))
            + (" (total sigma)" if bs.has_ins else " (adjustment's sigma alone)"), ""]
    if bs.has_ins:
        rows += ["| sigma, INS attitude common to the exposures (arcsec) | "
                 + _fmt3(bs.ins_common) + " |",
                 "| **sigma, total** (arcsec): calibrate with this | " + _fmt3(bs.total)
                 + " |", "",
                 f"The total sigma is sqrt(adjustment^2 + INS^2): {why}.  The INS part is the "
                 f"smoothed roll, pitch, yaw sigma of `{bs.source}` at the exposures, turned "
                 "into the camera frame and taken as fully correlated over the block (the "
                 "mean of the sigmas: an upper bound, as the INS error is strongly "
                 "correlated in time but not wholly)."]
    else:
        rows += ["", f"The sigma is the adjustment's alone ({note}).  It understates the "
                 f"boresight's error: {why}, of the size of the smoothed INS attitude sigma "
                 "(often many times the adjustment's sigma).  Give the trajectory's sigma "
                 "file (`--ins-std solution_std.txt`) for the total sigma."]
    return head + rows


def report_text(result, plots=(), boresight_sigma=None, boresight_note=None):
    """The report as Markdown text (plots: file names to link; ``boresight_sigma``,
    ``boresight_note``: see :func:`boresight_lines`)."""
    s, blk, a = result.settings, result.block, result.assessment
    names = a.names
    px = s["pixel_size_mm"]
    lines = ["# Coplanarity refinement of the exposure angles", "",
             f"- method **{s['method']}**, datum **{s['datum']}**, angle system "
             f"`{s['system']}`, mapping frame `{result.eo.frame}`",
             f"- {s['n_images']} images, {s['n_pairs']} pairs, {s['n_observations']} "
             f"tie-point observations, {int(blk.mask.sum())} coplanarity conditions used, "
             f"{int(blk.rejected.sum())} rejected (data snooping)",
             f"- a-priori photo sigma {s['sigma_mm'] / px:.3g} px ({s['sigma_mm']:.4g} mm); "
             f"**sigma0 = {blk.sigma0:.3f}** (= {blk.sigma0 * s['sigma_mm'] / px:.3g} px), "
             f"redundancy {blk.redundancy}, {blk.iterations} iterations, "
             f"{'converged' if blk.converged else 'NOT converged'}", ""]
    if s.get("n_tiles"):
        sizes = s.get("tile_sizes") or [0]
        lines[-1:-1] = [
            f"- adjusted in **{s['n_tiles']} tiles** of at most {s['tile_images']} core "
            f"images (with a halo of {s['halo_hops']} pair-hops: {min(sizes)}-{max(sizes)} "
            "images each); each image's angles and sigmas are those of its core tile, the "
            "correlation across tile borders is not kept and the assessment combines the "
            "tiles' own (see docs/interfaces.md, tiled refinement)"]
    lines += _trust_lines(blk.quality)
    bad = [(k, st) for k, st in enumerate(blk.pair_status) if st != 0]
    if bad:
        lines += ["Pairs left out:", ""]
        lines += [f"- {result.eo.image_id[result.pairs[k, 0]]}-"
                  f"{result.eo.image_id[result.pairs[k, 1]]}: {STATUS_TEXT[st]}"
                  for k, st in bad] + [""]
    lines += ["## INS assessment (INS minus adjusted, arcsec)", "",
              "| | " + " | ".join(names) + " |", "|---|" + "---:|" * 3,
              "| mean | " + _fmt3(a.mean) + " |",
              "| sigma of the mean (full covariance) | " + _fmt3(a.mean_sigma) + " |",
              "| GLS mean | " + _fmt3(a.gls_mean) + " |",
              "| sigma of the GLS mean | " + _fmt3(a.gls_mean_sigma) + " |",
              "| RMS | " + _fmt3(a.rms) + " |",
              "| RMS after boresight/datum | " + _fmt3(a.residual_rms) + " |",
              "| adjustment sigma (RMS) | " + _fmt3(a.adj_sigma_rms) + " |",
              "| **INS noise** (REML variance component) | "
              + _fmt3(a.ins_noise, nan_text="not estimable (negative)") + " |",
              "| sigma of the INS noise | " + _fmt3(a.ins_noise_sigma) + " |", ""]
    negative = [n for n, neg in zip(names, np.atleast_1d(a.ins_noise_negative)) if neg]
    if negative:
        lines += [f"INS noise of {', '.join(negative)}: the variance component came out "
                  "negative (the differences scatter less than the adjustment's own "
                  "covariance predicts), so it is not estimable here: below the "
                  "adjustment's sigma, not zero.", ""]
    lines += ["The differences are correlated (the adjusted angles of a strip chain through "
              "the relative orientations): the sigma of the mean is sqrt(1' V 1)/k and the "
              "GLS mean, the boresight and the INS noise are estimated with the full "
              "covariance V = lambda C_adj + diag(s^2) (generalized least squares; s and "
              f"lambda by REML; lambda = {a.cov_factor:.2f}"
              + (f" +- {a.cov_factor_sigma:.2f}" if a.cov_factor_sigma > 0 else
                 " held: not separable from the INS noise")
              + f"; chi2 {a.chi2:.1f} for {a.dof} degrees of freedom)."
              + (f" EO position sigma {s['position_sigma_m']:.3g} m propagated into C_adj."
                 if s.get("position_sigma_m") else
                 (" The bases are taken as exact (no EO position sigmas; "
                  "--position-sigma-m)." if s["method"] == "known-base" else "")), ""]
    if a.boresight_observable:
        lines += boresight_lines(a, boresight_sigma, boresight_note) + [""]
    else:
        lines += ["Boresight: not observable with this datum/method (the block is oriented "
                  "by INS angles); use --method known-base --datum none.", ""]
    lines += ["## Images", "",
              "| image | " + " | ".join(f"{n} (deg)" for n in names) + " | "
              + " | ".join(f"sigma {n} (\")" for n in names) + " | "
              + " | ".join(f"d{n} (\")" for n in names) + " | r(1,2) r(1,3) r(2,3) |",
              "|---|" + "---:|" * 10]
    for i, iid in enumerate(result.eo.image_id):
        c = a.correlations[i]
        lines.append(f"| {iid} | " + _deg3(result.eo.angles[i]) + " | "
                     + _fmt3(blk.sigma[i]) + " | " + _fmt3(a.diff[i]) + " | "
                     + f"{c[0, 1]:.2f} {c[0, 2]:.2f} {c[1, 2]:.2f} |")
    lines.append("")
    for title, name in plots:
        lines += [f"![{title}]({name})", ""]
    return "\n".join(lines)


def write_report(path, result, boresight_sigma=None, boresight_note=None):
    """Write the Markdown report and its two PNG plots beside it (atomically);
    ``boresight_sigma``, ``boresight_note``: see :func:`boresight_lines`."""
    stem = os.path.splitext(path)[0]
    plots = [("residuals in the image", stem + "_residuals.png"),
             ("angle corrections along the strips", stem + "_corrections.png")]
    _plot_residuals(result, plots[0][1])
    _plot_corrections(result, plots[1][1])
    text = report_text(result, [(t, os.path.basename(p)) for t, p in plots],
                       boresight_sigma, boresight_note)
    with atomic_open(path, "w") as f:
        f.write(text)
    return [p for _, p in plots]


def write_html_report(path, result, boresight_sigma=None, boresight_note=None):
    """Write the report of :func:`report_text` as one self-contained HTML file
    (atomically): the same text, its two plots embedded as PNG data URIs, nothing
    written beside it.  Returns ``path``."""
    from ins.common.html_report import HtmlReport
    plots = [("residuals in the image", "residuals.png", _plot_residuals(result)),
             ("angle corrections along the strips", "corrections.png",
              _plot_corrections(result))]
    text = report_text(result, [(t, n) for t, n, _ in plots], boresight_sigma,
                       boresight_note)
    page = HtmlReport(None, "photogrammetry refine")
    q = result.block.quality
    if q is not None and q.poor:                 # the verdict first, as in ins process's
        page.verdict("poor", "Poor: written with --accept-poor", q.reasons)
    elif q is not None:
        page.verdict("ok", f"No trust flag (block sigma0 limit {q.sigma0_limit:.2f})")
    page.markdown(text, images={n: png for _, n, png in plots})
    return page.write(path)
