"""The architecture as a test: ``ins`` sits below ``photogrammetry`` with no way back,
the subpackages depend on each other only as listed in :data:`GRAPH` (lowest first, no
arrow up or sideways), no two modules import each other through any chain (no cycle),
no module reaches a private name (leading underscore) of another package or subpackage
except those in :data:`ALLOWED_PRIVATE` with their reason, and no library module is
longer than :data:`MAX_LINES`.

Every module of both packages is parsed with :mod:`ast` (nothing is imported): all
import statements at any level (also inside functions and ``if`` blocks), the string
arguments of ``importlib.import_module`` / ``__import__``, string constants that name a
module of the upper package (a list of command modules, an entry point written in code),
and attribute access to a private name through an imported module
(``from ins.nav import rotation; rotation._as_stack``).  Private members of classes
(``Class._member``) are not covered.
"""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ins", "photogrammetry")
#: The lower package and the upper one: ``ins`` never imports ``photogrammetry``.
LOWER, UPPER = "ins", "photogrammetry"
#: Longest library module, lines.
MAX_LINES = 600

_INS_BELOW_CLI = {"ins.common", "ins.nav", "ins.io", "ins.lidar", "ins.estimation.core",
                  "ins.estimation.alignment", "ins.estimation.tools", "ins.estimation.pipeline"}
#: The import graph between subpackages (importer -> imported), edges inside one
#: subpackage left out.  The layers, lowest first: common < nav < io < gnss < estimation, lidar
#: < simulate, cli; photogrammetry's imagery < orientation < adjustment, sfm; lunar;
#: simulate; cli.  A new edge is a design decision: add it here, or move the code.
GRAPH = {
    "ins": {"ins.common"},                   # the lazy public API (import_module by name)
    "ins.common": set(),                     # errors, files, text tables, TOML, plot style
    "ins.nav": {"ins.common"},               # Earth, rotations, IMU, mechanization
    "ins.io": {"ins.common", "ins.nav"},     # file formats
    # raw GNSS through RTKLIB's engine: a processing step, not a file format, that reads
    # its solution back with ins.io's .pos reader; below estimation, whose pipeline may
    # run it before the filter (and tight coupling take its satellite data)
    "ins.gnss": {"ins.common", "ins.nav", "ins.io"},
    # ins.estimation in five layers, lowest first (the filter core; the starts; the GNSS
    # measurement models; tools run on a log beside the filter: Allan, time offset,
    # mounting, noise identification; the ins process pipeline, which alone runs RTKLIB
    # on raw observations and reads them through ins.gnss.raw_epochs)
    "ins.estimation.core": {"ins.common", "ins.nav"},
    "ins.estimation.alignment": {"ins.common", "ins.nav", "ins.estimation.core"},
    "ins.estimation.coupling": {"ins.common", "ins.nav", "ins.estimation.core"},
    "ins.estimation.tools": {"ins.common", "ins.nav", "ins.estimation.core"},
    "ins.estimation.pipeline": {"ins.common", "ins.nav", "ins.io", "ins.gnss",
                                "ins.estimation.core", "ins.estimation.alignment",
                                "ins.estimation.coupling", "ins.estimation.tools"},
    "ins.estimation": set(),                 # the package's docstring only
    "ins.lidar": {"ins.common", "ins.nav", "ins.io"},
    # the simulator's GNSS antenna uses the lever-arm model, its scanner the georeferencing
    "ins.simulate": {"ins.common", "ins.nav", "ins.io", "ins.lidar", "ins.estimation.core"},
    # ins.__version__; ins simulate-phone: the GnssLogger twin (ins.simulate's ground
    # journeys and raw GNSS, no camera: ins simulate itself lives in photogrammetry.cli)
    "ins.cli": {"ins", "ins.gnss", "ins.simulate"} | _INS_BELOW_CLI,
    "photogrammetry": {"ins.common"},        # the lazy public API (ins.common.lazy)
    "photogrammetry.imagery": {"ins.common"},
    "photogrammetry.orientation": {"ins.common", "ins.nav", "photogrammetry.imagery"},
    "photogrammetry.adjustment": {"ins.common", "ins.nav", "photogrammetry.orientation"},
    "photogrammetry.sfm": {"ins.common", "photogrammetry.orientation"},
    "photogrammetry.lunar": {"ins.common", "ins.nav"},
    "photogrammetry.simulate": {"ins.common", "ins.nav", "ins.simulate",
                                "photogrammetry.orientation"},
    "photogrammetry.cli": {"ins.cli", "ins.common", "ins.io", "ins.nav", "ins.simulate",
                           "photogrammetry", "photogrammetry.adjustment",
                           "photogrammetry.imagery", "photogrammetry.lunar",
                           "photogrammetry.orientation", "photogrammetry.sfm",
                           "photogrammetry.simulate"},
}

