r"""Pictures that move: a plan in its traffic, a closed-loop episode, a CommonRoad solution.

Each function writes an animated GIF (Pillow, which matplotlib already needs) or an MP4
(``ffmpeg`` on the ``PATH``), chosen by the suffix of the output, atomically (the previous file
stays until the new one is complete). Everything is drawn **to scale** in the road plane:

* :func:`animate_plan` — one :class:`~iamp.core.plan.Plan`: every surrounding vehicle's body
  and safety box :math:`x_{s,i}(t) \pm (L_i/2 + S_{x,i})` by :math:`y_{s,i} \pm (W_i/2 + S_{y,i})`
  moving along its prediction, the ego's body (its own ``[ego] length × width``) turned along
  its heading :math:`\operatorname{atan2}(v_y, v_x)`, the path driven so far, and the contact
  (or crossing) points once their time has passed;
* :func:`animate_episode` — the step log of ``iamp simulate --log`` (ego and neighbours per
  step, centres, SI units), in a window that follows the ego;
* :func:`animate_commonroad` — a CommonRoad scenario and a solution file, drawn with
  CommonRoad's own renderer (``MPRenderer``) at each time step, the ego from the solution's
  trajectory (needs the ``[commonroad]`` extra).

Frames are sampled at equal times; ``fps`` and ``speed`` (simulated seconds per real second)
set the pace, ``max_frames`` bounds the work (the frame count, never a clock).
"""

from __future__ import annotations

import csv
import shutil
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from iamp.core.atomic import atomic_path
from iamp.core.errors import MissingDependencyError, ScenarioError

from .style import EGO_COLOR, SAFETY_COLOR, VEHICLE_COLORS, PathLike, is_avoidance
from .trajectory import lane_lines, xy_limits

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes

    from iamp.core.plan import Plan

__all__ = ["ANIMATION_FORMATS", "animate_commonroad", "animate_episode", "animate_plan", "check_animation_path",
           "frame_times", "plan_frames"]

#: Suffixes an animation can be written as.
ANIMATION_FORMATS = ("gif", "mp4")


def frame_times(duration: float, fps: float, speed: float = 1.0, max_frames: int = 400) -> np.ndarray:
    """The instants drawn: evenly spaced over ``[0, duration]`` at most ``Δ = speed / fps`` apart,
    thinned evenly to at most ``max_frames`` frames (both ends are always drawn).

    Parameters
    ----------
    duration : float
        The time span to show [s], > 0.
    fps : float
        Frames per second of the animation, > 0.
    speed : float
        Simulated seconds per second of animation (1 = real time), > 0.
    max_frames : int
        Upper bound on the number of frames (>= 2).

    Returns
    -------
    ndarray
        Increasing instants in ``[0, duration]``, the first 0 and the last ``duration``.
    """
    if not (duration > 0 and fps > 0 and speed > 0 and max_frames >= 2):
        raise ValueError("duration, fps and speed must be > 0 and max_frames >= 2")
    n = int(np.ceil(duration * fps / speed - 1e-9)) + 1
    n = min(max(n, 2), int(max_frames))
    return np.linspace(0.0, float(duration), n)


def check_animation_path(path: PathLike) -> Path:
    """Refuse, before any work, an output an animation cannot be written to.

    Parameters
    ----------
    path : path-like
        The intended output file.

    Returns
    -------
    Path
        ``path`` as a :class:`~pathlib.Path`.

    Raises
    ------
    iamp.ScenarioError
        If the suffix is not ``.gif`` or ``.mp4``.
    iamp.MissingDependencyError
        For an ``.mp4`` without ``ffmpeg`` on the ``PATH``.
    """
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower()
    if fmt not in ANIMATION_FORMATS:
        raise ScenarioError(f"must end in {', '.join('.' + f for f in ANIMATION_FORMATS)} (got {path.name!r})",
                            "--out")
    if fmt == "mp4" and shutil.which("ffmpeg") is None:
        raise MissingDependencyError("an MP4 needs ffmpeg on the PATH (Debian: apt-get install ffmpeg); "
                                     "write a .gif instead")
    return path


def _writer(path: Path, fps: float) -> Any:
    from matplotlib import animation

    if check_animation_path(path).suffix.lower() == ".gif":
        return animation.PillowWriter(fps=round(fps))
    return animation.FFMpegWriter(fps=round(fps), codec="libx264", extra_args=["-pix_fmt", "yuv420p"])


