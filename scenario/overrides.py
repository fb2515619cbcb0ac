"""Overrides of a scenario's fields from the command line: ``--set dotted.path=value``.

An override is applied to the raw mapping read from the file, *before* validation, so a bad
value is refused exactly as the same value written in the file would be. The value is parsed as
YAML (``0.2`` a float, ``[1, 2]`` a list, ``true`` a bool, ``null`` None); list indices are
integers in the path (``setpoints.0.value=0.8``). Every segment but the last must exist: a
missing key, an index out of range or a step into a scalar is refused naming the argument. The
last segment may be new (a mapping gains the key; the model then refuses a field it does not
know, as it would in the file).
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from core.errors import ConfigError
from scenario.yaml_positions import read_yaml

__all__ = ["Override", "parse_override", "apply_overrides"]


@dataclass(frozen=True)
class Override:
    """One ``--set PATH=VALUE``: the argument as given, its path segments and parsed value."""

    text: str
    path: tuple[str, ...]
    value: Any


def parse_override(text: str) -> Override:
    """Parse ``dotted.path=value``; the value is YAML.

    Raises
    ------
    ConfigError
        If there is no ``=``, the path is empty or has an empty segment, or the value is not YAML.
    """
    where = f"--set {text}"
    name, sep, raw = text.partition("=")
    if not sep:
        raise ConfigError(f"{where}: expected PATH=VALUE, e.g. loops.level.tau_s=0.2")
    path = tuple(name.strip().split("."))
    if not all(path):
        raise ConfigError(f"{where}: {name.strip()!r} is not a dotted path (empty segment)")
    return Override(text, path, read_yaml(raw, source=f"{where}: the value"))


def _child(node: Any, segment: str, done: tuple[str, ...], where: str) -> tuple[Any, Any]:
    """The key or index of ``segment`` in ``node``, checked; ``done`` is the path up to it."""
    at = ".".join(done) or "the scenario"
    if isinstance(node, dict):
        if segment in node:
            return segment, node[segment]
        if segment.lstrip("-").isdigit() and int(segment) in node:
            return int(segment), node[int(segment)]
        known = ", ".join(str(k) for k in node) or "none"
        raise ConfigError(
            f"{where}: {at} has no key {segment!r} (keys: {known}; to add one, set it whole: "
            f"--set {'.'.join((*done, segment))}={{...}})"
        )
    if isinstance(node, list):
        if not segment.isdigit():
            raise ConfigError(f"{where}: {at} is a list, {segment!r} is not an index")
        index = int(segment)
        if index >= len(node):
            raise ConfigError(f"{where}: {at} has {len(node)} items, no index {index}")
        return index, node[index]
    raise ConfigError(f"{where}: {at} is {node!r}, not a mapping or list: cannot set {segment!r}")


def _apply(data: Any, override: Override) -> None:
    where = f"--set {override.text}"
    node = data
    *parents, last = override.path
    for i, segment in enumerate(parents):
        _, node = _child(node, segment, override.path[:i], where)
    if isinstance(node, dict):
        key: Any = last
        if last not in node and last.lstrip("-").isdigit() and int(last) in node:
            key = int(last)
        node[key] = override.value
        return
    index, _ = _child(node, last, tuple(parents), where)
    node[index] = override.value


def apply_overrides(data: Any, overrides: Sequence[Override]) -> Any:
    """A copy of the raw scenario ``data`` with ``overrides`` applied in order.

    Raises
    ------
    ConfigError
        Naming the ``--set`` argument, if a segment before the last does not exist.
    """
    if not overrides:
        return data
    data = copy.deepcopy(data)
    for override in overrides:
        _apply(data, override)
    return data