#: Private modules of one subpackage that others may import, with the reason.
ALLOWED_PRIVATE = {
    "ins.estimation.core._filter_kernels": "the compiled feedback of a navigation-state "
    "correction (correct_state) and the IMU-row propagation (propagate_rows) are the "
    "filter's; the fine alignment, the pseudorange update and the pipeline's start run "
    "the same loops",
}

#: Cython declaration files (``.pxd``, C inline functions) of one subpackage that the
#: compiled kernels of another may ``cimport``, with the reason (the ``.pyx``/``.pxd``
#: scan of :func:`test_compiled_sources_follow_the_graph`).
ALLOWED_PRIVATE_PXD = {
    "ins.nav._strapdown": "the filter's propagation inlines the mechanization step",
    "ins.nav._earth": "the filter's covariance kernels inline the WGS84 formulas",
}


# ---------------------------------------------------------------------------------------
# the scanner

def _module_files():
    """(module name, own package, path) of every module of :data:`PACKAGES`."""
    for top in PACKAGES:
        for path in sorted((ROOT / top).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
                yield ".".join(parts), ".".join(parts), path
            else:
                yield ".".join(parts), ".".join(parts[:-1]), path


def _is_package(dotted):
    return (ROOT.joinpath(*dotted.split(".")) / "__init__.py").is_file()


def _is_module(dotted):
    return _is_package(dotted) or ROOT.joinpath(*dotted.split(".")).with_suffix(".py").is_file()


def package_of(dotted):
    """The subpackage that holds the module, package or attribute ``dotted``, or None
    outside :data:`PACKAGES` (numpy, the standard library)."""
    if dotted.split(".")[0] not in PACKAGES:
        return None
    parts = dotted.split(".")
    while parts and not _is_module(".".join(parts)):
        parts.pop()                                   # an attribute: its module's
    name = ".".join(parts)
    return name if _is_package(name) else ".".join(parts[:-1])


def _resolve(name, level, package):
    """Absolute name of ``from <level dots><name>`` in a module of ``package``."""
    if not level:
        return name
    base = package.split(".")
    base = base[:len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def _call_name(func):
    if isinstance(func, ast.Name):
        return func.id
    if isinstance(func, ast.Attribute):
        return func.attr
    return None


def _docstrings(tree):
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef,
                             ast.ClassDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                found.add(id(first.value))
    return found


def references(source, package):
    """(line, dotted name, how) of every module or name that ``source`` (a module of
    ``package``) imports or names, at any level of the code."""
    tree = ast.parse(source)
    docstrings = _docstrings(tree)
    bound = {}                 # local name -> the imported module or name it stands for
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                found.append((node.lineno, a.name, "import"))
                bound[a.asname or a.name.split(".")[0]] = a.name if a.asname else \
                    a.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(node.module, node.level, package)
            for a in node.names:
                target = f"{base}.{a.name}" if a.name != "*" else base
                found.append((node.lineno, target, "from-import"))
                bound[a.asname or a.name] = target
        elif isinstance(node, ast.Call) and _call_name(node.func) in ("import_module",
                                                                       "__import__"):
            if node.args and isinstance(node.args[0], ast.Constant) \
                    and isinstance(node.args[0].value, str):
                text = node.args[0].value
                level = len(text) - len(text.lstrip("."))
                found.append((node.lineno, _resolve(text[level:], level, package),
                              "import_module"))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) \
                and id(node) not in docstrings:
            text = node.value.split(":")[0]
            if text.split(".")[0] == UPPER and all(p.isidentifier() for p in text.split(".")):
                found.append((node.lineno, text, "string"))
    for node in ast.walk(tree):              # private attributes of imported modules
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                and node.value.id in bound and _private(node.attr) \
                and _is_module(bound[node.value.id]):
            found.append((node.lineno, f"{bound[node.value.id]}.{node.attr}", "attribute"))
    return found


def _private(part):
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


def private_owner(dotted):
    """``(owner package, private prefix)`` of the first private part of ``dotted``
    (``ins.cli.main._Progress`` -> ``("ins", "ins.cli.main._Progress")``), or None."""
    parts = dotted.split(".")
    for i, part in enumerate(parts):
        if _private(part):
            return package_of(".".join(parts[:i])), ".".join(parts[:i + 1])
    return None


def scan():
    """{module: (own package, path, references)} of every module."""
    return {name: (package, path, references(path.read_text(encoding="utf-8"), package))
            for name, package, path in _module_files()}


@pytest.fixture(scope="module")
def modules():
    return scan()


# ---------------------------------------------------------------------------------------
# the rules

def test_ins_never_names_photogrammetry(modules):
    bad = [f"{path.relative_to(ROOT)}:{line}: {how} {target}"
           for name, (package, path, refs) in modules.items() if name.split(".")[0] == LOWER
           for line, target, how in refs if target.split(".")[0] == UPPER]
    assert not bad, "ins must not depend on photogrammetry:\n" + "\n".join(bad)


def import_graph(modules):
    """{importer subpackage: {imported subpackages}} of the scanned modules."""
    graph = {}
    for name, (package, path, refs) in modules.items():
        for line, target, how in refs:
            other = package_of(target)
            if other is not None and other != package:
                graph.setdefault(package, set()).add(other)
    return graph


def test_import_graph_is_the_listed_one(modules):
    graph = import_graph(modules)
    where = {}
    for name, (package, path, refs) in modules.items():
        for line, target, how in refs:
            other = package_of(target)
            if other is not None and other != package:
                where.setdefault((package, other), f"{path.relative_to(ROOT)}:{line} {target}")
    packages = {package for package, _, _ in modules.values()}
    assert packages == set(GRAPH), f"subpackages not in GRAPH: {packages - set(GRAPH)}"
    new = sorted((a, b) for a in graph for b in graph[a] - GRAPH.get(a, set()))
    gone = sorted((a, b) for a in GRAPH for b in GRAPH[a] - graph.get(a, set()))
    assert not new, "edges not in GRAPH (add them there or move the code):\n" + "\n".join(
        f"{a} -> {b}  (first: {where[a, b]})" for a, b in new)
    assert not gone, f"edges of GRAPH no module uses any more (remove them): {gone}"
    for a, targets in graph.items():           # no way back from ins to photogrammetry
        if a.split(".")[0] == LOWER:
            assert all(b.split(".")[0] == LOWER for b in targets), (a, targets)


def test_no_private_name_of_another_subpackage(modules):
    bad, allowed_used = [], set()
    for name, (package, path, refs) in modules.items():
        for line, target, how in refs:
            owner = private_owner(target)
            if owner is None or owner[0] is None or owner[0] == package:
                continue
            if owner[1] in ALLOWED_PRIVATE:
                allowed_used.add(owner[1])
                continue
            bad.append(f"{path.relative_to(ROOT)}:{line}: {how} {target} (private to "
                       f"{owner[0]})")
    assert not bad, "private names used across subpackages:\n" + "\n".join(bad)
    assert allowed_used == set(ALLOWED_PRIVATE), \
        f"no longer used (remove from ALLOWED_PRIVATE): {set(ALLOWED_PRIVATE) - allowed_used}"


def _compiled_refs():
    """(path, line, importer package, target module) of every ``import`` / ``cimport`` of
    the Cython sources (``.pyx``, ``.pxd``) of :data:`PACKAGES`."""
    import re
    pattern = re.compile(r"^\s*(?:from\s+([\w.]+)\s+c?import\s+(\w+)|c?import\s+([\w.]+))")
    for top in PACKAGES:
        for path in sorted(p for suffix in ("*.pyx", "*.pxd")
                           for p in (ROOT / top).rglob(suffix)):
            package = ".".join(path.relative_to(ROOT).parts[:-1])
            for k, text in enumerate(path.read_text().splitlines(), 1):
                m = pattern.match(text)
                if m and m.group(1):          # from X cimport Y: the module X.Y or X's name Y
                    both = f"{m.group(1)}.{m.group(2)}"
                    yield path, k, package, both if _is_compiled(both) else m.group(1)
                elif m:
                    yield path, k, package, m.group(3)


def _is_compiled(dotted):
    base = ROOT.joinpath(*dotted.split("."))
    return _is_module(dotted) or any(base.with_suffix(s).is_file() for s in (".pyx", ".pxd"))


def test_compiled_sources_follow_the_graph():
    """The Cython kernels import only downwards (:data:`GRAPH`), and reach into another
    subpackage's private modules only through the listed declaration files."""
    bad, used = [], set()
    for path, line, package, target in _compiled_refs():
        if target.split(".")[0] not in PACKAGES:
            continue                                  # numpy, libc, cython
        other = ".".join(target.split(".")[:-1])
        where = f"{path.relative_to(ROOT)}:{line}: {target}"
        if other != package and other not in GRAPH.get(package, set()):
            bad.append(f"{where} ({package} -> {other} is not in GRAPH)")
        if other != package and target.split(".")[-1].startswith("_"):
            if target in ALLOWED_PRIVATE_PXD:
                used.add(target)
            else:
                bad.append(f"{where} (private to {other})")
    assert not bad, "compiled sources against the layering:\n" + "\n".join(bad)
    assert used == set(ALLOWED_PRIVATE_PXD), \
        f"no longer used (remove from ALLOWED_PRIVATE_PXD): {set(ALLOWED_PRIVATE_PXD) - used}"


def module_graph(modules):
    """{module: {modules it imports}} (any level of the code), within :data:`PACKAGES`."""
    names = set(modules)
    graph = {}
    for name, (package, path, refs) in modules.items():
        for line, target, how in refs:
            parts = target.split(".")
            while parts and ".".join(parts) not in names:
                parts.pop()                        # an attribute: its module's
            other = ".".join(parts)
            if parts and other != name:
                graph.setdefault(name, set()).add(other)
    return graph


def cycles(graph):
    """The strongly connected components of more than one node (Tarjan, iterative)."""
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph.get(w, ())))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    found.append(sorted(comp))
    return found


