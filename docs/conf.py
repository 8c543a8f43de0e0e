"""Sphinx configuration of aerorelay's documentation (``make docs``; CI builds it with -W)."""

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

project = "aerorelay"
author = "the aerorelay developers"
copyright = "2026, the aerorelay developers"  # noqa: A001 (Sphinx's name)

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx_click",
    "sphinx_gallery.gen_gallery",
    "scenario_reference",
]
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build", "tutorials/*.ipynb", "tutorials/*.py.md5", "tutorials/*.zip", "tutorials/*.json"]
suppress_warnings = ["config.cache"]  # sphinx-gallery's configuration holds functions

html_theme = "furo"
html_title = "aerorelay"
html_extra_path = ["foxglove_layout.json"]

autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}
napoleon_google_docstring = True
napoleon_numpy_docstring = True

# Tutorials: the scripts in examples/, rendered with their output and figures. What CI executes:
# the scripts matching EXECUTED, each with a short mission (AERORELAY_EXAMPLE_DURATION s) and no
# bound; the others are shown as code (their run time is minutes: a batch of estimator replays,
# a dask cluster, the QP tail study). tests/test_examples.py runs every one of them.
EXECUTED = r"/(fly_nominal|own_planner|directional_jammer|two_jammers_one_moving)\.py$"
os.environ.setdefault("AERORELAY_EXAMPLE_DURATION", "8.0")
os.environ.setdefault("AERORELAY_EXAMPLE_BOUND", "0")
os.environ.setdefault("AERORELAY_EXAMPLE_OUT", str(HERE / "_build" / "example_runs"))
os.environ.setdefault("MPLBACKEND", "Agg")
sphinx_gallery_conf = {
    "examples_dirs": str(HERE.parent / "examples"),
    "gallery_dirs": "tutorials",
    "filename_pattern": EXECUTED,
    "ignore_pattern": r"__init__\.py",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "abort_on_example_error": True,
    "show_memory": False,
    "min_reported_time": 1e9,
    "reset_modules": ("matplotlib",),
}
