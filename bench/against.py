"""Measure the same thing in this tree and in another revision, side by side (``--against REV``).

A "before and after" figure is only honest when both sides are measured on the same machine at
the same time: this checks ``REV`` out into a temporary git worktree and runs a measurement (a
Python snippet printing one JSON value) alternately in this tree and in that one, each in a fresh
process with its own tree first on ``sys.path``. Alternating spreads another process's load over
both sides; each side keeps its fastest figure (load only ever slows a run down).

    from against import Comparison
    with Comparison("f0882bf~1") as cmp:
        ours, theirs = cmp.run(SNIPPET, rounds=5)
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from types import TracebackType
from typing import Any

__all__ = ["ROOT", "Comparison", "measure_in"]

ROOT = Path(__file__).resolve().parents[1]

_PRELUDE = """import importlib.util, sys
sys.path.insert(0, {root!r})
if importlib.util.find_spec("runtime.scenario") is not None:  # a tree before issue 34's package
    from runtime.scenario import load_scenario
else:
    from scenario import load_scenario
"""
"""What every measurement starts with: its tree first on ``sys.path``, and that tree's
``load_scenario`` (``runtime.scenario`` before the scenario package, ``scenario`` after)."""


def measure_in(root: Path, snippet: str) -> Any:
    """Run ``snippet`` (it prints one JSON value last) in a fresh interpreter with the tree at
    ``root`` first on ``sys.path``; the snippet finds the tree's root in ``ROOT`` and its
    ``load_scenario`` defined (:data:`_PRELUDE`)."""
    code = _PRELUDE.format(root=str(root)) + f"ROOT = {str(root)!r}\n" + snippet
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=root, capture_output=True, text=True, check=False
    )
    if done.returncode != 0:
        raise RuntimeError(f"measurement in {root} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


class Comparison:
    """A worktree of ``rev`` for as long as the ``with`` block lasts."""

    def __init__(self, rev: str) -> None:
        self.rev = rev
        self._tmp = tempfile.TemporaryDirectory(prefix="wncs-against-")
        self.tree = Path(self._tmp.name) / "tree"

    def __enter__(self) -> Comparison:
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(self.tree), self.rev],
            check=True,
            capture_output=True,
        )
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        err: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(self.tree)],
            check=False,
            capture_output=True,
        )
        self._tmp.cleanup()

    def run(self, snippet: str, *, rounds: int) -> tuple[list[Any], list[Any]]:
        """``rounds`` alternating measurements here and in ``rev``: (ours, theirs), each the
        JSON value the snippet printed."""
        ours: list[Any] = []
        theirs: list[Any] = []
        for _ in range(rounds):
            ours.append(measure_in(ROOT, snippet))
            theirs.append(measure_in(self.tree, snippet))
        return ours, theirs

    def print_table(self, ours: list[float], theirs: list[float], *, digits: int) -> None:
        """The fastest and median figure of each side, as a Markdown table."""
        print("| tree | fastest | median |")
        print("|---|---:|---:|")
        for label, xs in (("this tree", ours), (self.rev, theirs)):
            print(f"| {label} | {min(xs):.{digits}f} | {statistics.median(xs):.{digits}f} |")
