"""What a secure run's router refuses, counted from zenoh's own log (issue 19).

Zenoh 1.10's router drops what its access control denies and a session whose credentials fail,
and tells nobody: the sender gets no error, and the wheel this project installs is built without
zenoh's ``stats`` feature, so its admin space has no drop counters. What it does is log each
decision: the access-control interceptor at TRACE (``<zid> on ...+Username(reactor)+... is
unauthorized to Put (ingress) on wncs/<run>/clock/tick``), the session handshake at DEBUG
(``UsrPwd extension - Recv OpenSyn. Invalid password.``). Those lines go from Rust straight to
the process's standard output. A router process that audits therefore hands its standard output
(file descriptor 1) to a pipe before zenoh's logging starts (:class:`LogCapture`), with exactly
the two log targets turned on (:func:`audit_filter`), and reads the pipe in a thread:
:class:`RefusalLog` turns the lines into :class:`Refused` attempts and counts them.

Authorised decisions are logged at the same TRACE level, so the router formats one line per
message it routes (about 20 lines a round on the JCSTR benchmark); ``bench/security.py`` prints
what that costs. Two kinds of decision line are not attempts, and are not counted:

* when the router first meets a key expression it computes (and logs) its permission for all
  nine actions at once, in one thread, right after ``ACL (ingress|egress): caching permissions
  for `KEY` ...``; the block ends with the ``Declare Liveliness Subscriber`` decision. (With
  several authentication subjects on one link, zenoh logs one line per subject; the block then
  ends at the first, and a second subject's denial of that last action would be counted: zenoh
  warns of such links, "Transport returned multiple network interfaces".)
* authorised decisions.

Every other ``unauthorized`` line is one message, declaration or token the router dropped; a
cached decision names the session by its zenoh id only, which is mapped back to the user name
the session logged in with from the other lines. A failed login is counted from the handshake's
line (``Expected extension``: no credentials; ``Invalid user``; ``Invalid password``).
"""

from __future__ import annotations

import fcntl
import os
import re
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

from kernel.bus import init_zenoh_log, zenoh_log_started

__all__ = [
    "AUDIT_DIRECTIVES",
    "audit_filter",
    "Refused",
    "RefusalLog",
    "LogCapture",
]

_ACL_TARGET = "zenoh::net::routing::interceptor::access_control"
_LOGIN_TARGET = "zenoh_transport::unicast::establishment::accept"
AUDIT_DIRECTIVES = (f"{_ACL_TARGET}=trace", f"{_LOGIN_TARGET}=debug")
"""The zenoh log targets an auditing router turns on (``RUST_LOG`` directives)."""

_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_THREAD = re.compile(r"ThreadId\((\d+)\)")
_DECISION = re.compile(
    r"(?P<cached>Using cached result: )?(?P<zid>[0-9a-f]+)(?: on (?P<subject>\S+))? "
    r"is (?P<verdict>authorized|unauthorized) to (?P<what>.+) on (?P<key>\S+)$"
)
_USER = re.compile(r"Username\(([^)]*)\)")
_LOGIN = re.compile(r"UsrPwd extension - (?P<reason>.+?)(?: at /\S+)?$")
_LAST_CACHED = "Declare Liveliness Subscriber"
_WORTH_READING = ("unauthorized", "caching permissions", _LAST_CACHED, "UsrPwd extension")
"""A line holding none of these is an authorised decision outside a caching block's end: most
of the lines, skipped without a regular expression."""
_READ_EVERY_S = 0.02
_PIPE_BYTES = 1 << 20
_F_SETPIPE_SZ = 1031


def audit_filter(user: str | None = None) -> str:
    """The ``RUST_LOG`` filter of an auditing router: the user's own filter (or ``off``) and
    the two audited targets."""
    return ",".join([user or "off", *AUDIT_DIRECTIVES])


@dataclass(frozen=True)
class Refused:
    """One kind of attempt the router refused.

    Attributes
    ----------
    who : the user name the session logged in with; ``zid <hex>`` if it never said; for a
        refused login, ``unauthenticated``.
    what : the action as zenoh names it (``Put (ingress)``, ``Liveliness Token (ingress)``), or
        ``login (<reason>)``.
    where : the key expression; empty for a login.
    """

    who: str
    what: str
    where: str

    def __str__(self) -> str:
        return f"{self.who}: {self.what}" + (f" on {self.where}" if self.where else "")


