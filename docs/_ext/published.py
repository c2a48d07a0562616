"""The results the README and the documentation's pages publish, made from the reports
that hold them (figures/**/REPORT.md, which `hpg-mj reproduce` writes), so that a page
cannot say another number than its report. A page's generated part lies between two
comments, which neither GitHub nor the site shows:

    <!-- published NAME: made from REPORTS by docs/_ext/published.py -->
    ...
    <!-- /published NAME -->

After a report changes, `python docs/_ext/published.py` rewrites every such part of
the README and of docs/*.md (`--check` only says which differ, and exits 1). The site's
build refuses a page whose part differs from its report (`setup`), and
tests/test_published.py holds the README and the pages to the reports."""
import csv
import pathlib
import re
import sys

REPO = pathlib.Path(__file__).resolve().parents[2]
FULL = "figures/REPORT.md"
REFERENCE = "figures/reference/REPORT.md"
BEYOND = "figures/beyond/REPORT.md"
SPEC_D = "SPEC.md#10-declared-deviations-of-the-shipped-task-files"


# --- reading a report --------------------------------------------------------------

def _read(report):
  return (REPO / report).read_text()


def section(text, heading, report="a report"):
  """The text under the first heading that begins with `heading` (any level), to the
  next heading of its level or above."""
  match = re.search(rf"^(#+) {re.escape(heading)}.*$", text, re.M)
  if match is None:
    raise ValueError(f"{report} has no heading beginning {heading!r}")
  level = len(match.group(1))
  end = re.compile(rf"^#{{1,{level}}} ", re.M).search(text, match.end())
  return text[match.end():end.start() if end else len(text)]


def _cells(line):
  return [cell.strip() for cell in line.strip().strip("|").split("|")]


class Table:
  """A Markdown table of a report: its lines, and its cells by row and column label."""

  def __init__(self, lines, where):
    self.lines, self.where = lines, where
    self.header = _cells(lines[0])
    self.rows = {_cells(line)[0]: _cells(line) for line in lines[2:]}

  def __call__(self, row, column):
    if row not in self.rows:
      raise ValueError(f"{self.where}: no row {row!r}; rows: {list(self.rows)}")
    if column not in self.header:
      raise ValueError(f"{self.where}: no column {column!r}; columns: {self.header}")
    return self.rows[row][self.header.index(column)]

  def text(self):
    return "\n".join(self.lines)


def table(report, heading, index=0):
  """The `index`-th table under `heading` in `report` (a path under the repository)."""
  text = section(_read(report), heading, report)
  found, current = [], []
  for line in text.splitlines() + [""]:
    if line.startswith("|"):
      current.append(line)
    elif current:
      found.append(current)
      current = []
  if len(found) <= index:
    raise ValueError(f"{report}, '{heading}': no table {index}")
  return Table(found[index], f"{report}, '{heading}'")


def interval(cell):
  """'0.930 [0.925, 0.934], IQM 0.930' -> '0.930 [0.925, 0.934]'."""
  return cell.split(", IQM")[0]


def mean(cell):
  """'0.930 [0.925, 0.934], IQM 0.930' -> '0.930'."""
  return cell.split()[0]


# --- the published parts -------------------------------------------------------------

# The paper's results (Figures 6-11) by task file: (the report's column, the page's
# name for it, what the paper says, the deviations of SPEC section 10 it runs with).
SHIP = [("ship_hybrid", "Hierarchical hybrid", "Hierarchical hybrid",
         "~4 calls, ~220 steps", "D1, D2, D3"),
        ("ship_flat_pg", "Flat PGRL", "Flat PGRL", "worse than the hybrid", "D1"),
        ("ship_actor_critic", "Actor-critic", "Actor-critic", "worse than the hybrid", "D1"),
        ("ship_hybrid_eq3", "Hierarchical hybrid, plain Eq. 3",
         "Hierarchical hybrid, plain Eq. 3: no baseline, undiscounted trace",
         "(the paper's low level)", "D1, D2")]
TAXI = [("taxi_fuel_hpg", "HPG", "HPG", "second fastest", "D4, D5"),
        ("taxi_fuel_maxq", "MAXQ-Q", "MAXQ-Q", "fastest", "D6"),
        ("taxi_fuel_flat_q", "Flat Q-learning", "Flat Q-learning", "slowest", ""),
        ("taxi_fuel_hpg_eq3", "HPG, plain Eq. 3", "HPG, plain Eq. 3: no warm-up, no baseline",
         "(the paper's HPG)", ""),
        ("taxi_fuel_hpg_no_baseline", "HPG, no baseline",
         "HPG, no baseline: the ablation of D5", "(an ablation)", "D4"),
        ("taxi_fuel_hpg_no_warmup", "HPG, no warm-up", "HPG, no warm-up: the ablation of D4",
         "(an ablation)", "D5")]
