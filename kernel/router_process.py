"""A run's router in a process of its own, auditing what it refuses (issue 19).

``wncs run`` starts its router here rather than in its own process: zenoh reports a refused
message or login only in its log, which goes to the process's standard output
(:mod:`kernel.audit`), and only a process of its own can hand that to a pipe without taking the
launcher's terminal, or the threads engine's node sessions' logging, with it.

The child, ``python -m kernel.router_process --listen EP [--security DIR] [--zenoh-config F]
[--refused-log FILE]``, opens the router (with the access control and logins of ``DIR``, and
then audits), writes one JSON line ``{"locators": [...]}`` on its standard output (each of its
own lines tagged, :data:`_TAG`), serves until
its standard input ends (the parent closes it, or dies) or a SIGTERM/SIGINT arrives, and writes
a last JSON line, ``{"refused": N, "attempts": [...]}`` (:meth:`kernel.audit.RefusalLog.as_dict`;
``refused`` is ``null`` when nothing was audited: an insecure run). :class:`RouterProcess` is
the parent's side.
"""

from __future__ import annotations

import argparse
import json
import queue
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO, Any

from core.errors import ConfigError
from kernel.audit import LogCapture
from kernel.bus import open_router
from kernel.lifetime import die_with_parent
from kernel.security import router_settings

__all__ = ["RouterProcess", "main"]

_TAG = "wncs-router-process: "
"""Begins each line the child says to its parent; its other output lines are zenoh's log lines
(``RUST_LOG``), which the parent passes on."""


class RouterProcess:
    """Start a router process and learn its endpoint; :meth:`close` stops it and returns what it
    refused.

    Raises
    ------
    ConfigError
        If the router cannot start (its own message: a port in use, a bad configuration file),
        or says nothing within ``timeout`` seconds.
    """

    def __init__(
        self,
        listen: str,
        *,
        security: Path | None = None,
        zenoh_config: str | None = None,
        refused_log: Path | None = None,
        timeout: float = 60.0,
    ) -> None:
        cmd = [sys.executable, "-m", "kernel.router_process", "--listen", listen]
        if security is not None:
            cmd += ["--security", str(security)]
        if zenoh_config:
            cmd += ["--zenoh-config", zenoh_config]
        if refused_log is not None:
            cmd += ["--refused-log", str(refused_log)]
        self._proc = subprocess.Popen(
            cmd,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=die_with_parent,
            # out of the terminal's process group: Ctrl-C goes to the launcher, which stops the
            # run through its clock and closes the router last (the nodes still need it then)
            start_new_session=True,
        )
        self._lines: queue.Queue[str | None] = queue.Queue()
        self._stderr: list[str] = []
        assert self._proc.stdout is not None and self._proc.stderr is not None
        sinks: tuple[tuple[IO[str], Callable[[str | None], None]], ...] = (
            (self._proc.stdout, self._said),
            (self._proc.stderr, self._err),
        )
        for stream, sink in sinks:
            threading.Thread(
                target=self._pump, args=(stream, sink), name="router-process", daemon=True
            ).start()
        first = self._next(timeout)
        if first is None or "locators" not in first:
            self._proc.kill()
            self._proc.wait()
            said = "".join(self._stderr).strip().splitlines()
            raise ConfigError(
                said[-1] if said else f"the router process did not start within {timeout:g} s"
            )
        self.locators: list[str] = list(first["locators"])

    @property
    def pid(self) -> int:
        """The router process's id."""
        return self._proc.pid

    def _said(self, line: str | None) -> None:
        """A line of the child's standard output: its own word (tagged), or zenoh's log
        lines that ``RUST_LOG`` asked for, passed on to this process's output."""
        if line is None or line.startswith(_TAG):
            self._lines.put(line if line is None else line[len(_TAG) :])
        else:
            sys.stdout.write(line)

    def _err(self, line: str | None) -> None:
        """A line of the child's standard error: kept, to say why it failed."""
        if line is not None:
            self._stderr.append(line)

    @staticmethod
    def _pump(stream: IO[str], sink: Callable[[str | None], None]) -> None:
        """Each line of ``stream`` to ``sink``, then ``None`` at its end."""
        for line in stream:
            sink(line)
        sink(None)

    def _next(self, timeout: float) -> dict[str, Any] | None:
        try:
            line = self._lines.get(timeout=timeout)
        except queue.Empty:
            return None
        if line is None:
            self._proc.wait()
            return None
        try:
            data = json.loads(line)
        except ValueError:
            return None
        return data if isinstance(data, dict) else None

    def close(self, timeout: float = 10.0) -> dict[str, Any] | None:
        """Stop the router and return what it refused (``{"refused": N, "attempts": [...]}``;
        ``None`` if it died without saying)."""
        if self._proc.stdin is not None and not self._proc.stdin.closed:
            try:
                self._proc.stdin.close()
            except OSError:  # it died already
                pass
        last = self._next(timeout)
        try:
            self._proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        return last


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m kernel.router_process", description=__doc__)
    p.add_argument("--listen", required=True, help="the endpoint to listen on")
    p.add_argument("--security", default=None, help="the run's security directory")
    p.add_argument("--zenoh-config", default=None, help="a zenoh configuration file")
    p.add_argument("--refused-log", default=None, help="file the refused attempts go to")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    die_with_parent()
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda signum, frame: stop.set())
    signal.signal(signal.SIGINT, lambda signum, frame: stop.set())
    capture = None
    if args.security is not None:
        capture = LogCapture(Path(args.refused_log) if args.refused_log else None)
        capture.start()
    try:
        settings = router_settings(Path(args.security)) if args.security else None
        router, locators = open_router(
            args.listen, settings=settings, config_file=args.zenoh_config
        )
    except ConfigError as err:
        print(f"wncs router: {err}", file=sys.stderr, flush=True)
        return 2
    print(_TAG + json.dumps({"locators": locators}), flush=True)

    def watch_stdin() -> None:
        sys.stdin.read()  # until the parent closes it, or dies
        stop.set()

    threading.Thread(target=watch_stdin, name="stdin", daemon=True).start()
    try:
        while not stop.wait(0.5):
            pass
    finally:
        router.close()
        counts = capture.close() if capture is not None else {"refused": None, "attempts": []}
        print(_TAG + json.dumps(counts), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
