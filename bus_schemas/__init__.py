"""Bus contract: message bodies, the envelope, key-expression builders and the msgpack codec.

No zenoh import here: the schemas are plain pydantic models usable from any process or test.
"""

from bus_schemas.bodies import (
    Decision,
    DelayDistribution,
    Done,
    Estimate,
    InjectRequest,
    Loss,
    ModeRequest,
    MonitorAssessment,
    MonitorCandidate,
    MonitorHarris,
    Move,
    NetApplied,
    NetStats,
    NetworkEvent,
    PlantState,
    Proposal,
    Rates,
    Sample,
    SamplingPeriod,
    Setpoint,
    Stop,
    Tick,
    Timing,
)
from bus_schemas.envelope import SCHEMA_VERSION, Envelope

__all__ = [
    "SCHEMA_VERSION",
    "Envelope",
    "Decision",
    "DelayDistribution",
    "Done",
    "Estimate",
    "InjectRequest",
    "Loss",
    "ModeRequest",
    "Move",
    "NetApplied",
    "NetStats",
    "NetworkEvent",
    "PlantState",
    "Proposal",
    "Rates",
    "Sample",
    "SamplingPeriod",
    "Setpoint",
    "Stop",
    "Tick",
    "Timing",
    "MonitorAssessment",
    "MonitorCandidate",
    "MonitorHarris",
]
