"""The workflow guides (docs/guide-*.md, and docs/refusals.md's examples) run as tests,
as docs/tour.md is; and docs/refusals.md holds every refusal message of the code.

Each page's ```sh blocks run in order, each as one bash script (``set -euo pipefail``),
in one empty folder per page, with the commands a user types: ``ins``,
``photogrammetry`` and ``python`` of this environment (this checkout first on the
path), ``data/`` and ``tools/`` of the repository beside the folder as in a checkout,
and ``../shared`` (the real data sets, outside the repository) where it exists.  The
```text block under a block is an excerpt of what it prints (stdout and stderr): each
of its lines must match a line of the printout, in order (words exactly, numbers
within 1 %, as in the tour; a line ``...`` stands for lines left out, a
``...`` within a line for any text: a time taken, a temporary path).

A page states what it needs in MyST comment lines (not rendered)::

    % guide-needs: path ../shared/real/rtklib_static_pair/07590920.05n
    % guide-needs: module laspy

and is skipped, with the reason, when one is missing.  After the page has run, its
``% guide-files:`` line names files that must exist and be non-empty.
"""
import os
import re
import subprocess
import sys
import time
from importlib.util import find_spec
from pathlib import Path

import pytest
from test_tour import FENCE, NUMBER, same_printout

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
GUIDES = sorted(DOCS.glob("guide-*.md")) + [DOCS / "refusals.md"]
NEEDS = re.compile(r"^% guide-needs: (path|module) (\S+)\s*$", re.MULTILINE)
FILES = re.compile(r"^% guide-files: (.+)$", re.MULTILINE)


def sh_blocks(text):
    """``[(script, expected excerpt or None)]`` of a page's sh blocks, in order."""
    fences = [(m.group(1), m.group(2)) for m in FENCE.finditer(text)]
    out = []
    for k, (lang, body) in enumerate(fences):
        if lang == "sh":
            after = fences[k + 1] if k + 1 < len(fences) else None
            out.append((body, after[1] if after and after[0] == "text" else None))
    return out


#: Numbers of a printout within 1 % (or 2 units of their last digit): the runs are seeded.
REL = 0.01


def _close(g, e, rel=REL):
    decimals = len(e.split(".")[1].split("e")[0]) if "." in e else 0
    return abs(float(g) - float(e)) <= max(rel * abs(float(e)), 2 * 10.0 ** -decimals)


def line_matches(got, want):
    """``want`` as :func:`test_tour.same_printout` reads it; a ``...`` within the line
    stands for any text (a time taken, a temporary path)."""
    if "..." not in want:
        return same_printout(got, want, rel=REL)
    numbers = []
    pattern = []
    for k, part in enumerate(want.strip().split("...")):
        if k:
            pattern.append(".*?")
        pos = 0
        for m in NUMBER.finditer(part):
            pattern.append(re.escape(part[pos:m.start()]) + f"({NUMBER.pattern})")
            numbers.append(m.group())
            pos = m.end()
        pattern.append(re.escape(part[pos:]))
    m = re.fullmatch("".join(pattern), got.strip())
    return bool(m) and all(_close(g, e) for g, e in zip(m.groups(), numbers))


def excerpt_matches(got, expected):
    """None when every line of ``expected`` (but ``...``) matches a line of ``got`` in
    order, else the first line that does not."""
    lines = [g.rstrip() for g in got.splitlines()]
    i = 0
    for want in expected.splitlines():
        if not want.strip() or want.strip() == "...":
            continue
        while i < len(lines) and not line_matches(lines[i], want):
            i += 1
        if i == len(lines):
            return want
        i += 1
    return None


def test_excerpt_comparison():
    got = "reading a\n12 IMU epochs, 3.05 m\nprocessed in 2.1 s\nwrote x\n"
    assert excerpt_matches(got, "12 IMU epochs, 3.04 m\n...\nwrote x\n") is None
    assert excerpt_matches(got, "wrote x\n12 IMU epochs, 3.05 m\n") == "12 IMU epochs, 3.05 m"
    assert excerpt_matches(got, "12 IMU epochs, 3.9 m\n") == "12 IMU epochs, 3.9 m"
    assert excerpt_matches(got, "processed in ... s\n12 IMU") == "12 IMU"
    assert line_matches("a 3.05 m, took 2.1 s", "a 3.0 m, took ... s")
    assert not line_matches("a 3.55 m, took 2.1 s", "a 3.0 m, took ... s")


def test_blocks_are_found():
    page = "x\n```sh\nins a\n```\n\n```text\nout\n```\n```sh\nins b\n```\n"
    assert sh_blocks(page) == [("ins a\n", "out\n"), ("ins b\n", None)]


