r"""Is a loaded table plausible for road vehicles?  (Issue 22 item 6.)

A file can parse and still be wrong: positions in centimetres where feet are declared (the
converted positions then imply ~900 m/s), frames listed backwards, a value of ``1e308`` in one
row.  Such tables would train a model or score a predictor on nonsense (or on overflowing
numbers), so after loading every loader checks the implied speed of every track,

.. math::  \tilde v_k = (x_{k+1} - x_k) / \Delta t \quad \text{(consecutive samples of one track)},

against the bounds below, and refuses the table (naming the file, the vehicle and the frame,
and the unit it assumed) when

* one step implies ``|ṽ| >`` :data:`STEP_SPEED_MAX_MPS` (a jump no vehicle makes: a corrupt
  row, or swapped frames);
* the median ``|ṽ|`` exceeds :data:`MEDIAN_SPEED_MAX_MPS` (the positions are not in the unit
  the format declares);
* a position, speed or acceleration is beyond :data:`POSITION_MAX_M`, :data:`STEP_SPEED_MAX_MPS`
  or :data:`ACCELERATION_MAX_MPS2` in absolute value (``Local_Y = 1e308``: a corrupt value; such
  numbers would overflow the fit and the JSON report);
* the positions run backwards (median ``ṽ < 0``) while the recorded speeds are positive
  (frames reversed), or the median ``|ṽ|`` and the median recorded speed differ by more than
  a factor :data:`SPEED_RATIO_MAX` (positions and speeds in different units).
"""

from __future__ import annotations

import os

import numpy as np

from iamp.prediction._typing import FloatArray, Lines
from iamp.prediction.tracks import TrackDataError, Tracks

from .report import LoadReport

__all__ = ["ACCELERATION_MAX_MPS2", "MEDIAN_SPEED_MAX_MPS", "POSITION_MAX_M", "SPEED_RATIO_MAX",
           "STEP_SPEED_MAX_MPS", "check_plausible"]

#: Largest speed one step may imply [m/s] (``LIMITS["speed_max_mps"]`` of the scenarios).
STEP_SPEED_MAX_MPS = 1e3
#: Largest absolute position [m] (10,000 km: any road's coordinates).
POSITION_MAX_M = 1e7
#: Largest absolute recorded acceleration [m/s^2] (10 g).
ACCELERATION_MAX_MPS2 = 100.0
#: Largest median implied speed of a table [m/s] (540 km/h).
MEDIAN_SPEED_MAX_MPS = 150.0
#: Largest ratio between the median implied and the median recorded speed.
SPEED_RATIO_MAX = 2.0


def _vehicle(tracks: Tracks, row: int, lines: Lines) -> str:
    ids = tracks.meta.get("source_ids")
    tid = int(tracks.track_id[row])
    name = ids[tid] if isinstance(ids, list) and 0 <= tid < len(ids) else tid
    if isinstance(name, list):  # NGSIM's [location, vehicle id, first frame]
        name = " ".join(str(p) for p in name[:2])
    where = f"line {int(lines[row])}: " if lines is not None else ""
    return f"{where}vehicle {name} at t = {tracks.t[row]:.6g} s"


def _absurd(tracks: Tracks, source: str | os.PathLike[str], unit: str, lines: Lines) -> None:
    """Refuse the first row whose position, speed, acceleration or lateral position is absurd."""
    checks: list[tuple[str, FloatArray, float, str]] = [
        ("x", tracks.x, POSITION_MAX_M, "m"), ("v", tracks.v, STEP_SPEED_MAX_MPS, "m/s"),
        ("a", tracks.a, ACCELERATION_MAX_MPS2, "m/s^2")]
    if tracks.y is not None:
        checks.append(("y", tracks.y, POSITION_MAX_M, "m"))
    for column, values, bound, si in checks:
        with np.errstate(invalid="ignore"):
            bad = ~(np.abs(values) <= bound)
        if np.any(bad):
            k = int(np.flatnonzero(bad)[0])
            raise TrackDataError(f"{_vehicle(tracks, k, lines)}: {column} = {values[k]:.6g} {si} is not a plausible "
                                 f"value (|{column}| <= {bound:g} {si}; read as {unit})", column=column,
                                 source=str(source))


def check_plausible(tracks: Tracks, source: str | os.PathLike[str], unit: str, lines: Lines = None) -> list[str]:
    """Refuse an implausible table (module docstring); returns notes for the load report.

    Parameters
    ----------
    tracks : Tracks
    source : path
        The file, named in the refusal.
    unit : str
        What the loader assumed, e.g. ``"feet (NGSIM), converted to metres"``.
    lines : array of int, optional
        The file line of each row, named in the refusal (else the vehicle and time name it).
    """
    _absurd(tracks, source, unit, lines)
    same = np.diff(tracks.track_id) == 0
    if not np.any(same):
        return []
    with np.errstate(over="ignore", invalid="ignore"):
        step = np.diff(tracks.x) / tracks.dt
    rows = np.flatnonzero(same)
    implied = step[rows]
    bad = ~np.isfinite(implied) | (np.abs(implied) > STEP_SPEED_MAX_MPS)
    if np.any(bad):
        k = int(rows[np.flatnonzero(bad)[0]])
        jump = tracks.x[k + 1] - tracks.x[k]
        raise TrackDataError(f"{_vehicle(tracks, k + 1, lines)}: the position jumps by {jump:.6g} m "
                             f"in one {tracks.dt:g} s step (implied speed above {STEP_SPEED_MAX_MPS:g} m/s): a corrupt "
                             f"value or swapped frames; positions were read as {unit}", column="x", source=str(source))
    med = float(np.median(np.abs(implied)))
    if med > MEDIAN_SPEED_MAX_MPS:
        raise TrackDataError(f"the positions imply a median speed of {med:.4g} m/s (above {MEDIAN_SPEED_MAX_MPS:g}): "
                             f"not in the unit assumed ({unit})?", column="x", source=str(source))
    recorded = float(np.median(tracks.v))
    signed = float(np.median(implied))
    if recorded > 1.0 and signed < -0.5 * recorded:
        raise TrackDataError(f"positions decrease with time (median {signed:.4g} m/s) while the recorded speeds are "
                             f"positive (median {recorded:.4g} m/s): frames reversed?", column="x", source=str(source))
    notes: list[str] = []
    if recorded > 1.0 and med > 1.0:
        ratio = med / recorded
        if not (1.0 / SPEED_RATIO_MAX <= ratio <= SPEED_RATIO_MAX):
            raise TrackDataError(f"positions imply a median speed of {med:.4g} m/s but the speed column's median is "
                                 f"{recorded:.4g} m/s (ratio {ratio:.3g}): positions and speeds in different units? "
                                 f"(read as {unit})", column="x", source=str(source))
    notes.append(f"plausibility: median implied speed {med:.3g} m/s, median recorded speed {recorded:.3g} m/s "
                 f"(positions read as {unit})")
    return notes


def apply(tracks: Tracks, source: str | os.PathLike[str], unit: str, report: LoadReport,
          lines: Lines = None) -> Tracks:
    """:func:`check_plausible`, its notes added to ``report`` and to ``tracks.meta["load_report"]``."""
    for note in check_plausible(tracks, source, unit, lines):
        report.note(note)
    tracks.meta["load_report"] = report.to_dict()
    return tracks
