"""Command-line wiring of the reproduction report: ``iamp reproduce [--out DIR] [--no-pdf]``.

:func:`add_parsers` adds the sub-command to the main ``iamp`` parser.  The handler runs
:func:`iamp.comparison.report.reproduce` with a progress bar on standard error (the step under
way and the time left; silent with ``--quiet`` or when standard error is not a terminal), then
compiles ``report.tex`` with ``pdflatex`` (twice, in a temporary folder inside the output
folder, ``-interaction=nonstopmode -halt-on-error``) and moves ``report.pdf`` into place
atomically.  Standard output carries only the final summary.

Without ``pdflatex`` (or with ``--no-pdf``, or when it fails) no PDF is produced.  A
``report.pdf`` left by an earlier run is *kept* (iamp never deletes what it cannot rebuild —
it may be the committed report), and the summary says plainly that it is from an earlier run
and does not match the new ``report.tex``, and how to install LaTeX.

Exit status: 0 success (also without ``pdflatex``: the report is written, the PDF is not);
1 the report was written but ``pdflatex`` failed; 2 bad input; 3 a solver failed.
"""

from __future__ import annotations

import argparse
import errno
import glob
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from iamp.core.errors import IampError

EXIT_OK, EXIT_LATEX = 0, 1

__all__ = ["add_parsers", "cmd_reproduce", "compile_pdf", "remove_stale_staging", "staged_folder"]


def compile_pdf(out_dir: str | os.PathLike[str], tex_name: str = "report.tex", runs: int = 2,
                timeout: float = 300.0) -> tuple[bool, str]:
    """Compile ``out_dir/tex_name`` with ``pdflatex``; returns ``(ok, message)``.

    The auxiliary files go to a temporary folder inside ``out_dir`` (removed afterwards);
    the PDF replaces ``out_dir/<stem>.pdf`` atomically, and only on success.  The dates in the
    PDF are fixed (:func:`reproducible_latex_env`).  Returns
    ``(False, "pdflatex not found ...")`` if ``pdflatex`` is not installed.
    """
    exe = shutil.which("pdflatex")
    out = Path(out_dir)
    if exe is None:
        return False, ("pdflatex not found: report.tex was written but not compiled (install TeX Live, e.g. "
                       "apt-get install texlive-latex-recommended texlive-latex-extra lmodern)")
    stem = Path(tex_name).stem
    build = Path(tempfile.mkdtemp(prefix=".pdflatex-", dir=str(out)))
    try:
        for _ in range(runs):
            try:
                proc = subprocess.run([exe, "-interaction=nonstopmode", "-halt-on-error",
                                       f"-output-directory={build.name}", tex_name],
                                      cwd=str(out), capture_output=True, text=True, errors="replace",
                                      timeout=timeout, env=reproducible_latex_env())
            except subprocess.TimeoutExpired:
                return False, f"pdflatex timed out after {timeout:g} s"
            if proc.returncode != 0:
                log = (build / f"{stem}.log")
                text = log.read_text(errors="replace") if log.is_file() else proc.stdout
                lines = text.splitlines()
                err = [i for i, line in enumerate(lines) if line.startswith("!")]
                excerpt = "\n".join(lines[err[0]:err[0] + 6]) if err else "\n".join(lines[-15:])
                return False, f"pdflatex failed (exit {proc.returncode}):\n{excerpt}"
        pdf = build / f"{stem}.pdf"
        if not pdf.is_file():
            return False, "pdflatex produced no PDF"
        os.replace(pdf, out / f"{stem}.pdf")
        return True, str(out / f"{stem}.pdf")
    finally:
        shutil.rmtree(build, ignore_errors=True)


LATEX_INSTALL = "apt-get install texlive-latex-recommended texlive-latex-extra lmodern"


def reproducible_latex_env() -> dict[str, str]:
    """The environment for ``pdflatex``: the same PDF bytes from the same input.

    ``SOURCE_DATE_EPOCH`` (the user's, else ``0``) with ``FORCE_SOURCE_DATE=1`` fixes the
    creation and modification dates pdfTeX writes; ``report.tex`` sets ``\\pdftrailerid{}`` (no
    random file ID).
    """
    return {**os.environ, "SOURCE_DATE_EPOCH": os.environ.get("SOURCE_DATE_EPOCH", "0"), "FORCE_SOURCE_DATE": "1"}


