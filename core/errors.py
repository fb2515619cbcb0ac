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
