"""Blender Cycles backend: one greenhouse scene per process, then one path-traced RGB-D frame per pose.

The scene is built once (the object list of `scene/objects.py` as meshes from numpy
arrays, copies of a template as linked duplicates of its one mesh, a plant prototype's objects
as one collection that each of its copies instances (its leaves one mesh), procedural materials
from the table in `scene/materials.py`, randomised greenhouse light) and `render()` only
moves the camera, so with persistent data Cycles keeps its BVH between frames and the
per-frame cost is path tracing plus a short sync.
`renderer.device` picks the CPU or an NVIDIA GPU (OptiX or CUDA, bpy's own kernels).

Each frame is written as one multi-layer EXR into a private temp directory and read
back with `OpenEXR`: that is the one route in bpy 5 that gives the exact float passes
(Combined, planar Z, Object Index) in background mode. RGB is the Combined pass under
the "Standard" view transform, which for the sRGB display is the plain sRGB OETF:
applying it in numpy to the EXR's float pixels matches the PNG Blender itself saves
(`Image.save_render`, dither off) to within one 8-bit level (28 of 57 600 values off
by one in a 160x120 greenhouse frame: OCIO's own rounding), and saves writing a file.

`render_blurred()` path traces the colour sensor's frame again with motion blur, the camera
keyed at the shutter's opening and closing (render/motion.py); the ideal passes stay sharp.

`bpy` is a process-wide singleton: building a renderer resets it, so constructing a
second renderer retires the first (its `render()` then raises).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import bpy
import numpy as np
import OpenEXR
from mathutils import Matrix

from renderloop.config import Config
from renderloop.errors import UserError
from renderloop.render import materials as looks
from renderloop.render.camera import Intrinsics, to_gl_camera
from renderloop.render.frame import RenderedFrame
from renderloop.render.sky import LIGHTING_STREAM
from renderloop.render.srgb import encode_u8, to_linear
from renderloop.scene.meshes import Mesh
from renderloop.scene.model import NEIGHBOUR_FRUIT_ID, Environment, Scene
from renderloop.scene.objects import Group, SceneObject, greenhouse_objects
from renderloop.scene.visible import farthest_seen, visible_scene

__all__ = ["CyclesRenderer", "RenderedFrame", "SceneObject", "greenhouse_objects", "VIEW_TRANSFORM"]

log = logging.getLogger(__name__)

VIEW_TRANSFORM = "Standard"  # plain sRGB OETF; no tone curve a detector would have to unlearn
SENSOR_WIDTH_MM = 36.0  # any value works: the lens is derived from fx and this width
DEFAULT_ROOM = (12.0, 10.0, 3.5)
_PASSES = {"rgb": "ViewLayer.Combined", "z": "ViewLayer.Depth.Z", "index": "ViewLayer.Object Index.X"}
_active: CyclesRenderer | None = None


def _bpy_mesh(name: str, mesh: Mesh) -> bpy.types.Mesh:
    """numpy arrays straight into a Blender mesh with foreach_set (no per-element Python)."""
    data = bpy.data.meshes.new(name)
    n_faces = len(mesh.faces)
    data.vertices.add(len(mesh.vertices))
    data.vertices.foreach_set("co", mesh.vertices.astype(np.float32).ravel())
    data.loops.add(3 * n_faces)
    data.loops.foreach_set("vertex_index", mesh.faces.ravel())
    data.polygons.add(n_faces)
    data.polygons.foreach_set("loop_start", np.arange(0, 3 * n_faces, 3, dtype=np.int32))
    if mesh.uv is not None:
        layer = data.uv_layers.new(name="UVMap")
        layer.uv.foreach_set("vector", mesh.uv[mesh.faces.ravel()].astype(np.float32).ravel())
    data.update(calc_edges=True)
    return data


def _leaf_colors(data: bpy.types.Mesh, vertex_rgb: np.ndarray) -> None:
    """Per-vertex sRGB colours into the linear attribute the leaf material reads."""
    linear = to_linear(np.asarray(vertex_rgb, dtype=float).reshape(-1, 3))
    rgba = np.column_stack([linear, np.ones(len(linear))]).astype(np.float32)
    data.attributes.new(looks.LEAF_COLOR_ATTRIBUTE, "FLOAT_COLOR", "POINT").data.foreach_set("color", rgba.ravel())


def _seconds(timecode: object) -> float:
    """Blender's stamp times ("MM:SS.cc" or "HH:MM:SS.cc") to seconds; NaN when absent."""
    try:
        fields = str(timecode).strip().split(":")
        return float(sum(float(value) * 60**power for power, value in enumerate(reversed(fields))))
    except ValueError:
        return math.nan


