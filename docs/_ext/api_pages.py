"""The API reference, written when the build starts: one page per subpackage of
hpg_mj (and one for its top-level modules), each module on it documented by
autodoc from its docstrings. The modules are found by walking the installed
package, so a new module has its place without an edit here; private ones (a name
that starts with "_") are not part of the reference. One page per subpackage rather
than per module keeps the site's navigation small: the theme draws the whole tree
on every page, and 80 module pages made that most of the build's time."""
import importlib
import pathlib
import pkgutil

import generated   # docs/_ext

PACKAGE = "hpg_mj"
OUT = "api"          # under docs/, written at build time (not tracked)


def _walk():
  """Every public module of the package, by name, in order -> whether it is a package.
  pkgutil imports the packages to walk them, not the modules: hpg_mj.jax's modules
  import JAX, whose threads must not be running when Sphinx forks its parallel
  readers (where autodoc imports them)."""
  package = importlib.import_module(PACKAGE)
  found = {PACKAGE: True}
  found.update((info.name, info.ispkg)
               for info in pkgutil.walk_packages(package.__path__, PACKAGE + "."))
  return {n: found[n] for n in sorted(found)
          if not any(part.startswith("_") for part in n.split("."))}


def modules():
  """Every public module of the package, by name, in order."""
  return list(_walk())


def pages():
  """page name -> its modules: a subpackage with everything under it; the package
  itself with its top-level modules."""
  grouped = {}
  found = _walk()
  packages = {n for n, is_package in found.items() if is_package}
  for name in found:
    parts = name.split(".")
    page = ".".join(parts[:2]) if len(parts) > 1 and ".".join(parts[:2]) in packages else PACKAGE
    grouped.setdefault(page, []).append(name)
  return grouped


def render(page, names):
  lines = [f"# `{page}`", ""]
  for name in names:
    if name != page:
      lines += [f"## `{name}`", ""]
    lines += ["```{eval-rst}", f".. automodule:: {name}", "```", ""]
  return "\n".join(lines)


def write_pages(srcdir):
  """Writes docs/api/*.md."""
  texts = {page: render(page, names) for page, names in pages().items()}
  generated.write(pathlib.Path(srcdir) / OUT, texts)


def setup(app):
  app.connect("builder-inited", lambda app: write_pages(app.srcdir))
  return {"parallel_read_safe": True}
