"""Block scale: refine + assess time and peak memory against the number of images.

    .venv/bin/python bench/bench_block_scale.py [--sizes 50,200,1000,5000]
        [--method known-base,relative,base-free] [--datum auto]

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
                       else f"L={f.nnz / 1e6:.2f}M"),
            "sigma0": res.sigma0, "boresight_err_sigmas": np.round(err, 2).tolist(),
            "ins_noise_arcsec": np.round(a.ins_noise * 206264.8, 1).tolist()}


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
    ap.add_argument("--method", default="known-base",
                    help="comma-separated: known-base, relative, base-free")
    ap.add_argument("--datum", default="auto",
                    help="first, ins, none or auto (none for known-base, else first)")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
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
