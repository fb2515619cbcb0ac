"""Configuration of the WNCSCA coordination agent (seed 000, section III.E): the overshoot limit
and tolerances of its searches, the set-point test it simulates, how it reads a proposal's delays,
which method assigns the sampling periods, and the sampling periods of its operating modes.

It is a scenario node (``kind: agent``); ``wncs analyze`` uses the same model with the defaults
when a scenario has no agent node.
"""

from __future__ import annotations

import math
from typing import Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, model_validator

from bus_schemas.bodies import EstimateName

__all__ = [
    "ESTIMATES",
    "MODES",
    "TestStep",
    "SetpointTest",
    "ModesConfig",
    "LinksConfig",
    "ParameterUncertainty",
    "PlantBelief",
    "IdentifyConfig",
    "WatchConfig",
    "WncscaConfig",
]

_STRICT = ConfigDict(frozen=True, extra="forbid")

ESTIMATES: tuple[str, ...] = get_args(EstimateName)
"""The paper's three path-delay estimates (III.E step 1), as the gateway's proposals carry them."""

MODES = (
    "startup",
    "setpoint_change",
    "identification",
    "steady_state",
    "fault_detection",
    "regulation",
)
"""Operating modes (seed 000, section II; DESIGN section 6). ``regulation``: loops closed at the
control periods after the monitoring raised and confirmed an alarm."""


class TestStep(BaseModel):
    """One set-point change of the agent's test."""

    model_config = _STRICT

    t: float = Field(ge=0)
    loop: str
    value: float


class SetpointTest(BaseModel):
    """The closed-loop experiment whose overshoots the agent judges (seed 000, III.C: the level
    step at 1.8 pu and the temperature step at 2.4 pu from the initial state)."""

    model_config = _STRICT

    end_time: float = Field(gt=0)
    setpoints: list[TestStep] = Field(min_length=1)


class ModesConfig(BaseModel):
    """Sampling periods of the modes that do not use the negotiated control periods.

    Periods are per loop in scenario time units; a loop not named keeps its control period.
    """

    model_config = _STRICT

    identification: dict[str, float] = Field(
        default_factory=dict, description="per-loop periods while the plant is identified"
    )
    monitoring: dict[str, float] = Field(
        default_factory=dict,
        description="steady state: loops open, sensors report at these periods",
    )
    fault_detection: dict[str, float] = Field(
        default_factory=dict,
        description="between monitoring and control: loops open, faster reports",
    )

    @model_validator(mode="after")
    def _positive(self) -> ModesConfig:
        for mode in ("identification", "monitoring", "fault_detection"):
            for loop, period in getattr(self, mode).items():
                if not period > 0:
                    raise ValueError(f"{mode}.{loop}: a period must be > 0, got {period}")
        return self


class LinksConfig(BaseModel):
    """How the agent governs the update period of estimates exchanged on the scenario's
    ``links:`` (controllers of interconnected units, seed 001): by the spectral-radius test of
    the linearized networked loop (:mod:`agents.update_period`), not by simulation."""

    model_config = _STRICT

    analysis: Literal["spectral_radius", "sampled"] = Field(
        default="spectral_radius",
        description="spectral_radius: rho(M_d(h)) < 1 with the links' delay, continuous-time "
        "local loops (seed 001 eq. (8), delayed updates: agents/update_period/delay.py); "
        "sampled: the loop as the platform runs it, sampled measurements and held moves, h a "
        "multiple of the controllers' tau_s (agents/update_period/sampled.py)",
    )
    margin: float = Field(
        default=0.9, gt=0, lt=1, description="assigned period = margin x the largest allowable one"
    )
    h_hi: float = Field(default=0.2, gt=0, description="longest update period scanned, time units")
    n_grid: int = Field(default=200, ge=10, le=5000, description="periods scanned on (d, h_hi]")


class ParameterUncertainty(BaseModel):
    """How well the agent knows one parameter of its model: a relative standard deviation (the
    belief is normal about its value) or an interval (the parameter lies in ``[low, high]``, in
    the parameter's own unit). Exactly one of the two."""

    model_config = _STRICT

    rel_sd: float | None = Field(
        default=None,
        gt=0,
        le=0.3,
        description="relative standard deviation of the believed value (0.1: 10 %), normal, "
        "drawn within +-2.5 sd (beyond 30 %, state an interval)",
    )
    interval: tuple[float, float] | None = Field(
        default=None,
        description="[low, high]: the parameter lies in it (its own unit), with the believed "
        "value inside",
    )

    @model_validator(mode="after")
    def _one(self) -> ParameterUncertainty:
        if (self.rel_sd is None) == (self.interval is None):
            raise ValueError("give exactly one of rel_sd or interval")
        if self.interval is not None:
            low, high = self.interval
            if not (math.isfinite(low) and math.isfinite(high) and low < high):
                raise ValueError(f"interval: low ({low}) must be below high ({high}), both finite")
        return self


