"""Offscreen pictures of the worlds, drawn by MuJoCo from the MJCF models.

Headless: `MUJOCO_GL=osmesa` without a GPU (`apt-get install libosmesa6`), `egl`
with one; `import hpg_mj` picks one when MUJOCO_GL is unset.
"""
import mujoco
import numpy as np

from hpg_mj.worlds import ship

_WAKE_RGBA = np.array([1.0, 1.0, 1.0, 0.85], dtype=np.float32)
_MARK_RGBA = np.array([1.0, 0.35, 0.1, 1.0], dtype=np.float32)
_MAX_WAKE_SEGMENTS = 1500


def _pixel_size(model, camera_id, height):
  """Metres per pixel at the sea for an orthographic camera, else a fixed guess."""
  if camera_id >= 0 and model.cam_projection[camera_id] == mujoco.mjtProjection.mjPROJ_ORTHOGRAPHIC:
    return float(model.cam_fovy[camera_id]) / height
  return 1.0


def add_polyline(scene, points_xy, width, rgba, z=1.0):
  """Draws a polyline on the sea as capsules appended to `scene` (a wake, a path)."""
  points = np.asarray(points_xy, dtype=np.float64)
  if len(points) < 2:
    return
  stride = max(1, int(np.ceil((len(points) - 1) / _MAX_WAKE_SEGMENTS)))
  points = np.concatenate([points[::stride], points[-1:]])
  room = scene.maxgeom - scene.ngeom
  for a, b in zip(points[:-1], points[1:]):
    if room <= 0:
      break
    if a[0] == b[0] and a[1] == b[1]:
      continue
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3),
                        np.eye(3).ravel(), rgba)
    mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_CAPSULE, width,
                         np.array([a[0], a[1], z]), np.array([b[0], b[1], z]))
    scene.ngeom += 1
    room -= 1


def add_markers(scene, points_xy, radius, rgba, z=2.0):
  """Draws discs at `points_xy` (for example where the root made a decision)."""
  for x, y in np.asarray(points_xy, dtype=np.float64).reshape(-1, 2):
    if scene.ngeom >= scene.maxgeom:
      break
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_SPHERE, np.array([radius, radius, radius]),
                        np.array([x, y, z]), np.eye(3).ravel(), rgba)
    scene.ngeom += 1


class ShipScene:
  """Renders ship states: the field, the gate, the bounds, the ship and its wake."""

  def __init__(self, width=640, height=480):
    self.physics = ship.Physics.from_xml_string(*ship.get_model_and_assets())
    self.width, self.height = int(width), int(height)
    self._renderer = mujoco.Renderer(self.physics.model.ptr, self.height, self.width,
                                     max_geom=4000)

  def render(self, state, trail=(), target=None, camera="top", marks=()):
    """An RGB frame (height, width, 3) of the ship at `state` [x, y, theta_deg, theta_dot_deg].

    `trail`: positions sailed so far, drawn as the wake. `target`: a subtask's
    goal disc. `marks`: positions drawn as dots (the root's decisions).
    """
    model = self.physics.model.ptr
    camera_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
    if camera_id < 0:
      cameras = [model.camera(i).name for i in range(model.ncam)]
      raise ValueError(f"unknown camera {camera!r}; the ship model has {cameras}")
    self.physics.set_ship_state(state)
    self.physics.place_target(target)
    mujoco.mj_forward(model, self.physics.data.ptr)
    self._renderer.update_scene(self.physics.data.ptr, camera=camera_id)
    pixel = _pixel_size(model, camera_id, self.height)
    add_polyline(self._renderer.scene, trail, width=min(5.0, max(0.2, 0.8 * pixel)),
                 rgba=_WAKE_RGBA)
    add_markers(self._renderer.scene, marks, radius=max(1.0, 3.0 * pixel), rgba=_MARK_RGBA)
    return self._renderer.render().copy()

  def close(self):
    self._renderer.close()
