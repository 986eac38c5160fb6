"""Leader-aware prediction: who follows whom, car-following laws (IDM, linear) and the predictor.

:mod:`.leaders` finds each vehicle's leader (NGSIM ``Preceding`` or same lane and nearest ahead),
:mod:`.car_following` holds the laws, their calibration and simulation (:mod:`.kernel` IDM's
forward simulation, written once: compiled by numba when importable, run as Python otherwise, the
same numbers), :mod:`.model` the saved model and :class:`~.model.LeaderPredictor` (MTD fallback
where no leader is known), :mod:`.ego` the follower's forecast with the ego's plan as its leader.
"""

from __future__ import annotations

from .car_following import CarFollowingLaw, accel, calibrate, calibrate_trajectories, simulate
from .leaders import Leaders, derive_leaders, leaders_for, ngsim_leaders
from .model import LeaderPredictor, default_leader_model, load_any_model, train_leader_model

__all__ = [
    "CarFollowingLaw",
    "LeaderPredictor",
    "Leaders",
    "accel",
    "calibrate",
    "calibrate_trajectories",
    "default_leader_model",
    "derive_leaders",
    "leaders_for",
    "load_any_model",
    "ngsim_leaders",
    "simulate",
    "train_leader_model",
]
