"""Safe, bounded YAML loading for configs, manifests and study files (docs/model.md section 6).

:func:`load_yaml` never runs code (``yaml.SafeLoader``: a ``!!python/...`` tag is
an error), rejects duplicate keys, and refuses documents too large, too deeply
nested, with too many values once aliases are expanded, or with integers too
long (:data:`MAX_YAML_BYTES`, :data:`MAX_YAML_DEPTH`, :data:`MAX_YAML_VALUES`,
:data:`MAX_INT_DIGITS`). Errors are :class:`~phri_spring.errors.ConfigError`
naming the file. Split out of :mod:`phri_spring.io.config`, which validates the
loaded mapping and re-exports these names.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import yaml

from ...errors import ConfigError, DataError

__all__ = ["load_yaml", "MAX_YAML_BYTES", "MAX_YAML_DEPTH", "MAX_YAML_VALUES", "MAX_INT_DIGITS"]

#: a config or manifest larger than this is refused before parsing [bytes]
MAX_YAML_BYTES = 1 << 20
#: deepest nesting of lists and mappings (a config needs 4 levels)
MAX_YAML_DEPTH = 64
#: most values a document may hold once every alias is expanded
MAX_YAML_VALUES = 100_000
#: most digits of an integer (an int64 has 19)
MAX_INT_DIGITS = 18


class _YamlLimit(yaml.YAMLError):
    """A document beyond the loader's bounds; ``key`` is where (a key path)."""

    def __init__(self, message: str, key: str | None = None):
        super().__init__(message)
        self.message = message
        self.key = key


class _StrictSafeLoader(yaml.SafeLoader):
    """SafeLoader that also rejects duplicate keys and bounds nesting depth.

    Aliases are composed as shared nodes (no copy), so a document with
    aliases of aliases is small in memory; :func:`_check_document` then bounds
    the size it would have once expanded, before anything walks it.
    """

    _depth = 0

    def compose_node(self, parent, index):
        # the composer recurses once per level: bound it before Python's recursion limit
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                mark = self.peek_event().start_mark
                raise _YamlLimit(f"line {mark.line + 1}: lists and mappings nested deeper than "
                                 f"{MAX_YAML_DEPTH} levels; expected a config-like document")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


def _construct_mapping(loader, node, deep=False):
    merge = "tag:yaml.org,2002:merge"
    seen = {}
    for key_node, _ in node.value:
        if key_node.tag == merge:  # '<<: *anchor' merges are expanded by SafeLoader
            continue
        key = loader.construct_object(key_node, deep=deep)
        try:
            hash(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(
                None, None, "a list or mapping used as a key; expected text keys",
                key_node.start_mark) from None
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r} (first at line {seen[key] + 1})",
                key_node.start_mark)
        seen[key] = key_node.start_mark.line
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


_StrictSafeLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG,
                                  _construct_mapping)
# YAML 1.1 reads ``1.0e6`` and ``1e6`` as text; labs write them as numbers (YAML 1.2 does too).
_StrictSafeLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"))


def _key_text(node) -> str:
    if isinstance(node, yaml.ScalarNode):
        text = str(node.value)
        return text if len(text) <= 40 else text[:37] + "..."
    return "?"


def _check_scalar(loader, node, where: str) -> None:
    """Refuse numbers the config cannot hold: huge integers, floats that overflow to inf."""
    if node.tag == "tag:yaml.org,2002:int":
        digits = re.sub(r"[^0-9a-fA-F]", "", str(node.value).lstrip("+-").replace("0x", "", 1))
        if len(digits) > MAX_INT_DIGITS:
            raise _YamlLimit(f"line {node.start_mark.line + 1}: an integer of {len(digits)} "
                             f"digits; expected at most {MAX_INT_DIGITS} digits", where or None)
    elif node.tag == "tag:yaml.org,2002:float":
        text = str(node.value).replace("_", "").lower()
        if ".inf" in text or ".nan" in text:
            return
        try:
            value = loader.construct_yaml_float(node)
        except (ValueError, OverflowError):
            value = math.inf
        if not math.isfinite(value):
            raise _YamlLimit(f"line {node.start_mark.line + 1}: number {str(node.value)[:40]!r} "
                             "is too large for a double (beyond 1.8e308); expected a finite "
                             "number (write .inf for an infinite stiffness)", where or None)


