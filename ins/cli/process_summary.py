"""The terminal summary of one ``ins process`` run (:func:`summary`): the GNSS source,
the counts, the tight coupling and RTK lines, the recoveries, the start, the trust
verdict's figures and, with a truth, the error table."""
import os
import sys

import numpy as np

__all__ = ["summary"]


def _cell(value, width=10, decimals=2):
    """``value`` right-aligned in exactly ``width`` characters: fixed-point when it
    fits, else scientific (never wider, so that columns never run together)."""
    text = f"{value:.{decimals}f}"
    if len(text) > width:
        text = f"{value:.{max(width - 7, 1)}e}"
    return text.rjust(width)


def _table(title, columns, rows, width=10):
    """Lines of a table: a label column, then ``columns`` in cells of ``width``
    characters separated by a space."""
    label = max([len(title)] + [len(name) for name, _ in rows])
    lines = [f"{title:<{label}} " + " ".join(c.rjust(width) for c in columns)]
    for name, values in rows:
        lines.append(f"{name:<{label}} " + " ".join(_cell(v, width) for v in values))
    return lines


def _start_lines(result, out):
    """What the start left open (``quality["start"]``): the IMU span skipped before the
    first fix; the heading of a log that never moved, resolved or not, with its sigma."""
    st = (result.quality or {}).get("start")
    if not st:
        return
    if st["imu_skipped_s"] is not None:
        a, b = st["imu_skipped_s"]
        print(f"IMU skipped: {a:.3f} .. {b:.3f} s ({b - a:.1f} s before the run's start, "
              f"with no GNSS fix to start from)", file=out)
    if st["heading_from"] != "gyrocompass":
        return
    from ins.estimation.core.error_model import NAV
    from ins.nav.rotation import quat_to_euler
    last = result.node_solution()[-1]
    yaw = np.mod(np.rad2deg(quat_to_euler(last[NAV.q_nb])[2]), 360)
    state = "resolved by the gyrocompass" if st["heading_resolved"] else "NOT resolved"
    print(f"heading: {state} (the log never moves): {yaw:.2f} deg, sigma "
          f"{st['heading_std_deg']:.3g} deg (the filter's {st['heading_filter_std_deg']:.3g}); "
          f"positions and level hold, the heading is what the Earth rate and the gyro "
          f"biases allow", file=out)