class PlantBelief(BaseModel):
    """What the agent believes of one plant it judges: its model's parameters (those not named
    are the plant node's own) and how uncertain they are. The true plant node keeps its own
    parameters; the agent judges every trial on this model."""

    model_config = _STRICT

    params: dict[str, Any] = Field(
        default_factory=dict,
        description="parameter -> the value the agent believes, by the plant model's symbols "
        "(not named: the plant node's own value)",
    )
    uncertainty: dict[str, ParameterUncertainty] = Field(
        default_factory=dict,
        description="parameter -> how well the agent knows it (rel_sd or interval)",
    )


class IdentifyConfig(BaseModel):
    """The identification experiment the agent runs first (seed 000, section II: the LMId
    "perturbs the plant with pseudo-random signals ... gathers data and applies its model
    identification algorithm"; issue 35, item 3): from ``t = 0`` for ``duration``, in mode
    ``identification`` (its periods: ``modes.identification``), every loop named in
    ``amplitude`` has its set point switched between ``r0 - amplitude`` and ``r0 + amplitude``
    by generalized binary noise (:func:`agents.identify.excitation.gbn`); the agent then fits
    its model's ``params`` to the delivered samples (:func:`agents.wncsca.identification.identify`),
    takes the estimate and its covariance as its model and re-judges the configuration that
    runs."""

    model_config = _STRICT

    params: dict[str, list[str]] = Field(
        min_length=1,
        description="plant -> the parameters of the agent's model the experiment fits",
    )
    duration: float = Field(gt=0, description="the experiment's length from t = 0, time units")
    clock: float = Field(
        gt=0, description="the noise's clock: the set points may switch every clock, time units"
    )
    switch: float = Field(
        default=0.5,
        gt=0,
        le=1,
        description="probability of a switch per clock (0.5: a PRBS-like spectrum; lower puts "
        "more power at low frequencies)",
    )
    amplitude: dict[str, float] = Field(
        min_length=1,
        description="loop -> the set point's excursion either side of its initial value, in the "
        "signal's unit (the experiment never moves a set point farther)",
    )

    @model_validator(mode="after")
    def _check(self) -> IdentifyConfig:
        for loop, a in self.amplitude.items():
            if not (a > 0 and math.isfinite(a)):
                raise ValueError(f"amplitude.{loop}: must be > 0 and finite, got {a}")
        for plant, names in self.params.items():
            if not names or len(set(names)) != len(names):
                raise ValueError(f"params.{plant}: name each parameter once, got {names}")
        if self.clock > self.duration:
            raise ValueError(f"clock: {self.clock} is longer than duration {self.duration}")
        return self


class WatchConfig(BaseModel):
    """The model watch (issue 35, item 4; :mod:`agents.wncsca.watch`): after every step the
    chance method judged, the agent compares what its loops delivered over the test's length
    with its model's prediction of it, scores the misfit against replays of the same window on
    its model (noise and stated uncertainty), and runs a one-sided CUSUM on the scores; past
    ``threshold`` the model no longer fits: the agent identifies it again (with ``identify:``)
    or widens its stated uncertainty by ``widen``, and judges the running configurations
    again."""

    model_config = _STRICT

    allowance: float = Field(
        default=0.5,
        ge=0,
        description="CUSUM's k: the score (in standard deviations of what the model expects) a "
        "window may have without moving the sum up",
    )
    threshold: float = Field(
        default=5.0, gt=0, description="CUSUM's h: past this sum the model no longer fits"
    )
    replays: int = Field(
        default=20,
        ge=3,
        le=1000,
        description="replays of each window on the model (its noise and stated uncertainty) "
        "that say what a fitting model's score looks like",
    )
    widen: float = Field(
        default=2.0,
        gt=1,
        description="without identify: the factor on the stated uncertainty (its standard "
        "deviations, its intervals' half-widths) when the model no longer fits",
    )


