"""The oriented bodies' separations of an episode are computed for all steps in one call
(:func:`iamp.simulation.metrics.episode_geometry` through ``_separation_rows``) instead of one
:func:`~iamp.simulation.metrics.separation` call per step: the same floats, bit for bit, as the former
per-step function (kept here as the oracle) — random logs of several steps with any number of
neighbours, headings of both signs and zero, overlapping and distant bodies — and
:func:`~iamp.simulation.metrics.separation` itself is unchanged."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.metrics import (
    StepLog,
    ego_headings,
    episode_geometry,
    neighbour_headings,
    separation,
    step_geometry,
)


def _old_separation(c1, L1, W1, psi1, c2, L2, W2, psi2):
    c2 = np.asarray(c2, dtype=float).reshape(-1, 2)
    L2, W2, psi2 = (np.asarray(a, dtype=float).reshape(-1) for a in (L2, W2, psi2))
    d = c2 - np.asarray(c1, dtype=float).reshape(1, 2)
    a1 = np.array([[math.cos(psi1), math.sin(psi1)], [-math.sin(psi1), math.cos(psi1)]])
    a2 = np.stack([np.stack([np.cos(psi2), np.sin(psi2)], axis=1),
                   np.stack([-np.sin(psi2), np.cos(psi2)], axis=1)], axis=1)
    axes = np.concatenate([np.broadcast_to(a1, (c2.shape[0], 2, 2)), a2], axis=1)
    r1 = L1 / 2 * np.abs(axes @ a1[0]) + W1 / 2 * np.abs(axes @ a1[1])
    r2 = L2[:, None] / 2 * np.abs(np.einsum("nkx,nx->nk", axes, a2[:, 0])) \
        + W2[:, None] / 2 * np.abs(np.einsum("nkx,nx->nk", axes, a2[:, 1]))
    dist = np.abs(np.einsum("nkx,nx->nk", axes, d))
    return np.asarray(np.max(dist - r1 - r2, axis=1), dtype=float)


def _old_episode_geometry(log, ego_size):
    E = np.asarray(log.ego, dtype=float).reshape(-1, 6)
    psi_e = ego_headings(log)
    return [(g, _old_separation(np.array([E[g.k, 0], E[g.k, 2]]), ego_size[0], ego_size[1], float(psi_e[g.k]),
                                g.nb[:, :2], g.L, g.W, neighbour_headings(g.nb)))
            for g in step_geometry(log, ego_size)]


heading = st.one_of(st.floats(-1.2, 1.2), st.sampled_from([0.0, -0.0, 1e-9, math.pi / 2]))
row = st.tuples(st.floats(-60.0, 60.0), st.floats(-8.0, 1.0), st.floats(0.0, 40.0), st.floats(-6.0, 3.0),
                st.integers(0, 3), st.sampled_from([4.5, 4.8, 12.0]), st.sampled_from([1.8, 2.5]), heading)
step = st.tuples(st.floats(-5.0, 5.0), st.floats(0.0, 35.0), st.floats(-7.0, 0.0), st.floats(-1.0, 1.0), heading,
                 st.lists(row, min_size=0, max_size=7))


def _log(steps, with_heading):
    log = StepLog()
    for k, (x, vx, y, vy, psi, rows) in enumerate(steps):
        log.t.append(0.1 * k)
        log.ego.append((x, vx, y, vy, 0.0, 0.0))
        log.mode.append("seek")
        log.plan_time.append(math.nan)
        log.ids.append(tuple(f"v{j}" for j in range(len(rows))))
        log.nb.append(np.array(rows, dtype=float).reshape(-1, 8))
        if with_heading:
            log.ego_heading.append(psi)
    return log


@settings(max_examples=150, deadline=None)
@given(steps=st.lists(step, min_size=0, max_size=12), with_heading=st.booleans(),
       size=st.sampled_from([(4.8, 1.8), (4.5, 2.0)]))
def test_episode_geometry_is_the_per_step_separation(steps, with_heading, size):
    log = _log(steps, with_heading)
    new, old = episode_geometry(log, size), _old_episode_geometry(log, size)
    assert [g.k for g, _ in new] == [g.k for g, _ in old]
    for (_, a), (_, b) in zip(new, old):
        assert a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@settings(max_examples=150, deadline=None)
@given(c1=st.tuples(st.floats(-5.0, 5.0), st.floats(-7.0, 0.0)), psi1=heading,
       rows=st.lists(row, min_size=0, max_size=9))
def test_separation_is_unchanged(c1, psi1, rows):
    nb = np.array(rows, dtype=float).reshape(-1, 8)
    args = (np.array(c1), 4.8, 1.8, psi1, nb[:, :2], nb[:, 5], nb[:, 6], nb[:, 7])
    a, b = separation(*args), _old_separation(*args)
    assert a.shape == b.shape and a.tobytes() == b.tobytes()
