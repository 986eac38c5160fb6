"""Rewrite imports of the old flat layout to the packages by concept (issue 18).

The table :data:`MOVES` maps every old dotted module to its new one.  The command::

    python scripts/restructure_imports.py FILE...

rewrites, in each given file, every dotted name that starts with an old module — absolute imports
(``from iamp.planners.pmp_fixed import X``, ``import iamp.planners.pmp_fixed as m``), the
``from iamp.planners import pmp_fixed`` form, and strings such as monkeypatch targets
(``"iamp.planners.pmp_fixed.foo"``).  It is idempotent: names that already start with a new module
are left alone, and so are lines marked ``# restructure: keep``.  ``--check`` only lists the files
it would change (exit 1 if any).
"""

from __future__ import annotations

import ast
import re
import sys
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_FOLDERS = {"iamp.planners": "planners", "iamp.prediction": "prediction", "iamp.comparison": "compare"}

MOVES: dict[str, str] = {
    # planners/pmp/
    "iamp.planners.pmp": "iamp.planners.pmp.planner",
    "iamp.planners.pmp_basin": "iamp.planners.pmp.basin",
    "iamp.planners.pmp_batch": "iamp.planners.pmp.batch",
    "iamp.planners.pmp_bound": "iamp.planners.pmp.bound",
    "iamp.planners.pmp_compiled": "iamp.planners.pmp.compiled",
    "iamp.planners.pmp_compiled_kernels": "iamp.planners.pmp.compiled_kernels",
    "iamp.planners.pmp_fixed": "iamp.planners.pmp.fixed",
    "iamp.planners.pmp_one": "iamp.planners.pmp.one",
    "iamp.planners.pmp_roots": "iamp.planners.pmp.roots",
    "iamp.planners.pmp_scale": "iamp.planners.pmp.scale",
    "iamp.planners.pmp_search": "iamp.planners.pmp.search",
    "iamp.planners.pmp_solution": "iamp.planners.pmp.solution",
    "iamp.planners.pmp_verify": "iamp.planners.pmp.verify",
    # planners/qp/ (with the backends)
    "iamp.planners.qp": "iamp.planners.qp.planner",
    "iamp.planners.qp_core": "iamp.planners.qp.core",
    "iamp.planners.qp_data": "iamp.planners.qp.data",
    "iamp.planners.sweep": "iamp.planners.qp.sweep",
    "iamp.planners.hold": "iamp.planners.qp.hold",
    "iamp.planners.backends": "iamp.planners.qp.backends",
    # branch limits (issue 19): the bounded equality QP's modules, moved into the package
    "iamp.planners.qp_limits": "iamp.planners.qp.limits",
    "iamp.planners.qp_bounded": "iamp.planners.qp.bounded",
    # planners/avoid/
    "iamp.planners.avoid": "iamp.planners.avoid.planner",
    "iamp.planners.avoid_check": "iamp.planners.avoid.check",
    "iamp.planners.avoid_data": "iamp.planners.avoid.data",
    "iamp.planners.avoid_pmp": "iamp.planners.avoid.pmp",
    "iamp.planners.avoid_result": "iamp.planners.avoid.result",
    "iamp.planners.avoid_search": "iamp.planners.avoid.search",
    "iamp.planners.avoid_solve": "iamp.planners.avoid.solve",
    # prediction/loaders/
    "iamp.prediction.loaders": "iamp.prediction.loaders.formats",
    "iamp.prediction.loaders_csv": "iamp.prediction.loaders.csv",
    "iamp.prediction.loaders_highd": "iamp.prediction.loaders.highd",
    "iamp.prediction.loaders_ngsim": "iamp.prediction.loaders.ngsim",
    "iamp.prediction.loaders_sumo": "iamp.prediction.loaders.sumo",
    "iamp.prediction.load_report": "iamp.prediction.loaders.report",
    # prediction/tracks/
    "iamp.prediction.tracks": "iamp.prediction.tracks.table",
    "iamp.prediction.tracks_io": "iamp.prediction.tracks.io",
    # prediction/mtd/ (mtd.py, the facade, is the package's __init__)
    "iamp.prediction.mtd_chain": "iamp.prediction.mtd.chain",
    "iamp.prediction.mtd_counts": "iamp.prediction.mtd.counts",
    "iamp.prediction.mtd_em": "iamp.prediction.mtd.em",
    "iamp.prediction.mtd_fit": "iamp.prediction.mtd.estimation",
    "iamp.prediction.mtd_io": "iamp.prediction.mtd.io",
    "iamp.prediction.mtd_model": "iamp.prediction.mtd.model",
    # prediction/evaluation/
    "iamp.prediction.evaluate": "iamp.prediction.evaluation.evaluate",
    "iamp.prediction.evaluate_data": "iamp.prediction.evaluation.data",
    "iamp.prediction.evaluate_report": "iamp.prediction.evaluation.report",
    "iamp.prediction.evaluate_select": "iamp.prediction.evaluation.select",
    "iamp.prediction.evaluate_user": "iamp.prediction.evaluation.user",
    "iamp.prediction.evaluate_windows": "iamp.prediction.evaluation.windows",
    # compare/report/
    "iamp.comparison.report": "iamp.comparison.report.reproduction",
    "iamp.comparison.report_campaign": "iamp.comparison.report.campaign",
    "iamp.comparison.report_config": "iamp.comparison.report.config",
    "iamp.comparison.report_convergence": "iamp.comparison.report.convergence",
    "iamp.comparison.report_document": "iamp.comparison.report.document",
    "iamp.comparison.report_predictor": "iamp.comparison.report.predictor",
    "iamp.comparison.report_scenarios": "iamp.comparison.report.scenarios",
    "iamp.comparison.report_tables": "iamp.comparison.report.tables",
    "iamp.comparison.report_tex": "iamp.comparison.report.tex",
    "iamp.comparison.report_timing": "iamp.comparison.report.timing",
    "iamp.comparison.latex": "iamp.comparison.report.latex",
    "iamp.comparison.paper": "iamp.comparison.report.paper",
    # compare/figures/
    "iamp.comparison.figures": "iamp.comparison.figures.style",
    "iamp.comparison.figures_comparison": "iamp.comparison.figures.comparison",
    "iamp.comparison.figures_safety": "iamp.comparison.figures.safety",
    "iamp.comparison.figures_studies": "iamp.comparison.figures.studies",
    "iamp.comparison.figures_trajectory": "iamp.comparison.figures.trajectory",
    # compare/bench/
    "iamp.comparison.bench": "iamp.comparison.bench.run",
    "iamp.comparison.bench_casadi": "iamp.comparison.bench.casadi",
    "iamp.comparison.bench_pmp": "iamp.comparison.bench.pmp",
    "iamp.comparison.bench_text": "iamp.comparison.bench.text",
    # compare/agreement/
    "iamp.comparison.agreement": "iamp.comparison.agreement.judge",
    "iamp.comparison.verdict": "iamp.comparison.agreement.verdict",
    "iamp.comparison.verdict_pmp_qp": "iamp.comparison.agreement.pmp_qp",
    "iamp.comparison.verdict_qp_qp": "iamp.comparison.agreement.qp_qp",
    "iamp.comparison.gaps": "iamp.comparison.agreement.gaps",
    "iamp.comparison.signs": "iamp.comparison.agreement.signs",
    "iamp.comparison.fingerprints": "iamp.comparison.agreement.fingerprints",
    "iamp.comparison.runs": "iamp.comparison.agreement.runs",
    "iamp.comparison.references": "iamp.comparison.agreement.references",
}