def _check_document(loader, root) -> None:
    """Bound the expanded size of a composed document and its numbers; name the key.

    Shared (aliased) nodes are sized once and their size reused, so this takes
    time in proportion to the document as written, however far its aliases
    would expand; a node that contains itself is refused.
    """
    sizes: dict = {}

    def walk(node, where: str) -> int:
        nid = id(node)
        if nid in sizes:
            if sizes[nid] is None:
                raise _YamlLimit("an alias refers to a list or mapping that contains it "
                                 "(a recursive structure); expected plain values", where or None)
            return sizes[nid]
        sizes[nid] = None
        total = 1
        if isinstance(node, yaml.ScalarNode):
            _check_scalar(loader, node, where)
        elif isinstance(node, yaml.SequenceNode):
            for i, child in enumerate(node.value):
                total += walk(child, f"{where}[{i}]")
                if total > MAX_YAML_VALUES:
                    break
        elif isinstance(node, yaml.MappingNode):
            for knode, vnode in node.value:
                key = _key_text(knode)
                total += walk(knode, where) + walk(vnode, f"{where}.{key}" if where else key)
                if total > MAX_YAML_VALUES:
                    break
        if total > MAX_YAML_VALUES:
            aliases = 2 * len(sizes) < total
            what = "aliases expand to" if aliases else "holds"
            raise _YamlLimit(f"{what} more than {MAX_YAML_VALUES:,} values; expected a "
                             "config-sized document (anchors and aliases that share values "
                             "are fine, aliases of lists of aliases are not)", where or None)
        sizes[nid] = total
        return total

    walk(root, "")


_QUOTED_OR_COMMENT = re.compile(r'"(?:[^"\\\n]|\\.)*"|\'(?:[^\'\n]|\'\')*\'|(?:^|(?<=\s))#[^\n]*',
                                re.M)
_NOT_BRACKET = re.compile(r"[^\[\]{}]+")


def _flow_depth(text: str) -> int:
    """Deepest nesting of flow lists and mappings (``[`` ``{``), quoted text and comments aside.

    PyYAML's scanner looks ahead over every open bracket on a line, which costs
    time in the square of the nesting: the depth is bounded before parsing.
    """
    if "[" not in text and "{" not in text:
        return 0
    brackets = _NOT_BRACKET.sub("", _QUOTED_OR_COMMENT.sub("", text))
    if not brackets:
        return 0
    import numpy as np

    codes = np.frombuffer(brackets.encode("ascii"), dtype=np.uint8)
    step = np.where((codes == ord("[")) | (codes == ord("{")), 1, -1)
    return int(np.cumsum(step).max())


def _parse_yaml(text: str) -> Any:
    depth = _flow_depth(text)
    if depth > MAX_YAML_DEPTH:
        raise _YamlLimit(f"lists and mappings nested deeper than {MAX_YAML_DEPTH} levels "
                         f"({depth} brackets deep); expected a config-like document")
    loader = _StrictSafeLoader(text)
    try:
        root = loader.get_single_node()
        if root is None:
            return None
        _check_document(loader, root)
        return loader.construct_document(root)
    finally:
        loader.dispose()


def load_yaml(path) -> Any:
    """Parse a YAML file safely; errors become one-line :class:`ConfigError`.

    The text may be UTF-8 (with or without a byte-order mark), UTF-16/32 with a
    byte-order mark, or Latin-1 (:mod:`phri_spring.io.logs.textio`). The document is
    bounded: at most :data:`MAX_YAML_BYTES`, :data:`MAX_YAML_DEPTH` levels,
    :data:`MAX_YAML_VALUES` values with aliases expanded, integers of at most
    :data:`MAX_INT_DIGITS` digits and floats that fit a double, so that a
    hostile file is refused in well under a second, naming the key.
    """
    from ..logs.textio import read_text

    path = Path(path)
    try:
        text = read_text(path, what="a YAML file", max_bytes=MAX_YAML_BYTES)
    except DataError as exc:
        raise ConfigError(exc.message, file=path) from None
    try:
        return _parse_yaml(text)
    except _YamlLimit as exc:
        raise ConfigError(f"invalid YAML: {exc.message}", file=path, key=exc.key) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc)
        if "python/" in str(exc) or "could not determine a constructor" in str(exc):
            problem = (f"{problem}; tags like !!python/... are not allowed "
                       "(configs are loaded safely and never run code)")
        raise ConfigError(f"{where}invalid YAML: {problem}".replace("\n", " "), file=path) from None
    except (ValueError, TypeError, OverflowError, RecursionError) as exc:
        # a value PyYAML's constructors cannot build (e.g. a bad !!timestamp or !!binary)
        raise ConfigError(f"invalid YAML: {type(exc).__name__}: {exc}".replace("\n", " "),
                          file=path) from None
