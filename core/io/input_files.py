"""Reading the text documents users hand to handeye (YAML, JSON) and their paths, without trusting them.

Every pose, board, intrinsics and time-stamp file that is YAML is read by `load_yaml`, every JSON
pose file by `load_json`; both raise one-line `handeye.base.errors.InputError`s naming the file (the
caller's `where`) and the line. Refused, beyond what the parsers refuse:

- **Alias bombs** (YAML). PyYAML shares an aliased node instead of copying it, so a 300-byte
  "billion laughs" (``a: &a [x, x, ...]``, ``b: &b [*a, *a, ...]``, nine levels) loads at once, but
  anything that then walks the result (flattening rows, converting to arrays) visits 9^9 nodes and
  runs for minutes. `load_yaml` counts, while composing, the nodes each alias adds when expanded,
  and refuses a document whose aliases add more than `MAX_ALIAS_NODES`, or an alias inside its own
  anchor (a structure that never ends). Aliases used sparingly (a shared matrix, ``<<: *defaults``)
  add tens or hundreds of nodes.
- **Duplicate keys** (YAML mappings, JSON objects). Both parsers keep the last value silently, so
  ``{x: 1, x: 2}`` would read as x = 2; which one the writer meant is unknowable.
- **Deep nesting** (both). A document nested deeper than `MAX_DEPTH` levels (``[[[[...]]]]``
  thousands deep) is no pose, board, intrinsics, cell or arm file; the parsers and whatever walks
  the result recurse once per level and end in RecursionError. Refused, while parsing or after.
- **YAML 1.1 numbers**. PyYAML resolves plain scalars by YAML 1.1, where ``1:30`` is the
  sexagesimal 90, ``1_000`` is 1000, ``017`` is octal 15 and ``0x1F`` hex, while ``1e5`` (no dot)
  is text. `load_yaml` resolves numbers by the YAML 1.2 core schema instead, decimal only:
  ``[-+]?[0-9]+`` is an int, ``1.5``, ``-.5``, ``1e5``, ``1.0e-3``, ``.inf``, ``.nan`` are floats;
  anything else stays a string (``"1:30"``), which a reader then refuses as not a number.

`check_not_looping` refuses a path that is a symbolic link loop (``ln -s a a``), on which
``Path.resolve`` raises RuntimeError and ``Path.is_file`` says False (so "not found" would mislead).
"""

from __future__ import annotations

import errno
import json
import math
import numbers
import re
from pathlib import Path
from typing import Any, ClassVar

import yaml

from handeye.base.errors import InputError, shown

#: most nodes the aliases of one YAML document may add when expanded (each use of ``*name`` adds
#: the expanded size of the anchored node). 10^5 is far above sparing use (a 4x4 matrix is 21
#: nodes) and cheap to walk (milliseconds); the nine-level billion laughs would add 4.3e8.
MAX_ALIAS_NODES = 100_000
#: deepest nesting of a YAML or JSON document handeye reads (a cell file of tables of 4x4 poses
#: is about 6 deep)
MAX_DEPTH = 64

_INT = "tag:yaml.org,2002:int"
_FLOAT = "tag:yaml.org,2002:float"
_MERGE = "tag:yaml.org,2002:merge"
#: YAML 1.2 core schema numbers, decimal only ([0-9] is ASCII only; no "_", ":", 0x, 0o)
_INT_RE = re.compile(r"^[-+]?[0-9]+$")
_FLOAT_RE = re.compile(r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
                       r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$")
_SPECIAL_FLOATS = {".inf": float("inf"), ".nan": float("nan")}


# ----------------------------------------------------------------------------- YAML


def load_yaml(text: str, where: str) -> Any:
    """The YAML document `text` as Python objects (as ``yaml.safe_load``, with the module
    docstring's rules). `where` names the file in messages, e.g. ``"'poses.yaml'"``.
    Raises InputError for invalid YAML, alias bombs, recursive aliases and duplicate keys."""
    loader = _Loader(text, where)
    try:
        return checked_depth(loader.get_single_data(), where)
    except RecursionError:
        raise _too_deep(where) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1} column {mark.column + 1}" if mark else ""
        reason = " ".join(str(getattr(exc, "problem", None) or exc).split())
        raise InputError(f"{where}: invalid YAML{at}: {reason}") from None
    finally:
        loader.dispose()