def _write(fig: Figure, draw: Callable[[int], None], frames: int, path: PathLike, fps: float, dpi: float) -> Path:
    """Draw ``frames`` frames with ``draw(k)`` and write them to ``path`` atomically."""
    from matplotlib import animation
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    path = Path(path)
    writer = _writer(path, fps)
    FigureCanvasAgg(fig)
    anim = animation.FuncAnimation(fig, lambda k: draw(int(k)), frames=range(frames), blit=False, repeat=False,
                                   cache_frame_data=False)
    with atomic_path(path) as tmp:
        # the writer picks its container by the file name: keep the suffix on the temporary file
        tmp_out = Path(tmp).with_suffix(path.suffix)
        try:
            anim.save(str(tmp_out), writer=writer, dpi=dpi)
            tmp_out.replace(tmp)
        finally:
            tmp_out.unlink(missing_ok=True)
    return path


def _oriented_body(ax: Axes, x: float, y: float, heading_rad: float, length: float, width: float, **kw: Any) -> None:
    ax.add_patch(Rectangle((x - length / 2, y - width / 2), length, width, angle=float(np.degrees(heading_rad)),
                           rotation_point="center", **kw))


def animate_plan(result: Plan, path: PathLike, *, fps: float = 12.0, speed: float = 1.0, max_frames: int = 240,
                 dpi: float = 90.0) -> Path:
    """Write an animation of one plan among its predicted vehicles (to scale).

    Parameters
    ----------
    result : Plan
        A plan with a trajectory (``result.ok``); its ``problem`` gives the vehicles, their
        predictions :math:`x_{s,i}(t)` and the ego's body.
    path : path-like
        Output file, ``.gif`` or ``.mp4``; written atomically.
    fps : float
        Frames per second.
    speed : float
        Plan seconds per second of animation.
    max_frames : int
        Upper bound on the number of frames.
    dpi : float
        Resolution of each frame.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ValueError
        If the plan has no trajectory (a failed plan).
    iamp.MissingDependencyError
        For an ``.mp4`` without ``ffmpeg``.
    """
    ts = frame_times(result.problem.tf, fps, speed, max_frames)
    fig, draw = plan_frames(result, ts)
    return _write(fig, draw, len(ts), path, fps, dpi)


def plan_frames(result: Plan, ts: np.ndarray) -> tuple[Figure, Callable[[int], None]]:
    """The figure of :func:`animate_plan` and the function that draws its frame ``k`` (time ``ts[k]``).

    Parameters
    ----------
    result : Plan
        A plan with a trajectory.
    ts : ndarray
        The frame instants in ``[0, t_f]``.

    Returns
    -------
    (Figure, callable)
        The figure, and ``draw(k)`` that redraws its axes at ``ts[k]``: the ego's body is the
        rectangle of its ``[ego] length × width`` centred at ``(s_x, s_y)(t_k)`` and turned by
        ``atan2(v_y, v_x)``; each vehicle's body and safety box at ``x_{s,i}(t_k)``.
    """
    problem = result.problem
    X = result.require_trajectory().states(ts)
    xmin, xmax, ymin, ymax = xy_limits(result)
    edges, dividers = lane_lines(problem)
    L_e, W_e = problem.ego.ego_length, problem.ego.ego_width
    crossing = is_avoidance(result)
    contacts = [(float(t), result.states(np.array([float(t)]))[0]) for t in result.contact_times if np.isfinite(t)]
    width_in = 10.0
    height_in = max(2.2, width_in * (ymax - ymin) / (xmax - xmin) + 0.9)
    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    ax = fig.add_subplot()
    name = "crossing" if crossing else "contact"

    def draw(k: int) -> None:
        ax.clear()
        t = float(ts[k])
        for y in edges:
            ax.axhline(y, color="0.3", lw=1.2, zorder=0)
        for y in dividers:
            ax.axhline(y, color="0.5", lw=0.9, ls=(0, (8, 6)), zorder=0)
        for i, v in enumerate(problem.vehicles):
            xc = float(v.position(t))
            hx, hy = v.length / 2 + v.safety_x, v.width / 2 + v.safety_y
            ax.add_patch(Rectangle((xc - hx, v.y - hy), 2 * hx, 2 * hy, fill=False, ec=SAFETY_COLOR, lw=0.8,
                                   alpha=0.6, zorder=1))
            _oriented_body(ax, xc, v.y, 0.0, v.length, v.width, fc=VEHICLE_COLORS[i % len(VEHICLE_COLORS)], ec="k",
                           lw=0.5, zorder=2)
            ax.annotate(v.name, (xc, v.y), ha="center", va="center", fontsize=7, zorder=3)
        ax.plot(X[: k + 1, 0], X[: k + 1, 2], color=EGO_COLOR, lw=1.3, zorder=3)
        _oriented_body(ax, float(X[k, 0]), float(X[k, 2]), float(np.arctan2(X[k, 3], X[k, 1])), L_e, W_e,
                       fc=EGO_COLOR, ec="k", lw=0.5, zorder=4)
        for tc, xc in contacts:
            if tc <= t + 1e-12:
                ax.plot(xc[0], xc[2], marker="*", ms=11, color=SAFETY_COLOR, mec="k", mew=0.5, zorder=5)
        ax.set_xlim(xmin, xmax)
        ax.set_ylim(ymin, ymax)
        ax.set_aspect("equal")
        ax.set_xlabel("$x$ [m]")
        ax.set_ylabel("$y$ [m]")
        cost = f", $J$ = {result.cost:.4g}" if result.cost is not None else ""
        ax.set_title(f"{problem.name}: {result.planner} ({result.status}{cost}); t = {t:4.2f} s; "
                     f"star = {name} point; boxes = safety regions", fontsize=9)

    return fig, draw


