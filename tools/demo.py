"""The whole chain on the embedded flight plan, as a user would run it, and how close
each stage comes to the simulator's truth.

    simulate -> process (filter + smoother, varying lever arm) -> EO -> refine

Each stage is the real command line (printed before it runs); the summary table and
``OUT/report.md`` (with PNG plots) compare every stage with the truth the simulator
wrote.  The camera file given to ``photogrammetry eo`` is the simulator's with the
boresight set to zero: the boresight is unknown to the user, and the coplanarity
adjustment estimates it.

Run by ``make demo``; ``python tools/demo.py --help`` for the options.
"""
import argparse
import shlex
import subprocess
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
ARCSEC = np.pi / 180 / 3600


def run(cmd):
    """Run one command of the chain; stop the demo with its exit code if it fails."""
    shown = " ".join(shlex.quote(str(c)) for c in cmd)
    print(f"\n$ {shown}", flush=True)
    t0 = time.perf_counter()
    code = subprocess.call([str(c) for c in cmd])
    if code:
        sys.exit(f"demo: the command above failed (exit code {code})")
    return time.perf_counter() - t0


def uncalibrated_camera(flight, out_path):
    """The flight's camera file with the boresight set to zero (what a user knows)."""
    from photogrammetry.orientation.camera import read_camera, write_camera
    camera, mounting = read_camera(flight / "camera.toml")
    write_camera(out_path, camera, replace(mounting, boresight_rad=np.zeros(3)))
    return camera, mounting


def rms(x, axis=0):
    return np.sqrt(np.mean(np.square(x), axis=axis))


def angle_errors(eo, truth):
    """Per-image angle errors (rad) of ``eo`` against ``truth`` as a rotation vector of
    ``C_mc_eo C_mc_true^T`` in the mapping frame, and the per-angle differences."""
    from ins.nav.rotation import dcm_to_rotvec, wrap_to_pi
    idx = [truth.image_id.index(i) for i in eo.image_id]
    t = truth.in_system(eo.system)
    R_true = t.matrices()[idx]
    rotvec = dcm_to_rotvec(np.einsum("nij,nkj->nik", eo.matrices(), R_true))
    return rotvec, wrap_to_pi(eo.angles - t.angles[idx]), idx


def trajectory_figures(nav, truth_nav):
    from ins.io.navfiles import read_nav
    from ins.nav.accuracy import compare
    err = compare(read_nav(nav), truth_nav)
    return {"pos_cm": rms(err.pos_n) * 100, "att_as": rms(err.att_n) / ARCSEC, "err": err}


def refine_figures(out, flight, camera, eo_ins, method, datum, accept_poor=False):
    """The assessment of the refinement (the same computation as the CLI's report)."""
    from photogrammetry.adjustment.batch import refine
    from photogrammetry.imagery.tiepoints import read_tiepoints
    tie = read_tiepoints(flight / "tiepoints.csv", camera=camera)
    with warnings.catch_warnings():      # the command above has already shown them
        warnings.simplefilter("ignore")
        return refine(eo_ins, tie, camera=camera, method=method, datum=datum,
                      accept_poor=accept_poor)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--plan", default=ROOT / "data" / "flights" / "demo.toml", type=Path)
    p.add_argument("--out", default=ROOT / "demo-output", type=Path)
    p.add_argument("--seed", default=1, type=int)
    p.add_argument("--method", default="known-base",
                   choices=["known-base", "relative", "base-free"])
    p.add_argument("--datum", default="none", choices=["none", "first", "ins"])
    p.add_argument("--accept-poor", action="store_true",
                   help="pass --accept-poor to refine (write a flagged refinement)")
    args = p.parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    flight, proc = out / "flight", out / "process"
    ins, pg = BIN / "ins", BIN / "photogrammetry"
    t_start = time.perf_counter()
    times = {}

    print("== 1. simulate the survey flight: truth, IMU with sensor errors, GNSS antenna, "
          "mount angles, exposures, tie points")
    times["simulate"] = run([ins, "simulate", args.plan, "-o", flight, "--seed", args.seed,
                             "--force"])
    print("\n== 2. GNSS/INS post-processing: forward filter + RTS smoother, varying lever arm")
    times["process"] = run([ins, "process", flight, "-o", proc, "--forward",
                            "--force"])

    print("\n== 3. exterior orientation per exposure from the smoothed trajectory "
          "(camera file without the boresight, which is unknown)")
    cam_file = out / "camera_uncalibrated.toml"
    camera, mounting = uncalibrated_camera(flight, cam_file)
    eo_ins_file = out / "eo_ins.csv"
    times["eo"] = run([pg, "eo", flight, "--trajectory", proc / "solution.nav",
                       "--sigma", proc / "solution_std.txt", "--camera", cam_file,
                       "-o", eo_ins_file])

    print("\n== 4. coplanarity refinement of the angles, INS assessment, boresight")
    refined_file = out / "eo_refined.csv"
    times["refine"] = run([pg, "refine", eo_ins_file, flight / "tiepoints.csv", "--camera",
                           cam_file, "--method", args.method, "--datum", args.datum,
                           "-o", refined_file, "--report", out / "refine_report.md"]
                          + (["--accept-poor"] if args.accept_poor else []))

    print("\n== 5. every stage against the simulator's truth")
    summary, figures = summarize(out, flight, proc, camera, mounting, eo_ins_file,
                                 refined_file, args.method, args.datum, args.accept_poor)
    total = time.perf_counter() - t_start
    timing = ", ".join(f"{k} {v:.1f} s" for k, v in times.items())
    summary.append("")
    summary.append(f"Wall time {total:.1f} s ({timing}).")
    text = "\n".join(summary)
    print(text)
    write_report(out, text)
    print(f"\nreport: {out / 'report.md'}")
    return figures


