"""Guards for everything iamp writes: nothing the user has is destroyed.

Every command that writes checks its outputs *before* the long work starts:

* an output that is also one of the inputs is refused (``iamp train data.csv --out
  data.csv`` would replace the training data with the model);
* an existing file is replaced only with ``--force``;
* an existing folder is written into only if iamp wrote it (it holds the marker file
  :data:`MARKER`, written at the start of every run into that folder), if it is empty, or
  with ``--force`` — so ``iamp reproduce`` may regenerate its own report folder, but not
  fill a folder of someone's papers with figures;
* the destination must be writable: a temporary file is created and removed where the
  output will go, so a read-only location fails in a second, not after the work;
* a folder is locked (:func:`output_lock`, ``fcntl.flock`` on :data:`LOCK_NAME` inside it)
  for the whole run, so two runs into one folder cannot interleave their files: the second
  one stops at once with exit status 2.

The files themselves are written atomically (:mod:`iamp.core.atomic`): a run stopped by
Ctrl-C or SIGTERM leaves the previous file, never half a file or a temporary file.

Refusals raise :class:`OutputError` (a :class:`~iamp.core.errors.ScenarioError`, so the
command line reports one line with the option and the path and exits with status 2).
"""

from __future__ import annotations

import errno
import json
import os
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from iamp.core.errors import ScenarioError

#: Marker file that identifies a folder written by iamp (it may be regenerated).
MARKER = ".iamp-output"
#: Lock file held (``flock``) by the run writing into a folder.
LOCK_NAME = ".iamp-lock"

PathLike = str | os.PathLike[str]


class OutputError(ScenarioError):
    """An output that would destroy something, cannot be written, or is in use."""


def _same(a: Path, b: Path) -> bool:
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return a.resolve() == b.resolve()


def _nearest_existing(path: Path) -> Path:
    p = path.absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _probe_writable(folder: Path, option: str, shown: str) -> None:
    """Create and remove a file in ``folder`` (or the folder's nearest existing ancestor)."""
    base = _nearest_existing(folder)
    if not base.is_dir():
        raise OutputError(f"cannot be written: {base} is not a folder", option, shown)
    try:
        fd, tmp = tempfile.mkstemp(prefix=".iamp-probe-", suffix=".tmp", dir=str(base))
    except OSError as exc:
        reason = exc.strerror or exc.__class__.__name__
        raise OutputError(f"cannot be written ({reason}: {base})", option, shown) from None
    os.close(fd)
    os.unlink(tmp)


def check_output(path: PathLike, inputs: Iterable[PathLike] = (), force: bool = False, *,
                 option: str = "--out", folder: bool = False) -> Path:
    """Check an output before any work; returns it as a :class:`Path`.

    Parameters
    ----------
    path : path
        The file (or, with ``folder=True``, the folder) the command will write.
    inputs : paths
        Everything the command reads; the output must be none of them.
    force : bool
        Allow replacing an existing file / writing into a folder iamp did not write.
    option : str
        The option named in refusals (``"--out"``, ``"--latex"``, ...).
    folder : bool
        ``path`` is an output folder (see the module docstring for when one is accepted).

    Raises
    ------
    OutputError
        With ``option`` as the field and ``path`` as the source.
    """
    p = Path(path)
    shown = str(path)
    if not shown.strip():
        raise OutputError("is empty; give a file name", option, shown)
    for inp in inputs:
        q = Path(inp)
        if _same(p, q):
            raise OutputError(f"is also an input ({inp}); writing it would destroy that input - choose another "
                              "path", option, shown)
    if folder:
        if p.exists() and not p.is_dir():
            raise OutputError("exists and is not a folder", option, shown)
        if p.is_dir() and not force and not (p / MARKER).exists():
            try:
                has_files = any(p.iterdir())
            except OSError as exc:
                raise OutputError(f"cannot be read ({exc.strerror or exc})", option, shown) from None
            if has_files:
                raise OutputError(f"is a folder with files iamp did not write (no {MARKER} marker); use --force to "
                                  "write into it anyway", option, shown)
        _probe_writable(p, option, shown)
        return p
    if p.is_dir():
        raise OutputError("is a folder; give a file name", option, shown)
    if p.exists() and not force:
        raise OutputError("exists; use --force to replace it", option, shown)
    _probe_writable(p.parent, option, shown)
    return p


def write_marker(folder: PathLike, command: str) -> Path:
    """Mark ``folder`` as written by ``iamp <command>`` (so a later run may regenerate it)."""
    from iamp.core.atomic import write_text

    target = Path(folder) / MARKER
    text = json.dumps({"written_by": f"iamp {command}",
                       "note": "this folder was generated by iamp and may be regenerated"}) + "\n"
    return write_text(target, text)


@contextmanager
def output_lock(folder: PathLike, option: str = "--out") -> Iterator[Path]:
    """Hold an exclusive lock on ``folder`` for the duration of the ``with`` block.

    Creates the folder if needed.  A second process trying to lock the same folder gets an
    :class:`OutputError` at once (it does not wait).  The lock is released when the block
    exits, however it exits (the kernel also drops it if the process dies).
    """
    import fcntl

    p = Path(folder)
    shown = str(folder)
    try:
        p.mkdir(parents=True, exist_ok=True)
        fd = os.open(p / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise OutputError(f"cannot be written ({exc.strerror or exc})", option, shown) from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                raise OutputError(f"cannot be locked ({exc.strerror or exc})", option, shown) from None
            holder = os.pread(fd, 64, 0).decode("ascii", "replace").strip()
            who = f" (pid {holder})" if holder.isdigit() else ""
            raise OutputError(f"is in use by another iamp run{who}; wait for it to finish or choose another folder",
                              option, shown) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode("ascii"), 0)
        try:
            yield p
        finally:
            try:
                os.ftruncate(fd, 0)
            except OSError:
                pass
            fcntl.flock(fd, fcntl.LOCK_UN)
    finally:
        os.close(fd)


@contextmanager
def guarded_folder(folder: PathLike, command: str, force: bool = False, inputs: Iterable[PathLike] = (),
                   option: str = "--out") -> Iterator[Path]:
    """Everything a command that writes into an output folder needs, in one ``with``:

    :func:`check_output` (fail fast, before the work), :func:`output_lock` for the whole
    block, and :func:`write_marker` so that the folder may be regenerated later.
    """
    from iamp.core.atomic import remove_stale_temporaries

    p = check_output(folder, inputs, force, option=option, folder=True)
    with output_lock(p, option=option):
        write_marker(p, command)
        remove_stale_temporaries(p)  # a killed earlier run's .tmp files (we hold the lock)
        yield p
