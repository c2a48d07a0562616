"""The open machine's test oracle: a graph of blocks rewritten as a graph of Python
callables and step-by-step learner objects, run by the pure-Python executor
(`hierarchy.executor`, recursive Algorithm 1). The oracle shares only the
learning rules with the machine (`learners`), not its stack, its bookkeeping or
its order of calls, so a test that holds the two equal checks the machine's
control flow: calls, returns, rewards summed per level, ends, runs and draws."""
import numpy as np

from hpg_mj.hierarchy import blocks, calls, executor, ship_rules
from hpg_mj.hierarchy.graph import Child, Primitive, Subtask, TaskGraph
from hpg_mj.hierarchy.kinds.rules import Abstraction, InternalReward, Termination
from hpg_mj.learners import schedules, stepwise, tiles
from hpg_mj.worlds import ship_core as core


def _record(call):
  """The call's record as a user's rule reads it on the open machine (`hierarchy.calls`):
  its arguments by name, the observation where it began, its steps."""
  names = sorted(call.args)
  return calls.record(names)(*[call.args[k] for k in names],
                             np.ascontiguousarray(call.origin, dtype=np.float64),
                             int(call.steps))


def _grid_cell(x, y, cell_m, grid):
  return min(max(int(x // cell_m), 0), grid - 1) * grid + min(max(int(y // cell_m), 0), grid - 1)


class Oracle:
  """Runs `graph` (of blocks) with fresh learners of the same hyper-parameters."""

  def __init__(self, graph, rng_state):
    sb = graph.schedule or blocks.HeldEpsilon()
    self.schedule = schedules.new_schedule(sb.epsilon, sb.window, max(len(sb.watch), 1))
    self.sb = sb
    self.learners = {}
    self.names = [n for n in graph.nodes if n != graph.root] + [graph.root]
    self.counters = np.zeros((len(self.names), 3))
    self.learn = True
    nodes = []
    for name, node in graph.nodes.items():
      if isinstance(node, Primitive):
        nodes.append(node)
        continue
      refs = graph.children(name)
      learner = self._reflected(node, self._learner(node.learner, len(refs)))
      nodes.append(Subtask(name, children=[Child(r.node, **r.args) for r in refs],
                           learner=learner, view=self._view(node, len(refs), learner),
                           termination=self._end(node),
                           internal_reward=self._internal(node),
                           reward=self._seen(node), on_exit=self._exit(name)))
    self.graph = TaskGraph(graph.root, nodes, on_episode_end=self._episode_end)
    self.rng_state = rng_state

  def _learner(self, block, n_children):
    if id(block) not in self.learners:
      source = (lambda: self.schedule[0][0]) if getattr(block, "epsilon_schedule", 0) else None
      if isinstance(block, blocks.QTable):
        self.learners[id(block)] = stepwise.QLambda(
            block.n_states, n_children, block.alpha, block.trace_decay, block.gamma,
            block.epsilon, epsilon_source=source, trace_capacity=block.trace_capacity)
      elif isinstance(block, blocks.TiledQTable):
        self.learners[id(block)] = stepwise.TiledQLambda(
            block.coder.size, block.coder.n_tilings, n_children, block.alpha,
            block.trace_decay, block.gamma, block.epsilon, epsilon_source=source,
            trace_capacity=block.trace_capacity)
      else:
        self.learners[id(block)] = stepwise.GaussianPolicyGradient(
            block.coder.size, block.coder.n_tilings, block.r_max, block.alpha,
            block.trace_gamma, baseline=block.baseline, width_alpha=block.width_alpha,
            sigma_low=block.sigma_low, sigma_high=block.sigma_high)
    return self.learners[id(block)]

  @staticmethod
  def _reflected(node, learner):
    """An AimTiles node's learner: its draw times the side of its last view."""
    return _Reflected(learner) if isinstance(node.view, blocks.AimTiles) else learner

  @staticmethod
  def _target(view, call, obs):
    t = view.targets
    side = ship_rules.side_of(float(call.origin[1]))
    return ship_rules.target_of(call.args["target"], np.asarray(obs, dtype=np.float64), side,
                                t.inset_m, t.approach_m)

  def _view(self, node, n_children, learner):
    view = node.view
    if isinstance(view, blocks.GridCell):
      return lambda call, obs: _grid_cell(obs[0], obs[1], view.cell_m, view.grid)
    if isinstance(view, Abstraction):
      return lambda call, obs: int(view.rule(np.ascontiguousarray(obs, dtype=np.float64),
                                             _record(call)))
    arrays = view.coder.arrays()
    out = np.empty(view.coder.n_tilings, dtype=np.int64)
    local = np.empty(4)
    if isinstance(view, blocks.StateTiles):
      def state_view(call, obs):
        obs = np.asarray(obs, dtype=np.float64)
        tiles.active_tiles(obs[:len(view.coder.low)], arrays, out)
        if isinstance(node.available, blocks.NearGateLine):
          near = abs(obs[1] - ship_rules.GATE_Y) <= node.available.within_m
          return out, n_children if near else 1
        return out
      return state_view
    if isinstance(view, blocks.AimTiles):
      aim = np.empty(3)
      sqrt_error = view.error_scale == "sqrt"
      reflect_at = ship_rules.error_coordinate(view.reflect_deg, view.error_scale)

      def aim_view(call, obs):
        # The executor views the state it acts in last before acting, so the side
        # set here is the one its act() applies.
        tx, ty = self._target(view, call, obs)
        learner.side = ship_rules.aim_view(np.asarray(obs, dtype=np.float64), tx, ty, aim,
                                                 sqrt_error, reflect_at)
        tiles.active_tiles(aim, arrays, out)
        return out
      return aim_view

    def local_view(call, obs):
      core.global_to_local(obs, self._origin(call), call.args["direction"], local)
      tiles.active_tiles(local, arrays, out)
      return out
    return local_view

  @staticmethod
  def _origin(call):
    return call.memo.setdefault("origin", np.array(call.origin[:2], dtype=np.float64))

  def _outcome(self, node, call, step):
    """(the call's event, G) after a child returned, once per return."""
    if call.memo.get("seen_at") != call.steps:
      event, internal = core.NO_EVENT, 0.0
      obs = np.ascontiguousarray(step.obs, dtype=np.float64)
      arg = call.args.get("direction", -1)
      if isinstance(node.termination, blocks.LocalGoal):
        event, internal = core.low_level_outcome(
            step.info["positions"], step.obs, self._origin(call), arg, call.steps,
            np.empty((4, 2)), np.empty(4), node.termination.max_steps)
      elif isinstance(node.termination, blocks.TargetReached):
        tx, ty = self._target(node.view, call, obs)
        t = node.view.targets
        weight = node.internal_reward.weight if isinstance(node.internal_reward,
                                                           blocks.Shaping) else 0.0
        event, internal = ship_rules.aim_outcome(step.info["positions"], obs, call.args["target"],
                                                 tx, ty, call.steps, node.termination.max_steps,
                                                 t.radius_m, weight)
        if not isinstance(node.internal_reward, blocks.Shaping):
          internal = 0.0
      elif isinstance(node.termination, Termination):
        event = int(node.termination.rule(obs, _record(call)))
      if isinstance(node.internal_reward, InternalReward):
        internal = float(node.internal_reward.rule(obs, _record(call), event))
      call.memo.update(seen_at=call.steps, event=event, internal=internal)
    return call.memo["event"], call.memo["internal"]

  def _end(self, node):
    if isinstance(node.termination, blocks.Never):
      return lambda call, step: False
    return lambda call, step: self._outcome(node, call, step)[0] != core.NO_EVENT

  def _internal(self, node):
    if node.internal_reward is None:
      return None
    return lambda call, step: self._outcome(node, call, step)[1]

  def _seen(self, node):
    if node.reward != blocks.STEP:
      return None

    def step_reward(call, step, child_reward):
      k = call.steps - call.memo.get("counted", 0)
      call.memo["counted"] = call.steps
      return core.STEP_REWARD * k
    return step_reward

  def _exit(self, name):
    i = self.names.index(name)

    def on_exit(call, step, episode_over):
      if name == self.names[-1]:
        return
      self.counters[i, 0] += 1
      if not episode_over:
        success = call.memo.get("event") == core.SUCCESS
        self.counters[i, 1] += 1
        self.counters[i, 2] += success
        if self.learn and name in self.sb.watch:
          schedules.record_run(self.schedule[1], self.schedule[2], self.sb.watch.index(name),
                               success)
    return on_exit

  def _episode_end(self, last, learn):
    if learn:
      schedules.end_episode(*self.schedule, self.sb.threshold, self.sb.every, self.sb.divisor)

  def run(self, env, episodes, learn, sample, start, on_call=None):
    """Rows as the machine's: passed, steps, return, 0, per node calls, runs, successes."""
    run = executor.Executor(self.graph, executor.adapter_for(env), self.rng_state,
                            on_call=on_call)
    rows = np.zeros((episodes, 4 + self.counters.size))
    self.learn = learn
    for i in range(episodes):
      self.counters[:] = 0.0
      total, steps, last = run.run_episode(start(), learn=learn, sample=sample)
      rows[i, :3] = last.info.get("event") == "gate", steps, total
      rows[i, 4:] = self.counters.reshape(-1)          # column 3: the taxi's illegal actions
    return rows


class _Reflected:
  """A learner whose draw is negated where its AimTiles view reflected the state."""

  def __init__(self, learner):
    self.learner = learner
    self.side = 1.0

  def act(self, features, mask, rng_state, sample):
    return self.side * self.learner.act(features, mask, rng_state, sample)

  def __getattr__(self, name):
    return getattr(self.learner, name)