def summarize(out, flight, proc, camera, mounting, eo_ins_file, refined_file, method, datum,
              accept_poor=False):
    from ins.io.navfiles import read_nav
    from photogrammetry.orientation.exposure import read_eo_csv
    from photogrammetry.orientation.rotation import matrix_to_angles
    truth_nav = read_nav(flight / "truth.nav")
    fwd = trajectory_figures(proc / "forward.nav", truth_nav)
    smo = trajectory_figures(proc / "solution.nav", truth_nav)
    eo_true = read_eo_csv(flight / "eo_true.csv")
    eo_ins = read_eo_csv(eo_ins_file)
    eo_ref = read_eo_csv(refined_file)
    _, d_ins, idx = angle_errors(eo_ins, eo_true)
    _, d_ref, _ = angle_errors(eo_ref, eo_true)
    dpos = eo_ins.position - eo_true.position[idx]
    res = refine_figures(out, flight, camera, eo_ins, method, datum, accept_poor)
    a = res.assessment
    names = eo_ins.system.split("-")
    b_true = np.asarray(mounting.boresight_rad)
    # What any boresight calibration sees: the rotation that takes the INS camera attitude
    # (no boresight) onto the true one, per exposure, as rx, ry, rz of the camera file.
    # It is the simulated boresight plus the INS attitude error expressed in the camera
    # frame; its body-fixed part (e.g. from the IMU's uncalibrated axis misalignment,
    # which levels the platform wrongly) cannot be told from a boresight by any method.
    t_idx = eo_true.in_system(eo_ins.system)
    C_rel = np.einsum("nji,njk->nik", eo_ins.matrices(), t_idx.matrices()[idx])
    apparent = matrix_to_angles(C_rel, "omega-phi-kappa")          # Rx Ry Rz angles
    b_apparent = apparent.mean(axis=0)
    # the truth of the INS-noise estimate: the scatter of that error about its mean, in
    # the order of the angle system (near nadir phi ~ a rotation about camera y, omega
    # ~ about camera x; phi-omega-kappa's Ry(-phi) turns the other way round y, which
    # changes the sign of the error, not its scatter: a reordering, no sign, is right here)
    order = [1, 0, 2] if eo_ins.system == "phi-omega-kappa" else [0, 1, 2]
    noise_true = apparent.std(axis=0, ddof=1)[order]

    # the boresight's sigma with the INS attitude's common error over the exposures (as
    # photogrammetry refine states it in its report and CSV: the EO file names the
    # trajectory's sigma file)
    from photogrammetry.orientation.boresight_sigma import boresight_sigma
    from photogrammetry.orientation.exposure import read_solution_std
    bs = boresight_sigma(a.boresight_sigma, read_solution_std(proc / "solution_std.txt"),
                         eo_ins.time, mounting.axes)
    b_sigma_total = bs.total

    def row(label, values, unit, fmt="{:9.1f}"):
        return f"| {label} | " + " | ".join(fmt.format(v) for v in values) + f" | {unit} |"

    n = len(eo_ins)
    e = smo["err"]
    during = (e.time >= eo_true.time.min()) & (e.time <= eo_true.time.max())
    strips_as = rms(e.att_n[during]) / ARCSEC
    lines = [
        "| stage | 1 | 2 | 3 | unit |", "|---|---:|---:|---:|---|",
        row("trajectory, forward filter: position RMS N/E/D", fwd["pos_cm"], "cm", "{:9.2f}"),
        row("trajectory, forward filter: attitude RMS N/E/D (tilt, heading)", fwd["att_as"],
            "arcsec"),
        row("trajectory, smoothed: position RMS N/E/D", smo["pos_cm"], "cm", "{:9.2f}"),
        row("trajectory, smoothed: attitude RMS N/E/D (tilt, heading)", smo["att_as"],
            "arcsec"),
        row("trajectory, smoothed, first to last exposure (strips and turns; the "
            "straight in-air start left out): attitude RMS N/E/D", strips_as, "arcsec"),
        row(f"EO from the INS ({n} images): perspective centre RMS X/Y/Z",
            rms(dpos) * 100, "cm", "{:9.2f}"),
        row(f"EO from the INS: {'/'.join(names)} RMS (boresight unknown)",
            rms(d_ins) / ARCSEC, "arcsec"),
        row(f"EO refined ({method}, datum {datum}): {'/'.join(names)} RMS",
            rms(d_ref) / ARCSEC, "arcsec"),
        row("boresight rx/ry/rz: simulated", b_true / ARCSEC, "arcsec"),
        row("boresight rx/ry/rz: simulated + INS attitude error in the camera frame "
            "(mean; what a calibration can see)", b_apparent / ARCSEC, "arcsec"),
        row("boresight rx/ry/rz: estimated by the refinement", a.boresight / ARCSEC,
            "arcsec"),
        row("boresight rx/ry/rz: sigma, adjustment alone", bs.adjustment / ARCSEC,
            "arcsec"),
        row("boresight rx/ry/rz: sigma, INS attitude common to the exposures (smoothed "
            "sigma, camera frame, fully correlated: an upper bound)", bs.ins_common / ARCSEC,
            "arcsec"),
        row("boresight rx/ry/rz: sigma, total (as refine's report and CSV state it)",
            b_sigma_total / ARCSEC, "arcsec"),
        row("boresight rx/ry/rz: (estimated - simulated) / adjustment sigma",
            (a.boresight - b_true) / bs.adjustment, "", "{:9.2f}"),
        row("boresight rx/ry/rz: (estimated - simulated) / total sigma",
            (a.boresight - b_true) / b_sigma_total, "", "{:9.2f}"),
        *misalignment_rows(flight, proc, row),
        row(f"INS angle noise {'/'.join(names)}: estimated by the refinement",
            a.ins_noise / ARCSEC, "arcsec"),
        row(f"INS angle noise {'/'.join(names)}: true (scatter of the INS camera attitude "
            "error)", noise_true / ARCSEC, "arcsec"),
    ]
    plot_angles(out, eo_ins, d_ins, d_ref, names)
    figures = {"forward_pos_m": fwd["pos_cm"] / 100, "smoothed_pos_m": smo["pos_cm"] / 100,
               "smoothed_att_rad": smo["att_as"] * ARCSEC,
               "smoothed_att_strips_rad": strips_as * ARCSEC, "eo_pos_m": rms(dpos),
               "ins_angles_rad": rms(d_ins), "refined_angles_rad": rms(d_ref),
               "boresight_true_rad": b_true, "boresight_apparent_rad": b_apparent,
               "ins_noise_rad": a.ins_noise, "ins_noise_true_rad": noise_true,
               "boresight_rad": a.boresight, "boresight_sigma_rad": a.boresight_sigma,
               "boresight_sigma_with_ins_rad": b_sigma_total,
               "boresight_sigma_ins_rad": bs.ins_common,
               "misalignment": misalignment_figures(flight, proc)}
    return lines, figures


