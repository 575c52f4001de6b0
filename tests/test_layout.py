"""The house (issue 17): the import graph read from the source has no circle, the pipeline
never imports the tools, the shells or the GUI, docs/design.md shows the graph as it is, and
modules and functions stay small. The layer contracts themselves are import-linter's
(pyproject.toml, `make lint`)."""

import ast
import re
from pathlib import Path

from clsonar.tools import imports

ROOT = Path(__file__).resolve().parents[1]

#: Above the pipeline: what may use it, never the other way round.
SHELLS = ("clsonar.gui", "clsonar.cli", "clsonar.tools", "clsonar.outputs", "clsonar.drawing",
          "clsonar.plots", "clsonar.__main__")

MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 60


def _in(module: str, parts: tuple[str, ...]) -> bool:
    return any(module == p or module.startswith(p + ".") for p in parts)


def test_the_import_graph_has_no_circle():
    edges = imports.graph()
    assert {"clsonar.pipeline", "clsonar.gui.app", "clsonar.tools.bench"} <= edges.keys()
    assert imports.cycles(edges) == []


def test_a_circle_is_found():
    assert imports.cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_the_pipeline_imports_no_tool_shell_or_gui():
    for module, targets in imports.graph().items():
        if module == "clsonar" or _in(module, SHELLS):
            continue
        assert not [t for t in targets if _in(t, SHELLS)], module


def test_design_md_shows_the_graph_of_the_parts_as_it_is():
    text = (ROOT / "docs" / "design.md").read_text()
    shown = re.search(r"```mermaid\n(.*?)\n```", text, re.S).group(1)
    assert shown == imports.mermaid(imports.parts_graph(imports.graph())), (
        "regenerate: python -m clsonar.tools.imports --parts")


def test_modules_and_functions_are_small():
    too_long = []
    for module, path in imports.modules().items():
        text = path.read_text(encoding="utf-8")
        if len(text.splitlines()) > MAX_MODULE_LINES:
            too_long.append(f"{module}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = node.end_lineno - node.lineno + 1
                if length > MAX_FUNCTION_LINES:
                    too_long.append(f"{module}.{node.name}: {length} lines")
    assert too_long == []


def test_no_file_outside_the_repository_is_cited():
    """The code and docs cite docs/design.md, not a design file outside the repository."""
    cited = [str(p.relative_to(ROOT)) for folder in ("clsonar", "gui", "tests", "docs")
             for p in (ROOT / folder).rglob("*") if p.suffix in (".py", ".md")
             and p.name != "test_layout.py" and "DESIGN.md" in p.read_text(encoding="utf-8")]
    assert cited == []
