"""The LiDAR chain on a simulated flight with a laser scanner, as a user would run it, and
how close the points and the recovered boresight come to the simulator's truth.

    simulate (plan with [scanner]) -> process -> georeference -> strip-check
        -> georeference with the calibrated scanner file

Each stage is the real command line (printed before it runs).  The scanner file the
simulator gives the user (``flight/scanner.toml``) has the boresight zero (unknown);
``ins strip-check`` estimates it from the strip overlaps.  The summary compares every
point with its true terrain point (``flight/points_true.csv``, matched by GPS time and
strip): RMS north/east/down and the mean z^2 against the sigmas written in the LAZ, before
and after the calibration, and the boresight against the true one
(``flight/scanner_true.toml``).  Run by ``make demo-lidar``; ``--help`` for the options.
"""
import argparse
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
ARCSEC = np.pi / 180 / 3600


def run(cmd, ok=(0,)):
    """Run one command of the chain; stop the demo with its exit code if it fails."""
    print(f"\n$ {' '.join(shlex.quote(str(c)) for c in cmd)}", flush=True)
    t0 = time.perf_counter()
    code = subprocess.call([str(c) for c in cmd])
    if code not in ok:
        sys.exit(f"demo-lidar: the command above failed (exit code {code})")
    return time.perf_counter() - t0


def point_errors(laz, truth_csv):
    """NED errors (m) of the LAZ points against the true points, the NED sigmas written
    in the file (m, from its sigma_n_m, sigma_e_m, sigma_u_m), the strip and the scan
    angle (deg) of each point; matched by GPS time and strip."""
    import laspy

    from ins.cli.strip_check import read_points_las
    from ins.lidar.georeference import ecef_to_lla
    from ins.nav.earth import dcm_en
    t, xyz, strip = read_points_las(str(laz))
    las = laspy.read(str(laz))
    sig = np.column_stack([np.asarray(las[f"sigma_{a}_m"], float) for a in "neu"])
    angle_deg = np.asarray(las.scan_angle, float) * 0.006
    tru = np.loadtxt(truth_csv, delimiter=",", skiprows=1)
    key_true = np.round(tru[:, 0] * 1e6).astype(np.int64) * 1000 + tru[:, 4].astype(np.int64)
    key = np.round(t * 1e6).astype(np.int64) * 1000 + strip
    order = np.argsort(key_true)
    pos = order[np.searchsorted(key_true, key, sorter=order)]
    if not np.array_equal(key_true[pos], key):
        raise SystemExit("demo-lidar: points without a true point (time, strip)")
    lla = ecef_to_lla(xyz)
    d = np.einsum("nji,nj->ni", dcm_en(lla[:, 0], lla[:, 1]), xyz - tru[pos, 1:4])
    return d, sig, strip, angle_deg


def error_lines(name, d, sig):
    rms = np.sqrt(np.mean(d ** 2, axis=0)) * 1000
    z2 = np.mean((d / sig) ** 2, axis=0)
    med = np.median(sig, axis=0) * 1000
    return (f"| {name} | {rms[0]:.1f} / {rms[1]:.1f} / {rms[2]:.1f} | "
            + " / ".join(f"{v:.1f}" for v in med) + " | "
            + " / ".join(f"{v:.2f}" for v in z2) + " |")


