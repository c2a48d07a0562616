"""The API reference: every entry it lists says what it is, no docstring it shows
cites a tracker number, and every example in one is highlighted as its language.

Read with inspect, without a Sphinx build (tests/test_doc_build.py builds the site):
the modules are those docs/_ext/api_pages.py puts on the pages, the entries those
autodoc picks there (conf.py's `members` and `undoc-members`: each module's public
functions and classes defined in it, each class's own public methods and
properties; a method without a docstring shows its base class's, a class does not),
and a docstring is read as docs/_ext/docstrings.py renders it (Markdown, its
indented column layouts kept as plain text). hpg_mj.jax's modules import JAX, so
tests/jax/test_jax_api_docstrings.py checks them in the JAX tests' process."""
import ast
import functools
import importlib
import inspect
import pathlib
import re
import sys
import textwrap
import tomllib

import pygments.lexers
import pygments.util
import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "docs" / "_ext"))
import api_pages  # noqa: E402  (docs/_ext: the modules on the pages)
import docstrings  # noqa: E402  (docs/_ext: a docstring as the site renders it)

from test_docs import TRACKER_NUMBER  # noqa: E402  (tests/, on the path: conftest.py)

JAX = "hpg_mj.jax"
# A docstring that opens with one of napoleon's sections has no summary on the page.
_SECTION = re.compile(r"(Args|Arguments|Parameters|Returns?|Raises|Yields?|Attributes|"
                      r"Examples?|Notes?):\s*$")
_FENCE = re.compile(r"^(\s*)```(\S*)\s*$")


def _doc(obj):
  """`obj`'s own docstring, cleaned ("" for none)."""
  doc = getattr(obj, "__doc__", None)
  return inspect.cleandoc(doc) if isinstance(doc, str) else ""


def _is_function(value):
  """A function as autodoc documents one: plain, compiled (numba) or jitted (JAX)."""
  return inspect.isfunction(value) or hasattr(value, "py_func") or (
      callable(value) and inspect.isfunction(inspect.unwrap(value)))


def _class_doc(cls):
  """A class's own docstring; the one a dataclass or a namedtuple is given, its
  signature (`Config(a: int = 1)`), is none."""
  doc = _doc(cls) if "__doc__" in vars(cls) else ""
  return "" if re.fullmatch(rf"{re.escape(cls.__name__)}\(.*\)", doc, re.S) else doc


def _member_doc(cls, name):
  """A method's or a property's docstring, its base classes' where it has none (none
  where a base class has a plain value by that name: autodoc would show the value's
  type's docstring, `int`'s)."""
  for klass in cls.__mro__:
    if name in vars(klass):
      raw = vars(klass)[name]
      if isinstance(raw, (staticmethod, classmethod)):
        raw = raw.__func__
      if not (_is_function(raw) or isinstance(raw, property)):
        return ""
      doc = _doc(raw)
      if doc:
        return doc
  return ""


def entries(module_names):
  """The reference's entries of the modules: qualified name -> the docstring shown."""
  found = {}
  for module_name in module_names:
    module = importlib.import_module(module_name)
    found[module_name] = _doc(module)
    for name, value in vars(module).items():
      if name.startswith("_") or getattr(value, "__module__", None) != module_name:
        continue
      where = f"{module_name}.{name}"
      if inspect.isclass(value):
        found[where] = _class_doc(value)
        for member, raw in vars(value).items():
          if member.startswith("_"):
            continue
          if isinstance(raw, (staticmethod, classmethod)):
            raw = raw.__func__
          if _is_function(raw) or isinstance(raw, property):
            found[f"{where}.{member}"] = _member_doc(value, member)
          elif inspect.isclass(raw) and raw.__name__ == member:   # `Config = Config`
            found[f"{where}.{member}"] = _class_doc(raw)     # (another name: "alias of")
      elif _is_function(value):
        found[where] = _doc(value)
  return found


def lacking(found):
  """The entries shown with no description."""
  return sorted(name for name, doc in found.items()
                if not doc.strip() or _SECTION.match(doc.strip().splitlines()[0]))


def tracker_numbers(found):
  """name -> the tracker numbers its docstring cites."""
  hits = {name: re.findall(TRACKER_NUMBER, doc) for name, doc in found.items()}
  return {name: found for name, found in hits.items() if found}


def blocks(doc):
  """The fenced blocks of a docstring as the site renders it: (language, code)."""
  out, language, body, indent = [], None, [], 0
  for line in docstrings.to_markdown(doc.splitlines()):
    fence = _FENCE.match(line)
    if fence and language is None:
      language, body, indent = fence.group(2), [], len(fence.group(1))
    elif fence:
      out.append((language, textwrap.dedent("\n".join(l[indent:] for l in body))))
      language = None
    elif language is not None:
      body.append(line)
  return out


