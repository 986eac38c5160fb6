"""Sampled mutation testing of one module, on a private copy of the tree.

mutmut 3 copies the project into ``mutants/`` and trampolines every function; with the
``iamp/planners -> ../planners`` symlinks of this layout that is awkward, and mutating the
shared working tree in place would hand mutated code to everyone else's test runs.  This
script instead

1. copies ``iamp/``, ``planners/``, ``prediction/``, ``compare/``, ``tests/`` and
   ``pyproject.toml`` to ``--workdir`` (symlinks kept, so ``iamp.planners`` resolves inside
   the copy when pytest runs there);
2. lists every mutation point of ``--file`` in its AST: arithmetic operator swaps
   (``+ ↔ -``, ``* ↔ /``, ``** → *``), comparison swaps (``< ↔ <=``, ``> ↔ >=``,
   ``== ↔ !=``), ``and ↔ or``, dropped unary minus, and numeric constants (``0 → 1``,
   ``c → c + 1``, ``c → −c``);
3. samples ``--sample`` of them (``--seed``), writes each mutant (``ast.unparse``) into the
   copy, runs ``python -m pytest -x -q <tests>`` there with a timeout, and restores the file;
4. prints a JSON report: killed, survived (with line and mutation), timeouts, the score.

A mutant is *killed* if the tests fail or time out.  The unmutated ``ast.unparse`` of the
file is run first and must pass.

Usage::

    python scripts/mutate.py --file planners/pmp/roots.py --tests tests/test_pmp_fast.py \\
        --sample 40 --seed 0 [--workdir /tmp/iamp-mutate] [--timeout 300] [-m "not slow"]
"""

from __future__ import annotations

import argparse
import ast
import copy
import json
import random
import shutil
import subprocess
import sys
import time
from pathlib import Path

SWAP_BIN = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult, ast.Pow: ast.Mult}
SWAP_CMP = {ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt, ast.Eq: ast.NotEq,
            ast.NotEq: ast.Eq}


def mutation_points(tree: ast.AST) -> list[tuple[int, str, int]]:
    """``(node index, kind, line)`` of every mutation; docstrings are left alone."""
    doc_ids = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                doc_ids.add(id(first.value))
    points = []
    for k, node in enumerate(ast.walk(tree)):
        line = getattr(node, "lineno", 0)
        if isinstance(node, ast.BinOp) and type(node.op) in SWAP_BIN:
            points.append((k, "binop", line))
        elif isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in SWAP_CMP:
            points.append((k, "compare", line))
        elif isinstance(node, ast.BoolOp):
            points.append((k, "boolop", line))
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            points.append((k, "neg", line))
        elif (isinstance(node, ast.Constant) and id(node) not in doc_ids and isinstance(node.value, (int, float))
              and not isinstance(node.value, bool)):
            points.append((k, "const+1", line))
            if node.value != 0:
                points.append((k, "const-neg", line))
    return points


def apply(tree: ast.AST, index: int, kind: str) -> tuple[ast.AST, str]:
    """A mutated copy of ``tree`` and a description."""
    new = copy.deepcopy(tree)
    node = list(ast.walk(new))[index]
    if kind == "binop":
        old = type(node.op).__name__
        node.op = SWAP_BIN[type(node.op)]()
        return new, f"{old} -> {type(node.op).__name__}"
    if kind == "compare":
        old = type(node.ops[0]).__name__
        node.ops = [SWAP_CMP[type(node.ops[0])]()]
        return new, f"{old} -> {type(node.ops[0]).__name__}"
    if kind == "boolop":
        old = type(node.op).__name__
        node.op = ast.Or() if isinstance(node.op, ast.And) else ast.And()
        return new, f"{old} -> {type(node.op).__name__}"
    if kind == "neg":
        parent = next(p for p in ast.walk(new) for c in ast.iter_child_nodes(p) if c is node)
        for field, value in ast.iter_fields(parent):
            if value is node:
                setattr(parent, field, node.operand)
            elif isinstance(value, list):
                setattr(parent, field, [node.operand if v is node else v for v in value])
        return new, "drop unary minus"
    old_value = node.value
    node.value = (1 if old_value == 0 else old_value + 1) if kind == "const+1" else -old_value
    return new, f"{old_value!r} -> {node.value!r}"


def run_tests(workdir: Path, tests: list[str], marker: str | None, timeout: float) -> str:
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests]
    if marker:
        cmd += ["-m", marker]
    try:
        proc = subprocess.run(cmd, cwd=workdir, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout"
    return "passed" if proc.returncode == 0 else "failed"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--file", required=True)
    ap.add_argument("--tests", nargs="+", required=True)
    ap.add_argument("--sample", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workdir", default="/tmp/iamp-mutate")
    ap.add_argument("--timeout", type=float, default=300.0)
    ap.add_argument("-m", dest="marker", default="not slow")
    args = ap.parse_args()
    root = Path(__file__).resolve().parents[1]
    work = Path(args.workdir)
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    for name in ("iamp", "planners", "prediction", "compare", "tests", "simulation"):
        if (root / name).exists():
            shutil.copytree(root / name, work / name, symlinks=True,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    shutil.copy2(root / "pyproject.toml", work / "pyproject.toml")
    target = work / args.file
    source = target.read_text()
    tree = ast.parse(source)
    target.write_text(ast.unparse(tree) + "\n")
    if run_tests(work, args.tests, args.marker, args.timeout) != "passed":
        print(json.dumps({"error": "the unmutated file does not pass the tests"}))
        return 1
    points = mutation_points(tree)
    rng = random.Random(args.seed)
    chosen = rng.sample(points, min(args.sample, len(points)))
    report: dict[str, list[dict[str, object]]] = {"killed": [], "survived": [], "timeout": []}
    t0 = time.time()
    for index, kind, line in chosen:
        mutant, desc = apply(tree, index, kind)
        try:
            target.write_text(ast.unparse(ast.fix_missing_locations(mutant)) + "\n")
        except Exception as exc:  # an unparsable mutant counts as killed (it cannot run)
            report["killed"].append({"line": line, "mutation": desc, "note": repr(exc)})
            continue
        outcome = run_tests(work, args.tests, args.marker, args.timeout)
        entry = {"line": line, "mutation": desc}
        report["survived" if outcome == "passed" else ("timeout" if outcome == "timeout" else "killed")].append(entry)
    target.write_text(source)
    n = len(chosen)
    killed = len(report["killed"]) + len(report["timeout"])
    print(json.dumps({"file": args.file, "tests": args.tests, "points": len(points), "sampled": n, "seed": args.seed,
                      "killed": killed, "survived": len(report["survived"]),
                      "score": killed / n if n else None, "seconds": round(time.time() - t0, 1),
                      "survivors": report["survived"]}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
