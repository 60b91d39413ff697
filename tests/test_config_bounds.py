"""Every config field is bounded, and any value a user can write either loads or is refused in one line.

The fields are found by walking the config's JSON schema (`config_schema()`), so a field added later is drawn
too. Values are drawn across and beyond each field's bounds (below, at, inside, above, NaN, infinities, wrong
types), one field at a time or a few at once, over the demo preset. A config that loads must then get through
the scene and planning stages with nothing worse than a UserError.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from renderloop.config import Config, config_schema, deep_merge, preset_overrides, validate
from renderloop.errors import UserError
from renderloop.planning.trajectory import time_parameterize
from renderloop.planning.waypoints import plan_waypoints
from renderloop.scene.generate import generate_scene
from renderloop.scene.world import world_xml

SOURCE = "drawn"
SCHEMA = config_schema()
PRESET = preset_overrides("demo")
BASE = validate(PRESET, "preset demo").model_dump(mode="json")

Where = tuple[str | int, ...]


@dataclass(frozen=True, repr=False)
class Leaf:
    """One value of the config a user can set: a field, an element of a tuple field, or a list field's length."""

    path: Where
    schema: dict[str, Any]
    length: bool = False  # the list at `path` as a whole, drawn by its length

    @property
    def name(self) -> str:
        return ".".join(str(part) for part in self.path)

    def __repr__(self) -> str:
        return self.name + (" (length)" if self.length else "")


def _resolve(node: dict[str, Any]) -> dict[str, Any]:
    refs = [node] + node.get("allOf", [])
    for ref in refs:
        if "$ref" in ref:
            return {**SCHEMA["$defs"][ref["$ref"].rsplit("/", 1)[-1]], **{k: v for k, v in node.items() if k not in ("$ref", "allOf")}}
    return node


def _at(document: Any, path: Where) -> Any:
    for part in path:
        document = document[part]
    return document


def _leaves(node: dict[str, Any], path: Where) -> Iterator[Leaf]:
    node = _resolve(node)
    if "properties" in node:
        for name, child in node["properties"].items():
            yield from _leaves(child, (*path, name))
    elif node.get("type") == "object" and "propertyNames" in node:
        for key in node["propertyNames"]["enum"]:
            yield Leaf((*path, key), node["additionalProperties"])
    elif node.get("type") == "array" and "prefixItems" in node:
        for index, item in enumerate(node["prefixItems"]):
            yield from _leaves(item, (*path, index))
    elif node.get("type") == "array":
        yield Leaf(path, node, length=True)
        for index in range(len(_at(BASE, path))):
            yield from _leaves(node["items"], (*path, index))
    else:
        yield Leaf(path, node)


LEAVES = list(_leaves(SCHEMA, ()))


def _fields(node: dict[str, Any], path: Where) -> Iterator[tuple[Where, dict[str, Any]]]:
    """Every field of every model in the schema, with its (unresolved) schema."""
    for name, child in _resolve(node).get("properties", {}).items():
        yield (*path, name), child
        if "properties" in _resolve(child):
            yield from _fields(child, (*path, name))


# --- values ------------------------------------------------------------------------------------------------------

# A drawn value and whether it must be refused (False: it may load or be refused, depending on the other fields).
Drawn = tuple[Any, bool]

WRONG_TYPES = st.sampled_from([None, "fast", "", "1 m", [], [1, 2], {}, {"a": 1}])
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf])


def _bounds(schema: dict[str, Any]) -> tuple[float, bool, float, bool]:
    """(low, low is open, high, high is open)."""
    low_open, high_open = "exclusiveMinimum" in schema, "exclusiveMaximum" in schema
    return (schema.get("exclusiveMinimum", schema.get("minimum")), low_open,
            schema.get("exclusiveMaximum", schema.get("maximum")), high_open)


def _inside_numbers(schema: dict[str, Any], cap: float | None = None) -> st.SearchStrategy[Any]:
    low, low_open, high, high_open = _bounds(schema)
    if cap is not None:  # |value| <= cap
        low, low_open = max(low, -cap), low_open and low >= -cap
        high, high_open = min(high, cap), high_open and high <= cap
    if schema["type"] == "integer":
        return st.sampled_from([low, high]) | st.integers(low, high)
    edges = [edge for edge, is_open in ((low, low_open), (high, high_open)) if not is_open]
    inside = st.floats(low, high, exclude_min=low_open, exclude_max=high_open, allow_nan=False)
    return (st.sampled_from(edges) | inside) if edges else inside


