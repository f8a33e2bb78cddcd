"""``ins process A B C -o OUT`` (any number of inputs): many logs at once, each into
OUT/<name>, as Dask tasks (``--workers N``, ``--scheduler ADDRESS``) or one after
another in this process.

Each input (a flight folder, or a per-log config with ``[files]``) is one run of
:func:`ins.cli.process.run_into` on its own: its own output folder, its own summary
(``summary.txt`` in the folder), its own exit status.  The main process makes every
run's staging folder (``OUT/.<name>.XXXXXXXX.part``, :func:`ins.common.fileio.make_staging`)
just before the run is handed out, the run builds its outputs there (on a worker, or
here), and the main process swaps it into place when the run reports back
(:func:`ins.common.fileio.install_staging`, Ctrl-C held back meanwhile) or removes it
if the run failed.  On Ctrl-C or SIGTERM the cluster is closed first
(:func:`ins.common.dask_tasks.map_tasks`), then the staging folders of the unfinished
runs are removed: the finished runs' folders are complete, the others absent.
"""
import dataclasses
import os
import sys
import time as wallclock

from ins.common.errors import InputError

__all__ = ["BATCH_EPILOG", "add_parser", "cmd_process", "add_batch_arguments", "run_batch",
           "run_one", "RunRecord", "output_names", "worst_status", "batch_table"]

BATCH_EPILOG = """
many logs (a batch):
  ins process A B C ... -o OUT [--workers N | --scheduler tcp://host:8786]
                    two or more inputs, each a flight folder (with manifest.toml; a
                    --config F.toml overrides keys of every manifest) or a per-log
                    config (INPUT.toml with [files]); each run goes into OUT/NAME
                    (OUT is made if missing; NAME: the input's base name, a config's
                    without .toml; a name already taken by an earlier input gets -2,
                    -3, ... in the order given: a/flight b/flight -> OUT/flight,
                    OUT/flight-2), built aside and swapped in whole as for one run,
                    with its summary in OUT/NAME/summary.txt; a failed run leaves no
                    folder (nor OUT, when made for none).  An existing non-empty
                    OUT/NAME stops the batch before any work (exit 2) unless --force
                    (each OUT/NAME replaced whole; nothing else in OUT touched).  The
                    options apply to every run; those naming one log's files (--imu,
                    --gnss, --rover ..., --mount, --truth) are refused; --report
                    NAME.html is written into each run's folder.
  --workers N       N local Dask worker processes (at most one per input); without
                    it, or with 1, the runs go one after another in this process.
  --scheduler ADDR  an existing dask.distributed scheduler's cluster instead; its
                    workers must see the inputs and OUT at the same paths (a shared
                    file system).  With one input, neither has any effect: the run
                    is in this process, as without them.
  output            one line per finished run on stderr (unless -q), each failed
                    run's error line and its warnings, then one table on stdout
                    (unless -q): input, exit, GNSS source, rejected % (innovation
                    test), the smoothed position sigmas' RMS over the run
                    (horizontal sqrt(N^2+E^2) and vertical, m), run time (s).
  exit status       the worst run's: the largest exit code of the runs (3 if any run
                    was untrustworthy, else 2 if any had bad input, else 1 if one
                    met an internal error, else 0); 2 at once for a bad batch
                    (clashing options, an occupied OUT/NAME).  Ctrl-C or SIGTERM:
                    130 or 143 and one line naming the runs completed: their
                    folders are complete, the others absent (no staging folder, no
                    Dask scratch left), the workers shut down quietly.
"""

#: Warnings of a run not shown (Python ignores them by default in a single run).
_QUIET = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)

#: Options that name one log's files: refused in a batch.
_ONE_LOG = ("imu", "gnss", "rover", "base", "nav", "sp3", "clk", "atx", "dcb", "mount",
            "truth")


def add_parser(sub):
    """``ins process``: the parser of :mod:`ins.cli.process` with the batch's options
    and help; several inputs run as a batch (:func:`run_batch`), one as before."""
    from ins.cli import process
    p = process.add_parser(sub)
    p.epilog += BATCH_EPILOG
    add_batch_arguments(p)
    p.set_defaults(func=cmd_process)


