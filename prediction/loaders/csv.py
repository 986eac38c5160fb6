"""CSV reading shared by the trajectory loaders: header resolution, chunked conversion, errors.

Problems with a file raise :class:`~iamp.prediction.tracks.table.TrackDataError` naming the file,
the column and the line.
"""

from __future__ import annotations

import csv
import gzip
import os
import warnings
import zlib
from array import array
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import IO

import numpy as np

from iamp.prediction._typing import Array, BoolArray, Lines, PathLike
from iamp.prediction.tracks.table import TrackDataError

from .report import LoadReport

__all__ = ["ColumnSpec", "read_csv"]

#: ``(logical name, accepted header names, required)``.
ColumnSpec = Sequence[tuple[str, tuple[str, ...], bool]]

_CHUNK_ROWS = 200_000  # CSV rows converted to arrays at a time
#: Longest line read [characters]: a longer one is refused as it is read (memory stays bounded;
#: a row of the supported formats is a few hundred characters).
MAX_LINE_CHARS = 1 << 20


def _bounded_lines(fh: IO[str], path: Path, first_line: int = 1) -> Iterable[str]:
    """The lines of ``fh``, refusing one longer than :data:`MAX_LINE_CHARS` before it is read whole."""
    limit = MAX_LINE_CHARS
    number = first_line
    while True:
        try:
            line = fh.readline(limit + 1)
        except (EOFError, zlib.error, gzip.BadGzipFile) as exc:  # a truncated or corrupt .gz
            raise TrackDataError(f"the compressed file is truncated or corrupt after line {number - 1} ({exc})",
                                 source=path) from None
        if not line:
            return
        if len(line) > limit:
            raise TrackDataError(f"line {number} is longer than {limit} characters: not a row of a trajectory table",
                                 source=path)
        yield line
        number += 1


def _open_text(path: Path) -> IO[str]:
    if path.suffix == ".gz":
        return gzip.open(path, "rt", newline="", encoding="utf-8-sig")
    return open(path, newline="", encoding="utf-8-sig")


def _norm(name: str) -> str:
    return name.strip().strip('"').strip().lower()


def _read_header(path: Path, delimiter: str | None) -> tuple[list[str], str]:
    try:
        with _open_text(path) as fh:
            first = next(iter(_bounded_lines(fh, path)), "")
    except FileNotFoundError:
        raise TrackDataError("no such file", source=path) from None
    except (OSError, UnicodeDecodeError, EOFError, zlib.error) as exc:
        raise TrackDataError(f"cannot read the file ({exc})", source=path) from None
    if not first.strip():
        raise TrackDataError("the file is empty (no header line)", source=path)
    if delimiter is None:
        delimiter = ";" if first.count(";") > first.count(",") else ","
    header = next(csv.reader([first], delimiter=delimiter))
    return header, delimiter


def _resolve(header: list[str], spec: Sequence[tuple[str, tuple[str, ...], bool]], path: Path) -> dict[str, int]:
    """Map logical column names to header indices; a missing required column is an error."""
    index: dict[str, int] = {}
    for i, name in enumerate(header):
        index.setdefault(_norm(name), i)
    found: dict[str, int] = {}
    for logical, candidates, required in spec:
        for cand in candidates:
            if cand.lower() in index:
                found[logical] = index[cand.lower()]
                break
        else:
            if required:
                shown = ", ".join(h.strip() for h in header[:6]) + (", ..." if len(header) > 6 else "")
                raise TrackDataError(f"missing (the header has: {shown})", column=candidates[0], source=path)
    return found


