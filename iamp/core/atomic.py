"""Atomic file output: nothing a user had is half-overwritten.

Every file iamp writes goes to a temporary file in the destination's folder, is flushed and
fsync'ed, given the permissions a plain ``open()`` would give (or those of the file it
replaces), and then renamed over the destination with :func:`os.replace`.  If anything
fails, the temporary file is removed and the destination is untouched.

A write the machine refuses (a full disk, a read-only file system, no permission, a quota)
raises :class:`~iamp.core.errors.EnvironmentProblem` naming the *destination* (not the
temporary file): ``cannot write reports/results.json: No space left on device``.
"""

from __future__ import annotations

import errno
import os
import re
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

PathLike = str | os.PathLike[str]

#: ``errno`` values that mean "the machine refuses this write" (not a bug in iamp).
WRITE_REFUSED = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG,
                           errno.EIO, errno.ENAMETOOLONG, errno.ENOTDIR, errno.EISDIR, errno.EMFILE})


def write_refused(path: PathLike, exc: OSError) -> Exception | None:
    """The :class:`EnvironmentProblem` for ``exc`` while writing ``path``, or ``None`` when its
    ``errno`` is not one of :data:`WRITE_REFUSED` (then ``exc`` propagates as it is)."""
    from iamp.core.errors import EnvironmentProblem

    if exc.errno not in WRITE_REFUSED:
        return None
    return EnvironmentProblem(f"cannot write {path}", exc.strerror or str(exc), exc.errno)


def _final_mode(path: Path) -> int:
    """The mode of the file being replaced, else ``0666 & ~umask``."""
    try:
        return os.stat(path).st_mode & 0o777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def write_through(path: Path) -> Path:
    """The file a write to ``path`` replaces: for a symbolic link, the file it points to.

    A link is written *through* (issue 22 item 16): ``--force`` onto ``out.csv -> data/run.csv``
    replaces ``data/run.csv`` and the link stays a link, as ``open(path, "w")`` would; the
    atomic replacement happens beside the target, in the target's folder (a link to a missing
    file creates that file).
    """
    return Path(os.path.realpath(path)) if path.is_symlink() else path


def refuse_special(path: Path) -> None:
    """Raise :class:`~iamp.core.errors.EnvironmentProblem` when ``path`` exists and is not a
    regular file (a device, a named pipe, a socket): the atomic rename would replace it by a regular
    file (``--csv /dev/null --force`` run as root replaced the system's ``/dev/null``), and writing
    into it is not a file a user can keep."""
    import stat

    from iamp.core.errors import EnvironmentProblem

    try:
        mode = os.stat(path).st_mode
    except OSError:
        return  # missing (created), or the write itself reports why not
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        kind = ("a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else
                "a named pipe" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "not a file")
        raise EnvironmentProblem(f"cannot write {path}", f"it is {kind}, not a regular file; give a file name")


#: The temporary names :func:`atomic_path` makes: ``.<name>.<8 random characters>.tmp``.
TEMPORARY_NAME = re.compile(r"^\..+\.[A-Za-z0-9_]{8}\.tmp$")


def remove_stale_temporaries(folder: PathLike) -> list[Path]:
    """Delete the temporary files a killed run left in ``folder`` (recursively); returns them.

    Only for a folder the caller holds the exclusive output lock of (so no live iamp run is
    writing there) and that iamp owns (its marker): a ``SIGKILL`` cannot run the cleanup of
    :func:`atomic_path`, so its ``.<name>.XXXXXXXX.tmp`` stays until the next run removes it.
    """
    removed = []
    for p in Path(folder).rglob(".*.tmp"):
        if TEMPORARY_NAME.match(p.name) and p.is_file() and not p.is_symlink():
            try:
                p.unlink()
            except OSError:
                continue
            removed.append(p)
    return removed


@contextmanager
def atomic_path(path: PathLike) -> Iterator[str]:
    """Yield a temporary path beside ``path``; on success it replaces ``path``.

    For writers that want a file name (``Figure.savefig``, ``np.savez``).  The temporary
    file is removed however the block exits — an exception, Ctrl-C (``KeyboardInterrupt``)
    or SIGTERM under the ``iamp`` command line (which turns it into an exception) — so an
    interrupted run leaves the previous file and no ``.tmp`` behind.
    """
    path = write_through(Path(path))
    refuse_special(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=str(path.parent))
        os.close(fd)
    except OSError as exc:
        problem = write_refused(path, exc)
        if problem is None:
            raise
        raise problem from exc
    try:
        yield tmp
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.chmod(tmp, _final_mode(path))
        os.replace(tmp, path)
    except OSError as exc:
        problem = write_refused(path, exc)
        if problem is None:
            raise
        raise problem from exc
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


@contextmanager
def atomic_open(path: PathLike, mode: str = "w", encoding: str | None = "utf-8") -> Iterator[IO[Any]]:
    """Like ``open(path, mode)`` for writing, but atomic (``mode`` is ``"w"`` or ``"wb"``)."""
    if mode not in ("w", "wb"):
        raise ValueError(f"atomic_open writes only ('w' or 'wb'), got {mode!r}")
    with atomic_path(path) as tmp:
        with open(tmp, mode, encoding=None if "b" in mode else encoding) as fh:
            yield fh


def write_text(path: PathLike, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically; returns the path."""
    with atomic_open(path, "w", encoding) as fh:
        fh.write(text)
    return Path(path)
