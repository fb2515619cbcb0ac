"""Which CPUs a run's processes may use: ``wncs run --affinity NAME=CPUS`` (Linux).

A round is a chain of wake-ups (the clock's tick, the router, the node, its ``Done`` back through
the router to the clock), one after the other. On a small virtual machine a wake-up that crosses
to another CPU costs more than one that stays (the other CPU may be idle in the hypervisor), so
a chain kept on one CPU can be faster than one spread over two, while the work off the chain
(the historian's recording) is better on the other. Measured on the 2-CPU machine of
``docs/benchmarks.md``: the benchmark's rounds 15-34 % faster on the threads engine with
``--affinity '*=0'``; on the processes engine with ``--affinity '*=0' --affinity historian=1``
about 8 % faster in two alternated comparisons, slower in one run of ``bench/engines.py``, and
no faster at 50 loops, where its processes work in parallel (all on one CPU: slower). So the
threads engine's process and its router run on one CPU unless told otherwise
(:func:`with_default`), and the processes engine's processes are pinned only when asked.

``NAME`` is a node of the scenario, ``clock``, ``historian`` or ``router`` (each a process of
its own in the processes engine), or ``*`` for every one of those not named (the launcher's own
process, which only shows the progress, and a dashboard's are left alone). The threads engine
runs the clock and every node in the launcher's process: it takes ``*`` (that process, for the
run) and ``router`` only. ``CPUS`` is a list of CPU numbers and ranges, as ``taskset -c`` takes
them (``0``, ``0,2``, ``0-3``), each one this process may use.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Collection, Iterator, Mapping, Sequence

from core.errors import ConfigError

__all__ = [
    "ANY",
    "ROUTER",
    "parse_affinity",
    "affinity_args",
    "check_affinity",
    "cpus_of",
    "with_default",
    "pin",
    "pinned_here",
]

ANY = "*"
ROUTER = "router"

Affinity = Mapping[str, frozenset[int]]


def _cpus(text: str, item: str) -> frozenset[int]:
    cpus: set[int] = set()
    for part in text.split(","):
        first, dash, last = part.strip().partition("-")
        try:
            lo, hi = int(first), int(last if dash else first)
        except ValueError:
            raise ConfigError(
                f"--affinity {item!r}: {part.strip()!r} is not a CPU number or range (e.g. 0, "
                "0,2, 0-3)"
            ) from None
        if lo < 0 or hi < lo:
            raise ConfigError(f"--affinity {item!r}: {part.strip()!r} is not a CPU range")
        cpus.update(range(lo, hi + 1))
    return frozenset(cpus)


def parse_affinity(items: Sequence[str]) -> dict[str, frozenset[int]]:
    """``NAME=CPUS`` items as a mapping (``ConfigError`` naming the item that is malformed or
    names a process twice)."""
    affinity: dict[str, frozenset[int]] = {}
    for item in items:
        name, sep, cpus = item.partition("=")
        name = name.strip()
        if not sep or not name or not cpus.strip():
            raise ConfigError(f"--affinity {item!r}: expected NAME=CPUS, e.g. '*=0' or router=1")
        if name in affinity:
            raise ConfigError(f"--affinity {item!r}: {name!r} is given twice")
        affinity[name] = _cpus(cpus, item)
    return affinity


def affinity_args(affinity: Affinity) -> list[str]:
    """``affinity`` as the ``--affinity NAME=CPUS`` arguments :func:`parse_affinity` reads."""
    return [
        f"--affinity={name}={','.join(map(str, sorted(cpus)))}" for name, cpus in affinity.items()
    ]


def check_affinity(affinity: Affinity, names: Collection[str], engine: str) -> None:
    """Refuse (``ConfigError``) an affinity a run of ``engine`` with processes ``names`` (the
    clock, the nodes and the historian) cannot apply, before anything starts."""
    if not affinity:
        return
    if engine == "direct":
        raise ConfigError(
            "--affinity: the direct engine runs in this process; use threads or processes"
        )
    if not hasattr(os, "sched_setaffinity"):
        raise ConfigError("--affinity: this system cannot pin processes to CPUs (Linux only)")
    allowed = {ANY, ROUTER} if engine == "threads" else {ANY, ROUTER, *names}
    usable = os.sched_getaffinity(0)
    for name, cpus in affinity.items():
        if name not in allowed:
            why = (
                "the threads engine runs the clock and every node in one process: it takes "
                f"'{ANY}' and '{ROUTER}' only"
                if engine == "threads" and name in names
                else f"not a process of this run (one of {sorted(allowed)})"
            )
            raise ConfigError(f"--affinity {name}=...: {why}")
        if not cpus <= usable:
            raise ConfigError(
                f"--affinity {name}=...: CPU(s) {sorted(cpus - usable)} not available here "
                f"(this process may use {sorted(usable)})"
            )


def cpus_of(affinity: Affinity, name: str) -> frozenset[int] | None:
    """The CPUs of process ``name``: its own entry, else ``*``'s, else ``None`` (any)."""
    return affinity.get(name, affinity.get(ANY))


def with_default(affinity: Affinity, engine: str) -> dict[str, frozenset[int]]:
    """``affinity`` with the engine's default: the threads engine's process and its router on
    one CPU, the lowest this process may use, unless ``*`` says otherwise (``'*=0-1'`` spreads
    them again). Its nodes share one interpreter lock, so a second CPU buys them little but the
    lock's hand-overs and wake-ups across CPUs (``docs/benchmarks.md``). Where processes cannot
    be pinned (not Linux), nothing is."""
    if engine != "threads" or ANY in affinity or not hasattr(os, "sched_getaffinity"):
        return dict(affinity)
    return {**affinity, ANY: frozenset({min(os.sched_getaffinity(0))})}


def pin(pid: int, cpus: Collection[int]) -> None:
    """Pin every thread process ``pid`` has to ``cpus`` (threads it starts later inherit it)."""
    for task in os.listdir(f"/proc/{pid}/task"):
        with contextlib.suppress(ProcessLookupError):  # a thread that ended meanwhile
            os.sched_setaffinity(int(task), cpus)


@contextlib.contextmanager
def pinned_here(cpus: Collection[int] | None) -> Iterator[None]:
    """This process pinned to ``cpus`` (``None``: left alone) while the block runs, then back
    to the CPUs it had."""
    if cpus is None:
        yield
        return
    before = os.sched_getaffinity(0)
    pin(os.getpid(), cpus)
    try:
        yield
    finally:
        pin(os.getpid(), before)