class WncscaConfig(BaseModel):
    """The coordination agent (a scenario node of ``kind: agent``)."""

    model_config = _STRICT

    kind: Literal["agent"] = "agent"
    overshoot_limit: float = Field(default=25.0, gt=0, description="largest acceptable OS, %")
    os_tolerance: float = Field(
        default=1.0,
        gt=0,
        description="eps_OS: a search stops when an acceptable trial is this close to the limit, "
        "percentage points (III.E step 3a)",
    )
    period_tolerance: float = Field(
        default=0.01,
        gt=0,
        description="eps_L: the alternation stops when a loop's period changes by less, "
        "time units (III.E step 3d)",
    )
    resolution: float = Field(
        default=0.001, gt=0, description="trial periods are multiples of this, time units"
    )
    phase: Literal["worst", "fixed"] = Field(
        default="worst",
        description="overshoot of a trial: worst case over the set-point step's phase relative "
        "to the sampling instants, or at the test's own step times (the paper)",
    )
    phases: int = Field(default=4, ge=1, le=64, description="phases tried in the worst case")
    method: Literal["paper", "fast", "chance"] = Field(
        default="chance",
        description="paper: seed 000's successive approximation at the mean delay, exactly; "
        "fast: the same question on the linearised loops; chance: the paper's searches on the "
        "risk of the proposal's delay distribution, P(overshoot <= limit) >= confidence "
        "(agents/wncsca/chance.py)",
    )
    confidence: float = Field(
        default=0.95,
        gt=0,
        lt=1,
        description="chance method: the probability with which every loop's overshoot of a "
        "step must stay within the limit, over delays, losses and step phases",
    )
    realizations: int = Field(
        default=400, ge=16, le=20000, description="chance method: Monte Carlo realizations"
    )
    checks: int = Field(
        default=24,
        ge=2,
        le=1000,
        description="chance method: realizations replayed on the non-linear model to correct "
        "the linearisation",
    )
    objective: Literal["paper", "energy"] = Field(
        default="paper",
        description="fast method: each loop's longest period with the others fixed (the "
        "paper's answer), or the joint choice using the least network energy",
    )
    estimate: Literal["timestamps", "ping", "hops", "quantile"] = Field(
        default="hops",
        description="which of a proposal's delay estimates is the control-path delay (the "
        "paper's three are means; a missing one falls back to the others in the order "
        "timestamps, ping, hops); quantile: the confidence-quantile of the path's delay "
        "distribution, a constant delay for the paper and fast methods (the chance method "
        "takes the whole distribution, located at one of the means)",
    )
    order: list[str] | None = Field(
        default=None, description="loops in the order the paper's method searches them"
    )
    ideal_period: dict[str, float] = Field(
        default_factory=dict,
        description="tau_si per loop, where the doubling starts (default: the benchmark period)",
    )
    max_period: float = Field(default=10.0, gt=0, description="longest period ever tried")
    max_trials: int = Field(default=40, ge=2, description="trials per single-loop search")
    max_alternations: int = Field(default=6, ge=1, description="rounds over all loops")
    delay_resolution: float = Field(
        default=0.001, gt=0, description="bisection of the delay bound stops at this width"
    )
    max_delay: float = Field(default=5.0, gt=0, description="largest delay bound looked for")
    test: SetpointTest | None = Field(
        default=None, description="the set-point test; default: the scenario's own schedule"
    )
    modes: ModesConfig = Field(default_factory=ModesConfig)
    alarm: dict[str, float] = Field(
        default_factory=dict,
        description="loop -> largest |y - r| tolerated while the loops are open, in the signal's "
        "unit: beyond it steady state becomes fault detection (faster reports), and a "
        "confirmed deviation closes the loops (regulation)",
    )
    confirm: int = Field(
        default=2, ge=1, description="samples beyond the alarm that confirm a fault"
    )
    links: LinksConfig | None = Field(
        default=None,
        description="govern the update period of the scenario's links (controllers exchanging "
        "estimates) by the spectral-radius analysis; their loops are then not simulated",
    )
    model: dict[str, PlantBelief] = Field(
        default_factory=dict,
        description="plant node -> the agent's own model of it (its believed parameters and "
        "their uncertainty); a plant not named: the plant node's own parameters, known exactly",
    )
    uncertainty: Literal["probability", "robust"] = Field(
        default="probability",
        description="chance method, how the model's uncertainty enters the guarantee: "
        "probability: the parameters drawn per realization (beside delays, losses and phases), "
        "so P(overshoot <= limit) covers model error; robust: the guarantee holds at every "
        "corner of the parameters' intervals (rel_sd: +-1.96 sd), a bound rather than a "
        "probability over the parameters",
    )
    identify: IdentifyConfig | None = Field(
        default=None,
        description="an identification experiment first (from t = 0), then the agent's model "
        "is the estimate, with its covariance as the model's uncertainty",
    )
    watch: WatchConfig | None = Field(
        default=None,
        description="chance method: after every judged step, test whether the model still "
        "fits what the loops delivered (a CUSUM on the innovations' score), and identify again "
        "or widen the uncertainty when it does not",
    )
    model_draws: int = Field(
        default=40,
        ge=2,
        le=1000,
        description="chance method, uncertainty probability: parameter sets drawn from the "
        "model's uncertainty (realization r uses set r mod model_draws)",
    )

    @model_validator(mode="after")
    def _check(self) -> WncscaConfig:
        for loop, period in self.ideal_period.items():
            if not period > 0:
                raise ValueError(f"ideal_period.{loop}: a period must be > 0, got {period}")
        for loop, band in self.alarm.items():
            if not band > 0:
                raise ValueError(f"alarm.{loop}: must be > 0, got {band}")
        if self.order is not None and len(set(self.order)) != len(self.order):
            raise ValueError(f"order: a loop is named twice in {self.order}")
        if self.watch is not None and self.method != "chance":
            raise ValueError(
                f"watch: the model watch follows the steps the chance method judges; method is "
                f"{self.method!r} (use method: chance)"
            )
        if self.method == "chance" and self.estimate == "quantile":
            raise ValueError(
                "estimate: quantile is a constant delay for the paper and fast methods; the "
                "chance method takes the whole distribution (estimate: hops, ping or timestamps "
                "says where its mean is)"
            )
        return self
