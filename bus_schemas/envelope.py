"""The envelope every bus message travels in: ``{v, run, src, seq, round, t, body}``."""

from __future__ import annotations

from typing import Any, Generic, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["SCHEMA_VERSION", "Envelope", "RawEnvelope"]

SCHEMA_VERSION = 1

BodyT = TypeVar("BodyT", bound=BaseModel)


class _EnvelopeFields(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    v: Literal[1] = Field(description="schema version of the envelope and its body")
    run: str = Field(min_length=1, description="run id; every key of a run is under wncs/<run>/")
    src: str = Field(min_length=1, description="name of the publishing node")
    seq: int = Field(ge=0, strict=True, description="per-source sequence number")
    round: int = Field(ge=0, strict=True, description="clock round the message was published in")
    t: int = Field(ge=0, strict=True, description="virtual time of that round, in ticks")


class RawEnvelope(_EnvelopeFields):
    """An envelope whose body has not been validated yet (a plain mapping)."""

    body: dict[str, Any]


class Envelope(_EnvelopeFields, Generic[BodyT]):
    """An envelope with a validated body of type ``BodyT``."""

    body: BodyT
