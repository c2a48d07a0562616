"""The code's docstrings, as autodoc renders them. They are written the way the
README is, in Markdown (fenced code blocks, `##` headings, `name` for code,
aligned columns), not in reStructuredText, so each one is parsed by MyST: a
`markdown` directive wraps it. napoleon first turns its Google-style sections
(Args:, Returns:, Raises:) into field lists, which MyST reads too; not an
attribute's or a property's, whose first line ("What ended the last step: ...")
napoleon would read as "type: description". An environment's manual (a
Gymnasium-style docstring) is rendered on its task page, and the API reference
points there."""
import re

from docutils.utils import new_document
from myst_parser.parsers.sphinx_ import MystParser
from sphinx.ext.napoleon import Config, GoogleDocstring
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


def _aligned(paragraph):
  """Whether a paragraph is an indented block laid out in columns (a docstring's
  table of names and meanings), which Markdown would run together."""
  return all(line.startswith("  ") for line in paragraph) and not re.match(
      r"\s*([-*+] |\d+[.)] |```)", paragraph[0])


def to_markdown(lines):
  """One docstring's lines as Markdown: its headings made bold (a docstring has no
  sections), its indented column layouts kept as they are (preformatted)."""
  out, paragraph, fenced = [], [], False

  def flush():
    if paragraph and not fenced and _aligned(paragraph):
      out.extend(["```text", *(line[2:] for line in paragraph), "```"])
    else:
      out.extend(paragraph)
    paragraph.clear()

  for line in lines:
    if line.strip().startswith("```"):
      flush()
      fenced = not fenced
      out.append(line)
    elif not line.strip():
      flush()
      out.append(line)
    else:
      paragraph.append(line if fenced else _HEADING.sub(r"\1**\2**", line))
  flush()
  return out


def to_markdown_directive(lines):
  """One docstring's lines, as Markdown, in a `markdown` directive."""
  return [".. markdown::", ""] + [f"   {line}" if line.strip() else "" for line in to_markdown(lines)]


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
