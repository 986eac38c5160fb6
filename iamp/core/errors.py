"""The exception tree of iamp.

Everything the library raises on purpose derives from :class:`IampError`.  Errors caused
by what the caller passed in (a bad scenario file, an invalid history) also derive from
:class:`ValueError`, so generic callers can catch them the usual way.
"""

from __future__ import annotations


class IampError(Exception):
    """Base class of every error iamp raises on purpose."""


class ScenarioError(IampError, ValueError):
    """An invalid scenario or problem.

    Parameters
    ----------
    message : str
        What is wrong.
    field : str, optional
        The offending field in the SPEC §4 vocabulary, e.g. ``"vehicles[0].length"``.
    source : str, optional
        The file (or built-in name) the scenario came from.
    """

    def __init__(self, message: str, field: str | None = None, source: str | None = None):
        self.message = message
        self.field = field
        self.source = source
        super().__init__(self.one_line())

    def one_line(self) -> str:
        parts = []
        if self.source:
            parts.append(str(self.source))
        if self.field:
            parts.append(f"field '{self.field}'")
        parts.append(self.message)
        return ": ".join(parts)


class HistoryError(ScenarioError):
    """An observed history that the predictor cannot use (SPEC §6)."""


class PredictorRequiredError(ScenarioError):
    """A vehicle is given by its history but no predictor was supplied."""


class OptionError(ScenarioError):
    """A planner option that does not exist, has an invalid value, or does not apply to the chosen
    planner (``field`` names the option, e.g. ``"solver"``)."""


class SolverError(IampError):
    """A numerical solver failed or reported a non-optimal status."""

    def __init__(self, message: str, status: str = "solver_error"):
        self.status = status
        super().__init__(message)


class MissingDependencyError(IampError, ImportError):
    """An optional dependency is not installed; the message says how to install it."""


class EnvironmentProblem(IampError):
    """The machine stops the work, not the input: a full disk, a read-only folder, an
    unreachable server.  The message names the path or address (the command line exits 2).

    Parameters
    ----------
    what : str
        ``"cannot write PATH"``, ``"cannot reach the Dask scheduler at ADDRESS"``, ...
    reason : str
        The system's reason (``"No space left on device"``).
    errno : int, optional
        The ``errno`` of the underlying :class:`OSError`.
    """

    def __init__(self, what: str, reason: str, errno: int | None = None):
        self.what = what
        self.reason = reason
        self.errno = errno
        super().__init__(f"{what}: {reason}")
