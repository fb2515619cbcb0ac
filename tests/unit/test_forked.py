"""The launcher's handle on a forked node (runtime.forked): a child's exit code reported by the
fork server is never mistaken for a kill because the server left before its last line was read
(CI saw 'the clock died (SIGKILL)' at the end of a run that had completed)."""

from __future__ import annotations

import subprocess
import sys
import threading

from runtime.forked import Forked, ForkServer


def _server_that_reported(line: str, gate: threading.Event) -> ForkServer:
    """A fork server that wrote ``line`` and left, whose reader reads only once ``gate`` opens
    (a reader thread starved on a busy machine)."""
    server = ForkServer.__new__(ForkServer)  # the real reader and handles, without a scenario
    server.names = ["clock"]
    server.children = {}
    server._all = threading.Event()
    server.proc = subprocess.Popen(
        [sys.executable, "-c", f"print({line!r})"], stdout=subprocess.PIPE, text=True
    )
    server.proc.wait()

    def read() -> None:
        gate.wait()
        server._read()

    server._reader = threading.Thread(target=read, daemon=True)
    return server


def _dead_pid() -> int:
    p = subprocess.Popen(["true"])
    p.wait()
    return p.pid


def test_an_exit_still_in_the_pipe_when_the_server_has_left_is_read_not_taken_for_a_kill():
    gate = threading.Event()
    server = _server_that_reported("exit clock 0", gate)
    clock = Forked("clock", _dead_pid(), server)
    server.children["clock"] = clock
    server._reader.start()
    threading.Timer(0.2, gate.set).start()
    assert server.gone()
    assert clock.poll() == 0
    assert clock.wait(timeout=5) == 0


def test_a_child_the_server_never_reported_is_taken_for_killed():
    gate = threading.Event()
    gate.set()
    server = _server_that_reported("started other 1", gate)
    clock = Forked("clock", _dead_pid(), server)
    server.children["clock"] = clock
    server._reader.start()
    assert clock.poll() == -9
