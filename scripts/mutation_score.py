#!/usr/bin/env python3
"""Sampled mutation testing of one module, in a private copy of the repository.

mutmut 3 rewrites a whole tree into ``mutants/`` and expects a flat layout; iamp's package
reaches ``planners/``, ``prediction/`` and ``compare/`` through symlinks, so this script does
the same job directly and never touches the working tree:

1. export the committed tree (``git archive HEAD``) to a temporary folder;
2. enumerate mutation points of FILE with :mod:`ast` — comparison operators
   (``<``/``<=``, ``>``/``>=``, ``==``/``!=``), arithmetic (``+``/``-``, ``*``/``/``),
   ``and``/``or``, numeric constants (``c -> c*1000 + 1`` and ``c -> -c``), ``not x -> x``,
   subscripts ``x[0] -> x[1]`` and ``min``/``max`` swaps;
3. draw ``--sample`` of them with ``--seed``, apply one at a time, run the given tests
   (``pytest -x -q``) in the copy with a timeout, and count *killed* (tests fail or time out)
   and *survived*;
4. print every survivor (line and the mutated source line) and the score.

Usage::

    python scripts/mutation_score.py compare/agreement.py --tests tests/test_compare.py \
        --sample 40 --seed 1 [--timeout 300] [-k EXPR] [--lines A-B]

The copy is run with ``python -m pytest`` from its root, so ``import iamp`` resolves to the
copy (the current directory precedes the editable install on ``sys.path``).
"""

from __future__ import annotations

import argparse
import ast
import random
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

SWAP_CMP = {ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt, ast.Eq: ast.NotEq,
            ast.NotEq: ast.Eq}
SWAP_BIN = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult}


@dataclass(frozen=True)
class Mutation:
    """One mutation: the ``index``-th node of kind ``kind`` in walk order, and its line."""

    kind: str
    index: int
    variant: int
    line: int


def _points(tree: ast.AST) -> list[Mutation]:
    out: list[Mutation] = []
    counters: dict[str, int] = {}

    def add(kind: str, node: ast.AST, variants: int = 1) -> None:
        i = counters.get(kind, 0)
        counters[kind] = i + 1
        for v in range(variants):
            out.append(Mutation(kind, i, v, getattr(node, "lineno", 0)))

    for node in ast.walk(tree):
        if isinstance(node, ast.Compare) and type(node.ops[0]) in SWAP_CMP:
            add("cmp", node)
        elif isinstance(node, ast.BinOp) and type(node.op) in SWAP_BIN:
            add("bin", node)
        elif isinstance(node, ast.BoolOp):
            add("bool", node)
        elif isinstance(node, ast.Constant) and type(node.value) in (int, float) and not isinstance(node.value, bool):
            add("num", node, 2)
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            add("not", node)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("min", "max"):
            add("minmax", node)
    return out


def _mutate(tree: ast.Module, m: Mutation) -> ast.Module:
    """Apply ``m`` by walking in :func:`ast.walk` order (breadth first), as :func:`_points` did."""
    counters: dict[str, int] = {}

    def hit(kind: str) -> bool:
        i = counters.get(kind, 0)
        counters[kind] = i + 1
        return kind == m.kind and i == m.index

    for node in ast.walk(tree):
        if isinstance(node, ast.Compare) and type(node.ops[0]) in SWAP_CMP:
            if hit("cmp"):
                node.ops[0] = SWAP_CMP[type(node.ops[0])]()
        elif isinstance(node, ast.BinOp) and type(node.op) in SWAP_BIN:
            if hit("bin"):
                node.op = SWAP_BIN[type(node.op)]()
        elif isinstance(node, ast.BoolOp):
            if hit("bool"):
                node.op = ast.Or() if isinstance(node.op, ast.And) else ast.And()
        elif isinstance(node, ast.Constant) and type(node.value) in (int, float) and not isinstance(node.value, bool):
            if hit("num"):
                node.value = node.value * 1000 + 1 if m.variant == 0 else -node.value
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
            if hit("not"):
                node.op = ast.UAdd()  # `+x` keeps x's truth value: the `not` is removed
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("min", "max"):
            if hit("minmax"):
                node.func.id = "max" if node.func.id == "min" else "min"
    return tree


def _copy_repo(src: Path, dst: Path) -> None:
    """The committed tree (``HEAD``), so that work in progress in the checkout cannot leak in."""
    archive = subprocess.run(["git", "archive", "--format=tar", "HEAD"], cwd=src, capture_output=True, check=True)
    subprocess.run(["tar", "-x", "-C", str(dst)], input=archive.stdout, check=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file", help="module to mutate, relative to the repository root (e.g. compare/agreement.py)")
    ap.add_argument("--tests", nargs="+", required=True, help="test files or node ids to run")
    ap.add_argument("--sample", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=300.0)
    ap.add_argument("-k", default=None, help="pytest -k expression")
    ap.add_argument("--lines", default=None, metavar="A-B",
                    help="mutate only the points on lines A..B of FILE (e.g. the function a change touched)")
    args = ap.parse_args(argv)
    root = Path(subprocess.run(["git", "rev-parse", "--show-toplevel"], capture_output=True, text=True,
                               check=True).stdout.strip())
    source = subprocess.run(["git", "show", f"HEAD:{args.file}"], cwd=root, capture_output=True, text=True,
                            check=True).stdout
    points = _points(ast.parse(source))
    if args.lines:
        a, b = (int(x) for x in args.lines.split("-"))
        points = [p for p in points if a <= p.line <= b]
    rng = random.Random(args.seed)
    chosen = rng.sample(points, min(args.sample, len(points)))
    lines = source.splitlines()
    with tempfile.TemporaryDirectory(prefix="iamp-mut-") as tmp:
        work = Path(tmp)
        _copy_repo(root, work)
        target = work / args.file
        cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *args.tests]
        if args.k:
            cmd += ["-k", args.k]
        base = subprocess.run(cmd, cwd=work, capture_output=True, text=True, timeout=args.timeout * 3)
        if base.returncode != 0:
            print("the tests fail on the unmutated code; fix them first:\n" + base.stdout[-2000:])
            return 2
        killed, survivors = 0, []
        for k, m in enumerate(chosen, 1):
            mutated = ast.unparse(_mutate(ast.parse(source), m))
            if mutated == ast.unparse(ast.parse(source)):
                continue
            target.write_text(mutated, encoding="utf-8")
            try:
                r = subprocess.run(cmd, cwd=work, capture_output=True, text=True, timeout=args.timeout)
                dead = r.returncode != 0
            except subprocess.TimeoutExpired:
                dead = True
            finally:
                target.write_text(source, encoding="utf-8")
            killed += dead
            if not dead:
                survivors.append(m)
            print(f"[{k}/{len(chosen)}] {m.kind}#{m.index}.{m.variant} line {m.line}: "
                  f"{'killed' if dead else 'SURVIVED'}", flush=True)
    total = killed + len(survivors)
    for m in survivors:
        print(f"survivor: {args.file}:{m.line} {m.kind} (variant {m.variant}): {lines[m.line - 1].strip()}")
    print(f"mutation score {killed}/{total} = {100.0 * killed / max(total, 1):.1f} % "
          f"({args.file}, sample {args.sample}, seed {args.seed})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
