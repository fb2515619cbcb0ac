"""Positions in a YAML text: syntax errors with line and column, and the line of a dotted field.

Lines and columns are 1-based, as editors show them (PyYAML's marks are 0-based). A field's line
comes from the node tree (``yaml.compose``), walked along a pydantic error location: mapping keys
by name, sequence items by index. A segment that names nothing in the mapping it should be in (a
discriminated union's tag such as ``gateway`` in ``nodes.network.gateway.topology``, or a field
the file leaves out) is skipped, so the line is that of the deepest part of the path the file
has.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

import yaml

from core.errors import ConfigError

__all__ = ["read_yaml", "field_line", "message_path"]

_PATH = re.compile(r"^([A-Za-z_][\w-]*(?:\[\d+\])*(?:\.[A-Za-z_][\w-]*(?:\[\d+\])*)*): ")
_SEGMENT = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def read_yaml(text: str, *, source: str) -> Any:
    """``yaml.safe_load`` of ``text``; a syntax error names ``source``, line and column.

    Raises
    ------
    ConfigError
        ``source: line L, column C: not valid YAML: <problem>`` (and PyYAML's context, if any),
        or nesting too deep to read.
    """
    try:
        return yaml.safe_load(text)
    except RecursionError as err:  # 100 000 nested brackets: the parser's recursion runs out
        raise ConfigError(f"{source}: not a scenario: nested too deeply to read") from err
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        where = source
        if mark is not None:
            where += f": line {mark.line + 1}, column {mark.column + 1}"
        what = err.problem or err.context or "syntax error"
        if err.context and err.problem and err.context_mark is not None:
            cm = err.context_mark
            what += f" ({err.context} at line {cm.line + 1}, column {cm.column + 1})"
        raise ConfigError(f"{where}: not valid YAML: {what}") from err
    except yaml.YAMLError as err:
        raise ConfigError(f"{source}: not valid YAML: {err}") from err


def message_path(loc: Sequence[int | str], msg: str) -> tuple[int | str, ...]:
    """The full location of an error: ``loc`` plus the dotted path its message starts with.

    Our cross-field validators name the field in the message (``loops.level.sensor_node: ...``,
    ``events[1].event: ...``); this turns that prefix into segments (``events``, ``1``, ...).
    """
    found = _PATH.match(msg)
    if found is None:
        return tuple(loc)
    extra: list[int | str] = [
        int(index) if index else name for name, index in _SEGMENT.findall(found.group(1))
    ]
    return (*loc, *extra)


def _key(node: yaml.MappingNode, segment: int | str) -> tuple[yaml.Node, yaml.Node] | None:
    for key, value in node.value:
        if isinstance(key, yaml.ScalarNode) and key.value == str(segment):
            return key, value
    return None


def field_line(text: str, path: Sequence[int | str]) -> int | None:
    """The 1-based line of the deepest node of ``path`` that ``text`` has, or None.

    None when the text does not compose (not YAML) or not even the first segment is in it.
    """
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError:
        return None
    line: int | None = None
    for segment in path:
        if isinstance(node, yaml.MappingNode):
            pair = _key(node, segment)
            if pair is None:
                continue  # a union's tag or a missing field: try the next segment here
            line = pair[0].start_mark.line + 1
            node = pair[1]
        elif isinstance(node, yaml.SequenceNode) and isinstance(segment, int):
            if not 0 <= segment < len(node.value):
                break
            node = node.value[segment]
            line = node.start_mark.line + 1
        else:
            break
    return line