def _outside_numbers(schema: dict[str, Any]) -> st.SearchStrategy[Any]:
    low, low_open, high, high_open = _bounds(schema)
    span = max(1.0, high - low)
    if schema["type"] == "integer":
        below = st.integers(low - 10 * int(span), low - 1) | st.just(low - 1)
        above = st.integers(high + 1, high + 10 * int(span)) | st.sampled_from([high + 1, 10**40])
        fractional = st.floats(float(low), min(float(high), 1e6), allow_nan=False).filter(lambda v: v != int(v))
        return below | above | fractional | NON_FINITE
    below = st.floats(max_value=low, exclude_max=not low_open, allow_nan=False, allow_infinity=False)
    above = st.floats(min_value=high, exclude_min=not high_open, allow_nan=False, allow_infinity=False)
    return below | above | st.sampled_from([low - span * 1e-9, high + span * 1e-9]).filter(lambda v: not low <= v <= high) | NON_FINITE


def _choices(schema: dict[str, Any]) -> list[Any] | None:
    if "enum" in schema:
        return schema["enum"]
    if "const" in schema:
        return [schema["const"]]
    return None


def drawn_values(leaf: Leaf, inside_only: bool = False, cap: float | None = None) -> st.SearchStrategy[Drawn]:
    """Values for one leaf: inside its bounds (and at them), or beyond them and of the wrong type."""
    schema = leaf.schema
    if leaf.length:
        low, high = schema.get("minItems", 0), schema["maxItems"]
        lengths = st.integers(low, min(high, low + 3)).map(lambda n: (n, False))
        if not inside_only:
            lengths |= st.sampled_from([high + 1, high + 7] + ([low - 1] if low > 0 else [])).map(lambda n: (n, True))
        return lengths
    if "anyOf" in schema:
        branch = next(option for option in schema["anyOf"] if option.get("type") != "null")
        if "properties" in _resolve(branch):  # an optional section: unset, or set (its fields' own bounds are below)
            defaults = {name: field["default"] for name, field in _resolve(branch)["properties"].items()}
            return st.sampled_from([(None, False), (defaults, False)])
        values = drawn_values(Leaf(leaf.path, branch), inside_only, cap)
        return st.just((None, False)) | values.map(lambda drawn: (None, False) if drawn[0] is None else drawn)
    choices = _choices(schema)
    if choices is not None:
        inside = st.sampled_from(choices).map(lambda v: (v, False))
        wrong = st.sampled_from(["z", "X", 0, 5, -1, None, [], "3 "]).filter(lambda v: v not in choices)
        return inside if inside_only else inside | wrong.map(lambda v: (v, True))
    kind = schema.get("type")
    if kind in ("number", "integer"):
        inside = _inside_numbers(schema, cap).map(lambda v: (v, False))
        return inside if inside_only else inside | _outside_numbers(schema).map(lambda v: (v, True)) | WRONG_TYPES.map(lambda v: (v, True))
    if kind == "boolean":
        inside = st.booleans().map(lambda v: (v, False))
        return inside if inside_only else inside | st.sampled_from([None, "maybe", [], {}, 2, 0.5]).map(lambda v: (v, True))
    if kind == "string" and "pattern" in schema:
        inside = st.sampled_from(["1x1", "2x2", "3x2", "8x8"]).map(lambda v: (v, False))
        return inside if inside_only else inside | st.sampled_from(["9x9", "0x1", "2x", "", "2x2\n", 3, None]).map(lambda v: (v, True))
    if kind == "string":  # a path
        return st.text(max_size=12).map(lambda v: (v, False)) | st.sampled_from([3, [], {}]).map(lambda v: (v, True))
    raise AssertionError(f"{leaf.name}: no values for schema {schema}")


# --- documents ---------------------------------------------------------------------------------------------------