README_TASKS = ("ship_hybrid", "ship_flat_pg", "ship_actor_critic", "taxi_fuel_hpg",
                "taxi_fuel_maxq", "taxi_fuel_flat_q")


def _taxi_facts():
  """The taxi report's optimum, its runs per learner, and how many of each learner's
  runs never reached 95% of the optimum (its "Against the paper" says)."""
  text = section(_read(FULL), "fig6:", FULL)
  optimum = float(re.search(r"Optimal mean return \(value iteration\): (\d+\.\d+)", text).group(1))
  runs = int(re.search(r"^(\d+) run\(s\) per task", text, re.M).group(1))
  never = re.search(r"Runs that never reached 95%: (.*?) \(left out", text)
  counts = {}
  for _, column, *_ in TAXI:
    found = re.search(rf"(?:^|, ){re.escape(column)} (\d+) of \d+", never.group(1)) \
        if never else None
    counts[column] = int(found.group(1)) if found else 0
  return optimum, runs, counts


def results_table():
  """docs/results.md's table: every learner of Figures 6-11, online and greedy."""
  ship, taxi = table(FULL, "fig7_11:"), table(FULL, "fig6:")
  for found, known in ((ship, SHIP), (taxi, TAXI)):
    unknown = set(found.header[1:]) - {column for _, column, *_ in known}
    if unknown:     # a learner the page has no row for: its paper and deviations
      raise ValueError(f"{found.where}: learners {sorted(unknown)} are not in "
                       "docs/_ext/published.py's SHIP or TAXI")
  optimum, runs, never = _taxi_facts()
  lines = ["| task file | online | greedy | paper | deviations ([SPEC section 10]"
           f"({SPEC_D})) |", "|---|---|---|---|---|"]

  def deviations(names):
    return f"[{names}]({SPEC_D})" if names else "none"

  for task, column, label, paper, names in SHIP:
    cell = lambda row: ship(row, column)
    online = (f"gate {interval(cell('gate pass rate, online'))}, "
              f"{interval(cell('control steps to the gate, online'))} control steps to the gate")
    if cell("low-level calls per episode, online") != "-":
      online += (f", {mean(cell('low-level calls per episode, online'))} calls per episode, "
                 f"diagonal {interval(cell('diagonal subtask success, online'))}, "
                 f"straight {interval(cell('straight subtask success, online'))}")
    online += f"; J {interval(cell('J (MushroomRL rewards), online'))}"
    greedy = (f"gate {interval(cell('gate pass rate, greedy'))}, "
              f"{interval(cell('control steps to the gate, greedy'))} steps; "
              f"J {interval(cell('J (MushroomRL rewards), greedy'))}")
    lines.append(f"| `{task}.toml` ({label}) | {online} | {greedy} | {paper} | "
                 f"{deviations(names)} |")
  for task, column, label, paper, names in TAXI:
    online_return = taxi("mean return, online", column)
    steps = taxi("million primitive steps to 95% of the optimum", column)
    online = f"return {interval(online_return)}"
    if steps != "-" and not never[column]:
      online += f" = {100 * float(mean(online_return)) / optimum:.1f}% of the optimal {optimum}"
    online += "; "
    if steps == "-":
      online += f"never reaches 95% (0 of {runs} runs)"
    else:
      online += f"95% after {interval(steps)} million primitive steps"
      if never[column]:
        online += f" in the {runs - never[column]} of {runs} runs that reach it"
    lines.append(f"| `{task}.toml` ({label}) | {online} | "
                 f"{interval(taxi('mean return, greedy', column))} | {paper} | "
                 f"{deviations(names)} |")
  return "\n".join(lines)


def readme_results():
  """The README's "Results": the paper's learners, the route past the paper's and the
  continuing task, online and greedy."""
  ship, taxi = table(FULL, "fig7_11:"), table(FULL, "fig6:")
  route = table(BEYOND, "A route past the paper's")
  patrol = table(BEYOND, "The continuing ship task")
  lines = ["| task file | online | greedy | the paper |", "|---|---|---|---|"]
  for task, column, label, paper, _ in SHIP:
    if task in README_TASKS:
      cell = lambda row: ship(row, column)
      lines.append(
          f"| `{task}` ({label}) | gate {interval(cell('gate pass rate, online'))}, "
          f"{mean(cell('control steps to the gate, online'))} steps, "
          f"J {mean(cell('J (MushroomRL rewards), online'))} | "
          f"gate {mean(cell('gate pass rate, greedy'))}, "
          f"{mean(cell('control steps to the gate, greedy'))} steps, "
          f"J {mean(cell('J (MushroomRL rewards), greedy'))} | {paper} |")
  for task, column, label, paper, _ in TAXI:
    if task in README_TASKS:
      lines.append(
          f"| `{task}` ({label}) | {interval(taxi('mean return, online', column))}; 95% of "
          f"the optimum after "
          f"{mean(taxi('million primitive steps to 95% of the optimum', column))} M steps | "
          f"{mean(taxi('mean return, greedy', column))} | {paper} |")
  lines.append(
      f"| `ship_hybrid_beyond` (beyond the paper) | | "
      f"gate {interval(route('gate passes', 'value'))}, "
      f"{mean(route('control steps to the gate (over passes)', 'value'))} steps, "
      f"J {mean(route('J (gamma 0.99, MushroomRL' + chr(39) + 's rewards)', 'value'))} | |")
  lines.append(
      f"| `ship_patrol_average_reward` (continuing) | "
      f"{mean(patrol('average-reward root, online (last block, exploring)', 'value'))} "
      f"gates an hour | {interval(patrol('average-reward root, greedy', 'value'))} gates an "
      f"hour | |")
  return "\n".join(lines)