def test_no_import_cycle_between_modules(modules):
    graph = module_graph(modules)
    # a package's __init__ is the parent of its modules, not an import of them
    for name in list(graph):
        graph[name] = {m for m in graph[name] if not name.startswith(m + ".")}
    found = cycles(graph)
    assert not found, "modules that import each other (through any chain):\n" + "\n".join(
        " <-> ".join(c) for c in found)


def test_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_library_module_over_the_line_limit():
    long = []
    for top in PACKAGES:
        for path in sorted((ROOT / top).rglob("*.py")):
            n = len(path.read_text(encoding="utf-8").splitlines())
            if n > MAX_LINES:
                long.append(f"{path.relative_to(ROOT)}: {n} lines")
    assert not long, f"modules over {MAX_LINES} lines (split them by concept):\n" + \
        "\n".join(long)


# ---------------------------------------------------------------------------------------
# the scanner finds what it must (so that the rules above can fail)

SNIPPET = '''
"""Docstring naming photogrammetry.orientation.camera, not an import."""
import importlib
import ins.nav.rotation as rot
from ins.nav import rotation


def f():
    from photogrammetry.orientation.camera import read_camera
    if True:
        import photogrammetry.orientation.exposure
    importlib.import_module("photogrammetry.orientation.rotation")
    __import__("photogrammetry")
    importlib.import_module(".cli_allan", "ins")
    return rot._hidden, rotation.public


MODULES = ["photogrammetry.cli.eo"]
ENTRY = "photogrammetry.cli.simulate:add_parser"
MESSAGE = "run photogrammetry eo first"


class C:
    def g(self):
        from ..cli.main import _Progress
        from . import _kernels
        from .._textio import read_toml
'''


