r"""CommonRoad's own verdict on a solution, one check at a time.

``commonroad_dc.feasibility.solution_checker.valid_solution`` stops at the first failing
check (it raises); this module runs every check separately and records each verdict:

* ``starts_at_initial_state`` - the first state matches the planning problem's;
* ``kinematically_feasible`` - every step reachable by the vehicle model (``PM``: a constant
  input per step inside the friction circle ``|u| <= a_max``, positions within 2 cm);
* ``collision`` - the ego's body (the vehicle type's rectangle at each step's heading) against
  every obstacle; on a collision, **which** obstacles (each one checked alone) and the first
  time step;
* ``road_boundary`` - the body against the road boundary built from the lanelet network
  (needs ``triangle``);
* ``goal_reached`` - CommonRoad's goal test, as is;
* ``goal_reached_corrected`` - the same test with the **point-mass orientation defect worked
  around**: commonroad-io 2024.3's ``GoalRegion._harmonize_state_types`` replaces a PM
  state's ``velocity`` (``v_x``) by the speed :math:`|v|` and *then* reads the orientation as
  ``atan2(v_y, velocity)`` = :math:`\operatorname{atan2}(v_y, |v|)` instead of
  :math:`\operatorname{atan2}(v_y, v_x)`; on US-101 (heading about -0.72 rad) a correct
  point-mass plan misses the goal's orientation.  The corrected test passes each state to the
  goal as position, speed :math:`|v|`, orientation :math:`\operatorname{atan2}(v_y, v_x)` and
  time step, so nothing else changes.

A ``PM`` solution that starts at rest gets a ``note``: its first state has no heading (CommonRoad
reads ``atan2(0, 0) = 0``), so ``starts_at_initial_state`` and the body at step 0 are judged at
heading 0 rather than the initial state's; the verdicts stay CommonRoad's, and the ``KS`` model,
which carries the heading, is not affected.

``valid`` is every check passing with the corrected goal test; ``valid_commonroad_raw`` is
``valid_solution``'s own answer (``False`` whenever the defect bites), both reported.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypedDict

from iamp.commonroad import require
from iamp.core.errors import ScenarioError

CHECKS = ("starts_at_initial_state", "kinematically_feasible", "collision", "road_boundary", "goal_reached",
          "goal_reached_corrected")


class CheckJSON(TypedDict):
    """One check's verdict: ``ok`` and a line of detail."""

    ok: bool
    detail: str


class VerdictJSON(TypedDict):
    """:meth:`Verdict.to_json`."""

    valid: bool
    valid_commonroad_raw: bool
    category: str
    checks: dict[str, CheckJSON]
    colliding_obstacles: list[int]
    cost: float | None
    cost_function: str | None
    orientation_defect: str
    notes: list[str]


