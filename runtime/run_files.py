"""A loop's routine data from a run directory (seed 004): a
:class:`~agents.monitor.run_data.RunSeries` fed from a bus run's ``history.sqlite`` or a direct
run's ``record.json``.

The application layer (it reads run files through :mod:`runtime.history` and
:mod:`runtime.report`, which know the scenario); ``wncs assess RUN_DIR``
(:mod:`runtime.assess`) reads runs with it. The monitor's core
(:mod:`agents.monitor.run_data`) is bus-free and file-free and does not import it.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ValidationError

from agents.monitor.run_data import RunSeries, feed_run_record
from bus_schemas import codec
from runtime.history import connect
from runtime.report import load_saved_record

__all__ = ["feed_history", "feed_record"]


def _validated(body_type: type[BaseModel], raw: bytes) -> BaseModel | None:
    try:
        return body_type.model_validate(codec.unpack_mapping(raw))
    except (ValidationError, ValueError):
        return None  # the node would have dropped it as invalid, too


def feed_history(path: str | Path, series: RunSeries, *, until: int) -> int:
    """Feed ``series`` from a run's ``history.sqlite``: the messages of its keys stamped before
    ``until`` (ticks), in the order the historian handled them. Returns the messages fed."""
    subs = dict(series.subscriptions())
    marks = ",".join("?" * len(subs))
    fed = 0
    with connect(path) as conn:
        rows = conn.execute(
            f"SELECT round, t, key, body FROM messages WHERE t < ? AND key IN ({marks}) "
            "ORDER BY id",
            (until, *subs),
        )
        for rnd, t, key, raw in rows:
            body = _validated(subs[key], raw)
            if body is not None:
                series.feed(key, rnd, t, body)
                fed += 1
    return fed


def feed_record(path: str | Path, series: RunSeries, *, until: int) -> int:
    """Feed ``series`` from a direct-engine run's ``record.json`` (no bus, no rounds: the time
    stands for the round, so a set point applies to the samples handled at its instant).
    Returns the messages fed."""
    return feed_run_record(load_saved_record(Path(path).parent), series, until=until)
