"""The documentation builds, strictly, and nothing in the package points at a document the repository lacks.

`mkdocs build --strict` fails on any warning: a broken link or anchor, a page missing from
the nav, a docstring mkdocstrings cannot find, a generated table whose hook failed, or a run
file that `renderloop.rundir.names` spells but docs/run-directory.md never describes
(docs/hooks/run_directory.py). About 15 s: the hooks import the package to read its models.
"""

from __future__ import annotations

import functools
import json
import os
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "src" / "renderloop"
TEXT_SUFFIXES = {".py", ".md", ".yaml", ".yml", ".txt", ".toml"}


def test_docs_build_strictly(tmp_path):
    site = tmp_path / "site"
    environment = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}  # Material's banner about MkDocs 2.0: not a warning
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(ROOT / "mkdocs.yml"),
         "--site-dir", str(site)],
        cwd=ROOT, env=environment, capture_output=True, text=True, timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert (site / "index.html").is_file()
    configuration = (site / "configuration" / "index.html").read_text(encoding="utf-8")
    assert "controller.position_xy.p" in configuration and "2.083" in configuration  # generated from the models
    assert "Simulation" in (site / "api" / "simulation" / "index.html").read_text(encoding="utf-8")
    assert "ssdlite320_efficientnet_lite0_s8" in (site / "model-card" / "index.html").read_text(encoding="utf-8")
    run = json.loads((ROOT / "benchmarks" / "results" / "run.json").read_text(encoding="utf-8"))
    benchmarks = (site / "benchmarks" / "index.html").read_text(encoding="utf-8")
    assert f"Measured {run['date']} on {run['machine']} at {run['commit']}" in benchmarks  # the results file's table
    assert "&lt;!-- results:" not in benchmarks.replace("<code>&lt;!-- results: NAME KEY --&gt;</code>", "")
    index = (site / "index.html").read_text(encoding="utf-8")
    assert "{{ result:" not in index and "figures headline" not in index  # the README's template, rendered


def source_texts():
    for path in sorted(SOURCE.rglob("*")):
        if path.is_file() and path.suffix in TEXT_SUFFIXES and "egg-info" not in str(path):
            yield path, path.read_text(encoding="utf-8")


def test_the_package_names_no_document_outside_the_repository():
    """The code once cited "DESIGN §4", notes that lived outside the repository; it cites docs/design.md now.
    Every Markdown file a source file names must exist in the repository."""
    documents = set()
    for folder, subfolders, names in os.walk(ROOT):
        subfolders[:] = [name for name in subfolders if not name.startswith(".") and name not in {"runs", "site", "build"}]
        documents |= {(Path(folder) / name).relative_to(ROOT).as_posix() for name in names if name.endswith(".md")}
    basenames = {Path(document).name for document in documents}
    problems = []
    for path, text in source_texts():
        where = path.relative_to(ROOT)
        for number, line in enumerate(text.splitlines(), start=1):
            if re.search(r"\bDESIGN\b|§", line):
                problems.append(f"{where}:{number}: cites a document outside the repository: {line.strip()}")
            for name in re.findall(r"[\w./-]*[\w-]+\.md\b", line):
                name = name.lstrip("./")
                if name not in documents and Path(name).name not in basenames:
                    problems.append(f"{where}:{number}: names {name}, which is not in the repository")
                elif "/" in name and name not in documents:
                    problems.append(f"{where}:{number}: names {name}, which is not at that path")
    assert not problems, "\n".join(problems)


# Measured figures: one source, benchmarks/results/*.json -------------------------------------------------------------

sys.path.insert(0, str(ROOT / "docs" / "hooks"))
import results as results_hook  # noqa: E402  (docs/hooks/results.py: not a package, MkDocs loads it by path)

RESULTS = ROOT / "benchmarks" / "results"


def test_a_results_file_drives_the_figures_of_the_page_that_shows_it(tmp_path):
    record = json.loads((RESULTS / "loop.json").read_text(encoding="utf-8"))
    record["figures"]["table"]["rows"][3][1] = 12.345678
    record["figures"]["cycles"]["wall_s"] = 98.7
    record["command"] = ".venv/bin/python benchmarks/loop.py --seconds 99"
    (tmp_path / "loop.json").write_text(json.dumps(record), encoding="utf-8")
    page = "Wall time {{ result: loop cycles.wall_s }} s.\n\n<!-- results: loop table -->\n"
    shown = results_hook.render(page, tmp_path, "benchmarks.md")
    assert "Wall time 98.7 s." in shown
    name, _, spread = record["figures"]["table"]["rows"][3]
    assert f"| {name} | 12.346 | {spread} |" in shown
    assert f"*Measured {record['date']} on {record['machine']} at {record['commit']}: " \
           "`.venv/bin/python benchmarks/loop.py --seconds 99`*" in shown
    assert "{{" not in shown and "<!--" not in shown