def test_scanner_finds_imports_at_every_level():
    refs = references(SNIPPET, "ins.simulate")
    targets = {(target, how) for _, target, how in refs}
    for expected in [("photogrammetry.orientation.camera.read_camera", "from-import"),
                     ("photogrammetry.orientation.exposure", "import"),
                     ("photogrammetry.orientation.rotation", "import_module"),
                     ("photogrammetry", "import_module"),
                     ("photogrammetry.cli.eo", "string"),
                     ("photogrammetry.cli.simulate", "string"),
                     ("ins.nav.rotation._hidden", "attribute"),
                     ("ins.cli.main._Progress", "from-import"),
                     ("ins.simulate._kernels", "from-import"),
                     ("ins._textio.read_toml", "from-import")]:
        assert expected in targets, expected
    assert not any("Docstring" in t or "eo first" in t for t, _ in targets)
    assert ("ins.nav.rotation.public", "attribute") not in targets        # not private
    assert ("photogrammetry.orientation.camera", "string") not in targets         # the docstring


def test_private_owner_and_package_of():
    assert package_of("ins.cli.main._Progress") == "ins.cli"
    assert package_of("ins.simulate.folder.simulate_flight") == "ins.simulate"
    assert package_of("ins.simulate") == "ins.simulate"
    assert package_of("photogrammetry.lunar.fisheye") == "photogrammetry.lunar"
    assert package_of("numpy.linalg") is None
    assert private_owner("ins.cli.main._Progress") == ("ins.cli", "ins.cli.main._Progress")
    assert private_owner("ins._textio.read_toml") == ("ins", "ins._textio")
    assert private_owner("ins.simulate._kernels") == ("ins.simulate", "ins.simulate._kernels")
    assert private_owner("ins.nav.stacks.as_stack") is None
    assert private_owner("ins.simulate.__init__") is None              # dunder: not private
    # the private rule as it applies to the snippet's module (in ins.simulate)
    cross = [t for _, t, _ in references(SNIPPET, "ins.simulate")
             if private_owner(t) and private_owner(t)[0] != "ins.simulate"]
    assert set(cross) == {"ins.nav.rotation._hidden", "ins.cli.main._Progress", "ins._textio.read_toml"}
