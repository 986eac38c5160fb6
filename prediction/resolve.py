"""A scenario turned into a plannable problem: history vehicles go through a predictor.

This sits in the prediction layer because it chooses the predictor (the shipped model by
default); :mod:`iamp.core.scenario` itself never imports the predictor.
"""

from __future__ import annotations

from typing import Any

from iamp.core.problem import Problem
from iamp.core.scenario import Scenario, load_scenario
from iamp.prediction.predictor import Predictor


def default_predictor() -> Predictor:
    """The shipped predictor (model ``prediction/data/mtd_default.json``)."""
    return Predictor.default()


def load_problem(spec: str, model: str | None = None) -> tuple[Scenario, Problem, list[Any]]:
    """Scenario file or built-in name -> ``(scenario, problem, predictions)``.

    Vehicles given by a ``history`` are predicted with the model file ``model`` or, if it is
    ``None``, the shipped model; vehicles given by ``x_poly`` pass through unchanged.
    """
    return problem_from_scenario(load_scenario(spec), model)


def problem_from_scenario(scenario: Scenario, model: str | None = None) -> tuple[Scenario, Problem, list[Any]]:
    """A loaded scenario -> ``(scenario, problem, predictions)``, predicting history vehicles
    with the model file ``model`` or the shipped model."""
    predictor = None
    if scenario.needs_prediction:
        predictor = Predictor.from_file(model) if model is not None else default_predictor()
    problem, predictions = scenario.to_problem(predictor)
    return scenario, problem, predictions
