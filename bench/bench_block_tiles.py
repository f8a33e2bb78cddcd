"""One 10 000-image block refined in tiles on Dask (photogrammetry.adjustment.tiling).

    .venv/bin/python bench/bench_block_tiles.py [--images 10000] [--tile-images 1000]
        [--halo-hops 3] [--workers 2] [--method known-base] [--datum none]

A single simulated block (``tests/scenario.py``'s ``make_large_block(images, seed=1)``:
strips of 50 images, 60 % forward and 30 % side overlap, ~40 tie points per image,
0.5 px noise, INS noise 0.005 rad, boresight (0.002, -0.003, 0.004) rad) is written as
files (eo.csv, tiepoints.csv, camera.toml) and read back as ``photogrammetry refine``
would; then ``photogrammetry.adjustment.tiling.refine_tiled`` cuts it into tiles of at most
``--tile-images`` core images with a halo of ``--halo-hops`` pair-hops and adjusts them
as tasks on a LocalCluster of ``--workers`` single-threaded worker processes (BLAS held
to one thread).  Printed: the time and the driver's peak resident memory of each stage
(simulation, files, reading and pairing, tiled refinement), the tiles' sizes, the wall
time of the refinement, every worker's peak resident memory, the angles' error against
the simulated truth (RMS per angle, arcsec, and chi-square per angle: the mean of
(error / sigma)^2, 1 when the sigmas are honest), the combined boresight's error in
its sigmas and the combined INS noise against the injected one.

Measured (2 cores shared with 5 other jobs, 2026-11-24, this script as committed;
defaults: 10 000 images, tiles of 1000, halo 3, known-base, datum none, 2 workers):

    simulate 10000 images: 80.4 s, 40985 pairs; driver peak 263 MB
    write files: 2.7 s (tiepoints.csv 20 MB)
    read files: 4.1 s; driver peak 562 MB
    pairing in the driver (TiePoints.pairs): 4.6 s, 59760 pairs (3 or more common points)
    10 tiles of <= 1000 core images, tile sizes with halo 1150-1300 (1.27x the images)
    wall 97.4 s on 2 workers (89-103 s over four runs as the load varied; first tile
      done at 32 s, the driver's pairing and partition included)
    peak resident memory per worker (VmHWM) 424, 428 MB; driver 674 MB
    current resident memory per worker between successive tiles: 310-424 MB, no trend
      over the 5 tiles each worker ran
    sigma0 0.997 (tiles 0.994-0.999); quality ok
    angles vs truth: RMS 3.94, 4.16, 7.70 arcsec (phi, omega, kappa); chi-square per
      angle 1.00, 0.95, 1.02
    boresight error 1.53, 0.49, -0.76 sigma (sigma 10.4, 10.3, 10.3 arcsec)
    INS noise 1029.0, 1039.1, 1028.7 +- 7.3 arcsec (injected 1031.0, 1040.6, 1031.5)

The simulation itself (``make_large_block``, pure numpy in the driver) is the heaviest
stage (80 s: the pair search compares every image with all later ones); the refinement
of one block of 10 000 images in one process was not run here (the 5000-image block
takes 83 s and 0.9 GB, ``bench_block_scale.py``).  ``--images 3000 --whole``: tiled
19.4 s wall on 2 workers of 378 MB against 14.7 s and 697 MB for the whole block in one
process; tiled minus whole 0.26, 0.26, 0.12 of the whole block's sigmas RMS (the
difference sits at the tiles' borders, docs/interfaces.md), boresight errors 2.01, 0.69,
1.38 sigma against 1.96, 0.68, 1.41.  The worker memory is VmHWM: ``ru_maxrss`` of a
worker spawned by fork + exec reports the driver's resident memory at the fork (563 MB
here), which is also in the ``--dask`` figures of ``bench_block_scale.py``.
"""
import argparse
import os
import resource
import sys
import tempfile
import time
import warnings
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

HERE = Path(__file__).resolve().parent
_AS = 206264.806


def _peak_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _worker_peak_mb():
    """(VmHWM, ru_maxrss) of the process, MB.  VmHWM (Linux /proc) is the peak resident
    memory of this process image; ru_maxrss also keeps that of the process before its
    exec, i.e. a worker spawned by fork + exec reports the parent's (the driver's)
    resident memory at the fork."""
    import resource as r
    hwm = float("nan")
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                hwm = int(line.split()[1]) / 1024
    return hwm, r.getrusage(r.RUSAGE_SELF).ru_maxrss / 1024


