"""Goal variants of CommonRoad problems: the same scene and start, other goals.

Usage::

    python scripts/commonroad_variants.py SRC_DIR OUT_DIR [--kinds orient,lanes,multi] [--seed 0] [--force]

For every ``*.xml`` of ``SRC_DIR`` (sorted) whose first goal state has a rectangle on a lanelet
(``θ`` the lane's heading at the rectangle's centre, ``n`` the lane's left normal, ``σ = ±1``
alternating over the files, flipped by an odd ``--seed``), each kind writes one scenario:

``orient``
    the orientation interval entirely on one side of the lane heading:
    ``[θ + 0.025, θ + 0.2]`` (``σ = +1``) or ``[θ − 0.2, θ − 0.025]``.
``lanes``
    the goal rectangle moved ``2σ`` lanes (3.7 m each along ``n``); where that leaves the
    road, ``−2σ``, then ``σ``, then ``−σ`` lanes.
``multi``
    two goal states: the original with a speed of 40-45 m/s (out of reach), and the original
    moved ``−σ`` (else ``σ``) lanes with its time window 5 steps later.
``lanes3``
    the goal rectangle moved three lanes (``3σ``, else ``−3σ``); none where both leave the road.
``window``
    a narrow time window: two steps ``[k, k + 1]``, ``k`` drawn uniformly from the original window.
``speed``
    a speed interval 3 m/s wide that does not contain the traffic's speed at the goal
    (``v̄``: the mean speed of the recorded vehicles within 30 m of the goal's centre at the
    window's middle step, else the ego's initial speed): ``[v̄ + g, v̄ + g + 3]`` or
    ``[v̄ − g − 3, v̄ − g]`` (clamped at 0; the side and ``g ∈ [1.5, 3]`` drawn), keeping the
    original interval's intersection out.
``combo``
    one lane over (``σ``, else ``−σ``), the heading interval ``[θ, θ + 0.15σ]`` turned toward
    the lane the ego came from, and a five-step window drawn inside the original one.

Draws come from ``numpy.random.default_rng([seed, i, kind code])`` (``i`` the file's index), so
the same command writes the same files.  A variant's benchmark ID is its source's with the
configuration ID ``100 (seed + 1) + code`` (``orient`` 1, ``lanes`` 2, ``multi`` 3, ``lanes3``
4, ``window`` 5, ``speed`` 6, ``combo`` 7; e.g. ``USA_US101-5_1_T-1`` -> ``USA_US101-5_102_T-1``
for its ``lanes`` variant with seed 0); the file is ``<benchmark ID>.xml``.  ``OUT_DIR/variants.json``
lists every variant: its source, kind, benchmark ID and goal states as written (the test
``tests/test_commonroad_variants.py`` reads the files back against it).

Nothing is overwritten without ``--force``; a bad source folder or output exits with status 2
and one line on stderr.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import io
import json
import math
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np

#: Lane width of the moved goals [m].
LANE_M = 3.7
#: Kind -> configuration-ID code (module docstring).
KIND_CODES = {"orient": 1, "lanes": 2, "multi": 3, "lanes3": 4, "window": 5, "speed": 6, "combo": 7}
#: The kinds written when ``--kinds`` is not given.
DEFAULT_KINDS = ("orient", "lanes", "multi")
#: Recorded vehicles within this distance of the goal's centre set the traffic's speed [m].
TRAFFIC_RADIUS_M = 30.0


def _interval(x: Any) -> list[float] | None:
    if x is None:
        return None
    if hasattr(x, "start"):
        return [float(x.start), float(x.end)]
    return [float(x), float(x)]


def describe_goal_state(state: Any) -> dict[str, Any]:
    """The elements of a CommonRoad goal state as plain JSON values.

    Parameters
    ----------
    state : commonroad.scenario.state.State
        A goal state (rectangle positions only are described by their geometry).

    Returns
    -------
    dict
        ``time_step``, ``velocity``, ``orientation`` as ``[start, end]`` (``None`` where absent),
        ``position`` as ``{"center", "length", "width", "orientation"}`` (``None`` where absent).
    """
    pos = getattr(state, "position", None)
    position = None if pos is None else {
        "center": [float(pos.center[0]), float(pos.center[1])], "length": float(pos.length),
        "width": float(pos.width), "orientation": float(pos.orientation)}
    return {"time_step": _interval(getattr(state, "time_step", None)),
            "velocity": _interval(getattr(state, "velocity", None)),
            "orientation": _interval(getattr(state, "orientation", None)), "position": position}


def read_goal_states(path: Path) -> list[dict[str, Any]]:
    """The goal states of the (first) planning problem of a scenario file, described.

    Parameters
    ----------
    path : Path
        A CommonRoad scenario file.

    Returns
    -------
    list of dict
        :func:`describe_goal_state` of every goal state, in order.
    """
    from commonroad.common.file_reader import CommonRoadFileReader

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _, pps = CommonRoadFileReader(str(path)).open()
    pp = next(iter(pps.planning_problem_dict.values()))
    return [describe_goal_state(s) for s in pp.goal.state_list]


class _Source:
    """One source problem and what its variants are made from."""

    def __init__(self, path: Path, index: int, seed: int):
        from commonroad.common.file_reader import CommonRoadFileReader

        from iamp.core.errors import ScenarioError

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                self.scenario, self.pps = CommonRoadFileReader(str(path)).open()
        except Exception as exc:  # the reader raises anything from lxml errors to KeyError
            raise ScenarioError(f"not a readable CommonRoad scenario ({type(exc).__name__}: {exc})",
                                source=str(path)) from None
        self.path, self.index, self.seed = path, index, seed
        self.pp = next(iter(self.pps.planning_problem_dict.values()))
        self.goal0 = self.pp.goal.state_list[0]
        self.sign = 1 if (index + seed) % 2 == 0 else -1
        rect: Any = getattr(self.goal0, "position", None)
        self.rect: Any = None  # the goal rectangle, None where the source has no variants
        self.theta = math.nan
        self.normal = np.zeros(2)
        if type(rect).__name__ != "Rectangle":
            return
        net = self.scenario.lanelet_network
        ids = net.find_lanelet_by_position([np.asarray(rect.center)])[0]
        if not ids:
            return
        self.rect = rect
        cv = net.find_lanelet_by_id(ids[0]).center_vertices
        j = min(int(np.argmin(np.linalg.norm(cv - rect.center, axis=1))), len(cv) - 2)
        self.theta = math.atan2(*(cv[j + 1] - cv[j])[::-1])
        self.normal = np.array([-math.sin(self.theta), math.cos(self.theta)])

    @property
    def usable(self) -> bool:
        return self.rect is not None

    def rng(self, kind: str) -> np.random.Generator:
        return np.random.default_rng([self.seed, self.index, KIND_CODES[kind]])

    def shifted(self, lanes: int) -> Any:
        """The goal rectangle moved ``lanes`` lanes along the left normal, or None off the lanelets."""
        from commonroad.geometry.shape import Rectangle

        c = np.array(self.rect.center, dtype=np.float64) + lanes * LANE_M * self.normal
        if not self.scenario.lanelet_network.find_lanelet_by_position([c])[0]:
            return None
        return Rectangle(self.rect.length, self.rect.width, c, self.rect.orientation)

    def traffic_speed(self) -> float:
        """Mean speed of the recorded vehicles near the goal's centre at the window's middle step."""
        ts = self.goal0.time_step
        k = int(round(0.5 * (ts.start + ts.end)))
        centre = np.array(self.rect.center, dtype=np.float64)
        speeds = []
        for ob in self.scenario.dynamic_obstacles:
            st = ob.state_at_time(k)
            if st is not None and np.linalg.norm(np.asarray(st.position) - centre) <= TRAFFIC_RADIUS_M:
                speeds.append(float(st.velocity))
        return float(np.mean(speeds)) if speeds else float(self.pp.initial_state.velocity)


def _orient(src: _Source) -> list[Any] | None:
    from commonroad.common.util import AngleInterval

    th = src.theta
    lo, hi = (th + 0.025, th + 0.2) if src.sign > 0 else (th - 0.2, th - 0.025)
    s = copy.deepcopy(src.goal0)
    s.orientation = AngleInterval(lo, hi)
    return [s]


def _moved(src: _Source, order: tuple[int, ...]) -> list[Any] | None:
    for lanes in order:
        r = src.shifted(lanes)
        if r is not None:
            s = copy.deepcopy(src.goal0)
            s.position = r
            return [s]
    return None


def _lanes(src: _Source) -> list[Any] | None:
    return _moved(src, (2 * src.sign, -2 * src.sign, src.sign, -src.sign))


def _lanes3(src: _Source) -> list[Any] | None:
    return _moved(src, (3 * src.sign, -3 * src.sign))


def _multi(src: _Source) -> list[Any] | None:
    from commonroad.common.util import Interval

    for lanes in (-src.sign, src.sign):
        r = src.shifted(lanes)
        if r is not None:
            a = copy.deepcopy(src.goal0)
            a.velocity = Interval(40.0, 45.0)
            b = copy.deepcopy(src.goal0)
            b.position = r
            b.time_step = Interval(src.goal0.time_step.start + 5, src.goal0.time_step.end + 5)
            return [a, b]
    return None


def _window(src: _Source) -> list[Any] | None:
    from commonroad.common.util import Interval

    ts = src.goal0.time_step
    k = int(src.rng("window").integers(int(ts.start), int(ts.end)))  # k + 1 <= end
    s = copy.deepcopy(src.goal0)
    s.time_step = Interval(k, k + 1)
    return [s]


def _speed(src: _Source) -> list[Any] | None:
    from commonroad.common.util import Interval

    rng = src.rng("speed")
    up = bool(rng.integers(0, 2))
    gap = float(rng.uniform(1.5, 3.0))
    v = src.traffic_speed()
    if not up and v - gap - 3.0 < 0.0:
        up = True
    lo, hi = (v + gap, v + gap + 3.0) if up else (v - gap - 3.0, v - gap)
    s = copy.deepcopy(src.goal0)
    s.velocity = Interval(round(lo, 3), round(hi, 3))
    return [s]


def _combo(src: _Source) -> list[Any] | None:
    from commonroad.common.util import AngleInterval, Interval

    out = _moved(src, (src.sign, -src.sign))
    if out is None:
        return None
    s = out[0]
    moved = float(np.dot(np.asarray(s.position.center) - np.asarray(src.rect.center), src.normal))
    toward = 1.0 if moved > 0 else -1.0  # still turned toward the new lane: heading left of θ for a left move
    lo, hi = sorted((src.theta, src.theta + 0.15 * toward))
    s.orientation = AngleInterval(lo, hi)
    ts = src.goal0.time_step
    start = int(src.rng("combo").integers(int(ts.start), max(int(ts.end) - 4, int(ts.start) + 1)))
    s.time_step = Interval(start, min(start + 4, int(ts.end)))
    return out


KINDS: dict[str, Callable[[_Source], list[Any] | None]] = {
    "orient": _orient, "lanes": _lanes, "multi": _multi, "lanes3": _lanes3, "window": _window, "speed": _speed,
    "combo": _combo}


def benchmark_id(source_id: str, kind: str, seed: int) -> str:
    """The variant's benchmark ID: ``source_id`` with configuration ID ``100 (seed + 1) + code``.

    Parameters
    ----------
    source_id : str
        The source scenario's benchmark ID (e.g. ``USA_US101-5_1_T-1``).
    kind : str
        A key of :data:`KIND_CODES`.
    seed : int
        The variants' seed (``>= 0``).

    Returns
    -------
    str
        E.g. ``USA_US101-5_102_T-1`` for ``lanes`` with seed 0.
    """
    from commonroad.scenario.scenario import ScenarioID

    sid = ScenarioID.from_benchmark_id(source_id, "2020a")
    sid.configuration_id = 100 * (seed + 1) + KIND_CODES[kind]
    return str(sid)


def make_variants(src_dir: Path, out_dir: Path, kinds: tuple[str, ...] = DEFAULT_KINDS, seed: int = 0,
                  force: bool = False) -> list[dict[str, Any]]:
    """Write the variants of every problem of ``src_dir`` into ``out_dir`` (module docstring).

    Parameters
    ----------
    src_dir : Path
        Folder of CommonRoad scenario files.
    out_dir : Path
        Output folder (created); gets ``<benchmark ID>.xml`` per variant and ``variants.json``.
    kinds : tuple of str
        Keys of :data:`KINDS`.
    seed : int
        Seed of the draws and of the side ``σ`` (``>= 0``).
    force : bool
        Replace files that exist.

    Returns
    -------
    list of dict
        One entry per variant written: ``file``, ``source``, ``kind``, ``benchmark_id``,
        ``goal_states`` (:func:`describe_goal_state`).

    Raises
    ------
    iamp.core.errors.ScenarioError
        ``src_dir`` holds no scenario, an unknown kind or a negative seed; an output that
        exists without ``force`` (:class:`iamp.core.outputs.OutputError`).
    """
    from commonroad.common.file_writer import CommonRoadFileWriter, OverwriteExistingFile

    from iamp.core.atomic import atomic_path, write_text
    from iamp.core.errors import ScenarioError
    from iamp.core.outputs import OutputError, check_output, write_marker

    bad = [k for k in kinds if k not in KINDS]
    if bad:
        raise ScenarioError(f"unknown kind(s) {', '.join(bad)}; choose from {', '.join(KINDS)}", "--kinds")
    if seed < 0:
        raise ScenarioError(f"must be >= 0 (got {seed})", "--seed")
    files = sorted(Path(src_dir).glob("*.xml"))
    if not files:
        raise ScenarioError("holds no *.xml scenario", "SRC_DIR", str(src_dir))
    check_output(out_dir, [src_dir], force, option="OUT_DIR", folder=True)
    sources = [_Source(f, i, seed) for i, f in enumerate(files)]
    plans: list[tuple[_Source, str, list[Any]]] = []
    for src in sources:
        if not src.usable:
            continue
        for kind in kinds:
            states = KINDS[kind](src)
            if states is not None:
                plans.append((src, kind, states))
    names = [benchmark_id(str(src.scenario.scenario_id), kind, seed) + ".xml" for src, kind, _ in plans]
    if not force:
        there = [n for n in names + ["variants.json"] if (out_dir / n).exists()]
        if there:
            raise OutputError(f"already holds {there[0]} ({len(there)} of the files to write); use --force to "
                              "replace them", "OUT_DIR", str(out_dir))
    out_dir.mkdir(parents=True, exist_ok=True)
    write_marker(out_dir, "scripts/commonroad_variants.py")
    entries = []
    for (src, kind, states), name in zip(plans, names):
        scenario = copy.deepcopy(src.scenario)
        scenario.scenario_id = copy.deepcopy(scenario.scenario_id)
        scenario.scenario_id.configuration_id = 100 * (seed + 1) + KIND_CODES[kind]
        pp = copy.deepcopy(src.pp)
        pp.goal.state_list = states
        pp.goal._lanelets_of_goal_position = None  # the setter refuses once set; the states give the positions
        pps = copy.deepcopy(src.pps)
        pps._planning_problem_dict = {pp.planning_problem_id: pp}
        with atomic_path(out_dir / name) as tmp, warnings.catch_warnings(), \
                contextlib.redirect_stdout(io.StringIO()):  # the writer prints "Replace file ..."
            warnings.simplefilter("ignore")
            CommonRoadFileWriter(scenario, pps, "iamp scripts/commonroad_variants.py", "", "", set()).write_to_file(
                tmp, OverwriteExistingFile.ALWAYS)
        entries.append({"file": name, "source": src.path.name, "kind": kind, "benchmark_id": name[:-4],
                        "goal_states": read_goal_states(out_dir / name)})  # as written (the writer rounds)
    write_text(out_dir / "variants.json", json.dumps({"seed": seed, "kinds": list(kinds), "variants": entries},
                                                     indent=1) + "\n")
    return entries


def main(argv: list[str] | None = None) -> int:
    """The command line (module docstring); returns the exit status."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("src_dir", metavar="SRC_DIR", help="folder of CommonRoad scenario files")
    ap.add_argument("out_dir", metavar="OUT_DIR", help="where the variants go")
    ap.add_argument("--kinds", default=",".join(DEFAULT_KINDS),
                    help=f"comma-separated, of {', '.join(KINDS)} (default {','.join(DEFAULT_KINDS)})")
    ap.add_argument("--seed", type=int, default=0, help="seed of the draws and sides (default 0)")
    ap.add_argument("--force", action="store_true", help="replace variant files that exist")
    a = ap.parse_args(argv)
    from iamp.core.errors import IampError

    try:
        entries = make_variants(Path(a.src_dir), Path(a.out_dir), tuple(k for k in a.kinds.split(",") if k), a.seed,
                                a.force)
    except IampError as exc:
        sys.stderr.write(f"iamp: error: {exc}\n")
        return 2
    except ImportError as exc:
        sys.stderr.write(f"iamp: error: needs the [commonroad] extra ({exc})\n")
        return 2
    sys.stderr.write(f"wrote {len(entries)} variants into {a.out_dir}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