def test_results_markers_in_code_stay_as_written():
    page = "Write `{{ result: NAME key }}` or\n\n```markdown\n<!-- results: NAME KEY -->\n```\n"
    assert results_hook.render(page, RESULTS, "benchmarks.md") == page


@pytest.mark.parametrize("marker, says", [
    ("{{ result: no_such_file figure }}", "no results file"),
    ("{{ result: loop no.such.key }}", "has no figure `no.such.key`"),
    ("<!-- results: loop cycles -->", "is not a table"),
    ("  <!-- results: loop table -->", "starts its line"),
])
def test_a_marker_naming_a_missing_file_or_figure_fails_the_build_naming_page_marker_and_file(marker, says):
    from mkdocs.exceptions import PluginError

    page = SimpleNamespace(file=SimpleNamespace(src_uri="stages/fly.md"))
    config = {"config_file_path": str(ROOT / "mkdocs.yml")}
    with pytest.raises(PluginError) as failure:
        results_hook.on_page_markdown(f"Text\n\n{marker}\n", page, config, None)
    message = str(failure.value)
    assert says in message and "stages/fly.md" in message and marker.strip() in message
    assert "benchmarks/results/" in message


def test_figures_show_as_stored_with_at_most_three_significant_decimals():
    shown = {value: results_hook.number(value) for value in (0.0, 97.5, 90.0, 27.9, 48.71234, 0.000123456, 237, "0.3-0.7")}
    assert shown == {0.0: "0.0", 97.5: "97.5", 90.0: "90.0", 27.9: "27.9", 48.71234: "48.712", 0.000123456: "0.000123",
                     237: "237", "0.3-0.7": "0.3-0.7"}


def test_every_results_file_is_what_save_result_writes():
    for path in sorted(RESULTS.glob("*.json")):
        record = json.loads(path.read_text(encoding="utf-8"))
        assert set(record) == {"name", "date", "machine", "commit", "command", "figures"}, path.name
        assert record["name"] == path.stem and isinstance(record["figures"], dict), path.name
        assert re.fullmatch(r"\d{4}-\d\d-\d\d|unknown", record["date"]), path.name  # unknown: transcribed, undated


def test_the_readme_shows_exactly_what_the_results_render():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert results_hook.render_readme(readme, RESULTS) == readme, \
        "README.md's figures differ from benchmarks/results: run .venv/bin/python scripts/readme_figures.py"
    assert {"<!-- /figures caption -->", "<!-- /figures headline -->"} <= set(readme.splitlines())
    assert len(readme.splitlines()) <= 150


def demo_row_figures() -> str:
    """The README's rendered demo-run cell, as benchmarks/results/run.json has it."""
    figures = json.loads((RESULTS / "run.json").read_text(encoding="utf-8"))["figures"]
    return f"| {figures['demo_wall_s']} / {figures['demo_peak_mb']} |"


def test_a_figure_edited_by_hand_in_the_readme_is_put_back_from_the_results():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    rendered_demo_row = [line for line in readme.splitlines() if line.startswith("| the demo run, whole pipeline")][-1]
    edited = readme.replace(rendered_demo_row, rendered_demo_row.replace(demo_row_figures(), "| 12.0 / 871 |"))
    assert edited != readme
    assert results_hook.render_readme(edited, RESULTS) == readme


def test_the_readme_figures_script_checks_and_exits_nonzero_on_a_stale_readme(tmp_path):
    stale = tmp_path / "README.md"
    stale.write_text((ROOT / "README.md").read_text(encoding="utf-8").replace(demo_row_figures(), "| 12.0 / 871 |"),
                     encoding="utf-8")
    script = [sys.executable, str(ROOT / "scripts" / "readme_figures.py")]
    check = subprocess.run([*script, "--check", "--readme", str(stale)], capture_output=True, text=True, timeout=60)
    assert check.returncode == 1 and check.stderr.count("\n") == 1 and "differs" in check.stderr
    fixed = subprocess.run([*script, "--readme", str(stale)], capture_output=True, text=True, timeout=60)
    assert fixed.returncode == 0
    assert stale.read_text(encoding="utf-8") == (ROOT / "README.md").read_text(encoding="utf-8")


