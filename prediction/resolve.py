"""A scenario turned into a plannable problem: history vehicles go through a predictor.

This sits in the prediction layer because it chooses the predictor (the shipped model by
default); :mod:`iamp.core.scenario` itself never imports the predictor.
"""

from __future__ import annotations

from dataclasses import dataclass

from iamp.core.problem import Problem
from iamp.core.scenario import History, Scenario, load_scenario
from iamp.prediction._typing import FloatArray
from iamp.prediction.predictor import Prediction, Predictor


def default_predictor() -> Predictor:
    """The shipped predictor (model ``prediction/data/mtd_default.json``)."""
    return Predictor.default()


def load_problem(spec: str, model: str | None = None) -> tuple[Scenario, Problem, list[Prediction | None]]:
    """Scenario file or built-in name -> ``(scenario, problem, predictions)``.

    Vehicles given by a ``history`` are predicted with the model file ``model`` or, if it is
    ``None``, the shipped model; vehicles given by ``x_poly`` pass through unchanged.
    """
    return problem_from_scenario(load_scenario(spec), model)


def problem_from_scenario(scenario: Scenario,
                          model: str | None = None) -> tuple[Scenario, Problem, list[Prediction | None]]:
    """A loaded scenario -> ``(scenario, problem, predictions)``, predicting history vehicles
    with the model file ``model`` or the shipped model."""
    predictor = None
    if scenario.needs_prediction:
        predictor = Predictor.from_file(model) if model is not None else default_predictor()
    problem, predictions = scenario.to_problem(predictor)
    return scenario, problem, predictions


@dataclass(frozen=True)
class _LeaderPrediction:
    x_poly: tuple[float, ...]
    t: FloatArray
    x: FloatArray


class _ScenarioLeaderPredictor:
    """``predict(history, tf)`` answering from :func:`~iamp.prediction.leader.model.predict_scenario`'s
    results for the scenario's own histories (looked up by identity)."""

    def __init__(self, predictions: dict[int, _LeaderPrediction], name: str, dt: float) -> None:
        self._by_history = predictions
        self.name = name
        self.dt = dt

    def predict(self, history: History, tf: float) -> _LeaderPrediction:
        return self._by_history[id(history)]


def problem_with_leader_model(scenario: Scenario,
                              leader_model: str) -> tuple[Problem, list[_LeaderPrediction | None]]:
    """``(problem, predictions)`` with every history vehicle predicted by the leader-aware predictor
    of the file ``leader_model`` (the vehicle ahead in its lane, |dy| < 1.75 m, as leader; the
    model's MTD fallback where there is none): the scenario-level counterpart of
    :func:`problem_from_scenario` (``iamp plan --leader-model``)."""
    from iamp.prediction.leader.model import SIM_DT, LeaderPredictor, predict_scenario

    lp = LeaderPredictor.from_file(leader_model)
    res = predict_scenario(lp, scenario.vehicles, scenario.ego.tf)
    by_history = {id(scenario.vehicles[i].history): _LeaderPrediction(c, t, x) for i, (c, t, x) in res.items()}
    return scenario.to_problem(_ScenarioLeaderPredictor(by_history, leader_model, SIM_DT))
