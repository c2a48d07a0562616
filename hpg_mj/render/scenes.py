"""Pictures of the worlds for the user's process, drawn in the render worker.

Nothing here loads OpenGL: the frames come from `hpg_mj._render_worker`, which
picks EGL, then OSMesa, in its own process (SPEC section 9).
"""
import numpy as np

from hpg_mj import _render_worker as worker


class ShipScene:
  """Renders ship states: the field, the gate, the bounds, the ship and its wake."""

  def __init__(self, width=640, height=480, model="ship.xml"):
    self.width, self.height = int(width), int(height)
    self._worker = worker.RenderWorker("ship", width=self.width, height=self.height,
                                       model=model)

  @property
  def backend(self):
    """The worker's OpenGL backend ("egl", "osmesa"), or None before the first frame."""
    return self._worker.backend

  def render(self, state, trail=(), target=None, camera="top", marks=(), gate=None,
             course=None, next_gate=0, obstacles=None):
    """An RGB frame (height, width, 3) of the ship at `state` [x, y, theta_deg, theta_dot_deg].

    `trail`: positions sailed so far, drawn as the wake. `target`: a subtask's
    goal disc. `marks`: positions drawn as dots (the root's decisions). `gate`: the
    gate's two posts, rows (x, y), where the goal task drew it (SPEC section 2's
    when None). `course`: the regatta's gates' posts, (gates, 2, 2), `next_gate` the
    one to pass next (a scene of assets/ship_regatta.xml). `obstacles`: the harbour's
    level whose obstacles show (a scene of assets/ship_harbour.xml).
    """
    return self._worker.render(
        state=np.asarray(state, dtype=np.float64),
        trail=np.asarray(trail, dtype=np.float64).reshape(-1, 2),
        target=None if target is None else np.asarray(target, dtype=np.float64),
        camera=camera, marks=np.asarray(marks, dtype=np.float64).reshape(-1, 2),
        gate=None if gate is None else np.asarray(gate, dtype=np.float64),
        course=None if course is None else np.asarray(course, dtype=np.float64),
        next_gate=int(next_gate), obstacles=obstacles)

  def close(self):
    """Stops its render worker."""
    self._worker.close()
