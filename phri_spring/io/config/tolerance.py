"""The optional ``tolerance`` section of a config (docs/tolerance.md).

``tolerance: {curve: NAME}`` names a pressure-time curve of
:data:`phri_spring.physics.response.tolerance.TOLERANCE_CURVES`; with it, ``phri simulate``
adds the dose columns. Without the section nothing changes.
"""

from __future__ import annotations

import difflib
from typing import TYPE_CHECKING, Optional

if TYPE_CHECKING:  # annotations only
    from ...physics.response.tolerance import ToleranceCurve

from ...errors import ConfigError, ModelInputError, UsageError

__all__ = ["TOLERANCE_KEYS", "parse_tolerance", "curve_option"]

#: the keys of the tolerance section
TOLERANCE_KEYS = ("curve",)


def _unknown_curve(name) -> str:
    # the curves are read only when a run asks for one (start-up of every other run)
    from ...physics.response.tolerance import TOLERANCE_CURVES, tolerance_curve  # noqa: F401

    close = difflib.get_close_matches(str(name), TOLERANCE_CURVES, n=1, cutoff=0.5)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return (f"unknown tolerance curve {name!r}{hint} (expected one of "
            f"{', '.join(TOLERANCE_CURVES)})")


def parse_tolerance(value, path=None) -> "Optional[ToleranceCurve]":
    """The curve the config's ``tolerance`` section names, or None without the section.

    Raises
    ------
    ConfigError
        A section that is not a mapping, an unknown key, a missing or unknown curve.
    """
    if value is None:
        return None
    # the curves are read only when a run asks for one (start-up of every other run)
    from ...physics.response.tolerance import TOLERANCE_CURVES, tolerance_curve  # noqa: F401

    if not isinstance(value, dict):
        raise ConfigError(f"expected a mapping such as {{curve: linder_ganz_2006}}, got "
                          f"{type(value).__name__}", file=path, key="tolerance")
    for key in value:
        if key not in TOLERANCE_KEYS:
            close = difflib.get_close_matches(str(key), TOLERANCE_KEYS, n=1, cutoff=0.5)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ConfigError(f"unknown key{hint} (expected {', '.join(TOLERANCE_KEYS)})",
                              file=path, key=f"tolerance.{key}")
    if "curve" not in value:
        raise ConfigError(f"missing required key (one of {', '.join(TOLERANCE_CURVES)})",
                          file=path, key="tolerance.curve")
    name = value["curve"]
    if not isinstance(name, str):
        raise ConfigError(f"expected a curve name, got {name!r}", file=path,
                          key="tolerance.curve")
    try:
        return tolerance_curve(name)
    except ModelInputError:
        raise ConfigError(_unknown_curve(name), file=path, key="tolerance.curve") from None


def curve_option(name, cfg=None, option: str = "--tolerance") -> "Optional[ToleranceCurve]":
    """The curve of a command's ``--tolerance NAME`` option, else the config's
    (``cfg.tolerance``), else None.

    Raises
    ------
    UsageError
        An unknown name.
    """
    if name is None:
        return getattr(cfg, "tolerance", None)
    # the curves are read only when a run asks for one (start-up of every other run)
    from ...physics.response.tolerance import TOLERANCE_CURVES, tolerance_curve  # noqa: F401

    try:
        return tolerance_curve(name)
    except ModelInputError:
        raise UsageError(_unknown_curve(name), key=option) from None
