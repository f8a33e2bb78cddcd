"""Block scale: refine + assess time and peak memory against the number of images; and
``photogrammetry refine`` as a user runs it, CPU time per stage (``--cli``).

    .venv/bin/python bench/bench_block_scale.py [--sizes 50,200,1000,5000]
        [--method known-base,relative,base-free] [--datum auto]
    .venv/bin/python bench/bench_block_scale.py --cli 470,1000 [--method base-free]

``--cli``: per size, in a fresh process, the block as files (EO CSV, tie points CSV,
camera TOML), then the command with its defaults (base-free, datum first) and
``--report`` (Markdown, residual and correction plots), each stage's CPU time
(``getrusage``; inclusive, the indented ones within the stage above), the peak resident
memory and the refined angles (``--save F.json``: to compare two versions).  The block
(``--block sim``, default): the demo chain on a plan derived from
``data/flights/demo.toml`` with ``round(N / 47)`` strips of 7.5 km (10 strips: 470
images, 21: 987), ``ins simulate`` (its own tie points), ``ins process --forward``,
``photogrammetry eo`` with the camera file less its boresight, as ``tools/demo.py``
runs them (``--block-dir D`` keeps the flights for the next run).  Measured (2-core VM
shared with other jobs, load 5-6, 2026-12-02, the three runs one after the other; CPU s):

    stage                                    470 images      987 images     before
                                           SuperLU CHOLMOD SuperLU CHOLMOD  470    987
    start-up (imports, compiled kernels)     0.91   1.14    0.88   0.99    1.14   0.89
    read inputs (EO, tie points, camera)     0.33   0.36    0.45   0.60    0.32   0.51
      tie-point assembly (pairs)             0.18   0.17    0.37   0.38    0.14   0.35
    block adjustment                         4.24   3.81   10.69   9.65    5.12  13.10
      pair screening (MSAC)                  0.68   0.72    1.30   1.47    0.71   1.40
      conditions                             0.11   0.12    0.24   0.22    0.13   0.29
      normal equations (J'WJ)                1.66   1.83    3.33   3.71    2.51   5.98
        joint weights                        0.69   0.72    1.37   1.50    0.72   1.65
      factor + solve                         1.29   0.77    3.28   1.87    1.28   3.50
      sigmas (covariance blocks)             0.45   0.32    2.44   2.30    0.43   1.80
    accuracy: INS assessment (REML)          1.00   0.99    6.99   7.22    8.37  22.36
    report                                   1.16   1.15    1.37   1.15    1.04   1.20
      residuals plot (with the import)       0.88   0.85    0.93   0.82    0.79   0.91
    total CPU                                7.87   7.68   20.85  20.06   16.19  38.48
    per image above start-up, ms             14.8   13.9    20.2   19.3    32.0   38.1
    peak resident memory, MB                  360    340     770    716     377    682

("Before": the same script on the code before this change (a second session of
2026-12-02), right before, same load; the session before had measured 35.2 and 44.3 ms
at load 6-7, 222 and 81 ms before it.  CHOLMOD: with the optional extra ``fast``
(cvxopt), :mod:`photogrammetry.adjustment.cholmod`.)  The refined angles are the same
to the bit with SuperLU (the block's result in rad and the refined CSV, both sizes);
with CHOLMOD within 3e-15 rad (one 1e-10 deg digit of the CSV at 987).  Sigmas within
3e-10 (470) and 1.2e-9 (987) relative: the dense inverse in place of the selected
inverse; the assessment's figures within 2e-10 and 1.4e-9 relative (the same REML
iterations; kappa noise 22.46 and 28.67 arcsec, lambda 1.248 and 1.283, the other
noises not estimable, as before).
What changed: the assessment works on the block's covariance as a dense matrix
(``BandedCovariance.C``, up to
:data:`photogrammetry.adjustment.block_covariance.DENSE_MAX_ANGLES` angles): the
reduced normal matrix ``H_aa - H_ab H_bb^-1 H_ba`` by a sparse half solve of the bases'
factor (compiled: ``lower_solve_sparse``, ``gram_rows``), inverted once by LAPACK, and
per REML evaluation a dense Cholesky of ``V`` (1407 angles: 0.035 s, where the sparse
augmented system took 0.2 s to factor and 0.07 s to solve the probes; the same 20
evaluations); its diagonal blocks are the sigmas (no selected inverse).  The block:
the condition terms in one compiled pass (30 -> 2 ms an iteration), ``J'`` as CSR
times ``W J`` (scipy converted ``W J`` to CSC and back: 45 ms an iteration), the CSR
structures of ``W`` and ``J`` made once per set of conditions.  What is left: 12
Gauss-Newton iterations of joint weights (a 15 x 15 eigh per point seen in six images)
and sparse products, SuperLU's 12 factorizations (0.1 s each; CHOLMOD 0.04 s), and at
987 images the dense algebra's ``n^3`` (2961 angles: 0.3 s a Cholesky, 25 of them; the
inverse 1.4 s), still three times cheaper than the sparse augmented system there.

``--block scenario``: ``tests/scenario.py``'s ``make_large_block`` (below).  Measured
(2-core VM shared with 6 other jobs, load 2-5, 2026-11-27; kernels then numba, cache warm):

    stage                                    470 images  1000 images   (before)
    start-up (imports, compiled kernels)           0.82         0.68     0.60
    read inputs (EO, tie points, camera)           0.13         0.28     0.25
    block adjustment                               1.65         6.88     8.96
      pair screening (MSAC)                        0.44         0.73     0.83
      linearize (weights, J'WJ)                    0.65         2.53     3.82
        joint weights                              0.16         0.64     1.59
      factor + solve                               0.35         2.30     3.00
      sigmas (selected inverse)                    0.16         1.11     1.10
    INS assessment (REML)                          0.87         3.95     5.49
    write refined CSV                              0.01         0.01     0.02
    report                                         0.87         1.22     1.48
      import matplotlib                            0.38         0.39     0.45
      residuals plot (with the import)             0.68         0.85     1.23
      corrections plot                             0.18         0.33     0.22
    total CPU                                      4.43        13.19    16.97
    per image above start-up, ms                    7.7         12.5     16.4

"Before": the same script on the code before 2026-11-27 (third session).  The savings:
the sparse factor's minimum-degree ordering found once per pattern, the assessment's
factor of V reused when asked for the same V (12 -> 9 factorizations), Gauss-Newton
stopped when the next step is predicted below tol (12 -> 9 joint iterations), the joint
weights compiled, the residual plot's markers without edges.  With a COLD numba cache
(the first run after an install or a change of the kernels) the pair screening
compiled its kernels: 23 s more at any size (470 images: 29.3 s total), which is what
a first run measured as start-up.  Since issue 35 the kernels are Cython, built at
install: the first run is the same as the next.

Each size runs in a fresh process (its peak resident memory is its own): a simulated
block (``tests/scenario.py``'s ``make_large_block``: strips of 50 images, 60 % forward and
30 % side overlap, ~40 tie points per image seen in up to 6 images, 0.5 px noise, INS
noise 0.005 rad, boresight (0.002, -0.003, 0.004) rad), then
``photogrammetry.adjustment.block.adjust_block`` (each method of ``--method``; datum ``auto``: none
for known-base, first for relative and base-free; tie-point ids: joint weights; banded
algebra from 100 images) and ``photogrammetry.adjustment.assessment.assess``.  Relative and
base-free blocks carry two base-direction unknowns per pair: their normal matrix is
factored whole (bordered) as a sparse ``L D L'`` (SuperLU, minimum degree, diagonal
pivots) for the steps, the solves and, by selected inversion, the covariance blocks.  BLAS
is held to one thread (the machine is shared; threads contend).  Prints one row per size
and the slope of log(time) and log(memory) against log(images).

Measured (2 cores, the machine otherwise quiet, 2026-11-24, this script as committed;
``cpu_s`` is the process's CPU time, which a loaded machine does not inflate):

    method      images  pairs  adjust_s  assess_s  total_s  cpu_s  peak_MB   factor
    known-base      50     69      0.26      0.04     0.30    0.3      216    dense
    known-base     200    659      0.45      0.04     0.48    0.5      227     b=44
    known-base     500   1845      0.82      0.08     0.91    0.9      252    b=116
    known-base    1000   3920      1.62      0.27     1.89    1.9      298    b=236
    known-base    2000   8020      3.68      0.70     4.37    4.4      402    b=296
    known-base    5000  20447      9.42      2.99    12.41   12.4      674    b=302
    known-base   10000  40985     23.87      6.94    30.80   30.8     1052    b=302
    base-free       50     69      0.29      0.09     0.38    0.4      216    dense
    base-free      200    659      0.53      0.23     0.76    0.8      240  L=0.12M
    base-free      500   1845      1.37      0.93     2.30    2.3      307  L=0.59M
    base-free     1000   3920      4.97      3.23     8.20    8.2      479  L=1.68M
    base-free     2000   8020     11.25      7.07    18.32   18.3      777  L=4.01M
    base-free     5000  20447     41.68     42.56    84.23   84.0     1747 L=11.52M
    base-free    10000  40985     97.42    115.45   212.87  199.4     3245 L=23.64M
    relative      1000   3920      4.96      3.24     8.20    8.2      466  L=1.68M
    slope of log(total time) vs log(images), 1000-5000: known-base 1.17, base-free 1.46;
    of log(peak memory): 0.51, 0.81; 5000-10000 (CPU): known-base 1.31, base-free 1.25

(sigma0 0.975-0.998; known-base boresight errors within 1.14 of their sigmas; relative
methods: boresight not observable.)  ``factor``: ``b`` the half-bandwidth of the banded
Cholesky factor (known-base), ``L`` the non-zeros of the sparse ``L D L'`` factor of the
bordered normal matrix (relative methods).  The same script before the changes of
2026-11-24 (second session), on a machine shared with 5 other jobs, gave known-base
8.1 s at 1000 and 83 s at 5000 images (the
assessment's REML refactored the covariance for every iterate of every boresight round,
and ran away on a free covariance factor the data could not tell), base-free 27.9 s and
0.75 GB at 1000 (covariance blocks by Takahashi on a banded factor of half-bandwidth
954, 81 factorizations in the assessment; now selected inversion of the sparse factor,
0.6 s, and 12 factorizations).  The relative methods' cost grows faster than the images:
the joint weights of a tie point couple the bases of all its pairs, so the sparse
factor's fill per image grows with the block's width in strips until it reaches the
strips' length (here 50 images: 1680, 2005, 2304, 2364 non-zeros per image at 20, 40,
100, 200 strips: it levels off, and so does the slope), and at 5000 images the data let the assessment try a free covariance factor
(9 more factorizations; ``photogrammetry.adjustment.assessment.LAMBDA_TRY_REL``).  Larger relative
blocks: ``photogrammetry refine --tile-images`` with ``--datum ins``
(``bench/bench_block_tiles.py``: one 10 000-image block in tiles on Dask).

Dask (``--dask 10x1000``: ten separate 1000-image flights written as files, read, and
refined as tasks by ``refine_many`` on a local cluster of 2 single-threaded worker
processes): 10 000 images in 173.6 s (the machine shared with 5 other jobs, first
session of 2026-11-24), peak resident memory per worker 502 and 562 MB as read from
``ru_maxrss``, which in a Dask worker includes the driver's memory when the worker was
forked (``bench_block_tiles.py`` reads ``VmHWM`` instead).

(50 images: dense algebra; the issue's 945-image block took 203 s and 1.24 GB, 216 s of
it in the dense assessment.)
"""
import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def one(n, method, datum):
    """Run one size in this process; returns a dict of figures."""
    import resource
    import time

    import numpy as np
    sys.path.insert(0, str(HERE.parent / "tests"))
    import scenario as sc

    from photogrammetry.adjustment.assessment import assess
    from photogrammetry.adjustment.block import adjust_block
    B = sc.make_large_block(n, seed=1)
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    t0 = time.perf_counter()
    res = adjust_block(B["prior"], B["pairs"], B["pair_points"], B["f_mm"], B["system"],
                       method, datum, positions=B["positions"], sigma_mm=B["sigma_mm"],
                       point_ids=B["point_ids"])
    t1 = time.perf_counter()
    a = assess(res, B["prior"], B["system"], datum, method)
    t2 = time.perf_counter()
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    f = res.cov_op.factor if res.cov_op is not None else None
    err = (a.boresight - B["boresight"]) / np.where(a.boresight_sigma > 0,
                                                   a.boresight_sigma, np.nan)
    return {"images": n, "pairs": len(B["pairs"]), "adjust_s": t1 - t0, "assess_s": t2 - t1,
            "peak_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "cpu_s": r1.ru_utime + r1.ru_stime - r0.ru_utime - r0.ru_stime,
            "factor": ("dense" if f is None else f"b={f.b}" if hasattr(f, "b")
                       else f"L={f.nnz / 1e6:.2f}M" if hasattr(f, "nnz") else "CHOLMOD"),
            "sigma0": res.sigma0, "boresight_err_sigmas": np.round(err, 2).tolist(),
            "ins_noise_arcsec": np.round(a.ins_noise * 206264.8, 1).tolist()}


