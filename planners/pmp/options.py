"""The options of the PMP planner (:class:`PMPOptions`), validated on construction."""

from __future__ import annotations

from dataclasses import dataclass

from iamp.core.errors import OptionError


@dataclass(frozen=True)
class PMPOptions:
    """Options of :class:`~iamp.planners.pmp.planner.PMPPlanner`.

    Parameters
    ----------
    max_starts : int
        Newton starts of the global contact-time search for ``m >= 2``.
    max_boxes : int
        Box budget of the branch-and-bound certificate (beyond it the status is ``local``).
    compiled : bool or None
        Accepted and ignored (kept for callers of earlier releases): the ``m >= 2`` search has one
        implementation whatever is installed or loaded (issue 32).
    diagnostics : bool
        Add the physical max-abs residuals to the plan after the clock stops.
    certify_bounded : bool
        With an active input box in ``problem.limits`` (SPEC §14), one vehicle: certify the
        bounded contact-time search global (``optimal``) or say ``local``; ``False`` skips the
        certificate (``local``, faster).
    """

    max_starts: int = 32
    max_boxes: int = 200_000
    compiled: bool | None = None
    diagnostics: bool = True
    certify_bounded: bool = True

    def __post_init__(self) -> None:
        for name in ("max_starts", "max_boxes"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise OptionError(f"must be a positive integer (got {value!r})", name)
        if self.compiled not in (None, True, False):
            raise OptionError(f"must be true, false or none (got {self.compiled!r})", "compiled")
        for flag in ("diagnostics", "certify_bounded"):
            if not isinstance(getattr(self, flag), bool):
                raise OptionError(f"must be true or false (got {getattr(self, flag)!r})", flag)
