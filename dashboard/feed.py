"""Reading a run's history as it grows: the rows the historian committed since the last read.

The historian commits each round (``runtime.historian``), so every read sees whole rounds, in
the table's order (round, then key, source, sequence): the order every engine agrees on. A body
is decoded and checked against its key's schema (:data:`runtime.history.BODIES`); one that fails
is returned with the reason instead of a body, never read as a number.
"""

from __future__ import annotations

import json
import sqlite3
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bus_schemas import codec
from bus_schemas.errors import SchemaError
from runtime.history import body_schema

__all__ = ["Row", "HistoryFeed"]


@dataclass(frozen=True, slots=True)
class Row:
    """One message of the history: ``body`` is the validated mapping, or ``None`` with
    ``invalid`` giving why the body was refused."""

    id: int
    round: int
    t: int
    key: str
    src: str
    body: dict[str, Any] | None
    invalid: str | None = None


class HistoryFeed:
    """Incremental reader of ``history.sqlite`` (read-only; the database may not exist yet).

    :meth:`read` returns the rows after the last one read, at most ``limit`` of them;
    :meth:`stop` the clock's stop message once the run has ended (``None`` before).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.last_id = 0
        self._conn: sqlite3.Connection | None = None

    def _connection(self) -> sqlite3.Connection | None:
        if self._conn is None:
            if not self.path.exists():
                return None
            # read-only: the dashboard never writes a run's history
            self._conn = sqlite3.connect(
                f"file:{self.path}?mode=ro", uri=True, check_same_thread=False
            )
        return self._conn

    def read(self, limit: int = 20_000) -> list[Row]:
        conn = self._connection()
        if conn is None:
            return []
        try:
            raw = conn.execute(
                "SELECT id, round, t, key, src, body FROM messages WHERE id > ? "
                "ORDER BY id LIMIT ?",
                (self.last_id, limit),
            ).fetchall()
        except sqlite3.OperationalError:  # the historian has not made its tables yet
            return []
        rows = [_row(*r) for r in raw]
        if rows:
            self.last_id = rows[-1].id
        return rows

    def stop(self) -> dict[str, Any] | None:
        """The clock's stop message (``ok``, ``reason``, ``round``, ``dropped_invalid`` ...)."""
        conn = self._connection()
        if conn is None:
            return None
        try:
            found = conn.execute("SELECT value FROM meta WHERE name = 'stop'").fetchone()
        except sqlite3.OperationalError:
            return None
        return dict(json.loads(found[0])) if found else None

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None


def _row(id_: int, rnd: int, t: int, key: str, src: str, body: bytes) -> Row:
    try:
        mapping = codec.unpack_mapping(body)
        schema = body_schema(key)
        if schema is not None:
            codec.validate_body(mapping, schema)
    except SchemaError as err:
        return Row(id_, rnd, t, key, src, None, str(err))
    return Row(id_, rnd, t, key, src, mapping)
