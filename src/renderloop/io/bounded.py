"""The limits every reader of a config or a run file applies: how deep a document nests, how many values it
expands to, and whether each number is finite and within its bounds.

Python's json and PyYAML's composer recurse once per level of nesting, so a file nested a few thousand levels
deep would end in a RecursionError; the depth is measured first, without recursion (the brackets of the JSON
text outside its strings; PyYAML's event stream, which its parser makes with a loop), and a document deeper
than MAX_DEPTH is refused before it is parsed. YAML aliases repeat a node without repeating its text, so a
small file can stand for billions of values (the "billion laughs"); the values a YAML document expands to are
counted on the same events and capped at MAX_VALUES. Every refusal is one UserError line naming the file.

Tables (CSV, TUM text) are checked column by column against a `Bound`: the message names the file, the row,
the column and the value, e.g. `trajectory.csv: row 12 has 1e+300 in column x, out of range [-1000, 1000] m`.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Annotated, Any, get_args, get_origin

import numpy as np
import yaml
from pydantic import BaseModel

from renderloop.errors import UserError

# A config nests 4 levels, the deepest run file 9 (scene.json: a leaf's base in a prototype of the neighbouring
# rows); 64 leaves room for any hand-written file and stays far below Python's recursion limit (1000 frames).
MAX_DEPTH = 64
# A config holds a few hundred values, camera_info.yaml forty: a million is room for any of them, not for a bomb.
MAX_VALUES = 1_000_000

_JSON_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"', re.DOTALL)


def json_depth(data: bytes) -> int:
    """How deep the JSON text nests: its most `[` and `{` open at once outside strings (computed without recursion)."""
    code = np.frombuffer(_JSON_STRING.sub(b'""', data), dtype=np.uint8)
    if not code.size:
        return 0
    step = (np.isin(code, (ord("["), ord("{"))).astype(np.int64) - np.isin(code, (ord("]"), ord("}"))))
    return int(np.cumsum(step).max(initial=0))


def check_json_depth(data: bytes | str, source: str) -> None:
    """Refuse JSON text that nests deeper than MAX_DEPTH, before any parser recurses into it."""
    depth = json_depth(data.encode("utf-8", "surrogatepass") if isinstance(data, str) else data)
    if depth > MAX_DEPTH:
        raise UserError(f"{source}: nested more than {MAX_DEPTH} levels deep ({depth})")


def load_json(data: bytes | str, source: str) -> Any:
    """A JSON document, its depth checked first; not JSON (or a number Python cannot hold) is one line."""
    check_json_depth(data, source)
    try:
        return json.loads(data)
    except (ValueError, UnicodeDecodeError) as exc:  # JSONDecodeError, and an integer of more than 4300 digits
        raise UserError(f"{source}: not a readable JSON file ({exc.__class__.__name__})") from None


def check_yaml_size(text: str, source: str) -> None:
    """Refuse YAML that nests deeper than MAX_DEPTH or expands (aliases included) to more than MAX_VALUES values.
    Walks the parser's events, a loop, so nothing recurses; a syntax error is left to the loader that follows."""
    sizes: dict[str, int] = {}  # values each anchor stands for
    open_nodes: list[list[Any]] = []  # [anchor, values so far] of each collection not yet closed
    total = 0
    try:
        for event in yaml.parse(text, Loader=yaml.SafeLoader):
            if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                open_nodes.append([event.anchor, 1])
                if len(open_nodes) > MAX_DEPTH:
                    raise UserError(f"{source}: nested more than {MAX_DEPTH} levels deep (line {event.start_mark.line + 1})")
                continue
            if isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                anchor, count = open_nodes.pop()
            elif isinstance(event, yaml.ScalarEvent):
                anchor, count = event.anchor, 1
            elif isinstance(event, yaml.AliasEvent):
                anchor, count = None, sizes.get(event.anchor, 1)
            else:
                continue
            if anchor is not None:
                sizes[anchor] = count
            if open_nodes:
                open_nodes[-1][1] += count
            else:
                total += count
            if total + sum(node[1] for node in open_nodes) > MAX_VALUES:
                raise UserError(f"{source}: stands for more than {MAX_VALUES:,} values (its aliases expanded)")
    except yaml.YAMLError:
        return


