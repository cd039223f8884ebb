"""Sphinx configuration of vsj's documentation (``make docs`` builds it offline into
docs/_build/html with warnings as errors)."""

from __future__ import annotations

import os
import sys
import types
from pathlib import Path

import vsj

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).parent / "_ext"))
# the gallery's scripts draw into files, never onto a screen
os.environ.setdefault("MPLBACKEND", "Agg")

project = "vsj"
author = "the vsj authors"
copyright = "2026, the vsj authors"
release = version = vsj.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpydoc",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",  # MathJax 3 shipped with the site: no CDN
    "sphinxarg.ext",
    "sphinx_gallery.gen_gallery",
    "myst_parser",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "**/*.ipynb", "**/*.py.md5", "**/*.codeobj.json"]
default_role = "py:obj"  # `vsj.params` in a docstring links to its page

# -- API reference -----------------------------------------------------------------------
# one page per public module, written from the sources before the build (docs/_ext)
import api_pages  # noqa: E402

api_pages.write_pages(Path(__file__).parent / "reference" / "generated")
autosummary_generate = False     # the summary tables only; the pages are written above
autodoc_default_options: dict[str, object] = {}
autodoc_typehints = "none"       # the docstrings give types and units
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_validation_checks: set[str] = set()

# -- MyST --------------------------------------------------------------------------------
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# -- executed examples -------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": [str(ROOT / "examples" / "getting_started"), str(ROOT / "examples" / "guide")],
    "gallery_dirs": ["getting-started/examples", "user-guide/examples"],
    "filename_pattern": r".*\.py$",   # every script of the gallery runs at build time
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "matplotlib_animations": False,
    "show_memory": False,
    "plot_gallery": "True",
    "abort_on_example_error": True,
    # the timing pages load jQuery and DataTables from a CDN: none, the site is offline
    "write_computation_times": False,
    "only_warn_on_example_error": False,
}

# -- HTML --------------------------------------------------------------------------------
html_theme = "furo"
html_title = f"vsj {release}"
html_static_path = ["_static"]
html_favicon = "_static/vsj.svg"  # a page without one makes the browser ask for /favicon.ico
html_show_sourcelink = False


def _skip_type_aliases(handler):
    """``handler`` of autodoc-process-signature, passing over type aliases: a type alias
    is callable, so numpydoc looks for its signature (and finds ``tuple``'s), and any
    answer for it makes Sphinx 9 fail on an object that has no signature."""
    def wrapped(app, what, name, obj, options, signature, annotation):
        if isinstance(obj, types.GenericAlias):
            return None
        return handler(app, what, name, obj, options, signature, annotation)
    return wrapped


def setup(app):
    for listener in list(app.events.listeners["autodoc-process-signature"]):
        if listener.handler.__module__.startswith("numpydoc"):
            app.disconnect(listener.id)
            app.connect("autodoc-process-signature", _skip_type_aliases(listener.handler),
                        priority=listener.priority)
