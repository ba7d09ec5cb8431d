#!/usr/bin/env python3
# Copyright 2026 rotor_estimator developers
# SPDX-License-Identifier: Apache-2.0
"""Report import cycles and private names imported across modules in the package tree.

    python tools/import_graph.py      # exit 1 when there is a cycle or a private cross-module import

Reads the source (no import is executed). Module-level imports form the graph; an import inside a
function is listed apart (a late import is how a cycle gets patched, so it counts too).
"""
from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("rotor_estimator", "msg_adapters")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}


def imports(path: Path, name: str, known: set[str]):
    """(imported module, imported names, at module level?) for every project import in ``path``."""
    tree = ast.parse(path.read_text(), str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    top_level = {id(n) for n in tree.body}
    top_level |= {id(c) for n in tree.body if isinstance(n, (ast.If, ast.Try)) for c in ast.walk(n)}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            if base.split(".")[0] not in PACKAGES:
                continue
            for alias in node.names:
                target = f"{base}.{alias.name}"
                if target in known:
                    yield target, [], id(node) in top_level
                else:
                    yield base, [alias.name], id(node) in top_level
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] in PACKAGES:
                    yield alias.name, [], id(node) in top_level


def find_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def ancestors(module: str) -> list[str]:
    parts = module.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def main() -> int:
    mods = modules()
    known = set(mods)
    graph: dict[str, set[str]] = {m: set() for m in mods}
    late: dict[str, set[str]] = {m: set() for m in mods}
    private = []
    for name, path in mods.items():
        for target, names, module_level in imports(path, name, known):
            if target not in known:
                continue
            # importing a.b.c runs a and a.b first: a package's __init__ counts as imported too
            for dep in [a for a in ancestors(target) if a in known and a not in ancestors(name) + [name]] + [target]:
                if dep != name:
                    (graph if module_level else late)[name].add(dep)
            private += [f"{name} imports {target}.{n}" for n in names if n.startswith("_") and not n.startswith("__")]
            importer_package = name if path.name == "__init__.py" else name.rpartition(".")[0]
            if target.rpartition(".")[2].startswith("_") and target.rpartition(".")[0] != importer_package:
                private.append(f"{name} imports the private module {target}")
    full = {m: graph[m] | late[m] for m in mods}
    cycles = find_cycles(full)
    for comp in cycles:
        print("import cycle:", " <-> ".join(comp))
    for line in private:
        print("private name across modules:", line)
    print(f"{len(mods)} modules, {len(cycles)} import cycles, {len(private)} private cross-module imports")
    return 1 if cycles or private else 0


if __name__ == "__main__":
    sys.exit(main())
