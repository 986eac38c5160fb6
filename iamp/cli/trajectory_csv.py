r"""``iamp plan --csv``: the plan sampled at :math:`t_k = k\,t_f/N`, :math:`k = 0..N` (SPEC §5), as CSV."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from iamp.core.atomic import atomic_open
from iamp.core.plan import TRAJECTORY_KEYS, Plan


def write_trajectory_csv(result: Plan, path: str | Path, steps: int) -> Path:
    """The plan sampled at :math:`t_k = k\\,t_f/N`, :math:`k = 0..N` (SPEC §5), as CSV.

    Columns ``t,x,y,vx,vy,ax,ay`` (SI units: s, m, m/s, m/s²), one header line and ``N + 1``
    rows, full double precision (``repr`` of each float), written atomically.
    """
    data = result.sample(steps)
    cols = [np.asarray(data[k], dtype=float) for k in TRAJECTORY_KEYS]
    with atomic_open(path, "w") as fh:
        fh.write(",".join(TRAJECTORY_KEYS) + "\n")
        for row in zip(*cols):
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
    return Path(path)