class CyclesRenderer:
    """Path-traced RGB, exact planar depth and the pepper instance mask for camera poses in one scene.

    `device` says what it renders on ("cpu", "optix" or "cuda"; `renderer.device: auto` picks) and
    `device_names` names the GPUs."""

    def __init__(self, scene: Scene, config: Config, intrinsics: Intrinsics, viewpoints: np.ndarray | None = None) -> None:
        """The Blender scene of `scene`; `viewpoints`, (N, 3) camera positions (m): of the plants only those the camera
        can see from one of them (scene/visible.py), None: every plant. The light is the whole scene's either way."""
        rng = np.random.default_rng(np.random.SeedSequence([scene.seed, LIGHTING_STREAM]))
        reach = farthest_seen(config.camera.clip[1], **dataclasses.asdict(intrinsics))
        objects = greenhouse_objects(visible_scene(scene, viewpoints, reach), groups=True)
        self._setup(config, intrinsics, scene.seed, objects, rng, scene.room, scene.environment)

    @classmethod
    def from_objects(
        cls,
        objects: Iterable[SceneObject | Group | tuple[str, Mesh, Sequence[float], int]],
        config: Config,
        intrinsics: Intrinsics,
        seed: int = 0,
        room: Sequence[float] = DEFAULT_ROOM,
        environment: Environment | None = None,
    ) -> CyclesRenderer:
        """A renderer of arbitrary meshes (a scene's objects and more, for the training set, tests and tools):
        SceneObjects, or plain (name, mesh, sRGB colour, pass_index) tuples drawn with a plain Principled material.
        Lighting is the greenhouse's, drawn from `seed` (`room` only sizes the roof fill), or the film greenhouse's
        light of `environment`; with a scene's seed, room and environment it lights as a renderer of the scene."""
        items = [obj if isinstance(obj, (SceneObject, Group)) else SceneObject(obj[0], obj[1], rgb=tuple(obj[2]), pass_index=int(obj[3]))
                 for obj in objects]
        renderer = cls.__new__(cls)
        rng = np.random.default_rng(np.random.SeedSequence([seed, LIGHTING_STREAM]))
        renderer._setup(config, intrinsics, seed, items, rng, room, environment)
        return renderer

    # -- construction -------------------------------------------------------------------------

    def _setup(self, config: Config, intrinsics: Intrinsics, seed: int, objects: list[SceneObject | Group],
               rng: np.random.Generator, room: Sequence[float], environment: Environment | None = None) -> None:
        global _active
        if not math.isclose(intrinsics.fx, intrinsics.fy, rel_tol=1e-9):
            raise ValueError(f"Cycles camera needs square pixels, got fx={intrinsics.fx} fy={intrinsics.fy}")
        if _active is not None:
            _active._retire()
        self._closed = True  # until fully built
        self.intrinsics = intrinsics
        self.clip = (float(config.camera.clip[0]), float(config.camera.clip[1]))
        self._tmp = Path(tempfile.mkdtemp(prefix="renderloop-cycles-"))
        self._exr = self._tmp / "frame.exr"
        try:
            bpy.ops.wm.read_factory_settings(use_empty=True)
            bpy.context.preferences.filepaths.use_scripts_auto_execute = False
            self._scene = bpy.context.scene
            self._configure(config, seed)
            self._camera = self._add_camera(intrinsics)
            if environment is None:
                self.lighting = looks.greenhouse_lighting(self._scene, rng, room)
            else:
                self.lighting = looks.film_lighting(self._scene, environment, room)
            self._add_objects(objects)
        except BaseException:
            shutil.rmtree(self._tmp, ignore_errors=True)
            raise
        self._closed = False
        _active = self

    def _configure(self, config: Config, seed: int) -> None:
        """Render settings: everything that could vary between runs is pinned."""
        r, s = config.renderer, self._scene
        s.render.engine = "CYCLES"
        c = s.cycles
        self.device, self.device_names = _choose_device(r.device)
        c.device = "CPU" if self.device == "cpu" else "GPU"
        c.samples = r.samples
        c.use_adaptive_sampling = r.adaptive_threshold > 0
        if r.adaptive_threshold > 0:
            c.adaptive_threshold = r.adaptive_threshold
        c.seed = seed & 0x7FFFFFFF
        c.use_animated_seed = False
        denoise = r.denoise
        if denoise and not _oidn_available():
            log.warning("Cycles was built without OpenImageDenoise: rendering without denoising")
            denoise = False
        c.use_denoising = denoise
        if denoise:
            c.denoiser = "OPENIMAGEDENOISE"
            c.denoising_use_gpu = self.device != "cpu"  # denoise where the frame already is
            c.denoising_input_passes = "RGB_ALBEDO_NORMAL"
            c.denoising_prefilter = "ACCURATE" if r.denoise_quality == "high" else "FAST"
            c.denoising_quality = r.denoise_quality.upper()
        b = r.bounces
        c.max_bounces, c.diffuse_bounces, c.glossy_bounces = b.total, b.diffuse, b.glossy
        c.transmission_bounces, c.transparent_max_bounces, c.volume_bounces = b.transmission, b.transparent, 0
        c.caustics_reflective = c.caustics_refractive = False
        c.sample_clamp_indirect = 10.0  # keeps fireflies out of few samples
        s.render.use_persistent_data = r.persistent_data
        s.render.threads_mode = "FIXED" if r.threads > 0 else "AUTO"
        if r.threads > 0:
            s.render.threads = r.threads
        s.render.resolution_x, s.render.resolution_y = self.intrinsics.width, self.intrinsics.height
        s.render.resolution_percentage = 100
        s.render.pixel_aspect_x = s.render.pixel_aspect_y = 1.0
        s.render.film_transparent = False
        s.render.dither_intensity = 0.0
        s.render.motion_blur_position, s.render.motion_blur_shutter = "START", 1.0  # used by render_blurred() only
        s.render.use_compositing = s.render.use_sequencer = False
        s.display_settings.display_device = "sRGB"
        s.view_settings.view_transform = VIEW_TRANSFORM
        s.view_settings.look = "None"
        s.view_settings.exposure, s.view_settings.gamma = 0.0, 1.0
        layer = s.view_layers[0]
        layer.use_pass_combined = layer.use_pass_z = layer.use_pass_object_index = True
        image = s.render.image_settings
        image.media_type = "MULTI_LAYER_IMAGE"
        image.color_depth, image.exr_codec = "32", "NONE"  # full float Z; no codec time for a file read once
        s.render.filepath = str(self._exr)
        s.render.use_file_extension = False

    def _add_camera(self, intrinsics: Intrinsics) -> bpy.types.Object:
        """Pinhole from the intrinsics: fx = lens * W / sensor_width (sensor fit horizontal); the
        shifts move the principal point off (W-1)/2, (H-1)/2 and are in units of W for that fit."""
        data = bpy.data.cameras.new("camera")
        data.sensor_fit = "HORIZONTAL"
        data.sensor_width = SENSOR_WIDTH_MM
        data.lens = intrinsics.fx * SENSOR_WIDTH_MM / intrinsics.width
        data.shift_x = ((intrinsics.width - 1) / 2 - intrinsics.cx) / intrinsics.width
        data.shift_y = (intrinsics.cy - (intrinsics.height - 1) / 2) / intrinsics.width
        data.clip_start, data.clip_end = self.clip
        camera = bpy.data.objects.new("camera", data)
        self._scene.collection.objects.link(camera)
        self._scene.camera = camera
        return camera

    def _add_objects(self, objects: list[SceneObject | Group]) -> None:
        materials = looks.greenhouse_materials()
        templates: dict[tuple[int, str], bpy.types.Mesh] = {}  # by template (its id) and material: shared by the copies
        self._add_items(objects, materials, templates, self._scene.collection.objects.link)

    def _add_items(self, objects: Iterable[SceneObject | Group], materials: dict[str, bpy.types.Material],
                   templates: dict[tuple[int, str], bpy.types.Mesh], link, merge: bool = False) -> None:
        """`merge`: copies of templates that share an instance id and whose material has a per-vertex variant become one
        mesh (`_add_merged_copies`), as inside a group."""
        for item in objects:  # the one place an object of the list becomes a Blender object
            if isinstance(item, Group):
                self._add_group(item, materials, templates)
                continue
            if item.instances is not None:
                if merge and item.instances.pass_index is None and looks.per_vertex_name(item.material) in materials:
                    self._add_merged_copies(item, materials, link)
                else:
                    self._add_copies(item, materials, templates, link)
                continue
            mesh = item.triangles()
            if len(mesh.faces) == 0:
                continue
            data = _bpy_mesh(item.name, mesh)
            if item.vertex_rgb is not None:
                _leaf_colors(data, item.vertex_rgb)
            if item.smooth:
                data.shade_smooth()
            if item.material not in materials:
                raise ValueError(f"{item.name}: material {item.material!r} has no Cycles recipe")
            data.materials.append(materials[item.material])
            obj = bpy.data.objects.new(item.name, data)
            obj.pass_index = item.pass_index
            if item.rgb is not None:
                obj.color = (*looks.srgb_to_linear(item.rgb), item.alpha)
            link(obj)

    def _add_group(self, group: Group, materials: dict[str, bpy.types.Material],
                   templates: dict[tuple[int, str], bpy.types.Mesh]) -> None:
        """A plant prototype's objects once, in a collection the scene does not hold, and an empty instancing that
        collection at each copy's pose: Cycles keeps one copy of the prototype's meshes and objects, however many
        plants stand in the rows. The prototype's leaves are one merged mesh (`_add_merged_copies`), not an object a
        leaf: Cycles walks every object of every instanced collection at each frame's sync, and a compartment's
        camera has about 130 plants of a few hundred leaves each in reach (`benchmarks/frame_scaling.py`)."""
        collection = bpy.data.collections.new(group.name)
        self._add_items(group.objects, materials, templates, collection.objects.link, merge=True)
        link = self._scene.collection.objects.link
        for k, transform in enumerate(group.transforms):
            empty = bpy.data.objects.new(f"{group.name}_copy_{k}", None)
            empty.instance_type = "COLLECTION"
            empty.instance_collection = collection
            empty.matrix_world = Matrix(np.asarray(transform, dtype=float).tolist())
            link(empty)

    def _add_copies(self, item: SceneObject, materials: dict[str, bpy.types.Material],
                    templates: dict[tuple[int, str], bpy.types.Mesh], link) -> None:
        """Each copy an object of its own (its transform, its colour and alpha) on its template's one mesh: linked
        duplicates, which Cycles instances, so a scene of thousands of leaves holds a few leaf meshes."""
        copies = item.instances
        if item.material not in materials:
            raise ValueError(f"{item.name}: material {item.material!r} has no Cycles recipe")
        linear = to_linear(np.asarray(copies.rgb, dtype=float).reshape(-1, 3))
        for k, (index, transform) in enumerate(zip(copies.template, copies.transforms)):
            template = copies.templates[int(index)]
            key = (id(template), item.material)
            data = templates.get(key)
            if data is None:
                data = templates[key] = _bpy_mesh(f"template_{len(templates)}", template)
                if copies.template_rgb is not None:
                    _leaf_colors(data, copies.template_rgb[int(index)])
                if item.smooth:
                    data.shade_smooth()
                data.materials.append(materials[item.material])
            obj = bpy.data.objects.new(f"{item.name}_{k}", data)
            obj.matrix_world = Matrix(np.asarray(transform, dtype=float).tolist())
            obj.pass_index = item.pass_index if copies.pass_index is None else int(copies.pass_index[k])
            obj.color = (*map(float, linear[k]), float(copies.alpha[k]))
            link(obj)

    def _add_merged_copies(self, item: SceneObject, materials: dict[str, bpy.types.Material], link) -> None:
        """The copies as one mesh (their templates' triangles where each copy lies) in the per-vertex variant of their
        material, each vertex carrying its copy's linear colour and alpha, its place in its own template and where its
        copy stands: what the object-wise copies read from their objects (render/materials.py: `_copy_values`)."""
        copies = item.instances
        counts = np.array([len(copies.templates[int(index)].vertices) for index in copies.template])
        data = _bpy_mesh(item.name, copies.merged())
        rgba = np.column_stack([to_linear(np.asarray(copies.rgb, dtype=float).reshape(-1, 3)), copies.alpha])
        own = np.concatenate([copies.templates[int(index)].vertices for index in copies.template])
        values = ((looks.LEAF_COLOR_ATTRIBUTE, "FLOAT_COLOR", "color", np.repeat(rgba, counts, axis=0)),
                  (looks.COPY_OBJECT_ATTRIBUTE, "FLOAT_VECTOR", "vector", own),
                  (looks.COPY_PLACE_ATTRIBUTE, "FLOAT_VECTOR", "vector",
                   np.repeat(np.asarray(copies.transforms, dtype=float)[:, :3, 3], counts, axis=0)))
        for name, kind, field, value in values:
            data.attributes.new(name, kind, "POINT").data.foreach_set(field, value.astype(np.float32).ravel())
        if item.smooth:
            data.shade_smooth()
        data.materials.append(materials[looks.per_vertex_name(item.material)])
        obj = bpy.data.objects.new(item.name, data)
        obj.pass_index = item.pass_index
        link(obj)

    # -- rendering ----------------------------------------------------------------------------

    def render(self, pose: np.ndarray) -> RenderedFrame:
        """Render the optical-frame pose T_world_optical (4x4)."""
        pose = self._checked(pose)
        start = time.perf_counter()
        self._camera.matrix_world = Matrix(to_gl_camera(pose).tolist())
        self._render_exr()
        rendered = time.perf_counter()
        frame = self._read()
        frame.timings["render_call"] = rendered - start
        frame.timings["readback"] = time.perf_counter() - rendered
        frame.timings["total"] = time.perf_counter() - start
        return frame

    def render_blurred(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """The colour (sRGB, uint8) of a camera moving from pose `start` to pose `end` while the shutter is open.
        Combined only: Cycles writes Depth and Object Index from a pixel's first sample, at a random instant of the
        shutter, so under blur their edges become dithered bands, neither a depth or mask nor the colour's edge."""
        start, end = self._checked(start), self._checked(end)
        s, camera, layer = self._scene, self._camera, self._scene.view_layers[0]
        # Keys at frames 1 and 2, linear (Blender's default eases in and out), the shutter open over exactly them.
        # Euler angles, the end's taken next to the start's so none wraps: the rotation mode render() decomposes
        # matrix_world into stays, or its next frame would differ in the last bit.
        gl_start, gl_end = (Matrix(to_gl_camera(pose).tolist()) for pose in (start, end))
        euler = gl_start.to_euler("XYZ")
        keyed = {"location": (gl_start.to_translation(), gl_end.to_translation()),
                 "rotation_euler": (euler, gl_end.to_euler("XYZ", euler))}
        action = bpy.data.actions.new("shutter")
        camera.animation_data_create().action = action
        try:
            for path, (opening, closing) in keyed.items():
                for axis in range(3):
                    keys = action.fcurve_ensure_for_datablock(camera, path, index=axis).keyframe_points
                    for frame, value in ((1, opening[axis]), (2, closing[axis])):
                        keys.insert(frame, value).interpolation = "LINEAR"
            s.frame_set(1)
            s.render.use_motion_blur = True  # the shutter: from frame 1 to frame 2 (_configure)
            layer.use_pass_z = layer.use_pass_object_index = False  # not read: see above
            self._render_exr()
            return encode_u8(self._channels([_PASSES["rgb"]])[0][_PASSES["rgb"]][..., :3])
        finally:  # back to the still camera render() expects
            camera.animation_data_clear()
            bpy.data.actions.remove(action)
            s.render.use_motion_blur = False
            layer.use_pass_z = layer.use_pass_object_index = True

    def _checked(self, pose: np.ndarray) -> np.ndarray:
        if self._closed:
            raise RuntimeError("CyclesRenderer is closed (or another renderer replaced its Blender scene)")
        pose = np.asarray(pose, dtype=float)
        if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
            raise ValueError("pose must be a finite 4x4 transform")
        if not np.allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-6):
            raise ValueError("pose rotation is not orthonormal")
        return pose

    def _render_exr(self) -> None:
        self._exr.unlink(missing_ok=True)
        with _quiet_stdout():
            bpy.ops.render.render(write_still=True)

    def _channels(self, needed: list[str]) -> tuple[dict[str, np.ndarray], dict]:
        """The EXR's channels by name, and its header."""
        if not self._exr.exists():
            raise RuntimeError(f"Cycles wrote no image to {self._exr}")
        channels: dict[str, np.ndarray] = {}
        with OpenEXR.File(str(self._exr)) as exr:
            header = dict(exr.parts[0].header)
            for part in exr.parts:
                for name, channel in part.channels.items():
                    channels[name] = np.array(channel.pixels)  # copy out of the file's buffers
        missing = [name for name in needed if name not in channels]
        if missing:
            raise RuntimeError(f"Cycles EXR lacks passes {missing} (has {sorted(channels)})")
        return channels, header

    def _read(self) -> RenderedFrame:
        channels, header = self._channels(list(_PASSES.values()))
        z = channels[_PASSES["z"]]
        near, far = self.clip
        depth = np.where(np.isfinite(z) & (z >= near) & (z <= far), z, 0.0).astype(np.float32)
        mask = np.rint(channels[_PASSES["index"]]).clip(0, NEIGHBOUR_FRUIT_ID).astype(np.uint16)
        rgb = encode_u8(channels[_PASSES["rgb"]][..., :3])
        timings = {key: _seconds(header.get(f"cycles.ViewLayer.{key}")) for key in ("render_time", "synchronization_time")}
        return RenderedFrame(rgb=rgb, depth=depth, mask=mask, timings=timings)

    # -- lifetime -----------------------------------------------------------------------------

    def _retire(self) -> None:
        global _active
        self._closed = True
        shutil.rmtree(self._tmp, ignore_errors=True)
        if _active is self:
            _active = None

    def close(self) -> None:
        """Delete the temp files and free Blender's copy of the scene. Idempotent."""
        was_active = _active is self
        self._retire()
        if was_active:
            bpy.ops.wm.read_factory_settings(use_empty=True)
            bpy.context.preferences.filepaths.use_scripts_auto_execute = False

    def __enter__(self) -> CyclesRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Blender prints a progress line per render from C, past Python's sys.stdout; it would
    tear through the progress display, so file descriptor 1 points at /dev/null meanwhile."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


