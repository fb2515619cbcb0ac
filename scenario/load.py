"""Reading a scenario: a file, or a parsed mapping, validated into a
:class:`~scenario.model.Scenario`.

Every problem becomes a :class:`~core.errors.ConfigError` naming the file and the dotted field
(``scenarios/x.yaml: line 14: loops.level.tau_s: Input should be greater than 0``; the line where
the file has the field, :mod:`scenario.yaml_positions`; ``--set`` overrides,
:mod:`scenario.overrides`, are applied before validation), before anything starts.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from core.errors import ConfigError
from scenario.model import Scenario
from scenario.overrides import Override, apply_overrides, parse_override
from scenario.yaml_positions import field_line, message_path, read_yaml

__all__ = ["parse_scenario", "load_scenario"]


def _format_error(source: str, err: ValidationError, text: str | None = None) -> str:
    """One line per error: ``source: field: message``; ``source: line N: field: ...`` with text."""
    lines = []
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"])
        msg = e["msg"].removeprefix("Value error, ")
        line = None if text is None else field_line(text, message_path(e["loc"], msg))
        where = source if line is None else f"{source}: line {line}"
        lines.append(f"{where}: {loc + ': ' if loc else ''}{msg}")
    return "\n".join(lines)


_INFINITE_OK = frozenset({"u_min", "u_max"})
"""Fields where an infinite value means "no limit" (actuator limits; and the bounds of a plant
node's ``input_range``)."""


def _infinite_ok(path: tuple[Any, ...]) -> bool:
    return bool(path) and (
        path[-1] in _INFINITE_OK or (len(path) >= 3 and path[-3] == "input_range")
    )


def _non_finite(data: Any, path: tuple[Any, ...] = ()) -> Iterator[tuple[tuple[Any, ...], float]]:
    """Every NaN, and every infinity outside :data:`_INFINITE_OK`, in a scenario's mapping."""
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _non_finite(value, (*path, key))
    elif isinstance(data, list | tuple):
        for i, value in enumerate(data):
            yield from _non_finite(value, (*path, i))
    elif isinstance(data, float) and not math.isfinite(data):
        if math.isnan(data) or not _infinite_ok(path):
            yield path, data


def parse_scenario(
    data: Any,
    *,
    source: str = "<scenario>",
    text: str | None = None,
    base_dir: str | Path | None = None,
) -> Scenario:
    """Validate an already-parsed mapping; errors name ``source`` and the field.

    With ``text`` (the YAML ``data`` was read from), each error also names the field's line.
    Relative file names in the scenario (a TSCH link trace) are taken from ``base_dir`` (the
    scenario file's folder) and kept absolute.
    """
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: a scenario must be a mapping, got {type(data).__name__}")
    for path, value in _non_finite(data):
        line = None if text is None else field_line(text, path)
        where = source if line is None else f"{source}: line {line}"
        raise ConfigError(f"{where}: {'.'.join(map(str, path))}: {value} is not a finite number")
    context = {"base_dir": str(base_dir)} if base_dir is not None else None
    try:
        return Scenario.model_validate(data, context=context)
    except ValidationError as err:
        raise ConfigError(_format_error(source, err, text)) from err


def load_scenario(path: str | Path, *, overrides: Sequence[str | Override] = ()) -> Scenario:
    """Read and validate a scenario file, after applying ``--set`` style ``overrides``.

    The overrides (``"loops.level.tau_s=0.2"``, see :mod:`scenario.overrides`) change the mapping
    read from the file before validation, so a bad value is refused as it would be in the file.

    Raises
    ------
    ConfigError
        If the file cannot be read, is not YAML (the message names line and column), an override
        names a path the file does not have, or the scenario does not validate; the message names
        the file, the dotted field and, where the file has it, the field's line
        (``scenarios/x.yaml: line 14: loops.level.tau_s: Input should be greater than 0``).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise ConfigError(f"{path}: cannot read scenario: {err.strerror or err}") from err
    except UnicodeDecodeError as err:
        raise ConfigError(
            f"{path}: not a text scenario: byte {err.object[err.start]:#04x} at offset "
            f"{err.start} is not UTF-8"
        ) from err
    if "\x00" in text:
        raise ConfigError(f"{path}: not a text scenario: NUL byte at offset {text.index(chr(0))}")
    data = read_yaml(text, source=str(path))
    parsed = [o if isinstance(o, Override) else parse_override(o) for o in overrides]
    data = apply_overrides(data, parsed)
    return parse_scenario(data, source=str(path), text=text, base_dir=path.parent)
