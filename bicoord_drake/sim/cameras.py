"""The three cameras: a fixed head camera and one camera on each wrist.

Camera frames follow Drake's (and OpenCV's) convention: +z forward, +x right, +y down, so the
exported extrinsics are directly OpenCV's world->camera ``[R | t]``.

Two render engines draw the same scene (:func:`make_render_engine`), chosen by the camera
setting ``renderer`` (``"vtk"`` when the setting is absent):

- ``"vtk"``: Drake's ``RenderEngineVtk`` over EGL, headless with no display; shadows optional.
- ``"gl"``: Drake's ``RenderEngineGl``, 0.55-0.7x VTK's CPU per frame on Mesa's software
  rasterizer (no FXAA pass, simpler shaders), but it needs an X display
  (:mod:`bicoord_drake.sim.gl_display` starts a private Xvfb when there is none) and has no
  shadows. Same cameras, lights, colours and textures; the images differ from VTK's only along
  edges, which VTK smooths (benchmarks/bench_render.md).

Both kinds in one process: GL's GLX context cannot be made current on a thread that has had
VTK's EGL context (libglvnd refuses: a fatal X error), so GL after a VTK engine over EGL is
refused with an error; VTK after GL draws over GLX on GL's display instead, the same pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.all import (
    CameraInfo,
    ClippingRange,
    ColorRenderCamera,
    DepthRange,
    DepthRenderCamera,
    DiagramBuilder,
    LightParameter,
    MakeRenderEngineGl,
    MakeRenderEngineVtk,
    MultibodyPlant,
    RenderCameraCore,
    RenderEngine,
    RenderEngineGlParams,
    RenderEngineVtkParams,
    Rgba,
    RgbdSensor,
    RigidTransform,
    RotationMatrix,
    SceneGraph,
)

from bicoord_drake.config import CameraConfig
from bicoord_drake.models.appearance import Appearance
from bicoord_drake.models.embodiment import Embodiment

#: The render engine kinds, and the name each is registered under in the scene graph.
RENDERERS = {"vtk": "bicoord_vtk", "gl": "bicoord_gl"}
#: The background where no geometry is (both engines).
CLEAR_COLOR = (0.92, 0.93, 0.95)
#: The OpenGL platforms this process's engines have used so far ("egl": VTK's default, "glx").
_platforms: set[str] = set()

#: Head camera: above and behind the robot, looking down at the table centre (1.075 m away;
#: 1 m until the ViperX's home was widened to the reference's 0.606 m start distance, when its
#: left fingers came within 7 px of the image's edge) from x = 0. With the default 42 deg
#: vertical FOV (`CameraConfig.head_fov_y_deg`; 54 deg
#: horizontal at 320x240, like RoboTwin's D435 head camera) both grippers at home and every task
#: object are in the image (tests/sim/test_head_camera_view.py checks it by projection).
HEAD_EYE = (0.0, -0.645, 1.61)
HEAD_DIRECTION = (0.0, 0.6, -0.8)
#: Wrist camera mount in the gripper link frame (x forward along the fingers, z up at home):
#: above the palm, looking past the fingertips at the workspace ahead.
WRIST_EYE = (-0.02, 0.0, 0.085)
WRIST_TARGET = (0.28, 0.0, -0.05)


@dataclass(frozen=True)
class CameraMount:
    """Where a camera sits: a parent body (None = world) and the camera pose in it."""

    name: str
    body_name: str | None
    side: str | None
    X_PC: RigidTransform
    fov_y_deg: float


def look_at(eye, target, up=(0.0, 0.0, 1.0)) -> RigidTransform:
    """Camera pose (Drake/OpenCV axes) at `eye` looking at `target`, image-up toward `up`."""
    eye, target, up = (np.asarray(v, float) for v in (eye, target, up))
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        raise ValueError("camera 'up' is parallel to the viewing direction")
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return RigidTransform(RotationMatrix(np.column_stack([x, y, z])), eye)


def camera_mounts(
    embodiment: Embodiment, config: CameraConfig, appearance: Appearance | None = None
) -> list[CameraMount]:
    """The mounts of the configured cameras (the head camera jittered by `appearance` and
    lowered by its `table_raise`: the camera stands on the floor, the world frame on the table)."""
    eye, direction = np.array(HEAD_EYE), np.array(HEAD_DIRECTION)
    if appearance is not None:
        eye = eye + appearance.head_camera_offset
        eye[2] -= appearance.table_raise  # fixed to the floor, which a higher table lowers
        pitch, yaw = appearance.head_camera_tilt
        direction = (
            RotationMatrix.MakeZRotation(yaw) @ RotationMatrix.MakeXRotation(pitch) @ direction
        )
    head = look_at(eye, eye + direction)
    wrist = look_at(WRIST_EYE, WRIST_TARGET)
    gripper = embodiment.arm.gripper_link.name
    all_mounts = {
        "head_camera": CameraMount("head_camera", None, None, head, config.head_fov_y_deg),
        "left_camera": CameraMount("left_camera", gripper, "left", wrist, config.wrist_fov_y_deg),
        "right_camera": CameraMount(
            "right_camera", gripper, "right", wrist, config.wrist_fov_y_deg
        ),
    }
    return [all_mounts[name] for name in config.names]


def intrinsics(config: CameraConfig, fov_y_deg: float) -> CameraInfo:
    return CameraInfo(width=config.width, height=config.height, fov_y=np.deg2rad(fov_y_deg))


def intrinsic_matrix(info: CameraInfo) -> np.ndarray:
    """OpenCV 3x3 intrinsics K."""
    return np.array(
        [
            [info.focal_x(), 0.0, info.center_x()],
            [0.0, info.focal_y(), info.center_y()],
            [0.0, 0.0, 1.0],
        ]
    )


def extrinsic_matrix(X_WC: RigidTransform) -> np.ndarray:
    """OpenCV 3x4 world->camera extrinsics [R | t] from the camera pose in world."""
    return X_WC.inverse().GetAsMatrix34()


def renderer_kind(config: CameraConfig) -> str:
    """The render engine `config` asks for: its ``renderer`` ("vtk" without that setting)."""
    kind = getattr(config, "renderer", "vtk")
    if kind not in RENDERERS:
        raise ValueError(f"unknown renderer {kind!r}; renderers: {', '.join(RENDERERS)}")
    return kind


def make_render_engine(
    kind: str, config: CameraConfig, appearance: Appearance | None = None
) -> RenderEngine:
    """A render engine of `kind` ("vtk" or "gl") with the appearance's lights (else the
    engine's default light at the camera) and the common background; VTK casts shadows if
    `config.shadows`. GL first makes sure there is an X display (:mod:`gl_display`)."""
    lights = [
        LightParameter(
            type="directional",
            frame="world",
            direction=light.direction,
            color=Rgba(*light.color, 1.0),
            intensity=light.intensity,
        )
        for light in (appearance.lights if appearance is not None else ())
    ]
    if kind == "vtk":
        params = RenderEngineVtkParams(default_clear_color=list(CLEAR_COLOR))
        params.cast_shadows = config.shadows
        params.shadow_map_size = 1024
        if lights:
            params.lights = lights
        if "glx" in _platforms:  # after a GL engine: share its GLX (EGL would now be refused)
            params.backend = "GLX"
        else:
            _platforms.add("egl")
        return MakeRenderEngineVtk(params)
    if kind == "gl":
        if config.shadows:
            raise ValueError("the GL renderer casts no shadows: use renderer 'vtk' for shadows")
        if "egl" in _platforms:
            raise RuntimeError(
                "the GL renderer cannot follow a VTK renderer in the same process (its GLX "
                "context cannot be made current where VTK's EGL context was): use one renderer "
                "kind per process, or make the GL engine first"
            )
        from bicoord_drake.sim.gl_display import ensure_x_display

        ensure_x_display()
        _platforms.add("glx")
        params = RenderEngineGlParams()
        params.default_clear_color = Rgba(*CLEAR_COLOR, 1.0)
        if lights:
            params.lights = lights
        return MakeRenderEngineGl(params)
    raise ValueError(f"unknown renderer {kind!r}; renderers: {', '.join(RENDERERS)}")


def add_cameras(
    builder: DiagramBuilder,
    plant: MultibodyPlant,
    scene_graph: SceneGraph,
    embodiment: Embodiment,
    arms: dict,
    config: CameraConfig,
    appearance: Appearance | None = None,
) -> dict[str, tuple[RgbdSensor, CameraMount]]:
    """Register the configured render engine (:func:`make_render_engine`) and add one
    RgbdSensor per configured camera."""
    kind = renderer_kind(config)
    renderer = RENDERERS[kind]
    if not scene_graph.HasRenderer(renderer):
        scene_graph.AddRenderer(renderer, make_render_engine(kind, config, appearance))
    sensors = {}
    lo, hi = config.depth_range
    for mount in camera_mounts(embodiment, config, appearance):
        info = intrinsics(config, mount.fov_y_deg)
        core = RenderCameraCore(renderer, info, ClippingRange(0.01, 10.0), RigidTransform())
        color = ColorRenderCamera(core, show_window=False)
        depth = DepthRenderCamera(core, DepthRange(lo, hi))
        if mount.body_name is None:
            parent = scene_graph.world_frame_id()
        else:
            body = plant.GetBodyByName(mount.body_name, arms[mount.side])
            parent = plant.GetBodyFrameIdOrThrow(body.index())
        sensor = builder.AddNamedSystem(mount.name, RgbdSensor(parent, mount.X_PC, color, depth))
        builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
        sensors[mount.name] = (sensor, mount)
    return sensors