def _read_log(path: PathLike, option: str = "--episode") -> tuple[np.ndarray, dict[str, dict[str, np.ndarray]]]:
    """``(t, {vehicle: {column: values over t}})`` of an ``iamp simulate --log`` file."""
    path = Path(path)
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
    except OSError as exc:
        raise ScenarioError(f"cannot be read ({exc.strerror or exc})", option, str(path)) from exc
    need = {"t", "vehicle", "x", "y", "vx"}
    if not rows or not need <= set(rows[0]):
        raise ScenarioError(f"is not an `iamp simulate --log` file (needs the columns {', '.join(sorted(need))})",
                            option, str(path))
    t = np.array(sorted({float(r["t"]) for r in rows}))
    index = {round(v, 6): k for k, v in enumerate(t)}
    tracks: dict[str, dict[str, np.ndarray]] = {}
    for r in rows:
        k = index[round(float(r["t"]), 6)]
        tr = tracks.setdefault(r["vehicle"], {c: np.full(len(t), np.nan) for c in ("x", "y", "vx", "vy", "lane",
                                                                                   "length", "width")})
        for c in tr:
            val = r.get(c, "")
            if val not in ("", None):
                tr[c][k] = float(val)
    if "ego" not in tracks:
        raise ScenarioError("has no ego rows", option, str(path))
    return t, tracks


