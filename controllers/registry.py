"""Control laws by the ``type:`` a scenario's controller node gives them.

To add a law: a frozen pydantic config with ``type: Literal["name"]``, a class with
``reset()``, ``step(t, y, r) -> u`` and (if it takes a steady-state feedforward)
``set_feedforward(u_bar)``; register both in :data:`LAWS` and add the config to
:data:`LawConfig`. Nodes and the direct engine use only this module, never a law by name.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, Field

from controllers.ewrls import SelfTuningNLPI, STNLPIConfig
from controllers.nlpi import NLPIConfig, NonlinearPI, PI2DOFConfig, TwoDofPI
from controllers.pi import PI, PIConfig

__all__ = ["LAWS", "LawConfig", "build_law", "uses_feedforward"]

LAWS: dict[str, type[Any]] = {
    "pi": PI,  # seed 000: PI with steady-state feedforward
    "nlpi": NonlinearPI,  # seed 002: feedback-linearizing 2-DOF PI
    "pi2dof": TwoDofPI,  # seed 002: fixed-gain 2-DOF PI (the baseline)
    "stnlpi": SelfTuningNLPI,  # seed 002: EW-RLS self-tuning non-linear PI
}

LawConfig = Annotated[
    PIConfig | NLPIConfig | PI2DOFConfig | STNLPIConfig, Field(discriminator="type")
]
"""The discriminated union of every law's configuration (``PIConfig | OtherConfig | ...``)."""


def uses_feedforward(config: BaseModel) -> bool:
    """Whether the law takes the plant's steady-state input ``u_bar`` (seed 000, eq. (5)-(7))."""
    return getattr(config, "feedforward", "none") == "steady_state"


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
    cls = LAWS[config.type]  # type: ignore[attr-defined]
    if hasattr(cls, "from_config"):
        return cls.from_config(config, u_bar=u_bar, plant=plant, tau_s=tau_s)
    return cls(config, u_bar=u_bar)
