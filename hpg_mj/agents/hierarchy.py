"""A hierarchy of one's own, from scratch: `ShipHierarchy`, the public base class of a
user's hierarchy on the ship, run by the open machine (`hierarchy.program`), and
`ShipLadderHierarchy`, the same on a task of the ladder (SPEC section 11) at a level.

```python
class Waypoints(ShipHierarchy):
  record_fields = ("passed", "steps", "return", "calls", "goto_runs")

  def graph(self):
    return TaskGraph("root", [...])      # blocks, your rules, Child arguments
```

Its graph is compiled once (the first `train`), fused with the analytic ship and step
by step through any Gymnasium or dm_control ship; its learned arrays are its state
by node name (`state()`: `"goto.theta"`, ... beside the generator's `rng_state`), so
that `hpg-mj train`, `evaluate`, `render --agent` and the runner's checkpoints save
and restore it with no code of its own (a task file names it by `kind =
"my_module:Waypoints"`). `parameters()` gives each learner's parameters by name.
Its record: the fields of `record_fields` among passed, steps, return, calls (the
calls below the root) and, per subtask, `{node}_runs`, `{node}_successes`.
"""
import dataclasses

from hpg_mj.agents import _ladder
from hpg_mj.agents import _ship
from hpg_mj.agents import _taxi


@dataclasses.dataclass(frozen=True)
class HierarchyConfig:
  """A ship hierarchy's task file: its [environment] (a subclass adds its own sections).
  Its defaults are the environments' own (leaving the field -100, MushroomRL's); the
  shipped ship agents' task files set out_of_bounds_reward = -300 (SPEC section 10, D1)."""
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)


@dataclasses.dataclass(frozen=True)
class LadderHierarchyConfig:
  """A ladder hierarchy's task file: its [environment], which names the task and its
  level (`world = "ship_goal"`, `level = "hard"`) with the task's rewards and step limit
  (a subclass adds its own sections)."""
  environment: _ladder.LadderEnvironment = dataclasses.field(
      default_factory=_ladder.LadderEnvironment)


@dataclasses.dataclass(frozen=True)
class TaxiHierarchyConfig:
  """A taxi hierarchy's task file: its [environment] (a subclass adds its own sections)."""
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)


class ShipHierarchy(_ship.ShipMachineAgent):
  """A user's hierarchy on the full ship task (see the module docstring): give
  `graph()`; `root_args` are the root call's arguments, if its rules read any."""

  Config = HierarchyConfig
  record_fields = ("passed", "steps", "return", "calls")


class ShipLadderHierarchy(_ladder.LadderMachineAgent):
  """A user's hierarchy on a task of the ladder (SPEC section 11) at a level, named by
  its [environment] (`LadderHierarchyConfig`): give `graph()`. The open machine runs it
  fused with the task's analytic world (`Program.run_world`: the world's own compiled
  rules, millions of control steps a second) and step by step through the task's
  Gymnasium environment (`make_env`; a trained agent is evaluated and rendered there),
  the same rows for a fixed seed. Its rules read the observation the environment gives
  (`obs_size` numbers): the current's state and water (6), the goal's dictionary
  flattened as observation, achieved_goal, desired_goal, ranges (19), the regatta's state, two
  gates and the gates left (11), the harbour's state and seven ranges (11); the ship's
  [x, y, theta_deg, theta_dot_deg] first on every task, so the steering task's views
  (`blocks.GridCell`, `blocks.LocalTiles`) read it as they are. Its metrics are the
  benchmark's for the task (`hpg_mj.benchmark`), scored from its fixed starts
  (`evaluate_fixed`) and normalized against its bounds by `hpg-mj train` and `evaluate`.
  Its record: the fields of `record_fields` among passed (the gate; the regatta's
  finish), steps, return, gates (the regatta's gates passed; 0 on the other tasks), calls
  and `{node}_runs`, `{node}_successes`."""

  Config = LadderHierarchyConfig
  record_fields = ("passed", "steps", "return", "gates", "calls")


class TaxiHierarchy(_taxi.TaxiMachineAgent):
  """A hierarchy on the taxi (SPEC section 5), fused with the taxi's rules
  (`Program.run_taxi`) and step by step through any taxi environment: give
  `graph()`. Its kinds read the task's world (`taxi_rules.world_config`); its
  observation is (row, col, passenger, destination[, fuel])."""

  Config = TaxiHierarchyConfig
  record_fields = ("return", "steps", "outcome")

  @property
  def obs_size(self):
    """The observation's length: 5 with the fuel tank, 4 for the classic taxi."""
    return 5 if self.rules.fuel_enabled else 4
