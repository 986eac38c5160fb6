"""Where a field of a scenario file is written: the line number of a TOML key.

``tomllib`` returns plain dictionaries without positions, so a refusal such as
``vehicles[1].history.t: must be strictly increasing`` would not say where to look.  This
module scans the text once, following table headers (``[ego]``, ``[[vehicles]]`` —
counted, so the second one is ``vehicles[1]`` — and ``[vehicles.history]``) and
``key = value`` lines (dotted keys included), and maps every field path in the SPEC §4
vocabulary to the line where it is written.  A field that is not written (a missing key)
maps to the line of its table's header; a field it cannot place maps to ``None``.

It is a locator for messages, not a parser: the document has already been parsed (and
validated) by ``tomllib``; keys inside inline tables or multi-line strings are not placed.
"""

from __future__ import annotations

import re

_AOT = re.compile(r"^\s*\[\[\s*([^\[\]]+?)\s*\]\]\s*(#.*)?$")
_TABLE = re.compile(r"^\s*\[\s*([^\[\]]+?)\s*\]\s*(#.*)?$")
_KEY = re.compile(r"""^\s*((?:[A-Za-z0-9_-]+|"[^"]*"|'[^']*')(?:\s*\.\s*(?:[A-Za-z0-9_-]+|"[^"]*"|'[^']*'))*)\s*=""")


def _split_key(key: str) -> list[str]:
    parts = re.findall(r"""[A-Za-z0-9_-]+|"[^"]*"|'[^']*'""", key)
    return [p[1:-1] if p[:1] in "\"'" else p for p in parts]


def field_lines(text: str) -> dict[str, int]:
    """Map field paths (``"ego.tf"``, ``"vehicles[1].history.t"``) to 1-based line numbers."""
    lines: dict[str, int] = {}
    counts: dict[str, int] = {}
    table: str = ""
    for number, line in enumerate(text.split("\n"), start=1):
        m = _AOT.match(line)
        if m:
            parts = _split_key(m.group(1))
            base = ".".join(parts)
            counts[base] = counts.get(base, -1) + 1
            # an array of tables nested under the last element of its parent
            prefix = _resolve(parts[:-1], counts)
            table = (f"{prefix}." if prefix else "") + f"{parts[-1]}[{counts[base]}]"
            lines.setdefault(table, number)
            lines.setdefault(table.rsplit("[", 1)[0], number)
            continue
        m = _TABLE.match(line)
        if m:
            table = _resolve(_split_key(m.group(1)), counts)
            lines.setdefault(table, number)
            continue
        m = _KEY.match(line)
        if m:
            path = table
            for part in _split_key(m.group(1)):
                path = f"{path}.{part}" if path else part
                lines.setdefault(path, number)
    return lines


def _resolve(parts: list[str], counts: dict[str, int]) -> str:
    """Table path with the current index of every array of tables on the way."""
    out = ""
    for k in range(len(parts)):
        name = ".".join(parts[: k + 1])
        piece = f"{parts[k]}[{counts[name]}]" if name in counts else parts[k]
        out = f"{out}.{piece}" if out else piece
    return out


def line_of(text: str, field: str | None) -> int | None:
    """The line where ``field`` is written, else that of its nearest written parent."""
    if not field:
        return None
    lines = field_lines(text)
    path = field
    while path:
        if path in lines:
            return lines[path]
        if path.endswith("]"):
            path = path[: path.rindex("[")]
        elif "." in path:
            path = path.rsplit(".", 1)[0]
        else:
            break
    return None
