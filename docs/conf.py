"""Sphinx configuration of hexcal's documentation site (``make docs``).

The generator is Sphinx with MyST-NB: pages are Markdown (MyST), tutorials are MyST notebooks
(``docs/tutorials/*.md``) that the build executes, the API reference is autodoc of every
package's public names, with napoleon reading the numpydoc docstrings. The build runs with
``-W --keep-going`` and ``nitpicky``: a warning, a broken cross-reference or a failing cell
fails it. The shell examples of the guide pages are ``{hexcal-run}`` blocks that the build
runs (``docs/_ext/hexcal_run.py``); an example that does not run is marked as a template.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

from importlib.metadata import version as _version  # noqa: E402

project = "hexcal"
author = "the hexcal authors"
copyright = "the hexcal authors, MIT licence"
release = _version("hexcal")
version = release

extensions = [
    "myst_nb",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "hexcal_docs",
    "hexcal_run",
]

# every docs/*.md page is a page of the site (new pages join the user guide by themselves,
# see hexcal_docs); the tutorials are notebooks; nothing else is read
source_suffix = {".md": "myst-nb"}
exclude_patterns = ["_build", "_ext", "**/.ipynb_checkpoints", "README.md"]
master_doc = "index"

# broken references fail the build; a reference to a Python object that exists but has no
# page of its own (an internal module, a numpy type) is shown as code (hexcal_docs)
nitpicky = True
# a code block in a language Pygments cannot highlight is shown as plain text, not an error
suppress_warnings = ["misc.highlighting_failure"]

myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# notebooks: executed on every build, in the docs folder, a failing cell fails the build
nb_execution_mode = "force"
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_execution_timeout = 600
nb_execution_in_temp = True
nb_merge_streams = True

autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_typehints_format = "short"
autodoc_preserve_defaults = True
autodoc_default_options = {"members": True}
# numpy's array aliases as written in the code, not expanded into their generic form
autodoc_type_aliases = {"NDArray": "numpy.typing.NDArray"}
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_ivar = True
# parameter types as text ("ndarray, shape (n, 6)"), not as cross-references
napoleon_use_param = False
napoleon_use_keyword = False
napoleon_custom_sections = ["Public names"]

html_theme = "furo"
html_title = f"hexcal {release}"
html_static_path: list[str] = []

# the tutorials' data: the Jugglebot sessions of the test data (a notebook run alone finds
# them relative to docs/tutorials/)
os.environ.setdefault("HEXCAL_JUGGLEBOT", str(HERE.parent / "tests" / "data" / "jugglebot"))
