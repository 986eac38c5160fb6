"""The one planner registry: the API, the CLI, the closed loop and the comparison select planners
from it; every QP backend is reachable; bad options are IampErrors naming the choices."""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
import pytest

import iamp
from iamp.core.tolerances import tol
from iamp.planners import registry
from iamp.planners.qp.backends import BACKENDS


@pytest.fixture(scope="module")
def one():
    return iamp.load_scenario("paper-1-poly")


@pytest.fixture(scope="module")
def two():
    return iamp.load_scenario("two-vehicle")


def _parser() -> argparse.ArgumentParser:
    from iamp.cli import plan as plan_cli

    top = argparse.ArgumentParser()
    plan_cli.add_parsers(top.add_subparsers())
    return top


def _choices(parser: argparse.ArgumentParser, option: str) -> tuple[str, ...]:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction)).choices["plan"]
    return tuple(next(a for a in sub._actions if option in a.option_strings).choices)


@pytest.mark.parametrize("kw, field, choices", [
    (dict(solver="nope"), "solver", tuple(BACKENDS)),
    (dict(planner="qp", solver="nope"), "solver", tuple(BACKENDS)),
    (dict(planner="nope"), "planner", ("pmp", "qp")),
    (dict(planner="qp", constraint="nope"), "constraint", ("equality", "avoid")),
    (dict(planner="qp", hold="nope"), "hold", ("foh", "zoh")),
    (dict(planner="qp", contact="nope"), "contact", ("grid", "refine")),
])
def test_a_bad_option_is_an_iamp_error_naming_the_choices(one, kw, field, choices):
    with pytest.raises(iamp.IampError) as info:
        iamp.plan(one, **kw)
    assert isinstance(info.value, iamp.OptionError) and info.value.field == field
    for c in choices:
        assert c in str(info.value)


def test_the_cli_offers_every_registered_backend_planner_and_constraint():
    parser = _parser()
    assert _choices(parser, "--solver") == tuple(BACKENDS) == registry.solvers()
    assert set(BACKENDS) >= {"osqp", "clarabel", "piqp", "kkt"}
    assert _choices(parser, "--planner") == registry.planners()
    assert _choices(parser, "--constraint") == registry.constraints()


def test_every_backend_solves_the_equality_qp_to_the_same_optimum(one):
    """The discretised QP of one problem through each backend: same contact node, costs equal to the
    KKT backend's (a direct solve, the independent reference) within the comparison tolerance."""
    plans = {s: iamp.plan(one, "qp", solver=s, steps=40) for s in BACKENDS}
    ref = plans["kkt"]
    assert ref.status == "optimal"
    for s, p in plans.items():
        assert p.status == "optimal", s
        assert np.allclose(p.contact_times, ref.contact_times, atol=0), s
        assert abs(p.cost - ref.cost) <= 1e-6 * ref.cost, (s, p.cost, ref.cost)


def test_the_avoidance_qp_reaches_every_backend_with_inequalities_and_refuses_kkt(two):
    ok = [s for s, cls in BACKENDS.items() if cls.supports_inequalities]
    assert set(ok) >= {"osqp", "clarabel", "piqp"} and "kkt" not in ok
    plans = {s: iamp.plan(two, "qp", constraint="avoid", solver=s, steps=30) for s in ok}
    ref = plans["clarabel"]
    assert ref.status == "optimal"
    for s, p in plans.items():
        assert p.status == "optimal", s
        assert abs(p.cost - ref.cost) <= tol("cmp_cost_rel_osqp") * max(1.0, ref.cost), (s, p.cost, ref.cost)
    with pytest.raises(iamp.OptionError, match="equality-constrained QPs only") as info:
        iamp.plan(two, "qp", constraint="avoid", solver="kkt")
    assert info.value.field == "solver" and "piqp" in str(info.value)


def test_options_are_validated_on_construction():
    spec = registry.get("qp")
    with pytest.raises(iamp.OptionError):
        spec.make_options(steps=0)
    with pytest.raises(iamp.OptionError):
        spec.make_options(steps=True)
    with pytest.raises(iamp.OptionError, match="does not apply"):
        registry.get("pmp").make_options(hold="foh")
    with pytest.raises(iamp.OptionError):
        registry.get("pmp").make_options(max_starts=0)
    opts = spec.make_options(steps=7, solver="kkt")
    assert dataclasses.is_dataclass(opts) and opts.steps == 7 and opts.hold == "foh"
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.steps = 8  # type: ignore[misc]