#: (module, attribute, class or None, label) of the stages of ``photogrammetry refine``
#: timed by :func:`cli_stages`; labels indented under the stage that calls them.
CLI_STAGES = [
    ("photogrammetry.cli.refine", "_task", None, "read inputs (EO, tie points, camera)"),
    ("photogrammetry.imagery.tiepoints", "pairs", "TiePoints", "  tie-point assembly (pairs)"),
    ("photogrammetry.adjustment.batch", "adjust_block", None, "block adjustment"),
    ("photogrammetry.adjustment.block", "_screen_pairs", None, "  pair screening (MSAC)"),
    ("photogrammetry.adjustment.block", "_conditions", None, "  conditions"),
    ("photogrammetry.adjustment.block", "_linearize", None, "  normal equations (J'WJ)"),
    ("photogrammetry.adjustment.block", "_joint_weights", None, "    joint weights"),
    ("photogrammetry.adjustment.block", "_solve_step", None, "  factor + solve"),
    ("photogrammetry.adjustment.block", "banded_covariance", None, "  sigmas (covariance blocks)"),
    ("photogrammetry.adjustment.batch", "assess", None, "accuracy: INS assessment (REML)"),
    ("photogrammetry.orientation.exposure", "write_eo_csv", None, "write refined CSV"),
    ("photogrammetry.adjustment.report", "write_report", None, "report"),
    ("ins.common.plotstyle", "pyplot", None, "  import matplotlib"),
    ("photogrammetry.adjustment.report", "_plot_residuals", None, "  residuals plot"),
    ("photogrammetry.adjustment.report", "_plot_corrections", None, "  corrections plot"),
    ("photogrammetry.adjustment.report", "report_text", None, "  report text"),
]