def test_every_guide_is_in_the_toctree():
    index = (DOCS / "index.md").read_text()
    assert len(GUIDES) > 1, "no docs/guide-*.md"
    for page in GUIDES:
        assert re.search(rf"^{page.stem}$", index, re.MULTILINE), page.name


def _environment(folder):
    """The user's shell: this checkout's packages, the venv's commands, a checkout's
    data/ and tools/ beside the folder, ../shared where it exists."""
    for name in ("data", "tools"):
        (folder / name).symlink_to(ROOT / name)
    shared = ROOT.parent / "shared"
    if shared.exists():
        (folder.parent / "shared").symlink_to(shared.resolve())
    env = dict(os.environ)
    env["PATH"] = os.path.dirname(sys.executable) + os.pathsep + env.get("PATH", "")
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get(
        "PYTHONPATH", "").split(os.pathsep) if p])
    env["MPLBACKEND"] = "Agg"
    env.pop("PYTHONHASHSEED", None)
    return env


def _missing(text):
    for kind, what in NEEDS.findall(text):
        if kind == "module" and find_spec(what) is None:
            return f"needs the module {what}"
        if kind == "path" and not (ROOT / what).exists():
            return f"needs {what} (outside the repository)"
    return None


@pytest.mark.parametrize("page", GUIDES, ids=[p.stem for p in GUIDES])
def test_guide_runs_and_prints_what_it_shows(page, tmp_path):
    text = page.read_text()
    reason = _missing(text)
    if reason:
        pytest.skip(f"{page.name}: {reason}")
    folder = tmp_path / "work"
    folder.mkdir()
    env = _environment(folder)
    blocks = sh_blocks(text)
    assert blocks, f"{page.name} has no sh block"
    times = []
    for k, (script, expected) in enumerate(blocks):
        t0 = time.perf_counter()
        run = subprocess.run(["bash", "-c", "set -euo pipefail\n" + script], cwd=folder,
                             env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             text=True)
        times.append(time.perf_counter() - t0)
        assert run.returncode == 0, (f"{page.name} sh block {k + 1} failed (exit "
                                     f"{run.returncode}):\n{script}\n{run.stdout[-4000:]}")
        if expected is not None:
            bad = excerpt_matches(run.stdout, expected)
            assert bad is None, (f"{page.name} sh block {k + 1}: the page shows\n  {bad}\n"
                                 f"which is not in what it printed:\n{run.stdout[-6000:]}")
    for names in FILES.findall(text):
        for name in names.split():
            path = folder / name
            assert path.is_file() and path.stat().st_size > 0, f"{page.name}: {name}"
    print(f"{page.name}: " + ", ".join(f"block {k + 1} {t:.1f} s" for k, t in
                                       enumerate(times)))


# --- docs/refusals.md: every refusal message of the code is on the page ---------------
#
# (file, function or functions "a|b", what to collect): "all" every string of the function but its
# docstring; "QualityError"/"InputError" the strings of ``raise X(...)``; "warn" those of
# ``warnings.warn(...)``; "why" those assigned to ``why``/``what`` or passed to
# ``_unadjusted``.
REFUSALS = [
    ("ins/estimation/pipeline/trust.py", "check_start", {"InputError"}),
    ("ins/estimation/pipeline/trust.py", "assess_quality", {"all"}),
    ("ins/estimation/pipeline/trust.py", "_causes", {"all"}),
    ("ins/cli/process.py", "_cmd_process|run_into", {"QualityError"}),
    ("ins/estimation/core/error_model.py", "checked_std", {"QualityError"}),
    ("ins/estimation/core/measurements.py", "kalman_update", {"QualityError"}),
    ("ins/estimation/core/smoother.py", "_not_positive", {"all"}),
    ("ins/estimation/core/smoother.py", "rts_errors", {"QualityError"}),
    ("photogrammetry/adjustment/batch.py", "check_quality", {"QualityError"}),
    ("photogrammetry/adjustment/quality.py", "block_quality", {"all"}),
    ("photogrammetry/adjustment/quality.py", "unadjusted_quality", {"all"}),
    ("photogrammetry/adjustment/block.py", "_screen_pairs", {"warn", "why"}),
    ("photogrammetry/adjustment/block.py", "adjust_block", {"why"}),
    ("ins/cli/strip_check.py", "_cmd_strip_check", {"QualityError"}),
    ("ins/gnss/rtklib_engine.py", "poor_reason", {"all"}),
    ("ins/cli/gnss.py", "_cmd_gnss", {"QualityError"}),
    ("ins/cli/align.py", "_cmd_align", {"QualityError"}),
    ("ins/cli/align.py", "_gyro_error_text", {"all"}),
    ("ins/cli/allan.py", "_cmd_allan", {"QualityError"}),
]


