"""Fuzz ``iamp plan`` with mutated scenario files and weird options; classify what happens.

Usage::

    python scripts/fuzz.py [--n 1000] [--seed 0] [--timeout 60] [--subprocess]
                           [--keep DIR] [--json]

Each case takes a built-in scenario, applies one to three random mutations (delete or
duplicate a key, a line or a ``[[vehicles]]`` block; replace a number by an extreme, NaN,
infinity, a huge integer, a string, a boolean or a list; inject a bare CR, a NUL, a BOM or
invalid UTF-8; grow ``x_poly`` or a history to a huge list; truncate the file; flip bytes)
and picks random options (``--planner``, ``--solver``, ``--hold``, ``--contact``,
``--steps`` from tiny to huge, a broken ``--model`` file), then runs ``iamp plan FILE
--json``: by default ``iamp.cli.main.main`` in a forked child (fast: the imports are
shared), with ``--subprocess`` as a real ``python -m iamp`` process.  A case that runs past
``--timeout`` seconds is killed and counted as a hang.

Outcomes: ``ok`` (exit 0), ``local`` (exit 3, status ``local``: verified at its contact times, the
global optimum not certified, so a cost is reported), ``refused`` (2), ``failed`` (3, no cost),
``unsafe`` (4), ``crash`` (exit 1:
an internal error, or any traceback on standard error), ``hang``, ``other`` (any other exit
status, more than one line on standard error for a refusal, or stdout that is not exactly
one JSON object), and ``unchecked-optimal``: exit 0 whose JSON does not satisfy its own
conditions — checked independently of the planner: the fixed-time optimum at the JSON's
contact times is the clamped cubic spline through the boundary states and the corners
(per axis, ``min ½∫s''²``), so the JSON trajectory must match that spline at every sample,
start and end at the file's boundary states, and report its cost (FOH QP: same optimum,
SPEC §3.1; ZOH QP: a cost not below it).

``refused-unnamed`` counts the refusals (already in ``refused``) whose line names neither a
field, an option nor a TOML line (e.g. a file that is not UTF-8: only the file is named).

Prints the counts (and with ``--keep DIR`` saves every non-ok case's file and command).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import random
import re
import shutil
import signal
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np

BASES = ("paper-1-poly", "paper-2", "two-vehicle", "paper-3-poly", "paper-3")
EXTREMES = ["1e308", "-1e308", "1e-300", "0", "-0.0", "nan", "inf", "-inf", "1e6", "-1e6", "1e5", "-99999.9",
            "1000", "1e-12", "99999999999999999999999999999", "9223372036854775807", '"text"', "true", "[]",
            "{}", "[1.0, 2.0]", "1e3", "-1e3", "0.01", "0.009", "3", "-5.0", "1e-6", "''"]
STEPS = ["1", "2", "3", "7", "100", "1000", "20000", "20001", "100000", "0", "-1", "abc", "1e3", "4.5"]
KEY_LINE = r"^\s*[A-Za-z_][A-Za-z0-9_]*\s*="


# ---------------------------------------------------------------------------------------------
# mutations
# ---------------------------------------------------------------------------------------------

def _lines_with_keys(text: str) -> list[int]:
    import re

    return [k for k, line in enumerate(text.split("\n")) if re.match(KEY_LINE, line)]


def mutate(text: str, rng: random.Random) -> tuple[str, str]:
    """One random mutation; returns (new text, description)."""
    import re

    lines = text.split("\n")
    keyed = _lines_with_keys(text)
    kind = rng.choice(["delete", "duplicate", "number", "number", "number", "number", "inject", "huge",
                       "truncate", "flip", "vehicle-block", "corner", "name", "list-item"])
    if kind == "delete" and keyed:
        k = rng.choice(keyed)
        return "\n".join(lines[:k] + lines[k + 1:]), f"delete line {k + 1}"
    if kind == "duplicate" and keyed:
        k = rng.choice(keyed)
        return "\n".join(lines[: k + 1] + [lines[k]] + lines[k + 1:]), f"duplicate line {k + 1}"
    if kind == "number":
        nums = list(re.finditer(r"(?<![\w.])-?\d+(\.\d+)?([eE][-+]?\d+)?", text))
        if nums:
            m = rng.choice(nums)
            new = rng.choice(EXTREMES)
            return text[: m.start()] + new + text[m.end():], f"number {m.group(0)} -> {new}"
    if kind == "inject":
        what = rng.choice(["\r", "\x00", "\ufeff", "\t", "\u00e9", "\x7f", "\r\n", "\udcff", "\x0c"])
        pos = rng.randrange(len(text) + 1)
        return text[:pos] + what + text[pos:], f"inject {what!r} at {pos}"
    if kind == "huge":
        if "x_poly = [" in text:
            n = rng.choice([65, 64, 200, 5000])
            c = rng.choice(["1e-300", "0.0", "1.0", "1e-20"])
            return (re.sub(r"x_poly = \[[^\]]*\]", "x_poly = [-15.0, 18.0" + f", {c}" * (n - 2) + "]", text, count=1),
                    f"x_poly with {n} terms of {c}")
        if "t = [" in text:
            n = rng.choice([100_001, 5000, 300])
            t = ", ".join(f"{-(n - 1 - k) * 0.01:.2f}" for k in range(n))
            x = ", ".join(f"{-15.0 - (n - 1 - k) * 0.2:.3f}" for k in range(n))
            text = re.sub(r"t = \[[^\]]*\]", f"t = [{t}]", text, count=1)
            return re.sub(r"\nx = \[[^\]]*\]", f"\nx = [{x}]", text, count=1), f"history of {n} samples"
    if kind == "truncate":
        pos = rng.randrange(len(text))
        return text[:pos], f"truncate at {pos}"
    if kind == "flip":
        pos = rng.randrange(len(text))
        return text[:pos] + chr(rng.randrange(32, 127)) + text[pos + 1:], f"flip char {pos}"
    if kind == "vehicle-block" and "[[vehicles]]" in text:
        start = text.index("[[vehicles]]")
        block = text[start:]
        if rng.random() < 0.5:
            return text + "\n" + block, "duplicate vehicle block"
        return text[:start] + block.replace("[[vehicles]]", "[[vehicles]]\n[[vehicles]]", 1), "empty vehicle table"
    if kind == "corner" and "corner = " in text:
        new = rng.choice(['"rear-upper"', '"front-upper"', '"rear-lower"', '"front"', '""', "1"])
        return re.sub(r'corner = "[^"]*"', f"corner = {new}", text, count=1), f"corner -> {new}"
    if kind == "name":
        return re.sub(r'name = "sv\d"', 'name = "sv1"', text), "all vehicle names sv1"
    if kind == "list-item" and "[" in text:
        m = rng.choice(list(re.finditer(r"= \[([^\]]*)\]", text)) or [None])
        if m is not None:
            new = rng.choice(["", "1.0", '"a", 1', "[1.0], [2.0]", "nan, 1.0", "1e308, -1e308", "0.0, 0.0, 0.0"])
            return text[: m.start(1)] + new + text[m.end(1):], f"list -> [{new}]"
    return text + "\nextra = 1\n", "unknown top-level key"


def random_options(rng: random.Random, bad_model: str) -> list[str]:
    opts: list[str] = []
    planner = rng.choice(["pmp", "pmp", "pmp", "qp"])
    if planner == "qp" or rng.random() < 0.2:
        opts += ["--planner", planner]
    if planner == "qp" or rng.random() < 0.1:
        if rng.random() < 0.5:
            opts += ["--solver", rng.choice(["osqp", "clarabel"])]
        if rng.random() < 0.3:
            opts += ["--hold", rng.choice(["foh", "zoh"])]
        if rng.random() < 0.2:
            opts += ["--contact", rng.choice(["grid", "refine"])]
    if rng.random() < 0.4:
        opts += ["--steps", rng.choice(STEPS if planner == "pmp" else ["1", "2", "10", "30", "1000", "20001"])]
    if rng.random() < 0.05:
        opts += ["--model", bad_model]
    return opts


# ---------------------------------------------------------------------------------------------
# running one case
# ---------------------------------------------------------------------------------------------

def run_forked(argv: list[str], timeout: float) -> tuple[int | None, str, str]:
    """``main(argv)`` in a forked child; ``(exit status or None on timeout, stdout, stderr)``."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        pid = os.fork()
        if pid == 0:  # child
            code = 1
            try:
                os.dup2(out.fileno(), 1)
                os.dup2(err.fileno(), 2)
                sys.stdout = io.TextIOWrapper(os.fdopen(1, "wb", closefd=False), write_through=True)
                sys.stderr = io.TextIOWrapper(os.fdopen(2, "wb", closefd=False), write_through=True)
                from iamp.cli.main import main

                try:
                    code = main(argv)
                except SystemExit as exc:
                    code = exc.code if isinstance(exc.code, int) else 1
                except BaseException:
                    import traceback

                    traceback.print_exc()
                    code = 1
                sys.stdout.flush()
                sys.stderr.flush()
            finally:
                os._exit(code)
        deadline = time.monotonic() + timeout
        status = None
        while time.monotonic() < deadline:
            done, st = os.waitpid(pid, os.WNOHANG)
            if done:
                status = os.waitstatus_to_exitcode(st)
                break
            time.sleep(0.01)
        if status is None:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
        out.seek(0)
        err.seek(0)
        return status, out.read().decode("utf-8", "replace"), err.read().decode("utf-8", "replace")