#: Every module of the new layout that is not also an old one: a name starting with one is new.
_NEW_ONLY = sorted({v for v in MOVES.values()} - set(MOVES), key=len, reverse=True)
_OLD = sorted(MOVES, key=len, reverse=True)
#: Old modules that are now packages (``iamp.planners.pmp``: the package re-exports ``pmp.planner``).
_PACKAGES = frozenset(old for old in MOVES if any(new.startswith(old + ".") for new in MOVES.values()))

#: A line with this comment is left alone (provenance strings that outputs and shipped data carry).
KEEP = "restructure: keep"
_DOTTED = re.compile(r"\biamp\.(?:planners|prediction|comparison)(?:\.[A-Za-z_]\w*)+")
_FROM = re.compile(r"^(\s*from\s+)(iamp(?:\.[A-Za-z_]\w*)+)(\s+import\s+)(.*)$")
_ONE = re.compile(r"^([A-Za-z_]\w*)(\s+as\s+[A-Za-z_]\w*)?(\s*(?:#.*)?)$")


def _starts(name: str, mod: str) -> bool:
    return name == mod or name.startswith(mod + ".")


def _is_new(name: str) -> bool:
    return any(_starts(name, new) for new in _NEW_ONLY)


@cache
def _package_names(pkg: str) -> frozenset[str]:
    """The names a new package offers: its ``__all__`` and its submodules (read, not imported)."""
    for prefix, folder in _FOLDERS.items():
        if pkg.startswith(prefix + "."):
            folder_path = ROOT / folder / pkg[len(prefix) + 1:].replace(".", "/")
            break
    else:
        return frozenset()
    init = folder_path / "__init__.py"
    if not init.is_file():
        return frozenset()
    names = {q.stem for q in folder_path.glob("*.py")} | {q.name for q in folder_path.iterdir() if q.is_dir()}
    for node in ast.parse(init.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "__all__" for t in node.targets):
            names |= set(ast.literal_eval(node.value))
    return frozenset(names)


