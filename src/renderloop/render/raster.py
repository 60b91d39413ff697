"""The raster backend: MuJoCo's OpenGL renderer on the same meshes and poses as Cycles.

Milliseconds per frame instead of seconds, for tests and previews: the paper's
"Gazebo quality" next to Cycles. The render world is its own MJCF, built from the
object list Cycles draws (`scene/objects.py`): every plant part as a mesh, the static
parts as boxes and cylinders, each in the flat display colour of the material table
(`scene/materials.py`), each pepper its own geom so that the segmentation render
gives its instance id, and a mocap camera that is moved to each pose. Headless
through EGL (renderloop sets MUJOCO_GL=egl on import).
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
from renderloop.scene.model import Scene
from renderloop.scene.objects import SceneObject, greenhouse_objects
from renderloop.scene.world import shape_geom

CAMERA = "render_camera"
GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)  # an int: numpy compares an array with the enum object in Python, pixel by pixel


def _mesh_asset(asset: ET.Element, name: str, mesh) -> None:
    ET.SubElement(asset, "mesh", name=name, inertia="shell", vertex=" ".join(f"{v:.6f}" for v in mesh.vertices.ravel()),
                  face=" ".join(map(str, mesh.faces.ravel())))


def _geom_names(obj: SceneObject) -> list[str]:
    """The names of the geoms `_add_object` makes of `obj`: a shape's own, one per copy of a rigid template, or the
    object's."""
    if obj.shapes:
        return [shape.name for shape in obj.shapes]
    if obj.instances is not None and obj.instances.rigid:
        return [f"{obj.name}_{k}" for k in range(len(obj.instances.template))]
    return [obj.name]


def _add_object(asset: ET.Element, world: ET.Element, obj: SceneObject) -> None:
    """One object of the list as geoms, in its flat display colour: a mesh (or copies of templates, merged)
    as a mesh geom named like the object, primitive shapes as one geom each. Copies that are their template
    only turned and moved (the neighbouring plants) share the template's mesh, one geom a copy at its pose."""
    rgba = fmt(*obj.display_rgba())
    if obj.shapes:
        for shape in obj.shapes:
            shape_geom(world, shape, rgba=rgba)
        return
    if obj.instances is not None and obj.instances.rigid:
        copies = obj.instances
        for index, template in enumerate(copies.templates):
            _mesh_asset(asset, f"{obj.name}_t{index}", template)
        for name, index, transform in zip(_geom_names(obj), copies.template, copies.transforms):
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, np.ascontiguousarray(transform[:3, :3]).ravel())
            ET.SubElement(world, "geom", name=name, type="mesh", mesh=f"{obj.name}_t{int(index)}",
                          pos=fmt(*transform[:3, 3]), quat=fmt(*quat), rgba=rgba)
        return
    mesh = obj.triangles()
    if len(mesh.faces) == 0:
        return
    _mesh_asset(asset, obj.name, mesh)
    ET.SubElement(world, "geom", name=obj.name, type="mesh", mesh=obj.name, rgba=rgba)


def render_world_xml(objects: list[SceneObject], config: Config, intrinsics: Intrinsics) -> str:
    root = ET.Element("mujoco", model="renderloop_render")
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    near, far = config.camera.clip
    ET.SubElement(root, "statistic", extent="1", center="0 0 0")  # so that znear and zfar are in metres
    visual = ET.SubElement(root, "visual")
    ET.SubElement(visual, "global", offwidth=str(intrinsics.width), offheight=str(intrinsics.height))
    ET.SubElement(visual, "map", znear=repr(near), zfar=repr(far))
    look = config.renderer.raster
    ET.SubElement(visual, "quality", shadowsize="2048", offsamples=str(look.antialias))
    ET.SubElement(visual, "headlight", ambient="0.3 0.3 0.3", diffuse="0.4 0.4 0.4", specular="0.1 0.1 0.1")
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", contype="0", conaffinity="0")
    asset = ET.SubElement(root, "asset")
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "light", name="sun", directional="true", pos="0 0 5", dir="0.3 0.4 -1", diffuse="0.6 0.6 0.6",
                  castshadow=str(look.shadows).lower())
    for obj in objects:
        _add_object(asset, world, obj)
    rig = ET.SubElement(world, "body", name="camera_rig", mocap="true")
    ET.SubElement(rig, "camera", name=CAMERA, fovy=repr(intrinsics.fovy_deg))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode")


