"""MkDocs hook: every measured figure comes from `benchmarks/results/NAME.json`, never from the page's own text.

A results file is what `benchmarks/common.py: save_result` writes: `{"name", "date", "machine",
"commit", "command", "figures": {...}}`. Inside `figures` a table is `{"columns": [..], "rows":
[[..], ..]}` under any key; anything else is a plain value or a nested dict. A page shows them
with two markers (outside code blocks and code spans, where they stay as written):

- a line `<!-- results: NAME TABLEKEY -->` becomes the table `figures[TABLEKEY]` (a dotted path)
  and one italic line under it: *Measured DATE on MACHINE at COMMIT: COMMAND*;
- `{{ result: NAME dotted.key }}` anywhere in the text becomes that value: a number with at
  most 3 significant decimals, a string as it is, a list of them joined by commas. A number
  in the key is a list index (`table.rows.0.2`). A key that is not in `figures` but is one of
  the record's own fields (`date`, `machine`, `commit`, `command`) gives that field.

An unknown file or key fails the build with one message naming the page, the marker and the file.

The README is not built by MkDocs, so `scripts/readme_figures.py` renders its marked blocks with
the same functions (`render_readme`); tests/test_docs.py checks that the README is what the
results render, so a figure edited by hand there fails the tests too.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

TABLE = re.compile(r"^<!-- results: (\S+) (\S+) -->[ \t]*$")
VALUE = re.compile(r"\{\{\s*result:\s*(\S+)\s+(\S+?)\s*\}\}")
FENCE = re.compile(r"^\s*(```|~~~)")
CODE_SPAN = re.compile(r"(?<!`)(`+)(?!`).*?(?<!`)\1(?!`)")
RECORD_FIELDS = ("date", "machine", "commit", "command")

# In the README each rendered block sits between its marker and an end marker, so it can be
# rendered again in place: a table, or a template in a comment with `{{ result: }}` values.
README_TABLE = re.compile(r"^(<!-- results: (\S+) (\S+) -->\n)(.*?)(^<!-- /results -->$)", re.M | re.S)
README_TEMPLATE = re.compile(r"^(<!-- figures ([\w-]+)\n(.*?)\nend of figures \2 -->\n)(.*?)(^<!-- /figures \2 -->$)", re.M | re.S)


class ResultsError(Exception):
    """A marker names a results file or key that does not exist; the message says where."""


def results_dir(root: Path) -> Path:
    return root / "benchmarks" / "results"


def load(name: str, directory: Path, where: str) -> dict[str, Any]:
    path = directory / f"{name}.json"
    if not re.fullmatch(r"[\w.-]+", name) or not path.is_file():
        raise ResultsError(f"{where}: no results file {path}")
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except ValueError as error:
        raise ResultsError(f"{where}: {path} is not JSON: {error}") from None
    if not isinstance(record, dict) or not isinstance(record.get("figures"), dict):
        raise ResultsError(f"{where}: {path} has no `figures` object")
    return record


def lookup(record: dict[str, Any], key: str, path: Path, where: str) -> Any:
    value: Any = record["figures"]
    for part in key.split("."):
        if isinstance(value, dict) and part in value:
            value = value[part]
        elif isinstance(value, list) and part.isdigit() and int(part) < len(value):
            value = value[int(part)]
        else:
            if key in RECORD_FIELDS and key in record:
                return record[key]
            raise ResultsError(f"{where}: {path} has no figure `{key}`")
    return value


def number(value: Any) -> str:
    """A figure as the page shows it: integers whole, other numbers with at most 3 significant decimals."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value) or value == 0:
            return repr(value)
        # As stored (27.9 stays 27.9, 0.0 stays 0.0), cut to the third significant decimal, and
        # never to fewer than 3 decimals for numbers of 1 and above: 0.000123456 -> 0.000123,
        # 48.71234 -> 48.712.
        limit = max(3, 2 - math.floor(math.log10(abs(value))))
        text = repr(value)
        if "e" in text or len(text.partition(".")[2]) > limit:
            text = f"{value:.{limit}f}"
            if "." in text:
                text = text.rstrip("0").rstrip(".")
        return text
    return str(value)