def run_subprocess(argv: list[str], timeout: float) -> tuple[int | None, str, str]:
    import subprocess

    try:
        r = subprocess.run([sys.executable, "-m", "iamp", *argv], capture_output=True, text=True, timeout=timeout,
                           errors="replace")
    except subprocess.TimeoutExpired:
        return None, "", ""
    return r.returncode, r.stdout, r.stderr


# ---------------------------------------------------------------------------------------------
# the independent check of an exit-0 plan
# ---------------------------------------------------------------------------------------------

def spline_reference(problem, times: np.ndarray, t_samples: np.ndarray) -> tuple[float, np.ndarray] | None:
    """Fixed-time optimum at ``times`` as clamped cubic splines (per axis); returns its cost
    ``½∫(s_x''² + s_y''²)`` and the samples ``(len(t), 4)`` of ``(s_x, v_x, s_y, v_y)``.
    ``None`` when the times are not distinct interior points."""
    from scipy.interpolate import CubicSpline

    tf = problem.tf
    order = np.argsort(times)
    ts = np.asarray(times, dtype=float)[order]
    knots = np.concatenate([[0.0], ts, [tf]])
    if np.any(np.diff(knots) <= 1e-9 * tf):
        return None
    corners = problem.corners(times)[order]
    e = problem.ego
    sx = CubicSpline(knots, np.concatenate([[e.x0], corners[:, 0], [e.xf]]), bc_type=((1, e.vx0), (1, e.vxf)))
    sy = CubicSpline(knots, np.concatenate([[e.y0], corners[:, 1], [e.yf]]), bc_type=((1, e.vy0), (1, e.vyf)))
    cost = 0.0
    for s in (sx, sy):
        a = s(knots, 2)
        h = np.diff(knots)
        cost += 0.5 * float(np.sum(h / 3.0 * (a[:-1] ** 2 + a[:-1] * a[1:] + a[1:] ** 2)))
    X = np.stack([sx(t_samples), sx(t_samples, 1), sy(t_samples), sy(t_samples, 1)], axis=1)
    return cost, X


