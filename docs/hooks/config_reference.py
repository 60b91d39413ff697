"""MkDocs hook: the configuration reference, generated at build time from the pydantic models.

Nothing about a config field is written twice: a page's line `<!-- generated: config-reference -->`
becomes one table per section of `renderloop.config.Config`, every field with its default,
its type and range and its description (where the unit is), all read from
`renderloop.config.config_schema()` by `renderloop.config.reference` (which `renderloop config --schema`
prints from too); `<!-- generated: config-presets -->` becomes the preset files as they ship. The other generated blocks (run directory, benchmarks) live in
`run_directory.py` beside this file; both fill `<!-- generated: NAME -->` markers, and a
marker no hook knows fails the build.
"""

from __future__ import annotations

import re
from importlib import resources
from typing import Any

from renderloop.config.reference import config_sections, value_text
from renderloop.config.reference import kind as kind_in_words

MARKER = re.compile(r"<!-- generated: ([a-z0-9-]+) -->")
__all__ = ["MARKER", "cell", "code", "config_reference", "dotted", "kind", "value_text"]  # run_directory.py reads these


def code(text: str) -> str:
    return f"`{text}`"


def kind(schema: dict[str, Any], defs: dict[str, Any]) -> str:
    """The type and range of a JSON-schema node in words, its names and values as code."""
    return kind_in_words(schema, defs, code)


def dotted(path: str) -> str:
    """A dotted field name as code that a narrow table column breaks only after a dot."""
    return "<code>" + ".<wbr>".join(path.split(".")) + "</code>"


def cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


HEADER = ["| field | default | type and range | description |", "| --- | --- | --- | --- |"]


def config_reference() -> str:
    """One Markdown table per section, of the rows `renderloop.config.reference` walks."""
    blocks = []
    for section in config_sections(code):
        rows = [f"| {dotted(row.path)} | {'' if row.default is None else f'`{row.default}`'} | {cell(row.kind)} | "
                f"{cell(row.description)} |" for row in section.rows]
        if section.name:
            blocks.append("\n".join([f"### {section.name}", "", section.description, "", *HEADER, *rows]))
        else:  # top-level fields that are not sections (the seed)
            blocks.append("### Top level\n\n" + "\n".join(HEADER + rows))
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
