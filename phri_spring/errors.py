"""Typed exceptions of phri-spring.

Every error a user can cause derives from :class:`PhriError` and carries the
file, the key or column, and what was expected, so that the command line can
print it as one line. The hierarchy builds on the standard ``ValueError`` and
``TypeError`` so that library users can catch the usual exceptions too.

========================  ==========  ==========================================
class                      exit code   meaning
========================  ==========  ==========================================
``DataError``              1           bad data in an input file (CSV, log, ...)
``ConfigError``            1           bad config or manifest (YAML)
``ConvergenceError``       1           the solver failed (reported, never hidden)
``OutputError``            1           the system refused an output (full disk, ...)
``UsageError``             2           bad command-line usage (options, paths)
========================  ==========  ==========================================
"""

from __future__ import annotations

from os import PathLike

__all__ = [
    "PhriError",
    "DataError",
    "ConfigError",
    "ConfigTypeError",
    "ConvergenceError",
    "OutputError",
    "UsageError",
    "ModelInputError",
]


class PhriError(Exception):
    """Base class of every error phri-spring reports to a user.

    Parameters
    ----------
    message : str
        What was wrong and what was expected.
    file : str or path-like, optional
        The file the problem is in.
    key : str, optional
        The config key path (``tissue.stiffness``) or the column (``Fx``).
    """

    exit_code = 1

    def __init__(self, message: str, *, file: str | PathLike | None = None,
                 key: str | None = None):
        self.message = str(message)
        self.file = None if file is None else str(file)
        self.key = key
        super().__init__(self.__str__())

    def __str__(self) -> str:
        parts = []
        if self.file:
            parts.append(self.file)
        if self.key:
            parts.append(self.key)
        parts.append(self.message)
        # one line, always
        return ": ".join(p.replace("\n", " ") for p in parts)


class DataError(PhriError, ValueError):
    """Bad data in an input file: missing column, text in a number, NaN, ..."""


class ConfigError(DataError):
    """A config file (or experiment manifest) is invalid."""


class ConfigTypeError(ConfigError, TypeError):
    """A config value has the wrong type (e.g. text where a number belongs)."""


class ConvergenceError(PhriError, RuntimeError):
    """The equilibrium solver did not converge for some samples."""


class OutputError(PhriError):
    """The system refused to write an output: full disk, file-size limit, read-only place,
    a file where a folder should be. ``file`` is the output the user asked for."""


class ModelInputError(ValueError):
    """A physics function refused its inputs (raised by ``phri_spring.physics``).

    ``quantity`` names what was wrong in the model's own terms, so that a caller
    holding a config can name the config key without reading the message:
    ``geometry`` (the cuff cannot be held), ``stiffness``, ``shear_ratio``,
    ``surface_stiffness``, ``normal_output``.
    """

    def __init__(self, message: str, quantity: str):
        self.quantity = quantity
        super().__init__(message)


class UsageError(PhriError, ValueError):
    """Bad usage of a command: an invalid option value, output equal to input, ..."""

    exit_code = 2
