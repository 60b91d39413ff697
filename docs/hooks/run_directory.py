"""MkDocs hook: the run-directory contract and the benchmark list, generated at build time from the code.

Fills these `<!-- generated: NAME -->` markers (the config reference is `config_reference.py`'s):

- `stages`: the pipeline's stages in order (`renderloop.pipeline`), what each needs and what it makes;
- `run-directory-names`: every file name of `renderloop.rundir.names`, with its note and the
  stage whose completeness it marks (`names.OUTPUTS`);
- `json-files`: the field tables of every JSON file of a run, from the pydantic models
  (`renderloop.rundir.models`, and `renderloop.scene.model` for scene.json): types and
  bounds from the JSON schema, the note of each field from its `description` or the
  comment at the end of its line;
- `csv-columns`: the column headers of waypoints.csv, trajectory.csv and flight.csv, as the
  writers spell them;
- `benchmarks`: each script of `benchmarks/` with its docstring (what it measures, how to run it).

It also keeps the hand-written run-directory page honest: a file name of
`renderloop.rundir.names` that the page never mentions is a warning, so `mkdocs build --strict`
fails until the new file is documented; so is a marker no hook knows.
"""

from __future__ import annotations

import ast
import io
import logging
import re
import sys
import tokenize
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))

from config_reference import MARKER, cell, kind, value_text  # noqa: E402

log = logging.getLogger("mkdocs.hooks.run_directory")


def trailing_comments(path: Path) -> dict[str, dict[str, str]]:
    """`{class name: {field: comment}}` for the fields of a module's classes (and "" for module-level names)."""
    source = path.read_text(encoding="utf-8")
    comments = {
        token.start[0]: token.string.lstrip("#").strip()
        for token in tokenize.generate_tokens(io.StringIO(source).readline)
        if token.type == tokenize.COMMENT
    }
    found: dict[str, dict[str, str]] = {"": {}}

    def collect(body: list[ast.stmt], into: dict[str, str]) -> None:
        for statement in body:
            target = None
            if isinstance(statement, ast.AnnAssign) and isinstance(statement.target, ast.Name):
                target = statement.target.id
            elif isinstance(statement, ast.Assign) and len(statement.targets) == 1 and isinstance(statement.targets[0], ast.Name):
                target = statement.targets[0].id
            if target is None:
                continue
            lines = range(statement.lineno, (statement.end_lineno or statement.lineno) + 1)
            note = next((comments[line] for line in lines if line in comments), None)
            if note:
                into[target] = note

    tree = ast.parse(source)
    collect(tree.body, found[""])
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            found[node.name] = {}
            collect(node.body, found[node.name])
    return found


# Stages -------------------------------------------------------------------------------------------------------------

def stages() -> str:
    from renderloop.pipeline import ONLINE_STAGES, STAGES

    rows = ["| stage | needs | makes (complete when all exist, newer than what it needs) |", "| --- | --- | --- |"]
    for stage in dict.fromkeys(STAGES + ONLINE_STAGES):
        online = " (`--online`: fly, render and detect in one loop)" if stage not in STAGES else ""
        needs = ", ".join(f"`{name}`" for name in stage.needs) or "the config"
        rows.append(f"| `{stage.name}`{online} | {needs} | {', '.join(f'`{name}`' for name in stage.makes)} |")
    return "\n".join(rows)


# Run-directory names ----------------------------------------------------------------------------------------------

def name_constants() -> list[tuple[str, str, str]]:
    """(constant, file name, note) of every file name `renderloop.rundir.names` spells."""
    from renderloop.rundir import names

    notes = trailing_comments(Path(names.__file__))[""]
    return [(constant, value, notes.get(constant, "")) for constant, value in vars(names).items()
            if constant.isupper() and isinstance(value, str)]


def run_directory_names() -> str:
    from renderloop.rundir import names

    marks = {name: stage for stage, outputs in names.OUTPUTS.items() for name in outputs}
    rows = ["| name | `renderloop.rundir.names` | marks this stage complete | note |", "| --- | --- | --- | --- |"]
    for constant, value, note in name_constants():
        marks_stage = next((stage for name, stage in marks.items() if name == value or name == names.frames_index(value)), "")
        shown = f"`{value}/`" if value in names.FRAME_DIRS or value == names.COUNT_PLOTS else f"`{value}`"
        rows.append(f"| {shown} | `{constant}` | {f'`{marks_stage}`' if marks_stage else ''} | {cell(note)} |")
    return "\n".join(rows)


def check_names_mentioned(markdown: str, page: Any) -> None:
    """Warn (a failure under --strict) for every run-directory file the hand-written page never names."""
    for constant, value, _ in name_constants():
        if not re.search(r"`" + re.escape(value) + r"[`/]", markdown):
            log.warning("%s does not describe `%s` (renderloop.rundir.names.%s): add it to the file table",
                        page.file.src_uri, value, constant)