def _worker_rss_mb():
    """Current resident memory of the process, MB (Linux /proc)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


def _poll(client, samples, stop, every_s=0.5):
    """Sample every worker's current resident memory until `stop` is set."""
    import time as _t
    while not stop.is_set():
        try:
            samples.append((_t.perf_counter(), client.run(_worker_rss_mb)))
        except Exception:                                  # the cluster closing
            return
        stop.wait(every_s)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--images", type=int, default=10000)
    ap.add_argument("--tile-images", type=int, default=1000)
    ap.add_argument("--halo-hops", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--method", default="known-base")
    ap.add_argument("--datum", default="none")
    ap.add_argument("--whole", action="store_true",
                    help="also refine the whole block in the driver (after the tiles) and "
                         "compare")
    args = ap.parse_args()
    import numpy as np
    sys.path.insert(0, str(HERE.parent / "tests"))
    import scenario as sc
    from dask.distributed import Client, LocalCluster

    from photogrammetry.adjustment.tiling import refine_tiled
    from photogrammetry.imagery.tiepoints import read_tiepoints
    from photogrammetry.orientation.camera import read_camera
    from photogrammetry.orientation.exposure import read_eo_csv
    from photogrammetry.orientation.rotation import angles_to_matrix

    t = time.perf_counter()
    B = sc.make_large_block(args.images, seed=1)
    print(f"simulate {args.images} images: {time.perf_counter() - t:.1f} s, "
          f"{len(B['pairs'])} pairs; driver peak {_peak_mb():.0f} MB", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        eo_p, tp_p, cam_p = sc.write_block_files(B, tmp)
        size = os.path.getsize(tp_p) / 1e6
        print(f"write files: {time.perf_counter() - t:.1f} s (tiepoints.csv {size:.0f} MB)",
              flush=True)
        t = time.perf_counter()
        camera, _ = read_camera(cam_p)
        eo, tp = read_eo_csv(eo_p), read_tiepoints(tp_p, camera)
        print(f"read files: {time.perf_counter() - t:.1f} s; driver peak {_peak_mb():.0f} MB",
              flush=True)
    t = time.perf_counter()
    pairs = tp.pairs(list(eo.image_id), camera, min_common=3)[0]
    print(f"pairing in the driver (TiePoints.pairs, again inside refine_tiled): "
          f"{time.perf_counter() - t:.1f} s, {len(pairs)} pairs; driver peak "
          f"{_peak_mb():.0f} MB", flush=True)
    del pairs
    truth, boresight, noise = B["angles"], B["boresight"], B["ins_noise"]
    system = B["system"]

    del B
    cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1,
                           dashboard_address=None,
                           env={"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
                                "MKL_NUM_THREADS": "1"})
    client = Client(cluster)
    marks, samples = [], []
    import threading
    stop = threading.Event()
    poller = threading.Thread(target=_poll, args=(client, samples, stop), daemon=True)
    poller.start()
    try:
        t0 = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = refine_tiled(eo, tp, camera, tile_images=args.tile_images,
                               halo_hops=args.halo_hops, method=args.method,
                               datum=args.datum, scheduler=cluster.scheduler_address,
                               accept_poor=True,
                               progress=lambda d, n, i, m: marks.append(
                                   (d, n, i, time.perf_counter() - t0)))
        wall = time.perf_counter() - t0
        peaks = client.run(_worker_peak_mb)
        stop.set()
        poller.join()
    finally:
        client.close()
        cluster.close()
    s = res.settings
    print(f"tiled refinement ({args.method}, datum {args.datum}): {s['n_tiles']} tiles of "
          f"<= {args.tile_images} core images, halo {args.halo_hops} hops; tile sizes with "
          f"halo {min(s['tile_sizes'])}-{max(s['tile_sizes'])} (mean "
          f"{np.mean(s['tile_sizes']):.0f}, {sum(s['tile_sizes']) / s['n_images']:.2f}x the "
          f"images)")
    print(f"  wall {wall:.1f} s on {args.workers} workers (first tile done at "
          f"{marks[0][3]:.1f} s, pairing and partition in the driver included); "
          f"{len(caught)} warnings")
    print("  peak resident memory per worker (MB, VmHWM): "
          + ", ".join(f"{v[0]:.0f}" for v in peaks.values())
          + " (ru_maxrss, which holds the driver's memory at the fork: "
          + ", ".join(f"{v[1]:.0f}" for v in peaks.values())
          + f"); driver {_peak_mb():.0f} MB")
    if samples:
        workers = sorted(samples[-1][1])
        cuts = [t for (_, _, _, t) in marks]
        rows = []
        for k, t_end in enumerate(cuts):
            t_start = cuts[k - 1] if k else 0.0
            inside = [v for (t, v) in samples if t_start <= t - t0 <= t_end]
            rows.append(" / ".join(f"{max((v.get(w, 0) for v in inside), default=0):.0f}"
                                   for w in workers))
        print("  current resident memory per worker, max between successive tiles done "
              "(MB, sampled every 0.5 s): " + "; ".join(rows))
    blk, a = res.block, res.assessment
    print(f"  sigma0 {blk.sigma0:.3f} (tiles {min(r.sigma0 for r in res.tile_results):.3f}-"
          f"{max(r.sigma0 for r in res.tile_results):.3f}); quality "
          f"{'POOR: ' + '; '.join(blk.quality.reasons[:3]) if blk.quality.poor else 'ok'}")
    ok = blk.adjusted
    d = np.angle(np.exp(1j * (blk.angles - truth)))[ok]
    rot = sc.rotation_error(angles_to_matrix(blk.angles[ok], system),
                            angles_to_matrix(truth[ok], system))
    chi = np.mean((d / blk.sigma[ok]) ** 2, axis=0)
    if args.datum != "none":
        # the INS datum orients each tile by its own INS angles (boresight and INS noise
        # included): compare the shape only, after one common model-frame rotation
        rest = rot - rot.mean(axis=0)
        print(f"  datum {args.datum}: rotation error vs truth after removing the block's "
              f"common model-frame rotation ({np.round(rot.mean(axis=0) * _AS, 1)} arcsec): "
              f"RMS {np.sqrt(np.mean(rest ** 2)) * _AS:.2f} arcsec (the boresight's "
              "heading-dependent part and the tiles' own datum rotations remain in it)")
    print(f"  angles vs truth ({ok.sum()} images): RMS "
          + ", ".join(f"{v * _AS:.2f}" for v in np.sqrt(np.mean(d ** 2, axis=0)))
          + " arcsec (" + "/".join(a.names) + "); chi-square per angle "
          + ", ".join(f"{v:.2f}" for v in chi)
          + f"; rotation error RMS {np.sqrt(np.mean(rot ** 2)) * _AS:.2f} arcsec")
    if a.boresight_observable:
        err = (a.boresight - boresight) / a.boresight_sigma
        print("  boresight " + ", ".join(f"{v * _AS:.1f}" for v in a.boresight)
              + " arcsec +- " + ", ".join(f"{v * _AS:.1f}" for v in a.boresight_sigma)
              + "; error in sigmas " + ", ".join(f"{v:.2f}" for v in err))
    if args.whole:
        from photogrammetry.adjustment.batch import refine
        t = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            w = refine(eo, tp, camera, method=args.method, datum=args.datum,
                       accept_poor=True)
        z = np.angle(np.exp(1j * (blk.angles - w.block.angles)))[ok] / w.block.sigma[ok]
        print(f"  whole block in the driver: {time.perf_counter() - t:.1f} s, driver peak "
              f"{_peak_mb():.0f} MB; tiled minus whole in the whole's sigmas: RMS "
              + ", ".join(f"{v:.2f}" for v in np.sqrt(np.mean(z ** 2, axis=0))) + ", max "
              + ", ".join(f"{v:.2f}" for v in np.max(np.abs(z), axis=0)))
        if w.assessment.boresight_observable:
            print("  whole-block boresight error in sigmas "
                  + ", ".join(f"{v:.2f}" for v in (w.assessment.boresight - boresight)
                              / w.assessment.boresight_sigma))
    injected = np.std(noise, axis=0)
    print("  INS noise " + ", ".join(f"{v * _AS:.1f}" for v in a.ins_noise) + " +- "
          + ", ".join(f"{v * _AS:.1f}" for v in a.ins_noise_sigma) + " arcsec (injected "
          + ", ".join(f"{v * _AS:.1f}" for v in injected) + ")")


if __name__ == "__main__":
    main()
