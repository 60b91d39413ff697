"""The config reference: every field of `Config` with its default, its type and range, and its description (where the
unit is), read from `config_schema()`.

Written once for both of its readers: the documentation's tables (docs/hooks/config_reference.py) and the table that
`renderloop config --schema` prints. Each says how a literal value is set (`code`), the rest is shared.
"""

from __future__ import annotations

import json
import math
import re
import textwrap
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from renderloop.config import config_schema

Code = Callable[[str], str]


def _plain(text: str) -> str:
    return text


def number(value: float | int) -> str:
    """A bound or default as people write it: 0.6, 1e-09, π/2, 2^63 - 1."""
    if isinstance(value, bool):
        return json.dumps(value)
    if isinstance(value, int):
        if value > 10**12 and ((value + 1) & value) == 0:
            return f"2^{(value + 1).bit_length() - 1} - 1"
        return str(value)
    for fraction, text in ((1.0, "π"), (0.5, "π/2")):
        if value and math.isclose(abs(value), fraction * math.pi, rel_tol=1e-12):
            return text if value > 0 else f"-{text}"
    short = f"{value:.6g}"
    if float(short) != value:
        short = repr(value)
    return re.sub(r"e([+-])0*(\d)", lambda m: "e" + ("-" if m.group(1) == "-" else "") + m.group(2), short)


