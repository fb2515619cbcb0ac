"""Progress heartbeats: a node busy with a long round says it is still working (DESIGN section 3).

The clock's ``round_timeout_s`` judges *silence*, not work. A node whose round lasts longer than
a beat (the agent deciding on a proposal, an identification fit, a monitor's assessment) sends
:class:`bus_schemas.Working` on ``clock/working/<node>`` every beat while the round goes on; the
clock counts each as a sign of life for that round, and only ``clock.work_timeout_s`` (measured
from the round's tick) ends a node that computes forever. The liveliness token stays the death
signal.

One :class:`Heartbeat` thread serves every node of a process: the threads engine's nodes share
one, a node process (``wncs node``, the processes engine) has its own. A round costs the node
two attribute writes (:attr:`Worker.working`); the thread wakes once a beat and sends only for
rounds older than a beat, so rounds of a millisecond send nothing. It changes nothing in virtual
time: no round waits for a beat, and the history never sees one.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Iterator
from typing import Protocol

__all__ = ["BEAT_S", "beat_interval", "Worker", "Heartbeat"]

log = logging.getLogger(__name__)

BEAT_S = 1.0
"""The longest interval between two beats of a busy node, wall seconds."""


def beat_interval(round_timeout_s: float) -> float:
    """The beat for a run whose clock waits ``round_timeout_s`` for a silent node: at most
    :data:`BEAT_S`, and a quarter of the timeout, so that three beats may go missing (a busy
    machine delays a thread) before a working node looks silent."""
    return min(BEAT_S, round_timeout_s / 4)


class Worker(Protocol):
    """What a heartbeat watches: a bus node (:class:`kernel.node.BusNode`)."""

    @property
    def working(self) -> tuple[int, int, float] | None:
        """``(round, t, began)`` of the round under way (``began``: ``time.monotonic()`` at its
        start), ``None`` between rounds."""

    def beat(self, round_: int, t: int, busy_s: float) -> None:
        """Say on the bus that round ``round_`` (at ``t`` ticks) is still under way, after
        ``busy_s`` wall seconds."""


class Heartbeat:
    """One thread that beats for every watched worker whose round has lasted a beat or more.

    Use :meth:`watching` around a worker's run; the thread starts with the first worker watched
    and ends within a beat of the last one leaving.
    """

    def __init__(self, interval_s: float) -> None:
        if not interval_s > 0:
            raise ValueError(f"heartbeat interval must be > 0 s, got {interval_s}")
        self.interval_s = interval_s
        self._lock = threading.Lock()
        self._workers: list[Worker] = []
        self._thread: threading.Thread | None = None
        self._wake = threading.Event()  # never set: the thread's timed wait between beats

    @contextlib.contextmanager
    def watching(self, worker: Worker) -> Iterator[None]:
        """Beat for ``worker`` while the block runs."""
        with self._lock:
            self._workers.append(worker)
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="heartbeat", daemon=True)
                self._thread.start()
        try:
            yield
        finally:
            with self._lock:
                self._workers.remove(worker)

    def _run(self) -> None:
        while True:
            self._wake.wait(self.interval_s)
            with self._lock:
                workers = list(self._workers)
                if not workers:
                    self._thread = None
                    return
            now = time.monotonic()
            for worker in workers:
                state = worker.working
                if state is None or now - state[2] < self.interval_s:
                    continue
                round_, t, began = state
                try:
                    worker.beat(round_, t, now - began)
                except Exception as err:  # noqa: BLE001 - a closing session must not end the beats
                    log.debug("heartbeat: could not beat for round %d: %s", round_, err)
