"""Sphinx configuration of sensorgym's docs site (``bash scripts/docs.sh`` builds it).

The Markdown pages are read by MyST; the env pages under ``envs/`` are generated at every build
from the env docstrings (``_ext/sensorgym_docs.py``); the API reference is autodoc.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

project = "sensorgym"
author = "sensorgym developers"
copyright = "sensorgym developers"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sensorgym_docs",
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "_ext", "**/*.json"]

myst_enable_extensions = ["colon_fence"]
# the pages link to their sections as GitHub does (environments.md#speed)
myst_heading_anchors = 4

autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_typehints_format = "short"
# numpy's aliases by their names, not their expansions (the annotations are postponed strings)
autodoc_type_aliases = {"ArrayLike": "ArrayLike", "NDArray": "NDArray"}
# a package's __all__ re-exports its modules' names: document each where it is defined
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}

html_theme = "furo"
html_title = "sensorgym"
