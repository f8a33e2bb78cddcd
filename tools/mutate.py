"""Mutation testing by hand: apply one text mutation, run a pytest selection, report
whether the tests kill it, and always revert.

    python tools/mutate.py FILE OLD NEW [-- PYTEST_ARGS...]
    python tools/mutate.py --batch MUTATIONS.toml [--only NAME ...]

``OLD`` must occur exactly once in ``FILE`` (give more context otherwise, or
``--occurrence K``).  By default the mutation is applied in a scratch copy of the
working tree (the files git tracks or would track), run there with ``PYTHONPATH``
pointing at it, and the copy is deleted afterwards: the real tree is never modified,
even by Ctrl-C or a crash, and other work in it is not disturbed.  ``--in-place``
edits the real file instead and restores its exact bytes in a ``finally`` (also on
Ctrl-C and SIGTERM), checking the restore.

The unmutated selection is run first (``--no-baseline`` skips it): a mutation counts as
killed only when the baseline passes and the mutated run fails.  The test caches of
``tests/benchdata.py`` are keyed on the sources, so a mutated simulator or Earth model
is simulated afresh; a mutated ``.pyx``/``.pxd`` is recompiled in the scratch copy
(:func:`build_compiled`, a few minutes for all the kernels on the 2-core VM).

A batch file (TOML) lists mutations::

    [[mutation]]
    name = "transport rate sign"
    file = "ins/nav/earth.py"
    old = "return (v_east / (rn + h), -v_north"
    new = "return (-v_east / (rn + h), -v_north"
    tests = ["tests/test_mechanization.py", "tests/test_earth.py"]

Output: one line per mutation (killed / SURVIVED / error) with the first failing tests,
and a Markdown table at the end.  Exit status 0 when every mutation was killed, 1 when
one survived, 2 on a usage error or a failing baseline.
"""
import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_TESTS = ["tests"]


class Usage(Exception):
    pass


def _tree_files(root):
    out = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=root,
                         capture_output=True, check=True).stdout
    return [p for p in out.decode().split("\0") if p]


#: Sources compiled at install (setup.py): a mutation of one is rebuilt in the scratch copy.
COMPILED_SUFFIXES = (".pyx", ".pxd")


def make_scratch(root):
    """A copy of the working tree's source files (mtimes kept) and of its built extension
    modules (the compiled kernels, ``*.so``) in a new temporary folder."""
    scratch = Path(tempfile.mkdtemp(prefix="mutate-"))
    built = [p.relative_to(root).as_posix() for top in ("ins", "photogrammetry")
             for p in (root / top).rglob("*.so")]
    for rel in _tree_files(root) + built:
        src = root / rel
        if not src.is_file():
            continue
        dst = scratch / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dst)
    return scratch


def mutated_text(text, old, new, occurrence=None):
    n = text.count(old)
    if n == 0:
        raise Usage(f"the text to mutate was not found: {old!r}")
    if occurrence is None:
        if n > 1:
            raise Usage(f"the text to mutate occurs {n} times (add context or give "
                        f"--occurrence): {old!r}")
        occurrence = 1
    if not 1 <= occurrence <= n:
        raise Usage(f"--occurrence {occurrence}: the text occurs {n} times")
    start = -1
    for _ in range(occurrence):
        start = text.index(old, start + 1)
    line = text.count("\n", 0, start) + 1
    return text[:start] + new + text[start + len(old):], line


def _env(tree, scratch_caches):
    env = dict(os.environ)
    env["PYTHONPATH"] = str(tree) + (os.pathsep + env["PYTHONPATH"]
                                     if env.get("PYTHONPATH") else "")
    # the shared dataset does not depend on our code: reuse the real tree's
    env.setdefault("INS_SHARED_DIR", str(ROOT.parent / "shared"))
    env.setdefault("INS_BENCH_DATA", str(ROOT / ".cache" / "ins-bench-data"))
    if scratch_caches:        # mutated simulators' flights die with the scratch copy
        env["INS_TEST_FLIGHTS"] = str(tree / ".cache" / "ins-test-flights")
    else:
        env.setdefault("INS_TEST_FLIGHTS", str(ROOT / ".cache" / "ins-test-flights"))
    return env