def example_language(code):
  """The language a block is written in, if it is code: "toml", "python" or "bash";
  None for prose, columns, formulas and pseudo-code (which stay plain text)."""
  try:
    if re.search(r"^\[\[?[\w.]+\]\]?", code, re.M) and tomllib.loads(code):
      return "toml"
  except tomllib.TOMLDecodeError:
    pass
  if re.search(r"^\s*>>> ", code, re.M):
    return "python"
  try:
    tree = ast.parse(code)
  except SyntaxError:
    tree = None
  if tree is not None and any(isinstance(node, (ast.Import, ast.ImportFrom, ast.Assign,
                                                ast.FunctionDef, ast.ClassDef, ast.Call))
                              for node in ast.walk(tree)):
    return "python"
  if re.match(r"(\$ |python -m |pip install |bash |hpg-mj )", code):
    return "bash"
  return None


def unhighlighted(found):
  """name -> the examples its docstring shows as plain text (an indented block or a
  fence without a language Pygments knows), or a >>> line outside a Python fence."""
  bad = {}
  for name, doc in found.items():
    for language, code in blocks(doc):
      try:
        pygments.lexers.get_lexer_by_name(language or "text")
        known = language not in ("", "text", "none")
      except pygments.util.ClassNotFound:
        known = False
      if not known and example_language(code):
        bad.setdefault(name, []).append(code.splitlines()[0])
    outside = re.sub(r"^```python\n.*?^```", "", "\n".join(docstrings.to_markdown(
        doc.splitlines())), flags=re.M | re.S)
    if re.search(r"^\s*>>>", outside, re.M):
      bad.setdefault(name, []).append(">>> outside a Python fence")
  return bad


@functools.cache
def reference():
  """The reference's entries, less hpg_mj.jax's."""
  return entries([m for m in api_pages.modules() if not m.startswith(JAX)])


def test_the_reference_is_read_whole():
  REFERENCE = reference()
  assert len(REFERENCE) > 1000
  assert {"hpg_mj.hierarchy.kinds.q_table.Settings", "hpg_mj.agents.base.Agent.state",
          "hpg_mj.agents.ship_hybrid.ShipHybrid.Config",
          "hpg_mj.learners.qlambda.epsilon_greedy"} <= set(REFERENCE)
  assert not any(name.startswith(JAX) for name in REFERENCE)
  assert sum(language == "python" for doc in REFERENCE.values()
             for language, _ in blocks(doc)) >= 5


def test_every_entry_of_the_api_reference_says_what_it_is():
  assert lacking(reference()) == []


def test_no_docstring_the_site_shows_cites_a_tracker_number():
  assert tracker_numbers(reference()) == {}


def test_every_example_in_a_docstring_is_highlighted():
  assert unhighlighted(reference()) == {}


# ---- the checks fail where they should -----------------------------------------------

def _module(tmp_path, monkeypatch, source):
  (tmp_path / "api_sample.py").write_text(textwrap.dedent(source))
  monkeypatch.syspath_prepend(str(tmp_path))
  sys.modules.pop("api_sample", None)
  return entries(["api_sample"])


def test_an_entry_without_a_description_is_found(tmp_path, monkeypatch):
  found = _module(tmp_path, monkeypatch, '''
      """A module."""
      import collections
      import dataclasses
      from os.path import join               # imported: not this module's entry

      Pair = collections.namedtuple("Pair", ("a", "b"))

      @dataclasses.dataclass
      class Config:
        size: int = 1

      class Base:
        """A base."""
        def act(self):
          """Acts."""

      class Child(Base):
        """A child."""
        Config = Config
        width = 4
        def act(self):                       # its base's docstring is shown
          pass
        def observe(self):
          pass
        @property
        def size(self):
          return 1

      class Grandchild(Child):
        """A grandchild."""
        @property
        def width(self):                     # autodoc would show int's docstring
          return 5

      def documented():
        """Does a thing."""

      def bare():
        pass

      def sections_only(x):
        """Args:
          x: a number."""
  ''')
  assert "api_sample.join" not in found
  assert lacking(found) == ["api_sample.Child.Config", "api_sample.Child.observe",
                            "api_sample.Child.size", "api_sample.Config",
                            "api_sample.Grandchild.width", "api_sample.Pair",
                            "api_sample.bare", "api_sample.sections_only"]


def test_a_tracker_number_is_found():
  found = {"a": "Fixed in issue 43.", "b": "See issue #12, and issues 3 and 4.",
           "c": "As [mujoco#644](https://github.com/google-deepmind/mujoco/issues/644) says."}
  assert sorted(tracker_numbers(found)) == ["a", "b"]


def test_an_example_left_plain_is_found():
  found = {
      "indented": "Use it:\n\n    from hpg_mj import suite\n    env = suite.load('ship', 'steer')\n",
      "doctest": "Use it:\n\n>>> 1 + 1\n2\n",
      "toml": "A file:\n\n    [experiment]\n    name = \"x\"\n",
      "shell": "Run:\n\n    python -m hpg_mj.jax.bench --envs 8\n",
      "fenced": "Use it:\n\n```python\nfrom hpg_mj import suite\n```\n",
      "columns": "Fields:\n\n  name    what it is\n  steps   how many\n",
      "formula": "The rule:\n\n  delta = r - rho * tau + max_b Q(s', b) - Q(s, a)\n",
  }
  assert sorted(unhighlighted(found)) == ["doctest", "indented", "shell", "toml"]
