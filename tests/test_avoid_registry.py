"""The avoidance and active-set options through the planner registry (iamp.plan and the CLI):
``constraint`` = equality | active | avoid, ``safety`` = continuous | nodes."""

from __future__ import annotations

import json

import pytest

import iamp
from iamp.core.errors import OptionError
from iamp.planners import registry
from iamp.planners.active_set import ActiveSetPlanner
from iamp.planners.avoid import AvoidQPPlanner
from iamp.planners.examples import builtin_problem


def test_registry_has_the_active_and_avoid_entries():
    assert registry.lookup("pmp", "active").name == "pmp-active"
    assert registry.lookup("qp", "active").name == "qp-active"
    assert "active" in registry.constraints() and "safety" in registry.cli_options()
    p = registry.make_planner("qp-avoid", safety="nodes", steps=20)
    assert isinstance(p, AvoidQPPlanner) and p.safety == "nodes" and p.steps == 20
    assert isinstance(registry.make_planner("qp-active", steps=30), ActiveSetPlanner)


def test_iamp_plan_reaches_the_options():
    prob = builtin_problem("two-vehicle")
    act = iamp.plan(prob, "pmp", constraint="active")
    assert "active_set" in act.info and act.info["active_set"]["imposed"] == []
    nodes = iamp.plan(prob, "qp", constraint="avoid", safety="nodes", steps=20)
    assert nodes.info["avoidance"]["safety"] == "nodes"
    cont = iamp.plan(prob, "qp", constraint="avoid", steps=20)
    assert cont.info["safety_mode"] == "continuous"
    with pytest.raises(OptionError, match="continuous, nodes"):
        iamp.plan(prob, "qp", constraint="avoid", safety="sometimes")
    with pytest.raises(OptionError):
        iamp.plan(prob, "pmp", constraint="avoid")
    with pytest.raises(OptionError):
        iamp.plan(prob, "qp", constraint="avoid", max_solves=0)


def test_cli_safety_flag(capsys):
    from iamp.cli.main import main

    rc = main(["plan", "two-vehicle", "--planner", "qp", "--constraint", "avoid", "--safety", "nodes",
               "--steps", "20", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["avoidance"]["safety"] == "nodes"
    rc = main(["plan", "two-vehicle", "--safety", "nodes"])
    err = capsys.readouterr().err
    assert rc == 2 and "--safety" in err