# The reference report's tables: (its heading, the README's name of the task's score).
REFERENCE_TASKS = [("Ship steering", "ship (gate rate)"), ("Taxi-fuel", "taxi-fuel (return)")]


def readme_reference():
  """The README's "Reference scores": every learner of the reference report, its greedy
  score, normalized score, budget, seconds and seeds, as the report gives them."""
  lines = ["| task | learner | greedy score | normalized | steps a run (M) | s a run | "
           "seeds |", "|---|---|---|---|---|---|---|"]
  for heading, task in REFERENCE_TASKS:
    found = table(REFERENCE, heading)
    score, normalized, steps = found.header[2], found.header[3], found.header[-3]
    for row in found.rows:
      seeds = re.search(r"\(seeds ([^)]*)\)", found(row, "runs"))
      lines.append(f"| {task} | {row} | {interval(found(row, score))} | "
                   f"{mean(found(row, normalized))} | {mean(found(row, steps))} | "
                   f"{mean(found(row, 'wall-clock per run (s)'))} | "
                   f"{seeds.group(1) if seeds else found(row, 'runs')} |")
  return "\n".join(lines)


def beyond_patrol():
  """docs/beyond.md's continuing task: the report's table, and the paired difference
  (root minus episodic hybrid) seed by seed from the report's data,
  beyond_patrol_final.csv, with the interval the report's text gives it."""
  found = table(BEYOND, "The continuing ship task")
  text = section(_read(BEYOND), "The continuing ship task", BEYOND)
  paired = re.search(r"average-reward root minus episodic hybrid: (\S+ \[[^\]]+\])", text)
  with open(REPO / "figures/beyond/beyond_patrol_final.csv", newline="") as f:
    finals = list(csv.DictReader(f))
  differences = ", ".join(
      f"{float(r['greedy_gates_per_hour']) - float(r['episodic_gates_per_hour']):.1f}"
      for r in finals)
  return found.text() + f"\n| paired: root minus episodic hybrid | {paired.group(1)} | " \
                        f"{differences} |"


def beyond_route():
  """docs/beyond.md's route past the paper's: the report's table."""
  return table(BEYOND, "A route past the paper's").text()


def beyond_width():
  """docs/beyond.md's learned exploration width: the report's table."""
  return table(BEYOND, "A more expressive low-level policy").text()


LADDER = "figures/ladder/REPORT.md"
LADDER_LEVELS = ("easy", "medium", "hard")


def _ladder_tasks():
  """The ladder report's text and its task sections' names, in its order."""
  text = _read(LADDER)
  return text, re.findall(r"^## (ship_\w+)$", text, re.M)


def ladder_summary():
  """The README's and docs/results_ladder.md's short ladder table: per task, each
  level's leading learner and its success rate normalized (the report's mean over
  runs, and whether its lead is distinguishable), and the scripted helmsman's."""
  lines = ["| task (score, normalized) | easy | medium | hard | the scripted helmsman "
           "(easy, medium, hard) |", "|---|---|---|---|---|"]
  missing = {}        # learner -> the task/levels it has not run yet
  report, tasks = _ladder_tasks()
  for task in tasks:
    text = section(report, task, LADDER)
    for learner, row in table(LADDER, task).rows.items():
      runs = [int(n) for n in row[-1].split(",")]
      levels = [level for level, n in zip(LADDER_LEVELS, runs) if n == 0]
      if levels:
        missing.setdefault(learner, []).append(
            task if len(levels) == len(LADDER_LEVELS) else f"{task} at {', '.join(levels)}")
    cells = []
    for level in LADDER_LEVELS:
      lead = re.search(rf"^- {level}: (.+?) leads \((\S+) \[[^\]]*\]\); "
                       r"(its interval lies above|not distinguishable)", text, re.M)
      if lead is None:
        raise ValueError(f"{LADDER}, '{task}': no line saying who leads at {level}")
      learner = lead.group(1).removesuffix(f" ({task.removeprefix('ship_')})")
      apart = "" if lead.group(3).startswith("its") else " (not distinguishable)"
      cells.append(f"{learner} {lead.group(2)}{apart}")
    helm = re.search(r"scripted helmsman .*? scores easy (\S+), medium (\S+), hard (\S+) "
                     r"\((\w+), normalized\)", text)
    if helm is None:
      raise ValueError(f"{LADDER}, '{task}': no line giving the scripted helmsman's scores")
    score = helm.group(4).replace("_", " ")
    lines.append(f"| {task} ({score}) | {' | '.join(cells)} | "
                 f"{helm.group(1)}, {helm.group(2)}, {helm.group(3)} |")
  lines += [f"\nNot run yet, so in no lead: {learner} on {'; '.join(where)}."
            for learner, where in missing.items()]
  return "\n".join(lines)


