"""The documentation builds, strictly, and nothing in the package points at a document the repository lacks.

`mkdocs build --strict` fails on any warning: a broken link or anchor, a page missing from
the nav, a docstring mkdocstrings cannot find, a generated table whose hook failed, or a run
file that `renderloop.rundir.names` spells but docs/run-directory.md never describes
(docs/hooks/run_directory.py). About 15 s: the hooks import the package to read its models.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

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
    assert "ssdlite320_mobilenet_v3_large" in (site / "model-card" / "index.html").read_text(encoding="utf-8")


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
