"""Sphinx configuration of the fingertip-dolfinx documentation (`make docs`).

The pages are MyST Markdown; the demos (`../demos/*.py`, jupytext percent scripts) are copied
into `demos/` at build time and executed by myst-nb at their coarse settings, so that every
figure on a demo page comes from the code as it is.
"""

from __future__ import annotations

import os
import shutil
import sys
from importlib.metadata import version as _version
from pathlib import Path

HERE = Path(__file__).parent
ROOT = HERE.parent

project = "fingertip-dolfinx"
author = "the fingertip-dolfinx developers"
copyright = "2026, the fingertip-dolfinx developers"
release = _version("fingertip-dolfinx")

sys.path.insert(0, str(HERE / "_ext"))

extensions = [
    "scene_keys",
    "myst_nb",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]
source_suffix = {".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "results/**/*.md", "reference/_keys.md", "reference/_api.md",
                    "conf.py", "_ext", "demos/*.ipynb", "Thumbs.db", ".DS_Store"]
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
suppress_warnings = ["myst.header"]

# The demos: jupytext percent scripts, executed at their coarse settings.
nb_custom_formats = {".py": ["jupytext.reads", {"fmt": "py:percent"}]}
nb_execution_mode = os.environ.get("FINGERTIP_DOCS_EXECUTE", "cache")
nb_execution_timeout = 900
nb_execution_raise_on_error = True
nb_execution_cache_path = str(HERE / "_build" / ".jupyter_cache")
os.environ.setdefault("FINGERTIP_DEMO_COARSE", "1")
nb_execution_in_temp = True  # the demos write their runs into a temporary directory
os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("PYVISTA_OFF_SCREEN", "true")

_demos = HERE / "demos"
_demos.mkdir(exist_ok=True)
for _demo in sorted((ROOT / "demos").glob("demo_*.py")):
    _copy = _demos / _demo.name
    if not _copy.exists() or _copy.read_bytes() != _demo.read_bytes():
        shutil.copyfile(_demo, _copy)

autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}
autodoc_typehints = "description"
autodoc_member_order = "bysource"
napoleon_numpy_docstring = True
napoleon_google_docstring = False
# An "Attributes" section as fields of the class, so that a dataclass's fields (also listed by
# :members:) are not described twice.
napoleon_use_ivar = True

html_theme = "furo"
html_title = "fingertip-dolfinx"
html_static_path: list[str] = []