class RefusalLog:
    """Counts the refused attempts in zenoh's log lines, fed one at a time (see the module
    docstring for which lines count)."""

    def __init__(self) -> None:
        self.counts: Counter[Refused] = Counter()
        self._names: dict[str, str] = {}  # zenoh id -> user name
        self._caching: set[str] = set()  # threads inside a permission-caching block

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def feed(self, line: str) -> Refused | None:
        """Read one log line; the attempt it refuses, counted, or ``None``."""
        if not any(word in line for word in _WORTH_READING):
            return None
        line = _ANSI.sub("", line).rstrip()
        if _ACL_TARGET + ":" in line:
            return self._acl(line)
        if _LOGIN_TARGET + ":" in line:
            found = _LOGIN.search(line)
            if found:
                return self._count(Refused("unauthenticated", f"login ({found['reason']})", ""))
        return None

    def _acl(self, line: str) -> Refused | None:
        thread = _THREAD.search(line)
        where = thread[1] if thread else ""
        message = line.split(_ACL_TARGET + ":", 1)[1].strip()
        if "caching permissions for" in message:
            self._caching.add(where)
            return None
        found = _DECISION.match(message)
        if found is None:
            return None
        zid = found["zid"]
        user = _USER.search(found["subject"] or "")
        if user:
            self._names[zid] = user[1]
        if not found["cached"] and where in self._caching:
            if found["what"].startswith(_LAST_CACHED):
                self._caching.discard(where)
            return None
        if found["verdict"] != "unauthorized":
            return None
        who = self._names.get(zid, f"zid {zid}")
        return self._count(Refused(who, found["what"], found["key"].strip("\"'")))

    def _count(self, refused: Refused) -> Refused:
        self.counts[refused] += 1
        return refused

    def as_dict(self) -> dict[str, Any]:
        """``{"refused": total, "attempts": [{who, what, where, count}, ...]}``, most first."""
        attempts = [
            {"who": r.who, "what": r.what, "where": r.where, "count": n}
            for r, n in sorted(self.counts.items(), key=lambda kv: (-kv[1], str(kv[0])))
        ]
        return {"refused": self.total, "attempts": attempts}


class LogCapture:
    """Takes this process's file descriptor 1 for zenoh's log and counts what it refuses.

    :meth:`start` must run before zenoh's logging starts in the process (the first router or
    session it opens); it sets ``RUST_LOG`` to :func:`audit_filter` of the user's own, points
    ``sys.stdout`` at a copy of the real standard output (what the process prints still shows)
    and reads the pipe in a thread: each refused attempt is appended to ``refused_log`` (one
    line: UTC time, the attempt and its count so far) and passed to
    ``on_refused(attempt, count)``; lines of other targets the user asked for with ``RUST_LOG``
    are passed through to the real output.
    """

    def __init__(
        self,
        refused_log: Path | None = None,
        on_refused: Callable[[Refused, int], None] | None = None,
    ) -> None:
        self.log = RefusalLog()
        self._path = refused_log
        self._on_refused = on_refused
        self._saved = -1
        self._thread: threading.Thread | None = None
        self._out: TextIO | None = None
        self._passthrough = False  # whether the user's RUST_LOG asked for other lines
        self._lock = threading.Lock()

    def start(self) -> bool:
        """Take file descriptor 1 and start zenoh's logging with the audit filter; ``False``
        (nothing done) if zenoh's logging had started already in this process."""
        if zenoh_log_started():
            return False
        user = os.environ.get("RUST_LOG")
        os.environ["RUST_LOG"] = audit_filter(user)
        os.environ.setdefault("NO_COLOR", "1")  # no ANSI colour codes in the lines read
        sys.stdout.flush()
        read, write = os.pipe()
        try:  # room for what gathers between two reads (Linux; the default is 64 kB)
            fcntl.fcntl(write, _F_SETPIPE_SZ, _PIPE_BYTES)
        except OSError:
            pass
        self._saved = os.dup(1)
        os.dup2(write, 1)
        os.close(write)
        sys.stdout = os.fdopen(os.dup(self._saved), "w", buffering=1)
        self._passthrough = user is not None
        self._out = open(self._path, "a", buffering=1) if self._path else None  # noqa: SIM115
        self._thread = threading.Thread(
            target=self._read, args=(read,), name="zenoh-log", daemon=True
        )
        self._thread.start()
        init_zenoh_log()
        return True

    def _read(self, fd: int) -> None:
        """Drain the pipe to its end, whatever a line or a callback does: a reader that stopped
        would fill the pipe, and zenoh's threads would block writing their log.

        It reads what has gathered every :data:`_READ_EVERY_S` rather than each line as it
        comes: the router writes about 20 lines a round, and a reader woken for each would take
        the run's CPU (measured: a tick's trip to a node 150 us longer on 2 cores). The pipe
        holds :data:`_PIPE_BYTES` meanwhile (a few thousand lines)."""
        rest = b""
        while True:
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                break
            lines = (rest + chunk).split(b"\n")
            rest = lines.pop()
            for raw in lines:
                try:
                    self._line(raw.decode(errors="replace"))
                except Exception:  # noqa: BLE001 - keep draining (see above)
                    continue
            time.sleep(_READ_EVERY_S)
        os.close(fd)

    def _line(self, line: str) -> None:
        with self._lock:
            refused = self.log.feed(line)
            count = self.log.counts[refused] if refused is not None else 0
        if refused is not None:
            if self._out is not None:
                stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
                self._out.write(f"{stamp} {refused} (#{count})\n")
            if self._on_refused is not None:
                self._on_refused(refused, count)
        elif self._passthrough:
            os.write(self._saved, line.encode() + b"\n")

    def close(self, timeout: float = 5.0) -> dict[str, Any]:
        """Give file descriptor 1 back (the pipe ends, the reader drains it) and return the
        counts (:meth:`RefusalLog.as_dict`)."""
        if self._thread is not None:
            sys.stdout.flush()
            os.dup2(self._saved, 1)  # the pipe's last writer goes: the reader sees its end
            self._thread.join(timeout)
            self._thread = None
            if self._out is not None:
                self._out.close()
        with self._lock:
            return self.log.as_dict()