def check_plan_json(out: dict, problem, rel: float = 1e-6) -> list[str]:
    """Violations of an exit-0 plan's own conditions (empty list: consistent).

    Boundary states from the samples at ``t = 0`` and ``t_f``; the trajectory and the cost
    against the clamped-spline optimum at the reported contact times (see the module
    docstring).  ``rel`` is relative to ``max(1, |value|)`` of the compared quantity.
    """
    bad: list[str] = []
    tr = out["trajectory"]
    t = np.asarray(tr["t"], dtype=float)
    X = np.stack([tr["x"], tr["vx"], tr["y"], tr["vy"]], axis=1).astype(float)
    e = problem.ego
    scale = max(1.0, float(np.max(np.abs(X))))
    for k, (want, at) in enumerate(((e.initial, 0), (e.final, -1))):
        gap = float(np.max(np.abs(X[at] - want)))
        if not gap <= rel * scale:
            bad.append(f"boundary {'initial' if k == 0 else 'final'} state off by {gap:.3g}")
    if abs(t[0]) > 0 or abs(t[-1] - problem.tf) > 1e-12 * problem.tf:
        bad.append("samples do not span [0, tf]")
    times = np.asarray(out["contact_times"], dtype=float)
    if times.shape != (problem.m,) or not np.all((times > 0) & (times < problem.tf)):
        return bad + [f"contact times {times.tolist()} not {problem.m} points in (0, tf)"]
    ref = spline_reference(problem, times, t)
    if ref is None:
        return bad
    cost, Xs = ref
    J = out["cost"]
    hold = out.get("hold")
    tol_rel = rel if out.get("planner") == "pmp" or out.get("solver") == "clarabel" else 1e-4
    if hold == "zoh":
        if not J >= cost * (1 - tol_rel) - 1e-12:
            bad.append(f"ZOH cost {J:.12g} below the continuous optimum {cost:.12g} at its contact times")
        return bad
    if not abs(J - cost) <= tol_rel * max(1.0, abs(cost)):
        bad.append(f"cost {J:.12g} != {cost:.12g} (optimum at its own contact times)")
    gap = float(np.max(np.abs(X - Xs)))
    if not gap <= tol_rel * scale * 10:
        bad.append(f"trajectory off the optimum through its corners by {gap:.3g}")
    return bad


# ---------------------------------------------------------------------------------------------
# the campaign
# ---------------------------------------------------------------------------------------------