# JSON files -------------------------------------------------------------------------------------------------------

def json_roots() -> list[tuple[str, type]]:
    """(file name, model) of every JSON file of a run: the models whose docstring starts with the file's name."""
    from pydantic import BaseModel

    from renderloop.rundir import models, names
    from renderloop.scene.model import Scene

    roots = [(names.SCENE, Scene)]
    for value in vars(models).values():
        if isinstance(value, type) and issubclass(value, BaseModel) and value.__module__ == models.__name__:
            match = re.match(r"`([\w.-]+\.json)`", (value.__doc__ or "").strip())
            if match:
                roots.append((match.group(1), value))
    return roots


def model_table(name: str, schema: dict[str, Any], notes: dict[str, str], defs: dict[str, Any]) -> str:
    required = set(schema.get("required", []))
    rows = ["| field | type and range | note |", "| --- | --- | --- |"]
    for field, spec in schema.get("properties", {}).items():
        note = spec.get("description") or notes.get(field, "")
        if field not in required:
            note = f"optional, default `{value_text(spec.get('default'))}`. {note}".rstrip(". ") + ("." if note else "")
        rows.append(f"| `{field}` | {cell(kind(spec, defs))} | {cell(note)} |")
    return "\n".join(rows)


def references(schema: Any) -> list[str]:
    """Names of the models a schema node refers to, in order of first appearance."""
    found: list[str] = []
    if isinstance(schema, dict):
        if "$ref" in schema:
            found.append(schema["$ref"].split("/")[-1])
        for value in schema.values():
            found += [name for name in references(value) if name not in found]
    elif isinstance(schema, list):
        for value in schema:
            found += [name for name in references(value) if name not in found]
    return list(dict.fromkeys(found))


def json_files() -> str:
    import inspect

    blocks = []
    for file_name, model in json_roots():
        schema = model.model_json_schema()
        defs = schema.get("$defs", {})
        comments = trailing_comments(Path(inspect.getsourcefile(model)))
        doc = (model.__doc__ or "").strip() or (inspect.getmodule(model).__doc__ or "").strip()
        doc = re.sub(r"^`[\w.-]+\.json`:\s*", "", doc)
        doc = doc[:1].upper() + doc[1:]
        text = [f"### {file_name}", "", f"Model: `{model.__module__}.{model.__name__}`. {cell(doc)}", ""]
        if "properties" in schema:
            text.append(model_table(model.__name__, schema, comments.get(model.__name__, {}), defs))
        else:
            text.append(f"The whole file is one {cell(kind(schema, defs))}.")
        for name in _reachable(schema, defs):
            sub = defs[name]
            about = cell((sub.get("description") or "").split("\n\n")[0])
            text += ["", f"`{name}`{': ' + about if about else ''}", "",
                     model_table(name, sub, comments.get(name, {}), defs)]
        blocks.append("\n".join(text))
    return "\n\n".join(blocks)


def _reachable(schema: dict[str, Any], defs: dict[str, Any]) -> list[str]:
    order: list[str] = []
    queue = references({k: v for k, v in schema.items() if k != "$defs"})
    while queue:
        name = queue.pop(0)
        if name in order:
            continue
        order.append(name)
        queue += [n for n in references(defs[name]) if n not in order]
    return order


# CSV files ---------------------------------------------------------------------------------------------------------

def csv_columns() -> str:
    from renderloop.planning.waypoints import WAYPOINT_HEADER
    from renderloop.rundir import files, names

    rows = []
    for file_name, header in ((names.WAYPOINTS, WAYPOINT_HEADER), (names.TRAJECTORY, files.TRAJECTORY_HEADER),
                              (names.FLIGHT, files.FLIGHT_HEADER)):
        rows.append(f"- `{file_name}` ({len(header)} columns): `{','.join(header)}`")
    return "\n".join(rows)


# Benchmarks --------------------------------------------------------------------------------------------------------

def benchmarks(root: Path) -> str:
    blocks = []
    for path in sorted((root / "benchmarks").glob("*.py")):
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8")))
        if path.stem == "common" or not doc:
            continue
        title, _, rest = doc.partition("\n")
        blocks.append(f"### `benchmarks/{path.name}`\n\n{title}\n{rest}")
    return "\n\n".join(blocks)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    root = Path(config["config_file_path"]).parent
    generators = {
        "stages": stages,
        "run-directory-names": run_directory_names,
        "json-files": json_files,
        "csv-columns": csv_columns,
        "benchmarks": lambda: benchmarks(root),
    }
    if "<!-- generated: run-directory-names -->" in markdown:
        check_names_mentioned(MARKER.sub("", markdown), page)
    markdown = MARKER.sub(lambda match: generators[match.group(1)]() if match.group(1) in generators else match.group(0),
                          markdown)
    for match in MARKER.finditer(markdown):
        log.warning("%s: no hook generates `%s`", page.file.src_uri, match.group(0))
    return markdown
