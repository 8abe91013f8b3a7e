"""The project's import graph: its circles (strongly connected groups of modules), counting every
import, also those inside functions and under `TYPE_CHECKING`, and `sys.path` edits.

    python -m bench.imports            # the circles, then one line of counts
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
from scipy.sparse import csr_array
from scipy.sparse.csgraph import connected_components

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
    """The strongly connected groups of more than one module, each sorted, in order."""
    names = sorted(graph)
    at = {name: i for i, name in enumerate(names)}
    edges = np.array([(at[a], at[b]) for a in names for b in graph[a]], dtype=np.int64).reshape(-1, 2)
    matrix = csr_array((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(len(names), len(names)))
    _, labels = connected_components(matrix, directed=True, connection="strong")
    groups = [[n for n, label in zip(names, labels) if label == k] for k in range(labels.max(initial=-1) + 1)]
    return sorted(group for group in groups if len(group) > 1)


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
