"""The raster backend: MuJoCo's OpenGL renderer on the same meshes and poses as Cycles.

Milliseconds per frame instead of seconds, for tests and previews: the paper's
"Gazebo quality" next to Cycles. The render world is its own MJCF, built from the
object list Cycles draws (`scene/objects.py`): every plant part as a mesh, the static
parts as boxes and cylinders, each in the flat display colour of the material table
(`scene/materials.py`), each pepper its own geom so that the segmentation render
gives its instance id, and a mocap camera that is moved to each pose. Headless
through EGL (renderloop sets MUJOCO_GL=egl on import).

Where no geometry lies in the clip range, Cycles shows its world (the sky, or the film greenhouse's glow) and
OpenGL leaves its black clear colour: the raster view paints Cycles' world colour there (`render/sky.py`),
composited by each pixel's coverage (the colour buffer's alpha, 0 where only the clear colour is, the share of
covered samples on an antialiased edge), so silhouettes against the sky blend with it as Cycles' do. Depth
and mask come from the id pass and stay as they are: 0 there.
"""

from __future__ import annotations

import dataclasses
import time
import xml.etree.ElementTree as ET

import mujoco
import numpy as np

from renderloop.config import Config
from renderloop.render.camera import Intrinsics, to_gl_camera
from renderloop.render.frame import RenderedFrame
from renderloop.render.sky import Sky, scene_sky
from renderloop.robot.mjcf import fmt
from renderloop.scene.model import Scene
from renderloop.scene.objects import SceneObject, greenhouse_objects
from renderloop.scene.visible import farthest_seen, visible_scene
from renderloop.scene.world import shape_geom

CAMERA, CAMERA_RIG, SUN_RIG = "render_camera", "camera_rig", "sun_rig"
SKY_BINS = 4096  # rows of the sky's table over a ray's world z in [-1, 1]: a fifth of an 8-bit level apart at most
HIDDEN = 5  # the geom group a frame does not draw: the geoms out of the camera's reach
SUN = (0.3, 0.4, -1.0)  # the direction the sun's light travels: dir of the world's light "sun"
SHADOW_MAP = 2048  # texels a side of the sun's shadow map
FLOOR_MARGIN = 0.2  # m: how far below the floor (z = 0) the sun's shadow map reaches
GEOM = int(mujoco.mjtObj.mjOBJ_GEOM)  # an int: numpy compares an array with the enum object in Python, pixel by pixel


def _mesh_asset(asset: ET.Element, files: dict[str, bytes], name: str, mesh) -> None:
    """A mesh asset read from MuJoCo's binary MSH format in memory (`files`, handed to the compiler with the MJCF):
    as text, the 6 million fruit vertices in reach of the middle row of five made a 200 MB MJCF, and that render world
    took 40 s to build against 24 s this way."""
    vertices, faces = np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.int32)
    header = np.array([len(vertices), 0, 0, len(faces)], np.int32)  # vertices, normals, texture coordinates, faces
    files[f"{name}.msh"] = header.tobytes() + vertices.tobytes() + faces.tobytes()
    ET.SubElement(asset, "mesh", name=name, inertia="shell", file=f"{name}.msh")


def _geom_names(obj: SceneObject) -> list[str]:
    """The names of the geoms `_add_object` makes of `obj`: a shape's own, one per copy of a rigid template, or the
    object's."""
    if obj.shapes:
        return [shape.name for shape in obj.shapes]
    if obj.instances is not None and obj.instances.rigid:
        return [f"{obj.name}_{k}" for k in range(len(obj.instances.template))]
    return [obj.name]


def _add_object(asset: ET.Element, files: dict[str, bytes], world: ET.Element, obj: SceneObject) -> None:
    """One object of the list as geoms, in its flat display colour: a mesh (or copies of templates, merged)
    as a mesh geom named like the object, primitive shapes as one geom each. Copies that are their template
    only turned and moved (the neighbouring plants) share the template's mesh, one geom a copy at its pose, each in
    its own colour."""
    rgba = fmt(*obj.display_rgba())
    if obj.shapes:
        for shape in obj.shapes:
            shape_geom(world, shape, rgba=rgba)
        return
    if obj.instances is not None and obj.instances.rigid:
        copies = obj.instances
        for index, template in enumerate(copies.templates):
            _mesh_asset(asset, files, f"{obj.name}_t{index}", template)
        # a copy in its own colour where the object has none (a neighbouring plant's leaves: its prototype's), so
        # that a copy looks the same whichever other copies a view builds (scene/visible.py)
        own = obj.rgb is None and obj.vertex_rgb is None
        colours = [fmt(*map(float, rgb), 1.0) for rgb in copies.rgb] if own else [rgba] * len(copies.template)
        for name, index, transform, colour in zip(_geom_names(obj), copies.template, copies.transforms, colours):
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, np.ascontiguousarray(transform[:3, :3]).ravel())
            ET.SubElement(world, "geom", name=name, type="mesh", mesh=f"{obj.name}_t{int(index)}",
                          pos=fmt(*transform[:3, 3]), quat=fmt(*quat), rgba=colour)
        return
    mesh = obj.triangles()
    if len(mesh.faces) == 0:
        return
    _mesh_asset(asset, files, obj.name, mesh)
    ET.SubElement(world, "geom", name=obj.name, type="mesh", mesh=obj.name, rgba=rgba)