def override(assignments: list[tuple[Leaf, Any]]) -> dict[str, Any]:
    """The override document setting each leaf; a tuple or list is written whole, from the demo config's value."""
    document: dict[str, Any] = {}
    for leaf, value in assignments:
        split = next((i for i, part in enumerate(leaf.path) if isinstance(part, int)), len(leaf.path))
        head, tail = leaf.path[:split], leaf.path[split:]
        parent = document
        for part in head[:-1]:
            parent = parent.setdefault(part, {})
        if leaf.length:
            base = _at(BASE, head)
            parent[head[-1]] = [copy.deepcopy(base[i % len(base)]) for i in range(value)]
        elif tail:
            container = parent.setdefault(head[-1], copy.deepcopy(_at(BASE, head)))
            _at(container, tail[:-1])[tail[-1]] = value
        else:
            parent[head[-1]] = value
    return document


@st.composite
def assignments(draw: st.DrawFn, leaves: list[Leaf], inside_only: bool = False,
                caps: dict[str, float] | None = None) -> list[tuple[Leaf, Any, bool]]:
    """One leaf (most often) or a few, each with a drawn value and whether that value must be refused."""
    count = draw(st.sampled_from([1, 1, 1, 2, 3, 4]))
    chosen = draw(st.lists(st.sampled_from(leaves), min_size=1, max_size=count, unique_by=lambda leaf: leaf.path))
    redrawn = [leaf.path for leaf in chosen if leaf.length]  # a list drawn whole leaves none of its elements to set
    chosen = [leaf for leaf in chosen if leaf.length or not any(leaf.path[:len(path)] == path for path in redrawn)]
    drawn = []
    for leaf in chosen:
        cap = next((value for prefix, value in (caps or {}).items() if leaf.name.startswith(prefix)), None)
        value, refused = draw(drawn_values(leaf, inside_only, cap))
        drawn.append((leaf, value, refused))
    return drawn


def load(drawn: list[tuple[Leaf, Any, bool]]) -> Config:
    return validate(deep_merge(PRESET, override([(leaf, value) for leaf, value, _ in drawn])), SOURCE)


# --- properties --------------------------------------------------------------------------------------------------

@settings(max_examples=400, deadline=None)
@given(drawn=assignments(LEAVES))
def test_every_drawn_config_loads_or_fails_in_one_line(drawn: list[tuple[Leaf, Any, bool]]):
    try:
        config = load(drawn)
    except UserError as error:
        message = str(error)
        assert message.startswith(f"{SOURCE}: ") and "\n" not in message, message
        if len(drawn) == 1 and drawn[0][2]:
            leaf = drawn[0][0]
            assert message.startswith(f"{SOURCE}: {leaf.name}"), (leaf.name, message)
        return
    assert isinstance(config, Config)
    for leaf, value, refused in drawn:
        assert not refused, f"{leaf.name} = {value!r} is beyond its bounds but loaded"


# The scene and plan property draws within bounds (out-of-bounds values never reach a stage) and keeps the
# greenhouse small: these caps bound the fields that multiply the scene's size or the planner's grid.
SCENE_SECTIONS = ("seed", "greenhouse", "plants", "robot", "camera.width", "camera.height", "camera.hfov_deg", "planner",
                  "controller.physics_dt", "controller.rate_hz")
SCENE_CAPS = {
    "greenhouse.size.0": 30.0, "greenhouse.size.1": 30.0, "greenhouse.table_size.1": 6.0,
    "greenhouse.plants_per_table": 8, "greenhouse.tables": 20.0, "greenhouse.workstation_center": 20.0,
    "plants.bearing": 8, "plants.leaves": 100, "plants.pepper_style.leaves": 100, "plants.flowers": 20, "plants.branches": 20, "plants.peppers.per_side": 10,
    "planner.points_per_ellipse": 40, "robot.home": 20.0,
}
SCENE_LEAVES = [leaf for leaf in LEAVES if leaf.name.startswith(SCENE_SECTIONS) and not leaf.length]


def scene_and_plan(config: Config) -> None:
    scene = generate_scene(config)
    mujoco.MjModel.from_xml_string(world_xml(scene, config))
    waypoints = plan_waypoints(scene, config)
    time_parameterize(np.array([w.dofs for w in waypoints]), config.planner)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(drawn=assignments(SCENE_LEAVES, inside_only=True, caps=SCENE_CAPS))