def summary(result, cfg, paths, t_proc, t_write, out=None):
    """The summary of a run, printed on ``out`` (default: standard output)."""
    c = result.counts
    out = sys.stdout if out is None else out
    if result.gnss_source is not None:
        from ins.estimation.pipeline.gnss_source import source_lines
        shown = next((p for p in paths if os.path.basename(p) == "gnss.pos"), None)
        for line in source_lines(result.gnss_source, shown):
            print(line, file=out)
    print(f"{c['imu_epochs']} IMU epochs, {c['gnss_records']} GNSS records: {c['updates']} "
          f"updates, {c['rejected']} rejected by the innovation test, {c['outside_imu_span']} "
          f"outside the processed span, {c['mount_fallback']} with the static arm (no mount data)",
          file=out)
    systems = "+".join(c.get("systems", ["G"]))
    if c.get("coupling") == "tight" and c.get("base"):
        print(f"tight coupling (double differences against {c['base']}): {systems} "
              f"satellites used per epoch min {c['satellites_min']}, mean "
              f"{c['satellites_mean']:.1f} (the references included, one per system; they "
              f"changed {c['reference_changes']} times; updates and rejections count "
              f"pseudorange and range-rate DDs)", file=out)
        if c.get("carrier_epochs") is not None:
            rate = c.get("fix_rate")
            refix = ", ".join(f"{v:g}" for v in c.get("refix_s", [])) or "none"
            print(f"RTK ({'+'.join(c.get('carriers', ['L1']))} carrier): "
                  f"{c['fixed_epochs']} of {c['carrier_epochs']} carrier epochs fixed "
                  f"({'-' if rate is None else f'{100 * rate:.1f} %'}; LAMBDA, ratio and "
                  f"success rate tests), {c['cycle_slips']} cycle slips; re-fix after "
                  f"each total outage: {refix} s", file=out)
    elif c.get("coupling") == "tight":
        print(f"tight coupling: {systems} satellites used per epoch min "
              f"{c['satellites_min']}, mean {c['satellites_mean']:.1f} (updates and "
              f"rejections count pseudoranges and range rates)", file=out)
        for t, jump in c.get("clock_jumps", []):
            print(f"receiver clock jump at {t:.2f} s: {jump:+.1f} m ({jump / 299792.458:+.4f} "
                  f"ms) common to the pseudoranges; the clock bias set again", file=out)
    rn = c.get("range_noise")
    if rn:
        how = "fitted to a first pass" if rn["mode"] == "auto" else "as configured"
        rob = ", IGG-III down-weighting" if rn["robust"] else ""
        print(f"code/Doppler noise ({how}{rob}): rover {rn['rover_text']}", file=out)
        if rn.get("base_text"):
            print(f"code/Doppler noise: base {rn['base_text']}", file=out)
    for a, b, n, factor in getattr(result.fwd, "recoveries", []):
        print(f"recovery: {n} position fixes in a row rejected from {a:.2f} to {b:.2f} s; "
              f"the navigation covariance inflated x{factor:.3g} and the fix at {b:.2f} s "
              f"taken", file=out)
    for a, b, n, factor in getattr(result.fwd, "reanchors", []):
        print(f"re-anchored: after a GNSS gap {n} mutually consistent fixes rejected from "
              f"{a:.2f} to {b:.2f} s (the INS drifted); the navigation covariance inflated "
              f"x{factor:.3g} and the fix at {b:.2f} s taken", file=out)
    if c.get("gnss_steps"):
        print(f"GNSS steps: {c['gnss_steps']} rejected fixes stepped away from the GNSS "
              f"track itself (the GNSS was wrong there)", file=out)
    q = result.quality
    if q is not None and np.isfinite(q["residual_rms_m"]):
        print(f"solution vs GNSS fixes (antenna): residual RMS {q['residual_rms_m']:.3g} m, "
              f"max {q['residual_max_m']:.3g} m; {q['rejected']} of {q['tested']} "
              f"measurements rejected ({100 * q['rejected_fraction']:.1f} %)", file=out)
    if result.start_check is not None:
        s = result.start_check
        print(f"start: {s['distance_m']:.3g} m from the first GNSS fix (bound "
              f"{s['bound_m']:.4g} m)", file=out)
    if result.alignment is not None:
        al = result.alignment
        from ins.estimation.core.error_model import NAV
        from ins.nav.rotation import quat_to_euler
        first = result.fwd.node_rows_of("node_states", 0, 1)[0]      # the first node
        rpy = np.rad2deg(quat_to_euler(first[NAV.q_nb]))
        print(f"alignment {al.method}: roll {rpy[0]:.4f} pitch {rpy[1]:.4f} yaw "
              f"{np.mod(rpy[2], 360):.4f} deg (stated accuracy {al.att_std_deg[0]:.4f}/"
              f"{al.att_std_deg[1]:.4f}/{al.att_std_deg[2]:.4f} deg)", file=out)
        if result.start_how:
            print(f"alignment: {result.start_how}", file=out)
    _start_lines(result, out)
    ident = getattr(result, "identified", None)
    if ident is not None:
        print(f"IMU noise: {ident.describe()}", file=out)
    print(f"processed in {t_proc:.2f} s, wrote {len(paths)} files in {t_write:.2f} s", file=out)
    if result.errors_smoothed is not None:
        rows = []
        for name, e in (("forward", result.errors_forward),
                        ("smoothed", result.errors_smoothed)):
            p = 1e3 * np.sqrt(np.mean(e.pos_n ** 2, axis=0))
            a = np.sqrt(np.mean(e.att_n ** 2, axis=0)) * 180 / np.pi * 3600
            rows.append((name, (*p, *a)))
        for line in _table("RMS vs truth", ("N mm", "E mm", "D mm", "tiltN as", "tiltE as",
                                            "head as"), rows):
            print(line, file=out)
    for p in paths:
        print(f"  {p}", file=out)
