"""zenoh's shared-memory transport is off in the sessions a run opens (kernel.bus.SHARED_MEMORY):
by zenoh's default, a session whose messages reach 3 KB (the clock's tick logs) creates a
shared-memory segment on its second such message, stalling inside that ``put`` for 5-9 ms. A
zenoh configuration file that names the transport keeps its own settings. Each case runs in a
fresh process: the segment, once mapped, stays for the process's life."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from kernel.bus import SHARED_MEMORY, BusConfig, zenoh_config

BIG_MESSAGES = """
import threading
from kernel.bus import open_client, open_router
router, locators = open_router()
sender, receiver = open_client(locators[0]), open_client(locators[0])
got, done = [], threading.Event()
def take(sample):
    got.append(len(sample.payload.to_bytes()))
    if len(got) == 3:
        done.set()
sub = receiver.declare_subscriber("big/**", take)
publisher = sender.declare_publisher("big/log")
for _ in range(300):  # the subscriber reaches the sender through the router
    if publisher.matching_status.matching:
        break
    threading.Event().wait(0.01)
for _ in range(3):
    publisher.put(b"x" * 8000)
assert done.wait(20), got
with open("/proc/self/maps") as maps:
    print(sum(".zenoh" in line for line in maps), got, flush=True)
for closing in (sub.undeclare, publisher.undeclare, sender.close, receiver.close, router.close):
    closing()
"""


def _segments_mapped(env: dict[str, str]) -> int:
    proc = subprocess.run(
        [sys.executable, "-c", BIG_MESSAGES], env=env, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    mapped, got = proc.stdout.split(" ", 1)
    assert got.strip() == "[8000, 8000, 8000]"
    return int(mapped)


def test_big_messages_between_sessions_of_a_run_map_no_shared_memory():
    env = {k: v for k, v in os.environ.items() if k != "ZENOH_CONFIG"}
    assert _segments_mapped(env) == 0


def test_a_configuration_file_that_names_shared_memory_keeps_its_settings(tmp_path):
    on = tmp_path / "shm.json5"
    on.write_text("{ transport: { shared_memory: { enabled: true } } }")
    assert _segments_mapped({**os.environ, "ZENOH_CONFIG": str(on)}) > 0  # zenoh's own way
    conf = zenoh_config(BusConfig(mode="client", config_file=str(on)))
    assert json.loads(conf.get_json(f"{SHARED_MEMORY}/enabled")) is True
    other = tmp_path / "other.json5"
    other.write_text("{ transport: { unicast: { open_timeout: 1234 } } }")
    conf = zenoh_config(BusConfig(mode="client", config_file=str(other)))
    assert json.loads(conf.get_json(f"{SHARED_MEMORY}/enabled")) is False
    assert json.loads(conf.get_json("transport/unicast/open_timeout")) == 1234