def _to_float(strings: Sequence[str], column: str, path: Path, lines: Lines = None) -> Array:
    try:
        out = np.asarray(strings, dtype=str).astype(np.float64)
    except ValueError:
        out = None
    if out is None:
        vals = []
        for k, s in enumerate(strings):
            try:
                vals.append(float(s))
            except ValueError:
                try:  # thousands separators, as in some NGSIM exports
                    vals.append(float(s.replace(",", "")))
                except ValueError:
                    line = lines[k] if lines is not None else k + 2
                    raise TrackDataError(f"line {line}: cannot read {s!r} as a number",
                                         column=column, source=path) from None
        out = np.asarray(vals, dtype=np.float64)
    bad = ~np.isfinite(out)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        line = lines[k] if lines is not None else k + 2
        raise TrackDataError(f"line {line}: value {strings[k]!r} is not finite", column=column, source=path)
    return out


def read_csv(path: Path, spec: Sequence[tuple[str, tuple[str, ...], bool]], *, text: Iterable[str] = (),
              delimiter: str | None = None, skip_empty: str | None = None, row_hash: bool = False) -> dict[str, Array]:
    """Read the columns of ``spec`` (logical name, accepted header names, required).

    Numeric columns come back as float64 arrays, the ``text`` ones as str arrays; with
    ``row_hash`` the key ``"__hash__"`` holds a hash of each full row (for exact-duplicate
    detection) and ``"__line__"`` the line numbers.  Rows where the ``skip_empty`` column is
    blank are dropped (SUMO CSV has such rows for empty time steps).
    """
    header, delimiter = _read_header(path, delimiter)
    where = _resolve(header, spec, path)
    text = set(text)
    if skip_empty is None and not row_hash:  # fast path (numpy's C parser); errors fall through
        cols_fast = _read_fast(path, header, where, set(text), delimiter)
        if cols_fast is not None:
            return cols_fast

    names = list(where)
    idx = [where[n] for n in names]
    width = max(idx) + 1
    store: list[list[str]] = [[] for _ in names]
    lines = array("q")
    hashes = array("q")
    skip_k = names.index(skip_empty) if skip_empty in where else None
    parts: dict[str, list[np.ndarray]] = {n: [] for n in names}

    def flush() -> None:  # convert the strings read so far (bounded memory for big files)
        line_arr = np.frombuffer(lines, dtype=np.int64)[len(lines) - len(store[0]):]
        for n, lst in zip(names, store):
            if not lst:
                continue
            if n in text:
                parts[n].append(np.asarray([s.strip() for s in lst], dtype=str))
            else:
                parts[n].append(_to_float(lst, header[where[n]].strip(), path, line_arr))
            lst.clear()

    try:
        with _open_text(path) as fh:
            reader = csv.reader(_bounded_lines(fh, path), delimiter=delimiter)
            next(reader)
            for row in reader:
                if not row or (len(row) == 1 and not row[0].strip()):
                    continue
                if len(row) < width:
                    short = next(n for n, i in zip(names, idx) if i >= len(row))
                    raise TrackDataError(f"line {reader.line_num}: row has only {len(row)} fields",
                                         column=header[where[short]].strip(), source=path)
                if skip_k is not None and not row[idx[skip_k]].strip():
                    continue
                for lst, i in zip(store, idx):
                    lst.append(row[i])
                lines.append(reader.line_num)
                if row_hash:
                    hashes.append(hash(tuple(row)))
                if len(store[0]) >= _CHUNK_ROWS:
                    flush()
            flush()
    except csv.Error as exc:
        raise TrackDataError(f"malformed CSV ({exc})", source=path) from None
    except UnicodeDecodeError as exc:
        raise TrackDataError(f"not a UTF-8 text file ({exc})", source=path) from None
    line_arr = np.frombuffer(lines, dtype=np.int64) if len(lines) else np.empty(0, np.int64)
    cols = {}
    for n in names:
        if parts[n]:
            cols[n] = np.concatenate(parts[n])
        else:
            cols[n] = np.empty(0, dtype=str) if n in text else np.empty(0)
    if row_hash:
        cols["__hash__"] = np.frombuffer(hashes, dtype=np.int64) if len(hashes) else np.empty(0, np.int64)
    cols["__line__"] = line_arr
    return cols