def render_world_xml(objects: list[SceneObject], config: Config, intrinsics: Intrinsics) -> tuple[str, dict[str, bytes]]:
    """The render world's MJCF and the mesh files it names (MuJoCo's `assets`)."""
    root = ET.Element("mujoco", model="renderloop_render")
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    near, far = config.camera.clip
    ET.SubElement(root, "statistic", extent="1", center="0 0 0")  # so that znear and zfar are in metres
    visual = ET.SubElement(root, "visual")
    ET.SubElement(visual, "global", offwidth=str(intrinsics.width), offheight=str(intrinsics.height))
    # shadowclip: the half-width (m, as extent is 1) of the sun's shadow map about its axis (_sun_position)
    ET.SubElement(visual, "map", znear=repr(near), zfar=repr(far), shadowclip=repr(_shadow_reach(intrinsics, far)))
    look = config.renderer.raster
    ET.SubElement(visual, "quality", shadowsize=str(SHADOW_MAP), offsamples=str(look.antialias))
    ET.SubElement(visual, "headlight", ambient="0.3 0.3 0.3", diffuse="0.4 0.4 0.4", specular="0.1 0.1 0.1")
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", contype="0", conaffinity="0")
    asset = ET.SubElement(root, "asset")
    world = ET.SubElement(root, "worldbody")
    # the sun rides a body of its own that each frame moves to where its shadow map covers the camera's view
    sun = ET.SubElement(world, "body", name=SUN_RIG, mocap="true")
    ET.SubElement(sun, "light", name="sun", directional="true", pos="0 0 0", dir=" ".join(f"{v:g}" for v in SUN),
                  diffuse="0.6 0.6 0.6", castshadow=str(look.shadows).lower())
    files: dict[str, bytes] = {}
    for obj in objects:
        _add_object(asset, files, world, obj)
    rig = ET.SubElement(world, "body", name=CAMERA_RIG, mocap="true")
    ET.SubElement(rig, "camera", name=CAMERA, fovy=repr(intrinsics.fovy_deg))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode"), files


def _shadow_reach(intrinsics: Intrinsics, far: float) -> float:
    """The half-width (m) of the sun's shadow map about its axis (`_sun_position`), which passes through the point half
    the far clip ahead of the camera: wide enough to hold every point the frame can show, out to its far corners."""
    off_axis = np.sqrt(farthest_seen(far, **dataclasses.asdict(intrinsics)) ** 2 - far**2)  # a far corner's, m
    return float(np.hypot(far / 2, off_axis))


def _sun_position(pose: np.ndarray, far: float) -> np.ndarray:
    """Where the sun's light stands for the camera at `pose`: MuJoCo draws a directional light's shadow map from its
    position, over `_shadow_reach` either side of its axis and out to the far clip along its light. The axis
    goes through the point half the far clip ahead of the camera, and the box ends FLOOR_MARGIN under the floor, so
    that it holds the view and what stands above it up to the box's top."""
    sun = np.array(SUN) / np.linalg.norm(SUN)
    centre = pose[:3, 3] + pose[:3, 2] * far / 2
    to_floor = (-FLOOR_MARGIN - centre[2]) / sun[2]  # along the light from the centre to under the floor
    return centre + sun * (to_floor - far)


def _frustum_sides(intrinsics: Intrinsics) -> np.ndarray:
    """The unit inward normals (4, 3), in the optical frame, of the planes through the camera's centre and the outer
    edges of its frame's first and last pixel columns and rows: a point p is in view when p . n >= 0 for all four."""
    left, right = (-0.5 - intrinsics.cx) / intrinsics.fx, (intrinsics.width - 0.5 - intrinsics.cx) / intrinsics.fx
    top, bottom = (-0.5 - intrinsics.cy) / intrinsics.fy, (intrinsics.height - 0.5 - intrinsics.cy) / intrinsics.fy
    sides = np.array([[1.0, 0.0, -left], [-1.0, 0.0, right], [0.0, 1.0, -top], [0.0, -1.0, bottom]])
    return sides / np.linalg.norm(sides, axis=1, keepdims=True)