def test_registering_a_planner_is_one_entry_and_reaches_api_and_cli(one, monkeypatch):
    @dataclasses.dataclass(frozen=True)
    class ScaledOptions:
        factor: float = 1.0
        side: str = registry.option("left", cli="which side", choices=("left", "right"))

        def __post_init__(self) -> None:
            if self.side not in ("left", "right"):
                raise iamp.OptionError(f"unknown side {self.side!r}; choose from left, right", "side")

    class Shifted:
        """A toy planner: the PMP's plan (the registry adds nothing to the mathematics)."""

        def __init__(self, options: ScaledOptions) -> None:
            self.options = options

        def plan(self, problem):
            return registry.make_planner("pmp").plan(problem)

    monkeypatch.setattr(registry, "REGISTRY", dict(registry.REGISTRY))
    monkeypatch.setattr(registry, "CLI_OPTIONS", dict(registry.CLI_OPTIONS))  # register() keeps both
    registry.register(registry.PlannerSpec("toy", "toy", "equality", ScaledOptions, Shifted, "a toy"))
    assert "toy" in registry.planners() and "toy" in _choices(_parser(), "--planner")
    assert isinstance(registry.make_planner("toy"), registry.Planner)
    p = iamp.plan(one, "toy")
    assert p.cost == pytest.approx(iamp.plan(one).cost, rel=1e-12)
    # a field made with registry.option is a CLI flag; every field is an API keyword
    args = _parser().parse_args(["plan", "x", "--planner", "toy", "--side", "right"])
    from iamp.cli import plan as plan_cli

    plan_cli.check_options(args)
    assert plan_cli.make_planner(args).options == ScaledOptions(side="right")
    assert registry.make_planner("toy", factor=2.0).options.factor == 2.0
    with pytest.raises(iamp.OptionError, match="choose from left, right"):
        iamp.plan(one, "toy", side="up")
    with pytest.raises(iamp.OptionError, match="does not apply"):
        iamp.plan(one, "qp", side="left")
    with pytest.raises(iamp.IampError, match="--planner toy"):
        plan_cli.check_options(_parser().parse_args(["plan", "x", "--side", "right"]))
    with pytest.raises(ValueError, match="already registered"):
        registry.register(registry.PlannerSpec("toy", "toy2", "equality", ScaledOptions, Shifted))
    with pytest.raises(ValueError, match="already registered"):
        registry.register(registry.PlannerSpec("toy2", "toy", "equality", ScaledOptions, Shifted))


def test_the_closed_loop_and_the_comparison_build_their_planners_from_the_registry(one, monkeypatch):
    from iamp.comparison.agreement import runs
    from iamp.simulation import planning

    made = []
    real = registry.make_planner

    def spy(name, options=None, **values):
        made.append(name)
        return real(name, options, **values)

    monkeypatch.setattr(registry, "make_planner", spy)
    for name in ("pmp", "qp", "qp-avoid", "pmp-active"):  # pmp-active: the PMP under an active set
        planning.make_planner(name)
    runs.QPConfig(solver="clarabel", hold="foh", steps=20, path="native").planner()
    assert made == ["pmp", "qp", "qp-avoid", "pmp-active", "qp"]
    with pytest.raises(iamp.IampError, match="unknown planner"):
        planning.make_planner("nope")


def _same_plan(a, b) -> None:
    assert a.status == b.status and a.planner == b.planner
    assert a.cost == b.cost  # the same arithmetic: bit for bit
    np.testing.assert_array_equal(a.contact_times, b.contact_times)
    np.testing.assert_array_equal(a.jumps, b.jumps)


@pytest.mark.parametrize("name", ["pmp", "qp", "qp-avoid", "pmp-active", "qp-active"])
def test_prepare_plans_as_the_entry_s_planner_does(name, one, two):
    """``registry.prepare`` (the CLI's one call: options validated now, the planner built when it
    plans, through the entry's ``run`` where it has one) gives the plan ``make(...).plan`` gives,
    on a one- and a two-vehicle problem; option values the entry does not take are left out."""
    spec = registry.get(name)
    values = {"steps": 40, "hold": None, "solver": None, "safety": None, "not_an_option": 1}
    known = {k: v for k, v in values.items() if k in spec.fields}
    for problem in (one, two):
        prepared = registry.prepare(spec.planner, spec.constraint, values)
        _same_plan(prepared(problem), spec.make(**known).plan(problem))
    assert bool(spec.run) == (name in ("pmp", "qp", "qp-avoid"))


def test_prepare_validates_the_options_before_any_plan():
    with pytest.raises(iamp.IampError, match="steps"):
        registry.prepare("qp", "equality", {"steps": 0})
    with pytest.raises(iamp.IampError, match="choose from"):
        registry.prepare("qp", "equality", {"solver": "nope"})
    with pytest.raises(iamp.IampError, match="does not implement the 'avoid' constraint; use planner 'qp'$"):
        registry.prepare("pmp", "avoid", {})


def test_an_entry_without_options_names_none_when_given_one():
    @dataclasses.dataclass(frozen=True)
    class NoOptions:
        pass

    spec = registry.PlannerSpec("bare", "bare", "equality", NoOptions, lambda o: None)
    assert spec.fields == ()
    with pytest.raises(iamp.OptionError, match=r"does not apply to the 'bare' planner \(its options: none\)"):
        spec.make_options(steps=3)


def test_the_registry_keeps_the_cli_options_and_each_entry_s_field_names():
    """``CLI_OPTIONS`` (kept by ``register``) is the fields marked with ``option`` over the entries,
    the first entry's field winning; ``fields`` is the options dataclass's field names."""
    expected: dict[str, dataclasses.Field] = {}
    for spec in registry.REGISTRY.values():
        assert spec.fields == tuple(f.name for f in dataclasses.fields(spec.options)) == spec.option_names()
        for f in dataclasses.fields(spec.options):
            if "cli" in f.metadata:
                expected.setdefault(f.name, f)
    assert registry.CLI_OPTIONS == expected == registry.cli_options()
    assert registry.cli_options() is not registry.CLI_OPTIONS  # a copy: callers cannot change the table


@pytest.mark.parametrize("run", ["iamp.planners.pmp.planner", "a:b:c", ":plan_with", "module:"])
def test_a_run_that_is_not_module_colon_function_is_refused_on_construction(run):
    with pytest.raises(TypeError, match="module:function"):
        registry.PlannerSpec("x", "x", "equality", registry.REGISTRY["pmp"].options, lambda o: None, run=run)
