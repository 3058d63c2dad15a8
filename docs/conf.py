"""Sphinx configuration of the teleopkit documentation.

Build (warnings are errors; the tutorials in ``examples/`` are executed by sphinx-gallery)::

    TELEOPKIT_DOCS_BUDGET=small python -m sphinx -W --keep-going -b html docs docs/_build/html

``TELEOPKIT_DOCS_BUDGET`` is ``small`` (CI: short runs, a few methods) or ``full`` (the default of
the scripts when run by hand).
"""

from __future__ import annotations

import os
import socket
import sys
import types
from pathlib import Path
from urllib.parse import urlsplit

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # document the working tree even without an editable install
sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

import api_pages  # noqa: E402  (docs/_ext)

import teleopkit  # noqa: E402

project = "teleopkit"
author = "teleopkit developers"
copyright = "teleopkit developers"
release = teleopkit.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",  # serves MathJax from _static/mathjax instead of a CDN
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "sphinx_click",
    "reexports",  # docs/_ext: references to teleopkit.X / certify.X re-exports
    "cli_page",  # docs/_ext: plain defaults and literal addresses on the command-line page
    "myst_parser",  # Markdown pages (benchmark_history.md)
]
templates_path = ["_templates"]
exclude_patterns = ["_build", "auto_examples/*.ipynb", "auto_examples/*.py",
                    "auto_examples/*.zip", "auto_examples/*.json", "auto_examples/*.md5",
                    "**.codeobj.json"]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
pygments_style = "sphinx"
smartquotes = False  # keep "--json" and quotes literal: copied commands must run
# Every reference into teleopkit and certify must resolve (with -W, a broken one fails the build);
# names of other libraries link through intersphinx when it is reachable, else stay text.
nitpicky = True
nitpick_ignore_regex = [(r"py:.*", r"(?!(teleopkit|certify)(\.|$)).*")]

# -- intersphinx: links into the libraries' own docs (only where their inventory is reachable) --
INVENTORIES = {
    "python": "https://docs.python.org/3/",
    "numpy": "https://numpy.org/doc/stable/",
    "scipy": "https://docs.scipy.org/doc/scipy/",
    "pandas": "https://pandas.pydata.org/docs/",
    "matplotlib": "https://matplotlib.org/stable/",
    "control": "https://python-control.readthedocs.io/en/latest/",
    "gymnasium": "https://gymnasium.farama.org/",
    "cvxpy": "https://www.cvxpy.org/",
    "torch": "https://docs.pytorch.org/docs/stable/",
    "click": "https://click.palletsprojects.com/en/stable/",
}


def _reachable(url: str, timeout: float = 1.0) -> bool:
    """Whether the host of ``url`` accepts a connection (the build must also work offline)."""
    try:
        with socket.create_connection((urlsplit(url).hostname or "", 443), timeout=timeout):
            return True
    except OSError:
        return False


intersphinx_mapping = {name: (url, None) for name, url in INVENTORIES.items()
                       if _reachable(url)}
if len(intersphinx_mapping) < len(INVENTORIES):
    print("intersphinx: offline, no links into "
          + ", ".join(sorted(set(INVENTORIES) - set(intersphinx_mapping))))
# ``-b linkcheck`` checks the pages' own links, and the web ones when the web is reachable
linkcheck_ignore = [] if intersphinx_mapping else [r"https?://"]

# -- autosummary: a page per public object (docs/_templates/autosummary) ----------------------
autosummary_generate = True
# autosummary writes a page per object but never removes one: start afresh, so that an object
# moved or renamed leaves no page behind (sphinx-gallery's back-references stay)
for page in (Path(__file__).resolve().parent / "api" / "generated").glob("*.rst"):
    page.unlink()
autosummary_imported_members = False  # a re-export is documented where it is defined
autosummary_ignore_module_all = False
autosummary_context = {name: getattr(api_pages, name)
                       for name in ("gallery_names", "is_package", "is_alias", "alias_doc")}
suppress_warnings = ["config.cache"]  # the context holds a function: no cached configuration

# -- autodoc / numpydoc -------------------------------------------------------------------------
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"  # the numpydoc sections carry the types
autodoc_inherit_docstrings = True
autodoc_mock_imports: list[str] = []
numpydoc_show_class_members = False  # autodoc's :members: lists them once
numpydoc_class_members_toctree = False
numpydoc_attributes_as_param_list = True
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# -- sphinx-gallery -----------------------------------------------------------------------------
BUDGET = os.environ.get("TELEOPKIT_DOCS_BUDGET", "small")
if BUDGET not in ("small", "full"):
    raise ValueError(f"TELEOPKIT_DOCS_BUDGET must be 'small' or 'full', got {BUDGET!r}")
os.environ["TELEOPKIT_DOCS_BUDGET"] = BUDGET

sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"(train_pretrained|train_covered|compare_certified_tuners)\.py",  # long runs
    "within_subsection_order": "tutorial_order.TutorialOrder",
    "download_all_examples": False,
    "remove_config_comments": True,
    "reset_modules": ("matplotlib",),
    "abort_on_example_error": True,
    "show_memory": False,
    "min_reported_time": 1.0,
    "thumbnail_size": (480, 320),
    "capture_repr": ("_repr_html_", "__repr__"),
    "ignore_repr_types": r"matplotlib\.",  # no "<matplotlib.legend.Legend ...>" outputs
    "image_scrapers": ("matplotlib",),
    "backreferences_dir": "api/generated/backreferences",  # "Examples using this" on API pages
    "doc_module": ("teleopkit", "certify"),
    "write_computation_times": False,
}

# -- HTML ---------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"teleopkit {release}"
html_static_path = ["_static"]
html_css_files = ["gallery.css"]  # larger tutorial thumbnails
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
html_show_sourcelink = False
# Source links point at the module an entry is documented in: following a type alias's value
# (``tuple[...]``) would send viewcode to ``builtins``, which has no source page.
viewcode_follow_imported_members = False
# Pages without sub-pages have no section to navigate: no empty "Section Navigation" sidebar.
html_sidebars = {page: [] for page in ("getting_started", "certified", "performance",
                                       "benchmark_history", "troubleshooting", "changelog",
                                       "citing", "references")}


def _skip_aliases(app: object, what: str, name: str, obj: object, skip: bool,
                  options: object) -> bool | None:
    """Type aliases (``tuple[bool, ...]``) are listed as constants, not as classes."""
    return True if isinstance(obj, types.GenericAlias) and what == "class" else None


def setup(app: object) -> None:
    """Connect the configuration's event handlers."""
    app.connect("autodoc-skip-member", _skip_aliases)  # type: ignore[attr-defined]