def cmd_process(args):
    """``ins process``: a batch for two or more inputs, else the one run of
    :mod:`ins.cli.process`, exactly as without the batch."""
    if len(args.flight_dir or []) > 1:
        return run_batch(args)
    from ins.cli import process
    return process._cmd_process(args)


def add_batch_arguments(p):
    """The batch options of ``ins process`` (``--workers``, ``--scheduler``)."""
    from ins.cli.util import positive_int
    p.add_argument("--workers", type=positive_int, metavar="N",
                   help="several inputs: N local Dask worker processes (default: one "
                        "run after another in this process)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="several inputs: an existing dask.distributed scheduler "
                        "(tcp://host:8786); a shared file system")


@dataclasses.dataclass
class RunRecord:
    """What one run of a batch reports back to the main process (small: no arrays)."""
    input: str
    name: str
    code: int = 0
    error: str = ""
    gnss: str = ""
    rejected_pct: float = float("nan")
    sigma_h_m: float = float("nan")
    sigma_v_m: float = float("nan")
    time_s: float = float("nan")
    traceback: str = ""
    warnings: list = dataclasses.field(default_factory=list)


def output_names(inputs):
    """The folder name of each input in OUT: its base name (a config's without .toml);
    a name taken by an earlier input gets ``-2``, ``-3``, ... (the first free one)."""
    names, taken = [], set()
    for path in inputs:
        base = os.path.basename(os.path.abspath(path))
        if base.lower().endswith(".toml") and not os.path.isdir(path):
            base = base[:-5]
        name, k = base, 1
        while name in taken:
            k += 1
            name = f"{base}-{k}"
        taken.add(name)
        names.append(name)
    return names


def worst_status(codes):
    """The batch's exit status: the largest of the runs' (0 for none)."""
    return max(codes, default=0)


def _check_batch(args, inputs):
    for key in _ONE_LOG:
        value = getattr(args, key, None)
        if value:
            raise InputError(f"--{key}: names one log's file; in a batch each input's "
                             "manifest or config ([files]) names its files")
    seen = {}
    for path in inputs:
        real = os.path.realpath(path)
        if real in seen:
            raise InputError(f"{path}: given twice (as {seen[real]})")
        seen[real] = path
    configs = [p for p in inputs if not os.path.isdir(p) and p.lower().endswith(".toml")]
    if configs and args.config:
        raise InputError(f"--config {args.config}: overrides the manifests of flight "
                         f"folders; {configs[0]} is a whole config of its own (give each "
                         "log's settings in its config)")
    if args.report and os.path.basename(args.report) != args.report:
        raise InputError(f"--report {args.report}: in a batch, a file name written into "
                         "each run's folder (no directory)")
    if args.report and os.path.splitext(args.report)[1].lower() not in (".html", ".htm"):
        raise InputError(f"--report {args.report}: expected an .html file (one "
                         "self-contained HTML page)")
    if args.workers is not None and args.scheduler:
        raise InputError("--workers N starts a local cluster, --scheduler ADDRESS uses an "
                         "existing one: give one of them")
    if (args.workers or 1) > 1 or args.scheduler:
        try:
            import distributed  # noqa: F401
        except ImportError:
            raise InputError("--workers/--scheduler run on dask.distributed, which is not "
                             "installed: pip install 'dask[distributed]' (a dependency of "
                             "insphoto: pip install insphoto)") from None


def _run_args(args, path, folder, absolute):
    """The arguments of one run: its input as a flight folder or a config."""
    run = argparse_copy(args)
    if absolute:
        path, folder = os.path.abspath(path), os.path.abspath(folder)
        if run.config:
            run.config = os.path.abspath(run.config)
    if os.path.isdir(path) or not path.lower().endswith(".toml"):
        run.flight_dir = path
    else:
        run.flight_dir, run.config = None, path
    run.output = folder
    run.quiet = True
    return run


def argparse_copy(args):
    """A shallow copy of the parsed arguments ``args``."""
    import argparse
    return argparse.Namespace(**vars(args))


def _clear(stage):
    """Empty ``stage`` but for its owner record (a run handed out again after its
    worker died starts afresh)."""
    import shutil

    from ins.common.fileio import OWNER_FILE
    for entry in os.listdir(stage):
        if entry != OWNER_FILE:
            p = os.path.join(stage, entry)
            if os.path.isdir(p) and not os.path.islink(p):
                shutil.rmtree(p)
            else:
                os.unlink(p)


