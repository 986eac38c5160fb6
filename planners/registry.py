r"""The one planner registry: name -> planner factory and its options class.

Every front end selects a planner here — the API (:func:`iamp.plan`), the CLI (its
``--planner``/``--constraint``/``--solver`` choices and help are generated from this table),
the closed loop (:mod:`iamp.simulation.planning`) and the comparison.  A planner is anything
with ``plan(problem) -> Plan`` (:class:`Planner`); its options are one frozen dataclass,
validated on construction (errors: :class:`~iamp.core.errors.OptionError`, an
:class:`~iamp.IampError`).

How to add a planner (one entry; nothing else to edit)
------------------------------------------------------
1. Write the options as a frozen dataclass next to the planner (``planners/<pkg>/options.py``);
   validate every field in ``__post_init__`` and raise
   :class:`~iamp.core.errors.OptionError` ``(message naming the choices, field_name)``.  A field
   made with :func:`option` (``option("continuous", cli="help text", choices=(...))``) becomes
   the CLI flag ``--field-name`` automatically; plain fields are API-only
   (``iamp.plan(problem, "name", field=value)``).  ``steps``, ``solver``, ``hold`` and ``contact``
   already are CLI flags: reuse those names for those meanings.
2. Write the planner: any class with ``plan(problem) -> Plan`` (:class:`Planner`) that takes the
   options; it returns a failed :class:`~iamp.core.plan.Plan`, never raises, on numerical trouble.
3. Register it at the bottom of this module (the built-in entries are there)::

       register(PlannerSpec(
           name="pmp-bounded",          # unique key: API/simulation/campaign name
           planner="pmp-bounded",       # --planner / iamp.plan(problem, planner) value, JSON "planner"
           constraint="equality",       # --constraint value it implements ("equality", "avoid", ...)
           options=BoundedOptions,      # the dataclass of step 1
           factory=BoundedPMPPlanner,   # options -> Planner (a class taking the options, or a function)
           summary="PMP with the physical limits of Problem.limits",   # one line of --planner help
       ))

   Optionally ``run="iamp.planners.<pkg>.planner:plan_with"``: a function ``(options, problem,
   **kwargs) -> Plan`` in the planner's module that builds the planner and plans in one call
   (what :func:`prepare`, the CLI's one call into the registry, hands out; without it,
   ``factory(options).plan``).

   A variant of an existing family with another constraint kind shares ``planner`` and differs
   in ``constraint`` (as ``qp``/``qp-avoid``: ``--planner qp --constraint avoid``).  A planner
   that lives above the planners layer (a closed-loop baseline in ``simulation/``) calls
   :func:`register` in its own module instead (``planners`` must not import ``simulation``);
   it is then registered wherever that module is imported.

Then: ``iamp.plan``, ``iamp plan --planner``, ``--constraint`` and their help, the closed loop's
``--planner`` (:data:`iamp.simulation.planning.PLANNERS`; its small-grid options in
``SIM_OPTIONS``) and :func:`make_planner` (the comparison) all offer it; bad option values are
:class:`~iamp.core.errors.OptionError` naming the choices.  Test it in ``tests/test_registry.py``
style: the registry finds it, the CLI offers it, its bad options raise.

Built-in entries (``name``: ``planner`` / ``constraint``):

============= ========= =========== =====================================================
name          planner   constraint  planner class
============= ========= =========== =====================================================
``pmp``       pmp       equality    :class:`~iamp.planners.pmp.planner.PMPPlanner`
``qp``        qp        equality    :class:`~iamp.planners.qp.planner.QPPlanner`
``qp-avoid``  qp        avoid       :class:`~iamp.planners.avoid.planner.AvoidQPPlanner`
``pmp-active`` pmp      active      :class:`~iamp.planners.active_set.ActiveSetPlanner` (PMP)
``qp-active`` qp        active      :class:`~iamp.planners.active_set.ActiveSetPlanner` (QP)
============= ========= =========== =====================================================
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from iamp.core.errors import OptionError
from iamp.core.plan import Plan
from iamp.core.problem import Problem

from .active_set import ActiveSetPlanner
from .avoid.options import AvoidOptions
from .pmp.options import PMPOptions
from .qp.backends import BACKENDS
from .qp.options import QPOptions

if TYPE_CHECKING:  # the planners are imported by their factories, on first use (issue 22 item 10:
    # `iamp plan` with the PMP must not import scipy.optimize and the QP solvers)
    from .avoid.planner import AvoidQPPlanner
    from .pmp.planner import PMPPlanner
    from .qp.planner import QPPlanner


@runtime_checkable
class Planner(Protocol):
    """What every planner offers: ``plan(problem) -> Plan`` (never raises for numerical trouble:
    a failed plan has a failure status)."""

    def plan(self, problem: Problem, /) -> Plan:
        """Plan the lane change of ``problem``."""
        ...


@dataclass(frozen=True)
class PlannerSpec:
    """One registry entry (see the module docstring).

    Attributes
    ----------
    name : str
        The registry key, unique.
    planner : str
        The family the user names with ``--planner`` / ``planner=`` (several entries may share it,
        one per ``constraint``).
    constraint : str
        The constraint kind (``"equality"``: the paper's corner equality; ``"avoid"``: the
        avoidance inequalities).
    options : type
        The options dataclass (frozen, validated in ``__post_init__``).
    factory : callable
        ``factory(options) -> Planner``.
    summary : str
        One line for the CLI help.
    run : str
        Optional ``"module:function"``: a function ``(options, problem, **kwargs) -> Plan`` in the
        planner's own module that builds the planner and plans in one call, so that a front end
        (:func:`prepare`) enters the planner's module once; empty: ``factory(options).plan``.
    fields : tuple of str
        The names of the options' fields (computed on construction; :meth:`option_names`).
    """

    name: str
    planner: str
    constraint: str
    options: type[Any]
    factory: Callable[[Any], Planner]
    summary: str = ""
    run: str = ""
    fields: tuple[str, ...] = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not dataclasses.is_dataclass(self.options):
            raise TypeError(f"options of planner {self.name!r} must be a dataclass")
        if self.run and (self.run.count(":") != 1 or not all(self.run.split(":"))):
            raise TypeError(f"run of planner {self.name!r} must be 'module:function' (got {self.run!r})")
        object.__setattr__(self, "fields", tuple(f.name for f in dataclasses.fields(self.options)))

    def option_names(self) -> tuple[str, ...]:
        """The fields of the options dataclass."""
        return self.fields

    def make_options(self, **values: Any) -> Any:
        """The options with ``values`` (``None`` means: the default); unknown names are refused."""
        known = set(self.option_names())
        for key in values:
            if key not in known:
                raise OptionError(f"does not apply to the {self.name!r} planner (its options: "
                                  f"{', '.join(sorted(known)) or 'none'})", key)
        return self.options(**{k: v for k, v in values.items() if v is not None})

    def make(self, options: Any = None, **values: Any) -> Planner:
        """A planner of this entry, from an options object or from option values."""
        if options is None:
            options = self.make_options(**values)
        elif values:
            options = dataclasses.replace(options, **values)
        return self.factory(options)


#: name -> entry, in registration order.
REGISTRY: dict[str, PlannerSpec] = {}

#: The options marked with :func:`option` over every entry (the first entry's field wins), kept by
#: :func:`register`: what :func:`cli_options` returns, readable without a call.
CLI_OPTIONS: dict[str, dataclasses.Field[Any]] = {}


def register(spec: PlannerSpec, *, replace: bool = False) -> PlannerSpec:
    """Add ``spec`` to the registry (a name may be registered once unless ``replace``)."""
    if spec.name in REGISTRY and not replace:
        raise ValueError(f"planner {spec.name!r} is already registered")
    if not replace and any(s.planner == spec.planner and s.constraint == spec.constraint
                           for s in REGISTRY.values()):
        raise ValueError(f"planner {spec.planner!r} with constraint {spec.constraint!r} is already registered")
    REGISTRY[spec.name] = spec
    CLI_OPTIONS.clear()
    for entry in REGISTRY.values():
        for f in dataclasses.fields(entry.options):
            if "cli" in f.metadata:
                CLI_OPTIONS.setdefault(f.name, f)
    return spec


def names() -> tuple[str, ...]:
    """Every registered name."""
    return tuple(REGISTRY)


def planners() -> tuple[str, ...]:
    """The ``planner`` values (the CLI's ``--planner`` choices), in registration order."""
    return tuple(dict.fromkeys(s.planner for s in REGISTRY.values()))


def constraints() -> tuple[str, ...]:
    """The constraint kinds (the CLI's ``--constraint`` choices)."""
    return tuple(dict.fromkeys(s.constraint for s in REGISTRY.values()))


def solvers() -> tuple[str, ...]:
    """Every registered QP backend (the CLI's ``--solver`` choices)."""
    return tuple(BACKENDS)


def get(name: str) -> PlannerSpec:
    """The entry registered as ``name``; :class:`OptionError` naming the choices otherwise."""
    try:
        return REGISTRY[name]
    except (KeyError, TypeError):
        raise OptionError(f"unknown planner {name!r}; choose from {', '.join(REGISTRY)}", "planner") from None


def lookup(planner: str, constraint: str = "equality") -> PlannerSpec:
    """The entry of ``planner`` (a ``--planner`` value) with ``constraint``.

    Raises :class:`OptionError` naming the choices for an unknown planner or constraint, or when the
    planner does not implement the constraint.
    """
    if planner not in planners():
        raise OptionError(f"unknown planner {planner!r}; choose from {', '.join(planners())}", "planner")
    if constraint not in constraints():
        raise OptionError(f"unknown constraint {constraint!r}; choose from {', '.join(constraints())}",
                          "constraint")
    for spec in REGISTRY.values():
        if spec.planner == planner and spec.constraint == constraint:
            return spec
    offer = [s.planner for s in REGISTRY.values() if s.constraint == constraint]
    raise OptionError(f"the {planner!r} planner does not implement the {constraint!r} constraint; "
                      f"{'use planner ' + ' or '.join(repr(p) for p in offer) if offer else 'no planner does'}",
                      "constraint")


def option(default: Any, *, cli: str = "", choices: tuple[str, ...] | None = None) -> Any:
    """A field of an options dataclass that the CLI offers as ``--NAME`` (``cli``: its help text;
    ``choices``: the accepted values).  Fields made with :func:`dataclasses.field` are API-only."""
    return dataclasses.field(default=default, metadata={"cli": cli, "choices": choices})


def cli_options() -> dict[str, dataclasses.Field[Any]]:
    """The options marked with :func:`option` over every entry (the first entry's field wins):
    the CLI adds ``--NAME`` for each one it does not already define."""
    return dict(CLI_OPTIONS)


def make_planner(name: str, options: Any = None, **values: Any) -> Planner:
    """``get(name).make(options, **values)``: a planner by registry name."""
    return get(name).make(options, **values)


def prepare(planner: str, constraint: str, values: Mapping[str, Any]) -> Callable[..., Plan]:
    """``plan(problem, **kwargs) -> Plan`` of the entry ``planner``/``constraint`` with the option
    ``values`` it accepts (the others are left out; ``None``: the default), the options validated
    now (:class:`OptionError`).

    One call for a front end: the entry's ``run`` function (see :class:`PlannerSpec`) builds the
    planner and plans when the returned callable is called, so the planner's module is entered once
    (``scripts/walk.py``); without one, ``factory(options).plan``.
    """
    spec = lookup(planner, constraint)
    options = spec.make_options(**options_of(spec, values))
    if not spec.run:
        return spec.factory(options).plan
    module, function = spec.run.split(":")
    return functools.partial(getattr(importlib.import_module(module), function), options)


def accepting(option: str) -> tuple[str, ...]:
    """The ``planner`` values whose options have the field ``option`` (for the CLI's refusals)."""
    return tuple(dict.fromkeys(s.planner for s in REGISTRY.values() if option in s.option_names()))


def options_of(spec: PlannerSpec, values: Mapping[str, Any]) -> dict[str, Any]:
    """The subset of ``values`` that ``spec``'s options accept (the others are left out)."""
    known = set(spec.option_names())
    return {k: v for k, v in values.items() if k in known}


def _pmp(o: PMPOptions) -> PMPPlanner:
    from .pmp.planner import PMPPlanner

    return PMPPlanner.from_options(o)


def _qp(o: QPOptions) -> QPPlanner:
    from .qp.planner import QPPlanner

    return QPPlanner.from_options(o)


def _avoid(o: AvoidOptions) -> AvoidQPPlanner:
    from .avoid.planner import AvoidQPPlanner

    return AvoidQPPlanner.from_options(o)


def _pmp_active(o: PMPOptions) -> ActiveSetPlanner:
    return ActiveSetPlanner(_pmp(o), "pmp")


def _qp_active(o: QPOptions) -> ActiveSetPlanner:
    return ActiveSetPlanner(_qp(o), "qp")


register(PlannerSpec("pmp", "pmp", "equality", PMPOptions, _pmp,
                     "the indirect method (PMP, jump conditions, global contact times)",
                     run="iamp.planners.pmp.planner:plan_with"))
register(PlannerSpec("qp", "qp", "equality", QPOptions, _qp,
                     "the discretised QP with a search over grid contact times",
                     run="iamp.planners.qp.planner:plan_with"))
register(PlannerSpec("qp-avoid", "qp", "avoid", AvoidOptions, _avoid,
                     "the avoidance QP: the ego stays out of every safety region",
                     run="iamp.planners.avoid.planner:plan_with"))
register(PlannerSpec("pmp-active", "pmp", "active", PMPOptions, _pmp_active,
                     "the paper's equality only on the vehicles in the way, chosen by the jump's sign (SPEC §14)"))
register(PlannerSpec("qp-active", "qp", "active", QPOptions, _qp_active,
                     "the equality QP with the corner imposed only on the vehicles in the way (SPEC §14)"))

__all__ = ["CLI_OPTIONS", "REGISTRY", "Planner", "PlannerSpec", "accepting", "cli_options", "constraints", "get",
           "lookup", "make_planner", "names", "option", "options_of", "planners", "prepare", "register", "solvers"]
