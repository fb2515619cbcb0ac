"""Configurations of the control-loop performance monitor (seed 004): the analysis settings, a
candidate secondary, and the monitor node of a scenario (``kind: monitor``).

Only pydantic and the column names here (scenarios import this module; the numerics stay out
of their import).

A monitor node assesses one loop from its routine data over a sliding window, live on the bus
(:mod:`agents.monitor.behaviour`)::

    temperature_monitor:
      kind: monitor
      loop: temperature                  # primary: the loop's delivered measurement
      secondaries:                       # candidate secondaries: columns of the run
        - {name: reactor.T_j, d1: 3, d2: 1}
      window: 2000                       # samples
      period: 500.0                      # an assessment every 500 time units, and at the end
      analysis: {max_order: 30}          # MonitorConfig

Columns are named as ``wncs assess RUN_DIR`` names them (:mod:`agents.monitor.columns`):
``LOOP`` (a loop's delivered measurement), ``LOOP.sp`` (its set point), ``PLANT.STATE`` (a plant
state on its monitoring grid).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from agents.monitor.columns import RunShape, resolve_column

__all__ = [
    "SecondarySpec",
    "OscillationConfig",
    "ScreeningAction",
    "ScreeningConfig",
    "MonitorConfig",
    "rows_needed",
    "MonitorNodeConfig",
]


class SecondarySpec(BaseModel):
    """A candidate secondary measurement and the delays around it (samples)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str = Field(min_length=1, description="column / series name")
    d1: int = Field(ge=0, description="dead time from this secondary to the primary")
    d2: int = Field(ge=1, description="dead time from the manipulated variable to this secondary")


class OscillationConfig(BaseModel):
    """Thresholds of the oscillation test (:mod:`agents.monitor.oscillation`, Thornhill et al.
    2003)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    min_regularity: float = Field(default=1.0, gt=0, description="r above which it is regular")
    min_decay: float = Field(
        default=0.8, gt=0, le=1, description="ACF lobe ratio per period from which it is sustained"
    )
    significance: float = Field(
        default=3.0, gt=0, description="ACF lobes count above significance/sqrt(N)"
    )
    max_crossings: int = Field(default=11, ge=4, description="ACF zero crossings used at most")
    min_periods: int = Field(default=3, ge=2, description="period estimates needed")


ScreeningAction = Literal["warn", "exclude", "refuse"]
"""What a data-quality finding does: report it; analyse without the rows concerned (spikes:
replaced by interpolation; other rows: the longest stretch without them); refuse the data."""


class ScreeningConfig(BaseModel):
    """Data-quality screening before the analysis (:mod:`agents.monitor.screening`): per check
    its threshold and its action."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    frozen: ScreeningAction = "exclude"
    frozen_run: int = Field(
        default=20, ge=3, description="equal values in a row that make a frozen segment"
    )
    compressed: ScreeningAction = "warn"
    compressed_run: int = Field(
        default=20, ge=3, description="samples on one straight line (historian interpolation)"
    )
    spike: ScreeningAction = "exclude"
    spike_threshold: float = Field(
        default=8.0, gt=0, description="robust z (MAD of the increments) of a spike"
    )
    quality: ScreeningAction = "exclude"
    mode: ScreeningAction = "exclude"
    offset: Literal["warn", "refuse"] = "warn"
    offset_ratio: float = Field(
        default=3.0, gt=0, description="|mean(SP - PV)| above this many std(PV): not tracking"
    )
    saturation: ScreeningAction = "warn"
    saturation_fraction: float = Field(
        default=0.05, gt=0, lt=1, description="share of samples at an OP limit that is flagged"
    )


