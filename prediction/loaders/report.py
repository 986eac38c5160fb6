"""What a loader did with every row of a file: :class:`LoadReport` (never silent).

Every loader counts the data rows it read, the rows it kept, and every dropped row under a
reason; ``rows_read == rows_kept + Σ dropped`` always holds.  Notes record conversions a
user must know about (a reference point used for some vehicles, a column that was ignored,
tracks split at gaps).  The CLI prints the report; it is also stored in
``Tracks.meta["load_report"]``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, TypedDict

__all__ = ["LoadReport", "LoadReportJSON"]


class LoadReportJSON(TypedDict):
    """:meth:`LoadReport.to_dict`."""

    sources: list[str]
    rows_read: int
    rows_kept: int
    rows_dropped: int
    dropped: dict[str, int]
    notes: list[str]


@dataclass
class LoadReport:
    """Row accounting of one or more loaded files.

    Attributes
    ----------
    sources : list of str
        The files read.
    rows_read : int
        Data rows read (header and blank lines excluded).
    rows_kept : int
        Rows in the resulting table.
    dropped : dict of str to int
        Rows dropped, by reason.
    notes : list of str
        Conversions and decisions the user should know about.
    """

    sources: list[str] = field(default_factory=list)
    rows_read: int = 0
    rows_kept: int = 0
    dropped: dict[str, int] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def drop(self, reason: str, count: int) -> None:
        """Count ``count`` rows dropped for ``reason`` (zero counts are not recorded)."""
        if count:
            self.dropped[reason] = self.dropped.get(reason, 0) + int(count)

    def note(self, text: str) -> None:
        """Record a conversion or decision (each text once)."""
        if text not in self.notes:
            self.notes.append(text)

    @property
    def rows_dropped(self) -> int:
        """Total dropped rows."""
        return sum(self.dropped.values())

    def check(self) -> None:
        """Assert the accounting identity ``rows_read == rows_kept + rows_dropped``."""
        if self.rows_read != self.rows_kept + self.rows_dropped:
            raise AssertionError(f"row accounting is off: read {self.rows_read}, kept {self.rows_kept}, "
                                 f"dropped {self.rows_dropped}")

    @staticmethod
    def merge(reports: Iterable[LoadReport]) -> LoadReport:
        """One report summing several (files loaded together)."""
        out = LoadReport()
        for r in reports:
            out.sources.extend(r.sources)
            out.rows_read += r.rows_read
            out.rows_kept += r.rows_kept
            for k, v in r.dropped.items():
                out.drop(k, v)
            for n in r.notes:
                out.note(n)
        return out

    def to_dict(self) -> LoadReportJSON:
        """JSON-ready form."""
        return {"sources": list(self.sources), "rows_read": self.rows_read, "rows_kept": self.rows_kept,
                "rows_dropped": self.rows_dropped, "dropped": dict(self.dropped), "notes": list(self.notes)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> LoadReport:
        """Inverse of :meth:`to_dict`."""
        return cls(list(d.get("sources", [])), int(d.get("rows_read", 0)), int(d.get("rows_kept", 0)),
                   {str(k): int(v) for k, v in dict(d.get("dropped", {})).items()}, list(d.get("notes", [])))

    def lines(self) -> list[str]:
        """Human-readable lines (what the CLI prints)."""
        pct = 100.0 * self.rows_kept / self.rows_read if self.rows_read else 0.0
        out = [f"read {self.rows_read} rows from {len(self.sources)} file(s); kept {self.rows_kept} ({pct:.1f} %), "
               f"dropped {self.rows_dropped}"]
        out += [f"  dropped {v}: {k}" for k, v in sorted(self.dropped.items(), key=lambda kv: -kv[1])]
        out += [f"  note: {n}" for n in self.notes]
        return out
