"""The historian node: records every data message of the run in ``history.sqlite``.

It is a participant like any other, so it handles each round's messages after they are all in,
in ``(key, src, seq)`` order: the table's order is deterministic and two runs with the same
scenario and seed write identical message tables (see :func:`runtime.history.messages_digest`).
"""

from __future__ import annotations

import json
from pathlib import Path

from bus_schemas import Stop, Tick, codec
from bus_schemas.envelope import RawEnvelope
from runtime import history
from runtime.node import Node, NodeContext

__all__ = ["HistorianNode", "HISTORY_FILE"]

HISTORY_FILE = "history.sqlite"
_COMMIT_EVERY = 200  # rounds


class HistorianNode(Node):
    def __init__(self, ctx: NodeContext) -> None:
        super().__init__(ctx)
        out = Path(ctx.options.get("out") or ".")
        out.mkdir(parents=True, exist_ok=True)
        self.path = out / HISTORY_FILE
        if self.path.exists():
            self.path.unlink()
        self.db = history.connect(self.path, create=True)
        self._set_meta("run_id", self.run_id)
        self._set_meta("scenario", self.scenario.name)
        self._set_meta("seed", self.scenario.seed)
        self._set_meta("engine", ctx.options.get("engine", "processes"))
        self.db.commit()
        self.subscribe("**", None, self._record)

    def _set_meta(self, name: str, value: object) -> None:
        self.db.execute(
            "INSERT OR REPLACE INTO meta (name, value) VALUES (?, ?)", (name, json.dumps(value))
        )

    def on_tick(self, tick: Tick) -> None:
        self.db.execute(
            "INSERT INTO ticks (round, t, expected) VALUES (?, ?, ?)",
            (tick.round, tick.t, json.dumps(tick.expected, sort_keys=True)),
        )
        if tick.round % _COMMIT_EVERY == 0:
            self.db.commit()

    def _record(self, env: RawEnvelope, body: dict) -> None:
        rel = self.current_key
        self.db.execute(
            "INSERT INTO messages (round, t, key, src, seq, body) VALUES (?, ?, ?, ?, ?, ?)",
            (env.round, env.t, rel, env.src, env.seq, codec.pack_mapping(body)),
        )

    def on_stop(self, stop: Stop) -> None:
        self._set_meta("stop", stop.model_dump())
        self.db.commit()
        self.db.close()
