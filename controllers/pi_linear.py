"""The PI law of :mod:`controllers.pi` as a linear system for python-control (kept apart so that
a controller node, which runs the law, does not import python-control)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from controllers.pi import PIConfig

if TYPE_CHECKING:
    import control

__all__ = ["pi_state_space"]


def pi_state_space(
    config: PIConfig,
    h: float,
    *,
    feedforward_gain: float = 0.0,
    signals: tuple[str, str, str] = ("r", "y", "u"),
) -> control.StateSpace:
    """The law at a constant period ``h`` as a discrete ``control.StateSpace`` (``dt = h``) in
    deviation variables, limits ignored: inputs ``(r, y)``, output ``u``, one state ``s`` (the
    integral the next execution starts from).

    ``integration: backward``: ``s_{k+1} = s_k + Ki h e_k``, ``u_k = s_k + (Kp + Ki h) e_k``;
    ``forward``: ``s_{k+1} = s_k + Ki h e_k``, ``u_k = s_k + Kp e_k``; ``e_k = r_k - y_k``.
    ``feedforward_gain`` is ``d u_bar / d r`` (seed 000 eq. (5)-(7) linearised), added to
    ``u_k`` as ``feedforward_gain r_k``. ``signals`` names ``(r, y, u)``.
    """
    import control

    if not h > 0.0:
        raise ValueError(f"the period must be > 0, got {h}")
    kp = config.Kp + (config.Ki * h if config.integration == "backward" else 0.0)
    r, y, u = signals
    return control.ss(
        [[1.0]],
        [[config.Ki * h, -config.Ki * h]],
        [[1.0]],
        [[kp + feedforward_gain, -kp]],
        h,
        states=["s"],
        inputs=[r, y],
        outputs=[u],
    )