#: The flight plan whose strips ``--block sim`` lengthens and multiplies.
DEMO_PLAN = HERE.parent / "data" / "flights" / "demo.toml"
#: Strip length (m) of ``--block sim``; 47 images a strip (demo camera, 60 % forward).
SIM_STRIP_M = 7500.0
SIM_IMAGES_PER_STRIP = 47


def sim_block_files(n, folder):
    """The demo chain on a longer flight: a plan derived from ``data/flights/demo.toml``
    with strips of :data:`SIM_STRIP_M` and ``round(n / 47)`` of them (10 strips: 470
    images), then ``ins simulate`` (its own tie points), ``ins process --forward`` and
    ``photogrammetry eo`` with the camera file without its boresight, as ``tools/demo.py``
    runs them.  Files are kept in `folder` and reused when present (the chain takes about
    20 s at 470 images).  Returns the paths of the EO, tie-point and camera files."""
    import re
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    eo, tp, cam = folder / "eo_ins.csv", folder / "flight" / "tiepoints.csv", folder / "camera.toml"
    if eo.exists() and tp.exists() and cam.exists():
        return str(eo), str(tp), str(cam)
    strips = max(1, round(n / SIM_IMAGES_PER_STRIP))
    plan = DEMO_PLAN.read_text()
    plan = re.sub(r"(?m)^strip_length_m = .*$", f"strip_length_m = {SIM_STRIP_M}", plan)
    plan = re.sub(r"(?m)^n_strips = .*$", f"n_strips = {strips}", plan)
    (folder / "plan.toml").write_text(plan)
    bindir = Path(sys.executable).parent
    ins, pg = str(bindir / "ins"), str(bindir / "photogrammetry")
    flight, proc = folder / "flight", folder / "process"
    for cmd in ([ins, "simulate", folder / "plan.toml", "-o", flight, "--seed", "1", "--force",
                 "-q"],
                [ins, "process", flight, "-o", proc, "--forward", "--force", "-q"]):
        subprocess.run([str(c) for c in cmd], check=True, stdout=subprocess.DEVNULL)
    sys.path.insert(0, str(HERE.parent / "tools"))
    import demo
    demo.uncalibrated_camera(flight, cam)
    subprocess.run([pg, "eo", str(flight), "--trajectory", str(proc / "solution.nav"),
                    "--sigma", str(proc / "solution_std.txt"), "--camera", str(cam), "-o",
                    str(eo)], check=True, stdout=subprocess.DEVNULL)
    return str(eo), str(tp), str(cam)


