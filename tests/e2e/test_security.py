"""What the bus refuses (issue 19): forged data from outside a run's nodes changes nothing.

Each test runs ``wncs run`` in real processes on a real zenoh router, sends forged messages from
an outside client, and compares the run with the clean run of the same scenario.
"""

from __future__ import annotations

import json
import subprocess
import threading
from pathlib import Path

import msgpack
import pytest

from bus_schemas import keys
from core.errors import ConfigError
from kernel.bus import open_client
from kernel.security import SECURITY_DIR, Credential, client_settings
from runtime.history import messages_digest
from runtime.security import DASHBOARD, credentials_of
from tests.conftest import BENCHMARK, last_tick, wait_until
from tests.e2e.test_runs import (
    WNCS,
    assert_same_traces,
    observer,
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
    """The benchmark run with nobody else on the bus (its history is the same on every engine)."""
    out = tmp_path_factory.mktemp("clean")
    return out, wncs_run(BENCHMARK, out, "--engine", "threads")


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
    proc, info = start_run(BENCHMARK, tmp_path, "--realtime", "1.0", "--insecure")
    run_id = info["run_id"]
    session = open_client(info["endpoint"])
    current = [0]

    def on_tick(sample) -> None:
        current[0] = getattr(last_tick(sample), "round", current[0])

    ticks = session.declare_subscriber(keys.full(run_id, keys.tick_log()), on_tick)
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


def test_without_credentials_or_with_another_nodes_nothing_gets_through_the_router(
    tmp_path, clean_run
):
    """A secure run (the default; the threads engine: the launcher's router is the same for
    both bus engines). A client without credentials cannot even open a session. With the
    reactor's credentials (a node of the run, but not the owner of these keys) a client puts
    an outflow command of 1e6 as the network would stamp it, the next tick, the level
    controller's Done, a set-point request as ``wncs inject`` would send it, and declares the
    level controller's and the clock's liveliness tokens (and drops them again, which would
    read as those nodes leaving); with the dashboard's it puts on the actuator key too. The
    router lets none of it through: no node even sees a message to drop, the run ends normally
    and its history is the clean run's, bit for bit. The router counts each attempt, exactly
    (the run's summary and ``refused.log``), and nothing in the clean run."""
    proc = subprocess.Popen(
        [*WNCS, "run", str(BENCHMARK), "--out", str(tmp_path), "--quiet"]
        + ["--engine", "threads", "--realtime", "1.0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    run_file = tmp_path / "run.json"
    wait_until(
        lambda: run_file.exists() and bool(json.loads(run_file.read_text()).get("endpoint")),
        timeout=60,
        what="run.json naming the endpoint",
    )
    info = json.loads(run_file.read_text())
    run_id = info["run_id"]
    assert info["secure"]
    security = tmp_path / SECURITY_DIR
    modes = {p.name: p.stat().st_mode & 0o777 for p in security.iterdir()}
    assert set(modes.values()) == {0o600} and (security.stat().st_mode & 0o777) == 0o700
    watcher = observer(info, tmp_path)
    try:
        wait_for_virtual_time(watcher, info, proc, 1_000_000)
        with pytest.raises(ConfigError):
            open_client(info["endpoint"])  # no credentials
        with pytest.raises(ConfigError):  # a made-up password for a real identity
            open_client(
                info["endpoint"],
                settings=client_settings(Credential("network", "guessed")),
            )
        current = [0]

        def on_tick(sample) -> None:
            current[0] = getattr(last_tick(sample), "round", current[0])

        ticks = watcher.declare_subscriber(keys.full(run_id, keys.tick_log()), on_tick)
        intruder = open_client(info["endpoint"], settings=credentials_of(security, "reactor"))
        dashboard = open_client(info["endpoint"], settings=credentials_of(security, DASHBOARD))
        for _ in range(20):
            r = current[0]
            move = {"value": 1e6, "t_computed": 0}
            tick = {"round": r + 1, "t": 10**9, "expected": {}}
            ctl = "level_controller"
            done = {"round": r, "node": ctl, "published": {}}
            request = {"setpoint": {"loop": "level", "value": 0.9}}
            forged = [
                (ACTUATOR, _envelope(run_id, "network", 10**9 + r, r, move)),
                (keys.tick_to(ctl), _envelope(run_id, "clock", 10**9 + r, r + 1, tick)),
                (
                    keys.done("level_controller"),
                    _envelope(run_id, "level_controller", 10**9, r, done),
                ),
                (keys.inject(), _envelope(run_id, "inject", r, 0, request)),
            ]
            for rel, raw in forged:
                intruder.put(keys.full(run_id, rel), raw)
            dashboard.put(keys.full(run_id, ACTUATOR), forged[0][1])
            tokens = [
                intruder.liveliness().declare_token(keys.full(run_id, keys.alive(n)))
                for n in ("level_controller", "clock")
            ]
            held_from = current[0]  # hold the tokens while the run takes a round
            wait_until(
                lambda h=held_from: current[0] > h or proc.poll() is not None,
                timeout=30,
                what="a round of the run with the forged tokens declared",
            )
            for token in tokens:
                token.undeclare()
        intruder.close()
        dashboard.close()
        ticks.undeclare()
        out, err = proc.communicate(timeout=300)
    finally:
        watcher.close()
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["messages"]["dropped_invalid"] == {}
    # the router counted each attempt (kernel.audit), and nothing in the clean run
    full = lambda rel: keys.full(run_id, rel)  # noqa: E731
    attempts = {
        (a["who"], a["what"], a["where"]): a["count"] for a in summary["router"]["attempts"]
    }
    assert attempts == {
        ("reactor", "Put (ingress)", full(ACTUATOR)): 20,
        ("reactor", "Put (ingress)", full(keys.tick_to("level_controller"))): 20,
        ("reactor", "Put (ingress)", full(keys.done("level_controller"))): 20,
        ("reactor", "Put (ingress)", full(keys.inject())): 20,
        ("reactor", "Liveliness Token (ingress)", full(keys.alive("level_controller"))): 20,
        ("reactor", "Liveliness Token (ingress)", full(keys.alive("clock"))): 20,
        ("dashboard", "Put (ingress)", full(ACTUATOR)): 20,
        ("unauthenticated", "login (Recv InitSyn. Expected extension.)", ""): 1,
        ("unauthenticated", "login (Recv OpenSyn. Invalid password.)", ""): 1,
    }
    assert f"the router refused {summary['router']['refused']} attempts" in err
    assert len((tmp_path / "refused.log").read_text().splitlines()) == 142
    clean_out, clean = clean_run
    assert clean["router"] == {"refused": 0, "attempts": []}
    assert_same_traces(traces(summary), traces(clean), atol=0.0)
    assert messages_digest(tmp_path / "history.sqlite") == messages_digest(
        clean_out / "history.sqlite"
    )