def misalignment_figures(flight, proc):
    """Injected and estimated IMU non-orthogonality (arcsec), with the smoothed sigma at
    the end of the flight: ``{group: (injected, estimate, sigma)}`` for the groups in
    ``states.txt`` (empty without it)."""
    import tomllib
    path = proc / "states.txt"
    if not path.is_file():
        return {}
    header = path.read_text().splitlines()[0].split()[1:]
    last = np.loadtxt(path, ndmin=2)[-1]
    man = tomllib.loads((flight / "manifest.toml").read_text())
    out = {}
    for group in ("gyro_misalignment", "accel_misalignment"):
        cols = [f"{group}_{a}_arcsec" for a in "xyz"]
        if cols[0] not in header:
            continue
        est = np.array([last[header.index(c)] for c in cols])
        sd = np.array([last[header.index("std_" + c)] for c in cols])
        injected = np.asarray(man["imu"].get(f"{group}_arcsec", [0.0] * 3), dtype=float)
        out[group] = (injected, est, sd)
    return out


def misalignment_rows(flight, proc, row):
    """Table rows: the injected and estimated non-orthogonality, sigma and the ratio."""
    lines = []
    for group, (inj, est, sd) in misalignment_figures(flight, proc).items():
        name = group.replace("_", " ")
        lines += [row(f"IMU {name} x/y/z: injected", inj, "arcsec"),
                  row(f"IMU {name} x/y/z: estimated (smoothed)",
                      est, "arcsec"),
                  row(f"IMU {name} x/y/z: sigma", sd, "arcsec"),
                  row(f"IMU {name} x/y/z: (estimated - injected) / sigma", (est - inj) / sd,
                      "", "{:9.2f}")]
    return lines


