"""A TSCH gateway's configuration (``mac: tsch`` in a scenario's ``kind: gateway`` node).

Every field has a default an engineer would recognise: 10 ms slots (IEEE 802.15.4 TSCH and
WirelessHART), the 16 channels of the 2.4 GHz band hopped in order, a queue of 10 packets per
node, 3 retransmissions per hop (``macMaxFrameRetries``), CSMA-CA backoff exponents 1..7
(``macMinBe``/``macMaxBe`` of 802.15.4-2015 for TSCH), one retry cell per hop of a chain, link
quality from the topology's per-link PRR on every channel, and the OpenMote-CC2538 charges.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from gateway.tsch.energy import RADIOS
from gateway.tsch.link_quality import PathLossConfig
from gateway.tsch.schedule import Cell

__all__ = ["CellSpec", "TraceSpec", "TschConfig", "BAND"]

BAND = tuple(range(11, 27))
"""IEEE 802.15.4 2.4 GHz O-QPSK channels."""

_STRICT = ConfigDict(frozen=True, extra="forbid")


class CellSpec(BaseModel):
    """A cell written in the scenario (a static schedule, or shared cells kept beside the
    scheduler's)."""

    model_config = _STRICT

    slot: int = Field(ge=0, description="slot offset in the slotframe")
    channel: int = Field(ge=0, description="channel offset")
    tx: str = Field(description="transmitting node")
    rx: str = Field(description="receiving node")
    shared: bool = Field(default=False, description="shared (contention, CSMA-CA backoff) cell")
    every: int = Field(default=1, ge=1, description="active every this many slotframes")
    phase: int = Field(
        default=0, ge=0, description="active in slotframes n with n % every == phase"
    )

    def cell(self) -> Cell:
        return Cell(self.slot, self.channel, self.tx, self.rx, self.shared, self.every, self.phase)


class TraceSpec(BaseModel):
    """A k7 link trace to replay (:mod:`gateway.tsch.k7`)."""

    model_config = _STRICT

    file: str = Field(description="k7 file; a relative path is taken from the scenario's folder")
    node_map: dict[str, str] = Field(
        default_factory=dict, description="trace node id -> topology node (empty: same names)"
    )
    seconds_per_unit: float | None = Field(
        default=None,
        gt=0,
        description="trace seconds per scenario time unit (default: the gateway's "
        "energy.seconds_per_unit)",
    )

    @field_validator("file")
    @classmethod
    def _absolute(cls, value: str, info: ValidationInfo) -> str:
        base = (info.context or {}).get("base_dir") if info.context else None
        path = Path(value)
        if not path.is_absolute() and base is not None:
            path = Path(base) / path
        return str(path)


class TschConfig(BaseModel):
    """Slotframe, channels, MAC parameters, link model, schedule and radio of a TSCH network."""

    model_config = _STRICT

    slot_duration: float = Field(default=0.010, gt=0, description="slot duration, seconds")
    length: int = Field(default=101, ge=1, description="slots per slotframe")
    channels: tuple[int, ...] = Field(
        default=BAND, min_length=1, description="channels in use (11..26)"
    )
    hopping: tuple[int, ...] | None = Field(
        default=None, description="hopping sequence over the channels (default: channels in order)"
    )
    channel_offsets: int | None = Field(
        default=None, ge=1, description="channel offsets the scheduler may use (default: all)"
    )
    queue_capacity: int = Field(default=10, ge=1, description="transmit queue per node, packets")
    max_retries: int = Field(default=3, ge=0, description="retransmissions per hop")
    min_be: int = Field(default=1, ge=0, le=15, description="CSMA-CA minimum backoff exponent")
    max_be: int = Field(default=7, ge=0, le=15, description="CSMA-CA maximum backoff exponent")
    retry_cells: int = Field(
        default=1, ge=0, description="scheduler: extra cells per hop of a chain, for retries"
    )
    link_model: Literal["prr", "pathloss", "trace"] = Field(
        default="prr",
        description="prr: each topology link's prr on every channel; pathloss: from positions; "
        "trace: replayed from a k7 file",
    )
    pathloss: PathLossConfig = Field(default_factory=PathLossConfig)
    min_link_pdr: float = Field(
        default=0.5,
        gt=0,
        le=1,
        description="pathloss/trace with no topology links: pairs whose mean PDR over the "
        "channels reaches this become links",
    )
    trace: TraceSpec | None = None
    schedule: Literal["auto"] | tuple[CellSpec, ...] = Field(
        default="auto", description="auto: the central scheduler; or the cells, written out"
    )
    shared_cells: tuple[CellSpec, ...] = Field(
        default=(), description="auto: cells kept beside the scheduler's (e.g. shared ones)"
    )
    radio: str = Field(default="openmote_cc2538", description="charges per slot type")

    @model_validator(mode="after")
    def _check(self) -> TschConfig:
        for i, ch in enumerate(self.channels):
            if ch not in BAND:
                raise ValueError(f"channels[{i}]: {ch} is not an IEEE 802.15.4 channel (11..26)")
        if len(set(self.channels)) != len(self.channels):
            raise ValueError("channels: a channel is listed twice")
        for i, ch in enumerate(self.hopping or ()):
            if ch not in self.channels:
                raise ValueError(
                    f"hopping[{i}]: channel {ch} is not in channels {list(self.channels)}"
                )
        if self.channel_offsets is not None and self.channel_offsets > len(self.sequence):
            raise ValueError(
                f"channel_offsets: {self.channel_offsets} offsets need as many channels in the "
                f"hopping sequence ({len(self.sequence)})"
            )
        if self.min_be > self.max_be:
            raise ValueError(f"min_be ({self.min_be}) must not exceed max_be ({self.max_be})")
        if self.link_model == "trace" and self.trace is None:
            raise ValueError("trace: link_model trace needs a trace (file, node_map)")
        if self.radio not in RADIOS:
            raise ValueError(f"radio: unknown radio {self.radio!r} (known: {sorted(RADIOS)})")
        return self

    @property
    def sequence(self) -> tuple[int, ...]:
        """The hopping sequence."""
        return self.hopping if self.hopping else self.channels

    @property
    def offsets(self) -> int:
        """Channel offsets available."""
        return self.channel_offsets or len(self.sequence)

    def cells(self) -> list[Cell]:
        """The written cells: the whole static schedule, or the shared cells kept beside the
        scheduler's."""
        written = self.shared_cells if self.schedule == "auto" else self.schedule
        return [c.cell() for c in written]
