"""Task files: TOML declarations of an agent (`[task] kind`), its configuration
(one section per part: environment, root, low level, ...) and the protocol
(tasks/*.toml).

An agent's `Config` dataclass is the schema: its fields are the sections, each a
dataclass whose fields (made with `param`) are the keys, with their types,
defaults, meanings and allowed ranges. Every key of a section is required, but for a
key added to a schema after task files of it were written and saved with agents
(`param(absent=...)`): a file without it means the value `absent`, the behaviour before
the key, so that an agent saved before it loads and runs as it did. An unknown key, a
wrong type, a missing value or one out of range is refused with the file, the key and
what is allowed, before anything runs.
"""
import dataclasses
import math
import pathlib
import tomllib

from hpg_mj import _paths
from hpg_mj.learners.rng import MAX_SEED

# Types accepted for a schema entry: "float" (int or float), "int", "bool",
# "str", "str_list" (a non-empty list of strings), ("choice", options),
# ("int_list", length) (positive integers; length None: one or more), ("int_min", least),
# ("float_lists", length, description) (a non-empty list of lists of numbers).


class TaskFileError(ValueError):
  """A task file that cannot be used; the message names the file and the key."""


def _check(path, where, key, value, kind):
  where = f"{path}: {where} {key}"
  if isinstance(kind, tuple) and kind[0] == "choice":
    if value not in kind[1]:
      raise TaskFileError(f"{where} = {value!r} is not allowed; allowed: {list(kind[1])}")
    return value
  if isinstance(kind, tuple) and kind[0] == "int_list":
    count = "one or more" if kind[1] is None else kind[1]
    if (not isinstance(value, list) or not value
        or (kind[1] is not None and len(value) != kind[1])
        or not all(_is_int(v) and v > 0 for v in value)):
      raise TaskFileError(f"{where} must be a list of {count} positive integers, got {value!r}")
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
  if kind in ("int_list_any", "seed_list"):
    high = MAX_SEED if kind == "seed_list" else math.inf
    if not isinstance(value, list) or not value or not all(_is_int(v) and 0 <= v <= high
                                                           for v in value):
      raise TaskFileError(f"{where} must be {_describe(kind)}, got {value!r}")
    return list(value)
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
  if not isinstance(table, dict):
    raise TaskFileError(f"{path}: {where} must be a table of keys, got {table!r}")
  optional = optional or {}
  allowed = {**required, **optional}
  unknown = set(table) - set(allowed)
  if unknown:
    raise TaskFileError(f"{path}: {where} unknown key(s) {sorted(unknown)}; allowed: "
                        f"{sorted(allowed)}")
  missing = [key for key in required if key not in table]
  if len(missing) == 1:
    raise TaskFileError(f"{path}: {where} {missing[0]} is missing "
                        f"({_describe(required[missing[0]])})")
  if missing:                                   # all of them at once, not one a try
    raise TaskFileError(f"{path}: {where} {', '.join(missing[:-1])} and {missing[-1]} are "
                        "missing (" + "; ".join(f"{key}: {_describe(required[key])}"
                                                for key in missing) + ")")
  return {key: _check(path, where, key, table[key], kind)
          for key, kind in allowed.items() if key in table}


# ---- configurations as dataclasses: the schema of a task file -------------------

_REQUIRED = object()


def param(default, doc="", *, low=None, high=None, low_open=False, high_open=False,
          choices=None, length=None, absent=_REQUIRED):
  """A field of a task file's section: its default, what it means, and what is
  allowed (`low`/`high` bounds, open with `low_open`/`high_open`; `choices`;
  `length` for a list of positive integers, None for one or more). `absent`: for a
  key added after files without it were written, the value a file without it means
  (the behaviour before the key); without `absent` the key is required."""
  meta = {"doc": doc, "low": low, "high": high, "low_open": low_open,
          "high_open": high_open, "choices": choices, "length": length, "absent": absent}
  if isinstance(default, (list, dict)):
    return dataclasses.field(default_factory=lambda: type(default)(default), metadata=meta)
  return dataclasses.field(default=default, metadata=meta)


