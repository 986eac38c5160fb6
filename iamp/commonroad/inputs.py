r"""Invalid CommonRoad input refused with the element named (SPEC §16; the project's rule for bad
input: one line naming the file and the field, exit status 2, never a traceback).

commonroad-io reads whatever its factories can and otherwise fails with whatever Python raises
(``TypeError: 'NoneType' object is not iterable`` for a planning problem without an initial
state); it also reads values no vehicle can have (a time step of 0 s, a goal rectangle of
negative length, an initial speed of :math:`10^9` m/s) without complaint, which later turn into
divisions by zero, a runaway road corridor or a goal "reached" by an empty shape.  This module
stands in front of it:

* :func:`read_scenario`: the file (a folder is named as a folder), commonroad-io's reader, and
  where that fails the XML walked to name the element it could not read
  (:func:`diagnose_scenario_xml`: a missing ``initialState``, an empty ``goalState``, text where
  a number belongs, an interval whose start exceeds its end, a goal lanelet the map lacks); then
  :func:`validate_scenario`.
* :func:`validate_scenario`: what commonroad-io accepts but no plan can use, each refused naming
  the element (``commonRoad.timeStepSize``, ``planningProblem.initialState.velocity``,
  ``planningProblem.goalState[0].time``, ``planningProblem.goalState[0].position.rectangle.length``):

  - ``timeStepSize``: a finite number of seconds > 0;
  - the initial state: an exact, finite position, orientation and time step; an exact, finite
    speed inside the vehicle type's speed range (CommonRoad's parameters of the type that is
    planned, e.g. :math:`[-13.9, 50.8]` m/s for type 2, the BMW 320i; ``check``, which has no
    type, takes iamp's bound on any speed, ``speed_max_mps`` of :mod:`iamp.core.limits`);
  - at least one goal state; each goal state's time interval within iamp's horizon: its last
    step at most ``steps_max`` (20000) steps and ``tf_max_s`` (1000 s) after the start
    (:mod:`iamp.core.limits`, the bounds every iamp problem has; a goal beyond them would have the
    final-state search and the road corridor run over a horizon no plan may have);
  - a goal state's speed and orientation intervals: numbers (no NaN); its position: a shape
    (rectangle, circle, polygon or a group of them) of finite coordinates and positive size
    (a rectangle's length and width, a circle's radius > 0; a polygon of at least 3 vertices),
    or lanelets.

  A goal that is valid but out of reach (a speed interval outside the vehicle's range, a
  position kilometres away, an orientation against the road) is not refused here: the planner
  reports it as ``unreachable`` naming the element (exit 3, :mod:`iamp.commonroad.goal`).
* :func:`read_solution`: a CommonRoad solution file likewise (a missing ``benchmark_id``, a state
  without its ``x``, a trajectory without states named instead of commonroad-io's exception).

Element names follow the XML: children are joined by ``.``; an element that has siblings of the
same tag gets ``[i]`` (its index among them; goal states always) or ``[id=N]`` where it has an
``id``; the planning problem is ``planningProblem`` when the file has one.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import numpy as np

from iamp.core.errors import ScenarioError
from iamp.core.limits import LIMITS, exact

#: Leaf elements of a CommonRoad XML file that hold a number.
NUMERIC_LEAVES = frozenset({"x", "y", "z", "exact", "intervalStart", "intervalEnd", "length", "width", "radius",
                            "orientation", "time", "xVelocity", "yVelocity", "velocity", "acceleration",
                            "steeringAngle", "yawRate", "slipAngle", "rollAngle", "rollRate", "pitchAngle",
                            "pitchRate", "velocityY", "positionZ", "velocityZ", "rollAngleFront",
                            "rollRateFront", "velocityYFront", "positionZFront", "velocityZFront",
                            "rollAngleRear", "rollRateRear", "velocityYRear", "positionZRear", "velocityZRear",
                            "leftFrontWheelAngularSpeed", "rightFrontWheelAngularSpeed",
                            "leftRearWheelAngularSpeed", "rightRearWheelAngularSpeed", "deltaYFront", "deltaYRear",
                            "curvature", "curvatureChange", "jerk", "jounce", "steeringAngleSpeed"})
#: Elements that hold a state (their children are exact values or intervals, or a position).
STATE_TAGS = frozenset({"initialState", "goalState", "state"})
#: Shapes a position may be given by.
SHAPES = ("point", "rectangle", "circle", "polygon", "lanelet")


# --- names of elements ---------------------------------------------------------------------------
def _child_names(node: ElementTree.Element) -> list[tuple[ElementTree.Element, str]]:
    """The children of ``node`` with their names (module docstring)."""
    kids = list(node)
    counts: dict[str, int] = {}
    for c in kids:
        counts[c.tag] = counts.get(c.tag, 0) + 1
    seen: dict[str, int] = {}
    out = []
    for c in kids:
        i = seen.get(c.tag, 0)
        seen[c.tag] = i + 1
        if c.tag == "goalState":
            name = f"goalState[{i}]"
        elif counts[c.tag] > 1:
            name = f"{c.tag}[id={c.get('id')}]" if c.get("id") is not None else f"{c.tag}[{i}]"
        else:
            name = c.tag
        out.append((c, name))
    return out


def problem_field(pps: Any, pp: Any) -> str:
    """The name of planning problem ``pp`` of the set ``pps`` (module docstring)."""
    return "planningProblem" if len(pps.planning_problem_dict) <= 1 else f"planningProblem[id={pp.planning_problem_id}]"


# --- reading a scenario ----------------------------------------------------------------------------
def _existing_file(path: Any, what: str) -> str:
    """``path`` as a string, refused (naming it) when it is a folder or no file."""
    src = str(path)
    p = Path(path)
    if p.is_dir():
        raise ScenarioError(f"is a folder, not a CommonRoad {what} file", None, src)
    if not p.is_file():
        raise ScenarioError("no such file", None, src)
    return src


def read_scenario(path: str | Path, speed_range: tuple[float, float] | None = None,
                  vehicle: str | None = None) -> tuple[Any, Any]:
    """The scenario and planning-problem set of the CommonRoad file ``path``, validated.

    Parameters
    ----------
    path : path
        A CommonRoad scenario (XML; commonroad-io also reads protobuf).
    speed_range : (float, float), optional
        The vehicle type's speed range [m/s] an initial speed must lie in (default: iamp's bound
        on any speed, ``speed_max_mps``).
    vehicle : str, optional
        The vehicle the range is of, for the message (``"vehicle type 2 (BMW 320i)"``).

    Returns
    -------
    (scenario, planning_problem_set)

    Raises
    ------
    iamp.ScenarioError
        A folder, a missing or unreadable file, or an invalid element (named).
    """
    from commonroad.common.file_reader import CommonRoadFileReader

    src = _existing_file(path, "scenario")
    try:
        scenario, pps = CommonRoadFileReader(src).open()
    except Exception as exc:  # the reader raises anything from XML errors to TypeError
        try:
            found = diagnose_scenario_xml(Path(src))
        except RecursionError:  # nested too deeply to walk: the reader's message stands
            found = None
        if found is not None:
            raise ScenarioError(found[1], found[0], src) from None
        raise ScenarioError(f"not a readable CommonRoad scenario ({exc.__class__.__name__}: {exc})", None,
                            src) from None
    validate_scenario(scenario, pps, src, speed_range, vehicle)
    return scenario, pps


def diagnose_scenario_xml(path: Path) -> tuple[str | None, str] | None:
    """The element of the CommonRoad XML file ``path`` that commonroad-io cannot read, as
    ``(field, reason)``; None where the file is not XML or no element is found at fault (the
    reader's own message is then the best there is)."""
    try:
        root = ElementTree.parse(str(path)).getroot()
    except Exception:  # not XML: the reader's ParseError says where
        return None
    if root.tag != "commonRoad":
        return None, f"not a CommonRoad scenario (the root element is <{root.tag}>, not <commonRoad>)"
    from commonroad.common.reader.file_reader_xml import SUPPORTED_COMMONROAD_VERSIONS

    version = root.get("commonRoadVersion")
    if version not in SUPPORTED_COMMONROAD_VERSIONS:
        return ("commonRoad.commonRoadVersion",
                f"{'missing' if version is None else repr(version)}: commonroad-io reads "
                f"{', '.join(sorted(SUPPORTED_COMMONROAD_VERSIONS))}")
    dt = root.get("timeStepSize")
    if dt is None:
        return "commonRoad.timeStepSize", "missing"
    if _number(dt) is None:
        return "commonRoad.timeStepSize", f"must be a number of seconds (got {dt!r})"
    lanelets = {c.get("id") for c in root.iter("lanelet") if c.get("id") is not None}
    return _walk(root, "commonRoad", lanelets)


def _number(text: str | None, integer: bool = False) -> float | None:
    """``text`` as a number (an integer where ``integer``), or None."""
    if text is None:
        return None
    try:
        return float(int(text.strip())) if integer else float(text)
    except (ValueError, OverflowError):
        return None


def _walk(node: ElementTree.Element, name: str, lanelets: set[str | None]) -> tuple[str | None, str] | None:
    """The first element at fault in document order (:func:`diagnose_scenario_xml`), or None."""
    top = name == "commonRoad"
    for child, cname in _child_names(node):
        where = cname if top else f"{name}.{cname}"
        why = _element_fault(node, child, where, lanelets)
        if why is not None:
            return why
        deeper = _walk(child, where, lanelets)
        if deeper is not None:
            return deeper
    return None


def _element_fault(parent: ElementTree.Element, el: ElementTree.Element, where: str,
                   lanelets: set[str | None]) -> tuple[str, str] | None:
    """What is wrong with ``el`` itself (not its descendants), or None."""
    tag = el.tag
    kids = {c.tag for c in el}
    if tag == "planningProblem":
        if _number(el.get("id"), integer=True) is None:
            return f"{where}.id", f"must be an integer id (got {el.get('id')!r})"
        if el.find("initialState") is None:
            return f"{where}.initialState", "missing: a planning problem needs the ego's initial state"
        if el.find("goalState") is None:
            return f"{where}.goalState", "missing: a planning problem needs at least one goal state"
    if tag in STATE_TAGS:
        if len(el) == 0:
            what = {"initialState": "an initial state needs its position, velocity, orientation and time",
                    "goalState": "a goal state needs at least its time step interval"}.get(
                tag, "a state needs its time")
            return where, f"is empty: {what}"
        if tag != "initialState" and el.find("time") is None:
            return f"{where}.time", "missing: a state needs its time step (exact or an interval)"
    if parent.tag in STATE_TAGS:
        if tag == "position":
            if not kids & set(SHAPES):
                return where, f"gives no {', '.join(SHAPES[:-1])} or {SHAPES[-1]}"
        elif not ("exact" in kids or {"intervalStart", "intervalEnd"} <= kids):
            return where, "needs <exact> or both <intervalStart> and <intervalEnd>"
    if len(el) == 0 and tag in NUMERIC_LEAVES:
        integer = parent.tag == "time" or (tag == "time")
        value = _number(el.text, integer=integer)
        if value is None:
            kind = "an integer time step" if integer else "a number"
            return where, f"must be {kind} (got {(el.text or '').strip()!r})"
    if {"intervalStart", "intervalEnd"} <= kids:
        integer = tag == "time"
        a, b = _number(el.findtext("intervalStart"), integer), _number(el.findtext("intervalEnd"), integer)
        if a is not None and b is not None:
            if math.isnan(a) or math.isnan(b):
                return where, f"must be numbers (got [{exact(a)}, {exact(b)}])"
            if a > b:
                return where, f"intervalStart {exact(a)} exceeds intervalEnd {exact(b)}"
            if tag == "orientation" and b - a >= 2 * math.pi:
                return where, f"spans {exact(b - a)} rad, more than a full turn"
    if tag == "rectangle" and not {"length", "width"} <= kids:
        return where, "needs <length> and <width>"
    if tag == "circle" and "radius" not in kids:
        return where, "needs <radius>"
    if tag == "point" and not {"x", "y"} <= kids:
        return where, "needs <x> and <y>"
    if tag == "lanelet" and parent.tag == "position":
        ref = el.get("ref")
        if _number(ref, integer=True) is None:
            return f"{where}.ref", f"must be a lanelet id (got {ref!r})"
        if ref not in lanelets:
            return f"{where}.ref", f"names lanelet {ref}, which the map does not have"
    return None


# --- values commonroad-io accepts but no plan can use ---------------------------------------------
def _finite_point(value: Any) -> bool:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return False
    return bool(arr.shape == (2,) and np.all(np.isfinite(arr)))


def _exact_number(value: Any) -> float | None:
    """``value`` as a finite float; None where it is an interval, missing or not finite."""
    if value is None or hasattr(value, "start"):
        return None
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if math.isfinite(out) else None


def validate_scenario(scenario: Any, pps: Any, src: str, speed_range: tuple[float, float] | None = None,
                      vehicle: str | None = None) -> None:
    """Refuse what commonroad-io read but no plan can use (module docstring), naming the element.

    Raises
    ------
    iamp.ScenarioError
    """
    dt = _exact_number(getattr(scenario, "dt", None))
    if dt is None or dt <= 0:
        raise ScenarioError(f"must be a finite number of seconds > 0 (got {scenario.dt!r})",
                            "commonRoad.timeStepSize", src)
    for pp in pps.planning_problem_dict.values():
        validate_planning_problem(pp, dt, src, problem_field(pps, pp), speed_range, vehicle)


def validate_planning_problem(pp: Any, dt: float, src: str, name: str = "planningProblem",
                              speed_range: tuple[float, float] | None = None, vehicle: str | None = None) -> None:
    """Refuse an initial state or goal of planning problem ``pp`` no plan can use (module
    docstring); ``name`` is its element's name, ``dt`` the scenario's time step [s].

    Raises
    ------
    iamp.ScenarioError
    """
    init = pp.initial_state
    where = f"{name}.initialState"
    if init is None:
        raise ScenarioError("missing: a planning problem needs the ego's initial state", where, src)
    if not _finite_point(getattr(init, "position", None)):
        raise ScenarioError(f"must be an exact point of finite coordinates (got {getattr(init, 'position', None)!r})",
                            f"{where}.position", src)
    for attr, tag, unit in (("orientation", "orientation", "rad"), ("velocity", "velocity", "m/s")):
        raw = getattr(init, attr, None)
        if _exact_number(raw) is None:
            raise ScenarioError(f"must be an exact finite number in {unit} (got {raw!r})", f"{where}.{tag}", src)
    speed = float(init.velocity)
    lo, hi = speed_range if speed_range is not None else (-LIMITS["speed_max_mps"], LIMITS["speed_max_mps"])
    if not lo <= speed <= hi:
        whose = (f"the speed range of {vehicle or 'the vehicle type'} (--vehicle-type chooses another)"
                 if speed_range is not None else "iamp's bound on any speed (speed_max_mps, iamp.core.limits)")
        raise ScenarioError(f"must lie in [{lo:g}, {hi:g}] m/s (got {exact(speed)}), {whose}", f"{where}.velocity",
                            src)
    raw_k = getattr(init, "time_step", None)
    k0 = _exact_number(raw_k)
    if k0 is None or k0 != int(k0):
        raise ScenarioError(f"must be an exact integer time step (got {raw_k!r})", f"{where}.time", src)

    goal = getattr(pp, "goal", None)
    states = list(getattr(goal, "state_list", None) or [])
    if not states:
        raise ScenarioError("missing: a planning problem needs at least one goal state", f"{name}.goalState", src)
    steps_max, tf_max = int(LIMITS["steps_max"]), float(LIMITS["tf_max_s"])
    for i, st in enumerate(states):
        gw = f"{name}.goalState[{i}]"
        ts = getattr(st, "time_step", None)
        if ts is None:
            raise ScenarioError("missing: a goal state needs its time step interval", f"{gw}.time", src)
        a, b = (getattr(ts, "start", ts), getattr(ts, "end", ts))
        if _exact_number(a) is None or _exact_number(b) is None:
            raise ScenarioError(f"must be integer time steps (got {ts!r})", f"{gw}.time", src)
        span = float(b) - float(k0)
        if span > steps_max or span * dt > tf_max:
            raise ScenarioError(
                f"ends at time step {int(b)}, {exact(span * dt)} s after the start (timeStepSize {exact(dt)} s): "
                f"beyond iamp's horizon of at most {steps_max} steps and {tf_max:g} s (steps_max, tf_max_s, "
                "iamp.core.limits)", f"{gw}.time", src)
        for attr, tag in (("velocity", "velocity"), ("orientation", "orientation")):
            iv = getattr(st, attr, None) if st.has_value(attr) else None
            if iv is None:
                continue
            ends = (getattr(iv, "start", iv), getattr(iv, "end", iv))
            if any(not isinstance(e, (int, float, np.number)) or math.isnan(float(e)) for e in ends):
                raise ScenarioError(f"must be numbers (got {iv!r})", f"{gw}.{tag}", src)
            if tag == "orientation" and not all(math.isfinite(float(e)) for e in ends):
                raise ScenarioError(f"must be finite angles (got {iv!r})", f"{gw}.{tag}", src)
        if st.has_value("position"):
            why = _shape_fault(st.position)
            if why is not None:
                raise ScenarioError(why[1], f"{gw}.position{why[0]}", src)


def _shape_fault(shape: Any, prefix: str = "") -> tuple[str, str] | None:
    """What makes a goal position unusable, as ``(element suffix, reason)``, or None."""
    kind = type(shape).__name__
    if kind == "ShapeGroup":
        parts = list(shape.shapes)
        if not parts:
            return prefix, "is an empty group of shapes"
        for j, part in enumerate(parts):
            why = _shape_fault(part, f"{prefix}[{j}]" if len(parts) > 1 else prefix)
            if why is not None:
                return why
        return None
    if kind in ("Rectangle", "Circle"):
        where = f"{prefix}.{kind.lower()}"
        for attr in ("length", "width") if kind == "Rectangle" else ("radius",):
            v = _exact_number(getattr(shape, attr, None))
            if v is None or v <= 0:
                return f"{where}.{attr}", f"must be a finite size > 0 m (got {getattr(shape, attr, None)!r})"
        if _exact_number(getattr(shape, "orientation", 0.0)) is None:
            return f"{where}.orientation", f"must be a finite angle (got {shape.orientation!r})"
        if not _finite_point(shape.center):
            return f"{where}.center", f"must have finite coordinates (got {shape.center!r})"
        return None
    if kind == "Polygon":
        where = f"{prefix}.polygon"
        try:
            pts = np.asarray(shape.vertices, dtype=float)
        except (TypeError, ValueError):
            return where, "has unreadable vertices"
        if pts.ndim != 2 or pts.shape[1] != 2 or not np.all(np.isfinite(pts)):
            return where, "must have points of finite coordinates"
        if len(np.unique(np.round(pts, 9), axis=0)) < 3:
            return where, f"has {len(np.unique(np.round(pts, 9), axis=0))} distinct points; an area needs 3"
        return None
    if isinstance(shape, np.ndarray) or kind in ("list", "tuple"):
        return prefix, "is a point; a goal position is an area (a rectangle, circle, polygon or lanelets)"
    return prefix, f"a {kind} is not a goal area (a rectangle, circle, polygon or lanelets)"


# --- reading a solution ----------------------------------------------------------------------------
def read_solution(path: str | Path) -> Any:
    """The CommonRoad solution in ``path`` (a file written by ``iamp commonroad plan --out`` or
    any CommonRoad planner), with a one-line refusal naming the element where it cannot be read.

    Raises
    ------
    iamp.ScenarioError
    """
    from commonroad.common.solution import CommonRoadSolutionReader

    src = _existing_file(path, "solution")
    try:
        solution = CommonRoadSolutionReader.open(src)
    except Exception as exc:  # the reader raises anything from XML errors to AttributeError
        try:
            found = diagnose_solution_xml(Path(src))
        except RecursionError:
            found = None
        if found is not None:
            raise ScenarioError(found[1], found[0], src) from None
        raise ScenarioError(f"not a readable CommonRoad solution ({exc.__class__.__name__}: {exc})", None,
                            src) from None
    if not getattr(solution, "planning_problem_solutions", None):
        raise ScenarioError("holds no trajectory (a <pmTrajectory>, <ksTrajectory>, ... per planning problem)",
                            "CommonRoadSolution", src)
    return solution


def diagnose_solution_xml(path: Path) -> tuple[str | None, str] | None:
    """The element of the solution file ``path`` commonroad-io cannot read, as ``(field, reason)``;
    None where the file is not XML or nothing is found at fault."""
    from commonroad.common.solution import CostFunction, StateType, TrajectoryType, VehicleModel, VehicleType

    try:
        root = ElementTree.parse(str(path)).getroot()
    except Exception:
        return None
    if root.tag != "CommonRoadSolution":
        return None, f"not a CommonRoad solution (the root element is <{root.tag}>, not <CommonRoadSolution>)"
    bid = root.get("benchmark_id")
    where = "CommonRoadSolution.benchmark_id"
    if not bid:
        return where, "missing (e.g. benchmark_id=\"PM2:WX1:USA_US101-11_1_T-1:2020a\")"
    segments = bid.replace(" ", "").split(":")
    if len(segments) != 4:
        return where, f"{bid!r} is not MODEL:COST:SCENARIO:VERSION (e.g. PM2:WX1:USA_US101-11_1_T-1:2020a)"
    models = segments[0].strip("[]").split(",")
    model_names = [m.name for m in VehicleModel]
    type_ids = [str(t.value) for t in VehicleType]
    for m in models:
        if m[:-1] not in model_names or m[-1:] not in type_ids:
            return where, (f"vehicle {m!r} is not a model ({', '.join(model_names)}) followed by a vehicle type "
                           f"({', '.join(type_ids)}), e.g. PM2")
    for c in segments[1].strip("[]").split(","):
        if c not in CostFunction.__members__:
            return where, f"cost function {c!r} is not one of {', '.join(CostFunction.__members__)}"
    trajectories = list(root)
    if not trajectories:
        return "CommonRoadSolution", "holds no trajectory (a <pmTrajectory>, <ksTrajectory>, ... per planning problem)"
    if len(trajectories) > len(models):
        return where, f"names {len(models)} vehicle model(s) for {len(trajectories)} trajectories"
    kinds = {t.value: t for t in TrajectoryType}
    for (traj, tname) in _child_names(root):
        tw = f"CommonRoadSolution.{tname}"
        if traj.tag not in kinds:
            return tw, f"is not a trajectory (one of {', '.join(sorted(kinds))})"
        if _number(traj.get("planningProblem"), integer=True) is None:
            return f"{tw}.planningProblem", f"must be a planning problem id (got {traj.get('planningProblem')!r})"
        state_type: StateType = kinds[traj.tag].state_type
        if len(traj) == 0:
            return tw, "holds no state"
        for st, sname in _child_names(traj):
            sw = f"{tw}.{sname}"
            if st.tag != state_type.value:
                return sw, f"is not a <{state_type.value}> (the state of a <{traj.tag}>)"
            for xml_name in state_type.xml_fields:
                for leaf in (xml_name if isinstance(xml_name, tuple) else (xml_name,)):
                    text = st.findtext(leaf)
                    if text is None:
                        return f"{sw}.{leaf}", "missing"
                    if _number(text, integer=leaf == "time") is None:
                        kind = "an integer time step" if leaf == "time" else "a number"
                        return f"{sw}.{leaf}", f"must be {kind} (got {text.strip()!r})"
    return None
