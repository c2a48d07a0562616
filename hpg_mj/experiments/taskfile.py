"""Task files: TOML declarations of an environment, a hierarchy, each node's
learner with its hyper-parameters, and the protocol (tasks/*.toml).

Every key of a section is required and typed; an unknown key, a wrong type or
a missing value is refused with the file, the key and what is allowed, before
anything runs.
"""
import dataclasses
import pathlib
import tomllib

# Types accepted for a schema entry: "float" (int or float), "int", "bool",
# "str", "str_list" (a non-empty list of strings), ("choice", options),
# ("int_list", length) (positive integers), ("int_min", least),
# ("float_lists", length, description) (a non-empty list of lists of numbers).


class TaskFileError(ValueError):
  """A task file that cannot be used; the message names the file and the key."""


@dataclasses.dataclass
class TaskFile:
  path: pathlib.Path
  kind: str
  sections: dict
  text: str

  def section(self, name):
    return self.sections[name]


def _check(path, where, key, value, kind):
  where = f"{path}: {where} {key}"
  if isinstance(kind, tuple) and kind[0] == "choice":
    if value not in kind[1]:
      raise TaskFileError(f"{where} = {value!r} is not allowed; allowed: {list(kind[1])}")
    return value
  if isinstance(kind, tuple) and kind[0] == "int_list":
    if (not isinstance(value, list) or len(value) != kind[1]
        or not all(_is_int(v) and v > 0 for v in value)):
      raise TaskFileError(f"{where} must be a list of {kind[1]} positive integers, got {value!r}")
    return tuple(value)
  if isinstance(kind, tuple) and kind[0] == "int_min":
    if not _is_int(value) or value < kind[1]:
      raise TaskFileError(f"{where} must be {_describe(kind)}, got {value!r}")
    return value
  if isinstance(kind, tuple) and kind[0] == "float_lists":
    if not isinstance(value, list) or not value or not all(
        isinstance(v, list) and len(v) == kind[1] and all(_is_number(x) for x in v)
        for v in value):
      raise TaskFileError(f"{where} must be {_describe(kind)}, got {value!r}")
    return [[float(x) for x in v] for v in value]
  if kind == "float":
    if not _is_number(value):
      raise TaskFileError(f"{where} must be a number, got {value!r}")
    return float(value)
  if kind == "int":
    if not _is_int(value):
      raise TaskFileError(f"{where} must be an integer, got {value!r}")
    return value
  if kind == "bool":
    if not isinstance(value, bool):
      raise TaskFileError(f"{where} must be true or false, got {value!r}")
    return value
  if kind == "str":
    if not isinstance(value, str):
      raise TaskFileError(f"{where} must be a string, got {value!r}")
    return value
  if kind == "str_list":
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
      raise TaskFileError(f"{where} must be {_describe(kind)}, got {value!r}")
    return list(value)
  raise AssertionError(kind)


def _is_int(value):
  return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value):
  return isinstance(value, (int, float)) and not isinstance(value, bool)


def check_table(path, where, table, required, optional=None):
  """The values of one TOML table (`where`, e.g. "[root]"), converted, after
  refusing unknown keys, missing required ones and wrong types; optional keys
  may be left out."""
  optional = optional or {}
  allowed = {**required, **optional}
  unknown = set(table) - set(allowed)
  if unknown:
    raise TaskFileError(f"{path}: {where} unknown key(s) {sorted(unknown)}; allowed: "
                        f"{sorted(allowed)}")
  values = {}
  for key, kind in allowed.items():
    if key in table:
      values[key] = _check(path, where, key, table[key], kind)
    elif key in required:
      raise TaskFileError(f"{path}: {where} {key} is missing ({_describe(kind)})")
  return values


def load(path, schemas):
  """Reads and validates a task file.

  `schemas` maps a task kind (the file's `[task] kind`) to its sections:
  {section: {key: type}}. Returns a `TaskFile` with converted values.
  """
  path = pathlib.Path(path)
  if not path.is_file():
    raise TaskFileError(f"{path}: no such task file")
  text = path.read_text()
  try:
    data = tomllib.loads(text)
  except tomllib.TOMLDecodeError as err:
    raise TaskFileError(f"{path}: not valid TOML: {err}") from None
  task = data.get("task")
  if not isinstance(task, dict) or "kind" not in task:
    raise TaskFileError(f"{path}: [task] kind is missing; allowed kinds: {sorted(schemas)}")
  kind = task["kind"]
  if kind not in schemas:
    raise TaskFileError(f"{path}: [task] kind = {kind!r} is not allowed; allowed: "
                        f"{sorted(schemas)}")
  schema = schemas[kind]
  unknown_sections = set(data) - set(schema)
  if unknown_sections:
    raise TaskFileError(f"{path}: unknown section(s) {sorted(unknown_sections)}; allowed: "
                        f"{sorted(schema)}")
  sections = {}
  for section, keys in schema.items():
    given = data.get(section)
    if not isinstance(given, dict):
      raise TaskFileError(f"{path}: section [{section}] is missing; it needs the keys "
                          f"{sorted(keys)}")
    values = check_table(path, f"[{section}]", given, keys)
    sections[section] = values
  return TaskFile(path, kind, sections, text)


def _describe(kind):
  if isinstance(kind, tuple):
    return {"choice": lambda: f"one of {list(kind[1])}",
            "int_list": lambda: f"a list of {kind[1]} integers",
            "int_min": lambda: "a positive integer" if kind[1] == 1 else f"an integer >= {kind[1]}",
            "float_lists": lambda: f"a non-empty list of {kind[2]}"}[kind[0]]()
  return {"float": "a number", "int": "an integer", "bool": "true or false",
          "str": "a string", "str_list": "a non-empty list of strings"}[kind]