def _field_kind(field):
  meta, typ = field.metadata, field.type
  typ = typ if isinstance(typ, type) else {"float": float, "int": int, "bool": bool,
                                           "str": str, "tuple": tuple, "list": list}[typ]
  if meta.get("choices"):
    return ("choice", tuple(meta["choices"]))
  if typ is tuple:
    return ("int_list", meta["length"])
  if typ is list:
    return "int_list_any"
  return {float: "float", int: "int", bool: "bool", str: "str"}[typ]


def section_schema(section_class):
  """{key: type} of one section dataclass, for `check_table`."""
  return {f.name: _field_kind(f) for f in dataclasses.fields(section_class)}


def config_schema(config_class):
  """{section: {key: type}} of a configuration dataclass whose fields are sections."""
  return {f.name: section_schema(f.type if isinstance(f.type, type) else f.default_factory)
          for f in dataclasses.fields(config_class)}


def _range(meta):
  parts = []
  if meta.get("low") is not None:
    parts.append(f"{'>' if meta['low_open'] else '>='} {meta['low']}")
  if meta.get("high") is not None:
    parts.append(f"{'<' if meta['high_open'] else '<='} {meta['high']}")
  return " and ".join(parts)


def check_range(where, section, field, value):
  """Refuses a value outside its field's bounds or choices, naming the key and what is
  allowed (`where`: the task file, or the section's class when it is made in Python)."""
  meta = field.metadata
  choices = meta.get("choices")
  if choices and value not in choices:
    raise TaskFileError(f"{where}: [{section}] {field.name} = {value!r} is not allowed; "
                        f"allowed: {list(choices)}")
  low, high = meta.get("low"), meta.get("high")
  values = value if isinstance(value, (tuple, list)) else (value,)
  for v in values:
    bad = ((low is not None and (v <= low if meta["low_open"] else v < low)) or
           (high is not None and (v >= high if meta["high_open"] else v > high)))
    if bad:
      raise TaskFileError(f"{where}: [{section}] {field.name} = {value!r} is out of range; "
                          f"allowed: {_range(meta)}")
    if isinstance(v, float) and not math.isfinite(v):
      raise TaskFileError(f"{where}: [{section}] {field.name} = {value!r} is not finite")


class Section:
  """Base of a task file's section dataclass: a value out of its field's range is
  refused however the section is made (from a file, or in Python)."""

  def __post_init__(self):
    name = getattr(type(self), "section_name", type(self).__name__)
    for field in dataclasses.fields(self):
      check_range(type(self).__qualname__, name, field, getattr(self, field.name))


def build_section(where, section, section_class, table):
  """A section dataclass from a TOML table: keys, types and ranges checked."""
  schema, fields = section_schema(section_class), dataclasses.fields(section_class)
  optional = {f.name: schema.pop(f.name) for f in fields
              if f.metadata.get("absent", _REQUIRED) is not _REQUIRED}
  values = check_table(where, f"[{section}]", table, schema, optional)
  for field in fields:
    if field.name not in values:
      values[field.name] = field.metadata["absent"]
    check_range(where, section, field, values[field.name])
  return section_class(**values)


def updated(config, **sections):
  """A copy of a configuration with some keys changed, section by section:
  `updated(config, root={"alpha": 0.5}, environment={"max_steps": 400})`. The
  changed sections are checked as a task file's are."""
  fields = {f.name for f in dataclasses.fields(config)}
  unknown = set(sections) - fields
  if unknown:
    raise TaskFileError(f"{type(config).__qualname__}: unknown section(s) {sorted(unknown)}; "
                        f"allowed: {sorted(fields)}")
  changes = {}
  for name, values in sections.items():
    section = getattr(config, name)
    keys = {f.name for f in dataclasses.fields(section)}
    wrong = set(values) - keys
    if wrong:
      raise TaskFileError(f"{type(config).__qualname__}: [{name}] unknown key(s) "
                          f"{sorted(wrong)}; allowed: {sorted(keys)}")
    changes[name] = dataclasses.replace(section, **values)
  return dataclasses.replace(config, **changes)


