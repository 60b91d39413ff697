"""The greenhouse as a list of objects, the one description every view draws.

Kubric's pattern: one scene, and each simulator or renderer a view of it. An object
has a name, either a triangle mesh, copies of template meshes (the 'pepper' style's
leaves) or primitive shapes (boxes, cylinders), a material name of the table in
`scene/materials.py`, and for a pepper its instance id. Cycles (`render/cycles.py`) draws
each object's triangles, and each copy of a template as an instance of one shared mesh;
the raster renderer (`render/raster.py`) makes a MuJoCo geom of each mesh, of the copies
merged, or of each shape; and the physics world (`scene/world.py`) reads the same static
shapes next to its own simple collision volumes for the plants. Each view translates
every kind of object in one function. The plants that are copies of a prototype come as a
`Group` per prototype (its parts once, and where each copy stands) when a view asks for groups
(Cycles instances a collection); `expand_groups` gives the others each part's copies placed by
pose, sharing one mesh.

Numpy only (no bpy, no mujoco), so any process can build the list.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from renderloop.scene import meshes
from renderloop.scene.materials import MATERIALS, RGBA
from renderloop.scene.meshes import Mesh
from renderloop.scene.model import NEIGHBOUR_FRUIT_ID, Environment, Pepper, Plant, Scene, placement
from renderloop.scene.plant_meshes import (
    LEAF_SHAPES,
    PETIOLE,
    calyx_mesh,
    leaf_template,
    leaf_transform,
    pepper_mesh,
    plant_meshes,
)

__all__ = ["Box", "Cylinder", "Group", "Instances", "SceneObject", "expand_groups", "greenhouse_objects", "collision_objects", "static_objects",
           "environment_objects", "wall_boxes", "table_boxes", "WALL_THICKNESS", "WORKSTATION_COLUMN"]

TABLE_TOP_THICKNESS = 0.04
TABLE_LEG = 0.04
WALL_THICKNESS = 0.05
WORKSTATION_COLUMN = (0.6, 0.05)  # height above the workstation table and radius of its manipulator, m
COLUMN_SIDES = 24  # facets of a cylinder's triangle mesh
# The 'film' greenhouse's structure: a Venlo house, its roof in spans between gutters that run along the rows
ROOF_SPAN = 4.0  # m between gutters
RIDGE_RISE = 0.8  # m: a span's ridge above its gutters (a 22° roof over 2 m)
GUTTER = (0.2, 0.15)  # m: a gutter's width and depth
POST = 0.08  # m: side of a square post under the gutters
TRUSS_SPACING = 4.5  # m between the trusses (and posts) along the gutters
TRUSS_DEPTH = 0.5  # m: a lattice truss under the gutters, its chords this far apart
TRUSS_BAY = 0.5  # m between a truss's verticals, a diagonal in each bay
CHORD = 0.04  # m: side of a truss chord; its verticals and diagonals are rods of half this radius
WIRE_RADIUS = 0.0025  # m: the crop wire over each row
STRING_RADIUS = 0.001  # m: the string from the wire down to each plant
TRAP_SIZE = (0.25, 0.1, 0.002)  # m: a sticky trap's width, height and thickness
# The neighbouring plants stand 1.6 m or more from any camera, where a leaf spans a few dozen pixels: their leaves
# are drawn with a tenth of the facets of the scanned plants' and their fruit with a quarter, or a crop of them is
# tens of millions of triangles (seconds a frame for the raster view's software OpenGL).
NEIGHBOUR_LEAF = (6, 1)  # a leaf template's stations along the blade and vertices across each half (scanned: 18, 4)
NEIGHBOUR_FRUIT = (8, 16)  # a fruit's rings and segments (scanned: 16, 32)


@dataclass(frozen=True)
class Box:
    """Axis-aligned box by centre and half size (MuJoCo's convention)."""

    name: str
    center: tuple[float, float, float]
    half: tuple[float, float, float]

    def mesh(self) -> Mesh:
        return meshes.box(self.center, 2 * np.asarray(self.half))

    @classmethod
    def sized(cls, name: str, center: Sequence[float], size: Sequence[float]) -> Box:
        """The box of a table or workstation, given by centre and full size."""
        return cls(name, tuple(float(c) for c in center), tuple(float(s) / 2 for s in size))

    @classmethod
    def bounding(cls, name: str, low: Sequence[float], high: Sequence[float]) -> Box:
        """The box between two corners (a plant's bounds)."""
        low, high = np.asarray(low, dtype=float), np.asarray(high, dtype=float)
        return cls(name, tuple((low + high) / 2), tuple((high - low) / 2))

    def apart(self, other: Box, gap: float = 0.0) -> bool:
        """Whether the two boxes are more than `gap` apart along some axis."""
        return bool(np.any(np.abs(np.asarray(self.center) - other.center) > np.asarray(self.half) + other.half + gap))


@dataclass(frozen=True)
class Cylinder:
    """Closed cylinder from `start` to `end` (the centres of its end faces)."""

    name: str
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    radius: float

    def mesh(self) -> Mesh:
        return meshes.tube(np.array([self.start, self.end]), self.radius, sides=COLUMN_SIDES)


Shape = Box | Cylinder


@dataclass(frozen=True)
class Instances:
    """Copies of template meshes: copy k is `templates[template[k]]` under the 4x4 affine map `transforms[k]`
    (a rotation times a positive scale, then a shift), in sRGB colour `rgb[k]`, with `alpha[k]` the number
    its material reads beside the colour (a leaf's dust)."""

    templates: tuple[Mesh, ...]
    template: np.ndarray  # (K,) int
    transforms: np.ndarray  # (K, 4, 4)
    rgb: np.ndarray  # (K, 3)
    alpha: np.ndarray  # (K,)
    template_rgb: tuple[np.ndarray, ...] | None = None  # per template, an sRGB colour per vertex (a 'simple' plant's leaves)
    pass_index: np.ndarray | None = None  # (K,) int: each copy's own instance id (the copies' fruit), else the object's

    def merged(self) -> Mesh:
        """Every copy's triangles in one mesh, in copy order (what a view without instancing draws)."""
        return meshes.merge([self.templates[i].transformed(m[:3, :3], m[:3, 3]) for i, m in zip(self.template, self.transforms)])

    @property
    def rigid(self) -> bool:
        """Every copy is its template turned and moved, not scaled (a view can place a shared mesh by pose alone)."""
        rotations = np.asarray(self.transforms, dtype=float)[:, :3, :3]
        return bool(np.allclose(rotations @ rotations.transpose(0, 2, 1), np.eye(3), atol=1e-9)
                    and np.all(np.linalg.det(rotations) > 0))


@dataclass(frozen=True)
class SceneObject:
    """One object of a view: a mesh, copies of templates or primitive shapes, a material of
    `scene.materials.MATERIALS`, its instance id (`pass_index`: a pepper's id, NEIGHBOUR_FRUIT_ID for the
    neighbouring rows' fruit, 0 for everything else), an object colour (sRGB, for materials that take the
    object's colour) and the number its material reads beside it (`alpha`: a fruit's ripe share), smooth
    shading, and an optional per-vertex sRGB colour (the leaf colour of each blade)."""

    name: str
    mesh: Mesh | None = None
    material: str = "object_color"
    pass_index: int = 0
    rgb: tuple[float, float, float] | None = None
    smooth: bool = False
    vertex_rgb: np.ndarray | None = None
    shapes: tuple[Shape, ...] = field(default=())
    instances: Instances | None = None
    alpha: float = 1.0

    def __post_init__(self) -> None:
        if (self.mesh is not None) + bool(self.shapes) + (self.instances is not None) != 1:
            raise ValueError(f"{self.name}: an object is one of a mesh, copies of templates or primitive shapes")
        if self.material not in MATERIALS:
            raise ValueError(f"{self.name}: no material {self.material!r}")
        if not 0 <= self.pass_index <= NEIGHBOUR_FRUIT_ID:
            raise ValueError(f"{self.name}: pass_index {self.pass_index} outside 0..{NEIGHBOUR_FRUIT_ID}")

    def triangles(self) -> Mesh:
        """The mesh, the copies merged, or the shapes' meshes merged in order (what a triangle renderer draws)."""
        if self.mesh is not None:
            return self.mesh
        if self.instances is not None:
            return self.instances.merged()
        return meshes.merge([shape.mesh() for shape in self.shapes])

    def display_rgba(self) -> RGBA:
        """The flat colour of a view without Cycles' materials: the object's own colour, else the mean
        of its vertex colours or of its copies' colours (a plant's leaves), else the material's display colour."""
        if self.rgb is not None:
            return (*map(float, self.rgb), 1.0)
        if self.vertex_rgb is not None and len(self.vertex_rgb):
            return (*map(float, np.asarray(self.vertex_rgb, dtype=float).reshape(-1, 3).mean(axis=0)), 1.0)
        if self.instances is not None and len(self.instances.rgb):
            return (*map(float, np.asarray(self.instances.rgb, dtype=float).mean(axis=0)), 1.0)
        return MATERIALS[self.material].rgba


def wall_boxes(room: Sequence[float]) -> list[Box]:
    """The four walls just outside the room."""
    length, width, height = room
    t = WALL_THICKNESS / 2
    return [
        Box("wall_east", (length / 2 + t, 0, height / 2), (t, width / 2, height / 2)),
        Box("wall_west", (-length / 2 - t, 0, height / 2), (t, width / 2, height / 2)),
        Box("wall_north", (0, width / 2 + t, height / 2), (length / 2, t, height / 2)),
        Box("wall_south", (0, -width / 2 - t, height / 2), (length / 2, t, height / 2)),
    ]


def table_boxes(name: str, center: Sequence[float], size: Sequence[float]) -> list[Box]:
    """A table's slab and four legs; `center` is the centre of the table's whole box, floor to top."""
    x, y, _ = center
    sx, sy, height = size
    leg_height = height - TABLE_TOP_THICKNESS
    boxes = [Box(name, (x, y, height - TABLE_TOP_THICKNESS / 2), (sx / 2, sy / 2, TABLE_TOP_THICKNESS / 2))]
    for index, (dx, dy) in enumerate(((-1, -1), (-1, 1), (1, -1), (1, 1))):
        leg_center = (x + dx * (sx / 2 - TABLE_LEG), y + dy * (sy / 2 - TABLE_LEG), leg_height / 2)
        boxes.append(Box(f"{name}_leg{index}", leg_center, (TABLE_LEG / 2, TABLE_LEG / 2, leg_height / 2)))
    return boxes


def static_objects(scene: Scene) -> list[SceneObject]:
    """Floor, walls, tables and workstation, each kind one object so that Cycles syncs few of them.
    The floor runs on under the walls, so no light leaks in where they meet it."""
    length, width, _ = scene.room
    t = WALL_THICKNESS
    station = scene.workstation
    column_height, column_radius = WORKSTATION_COLUMN
    top = (station.center[0], station.center[1], station.size[2])
    column = Cylinder("workstation_arm", top, (top[0], top[1], top[2] + column_height), column_radius)
    tables = [box for row in scene.rows for box in table_boxes(f"table_{row.id}", row.table.center, row.table.size)]
    return [
        SceneObject("floor", material="floor", shapes=(Box("floor", (0, 0, -0.05), ((length + 2 * t) / 2, (width + 2 * t) / 2, 0.05)),)),
        SceneObject("walls", material="wall", shapes=tuple(wall_boxes(scene.room))),
        SceneObject("tables", material="table", shapes=tuple(tables)),
        SceneObject("workstation", material="workstation",
                    shapes=(*table_boxes("workstation", station.center, station.size), column)),
    ]


def _film_shell(environment: Environment, half_x: float, half_y: float) -> Mesh:
    """Walls up to the gutters and a Venlo roof of spans between gutters, each two panes up to a ridge along y, the
    gable ends closed: one surface each (a film is one sheet; light passes it once), faces towards the inside."""
    height = environment.gutter_height
    gutters = np.append(np.arange(-half_x, half_x - 1e-9, ROOF_SPAN), half_x)
    corners = np.array([[-half_x, -half_y], [half_x, -half_y], [half_x, half_y], [-half_x, half_y]])
    polygons = [(np.array([[*a, 0.0], [*a, height], [*b, height], [*b, 0.0]]), np.r_[-(a + b) / 2, 0.0])
                for a, b in zip(corners, np.roll(corners, -1, axis=0))]  # (corners, a direction into the house)
    down = np.array([0.0, 0.0, -1.0])
    for left, right in zip(gutters[:-1], gutters[1:]):
        middle, top = (left + right) / 2, height + RIDGE_RISE * (right - left) / ROOF_SPAN
        polygons += [(np.array([[left, -half_y, height], [middle, -half_y, top], [middle, half_y, top], [left, half_y, height]]), down),
                     (np.array([[middle, -half_y, top], [right, -half_y, height], [right, half_y, height], [middle, half_y, top]]), down),
                     (np.array([[left, -half_y, height], [right, -half_y, height], [middle, -half_y, top]]), np.array([0.0, 1.0, 0.0])),
                     (np.array([[right, half_y, height], [left, half_y, height], [middle, half_y, top]]), np.array([0.0, -1.0, 0.0]))]
    parts = []
    for polygon, inward in polygons:
        fan = np.array([[0, k, k + 1] for k in range(1, len(polygon) - 1)])
        mesh = Mesh(polygon, fan)
        parts.append(mesh if mesh.face_normals()[0] @ inward > 0 else Mesh(polygon, fan[:, ::-1]))
    return meshes.merge(parts)


def _truss(y: float, half_x: float, height: float) -> list[Box | Cylinder]:
    """A lattice truss across the house under the gutters at `y`: two chords, a vertical and a diagonal each bay."""
    top, bottom = height - GUTTER[1] - CHORD / 2, height - GUTTER[1] - TRUSS_DEPTH
    shapes: list[Box | Cylinder] = [Box(f"truss_{y:.2f}_{z:.2f}", (0.0, y, z), (half_x, CHORD / 2, CHORD / 2)) for z in (top, bottom)]
    xs = np.append(np.arange(-half_x, half_x - 1e-9, TRUSS_BAY), half_x)
    for k, (a, b) in enumerate(zip(xs[:-1], xs[1:])):
        shapes.append(Cylinder(f"truss_{y:.2f}_v{k}", (a, y, bottom), (a, y, top), CHORD / 4))
        low, high = (a, b) if k % 2 == 0 else (b, a)
        shapes.append(Cylinder(f"truss_{y:.2f}_d{k}", (low, y, bottom), (high, y, top), CHORD / 4))
    return shapes


def _wires_and_strings(scene: Scene, inside: bool) -> list[Cylinder]:
    """The crop wire over every scanned row's line and the string from it down to each scanned plant's top: what of
    the structure stands in the room (`inside`), or the wires over the neighbouring rows and their strings."""
    environment = scene.environment
    half_y = scene.room[1] / 2 + environment.extent
    wire = environment.wire_height
    if inside:
        lines = sorted({row.table.center[0] for row in scene.rows})
        feet = [foot for plant in scene.plants for foot in _string_feet(plant, scene.strings_of(plant))]
    else:
        scanned = {round(row.table.center[0], 6) for row in scene.rows}
        lines = sorted({table.center[0] for table in environment.tables} - scanned)
        feet = [tuple(_yaw(copy.position, copy.yaw) @ (*foot, 1.0))[:3] for copy in environment.plants
                for foot in _string_feet(environment.prototypes[copy.prototype].plant)]
        feet += [(trap.center[0], trap.center[1], trap.center[2] + TRAP_SIZE[1] / 2) for trap in environment.traps]
    shapes = [Cylinder(f"wire_{x:.3f}", (x, -half_y, wire), (x, half_y, wire), WIRE_RADIUS) for x in lines]
    prefix = "string" if inside else "string_bg"
    shapes += [Cylinder(f"{prefix}_{k}", tuple(foot), (foot[0], foot[1], wire), STRING_RADIUS) for k, foot in enumerate(feet)]
    return shapes


def _string_feet(plant: Plant, strings: list[tuple[float, float, float]] | None = None) -> list[tuple[float, float, float]]:
    """Where a plant's strings start: where each stem's is tied (the 'highwire' style: `strings`, else the plant's
    own), else one at its top."""
    strings = plant.strings if strings is None else strings
    return list(strings) if strings else [(plant.position[0], plant.position[1], plant.bounds.max[2])]


@functools.cache
def _neighbour_leaf_template(index: int) -> Mesh:
    stations, half = NEIGHBOUR_LEAF
    return meshes.pepper_leaf(LEAF_SHAPES[index], petiole=PETIOLE, stations=stations, half=half)


def _neighbour_leaves(plant) -> Mesh:
    """A neighbouring 'pepper' plant's leaves, each its template's coarse copy scaled and placed, in one mesh."""
    parts = []
    for leaf in plant.leaves:
        transform = leaf_transform(leaf)
        parts.append(_neighbour_leaf_template(leaf.template).transformed(transform[:3, :3], transform[:3, 3]))
    return meshes.merge(parts)


def _neighbour_fruit(pepper) -> Mesh:
    rings, segments = NEIGHBOUR_FRUIT
    return meshes.pepper(pepper.center, pepper.axis, pepper.length, pepper.width, pepper.lobes, pepper.lobe_depth,
                         twist=pepper.twist, rings=rings, segments=segments)


def _yaw(position: tuple[float, float, float], yaw: float) -> np.ndarray:
    """4x4 map of a prototype (its pot's base at x = y = 0) turned by `yaw` about z and stood at `position`."""
    c, s = np.cos(yaw), np.sin(yaw)
    transform = np.eye(4)
    transform[:2, :2] = [[c, -s], [s, c]]
    transform[:2, 3] = position[:2]
    return transform


def _background_plants(environment: Environment) -> list[SceneObject]:
    """The neighbouring plants as copies of the prototypes, one object per part (pot, stem, leaves, flowers, calyces,
    fruit of each colour) whose templates are the prototypes' parts. A copy's leaves are one template in one
    colour; its fruit are drawn in their material with instance id NEIGHBOUR_FRUIT_ID: real peppers, never counted."""
    if not environment.plants:
        return []
    parts: dict[tuple[str, str], dict[int, tuple[Mesh, np.ndarray, float, np.ndarray | None]]] = {}
    for index, prototype in enumerate(environment.prototypes):
        plant, fruit = prototype.plant, prototype.fruit
        built = plant_meshes(plant, fruit)

        def add(part: str, material: str, mesh: Mesh | None, rgb, alpha: float = 1.0, vertex_rgb=None) -> None:
            if mesh is not None and len(mesh.faces):
                parts.setdefault((part, material), {})[index] = (mesh, np.asarray(rgb, dtype=float), alpha, vertex_rgb)

        add("pot", "pot", built.pot, MATERIALS["pot"].rgba[:3])
        add("stem", "stem", built.stem, MATERIALS["stem"].rgba[:3])
        leaf_rgb = np.mean([leaf.rgb for leaf in plant.leaves], axis=0)
        if plant.leaves and plant.leaves[0].template is not None:
            add("leaves", "pepper_leaf", _neighbour_leaves(plant), leaf_rgb, float(np.mean([leaf.dust or 0.0 for leaf in plant.leaves])))
        else:
            colors = np.concatenate([np.tile(leaf.rgb, (len(m.vertices), 1)) for leaf, m in zip(plant.leaves, built.leaves)])
            add("leaves", "leaf", meshes.merge(built.leaves), leaf_rgb, vertex_rgb=colors)
        add("flowers", "flower", built.flowers, MATERIALS["flower"].rgba[:3])
        add("calyces", "calyx", built.calyces, MATERIALS["calyx"].rgba[:3])
        for color in sorted({pepper.color for pepper in fruit}):
            same = [pepper for pepper in fruit if pepper.color == color]
            skin = "pepper" if same[0].ripeness is None else "fruit"
            ripe = float(np.mean([1.0 if p.ripeness is None else p.ripeness for p in same]))
            add(f"fruit_{color}", f"{skin}_{color}", meshes.merge([_neighbour_fruit(p) for p in same]),
                np.mean([p.rgb for p in same], axis=0), ripe)
    objects = []
    for (part, material), by_prototype in parts.items():
        order = sorted(by_prototype)
        copies = [copy for copy in environment.plants if copy.prototype in by_prototype]
        if not copies:
            continue
        slot = {prototype: k for k, prototype in enumerate(order)}
        vertex_rgb = [by_prototype[p][3] for p in order]
        instances = Instances(
            templates=tuple(by_prototype[p][0] for p in order),
            template=np.array([slot[copy.prototype] for copy in copies]),
            transforms=np.array([_yaw(copy.position, copy.yaw) for copy in copies]),
            rgb=np.array([by_prototype[copy.prototype][1] for copy in copies]),
            alpha=np.array([by_prototype[copy.prototype][2] for copy in copies]),
            template_rgb=tuple(vertex_rgb) if all(v is not None for v in vertex_rgb) else None,
        )
        objects.append(SceneObject(f"background_{part}", material=material, smooth=part != "pot", instances=instances,
                                   pass_index=NEIGHBOUR_FRUIT_ID if part.startswith("fruit_") else 0))
    return objects


def neighbour_fruit(environment: Environment | None) -> list[tuple[Pepper, np.ndarray]]:
    """Every fruit of the neighbouring rows as `_background_plants` draws it: its prototype's pepper and its mesh's
    vertices in the world, copy by copy. The masks mark them all NEIGHBOUR_FRUIT_ID; the training set tells them
    apart with these (`renderloop.dataset.labels.neighbour_fruit_boxes`)."""
    if environment is None:
        return []
    templates = [[(pepper, _neighbour_fruit(pepper)) for pepper in prototype.fruit] for prototype in environment.prototypes]
    fruit = []
    for copy in environment.plants:
        transform = _yaw(copy.position, copy.yaw)
        for pepper, mesh in templates[copy.prototype]:
            fruit.append((pepper, mesh.transformed(transform[:3, :3], transform[:3, 3]).vertices))
    return fruit


def film_tint(age: float) -> tuple[float, float, float]:
    """The film's colour at `age` (0 new, 1 old), sRGB: the material table's new and old tints mixed."""
    film = MATERIALS["film"]
    return tuple(float(a + age * (b - a)) for a, b in zip(film.base_rgb, film.accent_rgb))


def environment_objects(scene: Scene) -> list[SceneObject]:
    """The film greenhouse round the room (scene.json's `environment`): ground cover, the film shell, gutters, posts
    (none in the room) and trusses, wires and strings, the neighbouring rows' benches, plants and sticky traps."""
    environment = scene.environment
    length, width, _ = scene.room
    half_x, half_y = length / 2 + environment.extent, width / 2 + environment.extent
    height = environment.gutter_height
    gutters = np.append(np.arange(-half_x, half_x - 1e-9, ROOF_SPAN), half_x)
    stations = np.append(np.arange(-half_y, half_y - 1e-9, TRUSS_SPACING), half_y)
    steel: list[Box | Cylinder] = [Box(f"gutter_{k}", (x, 0.0, height - GUTTER[1] / 2), (GUTTER[0] / 2, half_y, GUTTER[1] / 2))
                                   for k, x in enumerate(gutters)]
    for x in gutters:
        for y in stations:
            if abs(x) > length / 2 + POST or abs(y) > width / 2 + POST:  # the room, the flight volume, has no posts
                half_height = (height - GUTTER[1]) / 2
                steel.append(Box(f"post_{x:.2f}_{y:.2f}", (x, y, half_height), (POST / 2, POST / 2, half_height)))
    for y in stations:
        steel.extend(_truss(y, half_x, height))
    benches = [box for k, table in enumerate(environment.tables) for box in table_boxes(f"bench_{k}", table.center, table.size)]
    card = (TRAP_SIZE[2] / 2, TRAP_SIZE[0] / 2, TRAP_SIZE[1] / 2)  # facing along x, as every trap does
    traps = [Box(f"trap_{k}", trap.center, card) for k, trap in enumerate(environment.traps)]
    objects = [
        SceneObject("ground_cover", material="ground_cover", shapes=(Box("ground_cover", (0, 0, -0.05), (half_x, half_y, 0.05)),)),
        SceneObject("film", _film_shell(environment, half_x, half_y), "film", rgb=film_tint(environment.film_age),
                    alpha=environment.film_age),
        SceneObject("structure", material="steel", shapes=tuple(steel)),
        SceneObject("wires", material="string", shapes=(*_wires_and_strings(scene, True), *_wires_and_strings(scene, False))),
    ]
    if benches:
        objects.append(SceneObject("benches", material="table", shapes=tuple(benches)))
    if traps:
        objects.append(SceneObject("traps", material="trap", shapes=tuple(traps)))
    return objects + _background_plants(environment)


@dataclass(frozen=True)
class Group:
    """Objects drawn together at many poses: the parts of a plant prototype in its own frame (`objects`), stood
    where each of its copies stands (`transforms`, 4x4 rigid maps). A view that can instance a group of objects
    (Cycles: a collection instanced by each copy) translates its objects once; `expand_groups` turns it into
    plain objects, each part's copies placed by pose, for the views that cannot."""

    name: str
    objects: tuple[SceneObject, ...]
    transforms: np.ndarray  # (K, 4, 4)


def _plant_body(plant: Plant, name: str, parts) -> list[SceneObject]:
    """A plant's pot, stem, leaves and flowers as objects named `<part>_<name>`."""
    objects = [SceneObject(f"pot_{name}", parts.pot, "pot"), SceneObject(f"stem_{name}", parts.stem, "stem", smooth=True)]
    own = [(leaf, m) for leaf, m in zip(plant.leaves, parts.leaves) if leaf.template is None]
    if own:
        colors = np.concatenate([np.tile(leaf.rgb, (len(m.vertices), 1)) for leaf, m in own])
        objects.append(SceneObject(f"leaves_{name}", meshes.merge([m for _, m in own]), "leaf", smooth=True,
                                   vertex_rgb=colors))
    copies = [leaf for leaf in plant.leaves if leaf.template is not None]
    if copies:
        instances = Instances(
            templates=tuple(leaf_template(i) for i in range(len(LEAF_SHAPES))),
            template=np.array([leaf.template for leaf in copies]),
            transforms=np.array([leaf_transform(leaf) for leaf in copies]),
            rgb=np.array([leaf.rgb for leaf in copies]),
            alpha=np.array([leaf.dust or 0.0 for leaf in copies]),
        )
        objects.append(SceneObject(f"leaf_copies_{name}", material="pepper_leaf", smooth=True, instances=instances))
    if parts.flowers is not None:
        objects.append(SceneObject(f"flowers_{name}", parts.flowers, "flower"))
    return objects


def _fruit(peppers: list[Pepper], parts) -> list[SceneObject]:
    """One object per pepper: its pass_index is its id; a 'pepper' style fruit has the 'fruit_' material and its ripe
    share as alpha."""
    objects = []
    for pepper in peppers:
        skin = "pepper" if pepper.ripeness is None else "fruit"
        objects.append(SceneObject(f"pepper_{pepper.id}", parts.peppers[pepper.id], f"{skin}_{pepper.color}",
                                   pass_index=pepper.id, rgb=tuple(pepper.rgb), smooth=True,
                                   alpha=1.0 if pepper.ripeness is None else pepper.ripeness))
    return objects


def _copied_plants(scene: Scene) -> list[SceneObject | Group]:
    """The plants that are copies of prototypes: each prototype's body once, as a group stood where its copies stand,
    then the copies' own parts: the stalks and calyces of all their fruit (two objects) and each fruit."""
    copies = [plant for plant in scene.plants if plant.is_copy]
    if not copies:
        return []
    groups: list[SceneObject | Group] = []
    for index, prototype in enumerate(scene.prototypes or ()):
        standing = [plant for plant in copies if plant.prototype == index]
        if standing:
            body = prototype.plant
            groups.append(Group(f"prototype_{index}", tuple(_plant_body(body, f"prototype_{index}", plant_meshes(body, []))),
                                np.array([placement(plant, body) for plant in standing])))
    stalks = [meshes.tube(np.array(p.peduncle.points), p.peduncle.radius)
              for plant in copies for p in scene.peppers_of(plant.id)]
    if stalks:
        groups.append(SceneObject("fruit_stalks", meshes.merge(stalks), "stem", smooth=True))
    return groups + _copied_fruit(scene, copies)


def _copied_fruit(scene: Scene, copies: list[Plant]) -> list[SceneObject]:
    """The copies' fruit as copies of their sites' meshes (scaled about the stalk end, turned and moved with the
    plant), one object per material whose copies each carry their fruit's id, colour and ripe share; their calyces
    likewise. A fruit's mesh so is its site's, shared by every copy that carries it (a compartment's ten thousand
    fruit are otherwise ten thousand meshes); `expand_groups` gives each its own object again."""
    sites: dict[tuple[int, int], int] = {}
    fruit_templates, calyx_templates, calyx_of = [], [], {}
    by_material: dict[str, list] = {}
    calyces: list = []
    for plant in copies:
        prototype = scene.prototype_of(plant)
        moved = placement(plant, prototype.plant)
        for pepper in scene.peppers_of(plant.id):
            key = (plant.prototype, pepper.site)
            site = prototype.fruit[pepper.site]
            if key not in sites:
                sites[key] = len(fruit_templates)
                fruit_templates.append(pepper_mesh(site))
                if site.calyx is not None:
                    calyx_of[key] = len(calyx_templates)
                    calyx_templates.append(calyx_mesh(site))
            stalk_end = np.asarray(site.peduncle.points[-1], dtype=float)
            scaled = np.eye(4)
            scaled[:3, :3] *= pepper.scale
            scaled[:3, 3] = (1.0 - pepper.scale) * stalk_end
            transform = moved @ scaled
            skin = "pepper" if pepper.ripeness is None else "fruit"
            alpha = 1.0 if pepper.ripeness is None else pepper.ripeness
            by_material.setdefault(f"{skin}_{pepper.color}", []).append((sites[key], transform, pepper.rgb, alpha, pepper.id))
            if key in calyx_of:
                calyces.append((calyx_of[key], transform))
    objects = []
    for material, fruit in sorted(by_material.items()):
        template, transforms, rgb, alpha, ids = zip(*fruit)
        objects.append(SceneObject(f"copied_{material}", material=material, smooth=True, instances=Instances(
            templates=tuple(fruit_templates), template=np.array(template), transforms=np.array(transforms),
            rgb=np.array(rgb, dtype=float), alpha=np.array(alpha, dtype=float), pass_index=np.array(ids))))
    if calyces:
        template, transforms = zip(*calyces)
        objects.append(SceneObject("copied_calyces", material="calyx", smooth=True, instances=Instances(
            templates=tuple(calyx_templates), template=np.array(template), transforms=np.array(transforms),
            rgb=np.ones((len(template), 3)), alpha=np.ones(len(template)))))  # as an object of no colour of its own
    return objects


def expand_groups(objects: Sequence[SceneObject | Group]) -> list[SceneObject]:
    """Plain objects for a view without groups: each object of a group becomes copies of its triangles (a template
    of one mesh) at the group's poses, in its flat display colour, so the copies still share one mesh."""
    out = []
    for item in objects:
        if not isinstance(item, Group):
            out += _own_objects(item)
            continue
        count = len(item.transforms)
        for obj in item.objects:
            mesh = obj.triangles()
            if not len(mesh.faces):
                continue
            alpha = float(np.mean(obj.instances.alpha)) if obj.instances is not None and len(obj.instances.alpha) else obj.alpha
            instances = Instances(
                templates=(mesh,), template=np.zeros(count, dtype=int), transforms=np.asarray(item.transforms, dtype=float),
                rgb=np.tile(obj.display_rgba()[:3], (count, 1)), alpha=np.full(count, alpha),
                template_rgb=None if obj.vertex_rgb is None else (np.asarray(obj.vertex_rgb, dtype=float),))
            out.append(SceneObject(obj.name, material=obj.material, pass_index=obj.pass_index, smooth=obj.smooth,
                                   instances=instances))
    return out


def _own_objects(item: SceneObject) -> list[SceneObject]:
    """`item`, or, for copies that each carry their own instance id (the copies' fruit), one object per copy: a view
    without groups tells instances apart by object."""
    copies = item.instances
    if copies is None or copies.pass_index is None:
        return [item]
    own = []
    for index, transform, rgb, alpha, pass_index in zip(copies.template, copies.transforms, copies.rgb, copies.alpha,
                                                         copies.pass_index):
        mesh = copies.templates[int(index)].transformed(transform[:3, :3], transform[:3, 3])
        own.append(SceneObject(f"pepper_{int(pass_index)}", mesh, item.material, pass_index=int(pass_index),
                               rgb=tuple(float(c) for c in rgb), smooth=item.smooth, alpha=float(alpha)))
    return own


def greenhouse_objects(scene: Scene, groups: bool = False) -> list[SceneObject] | list[SceneObject | Group]:
    """What the renderers draw: the static objects, then per plant one pot, one stem, one leaf and
    one flower object, the calyces, and one object per pepper (its pass_index is its id). A 'simple'
    plant's leaves are one mesh with per-vertex colours; a 'pepper' plant's are copies of the leaf
    templates (`Instances`), each fruit of its has the 'fruit_' material and its ripe share as alpha.
    Plants that are copies of prototypes come after the others: each prototype's body once, as a `Group` stood at
    its copies' poses (`groups`; else expanded by `expand_groups`), and the copies' own fruit, stalks and calyces.
    In a 'film' environment the room's floor and walls give way to the greenhouse round it (the walls stay in
    the physics world: the flight volume's fence)."""
    objects: list[SceneObject | Group] = list(static_objects(scene))
    if scene.environment is not None:
        objects = [obj for obj in objects if obj.name not in ("floor", "walls")] + environment_objects(scene)
    for plant in scene.plants:
        if plant.is_copy:
            continue
        peppers = scene.peppers_of(plant.id)
        parts = plant_meshes(plant, peppers)
        objects += _plant_body(plant, str(plant.id), parts)
        if parts.calyces is not None:
            objects.append(SceneObject(f"calyces_{plant.id}", parts.calyces, "calyx", smooth=True))
        objects += _fruit(peppers, parts)
    objects += _copied_plants(scene)
    return objects if groups else expand_groups(objects)


def collision_objects(scene: Scene) -> list[SceneObject]:
    """What the physics world holds: the same static objects, and per plant its pot as a cylinder and
    one box for the canopy (the plant's bounding volume above its pot: touching it counts as a
    collision with the plant), instead of thousands of leaf triangles."""
    objects = static_objects(scene)
    for plant in scene.plants:
        x, y, z = plant.position
        pot = plant.pot
        objects.append(SceneObject(f"pot_{plant.id}", material="pot",
                                   shapes=(Cylinder(f"pot_{plant.id}", (x, y, z), (x, y, z + pot.height), pot.radius_top),)))
        low, high = plant.bounds.min, plant.bounds.max
        bottom = z + pot.height
        canopy = Box(f"plant_{plant.id}", ((low[0] + high[0]) / 2, (low[1] + high[1]) / 2, (bottom + high[2]) / 2),
                     ((high[0] - low[0]) / 2, (high[1] - low[1]) / 2, (high[2] - bottom) / 2))
        objects.append(SceneObject(f"canopy_{plant.id}", material="canopy", shapes=(canopy,)))
    if scene.environment is not None:
        # of the film greenhouse, only the wires and strings over the scanned rows stand in the room; they hang over
        # the tables, where the planner never flies
        inside = [shape for shape in _wires_and_strings(scene, True) if min(shape.start[2], shape.end[2]) < scene.room[2]]
        if inside:
            objects.append(SceneObject("wires", material="string", shapes=tuple(inside)))
    return objects