def run_one(args, stage, input, name):
    """One run of a batch (on a Dask worker, or in this process) built in ``stage``:
    a :class:`RunRecord` with its exit status; its summary into ``stage/summary.txt``.
    Bad input and untrustworthy results are reported in the record, not raised; Ctrl-C
    is raised (this process)."""
    import io
    import traceback

    from ins.cli import process as cli
    from ins.cli.process_summary import summary
    from ins.common import interrupts
    from ins.common.errors import QualityError
    from ins.common.fileio import atomic_open
    rec = RunRecord(input=input, name=name)
    t0 = wallclock.perf_counter()
    try:
        _clear(stage)
        formats, height = cli._products(args)
        report = os.path.basename(args.report) if args.report else None
        cfg = cli._config(args)
        result, paths, t_proc, t_write = cli.run_into(args, cfg, formats, height, stage, t0,
                                                      report_inside=report,
                                                      progress=_Silent())
        rec.gnss = _gnss_source(result, cfg)
        q = result.quality or {}
        rec.rejected_pct = 100 * float(q.get("rejected_fraction", float("nan")))
        rec.sigma_h_m, rec.sigma_v_m = _sigmas(result)
        text = io.StringIO()
        summary(result, cfg, paths + [os.path.join(args.output, "summary.txt")],
                     t_proc, t_write, out=text)
        with atomic_open(os.path.join(stage, "summary.txt"), "w") as fh:
            fh.write(text.getvalue())
    except Exception as exc:
        if interrupts.caused_by_interrupt(exc):
            raise
        from ins.cli.main import _os_error_message
        if isinstance(exc, (InputError, QualityError)):
            rec.code, rec.error = (2 if isinstance(exc, InputError) else 3), str(exc)
        elif isinstance(exc, OSError):
            rec.code, rec.error = 2, _os_error_message(exc, args)
        else:                                   # a bug: its traceback is the report
            rec.code, rec.error = 1, f"internal error: {type(exc).__name__}: {exc}"
            rec.traceback = traceback.format_exc()
    rec.time_s = wallclock.perf_counter() - t0
    return rec


class _Silent:
    """A progress that shows nothing (a run of a batch)."""

    def note(self, text):
        pass

    def __call__(self, done, total):
        pass


def _gnss_source(result, cfg):
    """A few words for the table: RTKLIB's mode on raw observations, else the GNSS
    log's format; ``tight`` in front for tight coupling."""
    src = result.gnss_source
    if src is not None:
        text = f"RTKLIB {src['mode']}" + (f" {src['direction']}" if src.get("direction")
                                           else "")
    elif cfg.gnss:
        from ins.io.gnss import sniff_format
        text = f"{os.path.basename(str(cfg.gnss))} ({cfg.gnss_format or sniff_format(cfg.gnss)})"
    else:
        text = "-"
    if result.counts.get("coupling") == "tight":
        text = "tight, " + text
    return text


def _sigmas(result):
    """The smoothed position sigmas' RMS over the filter nodes: horizontal, vertical (m)."""
    import numpy as np

    from ins.estimation.core.error_model import STATE
    n, sh, sv = 0, 0.0, 0.0
    for c in result.node_chunks():
        sd = c.smoothed_std[:, STATE.pos]
        sh += float(np.sum(sd[:, 0] ** 2 + sd[:, 1] ** 2))
        sv += float(np.sum(sd[:, 2] ** 2))
        n += len(sd)
    return (np.sqrt(sh / n), np.sqrt(sv / n)) if n else (float("nan"), float("nan"))