def value_text(value: Any) -> str:
    """A default as it is written in YAML flow style (numbers as `number` writes them)."""
    if value is None:
        return "null"
    if isinstance(value, (bool, int, float)):
        return number(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(value_text(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {value_text(v)}" for k, v in value.items()) + "}"
    return str(value)


def interval(schema: dict[str, Any]) -> str:
    low = ("[", schema["minimum"]) if "minimum" in schema else ("(", schema.get("exclusiveMinimum"))
    high = ("]", schema["maximum"]) if "maximum" in schema else (")", schema.get("exclusiveMaximum"))
    if low[1] is None and high[1] is None:
        return ""
    if high[1] is None:
        return f" {'≥' if low[0] == '[' else '>'} {number(low[1])}"
    if low[1] is None:
        return f" {'≤' if high[0] == ']' else '<'} {number(high[1])}"
    return f" in {low[0]}{number(low[1])}, {number(high[1])}{high[0]}"


def kind(schema: dict[str, Any], defs: dict[str, Any], code: Code = _plain) -> str:
    """The type and range of a JSON-schema node, in words; `code` sets a literal (a name, a value) apart."""
    if "$ref" in schema:
        return code(schema["$ref"].split("/")[-1])
    if "anyOf" in schema:
        return " or ".join(kind(option, defs, code) for option in schema["anyOf"])
    if "enum" in schema:
        return "one of " + ", ".join(code(value_text(v)) for v in schema["enum"])
    if "const" in schema:
        return code(value_text(schema["const"]))
    type_ = schema.get("type")
    if type_ in ("number", "integer"):
        return type_ + interval(schema)
    if type_ == "boolean":
        return "true or false"
    if type_ == "null":
        return "null"
    if type_ == "string":
        if schema.get("format") == "path":
            return "file path"
        if "pattern" in schema:
            return f"text matching {code(schema['pattern'])}"
        return "text"
    if type_ == "array":
        if "prefixItems" in schema:
            parts = [kind(item, defs, code) for item in schema["prefixItems"]]
            runs: list[list] = []  # consecutive equal items as [count, kind]
            for part in parts:
                if runs and runs[-1][1] == part:
                    runs[-1][0] += 1
                else:
                    runs.append([1, part])
            if len(runs) == 1:
                return f"{len(parts)} × {parts[0]}"
            return "(" + ", then ".join(f"{n} × {k}" if n > 1 else k for n, k in runs) + ")"
        item = kind(schema.get("items", {}), defs, code) if schema.get("items") else "values"
        low, high = schema.get("minItems"), schema.get("maxItems")
        if low is not None and low == high:
            return f"{low} × {item}"
        if low is not None and high is not None:
            return f"{low} to {high} items, each {item}"
        if high is not None:
            return f"at most {high} items, each {item}"
        if low is not None:
            return f"at least {low} items, each {item}"
        return f"list of {item}"
    if type_ == "object":
        values = schema.get("additionalProperties")
        if isinstance(values, dict):
            keys = schema.get("propertyNames", {}).get("enum")
            key = " or ".join(code(k) for k in keys) if keys else "name"
            return f"map of {key} to {kind(values, defs, code)}"
        return "mapping"
    return "any value"


def one_line(text: str | None) -> str:
    return " ".join((text or "").split())


def first_paragraph(text: str | None) -> str:
    return one_line((text or "").split("\n\n")[0])


def reference_of(schema: dict[str, Any]) -> str | None:
    if "$ref" in schema:
        return schema["$ref"].split("/")[-1]
    for option in schema.get("allOf", []):
        if "$ref" in option:
            return option["$ref"].split("/")[-1]
    return None


SECTION = "section"  # the kind of a row that opens a nested model: its fields follow it


@dataclass(frozen=True)
class Row:
    path: str  # dotted from the config's root: controller.position_xy.p
    default: str | None  # the default as `value_text` writes it; None for a section and a field without one
    kind: str  # the type and range in words, or SECTION
    description: str  # one line; the unit is in it


@dataclass(frozen=True)
class Section:
    name: str  # "" for the top-level fields that are not sections (the seed)
    description: str
    rows: tuple[Row, ...]


def field_rows(prefix: str, model: dict[str, Any], defaults: dict[str, Any], defs: dict[str, Any],
               code: Code = _plain) -> list[Row]:
    """One row per leaf field of `model`, nested models flattened to dotted names, each default read from
    the enclosing field's default (a PID's gains are those of its loop, not the PID model's zeros)."""
    rows = []
    for name, schema in model.get("properties", {}).items():
        path = f"{prefix}.{name}" if prefix else name
        default = defaults[name] if name in defaults else schema.get("default")
        nested = reference_of(schema)
        if nested is not None:
            sub = defs[nested]
            note = one_line(schema.get("description", ""))
            about = first_paragraph(sub.get("description"))
            rows.append(Row(path, None, SECTION, f"{note}{' ' + about if about and about != note else ''}"))
            rows += field_rows(path, sub, default if isinstance(default, dict) else {}, defs, code)
            continue
        shown = None if default is None and "default" not in schema and name not in defaults else value_text(default)
        rows.append(Row(path, shown, kind(schema, defs, code), one_line(schema.get("description", ""))))
    return rows


def config_sections(code: Code = _plain) -> list[Section]:
    """Every field of `Config` by section, in the order the model lists them; the top-level fields first."""
    schema = config_schema()
    defs = schema.get("$defs", {})
    sections = []
    loose = {name: s for name, s in schema["properties"].items() if reference_of(s) is None}
    if loose:
        sections.append(Section("", "", tuple(field_rows("", {"properties": loose}, {}, defs, code))))
    for name, field in schema["properties"].items():
        nested = reference_of(field)
        if nested is None:
            continue
        model = defs[nested]
        about = model.get("description", "").strip() or one_line(field.get("description", ""))
        sections.append(Section(name, about, tuple(field_rows(name, model, field.get("default", {}), defs, code))))
    return sections


def _clip(text: str, width: int) -> str:
    return text if len(text) <= width else text[: width - 3] + "..."


def reference_text(width: int = 100) -> str:
    """The reference as plain text for a terminal `width` columns wide: per section a heading, then per field a line
    of its name (below the section), default and type and range, and its description (with the unit) indented
    under it. A nested model's fields follow its own line, which has no default."""
    sections = config_sections()
    name_width = 2 + max(len(row.path) - len(section.name) - 1 for section in sections if section.name
                         for row in section.rows)
    default_width = 20
    kind_indent = 2 + name_width + default_width
    blocks = []
    for section in sections:
        lines = []
        heading = section.name or "top level"
        about = first_paragraph(section.description)
        lines += textwrap.wrap(f"{heading}: {about}" if about else heading, width, subsequent_indent="  ")
        lines.append("=" * min(width, len(heading)))
        for row in section.rows:
            name = row.path[len(section.name) + 1:] if section.name else row.path
            if row.kind == SECTION:
                head = f"  {name}  (section)"
            else:
                default = "" if row.default is None else _clip(row.default, default_width - 2)
                head = f"  {name:<{name_width}}{default:<{default_width}}"
                kinds = textwrap.wrap(row.kind, max(20, width - len(head)), subsequent_indent="")
                head += kinds[0] if kinds else ""
                lines.append(head)
                lines += [" " * kind_indent + more for more in kinds[1:]]
                lines += textwrap.wrap(row.description, width, initial_indent="      ", subsequent_indent="      ")
                continue
            lines.append(head)
            lines += textwrap.wrap(row.description, width, initial_indent="      ", subsequent_indent="      ")
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks) + "\n"
