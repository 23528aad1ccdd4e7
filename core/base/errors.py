"""Exception types of handeye.

Every error a user can provoke with bad input is a subclass of `HandEyeError`, itself a
`ValueError`, so ``except ValueError`` keeps working for callers who do not care which one.
Messages say what was wrong, what was expected and, where it helps, what to do.
"""

from __future__ import annotations

from collections.abc import Iterable


def shown(value: object, limit: int = 60) -> str:
    """repr(value) on one line, cut to `limit` characters (with "..."), for a message that quotes
    what the user passed: that may be a huge integer or a whole array, whose repr spans lines."""
    text = " ".join(repr(value).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


class HandEyeError(ValueError):
    """Base class of every error raised by handeye."""


class InputError(HandEyeError):
    """Data has the wrong shape, length or type, contains NaN/inf, or is not in SE(3)."""


class DegenerateDataError(InputError):
    """Data is well formed but cannot determine the unknowns (too few pairs, too little motion)."""


class SolverError(HandEyeError):
    """A solver could not produce an answer it can stand behind (numerical failure, infeasible)."""


class SolverTimeoutError(SolverError):
    """A solver gave no answer within its time limit and was stopped (`handeye.framework.isolation`)."""


class UnknownPluginError(HandEyeError):
    """A problem, solver, backend or option name that nothing registered knows.

    `kind` is a plain noun ("solver", "backend", "option"); `owner` what the name belongs to, as
    a phrase that follows it ("of solver 'kron-lstsq'", "for problem 'axyb'"), so the message reads
    "unknown option 'normalise' of solver 'kron-lstsq'; known options: 'normalize'".
    """

    def __init__(self, kind: str, name: str, known: Iterable[str], hint: str = "", *, owner: str = "") -> None:
        self.kind = kind
        self.owner = owner
        self.name = name
        self.known = sorted(known)
        listing = ", ".join(repr(k) for k in self.known) or "(none registered)"
        where = f" {owner}" if owner else ""
        message = f"unknown {kind} {name!r}{where}; known {kind}s: {listing}"
        super().__init__(message + (f". {hint}" if hint else ""))


class BackendUnavailableError(HandEyeError):
    """A known backend (or solver) whose optional dependency is not installed or not usable."""


class PluginRegistrationError(HandEyeError):
    """A plugin registered something invalid, e.g. a name another plugin already holds."""


class PluginLoadWarning(UserWarning):
    """A third-party plugin failed to load (its module raised on import) and was skipped."""