def describe_config(config_class):
  """The sections and keys of a configuration, with their defaults and meanings."""
  lines = []
  for sec in dataclasses.fields(config_class):
    cls = sec.type if isinstance(sec.type, type) else sec.default_factory
    lines.append(f"[{sec.name}]")
    for f in dataclasses.fields(cls):
      default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
      allowed = _range(f.metadata) or (f"one of {list(f.metadata['choices'])}"
                                        if f.metadata.get("choices") else "")
      lines.append(f"{f.name} = {default!r}  # {f.metadata.get('doc', '')}"
                   + (f" ({allowed})" if allowed else ""))
  return "\n".join(lines)


def _toml_value(value):
  if isinstance(value, bool):
    return "true" if value else "false"
  if isinstance(value, (int, float)):
    return repr(value) if math.isfinite(value) else ("nan" if value != value else
                                                     ("inf" if value > 0 else "-inf"))
  if isinstance(value, str):
    return '"' + value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
  if isinstance(value, (tuple, list)):
    return "[" + ", ".join(_toml_value(v) for v in value) + "]"
  raise TypeError(f"{value!r} ({type(value).__name__}) has no task-file form")


def dumps(kind, config, episodes, seed, description=""):
  """The text of a task file that builds `config` for agent `kind` (a registered
  name or "module:Class"): what `agents.save` records for an agent made in Python
  without one, so that `agents.load` rebuilds it."""
  lines = ["[task]", f"kind = {_toml_value(kind)}", f"description = {_toml_value(description)}"]
  for sec in dataclasses.fields(config):
    section = getattr(config, sec.name)
    lines += ["", f"[{sec.name}]"] + [f"{f.name} = {_toml_value(getattr(section, f.name))}"
                                      for f in dataclasses.fields(section)]
  lines += ["", "[protocol]", f"episodes = {max(int(episodes), 1)}", f"seed = {int(seed)}"]
  return "\n".join(lines) + "\n"


# ---- task files ---------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Task(Section):
  """[task]: which agent (`kind`, a registered name) and what the file is for."""
  kind: str = param("", "the agent, by its registered name")
  description: str = param("", "one line on what this task file trains")


@dataclasses.dataclass(frozen=True)
class Protocol(Section):
  """[protocol]: how long a run trains, its default seed, and the seeds its
  hyper-parameters were tuned on (never reported)."""
  episodes: int = param(1000, "training episodes of one run", low=1)
  seed: int = param(0, "the default seed", low=0, high=MAX_SEED)


PROTOCOL_OPTIONAL = {"tuning_seeds": "seed_list"}
# A continuing agent (its class sets `record_steps`, the control steps of one record
# row) may give its training length in control steps or hours of sailing instead
# of episodes (SPEC section 8); exactly one of the three. It becomes `episodes`, the
# number of record rows, so everything downstream counts rows as before.
PROTOCOL_LENGTHS = {"episodes": "int", "control_steps": "int", "hours": "float"}
CONTROL_STEPS_PER_HOUR = 6000       # 0.6 s control steps (SPEC section 8)


