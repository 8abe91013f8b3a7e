"""The project's import graph: its circles (strongly connected groups of modules), counting every
import, also those inside functions and under `TYPE_CHECKING`, and `sys.path` edits.

    python -m bench.imports            # the circles, then one line of counts
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

PACKAGES = ("app", "sim", "models", "robot_client", "bench")


def modules(root: Path) -> dict[str, Path]:
    found = {}
    for package in PACKAGES:
        for path in (root / package).rglob("*.py"):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            found[".".join(parts)] = path
    return found


def imports(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The project's modules `name` imports (a name imported from a package counts as its
    submodule where there is one)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([base] if base else []))
            targets = [f"{base}.{alias.name}" for alias in node.names] + [base]
        else:
            continue
        for target in targets:
            while target and target not in known:
                target = target.rpartition(".")[0]
            if target and target != name:
                out.add(target)
    return out


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components with more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []
    sys.setrecursionlimit(10_000)

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def main() -> None:
    root = Path(__file__).resolve().parent.parent
    known = modules(root)
    graph = {name: imports(name, path, known) for name, path in known.items()}
    # A package's __init__ importing its own submodules is not a circle of design.
    graph = {n: {m for m in deps if not m.startswith(n + ".")} for n, deps in graph.items()}
    found = circles(graph)
    for group in found:
        print(" <-> ".join(group))
    path_edits = sum("sys.path" in p.read_text() for n, p in known.items() if n != "bench.imports")
    print(f"circles {len(found)}  modules in them {sum(map(len, found))}  sys.path edits {path_edits}")


if __name__ == "__main__":
    main()
