"""zenoh's ``ZENOH_RUNTIME`` variable (kernel.bus.RUNTIME_ENV): a value zenoh cannot parse is a
clear error naming it, before anything starts; an empty one counts as unset. zenoh panics on
both and its threads stay unusable, so every case runs in a process of its own."""

from __future__ import annotations

import os
import subprocess
import sys

from tests.conftest import BENCHMARK
from tests.e2e.test_runs import WNCS

OPEN_BOTH = """
from kernel.bus import open_client, open_router
router, locators = open_router()
client = open_client(locators[0])
print("opened", len(locators))
client.close()
router.close()
"""


def _env(value: str) -> dict[str, str]:
    return {**os.environ, "ZENOH_RUNTIME": value, "RUST_BACKTRACE": "0"}


def test_an_empty_zenoh_runtime_counts_as_unset():
    proc = subprocess.run(
        [sys.executable, "-c", OPEN_BOTH], env=_env(""), capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("opened")


def test_a_bad_zenoh_runtime_is_refused_naming_the_variable_before_the_run_starts(tmp_path):
    bad = "(rx: (workers: 2))"
    proc = subprocess.run(
        [sys.executable, "-c", OPEN_BOTH], env=_env(bad), capture_output=True, text=True, timeout=60
    )
    assert proc.returncode != 0
    last = proc.stderr.strip().splitlines()[-1]
    assert last.startswith("core.errors.ConfigError: ZENOH_RUNTIME='(rx: (workers: 2))'"), last
    assert "is not a zenoh runtime setting" in last and '"workers"' in last  # zenoh's reason
    run = subprocess.run(
        [*WNCS, "run", str(BENCHMARK), "--out", str(tmp_path / "run"), "--engine", "threads"],
        env=_env(bad),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 2, run.stderr
    assert "ZENOH_RUNTIME='(rx: (workers: 2))' is not a zenoh runtime setting" in run.stderr
    assert not (tmp_path / "run" / "history.sqlite").exists()
