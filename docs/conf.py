"""Sphinx configuration of the phri-spring documentation site.

Build it with warnings as errors (as CI does), output outside the repository:
``sphinx-build -W --keep-going -b html docs /tmp/phri-spring-docs``.
The pages are the Markdown files of this folder (MyST); the API reference (api.md) is
generated from the package's numpydoc docstrings (autodoc, autosummary, napoleon).
"""

project = "phri-spring"
author = "phri-spring developers"
copyright = "phri-spring developers, BSD 3-Clause"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "_templates"]
templates_path = ["_templates"]

# MyST: GitHub's heading anchors, so that links such as live.md#the-dashboard work on the
# site as they do on the repository's web view
myst_heading_anchors = 4
myst_enable_extensions = ["dollarmath"]
# a page may link to a repository file outside docs/ (a benchmark report, an example's
# README): on the repository's web view it is a link, on the site it stays its name
nitpick_ignore_regex = [("myst", r".*/(benchmarks|examples)/[^#]*")]

# the docstrings are numpydoc
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_param = False
napoleon_use_ivar = True
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "signature"

html_theme = "alabaster"
html_title = "phri-spring"
html_static_path: list[str] = []

# a class re-exported by its package (``phri_spring.physics.laws.SeriesElement`` is
# ``phri_spring.physics.laws.series.SeriesElement``) is one object under two names: a
# reference to it by its short name (a type annotation) finds both, which is not an error
suppress_warnings = ["ref.python"]
