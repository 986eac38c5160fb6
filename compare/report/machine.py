r"""What of ``iamp reproduce``'s output depends on the machine, and the byte-stable writing of the rest.

The reproduction's numbers are the same on every run of the same code on the same machine,
except the wall times (solve and plan times, the run time), the versions of the libraries and
the machine's description.  Those are kept out of ``results.json``, the tables and the figures
and written to the folder :data:`MACHINE_DIR` (``timing/``) beside them, which says so in its
``README.md`` (:data:`MACHINE_README`):

* :func:`split_machine` takes every value under a key :func:`is_machine_key` names out of the
  results (``time_s``, ``solve_time_s``, ``seconds``, ``runtime_s``, ``versions``, ``timing``,
  ``plan_time_*``, ``wall_*``, ``max_rss_mb``) and returns them by path
  (``scenarios/paper-1/runs/pmp/time_s``) for ``timing/timing.json``;
* :func:`canonical_json` writes JSON byte-stably: keys sorted, every float exact (Python's
  shortest round-trip form, so the numbers are the planners' own: a plan recomputed from
  ``results.json`` is the same plan), no ``-0.0``, no NaN.

What stays machine-dependent (:data:`MACHINE_FILES`): ``timing/`` itself, ``report.pdf`` (it
shows the timing table and figure) and ``campaign-small/episodes.csv`` (each closed-loop
episode's plan and wall times, written by :func:`iamp.simulation.campaign.run_campaign`).
Round-off at the level of the solvers' precision (gaps of ``1e-15``) may still differ between
machines (another CPU or BLAS): the tables show such magnitudes as a bound
(:func:`iamp.comparison.report.tex.tex_sci` with ``floor``), ``results.json`` keeps them.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

from iamp.core.jsonable import to_jsonable

__all__ = ["MACHINE_DIR", "MACHINE_FILES", "MACHINE_README", "canonical_json", "is_machine_key", "split_machine"]

#: The folder, inside the report folder, of everything that depends on the machine.
MACHINE_DIR = "timing"
#: Files of the report folder that differ between machines and runs (relative paths; a folder ends in ``/``).
MACHINE_FILES = (f"{MACHINE_DIR}/", "report.pdf", "campaign-small/episodes.csv")

_EXACT = frozenset({"time_s", "solve_time_s", "seconds", "runtime_s", "versions", "timing", "max_rss_mb"})
_PREFIXES = ("plan_time_", "wall_")

MACHINE_README = """# Machine-dependent outputs of `iamp reproduce`

Everything in this folder depends on the machine and the moment of the run, and changes every time
`iamp reproduce` runs; the rest of the report folder is the same, byte for byte, on every run of the same
code on the same machine (sorted keys, no dates or versions in the figures or the PDF).

* `timing.json` -- every wall time of the run (single QP solves, whole plans, the bounded problem, the
  predictor's evaluation, the small campaign), the run time, the machine and the versions of Python and
  the libraries; each value under the path of `results.json` it was taken from (`results.json` has the
  same structure without these keys).
* `timing.tex`, `timing.pdf`, `timing.png` -- the solve-time table and figure of the report.
* `environment.tex` -- the report's sentence on the run time and the versions.

Outside this folder, also machine-dependent: `report.pdf` (it shows the table and the figure above;
otherwise pdflatex writes it reproducibly: `SOURCE_DATE_EPOCH`, an empty trailer ID) and
`campaign-small/episodes.csv` (each closed-loop episode's plan and wall times, in the campaign's
own format).  Numbers at the level of the solvers' round-off (relative gaps of 1e-15) may differ between
machines with another CPU or BLAS; the tables show magnitudes below 1e-11 as `<1e-11`.
"""


def is_machine_key(key: str) -> bool:
    """Whether a results key holds a machine-dependent value (a wall time, versions, the machine)."""
    return key in _EXACT or key.startswith(_PREFIXES)


def _item_name(item: Any, index: int) -> str:
    """A list element's name in a path: its ``name`` / ``label``, else its scenario, mission,
    traffic and planner, else its index."""
    if isinstance(item, Mapping):
        for key in ("name", "label"):
            if isinstance(item.get(key), str):
                return str(item[key])
        parts = [str(item[k]) for k in ("scenario", "mission", "traffic", "planner") if k in item]
        if parts:
            return ":".join(parts)
    return str(index)


def split_machine(results: Any, path: str = "") -> tuple[Any, dict[str, Any]]:
    """``(results without the machine-dependent values, {path: value} of those values)``.

    Parameters
    ----------
    results : JSON-like
        Dictionaries, lists and scalars (``results.json`` before writing).
    path : str
        The path of ``results`` itself (for recursion).

    Returns
    -------
    tuple
        A copy of ``results`` without every key :func:`is_machine_key` names (at any depth),
        and those values by their path (``"scenarios/paper-1/runs/pmp/time_s"``).
    """
    moved: dict[str, Any] = {}
    if isinstance(results, Mapping):
        kept: dict[str, Any] = {}
        for key, value in results.items():
            sub = f"{path}/{key}" if path else str(key)
            if is_machine_key(str(key)):
                moved[sub] = value
                continue
            kept[key], more = split_machine(value, sub)
            moved.update(more)
        return kept, moved
    if isinstance(results, (list, tuple)):
        items = []
        for k, value in enumerate(results):
            item, more = split_machine(value, f"{path}/{_item_name(value, k)}" if path else _item_name(value, k))
            items.append(item)
            moved.update(more)
        return items, moved
    return results, moved


def _no_negative_zero(x: Any) -> Any:
    if isinstance(x, bool) or x is None:
        return x
    if isinstance(x, float):
        if not math.isfinite(x):
            raise ValueError(f"not a finite number: {x!r}")
        return x + 0.0  # + 0.0: no -0.0
    if isinstance(x, Mapping):
        return {str(k): _no_negative_zero(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_no_negative_zero(v) for v in x]
    return x


def canonical_json(obj: Any) -> str:
    """``obj`` as JSON text that is the same bytes for the same numbers: keys sorted, floats exact
    (no ``-0.0``), NaN as ``null``, one space of indent, a final newline.

    Raises
    ------
    ValueError
        An infinity that :func:`iamp.core.jsonable.to_jsonable` left (it writes NaN as ``null``).
    """
    return json.dumps(_no_negative_zero(to_jsonable(obj)), indent=1, sort_keys=True, allow_nan=False) + "\n"