def animate_episode(log: PathLike, path: PathLike, *, fps: float = 10.0, speed: float = 2.0, max_frames: int = 300,
                    window_m: float = 160.0, ego_size: tuple[float, float] = (4.8, 1.8), dpi: float = 90.0) -> Path:
    """Write an animation of a closed-loop episode from its step log (``iamp simulate --log``).

    Parameters
    ----------
    log : path-like
        The CSV step log (columns ``t, vehicle, x, y, vx, vy, ..., length, width``).
    path : path-like
        Output file, ``.gif`` or ``.mp4``; written atomically.
    fps : float
        Frames per second.
    speed : float
        Simulated seconds per second of animation.
    max_frames : int
        Upper bound on the number of frames.
    window_m : float
        Length of road shown, centred on the ego [m].
    ego_size : (float, float)
        The ego's length and width [m] where the log does not give them (the closed loop's
        ego is SUMO's 4.8 m x 1.8 m passenger car).
    dpi : float
        Resolution of each frame.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    iamp.ScenarioError
        If the log cannot be read or is not a step log.
    """
    t, tracks = _read_log(log)
    ego = tracks["ego"]
    frames = frame_times(float(t[-1] - t[0]), fps, speed, max_frames) + float(t[0])
    steps = np.searchsorted(t, frames - 1e-9).clip(0, len(t) - 1)
    ys = np.concatenate([tr["y"][np.isfinite(tr["y"])] for tr in tracks.values()])
    ymin, ymax = float(np.min(ys)) - 3.0, float(np.max(ys)) + 3.0
    # lane centres: the median lateral position of the neighbours SUMO puts in each lane index
    lane_y = np.concatenate([tr["lane"] for k, tr in tracks.items() if k != "ego"])
    all_y = np.concatenate([tr["y"] for k, tr in tracks.items() if k != "ego"])
    ok = np.isfinite(lane_y) & np.isfinite(all_y)
    centres = sorted(float(np.median(all_y[ok & (lane_y == j)])) for j in np.unique(lane_y[ok]))
    merged: list[float] = []
    for c in sorted([*centres, float(np.median(ego["y"][:5]))]):  # one lane per 1 m of lateral position
        if not merged or c - merged[-1] > 1.0:
            merged.append(c)
    centres = merged
    lines = [(a + b) / 2 for a, b in zip(centres[:-1], centres[1:])]
    half = (centres[1] - centres[0]) / 2 if len(centres) > 1 else 1.875
    edges = [centres[0] - half, centres[-1] + half]
    fig = Figure(figsize=(10.0, max(2.4, 10.0 * (ymax - ymin) / window_m + 0.9)), layout="constrained")
    ax = fig.add_subplot()
    L_e = float(ego["length"][np.isfinite(ego["length"])][0]) if np.isfinite(ego["length"]).any() else ego_size[0]
    W_e = float(ego["width"][np.isfinite(ego["width"])][0]) if np.isfinite(ego["width"]).any() else ego_size[1]
    others = sorted(k for k in tracks if k != "ego")
    colors = {k: VEHICLE_COLORS[i % len(VEHICLE_COLORS)] for i, k in enumerate(others)}

    def draw(j: int) -> None:
        ax.clear()
        k = int(steps[j])
        xe = float(ego["x"][k])
        for y in edges:
            ax.axhline(y, color="0.3", lw=1.2, zorder=0)
        for y in lines:
            ax.axhline(y, color="0.5", lw=0.9, ls=(0, (8, 6)), zorder=0)
        for vid in others:
            tr = tracks[vid]
            if not np.isfinite(tr["x"][k]) or abs(tr["x"][k] - xe) > window_m:
                continue
            L = float(tr["length"][k]) if np.isfinite(tr["length"][k]) else 4.8
            W = float(tr["width"][k]) if np.isfinite(tr["width"][k]) else 1.8
            _oriented_body(ax, float(tr["x"][k]), float(tr["y"][k]), 0.0, L, W, fc=colors[vid], ec="k", lw=0.4,
                           zorder=2)
        ax.plot(ego["x"][: k + 1], ego["y"][: k + 1], color=EGO_COLOR, lw=1.0, zorder=3)
        vy = float(ego["vy"][k]) if np.isfinite(ego["vy"][k]) else 0.0
        _oriented_body(ax, xe, float(ego["y"][k]), float(np.arctan2(vy, max(float(ego["vx"][k]), 1e-9))), L_e, W_e,
                       fc=EGO_COLOR, ec="k", lw=0.6, zorder=4)
        ax.set_xlim(xe - window_m / 2, xe + window_m / 2)
        ax.set_ylim(ymin, ymax)
        ax.set_aspect("equal")
        ax.set_xlabel("$x$ [m]")
        ax.set_ylabel("$y$ [m]")
        ax.set_title(f"closed loop: t = {t[k]:5.1f} s; the ego (with its path) at {float(ego['vx'][k]):4.1f} m/s",
                     fontsize=9)

    return _write(fig, draw, len(frames), path, fps, dpi)


