"""Many tasks on ``dask.distributed``: a quiet local cluster or an existing scheduler.

:func:`map_tasks` runs a module-level function on many sets of keyword arguments as Dask
tasks (a local cluster of ``workers`` processes, or the cluster of a running scheduler's
address), or one after another in this process (``workers=1``, no scheduler); the
results come back in the order of the tasks.  Shared by ``photogrammetry refine`` (blocks
and tiles) and ``ins process`` (many logs).

The local cluster (:func:`local_cluster`, :func:`close_cluster`) is made for a command
line: Ctrl-C and SIGTERM belong to the main process (its workers ignore SIGINT, and the
main process closes them, Ctrl-C held back meanwhile), distributed's log lines are not
printed, and every scratch file (``dask-scratch-space``, the workers' TMPDIR) lives in
one temporary folder removed on close.  ``dask`` is imported only when a cluster is used.
"""
import warnings

__all__ = ["map_tasks", "call_task", "reemit_warnings", "local_cluster", "close_cluster"]


def call_task(func, kwargs):
    """``func(**kwargs)`` on one task; its warnings travel with the result (a Dask
    worker's own warnings would otherwise be printed raw on the worker's stderr), as the
    result's ``warnings`` attribute: a list of ``(category, message)``."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = func(**kwargs)
    result.warnings = [(w.category, str(w.message)) for w in caught]
    return result


def reemit_warnings(results):
    """Issue again, in the caller, the warnings that :func:`call_task` kept with each
    result; returns ``results``."""
    for r in results:
        for category, message in getattr(r, "warnings", ()):
            warnings.warn(message, category, stacklevel=3)
    return results


def map_tasks(func, tasks, workers=None, scheduler=None, progress=None, processes=True,
              total=None, on_result=None):
    """``func(**task)`` for every task, as Dask tasks.

    Parameters
    ----------
    func : callable
    tasks : iterable of dict
        Keyword arguments of `func`, one dict per task.
    workers : int, optional
        Size of the local cluster (default: the number of cores); ``1`` with no
        scheduler runs in this process without Dask.
    scheduler : str, optional
        Address of a running ``dask.distributed`` scheduler (``tcp://host:8786``).
    progress : callable, optional
    processes : bool
        Local cluster of processes (default) or of threads in this process.
    total : int, optional
        The number of tasks when `tasks` is a generator.
    on_result : callable(index, result), optional
        Called in this thread with each result as it arrives (in the order the tasks
        finish), before `progress`.

    `func` must be a module-level function (pickled by reference) whose result takes a
    ``warnings`` attribute (the task's warnings, re-issued here in the caller).  Each
    task's keyword arguments travel to the worker that runs it, and only there; they are
    submitted a few at a time (twice the workers in flight), so neither the scheduler
    nor a worker holds the data of all tasks at once, and `tasks` may be a generator
    (give `total`, its length, for the progress).  `progress` is called as
    ``progress(done, total, index)`` with the index of the task just finished when it
    takes three arguments, else ``progress(done, total)``.

    Returns
    -------
    list of the results, in the order of `tasks`.
    """
    if total is None:
        tasks = list(tasks)
        total = len(tasks)
    note = _progress_call(progress)
    if scheduler is None and workers == 1:
        out = []
        for k, t in enumerate(tasks):
            out.append(call_task(func, t))
            if on_result is not None:
                on_result(k, out[-1])
            note(k + 1, total, k)
        return reemit_warnings(out)
    import dask
    from dask.distributed import Client, as_completed
    cluster = scratch = None
    try:
        if scheduler is None:
            cluster, scratch = local_cluster(workers, processes)
            client = Client(cluster)
        else:
            client = Client(scheduler)
    except BaseException:
        close_cluster(None, cluster, scratch)
        raise
    try:
        window = 2 * max(1, sum(client.nthreads().values()))
        pending = enumerate(tasks)
        running = as_completed()
        index = {}

        def submit_next():
            for k, task in pending:
                fut = client.submit(call_task, func, task, pure=False)
                index[fut.key] = k
                running.add(fut)
                return

        results = [None] * total
        # a task's own data (a tile of a block: tens of MB) is meant to travel with it
        with dask.config.set({"distributed.admin.large-graph-warning-threshold": "4GB"}):
            for _ in range(window):
                submit_next()
            for done, fut in enumerate(running, 1):
                k = index.pop(fut.key)
                results[k] = fut.result()
                fut.release()
                if on_result is not None:
                    on_result(k, results[k])
                note(done, total, k)
                submit_next()
        return reemit_warnings(results)
    finally:
        close_cluster(client, cluster, scratch)


def local_cluster(workers, processes):
    """A quiet local Dask cluster and its scratch: ``(cluster, scratch)``.

    Ctrl-C belongs to the main process: the worker processes are spawned through a
    two-line shell wrapper that ignores SIGINT before it runs Python (an ignored signal
    stays ignored across exec, and Python then installs no KeyboardInterrupt handler),
    so a Ctrl-C to the terminal's process group leaves them alone (it used to print a
    worker's KeyboardInterrupt traceback from the middle of its imports) and the main
    process closes them.  distributed's log lines are not printed (its warnings and
    errors of workers cut off by the close); every
    ``dask-scratch-space`` (workers and scheduler) is made in a temporary folder
    removed on close (:func:`close_cluster`)."""
    import logging
    import multiprocessing.spawn
    import os
    import shlex
    import sys
    import tempfile

    import dask
    from dask.distributed import LocalCluster

    from ins.common import interrupts
    for name in ("distributed", "distributed.nanny", "distributed.scheduler"):
        logging.getLogger(name).setLevel(logging.CRITICAL)
    # the semaphores of workers killed on close are the resource tracker's to clean up
    # (it says so at exit, in a process of its own that takes these warning options)
    quiet = "ignore::UserWarning:multiprocessing.resource_tracker"
    if quiet not in sys.warnoptions:
        sys.warnoptions.append(quiet)
    folder = tempfile.mkdtemp(prefix="insphoto-dask-")
    exe = os.fsdecode(multiprocessing.spawn.get_executable())
    scratch = (folder, dask.config.set({"temporary-directory": folder}), exe)
    cluster = None
    try:
        if os.name == "posix" and processes:
            wrapper = os.path.join(folder, "python-ignoring-sigint")
            with open(wrapper, "w") as fh:
                # TMPDIR: a worker killed on close inside its first tempfile.gettempdir()
                # leaves that call's empty probe file (a bare 8-letter name) behind; in
                # the scratch folder it goes with the folder
                fh.write(f"#!/bin/sh\ntrap '' INT\nTMPDIR={shlex.quote(folder)}\n"
                         f"export TMPDIR\nexec {shlex.quote(exe)} \"$@\"\n")
            os.chmod(wrapper, 0o755)
            multiprocessing.spawn.set_executable(wrapper)
        # Ctrl-C waits for the start-up (a second or two): a cluster cut off half started
        # has workers that nobody closes, and they write scratch after its removal
        with interrupts.deferred():
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                   processes=processes, dashboard_address=None,
                                   local_directory=folder, silence_logs=logging.CRITICAL)
    except BaseException:
        close_cluster(None, cluster, scratch)
        raise
    return cluster, scratch


def close_cluster(client, cluster, scratch):
    """Close the client and the local cluster (Ctrl-C held back meanwhile), then undo
    the scratch ``(folder, dask config setting, spawn executable)`` of
    :func:`local_cluster`."""
    from ins.common import interrupts
    with interrupts.deferred():
        for c in (client, cluster):
            if c is not None:
                try:
                    c.close()
                except Exception:           # a cluster half started or already gone
                    pass
        if scratch is not None:
            import multiprocessing.spawn
            import shutil
            multiprocessing.spawn.set_executable(scratch[2])
            scratch[1].__exit__(None, None, None)
            shutil.rmtree(scratch[0], ignore_errors=True)


def _progress_call(progress):
    """`progress` as a function of (done, total, index)."""
    if progress is None:
        return lambda done, total, k: None
    import inspect
    try:
        n = len(inspect.signature(progress).parameters)
    except (TypeError, ValueError):
        n = 2
    if n >= 3:
        return progress
    return lambda done, total, k: progress(done, total)
