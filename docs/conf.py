"""Sphinx configuration of hpg_mj's documentation (`bash scripts/docs.sh` builds it).

The pages are Markdown (MyST), as Gymnasium's are. The API reference (a page per
subpackage, `_ext/api_pages.py`) and the interfaces are autodoc of the installed
package, and the task pages are written at build time from the environments' own
docstrings (`_ext/task_pages.py`), so that neither can drift from the code; the
results tables of the README and the pages are made from the reports
(`_ext/published.py`), and the build stops when one differs from its report. The
build runs with warnings as errors (-W) and nitpicky cross-references: a broken
link or reference fails it.
"""
import pathlib
import sys

DOCS = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))

project = "hpg_mj"
author = "the hpg_mj authors"
copyright = "2026, the hpg_mj authors"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "docstrings",     # _ext/docstrings.py: the code's Markdown-flavoured docstrings
    "task_pages",     # _ext/task_pages.py: one page per task, from the docstrings
    "api_pages",      # _ext/api_pages.py: the API reference, a page per subpackage
    "published",      # _ext/published.py: the results tables, as their reports say
]

source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build"]
html_theme = "furo"
html_title = "hpg_mj"
# _static/tables.css: the reports' wide tables fit the page's column.
html_static_path = ["_static"]
html_css_files = ["tables.css"]

# SPEC.md's and the pages' section links (SPEC.md#7-evaluation-seeds-and-statistics)
# are GitHub's heading anchors; MyST makes the same ones.
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence", "dollarmath", "fieldlist"]
# Quotes and ellipses only: the reports quote command lines ("--seeds 3"), which the
# default ("qDe") would print with an en dash.
smartquotes_action = "qe"

# The docstrings write `name` for code, as Markdown does.
default_role = "code"
autodoc_default_options = {"members": True, "undoc-members": True, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
# The API pages' "on this page" lists their modules, not each of their ~2,900 functions,
# classes and methods (the index and the search find those): the per-object entries were
# a third of the build's time, copied into every page's navigation.
toc_object_entries = False

# Broken cross-references fail the build. The other libraries' names are not
# resolvable offline (no intersphinx: CI has no network), so those are let through.
nitpicky = True
nitpick_ignore_regex = [
    ("py:.*", r"(numpy|np|gymnasium|dm_control|dm_env|mujoco|numba|torch|"
              r"stable_baselines3|scipy|ray|collections|typing|dataclasses|pathlib|"
              r"concurrent|multiprocessing|subprocess|enum|abc|os|io|jax|gymnax)(\..*)?"),
    # napoleon's types in prose ("optional int", "observation"); gymnasium's type
    # variables; the private base classes of public ones (not in the reference).
    ("py:class", r"[a-z][a-z ]*|ObsType|ActType|types\.\w+|Any|Callable|Sequence|Optional"),
    ("py:(class|obj)", r"hpg_mj(\.\w+)*\._\w+(\.\w+)*"),
]


def _mark_long_words(app, doctree):
  """Classes a table holding a word of 40 characters or more outside code (the
  reports' task-file SHA-256s) `long-words`: _static/tables.css lets its cells break
  anywhere, so that the hash does not squeeze the columns beside it."""
  from docutils import nodes
  for table in doctree.findall(nodes.table):
    if any(len(word) >= 40 for text in table.findall(nodes.Text)
           if not isinstance(text.parent, nodes.literal) for word in text.split()):
      table["classes"].append("long-words")


def setup(app):
  app.connect("doctree-read", _mark_long_words)
