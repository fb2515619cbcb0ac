"""The contract's one error: a bus message that does not decode or does not validate."""

from __future__ import annotations

__all__ = ["SchemaError"]


class SchemaError(ValueError):
    """A bus message does not decode or does not validate against its schema.

    ``problems`` says what is wrong, one ``"<dotted field>: <what>"`` per problem (a body that
    validated against no schema at all: the message alone), so that a node that answers a
    malformed request (the coordination agent) can name every field in its refusal.

    Defined here, with the schemas, because :mod:`bus_schemas` imports nothing of ours;
    :mod:`core.errors` re-exports it beside the rest of the hierarchy.
    """

    def __init__(self, message: str, problems: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.problems = problems or (message,)
