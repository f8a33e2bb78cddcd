"""Sphinx configuration: the API reference from the numpydoc docstrings, with the Markdown
pages (README, docs/*.md) read by myst-parser.  Built by ``make docs``."""
import os
import sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(__file__))

import api_lists  # docs/api_lists.py: the public API tables (needs the path above)

project = "insphoto"
author = "insphoto contributors"
copyright = "insphoto contributors"
release = version = "0.1.0"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_parser",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_templates", "Thumbs.db", ".DS_Store"]
templates_path = ["_templates"]

# --- autodoc / autosummary -----------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"            # the docstrings state types, units and frames
autodoc_preserve_defaults = True      # signatures show `np.zeros(3)`, not its repr
# Optional extras are imported lazily inside functions; nothing to mock.
autodoc_mock_imports = []

# --- numpydoc --------------------------------------------------------------------------
numpydoc_show_class_members = False   # autodoc documents the members itself
numpydoc_class_members_toctree = False
numpydoc_validation_checks = set()    # docstring style checks off: markup errors still fail
numpydoc_xref_param_type = False
numpydoc_attributes_as_param_list = True

# --- myst ------------------------------------------------------------------------------
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3

# --- HTML ------------------------------------------------------------------------------
html_theme = "furo"
html_title = "insphoto"
html_static_path = []

# The public API tables of ``ins`` and ``photogrammetry`` (their lazy ``__all__``) are
# written from the packages' ``_LAZY`` tables at each build, so that they cannot drift.
api_lists.write(os.path.join(os.path.dirname(__file__), "api", "generated"))
