"""Lazy public API of a package (PEP 562): names imported from their modules on first use,
so that importing the package (or its command line) stays light."""
import importlib

__all__ = ["lazy_api"]


def lazy_api(package, table):
    """``(__getattr__, __dir__)`` for package ``package`` (its ``__name__``) whose public
    names are ``table``: {name: module relative to the package}."""
    def __getattr__(name):
        if name in table:
            value = getattr(importlib.import_module(f".{table[name]}", package), name)
            import sys
            setattr(sys.modules[package], name, value)
            return value
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        import sys
        return sorted(set(vars(sys.modules[package])) | set(table))

    return __getattr__, __dir__
