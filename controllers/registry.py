"""Control laws by the ``type:`` a scenario's controller node gives them.

To add a law: a frozen pydantic config with ``type: Literal["name"]``, a class with
``reset()``, ``step(t, y, r) -> u`` and (if it takes a steady-state feedforward)
``set_feedforward(u_bar)``; add one :class:`~core.registry.Kind` entry to :data:`LAWS` (the
scenario's :data:`LawConfig` union is made from it). Nodes and the direct engine use only this
module, never a law by name.

A **multi-loop** law (class attribute ``multi_loop = True``) controls several loops at once (a
controller node with ``loops: [a, b, ...]``): its ``step(t, y, r) -> u`` takes the latest
measurement and the set point of every loop by name (``dict[str, float]``) and returns a move for
every loop; it may have a static ``check_loops(config, loops)`` that refuses a loop list
(``ValueError``) and a classmethod ``from_config(config, *, loops, plant, tau_s, context)``
(``context``: :class:`MultiLoopContext`, the loops' signals and the controller's links). A law
with ``actuator_only_loops = True`` accepts loops without a sensor (``sensor: null``: it moves
their input, and ``y`` has no entry for them); one with ``measurement_only_loops = True`` accepts
loops without an actuator (``actuator: null``: ``y`` and ``r`` have entries for them, ``u`` has
none, and no move is published). A law that exchanges data with other controllers
over the scenario's ``links:`` has ``transmit(t) -> list[float]`` (what it sends on its links)
and ``receive(t, link, values)`` (what arrived on one).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from pydantic import BaseModel

from controllers.cascade.law import PIPCascadeLaw, PIPCascadeLawConfig
from controllers.ewrls import SelfTuningNLPI, STNLPIConfig
from controllers.mrac import MRACConfig, MultiLoopMRAC
from controllers.nlpi import NLPIConfig, NonlinearPI, PI2DOFConfig, TwoDofPI
from controllers.pi import PI, PIConfig
from controllers.qdc.law import QDCLaw, QDCLawConfig
from core.registry import Kind, Registry

__all__ = [
    "LAWS",
    "LawConfig",
    "MultiLoopContext",
    "accepts_actuator_only_loops",
    "accepts_measurement_only_loops",
    "exchanges_estimates",
    "build_law",
    "build_multi_loop_law",
    "check_loops",
    "is_multi_loop",
    "uses_feedforward",
]

LAWS: Registry[Any] = Registry(
    "law",
    tag="type",
    kinds=[
        Kind("pi", PIConfig, PI, "seed 000: PI with steady-state feedforward"),
        Kind("nlpi", NLPIConfig, NonlinearPI, "seed 002: feedback-linearizing 2-DOF PI"),
        Kind("pi2dof", PI2DOFConfig, TwoDofPI, "seed 002: fixed-gain 2-DOF PI (the baseline)"),
        Kind("stnlpi", STNLPIConfig, SelfTuningNLPI, "seed 002: EW-RLS self-tuning NLPI"),
        Kind("mrac", MRACConfig, MultiLoopMRAC, "seed 003: model-reference adaptive (multi-loop)"),
        Kind("qdc", QDCLawConfig, QDCLaw, "seed 001: a unit's quasi-decentralized control"),
        Kind("pip_cascade", PIPCascadeLawConfig, PIPCascadeLaw, "seed 004: PI-P cascade"),
    ],
)
"""Every control law: its ``type:`` name, its configuration, its class (the ``build``)."""

LawConfig = LAWS.union()
"""The discriminated union of every law's configuration (``PIConfig | OtherConfig | ...``)."""


@dataclass(frozen=True)
class MultiLoopContext:
    """What a multi-loop law may need from the scenario besides its configuration.

    Attributes
    ----------
    signals : mapping
        Loop -> ``(sensor, actuator)``: the plant output it measures (``None`` for an
        actuator-only loop) and the input it moves (``None`` for a measurement-only loop).
    sends, receives : tuple of str
        The links (``links:``) the controller transmits on and receives, by name.
    """

    signals: Mapping[str, tuple[str | None, str | None]] = field(default_factory=dict)
    sends: tuple[str, ...] = ()
    receives: tuple[str, ...] = ()


def _law_class(config: BaseModel) -> Any:
    return LAWS.of(config).build


def accepts_actuator_only_loops(config: BaseModel) -> bool:
    """Whether the law of ``config`` accepts loops without a sensor (``sensor: null``)."""
    return bool(getattr(_law_class(config), "actuator_only_loops", False))


def accepts_measurement_only_loops(config: BaseModel) -> bool:
    """Whether the law of ``config`` accepts loops without an actuator (``actuator: null``)."""
    return bool(getattr(_law_class(config), "measurement_only_loops", False))


def exchanges_estimates(config: BaseModel) -> bool:
    """Whether the law of ``config`` sends and receives on links (``transmit``/``receive``)."""
    cls = _law_class(config)
    return hasattr(cls, "transmit") and hasattr(cls, "receive")


def uses_feedforward(config: BaseModel) -> bool:
    """Whether the law takes the plant's steady-state input ``u_bar`` (seed 000, eq. (5)-(7))."""
    return getattr(config, "feedforward", "none") == "steady_state"


def is_multi_loop(config: BaseModel) -> bool:
    """Whether the law of ``config`` controls several loops at once (``loops:``)."""
    return bool(getattr(_law_class(config), "multi_loop", False))


def check_loops(config: BaseModel, loops: Sequence[str]) -> None:
    """Refuse a multi-loop law's loop list that does not fit it (``ValueError`` with the reason)."""
    check = getattr(_law_class(config), "check_loops", None)
    if check is not None:
        check(config, loops)


def build_law(config: BaseModel, *, u_bar: float, plant: Any, tau_s: float) -> Any:
    """The law object of ``config`` for one loop.

    Parameters
    ----------
    config : BaseModel
        A validated law configuration (its ``type`` selects the class).
    u_bar : float
        Initial steady-state feedforward (0 when the law takes none).
    plant : object
        The loop's plant model, for laws designed from its parameters.
    tau_s : float
        The loop's nominal sampling period (laws must still use the actual time between samples).
    """
    cls = _law_class(config)
    if hasattr(cls, "from_config"):
        return cls.from_config(config, u_bar=u_bar, plant=plant, tau_s=tau_s)
    return cls(config, u_bar=u_bar)


def build_multi_loop_law(
    config: BaseModel,
    *,
    loops: Sequence[str],
    plant: Any,
    tau_s: float,
    context: MultiLoopContext | None = None,
) -> Any:
    """The law object of a multi-loop ``config`` for the loops ``loops`` (in that order).

    Parameters
    ----------
    config : BaseModel
        A validated configuration of a multi-loop law.
    loops : sequence of str
        The controller's loops, in the order its ``loops:`` lists them.
    plant : object
        The plant model of the first loop, for laws designed from its parameters.
    tau_s : float
        The shortest nominal sampling period of the loops.
    context : MultiLoopContext, optional
        The loops' signals and the controller's links
        (:meth:`scenario.Scenario.multi_loop_context`).
    """
    cls = _law_class(config)
    if not getattr(cls, "multi_loop", False):
        raise ValueError(f"law {config.type!r} controls one loop; use build_law")  # type: ignore[attr-defined]
    if hasattr(cls, "from_config"):
        return cls.from_config(config, loops=loops, plant=plant, tau_s=tau_s, context=context)
    return cls(config, loops)
