"""Exception hierarchy of the platform.

Each subclass also inherits the builtin it refines, so callers may catch either
(`ConfigError` is a `ValueError`, `NodeTimeout` a `TimeoutError`). `SchemaError` is the bus
contract's own (:mod:`bus_schemas.errors`, a `ValueError`), re-exported here.
"""

from __future__ import annotations

from bus_schemas.errors import SchemaError

__all__ = [
    "WncsError",
    "ConfigError",
    "SchemaError",
    "ProtocolError",
    "NodeTimeout",
    "NodeFault",
    "exit_code",
]


class WncsError(Exception):
    """Base class of every error raised on purpose by this package."""


class ConfigError(WncsError, ValueError):
    """A scenario or configuration file is invalid; the message names the file and field."""


class ProtocolError(WncsError, RuntimeError):
    """A participant broke the round protocol of the virtual-time clock."""


class NodeTimeout(WncsError, TimeoutError):
    """A participant or an expected message did not arrive within its wall-clock timeout."""


class NodeFault(WncsError, RuntimeError):
    """A run was stopped because a node failed; the message names the node and the round."""


def exit_code(err: BaseException) -> int:
    """The exit code of a command that ends with ``err``: 2 for bad input (:class:`ConfigError`),
    130 for an interrupt (the shell's 128 + SIGINT), 1 for anything else."""
    if isinstance(err, ConfigError):
        return 2
    if isinstance(err, KeyboardInterrupt):
        return 130
    return 1
