"""Sphinx configuration: MyST pages in the diataxis layout, reference pages
written from the code at every build (`_ext/reference_pages.py`).

Build (offline): `sphinx-build -W --keep-going -b html docs build/docs`.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent / "_ext"))

from fastcs_ethercat import __version__

project = "fastcs-ethercat"
author = "fastcs-ethercat contributors"
copyright = "the fastcs-ethercat contributors"
release = __version__
version = __version__

extensions = ["myst_parser", "reference_pages"]
source_suffix = {".md": "markdown"}
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3
exclude_patterns = ["_build", "_ext", "README.md"]
html_theme = "furo"
html_title = f"fastcs-ethercat {__version__}"
html_static_path: list[str] = []
# a code block a lexer cannot read is shown plain: not worth failing the build
suppress_warnings = ["myst.header", "misc.highlighting_failure"]