GPU_BACKENDS = ("OPTIX", "CUDA")  # in this order: OptiX uses the ray-tracing cores of the GPUs that have them


def _gpu_devices() -> tuple[str, list[str]] | None:
    """The first GPU backend with a device that answers, enabled in Cycles' preferences with only its own
    devices (no CPU beside them): (backend, device names), or None. Asked only when a GPU is wanted:
    probing the drivers costs time and, per Blender, can crash on broken ones."""
    import _cycles

    prefs = bpy.context.preferences.addons["cycles"].preferences
    built = dict(zip(("CUDA", "OPTIX"), _cycles.get_device_types()[:2]))
    for backend in GPU_BACKENDS:
        if not built[backend]:
            continue
        found = [device for device in prefs.get_device_list(backend) if device[1] == backend]  # (name, type, id, ...)
        if found:
            prefs.compute_device_type = backend
            ids = {device[2] for device in found}
            for entry in prefs.devices:
                entry.use = entry.type == backend and entry.id in ids
            return backend, [device[0] for device in found]
    return None


def _choose_device(wanted: str) -> tuple[str, list[str]]:
    """`renderer.device` to what Cycles renders on: ("cpu", []) or ("optix" | "cuda", GPU names). Called after
    Blender's factory reset, which also resets the preferences the GPU choice is made in."""
    if wanted == "cpu":
        return "cpu", []
    gpu = _gpu_devices()
    if gpu is None:
        if wanted == "gpu":
            raise UserError("renderer.device: gpu, but Cycles finds no CUDA or OptiX GPU on this machine (use cpu or auto)")
        log.info("renderer.device auto: no CUDA or OptiX GPU answers, Cycles renders on the CPU")
        return "cpu", []
    backend, names = gpu
    log.info("Cycles renders on %s: %s", backend, ", ".join(names))
    return backend.lower(), names


def _oidn_available() -> bool:
    try:
        import _cycles

        return bool(getattr(_cycles, "with_openimagedenoise", False))
    except ImportError:
        return False
