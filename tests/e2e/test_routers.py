"""One run over two chained standalone routers (issue 19, item 3): ``wncs router`` twice on
loopback ports, the second joined to the first, every node a ``wncs node`` process connected to
one or the other with its own credentials. Its history is the single-router run's, bit for bit.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from bus_schemas import keys
from core.errors import ConfigError
from core.record import summarize
from kernel.bus import open_client
from kernel.security import SECURITY_DIR
from runtime.history import load_record, messages_digest
from runtime.security import SECURITY_ENV, credentials_of
from scenario import load_scenario
from tests.conftest import BENCHMARK, wait_until
from tests.e2e.test_runs import WNCS, assert_same_traces, traces, wncs_run

pytestmark = pytest.mark.slow


def wncs_router(
    out: Path, log: Path, *extra: str, listen: str = "tcp/127.0.0.1:0"
) -> subprocess.Popen:
    """``wncs router`` for the benchmark's run in ``out``, its output to ``log``."""
    cmd = [*WNCS, "router", "--scenario", str(BENCHMARK), "--out", str(out)]
    cmd += ["--listen", listen, *extra]
    return subprocess.Popen(cmd, stdout=log.open("w"), stderr=subprocess.STDOUT)


def chain_two_routers(
    out: Path,
    logs: Path,
    procs: list[subprocess.Popen],
    *,
    listen: str = "tcp/127.0.0.1:0",
    first: tuple[str, ...] = (),
    second: tuple[str, ...] = (),
    reach: Callable[[str], str] = lambda endpoint: endpoint,
) -> dict:
    """Two ``wncs router`` processes of one run in ``out`` (appended to ``procs``, for the
    caller to stop): the first with options ``first``, then the second with ``second``, joined
    to the first at ``reach(its endpoint)``. Returns ``run.json`` once both are in it."""
    run_file = out / "run.json"

    def routers() -> list[dict]:
        for p in procs:
            assert p.poll() is None, [f.read_text() for f in logs.glob("router_*.log")]
        return json.loads(run_file.read_text()).get("routers", []) if run_file.exists() else []

    procs.append(wncs_router(out, logs / "router_a.log", *first, listen=listen))
    wait_until(lambda: len(routers()) == 1, timeout=60, what="the first router")
    joined = reach(routers()[0]["endpoint"])
    procs.append(
        wncs_router(out, logs / "router_b.log", "--connect", joined, *second, listen=listen)
    )
    wait_until(lambda: len(routers()) == 2, timeout=60, what="the second router")
    return json.loads(run_file.read_text())


def stop_all(procs: list[subprocess.Popen]) -> None:
    """SIGTERM each process still running, then wait for each (killed after 20 s)."""
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def run_nodes_split(
    out: Path, logs: Path, run_id: str, endpoints: list[str], nodes: dict[str, subprocess.Popen]
) -> None:
    """Every node of the benchmark a ``wncs node`` process with its credentials, alternately
    on either router (the clock on the first), the historian writing to ``out``; wait for all
    to end, each with exit 0 (``nodes`` holds them, for the caller to stop if this fails)."""
    env = {**os.environ, SECURITY_ENV: str(out / SECURITY_DIR)}
    names = ["clock", *load_scenario(BENCHMARK).participants()]
    for i, name in enumerate(names):
        cmd = [*WNCS, "node", str(BENCHMARK), name, "--connect", endpoints[i % 2]]
        cmd += ["--run-id", run_id]
        if name == "historian":
            cmd += ["--out", str(out), "--engine", "threads"]
        log = (logs / f"{name}.log").open("w")
        nodes[name] = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
    assert nodes["clock"].wait(timeout=300) == 0, (logs / "clock.log").read_text()[-2000:]
    for name, p in nodes.items():
        assert p.wait(timeout=60) == 0, (name, (logs / f"{name}.log").read_text()[-2000:])


def test_a_run_over_two_chained_routers_equals_the_single_router_run(tmp_path):
    clean = wncs_run(BENCHMARK, tmp_path / "single", "--engine", "threads")
    out = tmp_path / "chained"
    logs = tmp_path / "logs"
    logs.mkdir()
    procs: list[subprocess.Popen] = []
    nodes: dict[str, subprocess.Popen] = {}
    try:
        info = chain_two_routers(out, logs, procs)
        assert info["secure"]
        endpoints = [r["endpoint"] for r in info["routers"]]
        assert len(set(endpoints)) == 2
        run_nodes_split(out, logs, info["run_id"], endpoints, nodes)
    finally:
        stop_all([*nodes.values(), *procs])
    history = out / "history.sqlite"
    assert messages_digest(history) == messages_digest(tmp_path / "single" / "history.sqlite")
    rec = load_record(history, load_scenario(BENCHMARK), engine="threads")
    assert_same_traces(traces(summarize(rec)), traces(clean), atol=0.0)


def test_a_standalone_router_says_and_logs_what_it_refuses(tmp_path):
    """``wncs router`` audits (kernel.audit): a login without credentials and three puts on the
    clock's tick with the reactor's login are refused, each a line of ``DIR/refused.log``; the
    router's terminal says the first of each kind and, when it stops, the total."""
    out = tmp_path / "run"
    log = tmp_path / "router.log"
    router = wncs_router(out, log)
    try:
        run_file = out / "run.json"
        wait_until(
            lambda: run_file.exists() and json.loads(run_file.read_text()).get("endpoint"),
            timeout=60,
            what="the router's run.json",
        )
        info = json.loads(run_file.read_text())
        with pytest.raises(ConfigError):
            open_client(info["endpoint"])
        security = out / SECURITY_DIR
        intruder = open_client(info["endpoint"], settings=credentials_of(security, "reactor"))
        tick = keys.full(info["run_id"], keys.tick_to("reactor"))
        for _ in range(3):
            intruder.put(tick, b"forged")
        refused = out / "refused.log"
        wait_until(
            lambda: refused.exists() and len(refused.read_text().splitlines()) == 4,
            timeout=30,
            what="four refused attempts in refused.log",
        )
        intruder.close()
    finally:
        stop_all([router])
    said = log.read_text()
    assert f"refused attempts go to {refused}" in said
    assert f"refused reactor: Put (ingress) on {tick} (1 so far)" in said
    assert "(2 so far)" not in said  # the first of a kind, then the 10th, 100th, ...
    assert "refused unauthenticated: login (Recv InitSyn. Expected extension.)" in said
    assert "it refused 4 attempts" in said
