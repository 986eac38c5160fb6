r"""What a planner reports about how it reached a :class:`~iamp.core.plan.Plan`: :class:`Diagnostics`.

Every planner family has one frozen, typed diagnostics class, a subclass of :class:`Diagnostics`
in its own package (:class:`~iamp.planners.pmp.diagnostics.PMPDiagnostics`,
:class:`~iamp.planners.pmp.diagnostics.BoundedPMPDiagnostics`,
:class:`~iamp.planners.qp.diagnostics.QPDiagnostics`,
:class:`~iamp.planners.avoid.diagnostics.AvoidDiagnostics`,
:class:`~iamp.planners.diagnostics.ActiveSetDiagnostics`).  ``Plan.diagnostics`` holds it.

The fields common to every planner live here: the checks a plan judged itself with (each
``{"value": r, "tol": τ, "ok": r ≤ τ}``, the residual ``r`` recomputed on the plan's own
solution against the tolerance table :mod:`iamp.core.tolerances`), the check that failed, and
the human-readable reasons.  Nothing a planner reported is lost: keys a family does not model
are kept in :attr:`Diagnostics.extra`.

``Plan.info`` (deprecated) is the read-only mapping :meth:`Diagnostics.as_info` of the same
data, key for key and in the order the planner reported them, so that code written against the
old ``info`` dicts keeps reading the same values.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any, TypeVar

D = TypeVar("D", bound="Diagnostics")
#: :meth:`Diagnostics.field_names` per class.
_FIELD_NAMES: dict[type, tuple[str, ...]] = {}
#: A JSON-like object a planner reports as it is (a search record, a certificate).
Record = Mapping[str, Any]


@dataclass(frozen=True)
class Diagnostics:
    """The diagnostics every planner reports (a plan of an unknown family has exactly these).

    Attributes
    ----------
    checks : mapping or None
        ``{name: {"value": r, "tol": τ, "ok": bool}}``: every condition the planner solved or
        satisfied, its max-abs residual ``r`` recomputed on the plan's own solution (units of
        the condition: m for a corner, m/s for a speed, relative for a KKT condition) and the
        tolerance ``τ`` of :data:`iamp.core.tolerances.TOLERANCES`.
    failed_check : str or None
        The name of the first check that failed (a key of ``checks``, or a stage such as
        ``"linear_algebra"``, ``"limits"``); ``None`` when every check holds.
    reason : str or None
        Why a plan is not a verified optimum (shown as the JSON ``reason`` of a failed plan).
    why : str or None
        Why a QP-based plan is ``local`` or not verified (the sweep / refine certificate).
    unsafe_reason : str or None
        Why a verified plan is ``unsafe`` (SPEC §14; the JSON ``reason`` of an unsafe plan).
    error : str or None
        The exception text of a numerical failure.
    constraint : str or None
        The interior-point constraint the plan imposed when it is not the default
        (``"avoid"``, ``"active"``).
    status_before_limits : str or None
        The status before :meth:`~iamp.core.plan.Plan.judge_limits` made it ``limits_violated``.
    polygon_sides : int or None
        Sides of the polygon that stands for the ``a_total`` disc in the QP's rows (SPEC §14).
    limits_polygon_sides : int or None
        The same number as it appears in the JSON (key ``limits_polygon_sides``).
    limits_infeasible : str or None
        The Farkas reason when no plan within the limits exists (JSON ``limits_infeasible``).
    free : bool or None
        ``True`` for the free minimum-energy cubic of a problem with zero vehicles.
    extra : mapping
        Keys a planner reported that its family does not model (kept for ``Plan.info``).
    order : tuple of str
        The order in which the planner reported its keys (``Plan.info``'s key order).
    """

    checks: Record | None = None
    failed_check: str | None = None
    reason: str | None = None
    why: str | None = None
    unsafe_reason: str | None = None
    error: str | None = None
    constraint: str | None = None
    status_before_limits: str | None = None
    polygon_sides: int | None = None
    limits_polygon_sides: int | None = None
    limits_infeasible: str | None = None
    free: bool | None = None
    extra: Mapping[str, object] = field(default_factory=dict)
    order: tuple[str, ...] = ()

    # --- the legacy mapping ----------------------------------------------------------------
    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """The typed fields (the keys this family models; found once per class: a dataclass's
        fields are fixed when it is created)."""
        names = _FIELD_NAMES.get(cls)
        if names is None:
            names = _FIELD_NAMES[cls] = tuple(f.name for f in fields(cls) if f.name not in ("extra", "order"))
        return names

    @classmethod
    def from_info(cls: type[D], info: Mapping[str, object]) -> D:
        """The diagnostics of a planner's ``info`` dict: modelled keys to typed fields, the rest
        to :attr:`extra`; the key order is kept (a key given as ``None`` stays present)."""
        return cls(**cls.info_fields(info))  # type: ignore[arg-type]

    @classmethod
    def info_fields(cls, info: Mapping[str, object]) -> dict[str, object]:
        """The constructor's keyword arguments for :meth:`from_info` (a planner that builds its
        own family's diagnostics with them is not called back from the core)."""
        names = set(cls.field_names())
        typed = {k: v for k, v in info.items() if k in names}
        extra = {k: v for k, v in info.items() if k not in names}
        return {**typed, "extra": extra, "order": tuple(info)}

    def as_info(self) -> dict[str, object]:
        """The legacy ``info`` dict: the reported keys in their order, then any typed field set
        later (not ``None``), then :attr:`extra`'s remaining keys."""
        names = self.field_names()
        out: dict[str, object] = {}
        for key in self.order:
            if key in names:
                out[key] = getattr(self, key)
            elif key in self.extra:
                out[key] = self.extra[key]
        for key in names:
            if key not in out and getattr(self, key) is not None:
                out[key] = getattr(self, key)
        for key, value in self.extra.items():
            out.setdefault(key, value)
        return out

    def updated(self: D, **values: object) -> D:
        """A copy with ``values`` set (typed fields replaced, other keys into :attr:`extra`);
        new keys go to the end of :attr:`order`."""
        names = set(self.field_names())
        typed = {k: v for k, v in values.items() if k in names}
        extra = dict(self.extra)
        extra.update({k: v for k, v in values.items() if k not in names})
        order = self.order + tuple(k for k in values if k not in self.order)
        return replace(self, **typed, extra=extra, order=order)  # type: ignore[arg-type]

    def find(self, cls: type[D]) -> D | None:
        """These diagnostics if they are a ``cls``, else those of the plan this one wraps
        (the active set's base plan), else ``None``."""
        if isinstance(self, cls):
            return self
        base = getattr(self, "base", None)
        return base.find(cls) if isinstance(base, Diagnostics) else None
