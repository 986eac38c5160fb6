"""The fixed whole-track split of a data set into train / validation / test (the shipped
model's, :func:`iamp.prediction.evaluation.evaluate.train_default_model`)."""

from __future__ import annotations

from .table import Tracks

__all__ = ["TEST_FRACTION", "TEST_SEED", "VAL_FRACTION", "VAL_SEED", "split_tracks"]

#: Test fraction of the tracks and its seed; validation fraction of the rest and its seed.
TEST_FRACTION, TEST_SEED, VAL_FRACTION, VAL_SEED = 0.2, 0, 0.25, 1


def split_tracks(tracks: Tracks) -> tuple[Tracks, Tracks, Tracks, Tracks]:
    """``(train, val, test)`` by whole track with the module's fixed seeds."""
    rest, test = tracks.split_by_track(TEST_FRACTION, seed=TEST_SEED)
    train, val = rest.split_by_track(VAL_FRACTION, seed=VAL_SEED)
    return train, val, test, rest