class MonitorConfig(BaseModel):
    """Settings of the analysis (defaults suit 1,000-50,000 samples of routine data)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    max_order: int = Field(default=30, ge=1, description="largest AR/VAR order tried")
    order: int | None = Field(default=None, ge=1, description="fixed order instead of selection")
    criterion: Literal["aic", "bic"] = "aic"
    method: Literal["ls", "yule_walker"] = Field(
        default="ls", description="VAR estimator of the decomposition"
    )
    removed_2a: tuple[float, float] = Field(
        default=(0.0, 0.5),
        description="fraction of component 2a a cascade is assumed to remove: band "
        "[1a + (1-hi) 2a, 1a + (1-lo) 2a]",
    )
    harris_uncertainty: Literal["delta", "bootstrap"] = "delta"
    n_boot: int = Field(default=200, ge=2, description="bootstrap replicates (Harris)")
    decomposition_boot: int = Field(
        default=0, ge=0, description="bootstrap replicates for the components (0: none)"
    )
    seed: int = Field(default=0, description="seed of np.random.default_rng for bootstraps")
    confidence: float = Field(default=0.95, gt=0, lt=1)
    max_innovation_correlation: float = Field(default=0.99, gt=0, le=1)
    min_reduction: float = Field(
        default=0.2,
        ge=0,
        lt=1,
        description="predicted relative variance reduction from which cascade is recommended",
    )
    oscillation: OscillationConfig = Field(default_factory=OscillationConfig)
    screening: ScreeningConfig = Field(default_factory=ScreeningConfig)

    @model_validator(mode="after")
    def _band(self) -> MonitorConfig:
        lo, hi = self.removed_2a
        if not 0.0 <= lo <= hi <= 1.0:
            raise ValueError(f"removed_2a must satisfy 0 <= lo <= hi <= 1, got {self.removed_2a}")
        return self


def rows_needed(config: MonitorConfig | None = None, n_series: int = 2) -> int:
    """Fewest samples the models need: ``p + 5 (k p + 1)`` at the largest order, and 200."""
    c = config or MonitorConfig()
    p = c.order or c.max_order
    return max(200, p + 5 * (n_series * p + 1))


class MonitorNodeConfig(BaseModel):
    """A performance monitor on the bus: assesses one loop over a sliding window of its samples
    and publishes ``monitor/assessment/<loop>`` every ``period`` and at the end of the run."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: Literal["monitor"]
    loop: str = Field(description="the loop assessed; its delivered measurement is the primary")
    secondaries: tuple[SecondarySpec, ...] = Field(
        default=(),
        description="candidate secondaries by column name (LOOP or PLANT.STATE), with d1, d2",
    )
    delay: int | None = Field(
        default=None,
        ge=1,
        description="dead time from the move to the primary, samples (default: d1 + d2)",
    )
    setpoint: bool = Field(
        default=True,
        description="analyse the control error LOOP.sp - LOOP (robust to set-point changes in "
        "the window) instead of the measurement",
    )
    window: int = Field(default=2000, ge=1, description="samples in the sliding window")
    start: float = Field(default=0.0, ge=0, description="samples taken before this are ignored")
    period: float | None = Field(
        default=None, gt=0, description="time between assessments (always one at the end)"
    )
    analysis: MonitorConfig = Field(default_factory=MonitorConfig)

    @model_validator(mode="after")
    def _consistent(self) -> MonitorNodeConfig:
        d = self.delay
        for i, s in enumerate(self.secondaries):
            if d is None:
                d = s.d1 + s.d2
            elif s.d1 + s.d2 != d:
                where = "delay" if self.delay is not None else "secondaries[0]"
                raise ValueError(
                    f"secondaries[{i}]: d1 + d2 = {s.d1} + {s.d2} = {s.d1 + s.d2}, but {where} "
                    f"gives {d} samples from the move to the primary; every candidate's d1 + d2 "
                    "must equal it"
                )
        if d is None:
            raise ValueError("delay: needed when there are no secondaries")
        names = [s.name for s in self.secondaries]
        for i, name in enumerate(names):
            if names.index(name) != i:
                raise ValueError(f"secondaries[{i}].name: {name!r} is listed twice")
            if name == self.loop:
                raise ValueError(f"secondaries[{i}].name: {name!r} is the primary itself")
        need = rows_needed(self.analysis, 2 if self.secondaries else 1)
        if self.window < need:
            raise ValueError(
                f"window: {self.window} samples, fewer than the {need} the analysis needs "
                f"(analysis.max_order {self.analysis.order or self.analysis.max_order})"
            )
        return self

    @property
    def d(self) -> int:
        """The dead time from the move to the primary, samples."""
        if self.delay is not None:
            return self.delay
        return self.secondaries[0].d1 + self.secondaries[0].d2

    def columns(self) -> list[str]:
        """The columns the analysis reads besides the primary (set point, then secondaries)."""
        return ([f"{self.loop}.sp"] if self.setpoint else []) + [s.name for s in self.secondaries]

    def check(self, run: RunShape, name: str) -> None:
        """Refuse names that are not in ``run`` (``ValueError`` naming the field, e.g.
        ``nodes.mon.secondaries[0].name: 'reactor.Tj' is not a column of this run ...``)."""
        at = f"nodes.{name}"
        if self.loop not in run.loops:
            raise ValueError(f"{at}.loop: unknown loop {self.loop!r} (loops: {sorted(run.loops)})")
        for i, s in enumerate(self.secondaries):
            try:
                resolve_column(run, s.name)
            except ValueError as err:
                raise ValueError(f"{at}.secondaries[{i}].name: {err}") from None
        if self.start >= run.end_time:
            raise ValueError(f"{at}.start: {self.start} is not before end_time {run.end_time}")
