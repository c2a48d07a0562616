"""A hierarchy of one's own, from scratch: `ShipHierarchy`, the public base class of a
user's hierarchy on the ship, run by the open machine (`hierarchy.program`).

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

from hpg_mj.agents import _ship
from hpg_mj.agents import _taxi


@dataclasses.dataclass(frozen=True)
class HierarchyConfig:
  """A ship hierarchy's task file: its [environment] (a subclass adds its own sections).
  Its defaults are the environments' own (leaving the field -100, MushroomRL's); the
  shipped ship agents' task files set out_of_bounds_reward = -300 (SPEC section 10, D1)."""
  environment: _ship.ShipEnvironment = dataclasses.field(default_factory=_ship.ShipEnvironment)


@dataclasses.dataclass(frozen=True)
class TaxiHierarchyConfig:
  """A taxi hierarchy's task file: its [environment] (a subclass adds its own sections)."""
  environment: _taxi.TaxiEnvironment = dataclasses.field(default_factory=_taxi.TaxiEnvironment)


class ShipHierarchy(_ship.ShipMachineAgent):
  """A user's hierarchy on the full ship task (see the module docstring): give
  `graph()`; `root_args` are the root call's arguments, if its rules read any."""

  Config = HierarchyConfig
  record_fields = ("passed", "steps", "return", "calls")


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
