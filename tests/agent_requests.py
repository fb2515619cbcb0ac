"""Requests to the coordination agent's core as its node hands them over, for the unit tests.

The agent node (:class:`agents.wncsca.behaviour.WncscaBehaviour`) subscribes with the schemas
(:class:`~bus_schemas.Proposal`, :class:`~bus_schemas.ModeRequest`,
:class:`~bus_schemas.Setpoint`): a body that validates reaches the core typed, one that does not
reaches the core's ``on_malformed_*`` with the schema's problems. These helpers do the same with
the same validation (:func:`bus_schemas.codec.validate_body`, what both engines call), so a test
can hand the core a raw mapping, well-formed or not.
"""

from __future__ import annotations

from typing import Any

from agents.wncsca.coordinator import Coordinator, Negotiation
from agents.wncsca.decision import Decision
from bus_schemas import ModeRequest, Proposal, Setpoint
from bus_schemas.bodies import PathConfig
from bus_schemas.codec import validate_body
from bus_schemas.errors import SchemaError

__all__ = ["proposal_body", "offer", "ask_mode", "ask_setpoint", "typed_paths"]


def proposal_body(pid: Any, paths: Any) -> dict[str, Any]:
    """A ``net/proposal`` body as a gateway sends it (``paths=None``: without paths)."""
    out: dict[str, Any] = {"id": pid, "event": "initial", "source": "initial"}
    if paths is not None:
        out["paths"] = paths
    return out


def offer(core: Coordinator, network: str, raw: Any) -> Negotiation:
    """``raw`` on ``net/proposal`` from ``network``."""
    try:
        proposal = validate_body(raw, Proposal)
    except SchemaError as err:
        return core.on_malformed_proposal(network, raw, err.problems)
    return core.on_proposal(network, proposal)


def ask_mode(core: Coordinator, raw: Any) -> Decision:
    """``raw`` on ``ops/mode``."""
    try:
        request = validate_body(raw, ModeRequest)
    except SchemaError as err:
        return core.on_malformed_mode(err.problems)
    return core.on_mode(request)


def ask_setpoint(
    core: Coordinator, loop: str, raw: Any, now: int
) -> tuple[Decision, float | None, int]:
    """``raw`` on ``ops/setpoint/<loop>`` at ``now`` (ticks)."""
    try:
        request = validate_body(raw, Setpoint)
    except SchemaError as err:
        return core.on_malformed_setpoint(loop, err.problems), None, now
    return core.on_setpoint(loop, request, now)


def typed_paths(raw: dict[str, Any]) -> dict[str, PathConfig]:
    """A proposal's ``paths`` as the core receives them (raises :class:`SchemaError`)."""
    return validate_body(proposal_body(0, raw), Proposal).paths