def _protocol_length(path, table, agent_class):
  """Replaces `control_steps` or `hours` in a [protocol] table by `episodes`;
  returns the control steps asked for (None when given in episodes)."""
  given = [k for k in PROTOCOL_LENGTHS if k in table]
  record_steps = getattr(agent_class, "record_steps", None)
  if record_steps is None:
    extra = [k for k in given if k != "episodes"]
    if extra:
      raise TaskFileError(f"{path}: [protocol] {extra[0]} is for continuing agents; "
                          f"{agent_class.name!r} is episodic: give [protocol] episodes")
    return None
  if len(given) != 1:
    raise TaskFileError(f"{path}: [protocol] needs exactly one of {list(PROTOCOL_LENGTHS)} "
                        f"for the continuing agent {agent_class.name!r}, got "
                        f"{given or 'none'}")
  key = given[0]
  if key == "episodes":
    return None
  value = _check(path, "[protocol]", key, table.pop(key), PROTOCOL_LENGTHS[key])
  steps = value * CONTROL_STEPS_PER_HOUR if key == "hours" else value
  rows = steps / record_steps
  if not steps > 0 or rows != int(rows):
    raise TaskFileError(f"{path}: [protocol] {key} = {value!r} must be a positive whole "
                        f"number of record rows of {record_steps} control steps "
                        f"({record_steps / CONTROL_STEPS_PER_HOUR:g} h) each")
  table["episodes"] = int(rows)
  return int(steps)

# [task] label: the learner's name in figures and reports (the paper's, e.g.
# "Hierarchical hybrid"); without it the file's name is shown.
TASK_OPTIONAL = {"label": "str"}


@dataclasses.dataclass
class TaskFile:
  """A loaded task file: its agent's kind and class, its configuration (the
  agent's Config dataclass), its protocol, and its text (saved with agents)."""
  path: pathlib.Path
  kind: str
  description: str
  config: object
  protocol: Protocol
  tuning_seeds: tuple
  text: str
  control_steps: int = None     # a continuing agent's training length, as given
  label: str = None
  tuning: dict = None      # [tuning], checked (`check_tuning`), or None

  @property
  def name(self):
    """The name shown in figures and reports: [task] label, else the file's name."""
    return self.label or self.path.stem

  def section(self, name):
    """A section's values as a dict (`protocol` included, with its tuning seeds)."""
    if name == "protocol":
      return {**dataclasses.asdict(self.protocol), "tuning_seeds": list(self.tuning_seeds)}
    return dataclasses.asdict(getattr(self.config, name))


def load(path, registry):
  """Reads and validates a task file.

  `registry.lookup(kind)` gives the agent class for the file's `[task] kind`;
  the class's `Config` (a dataclass of section dataclasses) is the schema.
  """
  path = pathlib.Path(path)
  if not path.is_file():
    raise TaskFileError(f"{path}: no such task file")
  return loads(_paths.read_text(path, "task file", TaskFileError), path, registry)


