"""The import graph of clsonar, read from its source: every ``import`` of every module, lazy
ones inside functions included, resolved to modules of the package.

``python -m clsonar.tools.imports [--parts]`` prints it as a Mermaid graph (``--parts``: one
node per stage module or subpackage, as docs/design.md shows it) and exits 1 if any module
imports itself through others (a circle). tests/test_layout.py asserts there is none; the
import contracts of pyproject.toml (import-linter) say which way the edges may go.

The GUI's sources live in the top-level ``gui/`` folder and are installed as
``clsonar.gui``; they are read from there.
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: Where each part of the installed package has its sources (pyproject.toml's package-dir).
SOURCES = {"clsonar": ROOT / "clsonar", "clsonar.gui": ROOT / "gui"}


def modules() -> dict[str, Path]:
    """Every module of the package: dotted name → source file (``__init__.py`` for a
    package)."""
    found: dict[str, Path] = {}
    for prefix, folder in SOURCES.items():
        for path in sorted(folder.rglob("*.py")):
            parts = path.relative_to(folder).with_suffix("").parts
            if prefix == "clsonar" and parts[0] == "gui":
                continue
            if parts[-1] == "__init__":
                parts = parts[:-1]
            found[".".join((prefix, *parts))] = path
    return found


def _imported(tree: ast.AST, name: str, is_package: bool, known: set[str]
              ) -> Iterator[str]:
    """The modules of ``known`` that module ``name`` imports: ``from X import y`` imports
    the submodule X.y where there is one, else X itself (as import-linter reads it)."""
    package = name if is_package else name.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names if a.name in known)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[:len(anchor) - node.level + 1]
                base = ".".join([*anchor, base]) if base else ".".join(anchor)
            for a in node.names:
                sub = f"{base}.{a.name}"
                yield sub if sub in known else base


def graph() -> dict[str, set[str]]:
    """Module → the modules of the package it imports."""
    mods = modules()
    edges: dict[str, set[str]] = {}
    for name, path in mods.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        targets = set(_imported(tree, name, path.name == "__init__.py", set(mods)))
        edges[name] = (targets & mods.keys()) - {name}
    return edges


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan): each is a set
    of modules that import one another through a circle."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def part_of(module: str) -> str:
    """The part a module belongs to: its stage module or subpackage (``clsonar.mapping``
    for ``clsonar.mapping.tiles``)."""
    return ".".join(module.split(".")[:2])


def parts_graph(edges: dict[str, set[str]]) -> dict[str, set[str]]:
    """The graph with each module replaced by its part (imports within a part left out,
    and the root package, a facade over the rest, too)."""
    out: dict[str, set[str]] = {}
    for a, targets in edges.items():
        if a == "clsonar":
            continue
        out.setdefault(part_of(a), set()).update(
            part_of(b) for b in targets if part_of(b) != part_of(a) and b != "clsonar")
    return out


def mermaid(edges: dict[str, set[str]]) -> str:
    """A Mermaid flowchart of ``edges``, each arrow from the importer to the imported."""
    def node(name: str) -> str:
        return name.removeprefix("clsonar.").replace(".", "_")

    lines = ["flowchart TD"]
    for a in sorted(edges):
        lines += [f"    {node(a)} --> {node(b)}" for b in sorted(edges[a])]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m clsonar.tools.imports",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--parts", action="store_true",
                        help="one node per stage module or subpackage")
    args = parser.parse_args(argv)
    edges = graph()
    print(mermaid(parts_graph(edges) if args.parts else edges))
    circles = cycles(edges)
    for c in circles:
        print("circle:", " ".join(c), file=sys.stderr)
    return 1 if circles else 0


if __name__ == "__main__":
    sys.exit(main())
