"""Counts that describe the shape of a checkout (issue 18's closing note), for a before/after table.

Usage (the tree's ``iamp`` must be importable: run with ``PYTHONPATH=TREE`` and ``grimp`` installed,
e.g. from the ``[test]`` extra's import-linter)::

    PYTHONPATH=TREE python scripts/architecture_counts.py TREE

Prints, as JSON:

* ``modules``: ``.py`` files per top-level folder and per sub-package (symlinks not followed);
* ``any``: occurrences of the word ``Any`` in those files (``grep -rwo Any | wc -l``);
* ``dict_any_returns``: functions annotated ``-> dict[str, Any]``;
* ``function_level_imports``: ``import`` statements indented inside a function;
* ``cycles``: import cycles, as strongly connected components (more than one module) of the module
  graph that grimp builds (every import, function-level ones included, ``TYPE_CHECKING`` ones not),
  and the number of modules in them.
"""

from __future__ import annotations

import json
import re
import sys
from collections import Counter
from pathlib import Path

FOLDERS = ("iamp", "planners", "prediction", "compare", "simulation")


def py_files(tree: Path) -> list[Path]:
    out = []
    for top in FOLDERS:
        base = tree / top
        if not base.is_dir():
            continue
        for p in base.rglob("*.py"):
            rel = p.relative_to(tree)
            if any((tree / Path(*rel.parts[:i])).is_symlink() for i in range(1, len(rel.parts) + 1)):
                continue  # iamp/planners -> ../planners: counted once, under planners/
            out.append(p)
    return sorted(out)


def sccs(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components (iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    counter = 0
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in graph:
                    continue
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    out.append(sorted(comp))
    return out


def main() -> int:
    tree = Path(sys.argv[1]).resolve()
    files = py_files(tree)
    per_dir = Counter(str(p.parent.relative_to(tree)) for p in files)
    text = {p: p.read_text(encoding="utf-8") for p in files}
    any_count = sum(len(re.findall(r"\bAny\b", t)) for t in text.values())
    dict_any = sum(len(re.findall(r"->\s*dict\[str,\s*Any\]\s*:", t)) for t in text.values())
    fn_imports = sum(len(re.findall(r"^[ \t]+(?:from [\w.]+ import|import [\w.]+)", t, flags=re.M))
                     for t in text.values())
    import grimp

    g = grimp.build_graph("iamp", exclude_type_checking_imports=True)
    graph = {m: set(g.find_modules_directly_imported_by(m)) for m in g.modules}
    cyc = [c for c in sccs(graph) if len(c) > 1]
    print(json.dumps({"tree": str(tree), "modules": dict(sorted(per_dir.items())), "modules_total": len(files),
                      "any": any_count, "dict_any_returns": dict_any, "function_level_imports": fn_imports,
                      "cycles": len(cyc), "modules_in_cycles": sum(map(len, cyc)),
                      "cycle_members": cyc}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