class _Loader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that counts alias expansion, refuses duplicate keys and resolves
    numbers by the YAML 1.2 core schema (decimal)."""

    # SafeLoader's implicit resolvers without its YAML 1.1 int and float; ours are added below
    yaml_implicit_resolvers: ClassVar[dict] = {
        first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT, _FLOAT)]
        for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}

    def __init__(self, text: str, where: str) -> None:
        super().__init__(text)
        self.where = where
        self._sizes: dict[int, int] = {}  # id(node) -> its size with every alias expanded
        self._alias_nodes = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        """Compose as PyYAML does, keeping each node's expanded size and the nodes aliases add."""
        mark = self.peek_event().start_mark if self.check_event(yaml.AliasEvent) else None
        node = super().compose_node(parent, index)
        if mark is None:
            self._sizes[id(node)] = 1 + sum(self._sizes[id(child)] for child in _children(node))
            return node
        size = self._sizes.get(id(node))
        if size is None:  # the anchored node is still being composed: the alias is inside it
            raise InputError(f"{self.where}: line {mark.line + 1}: an alias refers to the node that contains it, "
                             "a structure without end; write the values out")
        self._alias_nodes += size
        if self._alias_nodes > MAX_ALIAS_NODES:
            raise InputError(f"{self.where}: line {mark.line + 1}: aliases (*name) expand the document by more "
                             f"than {MAX_ALIAS_NODES:,} nodes (a YAML alias bomb?); write the values out or "
                             "use fewer aliases")
        return node

    def construct_mapping(self, node: Any, deep: bool = False) -> dict:
        """A mapping, refusing a key written twice (keys merged in by ``<<`` may be overridden)."""
        if isinstance(node, yaml.MappingNode):
            first_line: dict[Any, int] = {}
            for key_node, _ in node.value:
                if key_node.tag == _MERGE:
                    continue
                key = self.construct_object(key_node, deep=True)
                if not _hashable(key):  # SafeConstructor says so
                    continue
                if key in first_line:
                    raise InputError(f"{self.where}: line {key_node.start_mark.line + 1}: duplicate key "
                                     f"{shown(key)} (first at line {first_line[key]}); a key may appear once "
                                     "in a mapping: keep one")
                first_line[key] = key_node.start_mark.line + 1
        return super().construct_mapping(node, deep)


def _hashable(value: Any) -> bool:
    try:
        hash(value)
    except TypeError:
        return False
    return True


def _children(node: Any) -> list[Any]:
    """The nodes directly under `node` (keys and values of a mapping)."""
    if isinstance(node, yaml.SequenceNode):
        return node.value
    if isinstance(node, yaml.MappingNode):
        return [part for pair in node.value for part in pair]
    return []


def _construct_int(loader: _Loader, node: Any) -> int:
    value = loader.construct_scalar(node)
    if not _INT_RE.match(value):  # an explicit !!int tag on something else
        raise yaml.constructor.ConstructorError(None, None, f"{shown(value)} is not a decimal integer",
                                                node.start_mark)
    try:
        return int(value)
    except ValueError:  # more digits than Python converts (4300)
        raise yaml.constructor.ConstructorError(None, None, f"an integer of {len(value)} digits",
                                                node.start_mark) from None


def _construct_float(loader: _Loader, node: Any) -> float:
    value = loader.construct_scalar(node)
    if not _FLOAT_RE.match(value):  # an explicit !!float tag on something else
        raise yaml.constructor.ConstructorError(None, None, f"{shown(value)} is not a decimal number",
                                                node.start_mark)
    sign = -1.0 if value.startswith("-") else 1.0
    special = _SPECIAL_FLOATS.get(value.lstrip("+-").lower())
    return sign * special if special is not None else float(value)


# int before float: a plain 12 matches both patterns and is an int
_Loader.add_implicit_resolver(_INT, _INT_RE, list("-+0123456789"))
_Loader.add_implicit_resolver(_FLOAT, _FLOAT_RE, list("-+.0123456789"))
_Loader.add_constructor(_INT, _construct_int)
_Loader.add_constructor(_FLOAT, _construct_float)