def plot_angles(out, eo, d_ins, d_ref, names):
    """Exposure angle errors against the truth (arcsec) per image, strips marked."""
    from ins.common.plotstyle import (
        exposure_axis,
        legend_right,
        mark_strips,
        pyplot,
        save_png,
        strip_starts,
        with_gaps,
    )
    plt = pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(10, 7.5), sharex=True)
    x, xlabel, origin = exposure_axis(eo.time)
    starts = strip_starts(list(eo.image_id), heading_rad=eo.angles[:, 2])
    for k, ax in enumerate(axes):
        ins_as, ref_as = d_ins[:, k] / ARCSEC, d_ref[:, k] / ARCSEC
        ax.plot(*with_gaps(x, ins_as, starts), "o-", ms=3,
                label=f"INS EO (no boresight)\nRMS {np.sqrt(np.mean(ins_as ** 2)):.0f} arcsec")
        ax.plot(*with_gaps(x, ref_as, starts), "s-", ms=3,
                label=f"refined\nRMS {np.sqrt(np.mean(ref_as ** 2)):.0f} arcsec")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel(f"{names[k]} error, arcsec")
        ax.grid(alpha=0.3)
        legend_right(ax)
    mark_strips(axes, starts, len(x), x=x)
    axes[-1].set_xlabel(f"{xlabel}; dashed lines: strip boundaries")
    fig.suptitle("Exposure angles minus the truth, before and after the refinement"
                 + (f"\n{origin}" if origin else ""), fontsize=11)
    fig.tight_layout()
    save_png(fig, str(out / "angles.png"))


def write_report(out, table):
    from ins.common.fileio import atomic_open
    text = f"""# Demo: the whole chain against the simulator's truth

Flight: `flight/` (`ins simulate`, plan `data/flights/demo.toml`); processing:
`process/` (`ins process`); exterior orientation from the smoothed trajectory:
`eo_ins.csv` (`photogrammetry eo`, camera file without the boresight); refinement:
`eo_refined.csv` and `refine_report.md` (`photogrammetry refine`).

Attitude errors of the trajectory are the rotation vector of `C_nb_est C_nb_true^T`
in NED (north and east tilt, heading); angle errors of the EO are per angle in the
named system (arcsec).

{table}

![trajectory errors](process/errors.png)

![exposure angles before and after refinement](angles.png)

![residuals in the image](refine_report_residuals.png)
"""
    with atomic_open(out / "report.md", "w") as f:
        f.write(text)


if __name__ == "__main__":
    main()
