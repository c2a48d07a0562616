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
# "str", ("choice", options), ("int_list", length).


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


def _check(path, section, key, value, kind):
  where = f"{path}: [{section}] {key}"
  if isinstance(kind, tuple) and kind[0] == "choice":
    if value not in kind[1]:
      raise TaskFileError(f"{where} = {value!r} is not allowed; allowed: {list(kind[1])}")
    return value
  if isinstance(kind, tuple) and kind[0] == "int_list":
    if (not isinstance(value, list) or len(value) != kind[1]
        or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in value)):
      raise TaskFileError(f"{where} must be a list of {kind[1]} positive integers, got {value!r}")
    return tuple(value)
  if kind == "float":
    if isinstance(value, bool) or not isinstance(value, (int, float)):
      raise TaskFileError(f"{where} must be a number, got {value!r}")
    return float(value)
  if kind == "int":
    if isinstance(value, bool) or not isinstance(value, int):
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
  raise AssertionError(kind)


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
    unknown = set(given) - set(keys)
    if unknown:
      raise TaskFileError(f"{path}: [{section}] unknown key(s) {sorted(unknown)}; allowed: "
                          f"{sorted(keys)}")
    values = {}
    for key, kind_of in keys.items():
      if key not in given:
        raise TaskFileError(f"{path}: [{section}] {key} is missing ({_describe(kind_of)})")
      values[key] = _check(path, section, key, given[key], kind_of)
    sections[section] = values
  return TaskFile(path, kind, sections, text)


def _describe(kind):
  if isinstance(kind, tuple):
    return f"one of {list(kind[1])}" if kind[0] == "choice" else f"a list of {kind[1]} integers"
  return {"float": "a number", "int": "an integer", "bool": "true or false",
          "str": "a string"}[kind]