def _resolves(pkg: str, rest: str) -> bool:
    """Whether ``pkg.rest`` already names something in the new layout (``pkg``: an old module that is
    now a package, such as ``iamp.planners.pmp``, whose ``__init__`` re-exports its public names)."""
    head = rest.split(".")[0]
    return head in _package_names(pkg)


def rewrite_name(name: str) -> str:
    """The dotted ``name`` in the new layout (unchanged if it is already new or unknown)."""
    if _is_new(name):
        return name
    for old in _OLD:
        if _starts(name, old) and name != old and _resolves(old, name[len(old) + 1:]):
            return name
    for old in _OLD:
        if _starts(name, old):
            return MOVES[old] + name[len(old):]
    return name


def _from_line(m: re.Match[str]) -> str:
    """A ``from MODULE import NAMES`` line: ``MODULE.NAME`` may itself be a moved module."""
    head, mod, imp, rest = m.groups()
    if mod in MOVES:
        names = [n.split(" as ")[0].strip() for n in rest.strip("()\\ ").split(",") if n.strip()]
        if names and all(_resolves(mod, n) for n in names if n and not n.startswith("#")):
            return m.group(0)
    one = _ONE.match(rest)
    if one is not None:
        name, alias, tail = one.group(1), one.group(2) or "", one.group(3)
        full = f"{mod}.{name}"
        if _is_new(full):
            return m.group(0)
        if full in MOVES:
            parent, _, leaf = MOVES[full].rpartition(".")
            if leaf != name and not alias:
                alias = f" as {name}"
            return f"{head}{parent}{imp}{leaf}{alias}{tail}"
    return f"{head}{rewrite_name(mod)}{imp}{rest}"


def rewrite_text(text: str) -> str:
    """The text with every old module name rewritten."""
    out = []
    for line in text.splitlines(keepends=True):
        body = line.rstrip("\r\n")
        if KEEP in body:
            out.append(line)
            continue
        m = _FROM.match(body)
        if m is not None:
            out.append(_from_line(m) + line[len(body):])
        elif re.match(r"\s*import\s", body):
            out.append(_DOTTED.sub(lambda d: rewrite_name(d.group(0)), line))
        else:  # text: a bare old module that is now a package names the package (it re-exports the module)
            out.append(_DOTTED.sub(lambda d: d.group(0) if d.group(0) in _PACKAGES else rewrite_name(d.group(0)),
                                   line))
    return "".join(out)


def main(argv: list[str]) -> int:
    check = "--check" in argv
    files = [a for a in argv if a != "--check"]
    changed = []
    for f in files:
        p = Path(f)
        if not p.is_file() or p.name == "restructure_imports.py":
            continue
        old = p.read_text(encoding="utf-8")
        new = rewrite_text(old)
        if new != old:
            changed.append(f)
            if not check:
                p.write_text(new, encoding="utf-8")
    for f in changed:
        print(("would rewrite " if check else "rewrote ") + f)
    return 1 if (check and changed) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
