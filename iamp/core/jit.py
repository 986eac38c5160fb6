"""One source for the scalar kernels, run as Python or compiled by numba (opt-in).

A kernel function is written once, in plain Python over floats and lists (no classes, no
exceptions, nothing numba lacks), and marked :func:`compilable`.  The planner calls the
Python function itself.  :func:`twin` compiles the *same code object* with ``numba.njit`` (no
fastmath, so the same IEEE operations in the same order): every global of the function that
names another compilable function is replaced by that function's twin, recursively.  So the
compiled and the Python path give the same numbers bit for bit (tested in a subprocess with
and without ``NUMBA_DISABLE_JIT``), and no result depends on whether numba is installed or
loaded.  A function numba cannot compile as written (a dict cache) names a stand-in with
:func:`compiled_as`: the same sums in the same order, without the cache.  A small helper called
in an inner loop is marked :func:`inlined`: its compiled callers carry its code in place of a
call.

Machine code kept on disk (``cache=True``) goes to the user's cache folder,
``$XDG_CACHE_HOME/iamp/numba`` (default ``~/.cache/iamp/numba``; :func:`cache_dir`), unless
``NUMBA_CACHE_DIR`` names another: numba's default, ``__pycache__`` beside the source, wrote files
into an installed package that ``pip`` does not know, so after ``pip install .`` the README's
``pip install -e .`` left ``site-packages/iamp`` behind as a namespace package that hid the editable
install from every other directory.  (numba falls back to its own locations where that folder is
not writable.)

Nothing here imports numba until :func:`twin` is called.  It lives in the core, the lowest layer, so
that the core's kernels (:mod:`iamp.core.polyroots_kernel`) compile through it as the planners'
do (they import it as :mod:`iamp.planners.pmp.jit`).
"""

from __future__ import annotations

import importlib.util
import os
import types
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

#: pure function -> the source numba compiles for it (itself, or its stand-in)
_SOURCE: dict[Callable[..., Any], types.FunctionType] = {}
_TWINS: dict[Callable[..., Any], Any] = {}
#: compilable functions that their compiled callers inline (:func:`inlined`)
_INLINE: set[Callable[..., Any]] = set()


def compilable(fn: F) -> F:
    """Mark ``fn`` as a kernel function numba may compile; returns ``fn`` unchanged.

    Parameters
    ----------
    fn : callable
        A plain Python function over floats, ints and lists.

    Returns
    -------
    callable
        ``fn`` itself.
    """
    assert isinstance(fn, types.FunctionType)
    _SOURCE[fn] = fn
    return fn


def inlined(fn: F) -> F:
    """Mark ``fn`` as :func:`compilable` and inlined into its compiled callers (``numba.njit(inline=
    "always")``: numba puts the callee's code in the caller before compiling it, as if written
    there, so the same operations in the same order and the same numbers).  For a small helper
    called in an inner loop: compiled apart, each call is a function call that LLVM cannot
    inline (the avoidance's row scan, :func:`iamp.planners.avoid.schur_kernel.active_set`, over
    1 626 rows: 24.5 µs calling ``_row_dot`` per row, 7.4 µs with the loop written in place).
    Only small leaves: each caller compiles its own copy (every compilable function inlined,
    the planners' kernels took 9 min 22 s to compile instead of 77 s).

    Parameters
    ----------
    fn : callable
        A plain Python function over floats, ints and arrays that calls no compilable function.

    Returns
    -------
    callable
        ``fn`` itself.
    """
    compilable(fn)
    _INLINE.add(fn)
    return fn


def compiled_as(stand_in: Callable[..., Any]) -> Callable[[F], F]:
    """Mark a function whose compiled twin is built from ``stand_in`` (the same arithmetic
    without what numba lacks, e.g. a dict cache).

    Parameters
    ----------
    stand_in : callable
        A plain Python function with the same signature and the same operations.

    Returns
    -------
    callable
        A decorator returning the marked function unchanged.
    """
    def mark(fn: F) -> F:
        assert isinstance(stand_in, types.FunctionType)
        _SOURCE[fn] = stand_in
        return fn
    return mark


def available() -> bool:
    """Whether numba can be imported (without importing it)."""
    return importlib.util.find_spec("numba") is not None


def cache_dir() -> str:
    """The folder of numba's on-disk cache of the twins (module docstring):
    ``$XDG_CACHE_HOME/iamp/numba``, else ``~/.cache/iamp/numba``."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "iamp", "numba")


def twin(fn: Callable[..., Any], cache: bool = False) -> Any:
    """The numba-compiled twin of the compilable ``fn`` (cached; compiled on its first call).

    Parameters
    ----------
    fn : callable
        A function marked with :func:`compilable`, :func:`inlined` or :func:`compiled_as`.
    cache : bool
        Let numba keep the machine code on disk (in :func:`cache_dir`, unless
        ``NUMBA_CACHE_DIR`` is set) for later processes.  Only for a set of functions that call nothing
        compilable outside their own source file: numba invalidates a cached function when
        its own file changes, not when a callee's file does.  The compilable functions it
        calls get the same flag.

    Returns
    -------
    numba dispatcher
        The same code with its compilable globals replaced by their twins (those marked
        :func:`inlined` compiled to be inlined into it).

    Raises
    ------
    ImportError
        numba is not installed.
    """
    if fn in _TWINS:
        return _TWINS[fn]
    import numba

    config: Any = numba.config
    if cache and not config.CACHE_DIR:
        config.CACHE_DIR = cache_dir()
    src = _SOURCE[fn]
    env = dict(src.__globals__)
    for name in src.__code__.co_names:  # the globals the code reads
        value = src.__globals__.get(name)
        if isinstance(value, types.FunctionType) and value in _SOURCE:
            env[name] = twin(value, cache)
    out = numba.njit(cache=cache, inline="always" if fn in _INLINE else "never")(
        types.FunctionType(src.__code__, env, src.__name__, src.__defaults__))
    _TWINS[fn] = out
    return out