def loads(text, path, registry):
  """`load` from the file's text (`path` names it in errors)."""
  path = pathlib.Path(path)
  try:
    data = tomllib.loads(text)
  except tomllib.TOMLDecodeError as err:
    raise TaskFileError(f"{path}: not valid TOML: {err}") from None
  task = data.get("task")
  if not isinstance(task, dict) or "kind" not in task:
    raise TaskFileError(f"{path}: [task] kind is missing; allowed kinds: {registry.names()}")
  kind = task["kind"]
  how = getattr(registry, "how_to_add", "")       # a user's agent: the ways to it
  if not isinstance(kind, str) or (kind not in registry.names() and not (how and ":" in kind)):
    raise TaskFileError(f"{path}: [task] kind = {kind!r} is not allowed; allowed: "
                        f"{registry.names()}" + (f", {how}" if how else ""))
  try:
    agent_class = registry.lookup(kind)
  except (ValueError, TypeError, ImportError) as err:    # a user's class that is not found
    text = str(err).removeprefix(f"{kind!r}: ")
    raise TaskFileError(f"{path}: [task] kind = {kind!r}: {text}") from None
  data = dict(data)
  tuning_table = data.pop("tuning", None)
  schema = {"task": section_schema(Task), **config_schema(agent_class.Config),
            "protocol": section_schema(Protocol)}
  unknown_sections = set(data) - set(schema)
  if unknown_sections:
    raise TaskFileError(f"{path}: unknown section(s) {sorted(unknown_sections)}; allowed: "
                        f"{sorted(schema)}")
  for section, keys in schema.items():
    if not isinstance(data.get(section), dict):
      raise TaskFileError(f"{path}: section [{section}] is missing; it needs the keys "
                          f"{sorted(keys)}")
  task = dict(task)
  label = check_table(path, "[task]", {k: task.pop(k) for k in TASK_OPTIONAL if k in task},
                      {}, TASK_OPTIONAL).get("label")
  head = build_section(path, "task", Task, task)
  proto_table = dict(data["protocol"])
  tuning = check_table(path, "[protocol]", {k: proto_table.pop(k) for k in PROTOCOL_OPTIONAL
                                            if k in proto_table},
                       {}, PROTOCOL_OPTIONAL).get("tuning_seeds", [])
  control_steps = _protocol_length(path, proto_table, agent_class)
  protocol = build_section(path, "protocol", Protocol, proto_table)
  sections = {}
  for sec in dataclasses.fields(agent_class.Config):
    cls = sec.type if isinstance(sec.type, type) else sec.default_factory
    sections[sec.name] = build_section(path, sec.name, cls, data[sec.name])
  try:
    config = agent_class.Config(**sections)
  except (TypeError, ValueError) as err:
    raise TaskFileError(f"{path}: {err}") from None
  tuning_section = None if tuning_table is None else check_tuning(path, tuning_table,
                                                                  agent_class.Config)
  return TaskFile(path, kind, head.description, config, protocol, tuple(tuning), text,
                  control_steps, label, tuning_section)


def assigned(task, assignments, registry):
  """The task file `task` (a `TaskFile`) with keys set, each assignment
  "section.key=value" (`hpg-mj train --set environment.level=hard`): the value in
  TOML (a string may go unquoted), written over the line `key = ...` of the file's
  [section] (every key of a section has one), and the text loaded again, so that it
  is checked as a task file is and an agent saved with it rebuilds the same
  configuration. One line naming the assignment where it is malformed, where the
  file has no such section or key, or where the file refuses the value."""
  text = task.text
  for assignment in assignments:
    name, sep, raw = str(assignment).partition("=")
    section, dot, key = name.strip().rpartition(".")
    if not (sep and dot and section and key):
      raise TaskFileError(f"{task.path}: --set {assignment!r}: give SECTION.KEY=VALUE, for "
                          "example environment.level=hard")
    try:
      value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
      value = raw.strip()                  # a bare word: a string
    text = _set_line(text, task.path, section, key, value, assignment)
  try:
    return loads(text, task.path, registry)
  except TaskFileError as err:         # a value the file's schema refuses: name the --set
    sets = " ".join(f"--set {a!r}" for a in assignments)
    raise TaskFileError(f"{task.path}, with {sets}: "
                        f"{str(err).removeprefix(f'{task.path}: ')}") from None


def _set_line(text, path, section, key, value, assignment):
  """`text` with the line `key = ...` of its [section] rewritten to `value`."""
  lines = text.splitlines(keepends=True)
  headers = [(i, line.split("]")[0].strip(" \t[")) for i, line in enumerate(lines)
             if line.lstrip().startswith("[")]
  starts = [i for i, name in headers if name == section]
  if not starts:
    raise TaskFileError(f"{path}: --set {assignment!r}: the file has no [{section}]; its "
                        f"sections: {[name for _, name in headers]}")
  end = next((i for i, _ in headers if i > starts[0]), len(lines))
  keys = {}
  for i in range(starts[0] + 1, end):
    left, sep, _ = lines[i].partition("=")
    if sep and not left.lstrip().startswith("#"):
      keys[left.strip()] = i
  if key not in keys:
    raise TaskFileError(f"{path}: --set {assignment!r}: [{section}] has no key {key!r}; its "
                        f"keys: {sorted(keys)}")
  try:
    lines[keys[key]] = f"{key} = {_toml_value(value)}    # set by --set\n"
  except TypeError:
    raise TaskFileError(f"{path}: --set {assignment!r}: the value is no number, string, "
                        "boolean or list") from None
  changed = "".join(lines)
  try:
    new = tomllib.loads(changed)
  except tomllib.TOMLDecodeError:
    new = None
  old = table = tomllib.loads(text)
  for part in section.split("."):
    table = table[part]
  table[key] = value
  if new != old:               # a value written over several lines: refused, not guessed
    raise TaskFileError(f"{path}: --set {assignment!r}: [{section}] {key} is not on one line "
                        "of the file; change it there")
  return changed


