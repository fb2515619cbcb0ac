"""The names of what a run leaves in its directory (DESIGN section 7)."""

from __future__ import annotations

__all__ = ["RUN_FILE", "SCENARIO_FILE", "HISTORY_FILE", "SUMMARY_FILE", "REFUSED_LOG"]

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
