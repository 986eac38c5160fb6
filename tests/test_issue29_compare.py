"""Issue 29 items 1, 9, 10 and 16 (part): the comparison of bounded problems, the refusal of a
backend that cannot impose ``[limits]``, fast certified infeasibility of the bounded QP, and
the ``plan`` help and text output."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import iamp
from iamp.core.physical import PhysicalLimits
from iamp.prediction.resolve import load_problem

#: The template's [limits] (iamp template): a passenger car without the jerk bound.
TEMPLATE_LIMITS = PhysicalLimits(ax=(-6.0, 3.0), ay=(-2.0, 2.0), a_total=8.0, vx=(0.0, 40.0))


def _template(tmp_path: Path, cli) -> Path:  # type: ignore[no-untyped-def]
    r = cli("template")
    assert r.returncode == 0, r.stderr
    path = tmp_path / "t.toml"
    path.write_text(r.stdout)
    return path


# --- item 9: a backend that cannot take inequalities is refused, not a numerical error ----------


def test_cli_refuses_kkt_with_limits_naming_the_backends(tmp_path: Path, cli) -> None:  # type: ignore[no-untyped-def]
    t = _template(tmp_path, cli)
    for extra in ((), ("--constraint", "active"), ("--json",)):
        r = cli("plan", t, "--planner", "qp", "--solver", "kkt", "--steps", "10", *extra)
        assert r.returncode == 2, (extra, r.stdout, r.stderr)
        assert r.stdout == ""
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in r.stderr
        assert "--solver" in lines[0] and "kkt" in lines[0]
        for ok in ("osqp", "clarabel", "piqp"):
            assert ok in lines[0]


def test_api_refuses_kkt_with_limits() -> None:
    _, p, _ = load_problem("paper-1-poly")
    bounded = p.with_limits(TEMPLATE_LIMITS)
    with pytest.raises(iamp.OptionError) as err:
        iamp.plan(bounded, "qp", solver="kkt", steps=10)
    assert err.value.field == "solver" and "clarabel" in str(err.value)
    from iamp.planners.qp import QPPlanner

    with pytest.raises(iamp.OptionError):  # the planner object itself refuses, before any solve
        QPPlanner(steps=10, solver="kkt").plan(bounded)
    assert iamp.plan(p, "qp", solver="kkt", steps=10).status == "optimal"  # without limits kkt is fine


# --- item 16 (part): help without issue numbers; the active set's text has its limits line ------


def test_plan_help_cites_no_issue(cli) -> None:  # type: ignore[no-untyped-def]
    r = cli("plan", "--help")
    assert r.returncode == 0
    assert "issue" not in r.stdout.lower()


def test_active_text_output_has_a_limits_line(cli) -> None:  # type: ignore[no-untyped-def]
    outs = {}
    for planner in ("pmp", "qp"):
        r = cli("plan", "paper-1-poly", "--planner", planner, "--constraint", "active", "--steps", "10")
        assert r.returncode == 0, r.stderr
        outs[planner] = r.stdout
        limits = [line for line in r.stdout.splitlines() if line.startswith("limits ")]
        assert len(limits) == 1 and "vx" in limits[0]
    plain = cli("plan", "paper-1-poly", "--steps", "10").stdout
    assert any(line.startswith("limits ") for line in plain.splitlines())
