"""The launcher's side of the fork server (:mod:`runtime.forkserver`): start it, and a handle per
node process with the part of ``subprocess.Popen`` the launcher uses (``pid``, ``poll``,
``wait``, ``returncode``, ``send_signal``), fed by the server's ``started``/``exit`` lines."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

__all__ = ["ForkServer", "Forked"]

_POLL_S = 0.01
_DRAIN_S = 30.0
"""The longest wait for the reader thread after the server left (its pipe is at end of file:
only a starved thread takes more than moments)."""


class Forked:
    """A node process forked by the server: its exit code arrives on the server's pipe."""

    def __init__(self, name: str, pid: int, server: ForkServer) -> None:
        self.name = name
        self.pid = pid
        self.returncode: int | None = None
        self._server = server
        self._done = threading.Event()

    def _exited(self, code: int) -> None:
        self.returncode = code
        self._done.set()

    def poll(self) -> int | None:
        if self.returncode is None and self._server.gone():
            # The server leaves once it has reported every child: its last lines may still be
            # in the pipe, unread by the reader thread (a busy machine). Read them first; only
            # a child the server never reported died unseen (the server was killed first).
            self._server.drain()
            if self.returncode is None and not _exists(self.pid):
                self._exited(-9)  # nobody will report this child's code
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            left = _POLL_S if deadline is None else min(deadline - time.monotonic(), _POLL_S)
            if left <= 0:
                raise subprocess.TimeoutExpired(self.name, timeout or 0.0)
            self._done.wait(left)
        assert self.returncode is not None
        return self.returncode

    def send_signal(self, sig: int) -> None:
        if self.returncode is None:
            try:
                os.kill(self.pid, sig)
            except ProcessLookupError:
                pass


def _exists(pid: int) -> bool:
    """Whether process ``pid`` still runs (a zombie, reaped by nobody yet, does not)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[-1].split()[0] != "Z"
    except OSError:
        return False


class ForkServer:
    """``python -m runtime.forkserver`` started for ``names``; :meth:`nodes` waits until it has
    forked them all and returns their handles by name.

    With ``connect=None`` the server starts before the router's endpoint is known (it imports
    and validates meanwhile: the launcher starts it beside the router's process) and forks once
    :meth:`connect_to` gives it; :meth:`abandon` sends it away without forking. ``env`` is its
    environment (the nodes'), default this process's."""

    def __init__(
        self,
        scenario_path: str,
        names: Sequence[str],
        *,
        connect: str | None,
        run_id: str,
        logs: Path,
        args: Sequence[str],
        preexec_fn: Callable[[], None] | None = None,
        env: Mapping[str, str] | None = None,
    ) -> None:
        cmd = [sys.executable, "-m", "runtime.forkserver", scenario_path]
        cmd += ["--connect", connect or "-", "--run-id", run_id, "--logs", str(logs), *args]
        for name in names:
            cmd += ["--node", name]
        self.names = list(names)
        self._log = open(logs / "forkserver.log", "w")  # noqa: SIM115 - closed in close()
        self.proc = subprocess.Popen(
            cmd,
            stdout=subprocess.PIPE,
            stderr=self._log,
            stdin=subprocess.DEVNULL if connect else subprocess.PIPE,
            start_new_session=True,
            preexec_fn=preexec_fn,
            text=True,
            env=None if env is None else dict(env),
        )
        self.children: dict[str, Forked] = {}
        self._all = threading.Event()
        self._reader = threading.Thread(target=self._read, name="forkserver", daemon=True)
        self._reader.start()

    def connect_to(self, endpoint: str) -> None:
        """The router's endpoint, for a server started with ``connect=None``: it forks now."""
        self._send(endpoint + "\n")

    def abandon(self) -> None:
        """Send a server started with ``connect=None`` away without forking, and wait for it."""
        self._send("")
        self.close()

    def _send(self, text: str) -> None:
        stdin = self.proc.stdin
        if stdin is None or stdin.closed:
            return
        try:
            stdin.write(text)
            stdin.close()
        except OSError:  # it left already
            pass

    def gone(self) -> bool:
        return self.proc.poll() is not None

    def drain(self) -> None:
        """Once the server has left (:meth:`gone`): wait until every line it wrote is read, so
        each child it reaped has its exit code. Its standard output closes when it exits (the
        children write theirs to their logs), so this ends at once, bar a stalled reader."""
        self._reader.join(_DRAIN_S)

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            words = line.split()
            if len(words) != 3:
                continue
            what, name, number = words[0], words[1], int(words[2])
            if what == "started":
                self.children[name] = Forked(name, number, self)
                if len(self.children) == len(self.names):
                    self._all.set()
            elif what == "exit" and name in self.children:
                self.children[name]._exited(number)
        self._all.set()  # the server left: whatever it forked is all there will be

    def nodes(self, timeout: float) -> dict[str, Forked]:
        """The node processes by name, once all are forked; ``RuntimeError`` naming the missing
        ones if the server fails or takes longer than ``timeout`` s."""
        self._all.wait(timeout)
        missing = [n for n in self.names if n not in self.children]
        if missing:
            raise RuntimeError(
                f"the fork server did not start nodes {missing} (see {self._log.name})"
            )
        return dict(self.children)

    def close(self) -> None:
        """Wait for the server (it leaves once its children have); kill it if it lingers."""
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._reader.join(1.0)
        self._log.close()
