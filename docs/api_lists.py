"""The public API tables of the top-level packages, written at build time (``conf.py``).

``ins.__all__`` and ``photogrammetry.__all__`` are lazy: each name lives in a submodule
named by the package's ``_LAZY`` table.  This writes one autosummary table per package
that points each name at the object where it is defined (and so documented).
"""
import importlib
import os


def lines(package):
    """reST of an autosummary table of ``package.__all__`` (lazy names resolved)."""
    pkg = importlib.import_module(package)
    lazy = getattr(pkg, "_LAZY", {})
    out = [".. autosummary::", "   :nosignatures:", ""]
    for name in sorted(pkg.__all__, key=str.lower):
        if name in lazy:
            out.append(f"   ~{package}.{lazy[name]}.{name}")
        else:                                   # defined in (or imported into) __init__
            obj = getattr(pkg, name)
            out.append(f"   ~{obj.__module__}.{name}")
    return "\n".join(out) + "\n"


def write(out_dir):
    os.makedirs(out_dir, exist_ok=True)
    for package in ("ins", "photogrammetry"):
        text = lines(package)
        path = os.path.join(out_dir, f"{package}_public.rst.inc")
        old = None
        if os.path.exists(path):
            with open(path) as f:
                old = f.read()
        if old != text:                          # unchanged file: no needless rebuild
            with open(path, "w") as f:
                f.write(text)