def cli_stages(n, method, datum, block="sim", block_dir=None):
    """``photogrammetry refine`` as a user runs it (files in, refined CSV, report and
    plots out) on a simulated block of `n` images, in this process; returns the CPU
    time (s) of the start-up and of each stage of :data:`CLI_STAGES` (inclusive), the
    peak resident memory and the refined angles (deg).  `block`: ``sim`` the demo chain
    (:func:`sim_block_files`, kept in `block_dir` when given), ``scenario``
    ``tests/scenario.py``'s ``make_large_block``."""
    import functools
    import importlib
    import resource
    import tempfile
    import time

    import numpy as np

    def cpu():
        r = resource.getrusage(resource.RUSAGE_SELF)
        return r.ru_utime + r.ru_stime

    sys.path.insert(0, str(HERE.parent / "tests"))
    import scenario as sc
    with tempfile.TemporaryDirectory() as tmp:
        if block == "sim":
            eo, tp, cam = sim_block_files(n, Path(block_dir or tmp) / f"sim{n}")
        else:
            eo, tp, cam = sc.write_block_files(sc.make_large_block(n, seed=1), tmp)
        n = sum(1 for line in open(eo) if line.strip() and not line.startswith("#")) - 1
        c0 = cpu()
        from photogrammetry.cli.main import main
        times = {}
        for mod, attr, cls, label in CLI_STAGES:
            owner = importlib.import_module(mod)
            owner = getattr(owner, cls) if cls else owner
            f = getattr(owner, attr)

            def timed(*a, _f=f, _label=label, **k):
                t = cpu()
                try:
                    return _f(*a, **k)
                finally:
                    times[_label] = times.get(_label, 0.0) + cpu() - t
            setattr(owner, attr, functools.wraps(f)(timed))
        startup = cpu() - c0
        t0, w0 = cpu(), time.perf_counter()
        code = main(["refine", eo, tp, "--camera", cam, "--method", method, "--datum", datum,
                     "-o", os.path.join(tmp, "refined.csv"), "--report",
                     os.path.join(tmp, "report.md"), "-q"])
        run_s, wall = cpu() - t0, time.perf_counter() - w0
        angles = []
        if code == 0:
            from photogrammetry.orientation.exposure import read_eo_csv
            ref = read_eo_csv(os.path.join(tmp, "refined.csv"))
            angles = np.degrees(ref.angles).tolist()
    return {"images": n, "exit": code, "startup_s": startup, "run_s": run_s, "wall_s": wall,
            "peak_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "stages": [(label, times.get(label, 0.0)) for *_, label in CLI_STAGES],
            "angles_deg": angles}


