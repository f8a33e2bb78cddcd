"""Whether the compiled kernels (Cython ``.pyx``, built in place by ``pip install -e .``)
were built from the sources beside them.

An editable install keeps running the extension modules of its last build: after a
``git pull`` or an edit of a ``.pyx`` or of a ``.pxd`` it cimports, without a rebuild,
the program would run old kernels.  :func:`stale_kernels` names them (the CLI warns, the
test session refuses to start).  An installation into site-packages (from a wheel, built
there once) is not checked: its files' times are those of the installation.
"""
import re
from pathlib import Path

__all__ = ["stale_kernels"]

_PACKAGE = Path(__file__).resolve().parents[1]          # ins/
_CIMPORT = re.compile(r"^\s*(?:from\s+([\w.]+)\s+cimport\s+(\w+)|cimport\s+([\w.]+))", re.M)


def _pxd_deps(path, seen, root):
    """``seen`` plus the ``.pxd`` files that ``path`` cimports from the packages,
    recursively."""
    for m in _CIMPORT.finditer(path.read_text()):
        names = (f"{m.group(1)}.{m.group(2)}", m.group(1)) if m.group(1) else (m.group(3),)
        for dotted in names:
            pxd = root.joinpath(*dotted.split(".")).with_suffix(".pxd")
            if pxd.is_file():
                if pxd not in seen:
                    seen.add(pxd)
                    _pxd_deps(pxd, seen, root)
                break
    return seen


def stale_kernels(package=None):
    """Compiled kernels of a package whose built module is missing or older than their
    ``.pyx`` or a ``.pxd`` it cimports.

    Parameters
    ----------
    package : path-like, optional
        The package's folder (default: ``ins``'s own); cimports are resolved from its
        parent folder.

    Returns
    -------
    list of str
        Paths of the stale ``.pyx`` files relative to the package's parent (empty when
        every module is current, or for a package installed into site-packages).
    """
    package = _PACKAGE if package is None else Path(package)
    if {"site-packages", "dist-packages"} & set(package.parts):
        return []
    root = package.parent
    stale = []
    for pyx in sorted(package.rglob("*.pyx")):
        built = [p for p in pyx.parent.glob(pyx.stem + ".*") if p.suffix in (".so", ".pyd")]
        newest = max(p.stat().st_mtime for p in _pxd_deps(pyx, {pyx}, root))
        if not built or max(p.stat().st_mtime for p in built) < newest:
            stale.append(pyx.relative_to(root).as_posix())
    return stale