def animate_commonroad(scenario: PathLike, solution: PathLike, path: PathLike, *, fps: float = 10.0,
                       max_frames: int = 200, dpi: float = 80.0,
                       window: Sequence[float] | None = None) -> Path:
    """Write an animation of a CommonRoad solution among the recorded vehicles.

    Drawn with CommonRoad's own renderer (``commonroad.visualization.mp_renderer.MPRenderer``):
    the lanelet network and every obstacle at each time step, and the ego from the solution's
    trajectory as a dynamic obstacle of the planning problem's vehicle size.

    Parameters
    ----------
    scenario : path-like
        The CommonRoad scenario XML.
    solution : path-like
        A CommonRoad solution XML for it (e.g. from ``iamp commonroad plan --out``).
    path : path-like
        Output file, ``.gif`` or ``.mp4``; written atomically.
    fps : float
        Frames per second (one frame per time step of the solution, thinned to ``max_frames``).
    max_frames : int
        Upper bound on the number of frames.
    dpi : float
        Resolution of each frame.
    window : sequence of 4 floats, optional
        ``(xmin, xmax, ymin, ymax)`` of the view; default: around the ego's path.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    iamp.MissingDependencyError
        Without the ``[commonroad]`` extra.
    iamp.ScenarioError
        If a file cannot be read.
    """
    try:
        from commonroad.common.file_reader import CommonRoadFileReader
        from commonroad.common.solution import CommonRoadSolutionReader
        from commonroad.geometry.shape import Rectangle as CRRectangle
        from commonroad.prediction.prediction import TrajectoryPrediction
        from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType
        from commonroad.visualization.draw_params import DynamicObstacleParams
        from commonroad.visualization.mp_renderer import MPRenderer
    except ImportError as exc:
        raise MissingDependencyError("a CommonRoad animation needs the [commonroad] extra "
                                     "(pip install 'iamp[commonroad]')") from exc
    try:
        scen, problems = CommonRoadFileReader(str(scenario)).open()
    except Exception as exc:
        raise ScenarioError(f"cannot be read as a CommonRoad scenario ({exc})", "SCENARIO", str(scenario)) from exc
    try:
        sol = CommonRoadSolutionReader.open(str(solution))
    except Exception as exc:
        raise ScenarioError(f"cannot be read as a CommonRoad solution ({exc})", "SOLUTION", str(solution)) from exc
    ps = sol.planning_problem_solutions[0]
    traj = ps.trajectory
    pp = problems.planning_problem_dict[ps.planning_problem_id]
    from commonroad_dc.feasibility.vehicle_dynamics import VehicleParameterMapping

    params = VehicleParameterMapping.from_vehicle_type(ps.vehicle_type)
    ego_shape = CRRectangle(length=float(params.l), width=float(params.w))
    ego = DynamicObstacle(scen.generate_object_id(), ObstacleType.CAR, ego_shape, pp.initial_state,
                          TrajectoryPrediction(traj, ego_shape))
    states = traj.state_list
    steps_all = np.array([int(s.time_step) for s in states])
    span = float(steps_all[-1] - steps_all[0]) * float(scen.dt)
    pick = frame_times(max(span, float(scen.dt)), fps * float(scen.dt) / float(scen.dt), 1.0, max_frames)
    steps = np.unique(np.clip(np.round(pick / float(scen.dt)).astype(int) + int(steps_all[0]), steps_all[0],
                              steps_all[-1]))
    xy = np.array([s.position for s in states])
    if window is None:
        cx0, cx1 = float(xy[:, 0].min()) - 40.0, float(xy[:, 0].max()) + 40.0
        cy0, cy1 = float(xy[:, 1].min()) - 25.0, float(xy[:, 1].max()) + 25.0
        window = (cx0, cx1, cy0, cy1)
    fig = Figure(figsize=(10.0, max(3.0, 10.0 * (window[3] - window[2]) / (window[1] - window[0]) + 0.6)),
                 layout="constrained")
    ax = fig.add_subplot()

    def draw(j: int) -> None:
        ax.clear()
        k = int(steps[j])
        rnd = MPRenderer(ax=ax, plot_limits=list(window))
        rnd.draw_params.time_begin = k
        rnd.draw_params.dynamic_obstacle.draw_icon = False
        scen.draw(rnd)
        pp.goal.draw(rnd)
        ego_params = DynamicObstacleParams()
        ego_params.time_begin = k
        ego_params.draw_icon = False
        ego_params.vehicle_shape.occupancy.shape.facecolor = EGO_COLOR
        ego_params.vehicle_shape.occupancy.shape.edgecolor = "k"
        ego_params.vehicle_shape.occupancy.shape.zorder = 50
        ego.draw(rnd, draw_params=ego_params)
        rnd.render()
        done = xy[steps_all <= k]
        ax.plot(done[:, 0], done[:, 1], color=EGO_COLOR, lw=1.2, zorder=60)
        ax.set_title(f"{scen.scenario_id}: iamp's solution (the ego, with its path; the goal region shaded), "
                     f"time step {k} (t = {k * float(scen.dt):.1f} s)", fontsize=9)

    return _write(fig, draw, len(steps), path, fps, dpi)