def load_yaml(text: str, source: str) -> Any:
    """A YAML document (safe types only), its size checked first; not YAML is one line with the line number."""
    check_yaml_size(text, source)
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        raise UserError(f"{source}: not valid YAML{where}") from None
    except ValueError:  # an integer of more than 4300 digits
        raise UserError(f"{source}: not valid YAML (a number too long to read)") from None


# Numbers ---------------------------------------------------------------------------------------------------------

def number_text(value: float) -> str:
    """A number as a message shows it: NaN, inf, or its shortest exact-enough digits (1e+300, 0.25)."""
    return "NaN" if math.isnan(value) else f"{value:.12g}"


@dataclass(frozen=True)
class Bound:
    """The closed range [low, high] a column's numbers lie in, in `unit`; `integer`: whole numbers only."""

    low: float
    high: float
    unit: str = ""
    integer: bool = False

    def __str__(self) -> str:
        return f"[{self.low:g}, {self.high:g}]{' ' + self.unit if self.unit else ''}"

    def problem(self, value: float) -> str | None:
        """What is wrong with `value` here, or None."""
        if math.isnan(value):
            return "not a number"
        if math.isinf(value):
            return "not a finite number"
        if not self.low <= value <= self.high:
            return f"out of range {self}"
        if self.integer and value != round(value):
            return "not a whole number"
        return None

    def mask(self, values: np.ndarray) -> np.ndarray:
        """True where a value is outside the bound (NaN included)."""
        inside = np.isfinite(values) & (values >= self.low) & (values <= self.high)
        if self.integer:
            inside &= values == np.round(values)
        return ~inside


FINITE = Bound(-math.inf, math.inf)  # any finite number


def check_columns(source: str, table: np.ndarray, header: Sequence[str], bounds: Sequence[Bound],
                  row: Callable[[int], str]) -> None:
    """Every number of `table` (rows x columns) within its column's bound; the first one that is not is one line:
    `{source}: {row(i)} has {value} in column {name}, {problem}` (rows and columns in file order)."""
    outside = np.column_stack([bound.mask(table[:, column]) for column, bound in enumerate(bounds)]) if len(bounds) else None
    if outside is None or not outside.any():
        return
    index, column = divmod(int(np.flatnonzero(outside)[0]), table.shape[1])
    value = float(table[index, column])
    raise UserError(f"{source}: {row(index)} has {number_text(value)} in column {header[column]}, {bounds[column].problem(value)}")


def check_increasing(source: str, times: np.ndarray, column: str, row: Callable[[int], str], strictly: bool) -> None:
    """Times in file order, increasing (`strictly`) or at least not decreasing; the first that is not is one line."""
    steps = np.diff(times)
    bad = np.flatnonzero(steps <= 0 if strictly else steps < 0)
    if len(bad):
        index = int(bad[0]) + 1
        relation = "not after" if strictly else "before"
        raise UserError(f"{source}: {row(index)} has {number_text(float(times[index]))} in column {column}, "
                        f"{relation} the {number_text(float(times[index - 1]))} of {row(index - 1)}")


# Bounds of config fields ------------------------------------------------------------------------------------------

def field_bounds(model: type[BaseModel], name: str) -> tuple[Any, Any]:
    """The (ge, le) bounds of a config field, or of its items for a tuple of bounded numbers, so a file's bound
    follows the config's instead of repeating it."""
    found: dict[str, float] = {}

    def collect(metadata: Sequence[Any]) -> None:
        for item in metadata:
            for key in ("ge", "gt", "le", "lt"):
                if getattr(item, key, None) is not None:
                    found.setdefault(key[0], getattr(item, key))
            collect(getattr(item, "metadata", ()))

    field = model.model_fields[name]
    collect(field.metadata)
    stack = [field.annotation]
    while stack and not {"g", "l"} <= found.keys():
        annotation = stack.pop()
        if get_origin(annotation) is Annotated:
            collect(get_args(annotation)[1:])
        stack.extend(arg for arg in get_args(annotation) if arg is not Ellipsis)
    if not {"g", "l"} <= found.keys():
        raise TypeError(f"{model.__name__}.{name} has no lower and upper bound")
    return found["g"], found["l"]
