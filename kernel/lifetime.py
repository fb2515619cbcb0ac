"""A child process that never outlives its parent."""

from __future__ import annotations

import ctypes
import os
import signal

__all__ = ["die_with_parent"]


def die_with_parent(parent: int | None = None) -> None:
    """SIGTERM to this process when its parent dies, even by ``kill -9`` (Linux
    ``prctl(PR_SET_PDEATHSIG)``); as a ``preexec_fn`` or first thing in a forked child. With
    ``parent`` (its pid, read before the fork), leave at once if it is gone already."""
    try:
        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):  # not Linux: the parent's own clean-up still applies
        pass
    if parent is not None and os.getppid() != parent:
        os._exit(1)