def table(rows_spec: Any, path: Path, where: str) -> str:
    if not (isinstance(rows_spec, dict) and isinstance(rows_spec.get("columns"), list)
            and isinstance(rows_spec.get("rows"), list)):
        raise ResultsError(f"{where}: the figure in {path} is not a table ({{\"columns\": [..], \"rows\": [[..], ..]}})")
    columns = rows_spec["columns"]

    def cell(value: Any) -> str:
        return " ".join(number(value).split()).replace("|", "\\|")

    lines = ["| " + " | ".join(cell(c) for c in columns) + " |", "|" + " --- |" * len(columns)]
    for row in rows_spec["rows"]:
        if not isinstance(row, list) or len(row) != len(columns):
            raise ResultsError(f"{where}: a row of the table in {path} does not have {len(columns)} cells: {row!r}")
        lines.append("| " + " | ".join(cell(value) for value in row) + " |")
    return "\n".join(lines)


def code(text: str) -> str:
    """`text` as a Markdown code span, with enough backticks around it for any it holds."""
    ticks = "`" * (max((len(run) for run in re.findall(r"`+", text)), default=0) + 1)
    pad = " " if text.startswith("`") or text.endswith("`") else ""
    return f"{ticks}{pad}{text}{pad}{ticks}"


def measured(record: dict[str, Any]) -> str:
    return (f"*Measured {record.get('date', 'unknown')} on {record.get('machine', 'unknown')} "
            f"at {record.get('commit', 'unknown')}: {code(str(record.get('command', 'unknown')))}*")


def table_block(name: str, key: str, directory: Path, where: str) -> str:
    record = load(name, directory, where)
    path = directory / f"{name}.json"
    return table(lookup(record, key, path, where), path, where) + "\n\n" + measured(record)


def value_text(name: str, key: str, directory: Path, where: str) -> str:
    record = load(name, directory, where)
    value = lookup(record, key, directory / f"{name}.json", where)
    if isinstance(value, list) and not any(isinstance(item, (dict, list)) for item in value):
        return ", ".join(number(item) for item in value)
    if isinstance(value, (dict, list)):
        raise ResultsError(f"{where}: `{key}` in {directory / f'{name}.json'} is not a single value")
    return number(value)


def render(markdown: str, directory: Path, page: str) -> str:
    """`markdown` with every results marker outside code replaced by its figures."""

    def fill(text: str) -> str:
        return VALUE.sub(lambda m: value_text(m.group(1), m.group(2), directory, f"{page}: `{m.group(0)}`"), text)

    out, fence = [], None
    for line in markdown.split("\n"):
        opening = FENCE.match(line)
        if opening and (fence is None or opening.group(1) == fence):
            fence = opening.group(1) if fence is None else None
            out.append(line)
            continue
        if fence is not None:
            out.append(line)
            continue
        match = TABLE.match(line)
        if not match and TABLE.match(line.strip()):  # indented (in a list item), Markdown would hide it as a comment
            raise ResultsError(f"{page}: `{line.strip()}` is indented, where Markdown hides it: a table of {directory}/ "
                               "starts its line")
        if match:
            out.append(table_block(match.group(1), match.group(2), directory, f"{page}: `{line.strip()}`"))
            continue
        # A marker inside a code span is the marker's own documentation, shown as written.
        pieces, start = [], 0
        for span in CODE_SPAN.finditer(line):
            pieces += [fill(line[start:span.start()]), span.group(0)]
            start = span.end()
        out.append("".join(pieces) + fill(line[start:]))
    return "\n".join(out)


def render_readme(text: str, directory: Path, page: str = "README.md") -> str:
    """The README with each marked block rendered again from the results.

    `<!-- results: NAME KEY -->` ... `<!-- /results -->` holds that table; `<!-- figures LABEL`
    TEMPLATE `end of figures LABEL -->` ... `<!-- /figures LABEL -->` holds TEMPLATE with its
    `{{ result: }}` values filled in. The label makes each end unique, so a docs page can include
    the template itself (docs/index.md includes `headline` and renders it at build time).
    """
    text = README_TABLE.sub(
        lambda m: m.group(1) + "\n" + table_block(m.group(2), m.group(3), directory, f"{page}: `{m.group(1).strip()}`")
        + "\n\n" + m.group(5), text)
    return README_TEMPLATE.sub(lambda m: m.group(1) + render(m.group(3), directory, page) + "\n" + m.group(5), text)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    from mkdocs.exceptions import PluginError

    try:
        return render(markdown, results_dir(Path(config["config_file_path"]).parent), page.file.src_uri)
    except ResultsError as error:
        raise PluginError(f"results: {error}") from None