# Commands the pages show: they parse, and the configs they name are in the repository ---------------------------------

COMMAND_PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")),
                 ROOT / "src" / "renderloop" / "perception" / "model" / "MODEL_CARD.md"]
SHELL_FENCES = {"", "bash", "sh", "shell", "console"}
# The Configuration page shows `my.yaml` as the file the reader writes, its content beside the command.
READER_WRITTEN = {"my.yaml"}


def page_commands(path: Path):
    """(where, argv, complete) of every `renderloop` command the page shows.

    Fenced shell blocks (backslash continuations joined, comments cut) hold complete commands;
    an inline code span may name a verb with some of its options only (`renderloop count --force`
    on each seed, `renderloop train --photos`), so a missing argument, or the value of the option
    it ends with, is allowed there and nothing else is.
    """
    text = path.read_text(encoding="utf-8")
    where = path.relative_to(ROOT).as_posix()
    prose, fence, language, block = [], None, "", []
    for line in text.splitlines():
        opening = re.match(r"\s*(```+|~~~+)\s*([\w-]*)", line)
        if fence is None and opening:
            fence, language, block = opening.group(1), opening.group(2), []
            prose.append("")
        elif fence is not None and line.strip().startswith(fence):
            if language in SHELL_FENCES:
                for command in re.sub(r"\\\n\s*", " ", "\n".join(block)).splitlines():
                    command = re.sub(r"(^|\s)#.*", "", command)
                    for part in re.split(r"&&|;|\|", command):
                        yield from _renderloop(where, part, complete=True)
            fence = None
        elif fence is not None:
            block.append(line)
        else:
            prose.append(line)
    for span in re.findall(r"(?<!`)`([^`]+)`(?!`)", "\n".join(prose)):
        span = " ".join(span.split())
        if re.match(r"(\.venv/bin/)?renderloop ", span):
            for part in re.split(r"&&|;|\|", span):
                yield from _renderloop(where, part, complete=False)


def _renderloop(where: str, text: str, complete: bool):
    while re.search(r"\[[^\[\]]*\]", text):  # [--optional parts], nested too, are the reader's choice
        text = re.sub(r"\[[^\[\]]*\]", " ", text)
    words = text.split()
    if words and words[0] in ("renderloop", ".venv/bin/renderloop"):
        # `--mirror/--no-mirror` names a flag and its opposite: both must parse
        for side in (0, 1):
            yield where, [word.split("/")[side] if re.fullmatch(r"--[\w-]+/--[\w-]+", word) else word
                          for word in words[1:]], complete


PLACEHOLDER = re.compile(r"[A-Z][A-Z0-9_]*")  # DIR, N, S, SHARE: a value the reader chooses


@functools.cache
def cli_command():
    """The CLI as one click group, built once: building it takes longer than parsing a command with it."""
    import typer.main

    from renderloop.cli import app

    return typer.main.get_command(app)


def parse_failure(argv: list[str], complete: bool) -> str | None:
    """Why the real CLI refuses `argv`, or None; it resolves the verb and parses its options without running it.

    An option whose value is a placeholder (`--seed S`) must exist, and its value is the reader's.
    """
    from typer._click.exceptions import BadOptionUsage, MissingParameter  # typer carries its own click
    from typer.exceptions import Exit, TyperException

    from renderloop.errors import UserError

    group = cli_command()
    try:
        with group.make_context("renderloop", list(argv), resilient_parsing=False) as context:
            # click keeps the verb and what follows it for Group.invoke, which would run it
            name, verb, rest = group.resolve_command(context, [*context._protected_args, *context.args])
            if "--help" in rest:  # the verb prints its help and exits before anything else is checked
                return None
            options = {option for param in verb.params if param.param_type_name == "option" and not param.is_flag
                       for option in param.opts}
            kept = []
            for word in rest:
                if kept and kept[-1] in options and PLACEHOLDER.fullmatch(word):
                    kept.pop()
                elif not (word.partition("=")[0] in options and PLACEHOLDER.fullmatch(word.partition("=")[2])):
                    kept.append(word)
            verb.make_context(name, kept, parent=context, resilient_parsing=False)
    except MissingParameter as error:
        return error.format_message() if complete else None
    except BadOptionUsage as error:  # `renderloop train --photos` in prose names the option, its value follows
        return None if not complete and argv[-1].startswith("--") and "requires an argument" in error.format_message() \
            else error.format_message()
    except Exit:  # `renderloop --help`, `--version`
        return None
    except TyperException as error:
        return error.format_message()
    except UserError as error:  # an option's own check: an unknown backbone, executor, mission
        return str(error)
    return None


