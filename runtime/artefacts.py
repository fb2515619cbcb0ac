"""The names of what a run leaves in its directory (DESIGN section 7)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

__all__ = [
    "RUN_FILE",
    "SCENARIO_FILE",
    "HISTORY_FILE",
    "SUMMARY_FILE",
    "REFUSED_LOG",
    "write_json",
]

RUN_FILE = "run.json"
"""Run id, router endpoint and node pids, written at start (``wncs inject`` reads it)."""
SCENARIO_FILE = "scenario.yaml"
"""The copy of the scenario the run was launched with."""
HISTORY_FILE = "history.sqlite"
"""Every bus message the historian saw."""
SUMMARY_FILE = "summary.json"
"""Per-loop metrics, the agent's decisions, message counts, energy."""
REFUSED_LOG = "refused.log"
"""A secure run's router: each attempt it refused (a message, a token, a login), one a line."""


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` to ``path`` as JSON, whole or not at all (through a file beside it): a
    reader, ``wncs inject`` or a second router, never sees half a ``run.json``."""
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n")
    tmp.replace(path)
