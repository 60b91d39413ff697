"""MkDocs hook: the configuration reference, generated at build time from the pydantic models.

Nothing about a config field is written twice: a page's line `<!-- generated: config-reference -->`
becomes one table per section of `renderloop.config.Config`, every field with its default,
its type and range and its description (where the unit is), all read from
`renderloop.config.config_schema()`; `<!-- generated: config-presets -->` becomes the preset
files as they ship. The other generated blocks (run directory, benchmarks) live in
`run_directory.py` beside this file; both fill `<!-- generated: NAME -->` markers, and a
marker no hook knows fails the build.
"""

from __future__ import annotations

import json
import math
import re
from importlib import resources
from typing import Any

MARKER = re.compile(r"<!-- generated: ([a-z0-9-]+) -->")


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


def kind(schema: dict[str, Any], defs: dict[str, Any]) -> str:
    """The type and range of a JSON-schema node, in words."""
    if "$ref" in schema:
        return f"`{schema['$ref'].split('/')[-1]}`"
    if "anyOf" in schema:
        return " or ".join(kind(option, defs) for option in schema["anyOf"])
    if "enum" in schema:
        return "one of " + ", ".join(f"`{value_text(v)}`" for v in schema["enum"])
    if "const" in schema:
        return f"`{value_text(schema['const'])}`"
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
            return f"text matching `{schema['pattern']}`"
        return "text"
    if type_ == "array":
        if "prefixItems" in schema:
            parts = [kind(item, defs) for item in schema["prefixItems"]]
            runs: list[list] = []  # consecutive equal items as [count, kind]
            for part in parts:
                if runs and runs[-1][1] == part:
                    runs[-1][0] += 1
                else:
                    runs.append([1, part])
            if len(runs) == 1:
                return f"{len(parts)} × {parts[0]}"
            return "(" + ", then ".join(f"{n} × {k}" if n > 1 else k for n, k in runs) + ")"
        item = kind(schema.get("items", {}), defs) if schema.get("items") else "values"
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
            key = " or ".join(f"`{k}`" for k in keys) if keys else "name"
            return f"map of {key} to {kind(values, defs)}"
        return "mapping"
    return "any value"


def dotted(path: str) -> str:
    """A dotted field name as code that a narrow table column breaks only after a dot."""
    return "<code>" + ".<wbr>".join(path.split(".")) + "</code>"


def cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def first_paragraph(text: str | None) -> str:
    return cell((text or "").split("\n\n")[0])


def reference_of(schema: dict[str, Any]) -> str | None:
    if "$ref" in schema:
        return schema["$ref"].split("/")[-1]
    for option in schema.get("allOf", []):
        if "$ref" in option:
            return option["$ref"].split("/")[-1]
    return None


def field_rows(prefix: str, model: dict[str, Any], defaults: dict[str, Any], defs: dict[str, Any]) -> list[str]:
    """One table row per leaf field of `model`, nested models flattened to dotted names, each default read from
    the enclosing field's default (a PID's gains are those of its loop, not the PID model's zeros)."""
    rows = []
    for name, schema in model.get("properties", {}).items():
        path = f"{prefix}.{name}" if prefix else name
        default = defaults[name] if name in defaults else schema.get("default")
        nested = reference_of(schema)
        if nested is not None:
            sub = defs[nested]
            note = cell(schema.get("description", ""))
            about = first_paragraph(sub.get("description"))
            rows.append(f"| {dotted(path)} | | section | {note}{' ' + about if about and about != note else ''} |")
            rows += field_rows(path, sub, default if isinstance(default, dict) else {}, defs)
            continue
        shown = "" if default is None and "default" not in schema and name not in defaults else f"`{value_text(default)}`"
        rows.append(f"| {dotted(path)} | {shown} | {cell(kind(schema, defs))} | {cell(schema.get('description', ''))} |")
    return rows


HEADER = ["| field | default | type and range | description |", "| --- | --- | --- | --- |"]


def config_reference() -> str:
    from renderloop.config import config_schema

    schema = config_schema()
    defs = schema.get("$defs", {})
    blocks = []
    loose = {name: s for name, s in schema["properties"].items() if reference_of(s) is None}
    if loose:  # top-level fields that are not sections (the seed)
        blocks.append("### Top level\n\n" + "\n".join(HEADER + field_rows("", {"properties": loose}, {}, defs)))
    for name, field in schema["properties"].items():
        nested = reference_of(field)
        if nested is None:
            continue
        model = defs[nested]
        text = [f"### {name}", "", model.get("description", "").strip() or cell(field.get("description", ""))]
        text += ["", *HEADER, *field_rows(name, model, field.get("default", {}), defs)]
        blocks.append("\n".join(text))
    return "\n\n".join(blocks)


def config_presets() -> str:
    from renderloop.config import PRESETS

    blocks = []
    for name in PRESETS:
        text = resources.files("renderloop.presets").joinpath(f"{name}.yaml").read_text(encoding="utf-8")
        blocks.append(f"### {name}\n\n`src/renderloop/presets/{name}.yaml`:\n\n```yaml\n{text.rstrip()}\n```")
    return "\n\n".join(blocks)


GENERATORS = {"config-reference": config_reference, "config-presets": config_presets}


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    return MARKER.sub(lambda match: GENERATORS[match.group(1)]() if match.group(1) in GENERATORS else match.group(0), markdown)