def _strings(node):
    """The literal text of the string nodes under ``node``: each constant piece of an
    f-string (between its placeholders) on its own, format specs left out."""
    import ast
    out = []

    def visit(n):
        if isinstance(n, ast.JoinedStr):
            for v in n.values:
                if isinstance(v, ast.Constant) and isinstance(v.value, str):
                    out.append(v.value)
                elif isinstance(v, ast.FormattedValue):
                    visit(v.value)
            return
        if isinstance(n, ast.Constant) and isinstance(n.value, str):
            out.append(n.value)
            return
        for child in ast.iter_child_nodes(n):
            visit(child)
    visit(node)
    return out


def refusal_fragments(path, function, what):
    """The constant pieces of the messages ``function`` of ``path`` builds (see
    :data:`REFUSALS`), those with a space in them (message text, not keys)."""
    import ast
    tree = ast.parse((ROOT / path).read_text())
    names = function.split("|")             # where the code may have moved it
    fns = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name in names]
    assert fns, f"{path}: no function {function} (update REFUSALS)"
    found = []
    body = [stmt for fn in fns for stmt in (
        fn.body[1:] if (fn.body and isinstance(fn.body[0], ast.Expr) and isinstance(
            getattr(fn.body[0], "value", None), ast.Constant)) else fn.body)]
    for stmt in body:
        for n in ast.walk(stmt):
            name = None
            if isinstance(n, ast.Raise) and isinstance(n.exc, ast.Call):
                name = getattr(n.exc.func, "id", None)
            if "all" in what and n is stmt:
                found += _strings(stmt)
            if name in what:
                found += _strings(n.exc)
            if isinstance(n, ast.Call):
                f = n.func
                called = getattr(f, "attr", None) or getattr(f, "id", None)
                if "warn" in what and called == "warn":
                    found += _strings(n)
                if "why" in what and called == "_unadjusted":
                    found += _strings(n)
            if "why" in what and isinstance(n, ast.Assign) and any(
                    getattr(t, "id", None) in ("why", "what") for t in n.targets):
                found += _strings(n.value)
    pieces = [" ".join(s.split()) for s in found]
    return [p for p in dict.fromkeys(pieces) if " " in p and len(p) >= 6]


def _normalized(text):
    return " ".join(text.split())


def test_refusal_fragments_are_found():
    pieces = refusal_fragments("ins/estimation/pipeline/trust.py", "assess_quality", {"all"})
    assert "GNSS measurements rejected by the innovation test (" in " ".join(pieces)
    assert "from runs of rejected position fixes (" in pieces


@pytest.mark.parametrize("path,function,what", REFUSALS,
                         ids=[f"{Path(p).stem}.{f}" for p, f, _ in REFUSALS])
def test_every_refusal_message_is_on_the_refusals_page(path, function, what):
    page = _normalized((DOCS / "refusals.md").read_text())
    pieces = refusal_fragments(path, function, what)
    assert pieces, f"{path}:{function}: no message found"
    missing = [p for p in pieces if p not in page]
    assert not missing, (f"docs/refusals.md lacks these pieces of the messages of "
                         f"{path}:{function} (quote them as the code writes them):\n"
                         + "\n".join(repr(p) for p in missing))


def test_every_function_that_refuses_is_listed():
    """A new ``raise QualityError("...")`` anywhere in the packages must be added to
    :data:`REFUSALS` (and so its message to docs/refusals.md)."""
    import ast
    listed = {(p, name) for p, f, _ in REFUSALS for name in f.split("|")}
    missing = []
    for package in ("ins", "photogrammetry"):
        for path in sorted((ROOT / package).rglob("*.py")):
            tree = ast.parse(path.read_text())
            for fn in ast.walk(tree):
                if not isinstance(fn, ast.FunctionDef):
                    continue
                for n in ast.walk(fn):
                    if (isinstance(n, ast.Raise) and isinstance(n.exc, ast.Call)
                            and getattr(n.exc.func, "id", None) == "QualityError"
                            and any(" " in t for t in _strings(n.exc))):
                        rel = str(path.relative_to(ROOT))
                        if (rel, fn.name) not in listed:
                            missing.append(f"{rel}:{fn.name}")
                        break
    assert not missing, ("refusals not in REFUSALS (add them, and their messages to "
                         "docs/refusals.md): " + ", ".join(sorted(set(missing))))


def test_pair_status_texts_are_on_the_refusals_page():
    from photogrammetry.adjustment.coplanarity import STATUS_TEXT
    page = _normalized((DOCS / "refusals.md").read_text())
    for text in STATUS_TEXT.values():
        if text != "ok":
            assert _normalized(text) in page, text