def test_a_config_that_loads_gets_through_scene_and_plan_or_fails_in_one_line(drawn: list[tuple[Leaf, Any, bool]]):
    try:
        config = load(drawn)
    except UserError:
        return
    try:
        scene_and_plan(config)
    except UserError as error:
        assert "\n" not in str(error), str(error)


@pytest.mark.parametrize(
    ("document", "message"),
    [
        ({"camera": {"rate_hz": 60}, "controller": {"rate_hz": 50}}, "camera.rate_hz: frames are taken at control ticks"),
        ({"camera": {"width": 8192, "height": 8192}}, "camera: width: a 8192 x 8192 px image is more than 33554432 px"),
        ({"greenhouse": {"size": [200, 100, 4]}}, "greenhouse: size: a 200 x 100 m floor is larger than 10000 m²"),
        ({"greenhouse": {"tables": [[0, 0]] * 30, "plants_per_table": 200, "table_size": [0.5, 100, 0.6]}},
         "greenhouse: plants_per_table: 30 tables of 200 plants are more than 5000 plants"),
        ({"plants": {"leaves": [10, 2000], "prototypes": 120}, "greenhouse": {"plants_per_table": 4, "tables": [[-3, -2.5]] * 30}},
         "plants.leaves: 120 plants of up to 2000 leaves are more than 200000 leaves"),
        ({"greenhouse": {"workstation_center": [5.9, 0]}}, "greenhouse: workstation_center: the workstation at (5.9, 0.0) lies outside"),
        ({"robot": {"inertia": [0.01, 0.01, 0.05]}}, "robot: inertia: no rigid body has principal moments"),
        ({"controller": {"rate_hz": 300}}, "controller: rate_hz: the control period 1/300 s must be a whole number of physics steps"),
        ({"plants": {"peppers": {"lobe_depth": [0.1, 0.5]}}}, "plants.peppers.lobe_depth.1: Input should be less than 0.5"),
    ],
)
def test_each_bound_across_fields_is_one_line_naming_the_field(document: dict, message: str):
    with pytest.raises(UserError) as error:
        validate(deep_merge(PRESET, document), SOURCE)
    assert str(error.value).startswith(f"{SOURCE}: ") and message in str(error.value) and "\n" not in str(error.value)


# --- the schema --------------------------------------------------------------------------------------------------

def test_the_schema_gives_each_field_a_description_default_and_bounds():
    camera = SCHEMA["$defs"]["CameraConfig"]["properties"]["rate_hz"]
    samples = SCHEMA["$defs"]["RendererConfig"]["properties"]["samples"]
    for field, default in ((camera, 5.0), (samples, 1)):
        assert field["description"] and field["default"] == default
        assert field["minimum"] <= default <= field["maximum"]
    assert camera["maximum"] <= 100 and samples["maximum"] == 65536


def test_every_field_in_the_schema_has_a_description():
    fields = list(_fields(SCHEMA, ()))
    assert len(fields) > 100
    missing = [".".join(map(str, path)) for path, field in fields if not field.get("description")]
    assert not missing


def test_every_number_is_bounded_above_and_below_and_every_list_in_length():
    unbounded = []
    for leaf in LEAVES:
        schema = leaf.schema["anyOf"][0] if "anyOf" in leaf.schema else leaf.schema
        if leaf.length:
            bounded = "maxItems" in schema
        elif "$ref" in schema:  # an optional section: its fields are leaves, checked here, where its model is required
            bounded = any(schema["$ref"] in (child.get("$ref"), *(r.get("$ref") for r in child.get("allOf", [])))
                          for _, child in _fields(SCHEMA, ()) if "anyOf" not in child)
        elif schema.get("type") in ("number", "integer") and _choices(schema) is None:
            low, _, high, _ = _bounds(schema)
            bounded = low is not None and high is not None
        else:
            bounded = _choices(schema) is not None or "pattern" in schema or schema.get("format") == "path" or schema.get("type") == "boolean"
        if not bounded:
            unbounded.append(leaf.name)
    assert not unbounded


def test_the_presets_and_defaults_lie_within_the_bounds():
    for name in ("demo", "paper"):
        validate(preset_overrides(name), f"preset {name}")
    assert Config() == validate({}, "defaults")
