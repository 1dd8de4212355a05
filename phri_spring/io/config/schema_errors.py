"""One line from a pydantic validation error: the key path and what was expected.

Configs and study files are validated by pydantic models that refuse unknown keys; this
turns the first error into the :class:`~phri_spring.errors.ConfigError` a user reads,
with the closest valid key for a misspelt one.
"""

from __future__ import annotations

import difflib
from typing import Callable

from pydantic import ValidationError

from ...errors import ConfigError, ConfigTypeError

__all__ = ["config_error_from"]

#: pydantic's names of union branches, which are not keys of the file
_BRANCHES = ("float", "list[float]", "str", "list[str]", "list", "dict", "int")
_TYPE_ERRORS = ("float_parsing", "int_parsing", "float_type", "int_type", "bool_type",
                "string_type", "dict_type", "list_type", "tuple_type", "model_type")


def config_error_from(exc: ValidationError, path, valid_keys: Callable[[list], list]) -> ConfigError:
    """The ConfigError of a validation error of the file ``path``.

    ``valid_keys(loc)`` lists the keys valid in the mapping at key path ``loc`` (for
    "did you mean"). An unknown key is reported before a missing one, since a
    misspelt key explains the missing key next to it.
    """
    errors = exc.errors(include_url=False)
    err = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
    loc = [str(p) for p in err["loc"] if not str(p).startswith(("function-", "union"))]
    loc = [p for p in loc if p not in _BRANCHES]
    etype = err["type"]
    if etype == "extra_forbidden":
        bad = loc[-1]
        valid = list(valid_keys(loc[:-1]))
        close = difflib.get_close_matches(bad, valid, n=1, cutoff=0.5)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        parent = ".".join(loc[:-1]) or "the top level"
        return ConfigError(f"unknown key {bad!r} in {parent}{hint} (valid keys: "
                           f"{', '.join(valid)})", file=path, key=".".join(loc))
    if etype == "missing":
        return ConfigError("missing required key", file=path, key=".".join(loc))
    msg = err["msg"]
    if etype == "value_error":      # a validator's own message: pydantic's prefix adds nothing
        msg = msg.removeprefix("Value error, ")
    given = err.get("input")
    cls = ConfigTypeError if etype in _TYPE_ERRORS else ConfigError
    if isinstance(given, (int, float, str)) and not isinstance(given, bool):
        msg = f"{msg}, got {given!r}"
    return cls(msg, file=path, key=".".join(loc) or None)
