"""What the bus refuses (issue 19): forged data from outside a run's nodes changes nothing.

Each test runs ``wncs run`` in real processes on a real zenoh router, sends forged messages from
an outside client, and compares the run with the clean run of the same scenario.
"""

from __future__ import annotations

import json
import threading
from pathlib import Path

import msgpack
import pytest

from bus_schemas import Tick, codec, keys
from kernel.bus import open_client
from runtime.history import messages_digest
from tests.conftest import BENCHMARK
from tests.e2e.test_runs import (
    assert_same_traces,
    start_run,
    traces,
    wait_for_virtual_time,
    wncs_run,
)

pytestmark = pytest.mark.slow

ACTUATOR = keys.actuator("reactor", "F_out")  # owned by the network node alone
MEAS = keys.meas("level")  # likewise


@pytest.fixture(scope="module")
def clean_run(tmp_path_factory) -> tuple[Path, dict]:
    """The benchmark run with nobody else on the bus."""
    out = tmp_path_factory.mktemp("clean")
    return out, wncs_run(BENCHMARK, out)


def _envelope(run: str, src: str, seq: int, round_: int, body: dict) -> bytes:
    head = {"v": 1, "run": run, "src": src, "seq": seq, "round": round_, "t": 0}
    return msgpack.packb({**head, "body": body})


def test_forged_data_with_a_wrong_run_source_or_round_is_dropped_counted_and_harmless(
    tmp_path, clean_run
):
    """Valid bodies on keys the level loop acts on, each with one thing wrong: another run's id,
    a source that does not own the key (a participant of the run, or a stranger), or a round
    thousands ahead. Every node drops them and counts them; the run's history and
    traces are the clean run's, bit for bit (a command of 1e6 on the outflow, or a level
    measurement of 5, would change both)."""
    proc, info = start_run(BENCHMARK, tmp_path, "--realtime", "1.0")
    run_id = info["run_id"]
    session = open_client(info["endpoint"])
    current = [0]

    def on_tick(sample) -> None:
        current[0] = codec.decode(sample.payload.to_bytes(), Tick).body.round

    ticks = session.declare_subscriber(keys.full(run_id, keys.tick()), on_tick)
    move = {"value": 1e6, "t_computed": 0}
    sample = {"value": 5.0, "t_sampled": 0}
    stop = threading.Event()
    sent = [0]

    def forge() -> None:
        seq = 10**9
        while not stop.is_set():
            r = current[0]
            for rel, body in ((ACTUATOR, move), (MEAS, sample)):
                for run, src, round_ in (
                    ("r-other", "network", r),  # another run's
                    (run_id, "level_controller", r),  # a participant that does not own the key
                    (run_id, "intruder", r),  # nobody of the run
                    (run_id, "network", r + 5_000),  # the owner, far ahead
                ):
                    seq += 1
                    session.put(keys.full(run_id, rel), _envelope(run, src, seq, round_, body))
                    sent[0] += 1
            stop.wait(0.01)

    th = threading.Thread(target=forge)
    try:
        wait_for_virtual_time(session, info, proc, 1_000_000)
        th.start()
        out, err = proc.communicate(timeout=300)
    finally:
        stop.set()
        if th.is_alive():
            th.join()
        ticks.undeclare()
        session.close()
    assert proc.returncode == 0, err
    assert sent[0] > 100
    summary = json.loads((tmp_path / "summary.json").read_text())
    dropped = summary["messages"]["dropped_invalid"]
    assert dropped.get(ACTUATOR, 0) > 0 and dropped.get(MEAS, 0) > 0, dropped
    assert set(dropped) == {ACTUATOR, MEAS}, dropped
    clean_out, clean = clean_run
    assert_same_traces(traces(summary), traces(clean), atol=0.0)
    assert messages_digest(tmp_path / "history.sqlite") == messages_digest(
        clean_out / "history.sqlite"
    )
