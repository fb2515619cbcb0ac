"""Shared fixtures: paths, an in-process zenoh router, and scenario helpers."""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import json
import os
import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from bus_schemas import Tick, TickLog, codec
from kernel.bus import open_router
from runtime.launcher import launch
from scenario import NODE_KINDS

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
BENCHMARK = SCENARIOS / "jcstr_benchmark.yaml"
DELAY_CASE = SCENARIOS / "jcstr_delay.yaml"

# Seed 000, section III.C: benchmark percent overshoots.
PAPER_OS_LEVEL = 10.8
PAPER_OS_TEMPERATURE = 11.0


@pytest.fixture(autouse=True)
def _global_state_unchanged():
    """No test may leave numpy's global RNG or print options changed (python-control's habit)."""
    state = np.random.get_state()[1].copy()
    opts = np.get_printoptions()
    yield
    assert np.array_equal(np.random.get_state()[1], state), "global numpy RNG was used"
    assert np.get_printoptions() == opts


@pytest.fixture
def stand_in(monkeypatch):
    """``stand_in(kind, cls)``: nodes of ``kind`` run behaviour class ``cls(name, spec)`` (the
    kind's own spec) instead of their own, for this test (a registry entry swapped, as a new
    kind would be)."""

    def swap(kind: str, cls) -> None:
        build = dataclasses.replace(NODE_KINDS[kind].build, behaviour=cls)
        monkeypatch.setitem(NODE_KINDS.kinds, kind, NODE_KINDS[kind].with_build(build))

    return swap


def load_yaml(path: Path) -> dict[str, Any]:
    return yaml.safe_load(path.read_text())


def write_variant(tmp_path: Path, base: Path, name: str, edit) -> Path:
    """Write a modified copy of scenario ``base`` (``edit(data)`` changes the dict in place)."""
    data = copy.deepcopy(load_yaml(base))
    edit(data)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def last_tick(sample) -> Tick | None:
    """The last tick of a sample of the clock's log (``clock/log``), ``None`` if it has none:
    how a test watching a run knows how far it has gone."""
    ticks = codec.decode(sample.payload.to_bytes(), TickLog).body.ticks
    return ticks[-1] if ticks else None


def wait_until(predicate, *, timeout: float, what: str, interval: float = 0.02) -> None:
    """Wait for a condition that has no event to wait on (a file another process writes).

    Checks ``predicate`` every ``interval`` seconds (on an ``Event`` that is never set) and fails
    with ``what`` after ``timeout`` seconds. Bus conditions wait on zenoh callbacks instead.
    """
    ticker = threading.Event()
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        ticker.wait(interval)


def kill_group(proc: subprocess.Popen) -> None:
    """SIGKILL to what is left of ``proc``'s process group (started with
    ``start_new_session=True``): a test that fails or times out leaves none of its processes
    (a run, its router, its dashboard) behind."""
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.wait(timeout=30)


def launch_aside(scenario: Path, out: Path, **options: Any) -> tuple[threading.Thread, dict]:
    """``runtime.launcher.launch(scenario, out, **options)`` in a thread of its own, for a test
    that acts on the bus while the run goes: returns the thread, once ``run.json`` names the
    router's endpoint, and the dict its ``RunResult`` lands in (key ``"r"``) when it ends."""
    result: dict[str, Any] = {}
    runner = threading.Thread(target=lambda: result.update(r=launch(scenario, out, **options)))
    runner.start()
    run = out / "run.json"
    wait_until(
        lambda: run.exists() and bool(json.loads(run.read_text()).get("endpoint")),
        timeout=60,
        what="run.json with the router endpoint",
    )
    return runner, result


@pytest.fixture(scope="session")
def router():
    """A real zenoh router in this process on a free loopback port: ``(session, endpoint)``."""
    session, locators = open_router("tcp/127.0.0.1:0")
    yield session, locators[0]
    session.close()
