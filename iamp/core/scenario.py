"""Scenario files (SPEC §4): loading, validation (SPEC §6) and the built-in scenarios.

A scenario is what a user writes: the ego's boundary conditions and the surrounding
vehicles, each given either by a polynomial ``x_poly`` or by an observed ``history`` that a
predictor turns into a polynomial.  :meth:`Scenario.to_problem` produces the
:class:`~iamp.core.problem.Problem` that the planners solve.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from iamp.core.errors import HistoryError, PredictorRequiredError, ScenarioError
from iamp.core.limits import LIMITS, abs_message, exact, polynomial_message, prediction_message
from iamp.core.physical import PhysicalLimits
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.toml_lines import line_of

TOP_KEYS = {"name", "description", "ego", "vehicles", "limits"}
EGO_REQUIRED = ("tf", "x0", "y0", "vx0", "xf", "yf", "vxf")
EGO_OPTIONAL = ("vy0", "vyf", "length", "width")
#: ``[ego]`` keys whose EgoBoundary field has another name (the ego body, SPEC §9).
EGO_RENAMED = {"length": "ego_length", "width": "ego_width"}
VEHICLE_REQUIRED = ("corner", "y", "length", "width", "safety_x", "safety_y")
VEHICLE_OPTIONAL = ("name", "x_poly", "history")
HISTORY_KEYS = ("t", "x")
#: Smallest history any predictor can use; a predictor may demand more (SPEC §6).
MIN_HISTORY_SAMPLES = 2
#: Largest scenario file read (a history of ``history_samples_max`` samples fits easily).
MAX_FILE_BYTES = 16 * 1024 * 1024


class _Prediction(Protocol):
    x_poly: Sequence[float]


class PredictorLike(Protocol):
    """What :meth:`Scenario.to_problem` needs of a predictor."""

    def predict(self, history: History, tf: float) -> Any: ...


@dataclass(frozen=True)
class Predicted:
    """A :class:`PredictorLike` answering from predictions already made (by history, looked up by
    identity): the prediction layer predicts a scenario's histories first and hands the results
    to :meth:`Scenario.to_problem`, so the core reads predictions and never calls a predictor
    back (``scripts/walk.py``: no upward call).  A history whose prediction raised raises the
    same exception here, when the core asks for it (the refusal then names its TOML line)."""

    by_history: Mapping[int, object]
    name: str | None = None
    dt: float | None = None

    def predict(self, history: History, tf: float) -> Any:
        out = self.by_history[id(history)]
        if isinstance(out, BaseException):
            raise out
        return out


@dataclass(frozen=True)
class History:
    """An observed longitudinal history of a vehicle before ``t = 0`` (SPEC §4 ``history``).

    The samples ``(t_k, x_k)`` a predictor turns into the vehicle's future trajectory
    (:meth:`iamp.Predictor.predict`).  Validated on construction (SPEC §6): the times are
    strictly increasing, end at ``t = 0``, start no earlier than the longest accepted span
    and are at least the shortest accepted step apart; the positions are finite and bounded.

    Parameters
    ----------
    t : array_like of float
        Sample times [s], strictly increasing, the last one 0 (the present).
    x : array_like of float
        Longitudinal positions at ``t`` [m], as many as ``t``.
    field : str
        The scenario field refusals name (default ``"vehicles[0].history"``).
    source : str, optional
        The file the history came from (named by refusals).

    Raises
    ------
    iamp.HistoryError
        Fewer than two samples, ``t`` and ``x`` of different lengths, times not strictly
        increasing, not ending at 0, too long, too dense or positions beyond the bound
        (the message names the field, e.g. ``vehicles[0].history.t``).
    iamp.ScenarioError
        A value that is not a finite number.

    Examples
    --------
    >>> import numpy as np
    >>> from iamp import History
    >>> t = np.linspace(-2.0, 0.0, 21)            # 2 s at 10 Hz, ending now
    >>> history = History(t=t, x=20.0 * t)        # 20 m/s, at x = 0 now
    >>> history.duration, len(history.t)
    (2.0, 21)
    """

    t: npt.NDArray[np.float64]
    x: npt.NDArray[np.float64]
    field: str = "vehicles[0].history"
    source: str | None = None

    def __post_init__(self) -> None:
        t = _number_list(self.t, f"{self.field}.t", self.source)
        x = _number_list(self.x, f"{self.field}.x", self.source)
        cap = int(LIMITS["history_samples_max"])
        if len(t) > cap:
            raise HistoryError(f"has {len(t)} samples; at most {cap} are accepted", f"{self.field}.t", self.source)
        if len(t) != len(x):
            raise HistoryError(
                f"t and x have different lengths ({len(t)} and {len(x)})", f"{self.field}.x", self.source
            )
        if len(t) < MIN_HISTORY_SAMPLES:
            raise HistoryError(
                f"needs at least {MIN_HISTORY_SAMPLES} samples (got {len(t)})", f"{self.field}.t", self.source
            )
        if np.any(np.diff(t) <= 0):
            k = int(np.argmax(np.diff(t) <= 0)) + 1
            raise HistoryError(f"must be strictly increasing (t[{k}] = {t[k]} after {t[k - 1]})",
                               f"{self.field}.t", self.source)
        if abs(t[-1]) > 1e-9:
            raise HistoryError(f"must end at 0 (last sample at {t[-1]})", f"{self.field}.t", self.source)
        span, step = LIMITS["history_span_max_s"], LIMITS["history_step_min_s"]
        if t[0] < -span:
            raise HistoryError(f"must start at t >= {-span:g} s (first sample at {exact(t[0])})",
                               f"{self.field}.t", self.source)
        # a nominal step of exactly the minimum passes: the difference of two decimal times
        # is off by rounding (-0.0002 - -0.0003 = 9.999999999999999e-05), so compare with a margin
        short = np.diff(t) < step * (1.0 - 1e-6)
        if np.any(short):
            k = int(np.argmax(short)) + 1
            raise HistoryError(f"samples must be at least {step:g} s apart (t[{k}] - t[{k - 1}] = "
                               f"{t[k] - t[k - 1]:.3g} s)", f"{self.field}.t", self.source)
        big = np.abs(x) > LIMITS["position_max_m"]
        if big.any():
            k = int(np.argmax(big))
            raise HistoryError(str(abs_message(float(x[k]), LIMITS["position_max_m"], "m")),
                               f"{self.field}.x[{k}]", self.source)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "x", x)

    @property
    def duration(self) -> float:
        """``t[-1] − t[0]`` [s]."""
        return float(self.t[-1] - self.t[0])

    def require(self, min_samples: int = 0, min_duration: float = 0.0) -> None:
        """Check that the history is long enough for a predictor.

        Parameters
        ----------
        min_samples : int
            The fewest samples the predictor needs.
        min_duration : float
            The shortest span ``t[-1] - t[0]`` the predictor needs [s].

        Raises
        ------
        iamp.HistoryError
            The history has fewer samples or a shorter span (the message says both numbers
            and names the field).
        """
        if len(self.t) < min_samples:
            raise HistoryError(f"is shorter than the predictor needs ({len(self.t)} samples, "
                               f"needs {min_samples})", f"{self.field}.t", self.source)
        if self.duration + 1e-9 < min_duration:
            raise HistoryError(f"is shorter than the predictor needs ({self.duration:g} s, needs "
                               f"{min_duration:g} s)", f"{self.field}.t", self.source)


@dataclass(frozen=True)
class VehicleSpec:
    """A vehicle as written in the file: geometry plus ``x_poly`` or ``history``."""

    name: str
    corner: str
    y: float
    length: float
    width: float
    safety_x: float
    safety_y: float
    x_poly: tuple[float, ...] | None
    history: History | None
    field: str
    source: str | None

    def with_poly(self, x_poly: Sequence[float]) -> SurroundingVehicle:
        """The :class:`SurroundingVehicle` of this geometry moving along ``x_poly``."""
        return SurroundingVehicle(
            x_poly=tuple(float(c) for c in x_poly), corner=self.corner, y=self.y, length=self.length,
            width=self.width, safety_x=self.safety_x, safety_y=self.safety_y, name=self.name,
            field_prefix=self.field, source=self.source,
        )


@dataclass(frozen=True)
class Scenario:
    """A validated scenario file (SPEC §4): what a user writes, before prediction.

    Its vehicles are given either by a polynomial ``x_poly`` or by an observed ``history``;
    :meth:`to_problem` turns it into the :class:`Problem` the planners solve, predicting
    the history vehicles.  :func:`iamp.load_scenario` does both steps at once; load one with
    :func:`iamp.core.scenario.load_scenario` (a path or a built-in name) or
    :func:`iamp.core.scenario.loads_scenario` (TOML text).

    Parameters
    ----------
    name : str
        The scenario's name (the file's ``name``, else the file's stem).
    description : str
        The file's ``description`` (may be empty).
    ego : EgoBoundary
        The ``[ego]`` table.
    vehicles : tuple of iamp.core.scenario.VehicleSpec
        The ``[[vehicles]]`` tables as written: geometry plus ``x_poly`` or ``history``.
    source : str, optional
        The file (``builtin:NAME`` for a built-in scenario).
    text : str, optional
        The TOML text, so that a refusal can name the line of its field (not compared).
    limits : iamp.core.physical.PhysicalLimits, optional
        The ``[limits]`` table (SPEC §14); ``None`` when the file has none (the paper's problem).

    Attributes
    ----------
    needs_prediction : bool
        Whether any vehicle is given by a history (and so needs a predictor).

    Examples
    --------
    >>> from iamp.core.scenario import load_scenario
    >>> scenario = load_scenario("paper-1")
    >>> scenario.needs_prediction, len(scenario.vehicles[0].history.t)
    (True, 31)
    """

    name: str
    description: str
    ego: EgoBoundary
    vehicles: tuple[VehicleSpec, ...]
    source: str | None = None
    text: str | None = field(default=None, compare=False, repr=False)
    #: The ``[limits]`` table (SPEC §14); ``None`` when the file has none (the paper's problem).
    limits: PhysicalLimits | None = None

    def __post_init__(self) -> None:
        self.needs_prediction  # noqa: B018 - once, here: later reads are plain attributes

    @cached_property
    def needs_prediction(self) -> bool:
        """Whether any vehicle is given by a history (and so needs a predictor)."""
        return any(v.history is not None for v in self.vehicles)

    def locate(self, exc: ScenarioError) -> ScenarioError:
        """Add the TOML line of an error's field to its source.

        Parameters
        ----------
        exc : iamp.ScenarioError
            A refusal about a field of this scenario.

        Returns
        -------
        iamp.ScenarioError
            ``exc`` again (same class, message and field) with the source ``file:line`` when
            the field's line is known, else ``exc`` itself.
        """
        return with_line(exc, self.text, self.source)

    def to_problem(self, predictor: PredictorLike | None = None) -> tuple[Problem, list[Any]]:
        """Turn the scenario into a :class:`Problem`.

        Vehicles with a ``history`` are predicted by ``predictor`` over the horizon ``t_f``;
        vehicles given by ``x_poly`` pass through unchanged.  The same polynomial object
        reaches every planner that solves this problem.

        Parameters
        ----------
        predictor : object, optional
            Anything with ``predict(history, tf)`` returning an object whose ``x_poly`` is the
            vehicle's polynomial (:class:`iamp.Predictor`); may be ``None`` when no vehicle
            has a history.

        Returns
        -------
        problem : Problem
            The plannable problem.
        predictions : list
            One entry per vehicle: the predictor's result, or ``None`` for a vehicle given by
            ``x_poly``.

        Raises
        ------
        iamp.ScenarioError
            A history vehicle without a predictor, a predictor whose time step does not fit
            the horizon, or a predicted polynomial beyond the bounds; the predictor's own
            refusals (:class:`iamp.HistoryError`) pass through.  Every refusal names the TOML
            line of its field.

        Examples
        --------
        >>> import iamp
        >>> from iamp.core.scenario import load_scenario
        >>> problem, predictions = load_scenario("paper-1").to_problem(iamp.Predictor.default())
        >>> problem.m, predictions[0].model
        (1, 'builtin')
        """
        try:
            return self._to_problem(predictor)
        except ScenarioError as exc:
            raise self.locate(exc) from None

    def _to_problem(self, predictor: PredictorLike | None) -> tuple[Problem, list[Any]]:
        vehicles: list[SurroundingVehicle] = []
        predictions: list[Any] = []
        if predictor is not None and self.needs_prediction:
            dt = getattr(predictor, "dt", None)
            if isinstance(dt, (int, float)):
                msg = prediction_message(self.ego.tf, float(dt))
                if msg is not None:
                    name = getattr(predictor, "name", None)
                    raise ScenarioError(f"the predictor model's time step: {msg}", "dt",
                                        str(name) if name is not None else None)
        for v in self.vehicles:
            if v.history is None:
                vehicles.append(v.with_poly(v.x_poly or ()))
                predictions.append(None)
                continue
            if predictor is None:
                raise PredictorRequiredError(
                    "is an observed history and needs a predictor to become a trajectory",
                    f"{v.field}.history", self.source)
            pred = predictor.predict(v.history, self.ego.tf)
            msg = polynomial_message(pred.x_poly, self.ego.tf)
            if msg is not None:
                raise ScenarioError(f"the trajectory predicted from this history {msg}", f"{v.field}.history",
                                    self.source)
            vehicles.append(v.with_poly(pred.x_poly))
            predictions.append(pred)
        return Problem(self.ego, tuple(vehicles), self.name, self.limits), predictions


def _number_list(value: object, field: str, source: str | None) -> npt.NDArray[np.float64]:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)):
        raise ScenarioError("must be a list of numbers", field, source)
    out = []
    for k, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ScenarioError(f"must be a number (got {_short(v)})", f"{field}[{k}]", source)
        try:
            f = float(v)
        except OverflowError:
            raise ScenarioError(f"must be finite (got an integer of {len(str(v))} digits)", f"{field}[{k}]",
                                source) from None
        if not math.isfinite(f):
            raise ScenarioError(f"must be finite (got {v})", f"{field}[{k}]", source)
        out.append(f)
    return np.array(out, dtype=float)


def _short(value: object, n: int = 40) -> str:
    """``repr(value)`` cut to ``n`` characters (a refusal is one line)."""
    r = repr(value)
    return r if len(r) <= n else r[: n - 3] + "..."


def _check_keys(table: object, required: Sequence[str], optional: Sequence[str], prefix: str,
                source: str | None) -> None:
    if not isinstance(table, dict):
        raise ScenarioError("must be a table", prefix, source)
    for key in table:
        if key not in required and key not in optional:
            raise ScenarioError(f"unknown key {_short(key)}", f"{prefix}.{key}" if prefix else key, source)
    for key in required:
        if key not in table:
            raise ScenarioError("is missing", f"{prefix}.{key}" if prefix else key, source)


def parse_scenario(data: dict[str, Any], source: str | None = None, default_name: str = "scenario") -> Scenario:
    """Validate a decoded TOML document against SPEC §4 and §6 and the bounds of
    :mod:`iamp.core.limits`."""
    _check_keys(data, ("ego", "vehicles"), ("name", "description", "limits"), "", source)
    name = data.get("name", default_name)
    description = data.get("description", "")
    if not isinstance(name, str):
        raise ScenarioError("must be a string", "name", source)
    if not isinstance(description, str):
        raise ScenarioError("must be a string", "description", source)
    ego_t = data["ego"]
    _check_keys(ego_t, EGO_REQUIRED, EGO_OPTIONAL, "ego", source)
    ego = EgoBoundary(**{EGO_RENAMED.get(k, k): ego_t[k] for k in EGO_REQUIRED + EGO_OPTIONAL if k in ego_t},
                      source=source)
    vehicles_t = data["vehicles"]
    if not isinstance(vehicles_t, list) or not vehicles_t:
        raise ScenarioError("needs at least one [[vehicles]] table", "vehicles", source)
    if len(vehicles_t) > LIMITS["vehicles_max"]:
        raise ScenarioError(f"at most {LIMITS['vehicles_max']:g} vehicles are accepted (got {len(vehicles_t)})",
                            "vehicles", source)
    specs: list[VehicleSpec] = []
    names: dict[str, int] = {}
    for i, vt in enumerate(vehicles_t):
        prefix = f"vehicles[{i}]"
        _check_keys(vt, VEHICLE_REQUIRED, VEHICLE_OPTIONAL, prefix, source)
        has_poly, has_hist = "x_poly" in vt, "history" in vt
        if has_poly == has_hist:
            raise ScenarioError("needs exactly one of x_poly and history (got "
                                f"{'both' if has_poly else 'neither'})", f"{prefix}.x_poly", source)
        vname = vt.get("name", f"sv{i + 1}")
        if not isinstance(vname, str):
            raise ScenarioError("must be a string", f"{prefix}.name", source)
        if vname in names:
            raise ScenarioError(f"duplicate vehicle name {_short(vname)} (also vehicles[{names[vname]}])",
                                f"{prefix}.name", source)
        names[vname] = i
        history = None
        x_poly = None
        if has_hist:
            ht = vt["history"]
            _check_keys(ht, HISTORY_KEYS, (), f"{prefix}.history", source)
            history = History(ht["t"], ht["x"], field=f"{prefix}.history", source=source)
        else:
            x_poly = tuple(float(c) for c in _number_list(vt["x_poly"], f"{prefix}.x_poly", source))
        geometry = {k: vt[k] for k in VEHICLE_REQUIRED}
        if not isinstance(geometry["corner"], str):
            raise ScenarioError("must be a string such as 'front-lower'", f"{prefix}.corner", source)
        # Validate geometry (and x_poly) through the problem object itself.
        probe = SurroundingVehicle(x_poly=x_poly if x_poly is not None else (0.0,), name=vname,
                                   field_prefix=prefix, source=source, **geometry)
        if x_poly is not None:
            msg = polynomial_message(x_poly, ego.tf)
            if msg is not None:
                raise ScenarioError(msg, f"{prefix}.x_poly", source)
        specs.append(VehicleSpec(name=vname, corner=probe.corner, y=probe.y, length=probe.length,
                                 width=probe.width, safety_x=probe.safety_x, safety_y=probe.safety_y,
                                 x_poly=x_poly, history=history, field=prefix, source=source))
    limits = None
    if "limits" in data:
        if not isinstance(data["limits"], dict):
            raise ScenarioError("must be a table [limits]", "limits", source)
        limits = PhysicalLimits.from_table(data["limits"], source)
    return Scenario(name=name, description=description, ego=ego, vehicles=tuple(specs), source=source,
                    limits=limits)


def with_line(exc: ScenarioError, text: str | None, source: str | None) -> ScenarioError:
    """``exc`` again, its source extended to ``file:line`` when the field's line is known."""
    if text is None or exc.source != source or source is None:
        return exc
    line = line_of(text, exc.field)
    if line is None:
        return exc
    return type(exc)(exc.message, exc.field, f"{source}:{line}")


def _syntax_line(message: str) -> int | None:
    m = re.search(r"at line (\d+)", message)
    return int(m.group(1)) if m else None


def loads_scenario(text: str, source: str | None = None, default_name: str = "scenario") -> Scenario:
    """Parse scenario TOML text (TOML 1.0: a carriage return only as part of CRLF)."""
    lone_cr = re.search("\r(?!\n)", text)
    if lone_cr:
        line = text.count("\n", 0, lone_cr.start()) + 1
        raise ScenarioError("TOML syntax error: a bare carriage return (CR without LF) is not allowed in TOML",
                            None, f"{source}:{line}" if source else f"line {line}")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        at = _syntax_line(str(exc))
        if at is None and "end of document" in str(exc):
            at = text.rstrip("\n").count("\n") + 1  # the last line: where the document stopped
        where = f"{source}:{at}" if source and at else source
        raise ScenarioError(f"TOML syntax error: {exc}", None, where) from None
    except (RecursionError, MemoryError):
        raise ScenarioError("TOML document is nested too deeply or too large to parse", None, source) from None
    try:
        scenario = parse_scenario(data, source, default_name)
    except ScenarioError as exc:
        raise with_line(exc, text, source) from None
    return Scenario(scenario.name, scenario.description, scenario.ego, scenario.vehicles, scenario.source, text,
                    scenario.limits)


# --- built-in scenarios ---------------------------------------------------------------

def builtin_names() -> list[str]:
    """Names of the scenarios shipped inside the package."""
    folder = resources.files("iamp.core") / "scenarios"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def builtin_text(name: str) -> str:
    """The TOML text of a built-in scenario."""
    return (resources.files("iamp.core") / "scenarios" / f"{name}.toml").read_text(encoding="utf-8")


def load_scenario(path_or_name: str | Path) -> Scenario:
    """Load a scenario from a file path or by the name of a built-in scenario."""
    p = Path(path_or_name)
    if p.is_file():
        try:
            size = p.stat().st_size
        except OSError as exc:
            raise ScenarioError(f"cannot be read ({exc.strerror or exc})", None, str(p)) from None
        if size > MAX_FILE_BYTES:
            raise ScenarioError(f"is {size} bytes; a scenario file may have at most {MAX_FILE_BYTES} bytes",
                                None, str(p))
        try:
            # bytes, not read_text(): universal newlines would turn a bare CR (invalid TOML) into LF
            raw = p.read_bytes()
        except OSError as exc:
            raise ScenarioError(f"cannot be read ({exc.strerror or exc})", None, str(p)) from None
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            line = raw.count(b"\n", 0, exc.start) + 1
            raise ScenarioError(f"cannot be read: not UTF-8 (byte {raw[exc.start]:#04x} at offset {exc.start}; "
                                "TOML files are UTF-8)", None, f"{p}:{line}") from None
        return loads_scenario(text, str(p), default_name=p.stem)
    name = str(path_or_name)
    if name in builtin_names():
        return loads_scenario(builtin_text(name), f"builtin:{name}", default_name=name)
    if p.exists():
        raise ScenarioError("is not a file", None, str(p))
    raise ScenarioError(f"no such file or built-in scenario (built-ins: {', '.join(builtin_names())})",
                        None, str(p))