def _stale_pdf_note(out: Path) -> str | None:
    """A sentence about ``out/report.pdf`` left by an earlier run (kept: it cannot be rebuilt
    here, and it does not match the new report.tex), or ``None`` if there is none."""
    pdf = out / "report.pdf"
    if not pdf.is_file():
        return None
    return f"{pdf} is kept from an earlier run and does NOT match the new report.tex (not rebuilt here)"


def cmd_reproduce(args: argparse.Namespace) -> int:
    from iamp.core.outputs import guarded_folder  # checked (writable, ours or --force), locked, marked

    with guarded_folder(args.out, "reproduce", getattr(args, "force", False)) as out:
        with staged_folder(out) as stage:
            return _reproduce_into(args, stage, Path(args.out))


#: Name of the staging folder beside the output folder ``<name>``: ``.<name>.iamp-staging-XXXXXXXX``.
STAGING_INFIX = ".iamp-staging-"


@contextmanager
def staged_folder(out: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a staging copy of the folder ``out``; when the block completes, it replaces ``out``.

    The staging folder is a sibling of ``out`` (``.<name>.iamp-staging-XXXXXXXX``, the same file
    system, so the replacement is a rename) that starts as a copy of ``out`` (what the run does
    not rewrite — other commands' outputs, an earlier ``report.pdf`` — stays).  When the block
    exits normally the two folders are exchanged in one atomic ``renameat2(RENAME_EXCHANGE)``
    (Linux), else by two renames with Ctrl-C and SIGTERM held back between them, and the old
    contents are deleted.  If the block raises (an error, Ctrl-C: ``KeyboardInterrupt``, SIGTERM
    under the command line), the staging folder is deleted and ``out`` is untouched.

    Files that someone else writes into ``out`` while the block runs (another command's
    folder inside it) are copied into the staging folder before the exchange, unless the run
    wrote the same file; a folder inside ``out`` that another iamp run holds locked is refused
    at the start (exit 2).  The caller holds ``out``'s output lock
    (:func:`iamp.core.outputs.guarded_folder`): staging folders of ``out`` that a killed run left
    behind are deleted here.  A symbolic link to a
    folder stays a link; the folder it points to is replaced.

    Parameters
    ----------
    out : path-like
        An existing folder.

    Yields
    ------
    Path
        The staging folder to write into.

    Raises
    ------
    EnvironmentProblem
        The staging copy cannot be made (a full disk, a read-only parent folder), naming ``out``.
    """
    target = Path(os.path.realpath(out))
    remove_stale_staging(target)
    _refuse_busy_subfolders(target, Path(out))
    try:
        stage = Path(tempfile.mkdtemp(prefix=f".{target.name}{STAGING_INFIX}", dir=str(target.parent)))
    except OSError as exc:
        raise _refused(target, exc) from None
    try:
        try:
            shutil.copytree(target, stage, symlinks=True, dirs_exist_ok=True, ignore=_not_copied)
        except (OSError, shutil.Error) as exc:
            first = exc.args[0][0] if isinstance(exc, shutil.Error) and exc.args and exc.args[0] else None
            raise _refused(target, exc if isinstance(exc, OSError) else OSError(errno.EIO, str(first))) from None
        copied = _stats(target)
        try:
            yield stage
        except IampError as exc:
            raise _renamed(exc, stage, target) from exc
        with _signals_held():
            _take_over_changes(target, stage, copied)
            _exchange(stage, target)
            shutil.rmtree(stage, ignore_errors=True)  # now the old contents
    finally:
        shutil.rmtree(stage, ignore_errors=True)  # the staging copy of a run that did not complete


def _stats(folder: Path) -> dict[str, tuple[int, int]]:
    """``{relative path: (size, mtime_ns)}`` of every file below ``folder`` (links not followed)."""
    out: dict[str, tuple[int, int]] = {}
    for root, _, files in os.walk(folder):
        for name in files:
            path = Path(root) / name
            try:
                st = path.lstat()
            except OSError:
                continue
            out[path.relative_to(folder).as_posix()] = (st.st_size, st.st_mtime_ns)
    return out


def _take_over_changes(target: Path, stage: Path, copied: dict[str, tuple[int, int]]) -> None:
    """Copy into ``stage`` what someone else wrote into ``target`` while the run went on (another
    command's files in a subfolder: they must survive the exchange), unless the run wrote that
    file itself (its own outputs win)."""
    from iamp.core.outputs import LOCK_NAME

    staged = _stats(stage)
    for rel, stat in _stats(target).items():
        if copied.get(rel) == stat or Path(rel).name == LOCK_NAME or STAGING_INFIX in rel:
            continue
        if rel in staged and staged[rel] != copied.get(rel):
            continue  # the reproduction rewrote it
        dest = stage / rel
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(target / rel, dest, follow_symlinks=False)


def _refuse_busy_subfolders(target: Path, shown: Path) -> None:
    """Refuse (exit 2) when another iamp run holds the lock of a folder inside ``target``
    (``iamp campaign --out reports/campaign-new``): its files would change under the copy."""
    import fcntl

    from iamp.core.outputs import LOCK_NAME, OutputError

    for lock in target.rglob(LOCK_NAME):
        if lock.parent == target:
            continue
        try:
            fd = os.open(lock, os.O_RDONLY)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            fcntl.flock(fd, fcntl.LOCK_UN)
        except OSError:
            sub = shown / lock.parent.relative_to(target)
            raise OutputError(f"holds {sub}, which another iamp run is writing; wait for it to finish",
                              "--out", str(shown)) from None
        finally:
            os.close(fd)


def remove_stale_staging(target: Path) -> list[Path]:
    """Delete the staging folders of ``target`` that a killed run left (the caller holds its lock)."""
    removed: list[Path] = []
    try:
        siblings = list(target.parent.glob(f".{glob.escape(target.name)}{STAGING_INFIX}*"))
    except OSError:
        return removed
    for p in siblings:
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p, ignore_errors=True)
            removed.append(p)
    return removed


def _not_copied(folder: str, names: list[str]) -> set[str]:
    """The lock file and a killed run's temporary files are not copied into the staging folder."""
    from iamp.core.atomic import TEMPORARY_NAME
    from iamp.core.outputs import LOCK_NAME

    return {n for n in names if n == LOCK_NAME or TEMPORARY_NAME.match(n)
            or n.startswith((".pdflatex-", ".campaign-small-"))}


def _refused(target: Path, exc: OSError) -> Exception:
    from iamp.core.atomic import write_refused
    from iamp.core.errors import EnvironmentProblem

    problem = write_refused(target, exc)
    return problem if problem is not None else EnvironmentProblem(f"cannot write {target}",
                                                                  exc.strerror or str(exc), exc.errno)


def _renamed(exc: IampError, stage: Path, target: Path) -> IampError:
    """``exc`` with the staging folder's path replaced by the output folder's (a message names
    the file the user will look for, not a folder that no longer exists)."""
    from iamp.core.errors import EnvironmentProblem

    if isinstance(exc, EnvironmentProblem) and str(stage) in exc.what:
        return EnvironmentProblem(exc.what.replace(str(stage), str(target)), exc.reason, exc.errno)
    return exc


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(stage: Path, target: Path) -> None:
    """Swap the folders ``stage`` and ``target`` (afterwards ``stage`` holds the old contents)."""
    if _renameat2_exchange(stage, target):
        return
    aside = Path(tempfile.mkdtemp(prefix=f".{target.name}{STAGING_INFIX}", dir=str(target.parent)))
    os.rmdir(aside)
    os.rename(target, aside)
    try:
        os.rename(stage, target)
    except OSError:
        os.rename(aside, target)
        raise
    os.rename(aside, stage)


def _renameat2_exchange(a: Path, b: Path) -> bool:
    """``renameat2(a, b, RENAME_EXCHANGE)``: both names swapped in one step; False where the
    system cannot (not Linux, an old C library, a file system without it)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    return int(fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)) == 0


@contextmanager
def _signals_held() -> Iterator[None]:
    """Hold Ctrl-C and SIGTERM back while the folders are exchanged (delivered afterwards)."""
    held = {signal.SIGINT, signal.SIGTERM}
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _reproduce_into(args: argparse.Namespace, out: Path, shown: Path) -> int:
    """The reproduction into ``out`` (the staging folder); messages name ``shown`` (``--out``)."""
    from iamp.cli.progress import progress_bar, progress_enabled
    from iamp.comparison.report.reproduction import reproduce

    start = time.perf_counter()
    config = None
    if args.select_predictor:
        import dataclasses

        from iamp.comparison.report.reproduction import ReproduceConfig

        base = ReproduceConfig.quick_config() if args.quick else ReproduceConfig()
        config = dataclasses.replace(base, predictor_select=True)
    with progress_bar(None, "reproduce", enabled=progress_enabled(args)) as tick:
        res = reproduce(out, progress=tick, status=tick.describe, quick=args.quick, config=config)
    for note in res.get("notes", []):
        sys.stderr.write(f"note: {note}\n")
    status = EXIT_OK
    if args.no_pdf:
        pdf_msg = "PDF not compiled (--no-pdf)"
        ok = False
    elif shutil.which("pdflatex") is None:
        ok = False
        sys.stderr.write("iamp: cannot compile the PDF: pdflatex is not installed; report.tex and its tables and "
                         f"figures were written. To get report.pdf install LaTeX ({LATEX_INSTALL}) and run "
                         "iamp reproduce again.\n")
        pdf_msg = "PDF not compiled: pdflatex is not installed"
    else:
        if not args.quiet:
            sys.stderr.write("compiling report.tex with pdflatex (twice) ...\n")
        ok, msg = compile_pdf(out)
        if ok:
            pdf_msg = f"PDF: {msg}"
        else:
            pdf_msg = f"report.tex did not compile: {msg}"
            status = EXIT_LATEX
    if not ok:
        stale = _stale_pdf_note(out)
        if stale:
            pdf_msg += f"; {stale}".replace(str(out), str(shown))
    elif pdf_msg.startswith("PDF: "):
        pdf_msg = f"PDF: {shown / 'report.pdf'}"
    print(f"reproduction written to {shown}/ in {time.perf_counter() - start:.0f} s")
    print(f"  {len(res.get('outputs', []))} files: report.tex, results.json, tables/*.tex, figures/*.pdf|png, "
          "timing/ (the machine-dependent numbers)")
    print(f"  {pdf_msg}")
    for name, q in res.get("qualitative", {}).items():
        print(f"  {name} vs paper-1: paper says {q['paper_claim']}; measured {q['observed_majority']} "
              f"({q['n_more_aggressive']} of {q['n_measures']} measures more aggressive)")
    return status


def add_parsers(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Add ``reproduce`` to the ``iamp`` sub-command parsers."""
    from iamp.cli.progress import add_quiet_flag

    p = subparsers.add_parser(
        "reproduce", help="reproduce the paper's scenarios and the PMP/QP comparison as a report",
        description="Run the paper's scenarios 1-3 (from their histories, through the shipped predictor) and the "
                    "two-vehicle scenario with the PMP and QP planners, the ZOH convergence study, solve-time "
                    "samples and the predictor evaluation; write tables (booktabs), figures (PDF and PNG), "
                    "results.json and report.tex into the output folder, and compile report.pdf with pdflatex "
                    "if it is installed. Takes a few minutes.")
    p.add_argument("--out", default="reports", help="output folder (default: reports/)")
    p.add_argument("--force", action="store_true",
                   help="write into an existing folder that iamp did not write (no .iamp-output marker)")
    p.add_argument("--no-pdf", action="store_true", help="do not run pdflatex")
    p.add_argument("--quick", action="store_true", help="small grids and few repetitions (a smoke run)")
    p.add_argument("--select-predictor", action="store_true",
                   help="re-run the predictor's model-selection grid (many minutes); by default an existing "
                        "DIR/predictor_eval.json with a selection for the same data is reused, else the shipped "
                        "configuration is evaluated without selection")
    add_quiet_flag(p)
    p.set_defaults(func=cmd_reproduce)
