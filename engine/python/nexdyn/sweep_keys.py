"""The keys and values of a sweep (nexdyn.sweep, `nexdyn sweep --set KEY=V1,V2,...`): splitting
and parsing the command line's value lists, setting a dotted key in a scene, and the lists of
values a sweep's params give, as plain JSON data. docs/python.md, "Keys and values"."""

from __future__ import annotations

import copy
import json
import math
from typing import Any, List, Mapping, Tuple

from . import SceneError

__all__ = ["split_values", "parse_value", "parse_set", "set_key", "value_lists"]

# ----------------------------------------------------------------------------------------------
# KEY=V1,V2,... and dotted keys


def split_values(text: str) -> List[str]:
    """The values of `V1,V2,...`: split on the commas outside brackets ([ ], { }) and outside
    double-quoted strings, so `[0,-1,0],[0,-2,0]` is two values. Raises ValueError for an empty
    value or unbalanced brackets or quotes."""
    items: List[str] = []
    depth = 0
    start = 0
    in_string = escaped = False
    for i, c in enumerate(text):
        if in_string:
            if escaped:
                escaped = False
            elif c == "\\":
                escaped = True
            elif c == '"':
                in_string = False
        elif c == '"':
            in_string = True
        elif c in "[{":
            depth += 1
        elif c in "]}":
            depth -= 1
            if depth < 0:
                raise ValueError(f"unbalanced '{c}' at character {i + 1} of {text!r}")
        elif c == "," and depth == 0:
            items.append(text[start:i])
            start = i + 1
    if in_string:
        raise ValueError(f"unterminated string in {text!r}")
    if depth != 0:
        raise ValueError(f"unclosed bracket in {text!r}")
    items.append(text[start:])
    items = [item.strip() for item in items]
    for n, item in enumerate(items):
        if not item:
            raise ValueError(f"value {n + 1} of {text!r} is empty")
    return items


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def parse_value(text: str) -> Any:
    """One value: JSON when it parses (numbers, true/false/null, [lists], {objects},
    "strings"); anything else is the string itself (`stvk`). A value that starts with [, { or
    a double quote must be valid JSON (ValueError otherwise)."""
    try:
        return json.loads(text, parse_constant=_no_constant)
    except ValueError as e:
        if text[:1] in '[{"':
            raise ValueError(f"{text!r} is not valid JSON ({e})") from None
        return text


def parse_set(argument: str) -> Tuple[str, List[Any]]:
    """`KEY=V1,V2,...` (the CLI's --set) as (KEY, [values]). Raises ValueError."""
    key, equals, text = argument.partition("=")
    key = key.strip()
    if not equals or not key:
        raise ValueError(f"--set {argument!r}: expected KEY=V1,V2,... (for example contact.friction=0.1,0.3)")
    try:
        return key, [parse_value(item) for item in split_values(text)]
    except ValueError as e:
        raise ValueError(f"--set {key}: {e}") from None


def _describe(node: Any) -> str:
    if isinstance(node, dict):
        return "an object"
    if isinstance(node, list):
        return f"a list of {len(node)}"
    return f"the value {json.dumps(node)}"


def set_key(scene: Any, key: str, value: Any, where: str = "the scene") -> None:
    """Sets the dotted key `key` of the scene dict `scene` to `value`, in place. A component
    indexes a list when the node is a list (0, 1, ...); every component but the last must exist;
    the last may be a new key of an object (the engine's strict reader judges it). Raises
    SceneError naming the key; `where` names the scene in the message."""
    parts = key.split(".")
    if any(not part for part in parts):
        raise SceneError(f"sweep key {key!r}: an empty component (keys look like contact.friction or bodies.0.velocity)")
    node = scene
    for i, part in enumerate(parts):
        path = ".".join(parts[:i + 1])
        parent = ".".join(parts[:i]) or "the top level"
        last = i == len(parts) - 1
        if isinstance(node, list):
            if not (part.isascii() and part.isdigit()):
                raise SceneError(f"sweep key {key!r}: {parent} of {where} is {_describe(node)}; "
                                 f"{part!r} is not an index (0 to {len(node) - 1})")
            index = int(part)
            if index >= len(node):
                raise SceneError(f"sweep key {key!r}: {parent} of {where} is {_describe(node)}; "
                                 f"there is no item {index}")
            if last:
                node[index] = copy.deepcopy(value)
            else:
                node = node[index]
        elif isinstance(node, dict):
            if last:
                node[part] = copy.deepcopy(value)
            elif part not in node:
                known = ", ".join(node) or "none"
                raise SceneError(f"sweep key {key!r}: {where} has no {path} (the keys of {parent}: {known})")
            else:
                node = node[part]
        else:
            raise SceneError(f"sweep key {key!r}: {parent} of {where} is {_describe(node)}, "
                             f"not an object or a list")


# ----------------------------------------------------------------------------------------------
# The values of a sweep's params


def _plain(value: Any, key: str) -> Any:
    """`value` as plain JSON data (tuples as lists, NumPy scalars and arrays as numbers and
    lists). Raises ValueError for what JSON cannot hold."""
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        value = value.tolist()  # NumPy arrays and scalars
    if isinstance(value, (list, tuple)):
        return [_plain(v, key) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v, key) for k, v in value.items()}
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"sweep key {key!r}: {value} is not a finite number")
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise ValueError(f"sweep key {key!r}: a value of type {type(value).__name__} cannot be written as JSON")


def value_lists(params: Mapping[str, Any]) -> List[Tuple[str, List[Any]]]:
    if not isinstance(params, Mapping) or not params:
        raise ValueError("sweep: params must be a non-empty mapping of dotted keys to lists of values, "
                         "for example {\"contact.friction\": [0.1, 0.3]}")
    lists = []
    for key, values in params.items():
        if not isinstance(key, str):
            raise ValueError(f"sweep: the key {key!r} is not a string")
        if hasattr(values, "tolist") and not isinstance(values, (str, bytes)):
            values = values.tolist()
        if isinstance(values, tuple):
            values = list(values)
        if not isinstance(values, list):
            values = [values]  # one value
        if not values:
            raise ValueError(f"sweep key {key!r}: no values")
        lists.append((key, [_plain(v, key) for v in values]))
    return lists