def build_compiled(tree):
    """Rebuild the compiled kernels of ``tree`` in place (``setup.py build_ext``; needs
    Cython, in the ``test`` extra).  Raises :class:`Usage` with the compiler's output."""
    try:
        import Cython  # noqa: F401
    except ImportError:
        raise Usage("a mutated .pyx/.pxd must be recompiled and Cython is not installed "
                    "(pip install -e '.[test]')") from None
    proc = subprocess.run([sys.executable, "-c", "import setup; setup.build_inplace()"],
                          cwd=tree, capture_output=True, text=True)
    if proc.returncode:
        tail = (proc.stdout + proc.stderr).strip().splitlines()[-8:]
        raise Usage("the mutated kernels do not compile:\n" + "\n".join(tail))


def run_pytest(tree, tests, scratch_caches, timeout, first=False):
    """(return code, failed test ids, seconds) of the selection run in ``tree``."""
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rfE",
           "--no-header", *(["-x"] if first else []), *tests]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, cwd=tree, env=_env(tree, scratch_caches),
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout", [], time.perf_counter() - t0
    failed = re.findall(r"^(?:FAILED|ERROR) (\S+)", proc.stdout, flags=re.M)
    if proc.returncode not in (0, 1) and not failed:
        tail = (proc.stdout + proc.stderr).strip().splitlines()[-5:]
        failed = ["(pytest exit %d: %s)" % (proc.returncode, " | ".join(tail))]
    return proc.returncode, failed, time.perf_counter() - t0


class _Restore:
    """Put back the exact bytes of a file edited in place, whatever happens."""

    def __init__(self, path):
        self.path = path
        self.original = path.read_bytes()
        self.stat = path.stat()

    def __enter__(self):
        self._old_term = signal.signal(signal.SIGTERM, self._term)
        return self

    def _term(self, signum, frame):
        raise KeyboardInterrupt

    def __exit__(self, *exc):
        # hold off Ctrl-C while the bytes are put back
        old_int = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            self.path.write_bytes(self.original)
            os.utime(self.path, ns=(self.stat.st_atime_ns, self.stat.st_mtime_ns))
            if self.path.read_bytes() != self.original:
                raise RuntimeError(f"could not restore {self.path}")
        finally:
            signal.signal(signal.SIGINT, old_int)
            signal.signal(signal.SIGTERM, self._old_term)
        return False


def run_one(m, tree, in_place, baseline_cache, timeout, first=False, verbose=True):
    """Run one mutation; returns its result dict."""
    tests = m.get("tests") or DEFAULT_TESTS
    key = tuple(tests)
    if baseline_cache is not None and key not in baseline_cache:
        code, failed, secs = run_pytest(tree, tests, scratch_caches=False, timeout=timeout)
        baseline_cache[key] = (code, failed)
        if verbose:
            print(f"baseline {' '.join(tests)}: exit {code} ({secs:.0f} s)", flush=True)
    if baseline_cache is not None and baseline_cache[key][0] != 0:
        return dict(m, status="baseline fails", failed=baseline_cache[key][1], line=None,
                    seconds=0.0)
    path = tree / m["file"]
    text = path.read_text()
    new_text, line = mutated_text(text, m["old"], m["new"], m.get("occurrence"))
    compiled = path.suffix in COMPILED_SUFFIXES
    if compiled and in_place:
        raise Usage(f"{m['file']}: a compiled source is mutated in a scratch copy only "
                    f"(drop --in-place)")
    if in_place:
        with _Restore(path):
            path.write_text(new_text)
            code, failed, secs = run_pytest(tree, tests, scratch_caches=False,
                                            timeout=timeout, first=first)
    else:
        try:
            path.write_text(new_text)
            if compiled:
                build_compiled(tree)
            code, failed, secs = run_pytest(tree, tests, scratch_caches=True,
                                            timeout=timeout, first=first)
        finally:
            path.write_text(text)
            if compiled:
                build_compiled(tree)
    if code == 0:
        status = "SURVIVED"
    elif code in (1, "timeout"):
        status = "killed" if code == 1 else "killed (timeout)"
    else:
        status = f"error (pytest exit {code})"
    return dict(m, status=status, failed=failed, line=line, seconds=secs)


