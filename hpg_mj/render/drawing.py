"""The pictures themselves, drawn by MuJoCo in the render worker.

Only `hpg_mj._render_worker` imports this module, in its own process, after it
has chosen its OpenGL backend (SPEC section 9); the user's process uses the
proxies of `hpg_mj.render.scenes` and the worlds' `Physics.render`.
"""
import mujoco
import numpy as np

from hpg_mj import _assets

_WAKE_RGBA = np.array([1.0, 1.0, 1.0, 0.85], dtype=np.float32)
_MARK_RGBA = np.array([1.0, 0.35, 0.1, 1.0], dtype=np.float32)
_MAX_WAKE_SEGMENTS = 1500


def _scene_option():
  """MuJoCo's default visual options less its rangefinder rays: a frame shows the world,
  not the harbour's sensors (drawn to whatever they hit, past the 150 m they read)."""
  option = mujoco.MjvOption()
  option.flags[mujoco.mjtVisFlag.mjVIS_RANGEFINDER] = False
  return option


SCENE_OPTION = _scene_option()


def _pixel_size(model, camera_id, height):
  """Metres per pixel at the sea for an orthographic camera, else a fixed guess."""
  if camera_id >= 0 and model.cam_projection[camera_id] == mujoco.mjtProjection.mjPROJ_ORTHOGRAPHIC:
    return float(model.cam_fovy[camera_id]) / height
  return 1.0


def add_polyline(scene, points_xy, width_px, rgba, z=1.0):
  """Draws a polyline on the sea as GL lines `width_px` pixels wide, appended to `scene`
  (a wake, a path). Lines, not capsules: a capsule costs ~0.5 ms of llvmpipe per
  frame, so a 400-sample wake made a 320 x 240 frame 7 times slower; lines are free."""
  points = np.asarray(points_xy, dtype=np.float64)
  if len(points) < 2:
    return
  stride = max(1, int(np.ceil((len(points) - 1) / _MAX_WAKE_SEGMENTS)))
  points = np.concatenate([points[::stride], points[-1:]])
  room = scene.maxgeom - scene.ngeom
  line = mujoco.mjtGeom.mjGEOM_LINE
  for a, b in zip(points[:-1], points[1:]):
    if room <= 0:
      break
    if a[0] == b[0] and a[1] == b[1]:
      continue
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(geom, line, np.zeros(3), np.zeros(3), np.eye(3).ravel(), rgba)
    mujoco.mjv_connector(geom, line, width_px, np.array([a[0], a[1], z]),
                         np.array([b[0], b[1], z]))
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


def _camera_id(model, camera, what):
  if isinstance(camera, (int, np.integer)):
    if not -1 <= camera < model.ncam:
      raise ValueError(f"camera index {camera} is out of range for {what}: "
                       f"-1 (free camera) to {model.ncam - 1}")
    return int(camera)
  camera_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
  if camera_id < 0:
    cameras = [model.camera(i).name for i in range(model.ncam)]
    raise ValueError(f"unknown camera {camera!r}; {what} has {cameras}")
  return camera_id


class ShipDrawing:
  """The field, the gate, the bounds, the ship at a state and its wake; on the model
  `model` of assets/ (the regatta's draws its course too, the harbour a level's
  obstacles)."""

  def __init__(self, width=640, height=480, model="ship.xml"):
    from hpg_mj.worlds import ship_model
    self.physics = ship_model.ShipPhysics.from_xml_string(_assets.read_model(model),
                                                          _assets.included_assets(model))
    self.width, self.height = int(width), int(height)
    self._renderer = mujoco.Renderer(self.physics.model.ptr, self.height, self.width,
                                     max_geom=4000)

  def render_first(self):
    """Draws one frame and throws it away (the first frame's set-up, paid early)."""
    self.render(state=np.array([500.0, 500.0, 0.0, 0.0]))

  def render(self, state, trail=(), target=None, camera="top", marks=(), gate=None,
             course=None, next_gate=0, obstacles=None):
    """The ship at `state` with its wake `trail` (x, y rows, m) and `marks`, its
    target, gate, course or obstacles placed: an RGB frame (height, width, 3), uint8."""
    model = self.physics.model.ptr
    camera_id = _camera_id(model, camera, "the ship model")
    self.physics.set_ship_state(state)
    self.physics.place_target(target)
    self.physics.place_gate(gate)
    if course is not None:
      self.physics.place_course(course, next_gate)
    if obstacles is not None:           # the harbour's level: its obstacles, no other's
      from hpg_mj.worlds import ship_model
      ship_model.place_harbour_obstacles(model, obstacles)
    mujoco.mj_forward(model, self.physics.data.ptr)
    self._renderer.update_scene(self.physics.data.ptr, camera=camera_id,
                                scene_option=SCENE_OPTION)
    pixel = _pixel_size(model, camera_id, self.height)
    add_polyline(self._renderer.scene, trail, width_px=max(1.0, self.height / 160.0),
                 rgba=_WAKE_RGBA)
    add_markers(self._renderer.scene, marks, radius=max(1.0, 3.0 * pixel), rgba=_MARK_RGBA)
    return self._renderer.render().copy()

  def close(self):
    """Frees its renderer."""
    self._renderer.close()


class PhysicsDrawing:
  """A MuJoCo model drawn at the state arrays sent by a `Physics.render` call."""

  def __init__(self, model_name):
    self.model_name = model_name
    self.model = _assets.load_model(model_name)
    self.data = mujoco.MjData(self.model)
    self._renderers = {}   # (height, width) -> mujoco.Renderer

  def render_first(self):
    """Draws one small frame and throws it away (the first frame's set-up, paid
    early)."""
    self.render(height=16, width=16)

  def render(self, height, width, camera_id=-1, model_fields=None, data_fields=None):
    """The model at the state arrays sent (`model_fields`, `data_fields`: name ->
    array), seen from `camera_id`: an RGB frame (height, width, 3), uint8."""
    buffer = (self.model.vis.global_.offwidth, self.model.vis.global_.offheight)
    if not (1 <= width <= buffer[0] and 1 <= height <= buffer[1]):
      raise ValueError(f"{self.model_name}: a frame of {width} x {height} pixels does not fit "
                       f"the model's offscreen buffer of {buffer[0]} x {buffer[1]}")
    for name, value in (model_fields or {}).items():
      getattr(self.model, name)[...] = value
    for name, value in (data_fields or {}).items():
      getattr(self.data, name)[...] = value
    mujoco.mj_forward(self.model, self.data)
    key = (int(height), int(width))
    if key not in self._renderers:
      self._renderers[key] = mujoco.Renderer(self.model, *key)
    renderer = self._renderers[key]
    renderer.update_scene(self.data, camera=_camera_id(self.model, camera_id, self.model_name),
                          scene_option=SCENE_OPTION)
    return renderer.render().copy()

  def close(self):
    """Frees its renderers."""
    for renderer in self._renderers.values():
      renderer.close()
