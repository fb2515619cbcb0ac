"""How a controller node executes its law on the samples of a round: one protocol, two rules.

:class:`~controllers.behaviour.ControllerBehaviour` hands every delivered sample to its
:class:`Execution` (``take``) and, after the round's messages are dispatched, asks it for the
moves to publish (``moves``). What differs between a single-loop and a multi-loop law lives here,
not in forks of the node:

* :class:`SingleLoop` adapts a single-loop law (``step(t, y, r) -> u`` with floats, ``resume``,
  ``set_feedforward``) to the protocol: one move per delivered sample, in delivery order, with the
  set points current at the instant; the agent may open the loop (no moves, the plant holds the
  last one) and re-close it (``law.resume``); a set-point change re-computes the steady-state
  feedforward (seed 000, eq. (5)-(7)) before the round's samples are used.
* :class:`MultiLoop` is the hold rule of a multi-loop law (``step(t, y, r)`` with
  ``dict[loop, float]``, such as seed 003's MRAC): it keeps every measured loop's latest sample
  (a sample taken before the one held is not used), and executes once per round in which samples
  arrive, once every measured loop has delivered; its moves are for the loops with an actuator.
  The agent does not open or close its loops (refused when the scenario loads), so ``close`` only
  records nothing.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

from bus_schemas import Sample

__all__ = ["Execution", "MultiLoop", "SingleLoop"]


class Execution(Protocol):
    """What the controller node asks of its law, whichever rule it executes by."""

    law: Any
    """The law object (its ``transmit``/``receive`` serve the node's links)."""
    measured: tuple[str, ...]
    """The loops whose samples it takes, in subscription order."""

    def take(self, loop: str, sample: Sample) -> None:
        """A sample of ``loop`` delivered in this round."""

    def moves(
        self, t: float, setpoints: Mapping[str, float], changed: bool
    ) -> list[dict[str, float]]:
        """The moves of this round, each a loop -> value mapping to publish in order, at time
        ``t`` (time units) with the set points current now (``changed``: since last round)."""

    def close(self, t: float, closed: Mapping[str, bool]) -> str | None:
        """Apply the agent's ``closed`` flags at ``t``; a line for the log when one changed."""


class SingleLoop:
    """One loop's law, executed on every delivered sample (see the module docstring).

    Parameters
    ----------
    law : object
        A single-loop law (:func:`controllers.registry.build_law`).
    loop : str
        Its loop.
    feedforward : object or None
        Its steady-state feedforward (``u_bar(setpoints)``), if it takes one.
    """

    def __init__(self, law: Any, loop: str, feedforward: Any = None) -> None:
        self.law = law
        self.loop = loop
        self.measured: tuple[str, ...] = (loop,)
        self.feedforward = feedforward
        self.closed = True
        self._samples: list[Sample] = []

    def take(self, loop: str, sample: Sample) -> None:
        self._samples.append(sample)

    def moves(
        self, t: float, setpoints: Mapping[str, float], changed: bool
    ) -> list[dict[str, float]]:
        if changed and self.feedforward is not None:
            self.law.set_feedforward(self.feedforward.u_bar(setpoints))
        samples, self._samples = self._samples, []
        if not self.closed:
            return []
        r = setpoints[self.loop]
        return [{self.loop: self.law.step(t, s.value, r)} for s in samples]

    def close(self, t: float, closed: Mapping[str, bool]) -> str | None:
        now_closed = closed.get(self.loop, True)
        if now_closed == self.closed:
            return None
        if now_closed:
            self.law.resume(t)
        self.closed = now_closed
        return f"loop {self.loop} {'closed' if now_closed else 'opened (output held)'}"


class MultiLoop:
    """A multi-loop law under the hold rule (see the module docstring).

    Parameters
    ----------
    law : object
        A multi-loop law (:func:`controllers.registry.build_multi_loop_law`).
    loops : sequence of str
        Its loops, in the law's order (their set points are its references).
    measured, moved : sequence of str
        The loops with a sensor, with an actuator.
    """

    def __init__(
        self, law: Any, loops: tuple[str, ...], measured: tuple[str, ...], moved: tuple[str, ...]
    ) -> None:
        self.law = law
        self.loops = loops
        self.measured = measured
        self.moved = moved
        self._held: dict[str, tuple[int, float]] = {}  # loop -> (t_sampled, value)
        self._arrived: list[tuple[str, Sample]] = []

    def take(self, loop: str, sample: Sample) -> None:
        self._arrived.append((loop, sample))

    def moves(
        self, t: float, setpoints: Mapping[str, float], changed: bool
    ) -> list[dict[str, float]]:
        if not self._arrived:
            return []
        for loop, sample in self._arrived:
            held = self._held.get(loop)
            if held is None or sample.t_sampled >= held[0]:
                self._held[loop] = (sample.t_sampled, sample.value)
        self._arrived.clear()
        if len(self._held) < len(self.measured):
            return []  # some loop has not delivered yet: no move
        y = {n: self._held[n][1] for n in self.measured}
        r = {n: setpoints[n] for n in self.loops}
        u = self.law.step(t, y, r)
        return [{n: u[n] for n in self.moved}]

    def close(self, t: float, closed: Mapping[str, bool]) -> str | None:
        return None  # the agent does not open or close a multi-loop law's loops