def _integers(col: np.ndarray, column: str, path: Path) -> np.ndarray:
    r = np.round(col)
    if np.any(np.abs(r - col) > 1e-9):
        k = int(np.flatnonzero(np.abs(r - col) > 1e-9)[0])
        raise TrackDataError(f"row {k + 1}: {col[k]!r} is not an integer", column=column, source=path)
    return r.astype(np.int64)


def _segments(key_change: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """Segment number per row (rows sorted by key then frame): new segment where the key
    changes or the frame does not advance by exactly one."""
    n = frame.size
    if n == 0:
        return np.empty(0, dtype=np.int64)
    new = np.ones(n, dtype=bool)
    new[1:] = key_change | (np.diff(frame) != 1)
    return np.cumsum(new) - 1


def _path(p: PathLike) -> Path:
    return Path(os.fspath(p))


_read_csv = read_csv  # the former private name


#: Drop reasons shared by every loader.
EXACT_DUPLICATE = "exact duplicate row (same vehicle, frame and values)"
CONFLICTING_DUPLICATE = "conflicting row for the same vehicle and frame (the first in file order kept)"


def duplicate_rows(same_key: BoolArray, values: Sequence[Array], report: LoadReport) -> BoolArray:
    """Rows to keep of a table sorted by key (then file order), counting the dropped ones.

    ``same_key[k]`` says row ``k + 1`` has the key of row ``k``.  Of every group of rows with
    one key the first is kept; a later row is an *exact* duplicate when all ``values`` equal the
    first row's, else a *conflicting* one (both counted in ``report``).
    """
    m = same_key.size + 1
    dup = np.zeros(m, dtype=bool)
    dup[1:] = same_key
    first = np.maximum.accumulate(np.where(~dup, np.arange(m), 0))
    differs = np.zeros(m, dtype=bool)
    for v in values:
        differs |= v != v[first]
    report.drop(EXACT_DUPLICATE, int(np.sum(dup & ~differs)))
    report.drop(CONFLICTING_DUPLICATE, int(np.sum(dup & differs)))
    keep: BoolArray = ~dup
    return keep


def _read_fast(path: Path, header: list[str], where: dict[str, int], text: set[str],
               delimiter: str | None) -> dict[str, Array] | None:
    """All columns with :func:`numpy.loadtxt` (one pass for the numbers, one per text column).

    Returns ``None`` when numpy cannot parse the file (a bad value, a short row): the slow path
    then names the column and line.  ``"__line__"`` is the line number assuming one row per line
    (only used for messages and to keep file order).
    """
    nums = [n for n in where if n not in text]
    cols: dict[str, Array] = {}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "input contained no data": reported by the caller
            if nums:
                with _open_text(path) as fh:
                    data = np.loadtxt(_bounded_lines(fh, path), delimiter=delimiter, skiprows=1,
                                      usecols=[where[n] for n in nums],
                                      dtype=np.float64, ndmin=2, quotechar='"')
                for k, n in enumerate(nums):
                    cols[n] = data[:, k]
            for n in where:
                if n in text:
                    with _open_text(path) as fh:
                        cols[n] = np.char.strip(np.loadtxt(_bounded_lines(fh, path), delimiter=delimiter,
                                                           skiprows=1, usecols=[where[n]],
                                                           dtype=str, ndmin=1, quotechar='"'))
    except ValueError:
        return None
    sizes = {c.shape[0] for c in cols.values()}
    if len(sizes) != 1:
        return None
    for n in nums:
        if not np.all(np.isfinite(cols[n])):
            k = int(np.flatnonzero(~np.isfinite(cols[n]))[0])
            raise TrackDataError(f"line {k + 2}: value is not finite", column=header[where[n]].strip(), source=path)
    cols["__line__"] = np.arange(2, sizes.pop() + 2, dtype=np.int64)
    return cols