def _load_batch(path, only):
    with open(path, "rb") as f:
        doc = tomllib.load(f)
    muts = doc.get("mutation", [])
    for i, m in enumerate(muts):
        missing = {"name", "file", "old", "new"} - set(m)
        if missing:
            raise Usage(f"{path}: mutation {i + 1} lacks {', '.join(sorted(missing))}")
    if only:
        muts = [m for m in muts if m["name"] in only]
        if not muts:
            raise Usage(f"--only: no mutation named {', '.join(only)} in {path}")
    return muts


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    pytest_args = []
    if "--" in argv:
        i = argv.index("--")
        argv, pytest_args = argv[:i], argv[i + 1:]
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="Arguments after -- are the pytest selection "
                                        "(default: tests).")
    ap.add_argument("file", nargs="?", help="file to mutate, relative to the repository")
    ap.add_argument("old", nargs="?", help="exact text to replace")
    ap.add_argument("new", nargs="?", help="replacement text")
    ap.add_argument("--occurrence", type=int, help="which occurrence of OLD (1-based)")
    ap.add_argument("--batch", type=Path, help="TOML file of [[mutation]] entries")
    ap.add_argument("--only", nargs="+", default=[], help="names from the batch to run")
    ap.add_argument("--in-place", action="store_true",
                    help="edit the real file (restored afterwards) instead of a scratch copy")
    ap.add_argument("--no-baseline", action="store_true",
                    help="do not run the unmutated selection first")
    ap.add_argument("--timeout", type=float, default=1800.0, help="per pytest run, s")
    ap.add_argument("--pytest-arg", action="append", default=[], metavar="ARG",
                    help="extra pytest argument for every run, e.g. "
                         "--pytest-arg=--deselect=tests/test_x.py::test_y (repeatable)")
    ap.add_argument("-x", "--first", action="store_true",
                    help="stop each mutated run at its first failing test (faster)")
    args = ap.parse_args(argv)
    try:
        if args.batch:
            if args.file:
                raise Usage("give either --batch or FILE OLD NEW")
            muts = _load_batch(args.batch, args.only)
            for m in muts:
                m["tests"] = list(m.get("tests") or DEFAULT_TESTS) + args.pytest_arg
        else:
            if not (args.file and args.old is not None and args.new is not None):
                raise Usage("FILE OLD NEW are required (or --batch)")
            muts = [dict(name=f"{args.file}: {args.old!r} -> {args.new!r}", file=args.file,
                         old=args.old, new=args.new, occurrence=args.occurrence,
                         tests=(pytest_args or DEFAULT_TESTS) + args.pytest_arg)]
        for m in muts:                       # check every mutation applies before running
            mutated_text((ROOT / m["file"]).read_text(), m["old"], m["new"],
                         m.get("occurrence"))
    except (Usage, OSError, tomllib.TOMLDecodeError) as exc:
        print(f"mutate: {exc}", file=sys.stderr)
        return 2

    tree = ROOT if args.in_place else make_scratch(ROOT)
    baseline = None if args.no_baseline else {}
    results = []
    try:
        for m in muts:
            r = run_one(m, tree, args.in_place, baseline, args.timeout, first=args.first)
            results.append(r)
            where = f"{r['file']}:{r['line']}" if r["line"] else r["file"]
            first = ", ".join(r["failed"][:3])
            print(f"{r['status']:>9}  {r['name']}  ({where}, {r['seconds']:.0f} s)"
                  + (f"  <- {first}" if first else ""), flush=True)
    except KeyboardInterrupt:
        print("mutate: interrupted; the mutation was reverted", file=sys.stderr)
        return 130
    finally:
        if not args.in_place:
            shutil.rmtree(tree, ignore_errors=True)
    print("\n| mutation | where | result | killed by |\n|---|---|---|---|")
    for r in results:
        where = f"{r['file']}:{r['line']}" if r["line"] else r["file"]
        print(f"| {r['name']} | {where} | {r['status']} | "
              f"{', '.join(r['failed'][:3]) or '-'} |")
    if any(r["status"] == "baseline fails" for r in results):
        return 2
    return 1 if any(r["status"] == "SURVIVED" for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
