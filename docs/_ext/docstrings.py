"""The code's docstrings, as autodoc renders them. They are written the way the
README is, in Markdown (fenced code blocks, `##` headings, `name` for code,
aligned columns), not in reStructuredText, so each one is parsed by MyST: a
`markdown` directive wraps it. napoleon first turns its Google-style sections
(Args:, Returns:, Raises:) into field lists, which MyST reads too; not an
attribute's or a property's, whose first line ("What ended the last step: ...")
napoleon would read as "type: description". An
environment's manual (a Gymnasium-style docstring) is rendered on its task page,
and the API reference points there."""
import re

from docutils.utils import new_document
from sphinx.ext import autosummary
from sphinx.ext.napoleon import Config, GoogleDocstring
from myst_parser.parsers.sphinx_ import MystParser
from sphinx.util.docutils import SphinxDirective

_HEADING = re.compile(r"^(\s*)#{2,}\s+(.*)$")


class Markdown(SphinxDirective):
  """Its content, parsed as MyST Markdown in place."""
  has_content = True

  def run(self):
    document = new_document(self.state.document["source"], self.state.document.settings)
    document.reporter = self.state.document.reporter
    MystParser().parse("\n".join(self.content), document)
    return list(document.children)


def to_markdown_directive(lines):
  """One docstring's lines, its headings made bold (a docstring has no sections)."""
  body = [_HEADING.sub(r"\1**\2**", line) for line in lines]
  return [".. markdown::", ""] + [f"   {line}" if line.strip() else "" for line in body]


_RST_SPECIAL = re.compile(r"([*|\\]|_(?=\W|$))")


def _summary_text(lines):
  """A wrapped docstring's first paragraph, for autosummary's tables (which parse it
  as reStructuredText): the Markdown unwrapped, what reST would read as markup
  escaped outside `code`."""
  if not lines or lines[0] != ".. markdown::":
    return lines
  parts = [line[3:] for line in lines[2:]]
  # (A code span ends in an escaped space: reST needs one before "s" in "`summary`s".)
  return [re.sub(r"(`[^`]*`)|([^`]+)",
                 lambda m: m.group(1) + "\\ " if m.group(1) else _RST_SPECIAL.sub(r"\\\1", m.group(2)),
                 line) for line in parts]


_extract_summary = autosummary.extract_summary
autosummary.extract_summary = lambda doc, settings: _extract_summary(_summary_text(doc), settings)


_GOOGLE = Config(napoleon_numpy_docstring=False)


def _process(app, what, name, obj, options, lines):
  page = app.config.task_manual_pages.get(name)
  if page is not None:
    lines[:] = [f"The environment's manual is on its task pages: :doc:`{page}`."]
  elif lines:
    if what not in ("attribute", "property", "data"):
      lines[:] = GoogleDocstring(lines, _GOOGLE, app, what, name, obj, options).lines()
    lines[:] = to_markdown_directive(lines)


def setup(app):
  app.add_directive("markdown", Markdown)
  app.connect("autodoc-process-docstring", _process)
  return {"parallel_read_safe": True}