class RasterRenderer:
    """One MuJoCo render world and OpenGL context; render() moves the camera and draws two passes: the colour, then
    the geom ids, whose depth buffer is the depth (MuJoCo's own depth render is that same id pass read for depth,
    so reading both from one pass saves a third render and read-back: 10 ms of a 640x480 frame)."""

    MAX_GEOMS = 10_000  # mujoco.Renderer's default

    def __init__(self, scene: Scene, config: Config, intrinsics: Intrinsics):
        objects = greenhouse_objects(scene)
        model = self.model = mujoco.MjModel.from_xml_string(render_world_xml(objects, config, intrinsics))
        self.data = mujoco.MjData(model)
        self.near, self.far = config.camera.clip
        self.width, self.height = intrinsics.width, intrinsics.height
        self.gl = mujoco.GLContext(model.vis.global_.offwidth, model.vis.global_.offheight)
        self.gl.make_current()
        self.context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self.context)
        self.context.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR  # reversed z: far is 0, more precision far away
        self.scene = mujoco.MjvScene(model, maxgeom=self.MAX_GEOMS)
        self.option, self.perturb, self.camera = mujoco.MjvOption(), mujoco.MjvPerturb(), mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self.camera.fixedcamid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA)
        self.rect = mujoco.MjrRect(0, 0, self.width, self.height)
        extent = model.stat.extent  # the clip planes of the GL projection, float32 as glFrustum has them
        self.gl_near, self.gl_far = np.float32(model.vis.map.znear * extent), np.float32(model.vis.map.zfar * extent)
        self.pepper_of_geom = np.zeros(model.ngeom + 1, dtype=np.uint16)  # index -1 (background) lands on the extra 0
        for obj in filter(lambda obj: obj.pass_index, objects):
            for name in _geom_names(obj):
                geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
                if geom >= 0:  # -1: an empty mesh, not drawn
                    self.pepper_of_geom[geom] = obj.pass_index

    def _metric_depth(self, z: np.ndarray) -> np.ndarray:
        """Reversed-z depth buffer values to metres along the optical axis: the inverse of the perspective
        projection, in float64 as mujoco.Renderer computes it (so the depth is the same to the bit)."""
        near, far = self.gl_near, self.gl_far
        c = np.float32(-0.5) * (-(far + near) / (far - near)) - np.float32(0.5)
        d = np.float32(-0.5) * (-(np.float32(2) * far * near) / (far - near))
        return (d / (z.astype(np.float64) + c)).astype(np.float32)

    def render(self, pose: np.ndarray) -> RenderedFrame:
        start = time.perf_counter()
        camera = to_gl_camera(pose)
        self.data.mocap_pos[0] = camera[:3, 3]
        mujoco.mju_mat2Quat(self.data.mocap_quat[0], camera[:3, :3].ravel())
        mujoco.mj_forward(self.model, self.data)
        self.gl.make_current()
        scene, flags = self.scene, self.scene.flags
        mujoco.mjv_updateScene(self.model, self.data, self.option, self.perturb, self.camera, mujoco.mjtCatBit.mjCAT_ALL, scene)
        rgb = np.empty((self.height, self.width, 3), dtype=np.uint8)
        mujoco.mjr_render(self.rect, scene, self.context)
        mujoco.mjr_readPixels(rgb, None, self.rect, self.context)
        ids = np.empty((self.height, self.width, 3), dtype=np.uint8)
        z = np.empty((self.height, self.width), dtype=np.float32)
        saved = flags.copy()
        flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = True
        try:
            mujoco.mjr_render(self.rect, scene, self.context)
            mujoco.mjr_readPixels(ids, z, self.rect, self.context)
        finally:
            np.copyto(flags, saved)
        # GL's rows run bottom to top
        rgb, ids, depth = np.flipud(rgb).copy(), np.flipud(ids), np.flipud(self._metric_depth(z))
        depth[(depth < self.near) | (depth >= self.far * 0.9999)] = 0.0
        segment = ids[:, :, 0].astype(np.int32) + (ids[:, :, 1].astype(np.int32) << 8) + (ids[:, :, 2].astype(np.int32) << 16)
        geom_of_segment = np.full(scene.ngeom + 1, -1, dtype=np.int32)  # segment 0 is the background
        for k in range(scene.ngeom):
            drawn = scene.geoms[k]
            if drawn.segid != -1 and drawn.objtype == GEOM:
                geom_of_segment[drawn.segid + 1] = drawn.objid
        mask = self.pepper_of_geom[geom_of_segment[segment]]
        return RenderedFrame(rgb=rgb, depth=np.ascontiguousarray(depth), mask=mask, timings={"total": time.perf_counter() - start})

    def close(self) -> None:
        self.context.free()
        self.gl.free()

    def __enter__(self) -> RasterRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
