r"""Feet or metres?  The unit of an NGSIM-layout file, read from the data (issue 29 item 4).

NGSIM's files are in feet (ft, ft/s, ft/s²), but re-exports of the same layout circulate in
metres; read as feet, such a file is silently shrunk by 0.3048 (a median speed of 4.2 m/s for a
freeway at 13.7 m/s).  The layout carries no unit, so the loader asks the data.  Every piece of
evidence is a robust statistic of a column whose physical range is narrow, and each unit is
*plausible* for it when the value, converted to metres under that unit, lies in the range:

================================  =====================================  ==============================
evidence                          statistic                              plausible range (SI)
================================  =====================================  ==============================
vehicle length ``v_length``       median of the positive values          :data:`LENGTH_RANGE_M`
vehicle width ``v_Width``         median of the positive values          :data:`WIDTH_RANGE_M`
lane width ``Local_X``/``Lane_ID`` median over adjacent lane ids of the  :data:`LANE_WIDTH_RANGE_M`
                                  difference of the lanes' median
                                  ``Local_X`` (lanes with at least
                                  :data:`MIN_LANE_ROWS` rows; unused when
                                  every lane has the same ``Local_X``)
speed ``v_Vel``                   95th percentile of ``|v_Vel|``         at most :data:`SPEED_MAX_MPS`
================================  =====================================  ==============================

The ranges of the two units do not overlap for the width and the lane width (a value fits one
unit or neither), so either decides; nor for the length except a median of 8.2-9 (8.2-9 m or
27-30 ft: plausible in both, undecided by the length); the speed can only rule metres out (a slow recording is
plausible in either unit).  The unit is the one plausible under **every** available piece of
evidence.  If both remain (nothing decisive: no lengths, widths or lane ids, slow speeds) or
none does (the evidence contradicts itself), the file is refused with the evidence, and the
user says which with ``units`` (``iamp ... --units feet|metres``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from iamp.prediction._typing import Array
from iamp.prediction.tracks.table import TrackDataError

__all__ = ["FOOT_M", "LANE_WIDTH_RANGE_M", "LENGTH_RANGE_M", "MIN_LANE_ROWS", "SPEED_MAX_MPS", "UNITS",
           "WIDTH_RANGE_M", "UnitDecision", "detect_units", "unit_factor"]

#: One foot in metres.
FOOT_M = 0.3048
#: The accepted ``units`` (``iamp ... --units``) and their length in metres.
UNITS: dict[str, float] = {"feet": FOOT_M, "metres": 1.0}
#: Plausible median vehicle length [m] (small cars to a traffic mix with many trucks).
LENGTH_RANGE_M = (2.5, 9.0)
#: Plausible median vehicle width [m].
WIDTH_RANGE_M = (1.2, 3.0)
#: Plausible lane width [m] (freeway lanes are 3.5-3.7 m, NGSIM's 12 ft = 3.66 m).
LANE_WIDTH_RANGE_M = (2.5, 5.5)
#: Largest plausible 95th percentile of the recorded speeds [m/s] (162 km/h).
SPEED_MAX_MPS = 45.0
#: Rows a lane needs for its median lateral position to count.
MIN_LANE_ROWS = 20


def unit_factor(units: str) -> float:
    """Metres per unit of ``units`` (``"feet"`` or ``"metres"``; ``"meters"``, ``"ft"``, ``"m"`` accepted).

    Parameters
    ----------
    units : str

    Returns
    -------
    float

    Raises
    ------
    TrackDataError
        For any other name.
    """
    key = str(units).strip().lower()
    key = {"ft": "feet", "foot": "feet", "m": "metres", "meters": "metres", "metre": "metres",
           "meter": "metres"}.get(key, key)
    if key not in UNITS:
        raise TrackDataError(f"unknown units {units!r}; expected feet or metres", column="units")
    return UNITS[key]


@dataclass(frozen=True)
class UnitDecision:
    """The unit of a file and why.

    Attributes
    ----------
    units : str
        ``"feet"`` or ``"metres"``.
    factor : float
        Metres per unit.
    how : str
        ``"given"`` (the caller's ``units``) or ``"detected"``.
    evidence : tuple of str
        One phrase per piece of evidence (statistic, and which units it fits).
    """

    units: str
    factor: float
    how: str
    evidence: tuple[str, ...]

    def note(self) -> str:
        """One line for the load report."""
        ev = "; ".join(self.evidence) if self.evidence else "no evidence"
        if self.how == "given":
            return f"units: {self.units} (given; the data's evidence: {ev})"
        return f"units: {self.units} (detected from the data: {ev})"


def _median_positive(values: Array | None) -> float | None:
    if values is None:
        return None
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v) & (v > 0)]
    return float(np.median(v)) if v.size else None


def _lane_width(lane: Array | None, lateral: Array | None) -> float | None:
    """Median over adjacent lane ids of the difference of the lanes' median lateral positions."""
    if lane is None or lateral is None:
        return None
    ln = np.asarray(lane, dtype=float)
    y = np.asarray(lateral, dtype=float)
    ok = np.isfinite(ln) & np.isfinite(y) & (ln > 0) & (ln == np.round(ln))
    ids, counts = np.unique(ln[ok], return_counts=True)
    ids = ids[counts >= MIN_LANE_ROWS]
    if ids.size < 2:
        return None
    med = {int(i): float(np.median(y[ok & (ln == i)])) for i in ids}
    diffs = [abs(med[i + 1] - med[i]) for i in med if i + 1 in med]
    if not diffs or max(diffs) == 0.0:  # every lane at the same Local_X: the column says nothing lateral
        return None
    return float(np.median(diffs))


#: Relative round-off allowed at a range's ends: a value written in feet and converted back lands
#: a few ulps outside (3 m -> 9.8425 ft -> 3.0000000000000004 m).
_ROUND_OFF = 1e-12


def _fits(value: float, lo: float, hi: float) -> set[str]:
    return {u for u, f in UNITS.items() if lo * (1 - _ROUND_OFF) <= value * f <= hi * (1 + _ROUND_OFF)}


def _phrase(name: str, value: float, fits: set[str], lo: float, hi: float) -> str:
    conv = ", ".join(f"{value * f:.3g} m as {u}" for u, f in UNITS.items())
    verdict = ("fits " + " and ".join(sorted(fits))) if fits else "fits neither"
    return f"{name} {value:.4g} ({conv}; {verdict} of {lo:g}-{hi:g} m)"


def detect_units(cols: Mapping[str, Array], source: str | Path, units: str | None = None) -> UnitDecision:
    """The unit of an NGSIM-layout table (module docstring).

    Parameters
    ----------
    cols : mapping of column name to array
        The file's columns (``v_length``, ``v_Width``, ``Lane_ID``, ``Local_X``, ``v_Vel``; any may
        be missing).
    source : path
        The file, named in a refusal.
    units : {"feet", "metres"}, optional
        The caller's unit: then no refusal, the evidence is only reported.

    Returns
    -------
    UnitDecision

    Raises
    ------
    TrackDataError
        When ``units`` is not given and the evidence does not single out one unit (ambiguous or
        contradictory), naming the file and the evidence.
    """
    evidence: list[str] = []
    candidates = set(UNITS)
    for name, stat, (lo, hi) in (
            ("median v_length", _median_positive(cols.get("v_length")), LENGTH_RANGE_M),
            ("median v_Width", _median_positive(cols.get("v_Width")), WIDTH_RANGE_M),
            ("lane width (median Local_X per Lane_ID)", _lane_width(cols.get("Lane_ID"), cols.get("Local_X")),
             LANE_WIDTH_RANGE_M)):
        if stat is None:
            continue
        fits = _fits(stat, lo, hi)
        evidence.append(_phrase(name, stat, fits, lo, hi))
        candidates &= fits
    if "v_Vel" in cols and np.asarray(cols["v_Vel"]).size:
        speed = np.abs(np.asarray(cols["v_Vel"], dtype=float))
        speed = speed[np.isfinite(speed)]
        if speed.size:
            p95 = float(np.percentile(speed, 95))  # robust to a corrupt row (refused later, with its line)
            fits = {u for u, f in UNITS.items() if p95 * f <= SPEED_MAX_MPS}
            evidence.append(f"95th percentile of v_Vel {p95:.4g} (" + ", ".join(
                f"{p95 * f:.3g} m/s as {u}" for u, f in UNITS.items()) + "; "
                + (("fits " + " and ".join(sorted(fits))) if fits else "fits neither")
                + f" of <= {SPEED_MAX_MPS:g} m/s)")
            candidates &= fits
    if units is not None:
        f = unit_factor(units)
        name = next(u for u, g in UNITS.items() if g == f)
        return UnitDecision(name, f, "given", tuple(evidence))
    if len(candidates) == 1:
        name = next(iter(candidates))
        return UnitDecision(name, UNITS[name], "detected", tuple(evidence))
    what = "cannot tell feet from metres" if candidates else "the evidence on the unit contradicts itself"
    ev = "; ".join(evidence) if evidence else ("no v_length, v_Width or lane ids to judge by and no speed column")
    raise TrackDataError(f"{what}: {ev}; say which with --units feet or --units metres", source=str(source))
