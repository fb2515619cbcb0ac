"""Bus contract: message bodies, the envelope, key-expression builders and the msgpack codec.

No zenoh import here: the schemas are plain pydantic models usable from any process or test.
"""

from bus_schemas.bodies import (
    Done,
    InjectRequest,
    Loss,
    Move,
    NetApplied,
    NetStats,
    NetworkEvent,
    PlantState,
    Proposal,
    Sample,
    Setpoint,
    Stop,
    Tick,
)
from bus_schemas.envelope import SCHEMA_VERSION, Envelope

__all__ = [
    "SCHEMA_VERSION",
    "Envelope",
    "Done",
    "InjectRequest",
    "Loss",
    "Move",
    "NetApplied",
    "NetStats",
    "NetworkEvent",
    "PlantState",
    "Proposal",
    "Sample",
    "Setpoint",
    "Stop",
    "Tick",
]