def documented_commands():
    return [command for path in COMMAND_PAGES for command in page_commands(path)]


def test_the_pages_show_their_renderloop_commands():
    commands = documented_commands()
    assert len(commands) > 50
    pages = {where for where, _, _ in commands}
    assert {"README.md", "docs/getting-started.md", "src/renderloop/perception/model/MODEL_CARD.md"} <= pages


def test_every_renderloop_command_in_the_docs_parses_with_the_cli():
    problems = []
    for where, argv, complete in documented_commands():
        failure = parse_failure(argv, complete)
        if failure:
            problems.append(f"{where}: renderloop {' '.join(argv)}: {failure}")
    assert not problems, "\n".join(problems)


def test_a_command_the_cli_would_refuse_is_caught():
    assert parse_failure(["eval", "--preset", "paper", "--seedz", "0-4", "--out", "runs/x"], True)
    assert parse_failure(["plan"], True)  # no run directory
    assert parse_failure(["plan"], False) is None  # an inline mention of the verb
    assert parse_failure(["fly", "runs/x", "--force"], True) is None
    assert parse_failure(["frobnicate", "runs/x"], True)
    assert parse_failure(["scene", "--preset", "paper", "--seed", "S", "--out", "runs/x"], True) is None  # S: the reader's
    assert parse_failure(["scene", "--sede", "S", "--out", "runs/x"], True)
    assert parse_failure(["scene", "--help"], True) is None
    assert parse_failure(["train", "--backbone", "resnet", "--out", "m.onnx"], True)  # the option's own check


def test_every_config_file_a_docs_command_names_is_in_the_repository():
    problems = []
    for where, argv, _ in documented_commands():
        for index, word in enumerate(argv):
            name = argv[index + 1] if word == "--config" and index + 1 < len(argv) else word.partition("=")[2] \
                if word.startswith("--config=") else None
            if name and name not in READER_WRITTEN and not (ROOT / name).is_file():
                problems.append(f"{where}: renderloop {' '.join(argv)}: no file {name} in the repository")
    assert not problems, "\n".join(problems)


def test_every_benchmark_config_is_one_the_docs_name():
    pages = "\n".join(path.read_text(encoding="utf-8") for path in COMMAND_PAGES)
    shipped = sorted(path.relative_to(ROOT).as_posix() for path in (ROOT / "benchmarks" / "configs").glob("*.yaml"))
    unused = [name for name in shipped if name not in pages]
    assert shipped and not unused, f"configs no page uses: {unused}"


@pytest.mark.parametrize("path", sorted((ROOT / "benchmarks" / "configs").glob("*.yaml")), ids=lambda path: path.name)
def test_every_benchmark_config_is_a_valid_override_of_the_paper_preset(path):
    from renderloop.config import load_config

    default = load_config("paper")
    config = load_config("paper", path)
    assert config != default  # it changes something, and validates


# The pages say what is, not how it came to be: history is in CHANGELOG.md and the model card -------------------------

# Every page but the model card's (the detector's training log, history by design) and the changelog.
PRESENT_TENSE_PAGES = ["README.md"] + sorted(
    str(path.relative_to(ROOT)) for path in (ROOT / "docs").rglob("*.md") if path.name != "model-card.md")
HISTORY = re.compile(r"\b2026-|\bissues?\b|\bthe model before\b|\bsince\b", re.IGNORECASE)


def written_text(page: str) -> str:
    """The page as its authors write it: the README's blocks rendered from the results (with the date each figure
    was measured, its provenance) left out, their templates kept."""
    text = (ROOT / page).read_text(encoding="utf-8")
    text = results_hook.README_TEMPLATE.sub(lambda m: m.group(1) + m.group(5), text)
    return results_hook.README_TABLE.sub(lambda m: m.group(1) + m.group(5), text)


def test_the_pages_describe_the_present_without_dates_or_issues():
    problems = []
    for page in PRESENT_TENSE_PAGES:
        for number, line in enumerate(written_text(page).splitlines(), start=1):
            for match in HISTORY.finditer(line):
                problems.append(f"{page}:{number}: `{match.group(0)}`: {line.strip()}")
    assert not problems, "history belongs in CHANGELOG.md or the model card:\n" + "\n".join(problems)
