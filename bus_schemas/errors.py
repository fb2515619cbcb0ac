"""The contract's one error: a bus message that does not decode or does not validate."""

from __future__ import annotations

__all__ = ["SchemaError"]


class SchemaError(ValueError):
    """A bus message does not decode or does not validate against its schema.

    Defined here, with the schemas, because :mod:`bus_schemas` imports nothing of ours;
    :mod:`core.errors` re-exports it beside the rest of the hierarchy.
    """
