r"""The diagnostics of an active-set plan (:mod:`~iamp.planners.active_set`): :class:`ActiveSetDiagnostics`."""

from __future__ import annotations

from dataclasses import dataclass

from iamp.core.diagnostics import Diagnostics, Record


@dataclass(frozen=True)
class ActiveSetDiagnostics(Diagnostics):
    """What the active-set planner reports; the base planner's diagnostics stay in :attr:`base`.

    Attributes
    ----------
    active_set : mapping or None
        The JSON ``active_set`` object: the imposed vehicles (contact time [s], jump
        :math:`\\Phi` [m/s³·s]), the dropped ones and why, the iterations and the base planner.
    base : Diagnostics or None
        The diagnostics of the last plan of the base planner (its keys also appear in
        ``Plan.info``, the ``avoidance`` key excepted).
    """

    active_set: Record | None = None
    base: Diagnostics | None = None

    def as_info(self) -> dict[str, object]:
        """The legacy ``info`` dict (the base's keys are already in :attr:`extra`)."""
        out = super().as_info()
        out.pop("base", None)
        return out