def run_cli(method, datum, sizes, block="sim", block_dir=None, save=None):
    """One fresh process per size: the CLI's CPU time per stage (`save`: a JSON file for
    the figures and refined angles, to compare two versions of the code)."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
               MKL_NUM_THREADS="1", PYTHONWARNINGS="ignore")
    rows = []
    for n in sizes:
        out = subprocess.run([sys.executable, __file__, "--cli-one", str(n), "--method",
                              method, "--datum", datum, "--block", block]
                             + (["--block-dir", block_dir] if block_dir else []),
                             env=env, capture_output=True, text=True)
        if out.returncode:
            print(f"{n}: failed: {out.stderr.strip().splitlines()[-1]}")
            continue
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
    if not rows:
        return
    if save:
        Path(save).write_text(json.dumps(rows))
    print(f"block: {block}; photogrammetry refine --method {method} --datum {datum} "
          "--report (CPU s; "
          "stages inclusive, indented: within the stage above)")
    print(f"{'stage':<40}" + "".join(f"{r['images']:>9}" for r in rows))
    print(f"{'start-up (imports, compiled kernels)':<40}"
          + "".join(f"{r['startup_s']:9.2f}" for r in rows))
    for k, (label, _) in enumerate(rows[0]["stages"]):
        print(f"{label:<40}" + "".join(f"{r['stages'][k][1]:9.2f}" for r in rows))
    print(f"{'total CPU (start-up + run)':<40}"
          + "".join(f"{r['startup_s'] + r['run_s']:9.2f}" for r in rows))
    print(f"{'per image above start-up, ms':<40}"
          + "".join(f"{1e3 * r['run_s'] / r['images']:9.1f}" for r in rows))
    print(f"{'wall, s (run)':<40}" + "".join(f"{r['wall_s']:9.2f}" for r in rows))
    print(f"{'peak resident memory, MB':<40}" + "".join(f"{r['peak_MB']:9.0f}" for r in rows))
    print(f"{'exit code':<40}" + "".join(f"{r['exit']:9d}" for r in rows))


def dask_run(n_blocks, n_images, workers):
    """``n_blocks`` flights of ``n_images`` each written as files and refined as Dask
    tasks (``photogrammetry.adjustment.batch.refine_many``) on a local cluster of `workers`
    processes; prints the wall time and every worker's peak resident memory."""
    import resource
    import tempfile
    import time
    sys.path.insert(0, str(HERE.parent / "tests"))
    import scenario as sc
    from dask.distributed import Client, LocalCluster

    from photogrammetry.adjustment.batch import refine_many
    from photogrammetry.imagery.tiepoints import read_tiepoints
    from photogrammetry.orientation.camera import read_camera
    from photogrammetry.orientation.exposure import read_eo_csv
    with tempfile.TemporaryDirectory() as tmp:
        tasks = []
        for k in range(n_blocks):
            d = Path(tmp) / f"flight{k}"
            d.mkdir()
            eo, tp, cam = sc.write_block_files(sc.make_large_block(n_images, seed=100 + k),
                                               str(d))
            camera, _ = read_camera(cam)
            tasks.append(dict(eo=read_eo_csv(eo), tiepoints=read_tiepoints(tp, camera),
                              camera=camera, method="known-base", datum="none"))
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                               dashboard_address=None,
                               env={"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"})
        client = Client(cluster)
        try:
            t0 = time.perf_counter()
            res = refine_many(tasks, scheduler=cluster.scheduler_address)
            wall = time.perf_counter() - t0
            peak = client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
                              / 1024)
        finally:
            client.close()
            cluster.close()
    print(f"dask: {n_blocks} blocks x {n_images} images = {n_blocks * n_images} images on "
          f"{workers} workers: {wall:.1f} s; peak resident memory per worker (MB): "
          + ", ".join(f"{v:.0f}" for v in peak.values())
          + f"; sigma0 {min(r.block.sigma0 for r in res):.3f}-"
            f"{max(r.block.sigma0 for r in res):.3f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", default="50,200,1000,5000")
    ap.add_argument("--method", default=None,
                    help="comma-separated: known-base, relative, base-free (default "
                         "known-base; with --cli base-free, the command's default)")
    ap.add_argument("--datum", default="auto",
                    help="first, ins, none or auto (none for known-base, else first)")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--cli", metavar="SIZES",
                    help="instead: photogrammetry refine as a user runs it (files, report, "
                         "plots) at these sizes, CPU time per stage (e.g. 470,1000; method "
                         "default base-free, datum first: the command's defaults)")
    ap.add_argument("--cli-one", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--block", choices=["sim", "scenario"], default="sim",
                    help="--cli block: sim the demo chain on a plan of round(N/47) strips "
                         "of 7.5 km (default), scenario tests/scenario.py's make_large_block")
    ap.add_argument("--block-dir", metavar="DIR",
                    help="--cli block sim: keep (and reuse) the simulated flights here")
    ap.add_argument("--save", metavar="JSON",
                    help="--cli: write the figures and the refined angles to this file")
    ap.add_argument("--dask", metavar="BLOCKSxIMAGES",
                    help="instead: BLOCKS flights of IMAGES each as Dask tasks (10x1000)")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    if args.dask:
        b, n = (int(v) for v in args.dask.lower().split("x"))
        dask_run(b, n, args.workers)
        return
    if args.one:
        print(json.dumps(one(args.one, args.method, args.datum)))
        return
    if args.cli or args.cli_one:
        method = args.method or "base-free"
        datum = args.datum if args.datum != "auto" else (
            "none" if method == "known-base" else "first")
        if args.cli_one:
            print(json.dumps(cli_stages(args.cli_one, method, datum, args.block,
                                        args.block_dir)))
        else:
            run_cli(method, datum, [int(v) for v in args.cli.split(",")], args.block,
                    args.block_dir, args.save)
        return
    args.method = args.method or "known-base"
    for method in args.method.split(","):
        datum = args.datum if args.datum != "auto" else (
            "none" if method == "known-base" else "first")
        print(f"method {method}, datum {datum}")
        run_sizes(method, datum, [int(v) for v in args.sizes.split(",")])