# ----------------------------------------------------------------------------- JSON


#: a number written as text: ASCII digits only ([0-9], not \d), no digit separators (Python's
#: float() also takes "1_000" and full-width digits); nan / inf are read so that they are refused
#: as "not finite" rather than "not a number"
TEXT_NUMBER = re.compile(r"[+-]?(?:(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|inf|infinity|nan)",
                         re.IGNORECASE)


def number(value: Any) -> float | None:
    """`value` as a float, or None when it is not a number as a user's file may write one: a real
    number (not a bool), or text matching `TEXT_NUMBER` (surrounding spaces allowed)."""
    if isinstance(value, str):
        text = value.strip()
        return float(text) if TEXT_NUMBER.fullmatch(text) else None
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return None
    try:
        return float(value)
    except OverflowError:  # an integer of hundreds of digits
        return math.inf if value > 0 else -math.inf


def load_json(text: str, where: str) -> Any:
    """The JSON document `text` (as ``json.loads``), refusing duplicate keys in an object.
    Raises InputError for invalid JSON (line and column), a duplicate key (line of its object)
    and integers beyond Python's digit limit, and nesting deeper than `MAX_DEPTH`."""
    try:
        return checked_depth(json.loads(text, object_pairs_hook=_unique_keys), where)
    except RecursionError:
        raise _too_deep(where) from None
    except _DuplicateKey as dup:
        line = _object_line(text, dup.key)
        at = f" in the object at line {line}" if line else ""
        raise InputError(f"{where}: duplicate key {shown(dup.key)}{at}; a key may appear once in an object: "
                         "keep one") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{where}: invalid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}") from None
    except ValueError as exc:  # e.g. an integer of more than 4300 digits
        raise InputError(f"{where}: invalid JSON: {' '.join(str(exc).split())[:120]}") from None


def checked_depth(value: Any, where: str) -> Any:
    """`value` (parsed YAML or JSON), or InputError where its lists and mappings nest deeper than
    `MAX_DEPTH` (walked without recursion)."""
    stack = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        children = item.values() if isinstance(item, dict) else item if isinstance(item, list) else ()
        for child in children:
            if isinstance(child, (dict, list)):
                if depth + 1 > MAX_DEPTH:
                    raise _too_deep(where)
                stack.append((child, depth + 1))
    return value


def _too_deep(where: str) -> InputError:
    return InputError(f"{where}: nested more than {MAX_DEPTH} levels deep; no handeye file is (a pose is a row of "
                      "numbers or a 4x4 list of lists)")


class _DuplicateKey(Exception):
    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """The object of `pairs` (json's object_pairs_hook); _DuplicateKey at the first key seen twice."""
    obj = dict(pairs)
    if len(obj) != len(pairs):
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise _DuplicateKey(key)
            seen.add(key)
    return obj


def _object_line(text: str, key: str) -> int | None:
    """Line of the opening brace of the first object holding `key` twice: the text is read again
    by the pure-Python scanner, which tells where each object starts (only on this error path)."""
    found: list[int] = []

    def parse_object(s_and_end: tuple[str, int], *args: Any) -> Any:
        result, end = json.decoder.JSONObject(s_and_end, *args)
        if not found and [k for k, _ in result].count(key) > 1:
            found.append(s_and_end[0].count("\n", 0, s_and_end[1]) + 1)
        return result, end

    decoder = json.JSONDecoder(object_pairs_hook=list)  # pairs as read, duplicates kept
    decoder.parse_object = parse_object
    decoder.scan_once = json.scanner.py_make_scanner(decoder)
    try:
        decoder.decode(text)
    except (ValueError, RecursionError):
        return None
    return found[0] if found else None


# ----------------------------------------------------------------------------- paths


def check_not_looping(path: str | Path, what: str = "") -> None:
    """InputError when `path` is a symbolic link loop (``ln -s a a``, or a -> b -> a).
    `what` precedes the quoted path in the message (e.g. ``"pose file"``)."""
    try:
        Path(path).stat()
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            name = f"{what} {str(path)!r}".strip()
            raise InputError(f"{name} is a symbolic link that loops (following it leads back to itself); "
                             "point it at a file") from None
