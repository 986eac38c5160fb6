"""CommonRoad scenarios (SPEC §16, the ``[commonroad]`` extra): read a scenario and its
planning problem into an iamp :class:`~iamp.core.problem.Problem` in a road-aligned frame
(:mod:`~iamp.commonroad.frame`, :mod:`~iamp.commonroad.convert`), plan it with iamp's planners
(:mod:`~iamp.commonroad.planning`), write a CommonRoad solution
(:mod:`~iamp.commonroad.solution`), judge it with CommonRoad's own checker
(:mod:`~iamp.commonroad.check`) and benchmark a folder (:mod:`~iamp.commonroad.bench`).

Only :mod:`~iamp.commonroad.frame` works without the extra; everything else calls
:func:`require` first, which raises :class:`~iamp.core.errors.MissingDependencyError` with
the pip line.
"""

from __future__ import annotations

import importlib

from iamp.core.errors import MissingDependencyError

#: The pip line of the extra (the pins that work together: commonroad-io 2024.3 with
#: commonroad-drivability-checker 2025.4; 2026.1 does not).
PIP_LINE = "pip install 'iamp[commonroad]'"


def require() -> None:
    """Raise :class:`MissingDependencyError` naming the extra unless CommonRoad is importable."""
    for module in ("commonroad", "commonroad_dc", "triangle"):
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise MissingDependencyError(
                f"CommonRoad support needs the [commonroad] extra (module {module!r} is missing): {PIP_LINE}"
            ) from exc