# [tuning]: what a task file's hyper-parameters were tuned over, by `hpg-mj tune`
# (SPEC section 7: every learner of a figure gets the same budget, on the tuning
# seeds). Its [tuning.grid] names each tuned key by its section, e.g.
# `root.alpha = [0.1, 0.3]`; `result` says what the last tuning found.
TUNING_REQUIRED = {"score": "str", "better": ("choice", ("higher", "lower")),
                   "episodes": ("int_min", 1), "budget": ("int_min", 1)}
TUNING_OPTIONAL = {"result": "str"}


def check_tuning(path, table, config_class):
  """[tuning] of a task file: its keys, and a grid of lists of allowed values of
  the configuration's own keys."""
  if not isinstance(table, dict):
    raise TaskFileError(f"{path}: [tuning] must be a table, got {table!r}")
  table = dict(table)
  grid = table.pop("grid", None)
  values = check_table(path, "[tuning]", table, TUNING_REQUIRED, TUNING_OPTIONAL)
  sections = {f.name: (f.type if isinstance(f.type, type) else f.default_factory)
              for f in dataclasses.fields(config_class)}
  if not isinstance(grid, dict) or not grid:
    raise TaskFileError(f"{path}: [tuning.grid] is missing; it lists the values tried per "
                        f"key, e.g. root.alpha = [0.1, 0.3], of the sections {sorted(sections)}")
  checked = {}
  for section, keys in grid.items():
    if section not in sections or not isinstance(keys, dict):
      raise TaskFileError(f"{path}: [tuning.grid] {section!r} is not a section of this task; "
                          f"allowed: {sorted(sections)}")
    fields = {f.name: f for f in dataclasses.fields(sections[section])}
    for key, options in keys.items():
      where = f"[tuning.grid] {section}.{key}"
      if key not in fields:
        raise TaskFileError(f"{path}: {where} is not a key of [{section}]; allowed: "
                            f"{sorted(fields)}")
      if not isinstance(options, list) or not options:
        raise TaskFileError(f"{path}: {where} must be a non-empty list of values, got "
                            f"{options!r}")
      kind = _field_kind(fields[key])
      converted = []
      for v in options:
        v = _check(path, where, "", v, kind)
        check_range(str(path), section, fields[key], v)
        converted.append(v)
      checked.setdefault(section, {})[key] = converted
  values["grid"] = checked
  return values


def _describe(kind):
  if isinstance(kind, tuple):
    return {"choice": lambda: f"one of {list(kind[1])}",
            "int_list": lambda: ("a list of one or more positive integers" if kind[1] is None
                                 else f"a list of {kind[1]} integers"),
            "int_min": lambda: "a positive integer" if kind[1] == 1 else f"an integer >= {kind[1]}",
            "float_lists": lambda: f"a non-empty list of {kind[2]}"}[kind[0]]()
  return {"float": "a number", "int": "an integer", "bool": "true or false",
          "str": "a string", "str_list": "a non-empty list of strings",
          "int_list_any": "a non-empty list of integers >= 0",
          "seed_list": f"a non-empty list of seeds, integers in 0..{MAX_SEED}"}[kind]
