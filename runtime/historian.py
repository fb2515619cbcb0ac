"""The historian: records every data message of the run in ``history.sqlite``.

It is a bus node like any other, so it handles each round's messages after they are all in, in
``(key, src, seq)`` order: the table's order is deterministic and two runs with the same
scenario and seed write identical message tables (see :func:`runtime.history.messages_digest`).
It is an *observer* (:attr:`kernel.node.BusNode.observer`): it takes every tick and records
every round, but answers only the clock's sync rounds, so no round waits for its SQLite work.
:class:`Recorder` is the behaviour (it writes what it is handed), :class:`HistorianNode` the bus
node that also records each tick.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

from bus_schemas import Stop, Tick, codec, keys
from core.behaviour import Behaviour, Incoming
from core.rounds import merge_dropped
from kernel.node import BusNode, NodeContext
from runtime import history
from runtime.artefacts import HISTORY_FILE

__all__ = ["Recorder", "HistorianNode", "HISTORY_FILE"]


class Recorder(Behaviour):
    """Writes every data message it is handed (subscribed to every data key,
    :func:`bus_schemas.keys.data_all`) into an open history database."""

    def __init__(self, name: str, db: sqlite3.Connection) -> None:
        super().__init__(name)
        self.db = db
        for pattern in keys.data_all():
            self.subscribe(pattern, None, self._record)

    def _record(self, env: Incoming, body: dict[str, Any]) -> None:
        self.db.execute(
            "INSERT INTO messages (round, t, key, src, seq, body) VALUES (?, ?, ?, ?, ?, ?)",
            (env.round, env.t, self.current_key, env.src, env.seq, codec.pack_mapping(body)),
        )


class HistorianNode(BusNode):
    observer = True  # off the rounds' critical path (kernel.clock.ClockSpec.observers)

    def __init__(self, ctx: NodeContext, *, scenario_name: str, seed: int) -> None:
        out = Path(ctx.options.get("out") or ".")
        out.mkdir(parents=True, exist_ok=True)
        self.path = out / HISTORY_FILE
        if self.path.exists():
            self.path.unlink()
        self.db = history.connect(self.path, create=True)
        super().__init__(ctx, Recorder(ctx.name, self.db))
        self._set_meta("run_id", ctx.run_id)
        self._set_meta("scenario", scenario_name)
        self._set_meta("seed", seed)
        self._set_meta("engine", ctx.options.get("engine", "processes"))
        self.db.commit()

    def _set_meta(self, name: str, value: object) -> None:
        self.db.execute(
            "INSERT OR REPLACE INTO meta (name, value) VALUES (?, ?)", (name, json.dumps(value))
        )

    def on_tick(self, tick: Tick) -> None:
        """Record the tick (its round's messages follow)."""
        self.db.execute(
            "INSERT INTO ticks (round, t, expected) VALUES (?, ?, ?)",
            (tick.round, tick.t, json.dumps(tick.expected, sort_keys=True)),
        )

    def on_handled(self) -> None:
        """Commit once the ticks of one log of the clock's are recorded: every message of the
        rounds before them is then on disk (WAL), so a run cut short keeps all but the rounds
        of the log under way and its last round."""
        self.db.commit()

    def on_stop(self, stop: Stop) -> None:
        # what it refused since its last Done (it answers only the sync rounds) counts too
        dropped = merge_dropped([stop.dropped_invalid, self.dropped_invalid])
        self._set_meta("stop", {**stop.model_dump(), "dropped_invalid": dropped})
        self.db.commit()
        self.db.close()
