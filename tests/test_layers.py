"""The packages of renderloop stand in layers, and a module imports only its own package and the layers below
(docs/design.md). Every import counts, at module level or inside a function, except `from __future__` and those
under `if TYPE_CHECKING:`, which never run."""

from __future__ import annotations

import ast
from pathlib import Path

SOURCE = Path(__file__).resolve().parents[1] / "src" / "renderloop"

# Bottom to top; the packages of one layer import none of each other. A top-level module counts as a package, and
# "__init__" is renderloop itself (its version and its public API, imported on first use).
LAYERS = [
    ["errors", "presets"],
    ["io"],
    ["config"],
    ["parallel"],
    ["rundir"],
    ["robot"],
    ["scene", "control"],
    ["planning"],
    ["sim"],
    ["render"],
    ["perception"],
    ["counting"],
    ["loop"],
    ["__init__", "pipeline"],
    ["dataset", "evaluation", "export", "report"],
    ["fleet"],
    ["cli"],
    ["__main__"],
]
LAYER = {package: rank for rank, packages in enumerate(LAYERS) for package in packages}


def _module(path: Path) -> tuple[str, bool]:
    """The dotted name of a source file, and whether it is a package's __init__."""
    parts = list(path.relative_to(SOURCE.parent).with_suffix("").parts)
    is_package = parts[-1] == "__init__"
    return ".".join(parts[:-1] if is_package else parts), is_package


def _package(module: str) -> str:
    """The package (or top-level module) of renderloop that `module` belongs to, "__init__" for renderloop itself."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return isinstance(test, ast.Name) and test.id == "TYPE_CHECKING" or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST, module: str, is_package: bool) -> list[tuple[str, int]]:
    """Every module imported in `tree` that runs, with its line."""
    found = []

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _type_checking(child):
                for branch in child.orelse:
                    visit_node(branch)
            else:
                visit_node(child)

    def visit_node(node: ast.AST) -> None:
        if isinstance(node, ast.Import):
            found.extend((alias.name, node.lineno) for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module != "__future__":
            if node.level:
                base = module.split(".")[: len(module.split(".")) - node.level + is_package]
                found.append((".".join(base + ([node.module] if node.module else [])), node.lineno))
            else:
                found.append((node.module, node.lineno))
        visit(node)

    visit(tree)
    return found


def _graph() -> list[tuple[str, int, str]]:
    """(importing module, line, imported module) for every import of renderloop by a module of a package."""
    edges = []
    for path in sorted(SOURCE.rglob("*.py")):
        module, is_package = _module(path)
        for imported, line in _imports(ast.parse(path.read_text(encoding="utf-8")), module, is_package):
            if imported == "renderloop" or imported.startswith("renderloop."):
                edges.append((module, line, imported))
    return edges


def test_every_package_has_a_place_in_the_layers():
    packages = {_package(_module(path)[0]) for path in SOURCE.rglob("*.py")}
    assert packages <= set(LAYER), f"place {sorted(packages - set(LAYER))} in LAYERS here and in docs/design.md"


def test_no_module_imports_a_package_above_its_own_or_beside_it():
    wrong = [f"{module}:{line} imports {imported} ({_package(module)} is below or beside {_package(imported)})"
             for module, line, imported in _graph()
             if _package(imported) != _package(module) and LAYER[_package(imported)] >= LAYER[_package(module)]]
    assert not wrong, "\n".join(wrong)


def test_a_packages_stage_module_is_imported_by_none_of_its_own_modules():
    """A stage's `stage.py` is its file handling, on top of its package: the package's other modules hold the work it
    calls and never reach back for anything of it."""
    wrong = [f"{module}:{line} imports {imported}" for module, line, imported in _graph()
             if imported.endswith(".stage") and imported != module and imported.rsplit(".", 1)[0] == module.rsplit(".", 1)[0]]
    assert not wrong, "\n".join(wrong)


def test_the_graph_sees_function_level_imports_and_skips_type_checking_ones():
    tree = ast.parse("from __future__ import annotations\nfrom typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                     "    from renderloop.cli import main\ndef f():\n    from . import names\n    import renderloop.loop\n")
    assert _imports(tree, "renderloop.rundir.files", False) == [
        ("typing", 2), ("renderloop.rundir", 6), ("renderloop.loop", 7)]