@dataclass
class Verdict:
    """Every check's verdict (``ok`` True/False, ``detail`` text) and the overall validity."""

    checks: dict[str, CheckJSON] = field(default_factory=dict)
    colliding_obstacles: list[int] = field(default_factory=list)
    cost: float | None = None
    cost_function: str | None = None
    #: What the verdicts cannot say by themselves (a ``PM`` start at rest).
    notes: list[str] = field(default_factory=list)

    @property
    def valid(self) -> bool:
        need = ("starts_at_initial_state", "kinematically_feasible", "collision", "road_boundary",
                "goal_reached_corrected")
        return all(self._ok(k) for k in need)

    @property
    def valid_commonroad_raw(self) -> bool:
        need = ("starts_at_initial_state", "kinematically_feasible", "collision", "road_boundary", "goal_reached")
        return all(self._ok(k) for k in need)

    def _ok(self, name: str) -> bool:
        """The check ``name`` ran and passed."""
        c = self.checks.get(name)
        return c is not None and c["ok"] is True

    @property
    def category(self) -> str:
        """One word for the bench table: valid / collision / infeasible / goal missed / off road."""
        if self.valid:
            return "valid"
        if not self._ok("collision"):
            return "collision"
        if not self._ok("kinematically_feasible") or not self._ok("starts_at_initial_state"):
            return "infeasible"
        if not self._ok("road_boundary"):
            return "off road"
        return "goal missed"

    def to_json(self) -> VerdictJSON:
        return {"valid": self.valid, "valid_commonroad_raw": self.valid_commonroad_raw, "category": self.category,
                "checks": self.checks, "colliding_obstacles": self.colliding_obstacles,
                "cost": self.cost, "cost_function": self.cost_function,
                "orientation_defect": "commonroad-io 2024.3 reads a PM goal state's orientation as atan2(v_y, |v|); "
                                      "goal_reached_corrected uses atan2(v_y, v_x)",
                "notes": list(self.notes)}

    def lines(self) -> list[str]:
        out = []
        for name in CHECKS:
            c = self.checks.get(name)
            if c is None:
                continue
            out.append(f"{name:26s} {'pass' if c['ok'] else 'FAIL'}  {c['detail']}".rstrip())
        out.append(f"{'valid (corrected goal)':26s} {'yes' if self.valid else 'no'}")
        out.append(f"{'valid_solution (raw)':26s} {'yes' if self.valid_commonroad_raw else 'no'}"
                   + ("  (the PM orientation defect: see goal_reached_corrected)"
                      if self.valid and not self.valid_commonroad_raw else ""))
        out += [f"{'note':26s} {n}" for n in self.notes]
        if self.cost is not None:
            out.append(f"{'cost ' + str(self.cost_function):26s} {self.cost:.4f}")
        elif self.cost_function is not None:
            out.append(f"{'cost':26s} {self.cost_function}")
        return out


def read(scenario_path: str | Path, solution_path: str | Path) -> tuple[Any, Any, Any]:
    """Scenario, planning-problem set and solution from their files (one-line errors naming the
    file and the element, :mod:`iamp.commonroad.inputs`)."""
    require()
    from iamp.commonroad.inputs import read_scenario, read_solution

    for p in (scenario_path, solution_path):  # both named before either is read
        if Path(p).is_dir():
            raise ScenarioError("is a folder, not a CommonRoad file", None, str(p))
        if not Path(p).is_file():
            raise ScenarioError("no such file", None, str(p))
    scenario, pps = read_scenario(scenario_path)
    solution = read_solution(solution_path)
    return scenario, pps, solution


def _corrected_goal(pp: Any, trajectory: Any) -> tuple[bool, int | None]:
    from commonroad.scenario.state import CustomState

    for st in trajectory.state_list:
        vx, vy = float(st.velocity), float(getattr(st, "velocity_y", 0.0) or 0.0)
        probe = CustomState(time_step=st.time_step, position=st.position, velocity=math.hypot(vx, vy),
                            orientation=math.atan2(vy, vx))
        if pp.goal.is_reached(probe):
            return True, int(st.time_step)
    return False, None


#: A ``PM`` first state slower than this has no heading worth the name [m/s].
REST_MPS = 1e-3


def _pm_notes(pp: Any, pp_sol: Any) -> list[str]:
    """The notes of a ``PM`` solution whose first state CommonRoad cannot compare with the initial
    state's heading (module docstring): a start at rest (its heading read as ``atan2(0, 0) = 0``),
    and an initial heading outside ``(-π, π]`` (the number compared, not the direction: a ``PM``
    state's heading ``atan2(v_y, v_x)`` is the same direction written inside)."""
    if pp_sol.vehicle_model.name != "PM" or not pp_sol.trajectory.state_list:
        return []
    first = pp_sol.trajectory.state_list[0]
    speed = math.hypot(float(getattr(first, "velocity", 0.0)), float(getattr(first, "velocity_y", 0.0)))
    heading = float(getattr(pp.initial_state, "orientation", 0.0))
    inside = math.remainder(heading, 2 * math.pi)
    out = []
    if speed < REST_MPS and abs(inside) >= 1e-3:
        out.append(f"the ego starts at rest: CommonRoad reads a PM state at zero speed with heading atan2(0, 0) = 0, "
                   f"not the initial state's {heading:.4f} rad, so starts_at_initial_state and the body at step 0 "
                   "are judged turned (the KS model carries the heading: --vehicle-model KS)")
    if abs(inside - heading) >= 1e-9 and not (abs(inside + math.pi) < 1e-12 and abs(heading - math.pi) < 1e-9):
        out.append(f"the initial state's heading {heading:.4f} rad lies outside (-pi, pi]: a PM solution states the "
                   f"same direction as {inside:.4f} rad, and starts_at_initial_state compares the numbers")
    return out


