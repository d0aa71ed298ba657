"""Sphinx configuration of the rcm-kin documentation: MyST markdown pages, the API reference
generated from the docstrings of the public faces (``rcm_kin`` and each subpackage's ``__all__``).

Build: ``sphinx-build -W --keep-going -b html docs docs/_build/html`` (no warnings allowed).
"""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))     # autodoc imports the package from the source tree

import rcm_kin  # noqa: E402

project = "rcm-kin"
author = "rcm-kin contributors"
copyright = "2025-2026, rcm-kin contributors"
release = version = rcm_kin.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3

# the API reference: members in each face's __all__ order, signatures with their annotations as
# written (the type-checking-only imports stay strings), nothing imported beyond the package itself
autodoc_default_options = {"members": True, "member-order": "bysource", "show-inheritance": False}
autodoc_typehints = "signature"
autodoc_preserve_defaults = True
autosummary_generate = False
napoleon_google_docstring = True
napoleon_numpy_docstring = True

html_theme = "alabaster"
html_static_path = []
html_title = f"rcm-kin {release}"
