"""compose.yaml's commands, run: no Docker engine runs here, so each service's command runs as a
local process, as compose would start it (the router first; the nodes once its health check
passes), with the container names mapped to this host (``tcp/router:7447`` to the router's
loopback endpoint, ``/runs`` to a temporary directory, ``WNCS_SECURITY`` likewise). The run is
secure, ends normally, and its history is the launcher's, bit for bit."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest
import yaml

from runtime.history import messages_digest
from tests.conftest import BENCHMARK, ROOT, wait_until
from tests.e2e.test_routers import stop_all
from tests.e2e.test_runs import WNCS, wncs_run

pytestmark = pytest.mark.slow


def _local(words: list[str], runs: Path, endpoint: str | None) -> list[str]:
    """A compose command word by word, on this host."""
    mapped = []
    for w in words:
        if w == "tcp/0.0.0.0:7447":
            w = "tcp/127.0.0.1:0"
        elif w == "tcp/router:7447":
            assert endpoint is not None
            w = endpoint
        elif w.startswith("/runs/"):
            w = str(runs / w.removeprefix("/runs/"))
        elif w.startswith("scenarios/"):
            w = str(ROOT / w)
        mapped.append(w)
    assert mapped[0] == "wncs"
    return [*WNCS, *mapped[1:]]


def test_the_compose_services_run_a_secure_run_equal_to_the_launchers(tmp_path):
    clean = tmp_path / "clean"
    wncs_run(BENCHMARK, clean, "--engine", "threads")
    services = yaml.safe_load((ROOT / "compose.yaml").read_text())["services"]
    runs = tmp_path / "runs"
    logs = tmp_path / "logs"
    logs.mkdir()
    router_svc = services.pop("router")
    cmd, *health = router_svc["healthcheck"]["test"]
    assert cmd == "CMD"
    health = [str(runs / w.removeprefix("/runs/")) if w.startswith("/runs/") else w for w in health]
    procs: dict[str, subprocess.Popen] = {}
    try:
        procs["router"] = subprocess.Popen(
            _local(router_svc["command"], runs, None),
            stdout=(logs / "router.log").open("w"),
            stderr=subprocess.STDOUT,
        )
        wait_until(  # compose's condition: service_healthy
            lambda: subprocess.run(health).returncode == 0,
            timeout=60,
            what="the router's health check",
        )
        run = json.loads((runs / "compose" / "run.json").read_text())
        assert run["secure"] and run["run_id"] == "compose"
        for name, svc in services.items():
            env = dict(os.environ)
            env.update(
                {k: _local(["wncs", v], runs, None)[-1] for k, v in svc["environment"].items()}
            )
            procs[name] = subprocess.Popen(
                _local(svc["command"], runs, run["endpoint"]),
                stdout=(logs / f"{name}.log").open("w"),
                stderr=subprocess.STDOUT,
                env=env,
            )
        assert procs["clock"].wait(timeout=300) == 0, (logs / "clock.log").read_text()[-2000:]
        for name in services:
            assert procs[name].wait(timeout=60) == 0, (logs / f"{name}.log").read_text()[-2000:]
    finally:
        stop_all(list(procs.values()))
    said = (logs / "router.log").read_text()
    assert "(secure)" in said and "it refused 0 attempts" in said
    history = runs / "compose" / "history.sqlite"
    assert messages_digest(history) == messages_digest(clean / "history.sqlite")