def plot_errors(path, before, after, n_max=6000):
    """Point errors N, E, D (mm) against the scan angle, with the boresight as given and
    calibrated; the stated 1-sigma of each axis as a band of the points' median per
    degree."""
    from ins.common.plotstyle import pyplot, save_png
    plt = pyplot()
    fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    for col, (name, (d, sig, strip, angle)) in enumerate(
            (("boresight 0 (as given)", before), ("calibrated boresight", after))):
        k = np.random.default_rng(0).choice(len(d), min(n_max, len(d)), replace=False)
        bins = np.round(angle).astype(int)
        centres = np.unique(bins)
        for row, axis in enumerate("NED"):
            ax = axes[row, col]
            for s in np.unique(strip):
                m = k[strip[k] == s]
                ax.plot(angle[m], d[m, row] * 1e3, ".", ms=1.5, label=f"strip {s}")
            band = np.array([np.median(sig[bins == c, row]) for c in centres]) * 1e3
            ax.fill_between(centres, -band, band, color="0.5", alpha=0.3,
                            label="stated 1 sigma")
            ax.axhline(0, color="k", lw=0.5)
            ax.set_ylabel(f"{axis} error (mm)")
            if row == 0:
                ax.set_title(name)
            if row == 2:
                ax.set_xlabel("scan angle (deg, + right of the flight)")
        axes[0, col].legend(fontsize=7, markerscale=5, loc="upper right")
    fig.suptitle("LiDAR points against the simulator's true terrain points")
    save_png(fig, path)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--plan", default=ROOT / "data" / "flights" / "lidar_demo.toml", type=Path)
    p.add_argument("--out", default=ROOT / "demo-lidar-output", type=Path)
    p.add_argument("--seed", default=1, type=int)
    args = p.parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    flight, proc = out / "flight", out / "process"
    ins = BIN / "ins"
    t_start = time.perf_counter()
    times = {}
    print("== 1. simulate the flight with its laser scanner: truth, IMU, GNSS, returns, "
          "scanner file (boresight unknown), true points")
    times["simulate"] = run([ins, "simulate", args.plan, "-o", flight, "--seed", args.seed,
                             "--force", "-q"])
    print("\n== 2. GNSS/INS post-processing (smoothed trajectory and its sigmas)")
    times["process"] = run([ins, "process", flight, "-o", proc, "--force", "--no-plots",
                            "-q"])
    traj = ["--trajectory", proc / "solution.nav", "--trajectory-std",
            proc / "solution_std.txt"]
    print("\n== 3. georeference the returns with the scanner file as given (boresight 0)")
    times["georeference"] = run([ins, "georeference", flight / "returns.csv", *traj,
                                 "--scanner", flight / "scanner.toml", "-q",
                                 "-o", out / "points.laz"])
    print("\n== 4. strip overlaps -> scanner boresight")
    calibrated = out / "scanner_calibrated.toml"
    times["strip-check"] = run([ins, "strip-check", out / "points.laz", *traj,
                                "--scanner", flight / "scanner.toml", "--scanner-out",
                                calibrated])
    print("\n== 5. georeference again with the calibrated scanner file")
    times["georeference 2"] = run([ins, "georeference", flight / "returns.csv", *traj,
                                   "--scanner", calibrated, "-q",
                                   "-o", out / "points_calibrated.laz"])
    print("\n== 6. against the simulator's truth")
    figures = summarize(out, flight)
    total = time.perf_counter() - t_start
    print(f"\nWall time {total:.1f} s ("
          + ", ".join(f"{k} {v:.1f} s" for k, v in times.items()) + ")")
    return figures


def summarize(out, flight):
    from ins.lidar.scanner import read_scanner
    truth_csv = flight / "points_true.csv"
    before = point_errors(out / "points.laz", truth_csv)
    after = point_errors(out / "points_calibrated.laz", truth_csv)
    print("| points | RMS N / E / D (mm) | median sigma N / E / D (mm) | mean z^2 N / E / D |")
    print("|---|---|---|---|")
    print(error_lines("boresight 0 (as given)", *before[:2]))
    print(error_lines("calibrated boresight", *after[:2]))
    true = read_scanner(flight / "scanner_true.toml")
    cal = read_scanner(out / "scanner_calibrated.toml")
    est, sig, tru = (cal.boresight_rad / ARCSEC, cal.boresight_sigma_rad / ARCSEC,
                     true.boresight_rad / ARCSEC)
    print("\n| boresight (arcsec) | rx | ry | rz |")
    print("|---|---|---|---|")
    print("| true | " + " | ".join(f"{v:.1f}" for v in tru) + " |")
    print("| estimated +- sigma | " + " | ".join(f"{v:.1f} +- {s:.1f}"
                                               for v, s in zip(est, sig)) + " |")
    print("| (estimated - true) / sigma | " + " | ".join(
        f"{v:+.2f}" for v in (est - tru) / sig) + " |")
    plot_errors(out / "point_errors.png", before, after)
    print(f"\nplot: {out / 'point_errors.png'}")
    return {"before": before, "after": after, "boresight_arcsec": est,
            "boresight_sigma_arcsec": sig, "boresight_true_arcsec": tru}


if __name__ == "__main__":
    main()
