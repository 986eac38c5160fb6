"""The exception tree of iamp.

Everything the library raises on purpose derives from :class:`IampError`.  Errors caused
by what the caller passed in (a bad scenario file, an invalid history) also derive from
:class:`ValueError`, so generic callers can catch them the usual way.
"""

from __future__ import annotations


class IampError(Exception):
    """Base class of every error iamp raises on purpose.

    Catch it to handle every refusal of the library at once; the command line turns it into
    one line on stderr and exit status 2 (never a traceback).

    Examples
    --------
    >>> import iamp
    >>> try:
    ...     iamp.load_scenario("no-such-scenario")
    ... except iamp.IampError as exc:
    ...     print(type(exc).__name__)
    ScenarioError
    """


class ScenarioError(IampError, ValueError):
    """An invalid scenario or problem.

    Parameters
    ----------
    message : str
        What is wrong.
    field : str, optional
        The offending field in the SPEC §4 vocabulary, e.g. ``"vehicles[0].length"``.
    source : str, optional
        The file (or built-in name) the scenario came from, ``file:line`` when the line is known.

    Examples
    --------
    >>> import iamp
    >>> str(iamp.ScenarioError("must be > 0 (got -1.0)", "ego.tf", "my.toml:3"))
    "my.toml:3: field 'ego.tf': must be > 0 (got -1.0)"
    """

    def __init__(self, message: str, field: str | None = None, source: str | None = None):
        self.message = message
        self.field = field
        self.source = source
        super().__init__(self.one_line())

    def one_line(self) -> str:
        """The refusal as one line, ``SOURCE: field 'FIELD': MESSAGE``.

        Returns
        -------
        str
            The parts that are known, joined by ``": "`` (the exception's ``str``).
        """
        parts = []
        if self.source:
            parts.append(str(self.source))
        if self.field:
            parts.append(f"field '{self.field}'")
        parts.append(self.message)
        return ": ".join(parts)


class HistoryError(ScenarioError):
    """An observed history that the predictor cannot use (SPEC §6).

    Too few samples, times not strictly increasing or not ending at 0, or a span shorter
    than the predictor needs; ``field`` names the history (``vehicles[i].history.t``).
    A subclass of :class:`ScenarioError`, with its parameters.
    """


class PredictorRequiredError(ScenarioError):
    """A vehicle is given by its history but no predictor was supplied."""


class OptionError(ScenarioError):
    """A planner option that does not exist, has an invalid value, or does not apply to the chosen
    planner (``field`` names the option, e.g. ``"solver"``)."""


class SolverError(IampError):
    """A numerical solver failed or reported a non-optimal status.

    The planners turn it into a :class:`~iamp.core.plan.Plan` with a failure status;
    it reaches the caller only from lower-level functions (e.g. a contact-time search
    without an interior stationary point).

    Parameters
    ----------
    message : str
        What failed.
    status : str
        The plan status it stands for (:mod:`iamp.status`, default ``"solver_error"``).
    """

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
