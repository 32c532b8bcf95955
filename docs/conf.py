"""Sphinx configuration of the sparsekin site.

Build with warnings as errors (pip install -e ".[docs]"):

    python3 -m sphinx -W --keep-going -b html docs build/site

Pages are Markdown (MyST); the API reference comes from the numpydoc docstrings
(autodoc + numpydoc); docs/_ext/sparsekin_docs.py makes the gallery, the command line
reference and the command outputs when the site is built.  tests/test_docs_site.py builds
the site and checks it in headless Chromium.
"""

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))

project = "sparsekin"
author = "the sparsekin developers"
copyright = "the sparsekin developers"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "numpydoc",
    "sparsekin_docs",
]
source_suffix = {
    ".md": "markdown",
    ".rst": "restructuredtext",
}  # .rst: numpydoc loads autosummary, which wants it
root_doc = "index"
exclude_patterns = ["_ext", "make_element_reference.py", "generated/**/*.md"]

# Markdown: GitHub-style anchors on headings to level 3, so that links like
# design-notes.md#which-linear-solver-path-auto-takes resolve (and are checked).
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]
smartquotes = False  # "--plot" in prose stays two hyphens, not an en dash

# API reference: the types are in the numpydoc docstrings, not repeated from the hints.
autodoc_typehints = "none"
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_xref_param_type = False
default_role = "code"  # `name` in a docstring is code, as in the package's docstrings

html_theme = "pydata_sphinx_theme"
html_title = "sparsekin"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 6,
}
html_show_sourcelink = False
html_context = {
    "default_mode": "light"
}  # a first visit has no stored mode; without it the theme logs an error
html_static_path = ["_static"]
html_css_files = ["sparsekin.css"]
