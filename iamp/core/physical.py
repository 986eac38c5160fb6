r"""Physical limits of the ego vehicle (the scenario's ``[limits]`` table).

The paper's problem has no bounds; a scenario may state what the ego can do. Every field is
optional (``None``: not bounded):

=========  ======================  =========================================================
field      TOML                    meaning
=========  ======================  =========================================================
ax         ``ax = [lo, hi]``       longitudinal acceleration range :math:`lo \le u_x \le hi` [m/s²]
ay         ``ay = [lo, hi]``       lateral acceleration range [m/s²]
a_total    ``a_total = A``         friction circle :math:`\sqrt{u_x^2 + u_y^2} \le A` [m/s²]
vx         ``vx = [lo, hi]``       longitudinal speed range [m/s]
y          ``y = [lo, hi]``        range of the ego's centre :math:`s_y` (road edges less half
                                   the ego's width) [m]
jerk       ``jerk = J``            :math:`|\dot u_x|, |\dot u_y| \le J` [m/s³] (FOH only)
=========  ======================  =========================================================

:data:`PASSENGER_CAR` is the table ``iamp template`` writes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields

from iamp.core.errors import ScenarioError
from iamp.core.limits import exact

#: Fields that are ranges ``[lo, hi]`` and fields that are one positive magnitude.
RANGE_FIELDS = ("ax", "ay", "vx", "y")
MAGNITUDE_FIELDS = ("a_total", "jerk")

#: What any car can do at all: a plan beyond it is flagged even without a ``[limits]`` table.
ANY_CAR_ACCEL_MPS2 = 9.81


def _number(value: object, name: str, source: str | None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScenarioError(f"must be a number (got {value!r})", name, source)
    try:
        out = float(value)
    except OverflowError:
        raise ScenarioError("must be finite (got an integer beyond the float range)", name, source) from None
    if not math.isfinite(out):
        raise ScenarioError(f"must be finite (got {out})", name, source)
    return out


@dataclass(frozen=True)
class PhysicalLimits:
    """Bounds on the ego's inputs and states; ``None`` leaves a quantity unbounded.

    Validated on construction (:class:`~iamp.core.errors.ScenarioError` naming the field):
    ranges need ``lo <= hi``, the acceleration ranges must contain 0 (a car can coast), and
    magnitudes must be positive.
    """

    ax: tuple[float, float] | None = None
    ay: tuple[float, float] | None = None
    a_total: float | None = None
    vx: tuple[float, float] | None = None
    y: tuple[float, float] | None = None
    jerk: float | None = None
    source: str | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        src = self.source
        for name in RANGE_FIELDS:
            value = getattr(self, name)
            if value is None:
                continue
            if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") or len(value) != 2:
                raise ScenarioError(f"must be a range [lo, hi] (got {value!r})", f"limits.{name}", src)
            lo, hi = (_number(v, f"limits.{name}[{k}]", src) for k, v in enumerate(value))
            if lo > hi:
                raise ScenarioError(f"lower bound {lo:g} exceeds upper bound {hi:g}", f"limits.{name}", src)
            if name in ("ax", "ay") and not lo <= 0.0 <= hi:
                raise ScenarioError(f"must contain 0 (got [{lo:g}, {hi:g}])", f"limits.{name}", src)
            object.__setattr__(self, name, (lo, hi))
        for name in MAGNITUDE_FIELDS:
            value = getattr(self, name)
            if value is None:
                continue
            number = _number(value, f"limits.{name}", src)
            if number <= 0:
                raise ScenarioError(f"must be > 0 (got {exact(number)})", f"limits.{name}", src)
            object.__setattr__(self, name, number)

    @classmethod
    def from_table(cls, table: Mapping[str, object], source: str | None = None) -> PhysicalLimits:
        """The ``[limits]`` TOML table; unknown keys are errors."""
        known = RANGE_FIELDS + MAGNITUDE_FIELDS
        for key in table:
            if key not in known:
                raise ScenarioError(f"unknown key; expected one of {', '.join(known)}", f"limits.{key}", source)
        return cls(**{k: table[k] for k in known if k in table}, source=source)  # type: ignore[arg-type]

    def given(self) -> dict[str, tuple[float, float] | float]:
        """The bounds that are set, by field name, in the order of the table."""
        out: dict[str, tuple[float, float] | float] = {}
        for f in fields(self):
            if f.name == "source":
                continue
            value = getattr(self, f.name)
            if value is not None:
                out[f.name] = value
        return out

    @property
    def empty(self) -> bool:
        """True when no bound is set (the paper's unbounded problem)."""
        return not self.given()

    def to_toml_lines(self) -> list[str]:
        """The ``[limits]`` table as TOML lines (for ``iamp template``)."""
        lines = ["[limits]"]
        for name, value in self.given().items():
            if isinstance(value, tuple):
                lines.append(f"{name} = [{value[0]!r}, {value[1]!r}]")
            else:
                lines.append(f"{name} = {value!r}")
        return lines


#: A passenger car's limits: braking to -6, accelerating to 3 m/s², 2 m/s² lateral, an
#: 8 m/s² friction circle, speeds 0-40 m/s, 5 m/s³ jerk. ``y`` depends on the road and is
#: left to the scenario.
PASSENGER_CAR = PhysicalLimits(ax=(-6.0, 3.0), ay=(-2.0, 2.0), a_total=8.0, vx=(0.0, 40.0), jerk=5.0)