def run_sizes(method, datum, sizes):
    """One row per size (each in a fresh process) and the slopes."""
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
               MKL_NUM_THREADS="1")
    rows = []
    print(f"{'images':>7} {'pairs':>6} {'adjust_s':>9} {'assess_s':>9} {'total_s':>8} "
          f"{'cpu_s':>6} {'peak_MB':>8} {'factor':>8} {'sigma0':>7}  boresight error (sigmas)")
    for n in sizes:
        out = subprocess.run([sys.executable, __file__, "--one", str(n), "--method",
                              method, "--datum", datum], env=env,
                             capture_output=True, text=True)
        if out.returncode:
            print(f"{n:>7} failed: {out.stderr.strip().splitlines()[-1]}")
            continue
        r = json.loads(out.stdout.strip().splitlines()[-1])
        rows.append(r)
        print(f"{r['images']:>7} {r['pairs']:>6} {r['adjust_s']:9.2f} {r['assess_s']:9.2f} "
              f"{r['adjust_s'] + r['assess_s']:8.2f} {r['cpu_s']:6.1f} {r['peak_MB']:8.0f} "
              f"{r['factor']:>8} "
              f"{r['sigma0']:7.3f}  {r['boresight_err_sigmas']}", flush=True)
    import numpy as np
    big = [r for r in rows if r["images"] >= 200]
    if len(big) >= 2:
        x = np.log([r["images"] for r in big])
        t = np.log([r["adjust_s"] + r["assess_s"] for r in big])
        mem = np.log([r["peak_MB"] for r in big])
        print(f"slope of log(total time) vs log(images), {big[0]['images']}-"
              f"{big[-1]['images']}: {np.polyfit(x, t, 1)[0]:.2f}; of log(peak memory): "
              f"{np.polyfit(x, mem, 1)[0]:.2f}")


if __name__ == "__main__":
    main()