class RasterRenderer:
    """One MuJoCo render world and OpenGL context; render() moves the camera and draws two passes: the colour, then
    the geom ids, whose depth buffer is the depth (MuJoCo's own depth render is that same id pass read for depth,
    so reading both from one pass saves a third render and read-back: 10 ms of a 640x480 frame)."""

    DECOR_GEOMS = 100  # room in the drawn scene beyond the model's geoms, for what mjv_updateScene adds of its own

    def __init__(self, scene: Scene, config: Config, intrinsics: Intrinsics, viewpoints: np.ndarray | None = None):
        """The render world of `scene`; `viewpoints`, (N, 3) camera positions (m): of the plants only those the camera
        can see from one of them (scene/visible.py), None: every plant."""
        # PyOpenGL, which mujoco's GL contexts load: imported once MUJOCO_GL has chosen its platform
        from OpenGL import GL

        self._gl_api = GL
        self.sky: Sky = scene_sky(scene)
        self.sky_table = self.sky.colour(np.linspace(-1.0, 1.0, SKY_BINS))  # by a ray's world z
        shade = np.array(SUN) if config.renderer.raster.shadows else None  # the sun's shadows reach the view too
        reach = farthest_seen(config.camera.clip[1], **dataclasses.asdict(intrinsics))
        objects = greenhouse_objects(visible_scene(scene, viewpoints, reach, shade))
        model = self.model = mujoco.MjModel.from_xml_string(*render_world_xml(objects, config, intrinsics))
        self.data = mujoco.MjData(model)
        # every geom stands still in the world: where each is, once, so that a frame draws only those in reach
        mujoco.mj_kinematics(model, self.data)
        self.reach, self.shade = reach, shade
        self.geom_centre, self.geom_radius = self.data.geom_xpos.copy(), model.geom_rbound.copy()
        self.geom_group = model.geom_group.copy()
        self.sides = _frustum_sides(intrinsics)
        self.near, self.far = config.camera.clip
        self.width, self.height = intrinsics.width, intrinsics.height
        self.gl = mujoco.GLContext(model.vis.global_.offwidth, model.vis.global_.offheight)
        self.gl.make_current()
        self.context = mujoco.MjrContext(model, mujoco.mjtFontScale.mjFONTSCALE_150)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self.context)
        self.context.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR  # reversed z: far is 0, more precision far away
        self.scene = mujoco.MjvScene(model, maxgeom=model.ngeom + self.DECOR_GEOMS)
        self.option, self.perturb, self.camera = mujoco.MjvOption(), mujoco.MjvPerturb(), mujoco.MjvCamera()
        self.option.geomgroup[HIDDEN] = 0
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self.camera.fixedcamid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, CAMERA)
        self.camera_rig, self.sun_rig = (model.body_mocapid[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, rig)]
                                         for rig in (CAMERA_RIG, SUN_RIG))
        self.rect = mujoco.MjrRect(0, 0, self.width, self.height)
        extent = model.stat.extent  # the clip planes of the GL projection, float32 as glFrustum has them
        self.gl_near, self.gl_far = np.float32(model.vis.map.znear * extent), np.float32(model.vis.map.zfar * extent)
        # each pixel's ray in the optical frame, unit length, one plane per axis: its world z is what the sky's
        # gradient follows
        u, v = np.meshgrid(np.arange(self.width, dtype=np.float64), np.arange(self.height, dtype=np.float64))
        rays = np.stack([(u - intrinsics.cx) / intrinsics.fx, (v - intrinsics.cy) / intrinsics.fy, np.ones_like(u)])
        self.rays = (rays / np.linalg.norm(rays, axis=0)).astype(np.float32)
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
        self.data.mocap_pos[self.camera_rig] = camera[:3, 3]
        mujoco.mju_mat2Quat(self.data.mocap_quat[self.camera_rig], camera[:3, :3].ravel())
        self.data.mocap_pos[self.sun_rig] = _sun_position(np.asarray(pose, dtype=float), self.far)
        mujoco.mj_forward(self.model, self.data)
        self._show_in_view(np.asarray(pose, dtype=float))
        self.gl.make_current()
        scene, flags = self.scene, self.scene.flags
        mujoco.mjv_updateScene(self.model, self.data, self.option, self.perturb, self.camera, mujoco.mjtCatBit.mjCAT_ALL, scene)
        rgb = np.empty((self.height, self.width, 3), dtype=np.uint8)
        mujoco.mjr_render(self.rect, scene, self.context)
        mujoco.mjr_readPixels(rgb, None, self.rect, self.context)
        coverage = self._coverage()
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
        self._paint_sky(rgb, np.flipud(coverage), pose)
        depth[(depth < self.near) | (depth >= self.far * 0.9999)] = 0.0
        segment = ids[:, :, 0].astype(np.int32) + (ids[:, :, 1].astype(np.int32) << 8) + (ids[:, :, 2].astype(np.int32) << 16)
        geom_of_segment = np.full(scene.ngeom + 1, -1, dtype=np.int32)  # segment 0 is the background
        for k in range(scene.ngeom):
            drawn = scene.geoms[k]
            if drawn.segid != -1 and drawn.objtype == GEOM:
                geom_of_segment[drawn.segid + 1] = drawn.objid
        mask = self.pepper_of_geom[geom_of_segment[segment]]
        return RenderedFrame(rgb=rgb, depth=np.ascontiguousarray(depth), mask=mask, timings={"total": time.perf_counter() - start})

    def _show_in_view(self, pose: np.ndarray) -> None:
        """Draw only the geoms in the view of the camera at `pose` (T_world_optical), or whose shadow is (software
        OpenGL pays for every triangle it is given): within reach of it and inside the four sides of its frustum. The
        others are no pixel's and shade none, so the frame stays the same. A geom is its bounding sphere, or with the
        sun's shadows the capsule its sphere sweeps along the sun's light down to the floor."""
        position, centre, radius = pose[:3, 3], self.geom_centre, self.geom_radius
        if self.shade is None:
            distance = np.linalg.norm(centre - position, axis=1)
            ends = (centre,)
        else:  # to the path of the geom's centre along the sun down to the floor (a radius below it)
            length = np.maximum(centre[:, 2] + radius, 0.0) / -self.shade[2]
            along = np.clip((position - centre) @ self.shade / (self.shade @ self.shade), 0.0, length)
            distance = np.linalg.norm(centre + along[:, None] * self.shade - position, axis=1)
            ends = (centre, centre + length[:, None] * self.shade)
        # each side's signed distance (inside positive) of the farthest-in end: a capsule is out when both ends are
        # beyond one side by more than its radius
        inside = np.max([(end - position) @ pose[:3, :3] @ self.sides.T for end in ends], axis=0)
        shown = (distance <= self.reach + radius) & (inside >= -radius[:, None]).all(axis=1)
        self.model.geom_group[:] = np.where(shown, self.geom_group, HIDDEN)

    def _coverage(self) -> np.ndarray:
        """The colour pass's alpha, bottom row first: geometry writes 1 and the clear colour is 0, so after the
        multisample resolve it is the covered share of each pixel. mjr_readPixels reads RGB only; this reads the
        buffer it has just read from (the resolved one, or the single-sample one without antialiasing)."""
        GL, context = self._gl_api, self.context
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, context.offFBO_r if context.offSamples else context.offFBO)
        GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0)
        alpha = GL.glReadPixels(0, 0, self.width, self.height, GL.GL_ALPHA, GL.GL_UNSIGNED_BYTE)
        mujoco.mjr_restoreBuffer(context)
        return np.frombuffer(alpha, dtype=np.uint8).reshape(self.height, self.width)

    def _paint_sky(self, rgb: np.ndarray, coverage: np.ndarray, pose: np.ndarray) -> None:
        """Cycles' world colour behind the geometry, in place: rgb holds the geometry premultiplied by its
        coverage (over black), so the sky adds in by the uncovered share, whole where nothing is drawn."""
        if coverage.min() == 255:
            return
        if self.sky.uniform:
            sky = self.sky_table[0]
        else:
            # the world z of each pixel's ray, looked up in the sky's table (finer than an 8-bit level)
            x, y, z = np.asarray(pose, dtype=np.float32)[2, :3]
            up = self.rays[0] * x + self.rays[1] * y + self.rays[2] * z
            index = ((up + np.float32(1.0)) * np.float32((SKY_BINS - 1) / 2.0) + np.float32(0.5)).astype(np.intp)
            sky = np.take(self.sky_table, np.clip(index, 0, SKY_BINS - 1), axis=0)
        scaled = sky.astype(np.uint16) * (255 - coverage).astype(np.uint16)[..., None] + 128
        scaled = (scaled + (scaled >> 8)) >> 8  # sky times the uncovered share: x / 255 rounded, exact for 16 bits
        np.copyto(rgb, np.minimum(rgb + scaled, 255), casting="unsafe")

    def close(self) -> None:
        self.context.free()
        self.gl.free()

    def __enter__(self) -> RasterRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
