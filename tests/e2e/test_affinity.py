"""``wncs run --affinity`` pins a run's real processes to CPUs (runtime.affinity): each forked
node and the router on the processes engine, the launcher's own process for the rounds of the
threads engine (then its CPUs back) and its router, by default on one CPU; the history is the
unpinned run's, bit for bit."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from kernel.node import BusNode
from runtime.history import messages_digest
from runtime.launcher import launch
from scenario import load_scenario
from tests.conftest import BENCHMARK

USABLE = os.sched_getaffinity(0)
FIRST, LAST = frozenset({min(USABLE)}), frozenset({max(USABLE)})  # one CPU: the same


def _cpus_of(pid: int) -> set[frozenset[int]]:
    """The CPU sets of every thread of process ``pid``."""
    return {frozenset(os.sched_getaffinity(int(task))) for task in os.listdir(f"/proc/{pid}/task")}


def _router_pid() -> int:
    for pid in os.listdir("/proc"):
        try:
            if (
                pid.isdigit()
                and b"kernel.router_process" in Path(f"/proc/{pid}/cmdline").read_bytes()
                and int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
                == os.getpid()
            ):
                return int(pid)
        except OSError:
            continue
    raise AssertionError("no router process of this test")


def test_the_processes_engine_pins_each_node_and_the_router(tmp_path):
    plain = launch(BENCHMARK, tmp_path / "plain")
    assert plain.code == 0, plain.error
    router_cpus: list[set[frozenset[int]]] = []
    res = launch(
        BENCHMARK,
        tmp_path / "pinned",
        affinity={"*": FIRST, "historian": LAST},
        on_start=lambda out: router_cpus.append(_cpus_of(_router_pid())),
    )
    assert res.code == 0, res.error
    assert router_cpus == [{FIRST}]  # '*' covers the router
    logs = tmp_path / "pinned" / "logs"
    names = ["clock", *load_scenario(BENCHMARK).participants()]
    assert len(names) == 7  # the clock, five nodes, the historian
    for name in names:
        want = LAST if name == "historian" else FIRST
        said = (logs / f"{name}.log").read_text()
        assert f"{name} pinned to CPU(s) {sorted(want)}" in said, name
    assert messages_digest(tmp_path / "pinned" / "history.sqlite") == messages_digest(
        tmp_path / "plain" / "history.sqlite"
    )


@pytest.mark.parametrize(
    ("affinity", "want"),
    [
        (None, FIRST),  # the default: one CPU, the lowest this process may use
        ({"*": LAST}, LAST),
        ({"*": frozenset(USABLE)}, frozenset(USABLE)),  # spread again
    ],
)
def test_the_threads_engine_pins_its_process_and_router_for_the_rounds_then_gives_them_back(
    tmp_path, monkeypatch, affinity, want
):
    before = os.sched_getaffinity(0)
    seen: set[frozenset[int]] = set()
    round_ = BusNode._round_

    def noting(node, tick):
        seen.add(frozenset(os.sched_getaffinity(0)))  # the thread running the node's round
        return round_(node, tick)

    monkeypatch.setattr(BusNode, "_round_", noting)
    router_cpus: list[set[frozenset[int]]] = []
    res = launch(
        BENCHMARK,
        tmp_path / "run",
        engine="threads",
        affinity=affinity,
        on_start=lambda out: router_cpus.append(_cpus_of(_router_pid())),
    )
    assert res.code == 0, res.error
    assert seen == {want}
    assert router_cpus == [{want}]
    assert json.loads((tmp_path / "run" / "run.json").read_text())["affinity"] == {
        "*": sorted(want)
    }
    assert os.sched_getaffinity(0) == before
    assert _cpus_of(os.getpid()) == {frozenset(before)}