def run_batch(args):
    """``ins process`` on two or more inputs (see :data:`BATCH_EPILOG`); returns the
    batch's exit status."""
    from ins.common import interrupts
    from ins.common.dask_tasks import map_tasks
    from ins.common.fileio import (check_output_folder, check_parent_directory,
                                   install_staging, make_staging, remove_staging)
    inputs = list(args.flight_dir)
    _check_batch(args, inputs)
    out = args.output
    check_parent_directory(out, "the output's parent directory does not exist")
    if os.path.exists(out) and not os.path.isdir(out):
        raise NotADirectoryError(20, "exists and is not a directory", out)
    names = output_names(inputs)
    folders = [os.path.join(out, n) for n in names]
    for path, folder in zip(inputs, folders):
        a, b = os.path.realpath(path), os.path.realpath(folder)
        if a == b or a.startswith(b + os.sep) or b.startswith(a + os.sep):
            raise InputError(f"-o {out}: its run folder {folder} would hold or replace "
                             f"the input {path}; give an output folder outside the inputs")
    if os.path.isdir(out):                # an occupied OUT/NAME: before any work
        for f in folders:
            check_output_folder(f, args.force)
    made = not os.path.isdir(out)
    os.makedirs(out, exist_ok=True)
    total = len(inputs)
    workers = args.workers or 1
    if args.scheduler is None:
        workers = min(workers, total)
    quiet = args.quiet
    if not quiet:
        where = (f"on the Dask scheduler {args.scheduler}" if args.scheduler else
                 f"on {workers} local Dask workers" if workers > 1 else
                 "one after another")
        _say(f"process: {total} runs into {out}, {where}")
    stages = {}
    records = [None] * total

    def tasks():
        for k, (path, folder, name) in enumerate(zip(inputs, folders, names)):
            run = _run_args(args, path, folder, absolute=args.scheduler is not None)
            with interrupts.deferred():    # an interrupt cannot lose a staging folder
                stages[k] = make_staging(folder, args.force)
            yield {"args": run, "stage": stages[k], "input": path, "name": name}

    done = []

    def finished(k, rec):
        rec.input = inputs[k]              # the user's spelling
        shown = rec.warnings
        rec.warnings = []                  # printed here, not issued again at the end
        with interrupts.deferred():        # installed whole, or not at all
            stage = stages.pop(k)
            if rec.code == 0:
                try:
                    install_staging(stage, folders[k], args.force)
                except OSError as exc:
                    from ins.cli.main import _os_error_message
                    remove_staging(stage)
                    rec.code, rec.error = 2, _os_error_message(exc, args)
            else:
                remove_staging(stage)
        records[k] = rec
        done.append(k)
        if not quiet:
            what = (f"exit 0 -> {folders[k]}" if rec.code == 0 else f"exit {rec.code}")
            _say(f"process: {len(done)}/{total} {rec.input}: {what} ({rec.time_s:.1f} s)")
        for message in dict.fromkeys(m for c, m in shown if not issubclass(c, _QUIET)):
            _say(f"warning: {rec.input}: {message}")
        if rec.code:
            _say(f"ins process: {rec.input}: error: {rec.error}")
            if rec.traceback:
                sys.stderr.write(rec.traceback)

    try:
        map_tasks(run_one, tasks(), workers=workers, scheduler=args.scheduler,
                  total=total, on_result=finished)
    finally:
        with interrupts.deferred():
            for stage in list(stages.values()):    # the unfinished runs: after the cluster
                remove_staging(stage)
            if made and not os.listdir(out):       # no run finished: OUT as before
                os.rmdir(out)
    if not quiet:
        for line in batch_table(records, names):
            print(line)
    return worst_status(r.code for r in records)


def batch_table(records, names):
    """Lines of the batch's table (one row per run, in the order given)."""
    def num(x, fmt):
        return "-" if x != x else format(x, fmt)
    rows = [("input", "folder", "exit", "GNSS source", "rejected %", "sigma H m",
             "sigma V m", "time s")]
    for r, name in zip(records, names):
        ok = r.code == 0
        rows.append((r.input, name if ok else "-", str(r.code), r.gnss if ok else "-",
                     num(r.rejected_pct, ".2f") if ok else "-",
                     num(r.sigma_h_m, ".4f") if ok else "-",
                     num(r.sigma_v_m, ".4f") if ok else "-", num(r.time_s, ".1f")))
    widths = [max(len(row[j]) for row in rows) for j in range(len(rows[0]))]
    left = (True, True, False, True, False, False, False, False)
    return ["  ".join((c.ljust(w) if lft else c.rjust(w)) for c, w, lft in
                      zip(row, widths, left)).rstrip() for row in rows]


def _say(text):
    sys.stderr.write(text + "\n")
    sys.stderr.flush()