def check(scenario: Any, pps: Any, solution: Any, cost: bool = True) -> Verdict:
    """Run every check of the module docstring on ``solution``."""
    require()
    from commonroad_dc.collision.collision_detection.pycrcc_collision_dispatch import create_collision_object
    from commonroad_dc.feasibility import solution_checker as sc

    v = Verdict()
    pp_sol = solution.planning_problem_solutions[0]
    pp = pps.planning_problem_dict.get(pp_sol.planning_problem_id)
    if pp is None:
        raise ScenarioError(f"solves planning problem {pp_sol.planning_problem_id}, which the scenario does not have",
                            "planningProblemSolution")

    def run(name: str, fn: Callable[[], tuple[bool, str]]) -> None:
        try:
            ok, detail = fn()
        except Exception as exc:  # the checker raises its verdicts
            ok, detail = False, f"{exc.__class__.__name__}: {' '.join(str(exc).split())[:200]}"
        v.checks[name] = {"ok": bool(ok), "detail": detail}

    run("starts_at_initial_state", lambda: (sc.starts_at_correct_state(solution, pps), ""))
    v.notes += _pm_notes(pp, pp_sol)

    def feas() -> tuple[bool, str]:
        res = sc.solution_feasible(solution, scenario.dt, pps)
        ok = all(r[0] for r in res.values())
        return ok, (f"every step reachable by the {pp_sol.vehicle_model.name} model within its limits" if ok
                    else "a step is not reachable")
    run("kinematically_feasible", feas)

    def coll() -> tuple[bool, str]:
        ego = sc._create_pp_solution_collision_object(pps, pp_sol, scenario.dt)
        hit = []
        for ob in scenario.obstacles:
            if create_collision_object(ob).collide(ego):
                hit.append(int(ob.obstacle_id))
        v.colliding_obstacles = hit
        return (not hit), ("no obstacle" if not hit else "with obstacle(s) " + ", ".join(map(str, hit)))
    run("collision", coll)

    def road() -> tuple[bool, str]:
        off = sc.boundary_collision(scenario, pps, solution)
        return (not off), "inside the road boundary"
    run("road_boundary", road)

    def goal() -> tuple[bool, str]:
        ok, k = pp.goal_reached(pp_sol.trajectory)
        return bool(ok), (f"at time step {k}" if ok
                          else "no state inside the goal region (as checked by commonroad-io)")
    run("goal_reached", goal)

    def goal_fixed() -> tuple[bool, str]:
        if pp_sol.vehicle_model.name != "PM":  # the defect is the point-mass state's: nothing to correct
            ok_raw, k_raw = pp.goal_reached(pp_sol.trajectory)
            return bool(ok_raw), (f"at time step {k_raw} (vehicle model {pp_sol.vehicle_model.name}: the "
                                  "commonroad-io test, no PM defect)" if ok_raw else "no state inside the goal region")
        ok, k = _corrected_goal(pp, pp_sol.trajectory)
        return ok, (f"at time step {k} (orientation atan2(v_y, v_x))" if ok else "no state inside the goal region")
    run("goal_reached_corrected", goal_fixed)

    if cost:  # named here; computed by iamp.commonroad.costs (needs the road frame: the callers' cr)
        v.cost_function = str(pp_sol.cost_function.name)
    return v
