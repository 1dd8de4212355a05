"""Editing a config mapping by dotted path (``cuff.stiffness.per_angle[5]``), for ``phri design``.

A design is the base config's YAML mapping with each varied value put at its
dotted path (keys separated by dots, list items by ``[i]``, split by
:func:`phri_spring.io.config.study.parse_path`). :func:`check_parameter` checks once,
before any design is built, that a path holds a number (a list of numbers for
``scale``), and :func:`set_parameter` puts one value there. Errors are
:class:`ConfigError` naming the study file and ``vary.<path>``.
"""

from __future__ import annotations

import copy
import difflib

from ..errors import ConfigError
from ..io.config.study import Parameter, parse_path

__all__ = ["walk_path", "check_parameter", "set_parameter"]


def walk_path(raw, parts, path_text, study_file, create: bool):
    """(container, last key) of a dotted path in a config mapping.

    ``create``: missing mappings and lists on the way are added (the last key
    itself may be missing: a key the config leaves at its default).
    """
    node = raw
    key = f"vary.{path_text}"
    done = []
    for j, part in enumerate(parts[:-1]):
        nxt = parts[j + 1]
        if isinstance(part, int):
            if not isinstance(node, list) or part >= len(node):
                have = f"a list of {len(node)} values" if isinstance(node, list) else \
                    f"{type(node).__name__}"
                raise ConfigError(f"index [{part}] after {'.'.join(map(str, done))} is out of "
                                  f"range ({have})", file=study_file, key=key)
            node = node[part]
        else:
            if not isinstance(node, dict):
                raise ConfigError(f"{'.'.join(map(str, done)) or 'the config'} is not a "
                                  f"mapping; expected a numeric config key", file=study_file,
                                  key=key)
            if part not in node:
                if not create:
                    close = difflib.get_close_matches(part, [str(k) for k in node], n=1,
                                                      cutoff=0.5)
                    hint = f"; did you mean {close[0]!r}?" if close else ""
                    raise ConfigError(f"the config has no key {part!r} here{hint}",
                                      file=study_file, key=key)
                node[part] = [] if isinstance(nxt, int) else {}
            node = node[part]
        done.append(part)
    return node, parts[-1]


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def check_parameter(raw_cfg: dict, p: Parameter, study_file) -> None:
    """A parameter's path must hold a number (a list of numbers for ``scale``)."""
    parts = parse_path(p.path, file=study_file)
    node, last = walk_path(copy.deepcopy(raw_cfg), parts, p.path, study_file, create=True)
    key = f"vary.{p.path}"
    if isinstance(last, int):
        if not isinstance(node, list) or last >= len(node):
            n = len(node) if isinstance(node, list) else 0
            raise ConfigError(f"index [{last}] is out of range (the config's list has {n} "
                              "values)", file=study_file, key=key)
        cur = node[last]
    else:
        if not isinstance(node, dict):
            raise ConfigError("the parent is not a mapping; expected a numeric config key",
                              file=study_file, key=key)
        cur = node.get(last)
    if cur is None:
        if p.kind == "scale":
            raise ConfigError(f"the config has no value at {p.path!r} to scale; expected a key "
                              "the config sets", file=study_file, key=key)
        return  # a key the config leaves at its default: the schema checks each value
    if p.kind == "scale":
        ok = _is_number(cur) or (isinstance(cur, list) and cur and
                                 all(_is_number(v) for v in cur))
        if not ok:
            raise ConfigError(f"expected a number or a list of numbers to scale, found "
                              f"{_describe(cur)}", file=study_file, key=key)
    elif not _is_number(cur):
        raise ConfigError(f"expected a numeric config key, found {_describe(cur)}"
                          + (" (scale a whole list with {scale: [...]}, or vary one item "
                             f"as {p.path}[i])" if isinstance(cur, list) else ""),
                          file=study_file, key=key)


def _describe(v) -> str:
    if isinstance(v, dict):
        return f"a mapping with keys {', '.join(map(str, v))}"
    if isinstance(v, list):
        return f"a list of {len(v)} items"
    return f"{type(v).__name__} {v!r}"


def set_parameter(raw_cfg: dict, p: Parameter, value: float, study_file) -> None:
    """Put one value at a parameter's path in ``raw_cfg`` (in place); a ``scale``
    multiplies the number, or every number of the list, found there."""
    parts = parse_path(p.path, file=study_file)
    node, last = walk_path(raw_cfg, parts, p.path, study_file, create=True)
    if p.kind == "scale":
        cur = node[last]
        node[last] = [float(v) * value for v in cur] if isinstance(cur, list) \
            else float(cur) * value
    else:
        node[last] = float(value)

