"""Zenoh's threads: every process of a run asks for ``kernel.bus.RUNTIME`` (its receive,
transmit and accept work handed to the application runtime) before its first session, and a
user's ``$ZENOH_RUNTIME`` wins. Checked by the threads zenoh starts in a fresh process (Linux
names them after their runtime: ``rx-0``, ``tx-0``, ``acc-0``, ``app-0``, ``net-0``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from kernel.bus import RUNTIME

PROBE = """
import json, os
from kernel.bus import open_client, open_router
router, locators = open_router("tcp/127.0.0.1:0")
client = open_client(next(loc for loc in locators if loc.startswith("tcp/")))
tasks = os.listdir("/proc/self/task")
names = sorted(open(f"/proc/self/task/{t}/comm").read().strip() for t in tasks)
print(json.dumps({"threads": names, "env": os.environ.get("ZENOH_RUNTIME")}))
client.close()
router.close()
"""


def _zenoh_threads(env: dict[str, str]) -> tuple[set[str], str | None]:
    out = subprocess.run(
        [sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0, out.stderr
    said = json.loads(out.stdout.strip().splitlines()[-1])
    runtimes = {n.rsplit("-", 1)[0] for n in said["threads"] if n[-1].isdigit() and "-" in n}
    return runtimes, said["env"]


@pytest.mark.parametrize("given", [None, ""])
def test_a_run_s_sessions_hand_their_work_to_the_application_runtime(given: str | None) -> None:
    env = {k: v for k, v in os.environ.items() if k != "ZENOH_RUNTIME"}
    if given is not None:  # set but empty: zenoh would fail to parse it
        env["ZENOH_RUNTIME"] = given
    runtimes, asked = _zenoh_threads(env)
    assert asked == RUNTIME
    assert "app" in runtimes
    assert not runtimes & {"rx", "tx", "acc"}, runtimes


def test_a_user_s_zenoh_runtime_wins() -> None:
    mine = "(rx: (worker_threads: 2))"  # zenoh's default
    runtimes, asked = _zenoh_threads({**os.environ, "ZENOH_RUNTIME": mine})
    assert asked == mine
    assert {"rx", "tx", "app"} <= runtimes, runtimes
