"""The raster backend: MuJoCo's OpenGL renderer on the same meshes and poses as Cycles.

Milliseconds per frame instead of seconds, for tests and previews: the paper's
"Gazebo quality" next to Cycles. The render world is its own MJCF, built from
scene.json: every plant part as a mesh (the meshes Cycles draws), each pepper its own
geom so that the segmentation render gives its instance id, and a mocap camera that
is moved to each pose. Headless through EGL (renderloop sets MUJOCO_GL=egl on import).
"""

from __future__ import annotations

import time
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from renderloop.config import Config
from renderloop.render.camera import Intrinsics, to_gl_camera
from renderloop.render.frame import RenderedFrame
from renderloop.robot.mjcf import fmt
from renderloop.scene.meshes import Mesh, merge
from renderloop.scene.model import Scene
from renderloop.scene.plant_meshes import plant_meshes
from renderloop.scene.world import MATERIALS, WORKSTATION_COLUMN, table_boxes, wall_boxes

CAMERA = "render_camera"
PEPPER_PREFIX = "pepper_"


def _rgba(rgb, alpha: float = 1.0) -> str:
    return fmt(*rgb, alpha)


def _mesh_asset(asset: ET.Element, name: str, mesh: Mesh) -> None:
    ET.SubElement(asset, "mesh", name=name, inertia="shell",
                  vertex=" ".join(f"{v:.6f}" for v in mesh.vertices.ravel()), face=" ".join(map(str, mesh.faces.ravel())))


def _box(parent: ET.Element, name: str, center, half, rgba: str) -> None:
    ET.SubElement(parent, "geom", name=name, type="box", pos=fmt(*center), size=fmt(*half), rgba=rgba)


def render_world_xml(scene: Scene, config: Config, intrinsics: Intrinsics) -> str:
    root = ET.Element("mujoco", model="renderloop_render")
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    near, far = config.camera.clip
    ET.SubElement(root, "statistic", extent="1", center="0 0 0")  # so that znear and zfar are in metres
    visual = ET.SubElement(root, "visual")
    ET.SubElement(visual, "global", offwidth=str(intrinsics.width), offheight=str(intrinsics.height))
    ET.SubElement(visual, "map", znear=repr(near), zfar=repr(far))
    ET.SubElement(visual, "quality", shadowsize="2048")
    ET.SubElement(visual, "headlight", ambient="0.3 0.3 0.3", diffuse="0.4 0.4 0.4", specular="0.1 0.1 0.1")
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", contype="0", conaffinity="0")
    asset = ET.SubElement(root, "asset")
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "light", name="sun", directional="true", pos="0 0 5", dir="0.3 0.4 -1", diffuse="0.6 0.6 0.6", castshadow="true")

    length, width, _ = scene.room
    _box(world, "floor", (0, 0, -0.05), (length / 2, width / 2, 0.05), MATERIALS["floor"])
    for name, center, half in wall_boxes(scene.room):
        _box(world, name, center, half, MATERIALS["wall"])
    station = scene.workstation
    tables = [(f"table_{row.id}", row.table, MATERIALS["table"]) for row in scene.rows]
    for name, table, rgba in tables + [("workstation", station, MATERIALS["workstation"])]:
        for box_name, center, half in table_boxes(name, table.center, table.size):
            _box(world, box_name, center, half, rgba)
    height, radius = WORKSTATION_COLUMN
    top = station.size[2]
    ET.SubElement(world, "geom", name="workstation_arm", type="capsule", size=repr(radius), rgba=MATERIALS["workstation"],
                  fromto=fmt(station.center[0], station.center[1], top, station.center[0], station.center[1], top + height))

    for plant in scene.plants:
        peppers = scene.peppers_of(plant.id)
        parts = plant_meshes(plant, peppers)
        leaf_rgb = np.mean([leaf.rgb for leaf in plant.leaves], axis=0) if plant.leaves else (0.1, 0.3, 0.06)
        pieces = [("pot", parts.pot, MATERIALS["pot"]), ("stem", parts.stem, _rgba((0.2, 0.4, 0.1)))]
        if parts.leaves:
            pieces.append(("leaves", merge(parts.leaves), _rgba(leaf_rgb)))
        if parts.flowers is not None:
            pieces.append(("flowers", parts.flowers, _rgba((0.95, 0.95, 0.85))))
        for part, mesh, rgba in pieces:
            name = f"plant{plant.id}_{part}"
            _mesh_asset(asset, name, mesh)
            ET.SubElement(world, "geom", name=name, type="mesh", mesh=name, rgba=rgba)
        for pepper in peppers:
            name = f"{PEPPER_PREFIX}{pepper.id}"
            _mesh_asset(asset, name, parts.peppers[pepper.id])
            ET.SubElement(world, "geom", name=name, type="mesh", mesh=name, rgba=_rgba(pepper.rgb))

    rig = ET.SubElement(world, "body", name="camera_rig", mocap="true")
    ET.SubElement(rig, "camera", name=CAMERA, fovy=repr(intrinsics.fovy_deg))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode")


class RasterRenderer:
    """One MuJoCo render world and OpenGL context; render() moves the camera and draws three passes."""

    def __init__(self, scene: Scene, config: Config, intrinsics: Intrinsics):
        self.model = mujoco.MjModel.from_xml_string(render_world_xml(scene, config, intrinsics))
        self.data = mujoco.MjData(self.model)
        self.near, self.far = config.camera.clip
        self.renderer = mujoco.Renderer(self.model, intrinsics.height, intrinsics.width)
        self.pepper_of_geom = np.zeros(self.model.ngeom + 1, dtype=np.uint16)  # index -1 (background) lands on the extra 0
        for geom in range(self.model.ngeom):
            name = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, geom) or ""
            if name.startswith(PEPPER_PREFIX):
                self.pepper_of_geom[geom] = int(name.removeprefix(PEPPER_PREFIX))

    def render(self, pose: np.ndarray) -> RenderedFrame:
        start = time.perf_counter()
        camera = to_gl_camera(pose)
        self.data.mocap_pos[0] = camera[:3, 3]
        mujoco.mju_mat2Quat(self.data.mocap_quat[0], camera[:3, :3].ravel())
        mujoco.mj_forward(self.model, self.data)
        renderer = self.renderer
        renderer.update_scene(self.data, camera=CAMERA)
        rgb = renderer.render().copy()
        renderer.enable_depth_rendering()
        depth = renderer.render().astype(np.float32)
        renderer.disable_depth_rendering()
        renderer.enable_segmentation_rendering()
        segmentation = renderer.render()
        renderer.disable_segmentation_rendering()
        depth[(depth < self.near) | (depth >= self.far * 0.9999)] = 0.0
        geoms = np.where(segmentation[:, :, 1] == mujoco.mjtObj.mjOBJ_GEOM, segmentation[:, :, 0], -1)
        mask = self.pepper_of_geom[geoms]
        return RenderedFrame(rgb=rgb, depth=depth, mask=mask, timings={"total": time.perf_counter() - start})

    def close(self) -> None:
        self.renderer.close()

    def __enter__(self) -> RasterRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