def classify(code: int | None, stdout: str, stderr: str, path: Path, argv: list[str]) -> tuple[str, str]:
    if code is None:
        return "hang", ""
    if "Traceback" in stderr or code == 1:
        return "crash", stderr.strip().splitlines()[-1] if stderr.strip() else ""
    if code == 2:
        lines = stderr.strip().splitlines()
        if len(lines) != 1 or stdout:
            return "other", f"refusal with {len(lines)} stderr lines"
        return "refused", lines[0]
    if code in (0, 3, 4):
        try:
            out = json.loads(stdout)
        except json.JSONDecodeError:
            return "other", f"exit {code} without exactly one JSON object on stdout"
        if code == 3 and out.get("cost") is None:
            return "failed", out.get("status", "")
        if code == 3 and out.get("status") != "local":  # "local": verified, global optimum not certified
            return "other", f"failed ({out.get('status')}) with a cost"
        if code == 0 and (out.get("status") != "optimal" or out.get("cost") is None):
            return "other", "exit 0 but not optimal"
        if code in (0, 3):
            try:
                from iamp.prediction.resolve import load_problem

                model = argv[argv.index("--model") + 1] if "--model" in argv else None
                _, problem, _ = load_problem(str(path), model)
                bad = check_plan_json(out, problem)
            except Exception as exc:  # the fuzzer reports, never stops
                return "other", f"check failed: {exc.__class__.__name__}: {exc}"
            if bad:
                return "unchecked-optimal", "; ".join(bad)
            return ("ok", "") if code == 0 else ("local", "")
        return "unsafe", ""
    return "other", f"exit {code}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1000, help="cases (default 1000)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per case before it counts as a hang")
    ap.add_argument("--subprocess", action="store_true", help="run `python -m iamp` per case (slower)")
    ap.add_argument("--keep", default=None, help="folder to save every non-ok case into")
    ap.add_argument("--json", action="store_true", help="print the counts as JSON")
    args = ap.parse_args(argv)

    from iamp.core.scenario import builtin_text

    rng = random.Random(args.seed)
    work = Path(tempfile.mkdtemp(prefix="iamp-fuzz-"))
    bad_model = work / "model.json"
    bad_model.write_text(json.dumps({"format": "iamp-mtd/1", "order": "two", "Q": [[1]], "lambda": "x",
                                     "dt": 1e-6, "bins": [1, 2]}))
    keep = Path(args.keep) if args.keep else None
    if keep:
        keep.mkdir(parents=True, exist_ok=True)
    counts: Counter[str] = Counter()
    examples: dict[str, list[str]] = {}
    run = run_subprocess if args.subprocess else run_forked
    start = time.monotonic()
    try:
        for case in range(args.n):
            base = rng.choice(BASES)
            text, notes = builtin_text(base), []
            for _ in range(rng.choice([1, 1, 1, 2, 3])):
                text, note = mutate(text, rng)
                notes.append(note)
            path = work / f"case{case}.toml"
            path.write_bytes(text.encode("utf-8", "surrogateescape") if "\udcff" not in text
                             else text.replace("\udcff", "").encode() + b"\xff")
            opts = random_options(rng, str(bad_model))
            cmd = ["plan", str(path), "--json", *opts]
            code, out, err = run(cmd, args.timeout)
            kind, detail = classify(code, out, err, path, cmd)
            counts[kind] += 1
            if kind == "refused" and not re.search(r"field '|argument --|\.toml:\d+:", detail):
                counts["refused-unnamed"] += 1  # names neither a field, an option nor a TOML line
                examples.setdefault("refused-unnamed", []).append(detail)
            if kind not in ("ok", "local", "refused", "failed"):
                examples.setdefault(kind, []).append(f"{base} [{'; '.join(notes)}] {' '.join(opts)} -> {detail}")
                if keep:
                    shutil.copy(path, keep / f"{kind}-{case}.toml")
                    (keep / f"{kind}-{case}.cmd").write_text(" ".join(["iamp", *cmd]) + f"\n{notes}\n{err}\n")
            if (case + 1) % 100 == 0:
                sys.stderr.write(f"[{case + 1}/{args.n}] {dict(counts)}  ({time.monotonic() - start:.0f} s)\n")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    summary = {"cases": args.n, "seed": args.seed, "counts": dict(counts),
               "seconds": round(time.monotonic() - start, 1), "examples": {k: v[:5] for k, v in examples.items()}}
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        print(f"{args.n} cases (seed {args.seed}) in {summary['seconds']} s")
        for k in ("ok", "local", "refused", "refused-unnamed", "failed", "unsafe", "crash", "hang",
                  "unchecked-optimal", "other"):
            print(f"  {k:18s} {counts.get(k, 0)}")
        for k, v in examples.items():
            for line in v[:5]:
                print(f"  e.g. {k}: {line}")
    problems = sum(counts.get(k, 0) for k in ("crash", "hang", "unchecked-optimal", "other"))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