def ladder_learners():
  """docs/results_ladder.md's table of every learner at every level of every task: its
  success rate normalized (the report's first score column of each level: the mean
  over runs [its 95% interval]), "-" where it has not run."""
  lines = ["| task (score, normalized) | learner | easy | medium | hard |",
           "|---|---|---|---|---|"]
  for task in _ladder_tasks()[1]:
    found = table(LADDER, task)
    columns = [next((i for i, label in enumerate(found.header)
                     if label.startswith(f"{level}: ")), None) for level in LADDER_LEVELS]
    if None in columns:
      raise ValueError(f"{LADDER}, '{task}': no column for each of {LADDER_LEVELS}; "
                       f"columns: {found.header}")
    score = found.header[columns[0]].split(": ", 1)[1].removesuffix(", normalized")
    for learner, row in found.rows.items():
      name = learner.removesuffix(f" ({task.removeprefix('ship_')})")
      lines.append(f"| {task} ({score.replace('_', ' ')}) | {name} | "
                   f"{' | '.join(row[i] for i in columns)} |")
  return "\n".join(lines)


# NAME -> (the function that makes the part, the reports it is made from)
PARTS = {"readme_results": (readme_results, (FULL, BEYOND)),
         "readme_reference": (readme_reference, (REFERENCE,)),
         "results_table": (results_table, (FULL,)),
         "beyond_patrol": (beyond_patrol, (BEYOND,)),
         "beyond_route": (beyond_route, (BEYOND,)),
         "beyond_width": (beyond_width, (BEYOND,)),
         "ladder_summary": (ladder_summary, (LADDER,)),
         "ladder_learners": (ladder_learners, (LADDER,))}

_PART = re.compile(r"^<!-- published (\w+):[^\n]*-->\n(.*?)^<!-- /published \1 -->$",
                   re.M | re.S)


def pages():
  """The README and docs/*.md, by path under the repository."""
  return ["README.md", *(p.relative_to(REPO).as_posix()
                         for p in sorted((REPO / "docs").glob("*.md")))]


def updated(text, where):
  """`text` with each of its published parts made again from the reports."""
  def fill(match):
    name = match.group(1)
    if name not in PARTS:
      raise ValueError(f"{where}: unknown published part {name!r}; known: {sorted(PARTS)}")
    make, reports = PARTS[name]
    return (f"<!-- published {name}: made from {', '.join(reports)} by "
            f"docs/_ext/published.py -->\n{make()}\n<!-- /published {name} -->")
  return _PART.sub(fill, text)


def _full_report_stale(write=False):
  """Whether figures/REPORT.md's reference section differs from the reference report
  it is made of (`figures.replace_section`; `write`: make it again)."""
  from hpg_mj.experiments import figures
  return figures.replace_section(REPO / "figures", "reference", write=write)


def stale():
  """The pages whose published parts differ from what the reports make now, and the
  full report if its reference section is an older copy."""
  return [page for page in pages()
          if updated((REPO / page).read_text(), page) != (REPO / page).read_text()] + \
      ([FULL] if _full_report_stale() else [])


def _check(app):
  if stale():
    raise RuntimeError(f"{', '.join(stale())}: a published table differs from its report; "
                       "run `python docs/_ext/published.py` to make it again")


def setup(app):
  app.connect("builder-inited", _check)
  return {"parallel_read_safe": True}


def main(argv):
  if "--check" in argv:
    found = stale()
    print("\n".join(f"{page}: differs from its report" for page in found) or "up to date")
    return 1 if found else 0
  for page in pages():
    path = REPO / page
    text = path.read_text()
    new = updated(text, page)
    if new != text:
      path.write_text(new)
      print(f"{page}: made again from its reports")
  if _full_report_stale(write=True):
    print(f"{FULL}: its reference section made again from {REFERENCE}")
  return 0


if __name__ == "__main__":
  sys.exit(main(sys.argv[1:]))
