"""Serving until stopped, for ``sim`` and ``gateway``."""

from __future__ import annotations

import signal
import sys
import time
from types import FrameType
from typing import Any


def serve_until_stopped(where: str, what: str, seconds: float | None) -> None:
    """Print ``where`` (what clients open) on stdout and ``what`` on stderr, then block
    until Ctrl-C, SIGTERM or ``seconds`` (None: no limit), whichever comes first.

    SIGTERM's handler is in place before ``where`` is printed: whoever starts the command
    and stops it once it has read ``where`` gets a clean stop (exit status 0), however
    soon."""
    stop = []

    def on_sigterm(signum: int, frame: FrameType | None) -> None:
        stop.append(signum)

    try:
        previous: Any = signal.signal(signal.SIGTERM, on_sigterm)
    except ValueError:  # not the main thread: no handler, Ctrl-C and --seconds still work
        previous = None
    try:
        print(where, flush=True)
        print(f"{what} on {where}; Ctrl-C or SIGTERM stops it", file=sys.stderr, flush=True)
        end = None if seconds is None else time.monotonic() + seconds
        while not stop:
            left = 0.1 if end is None else min(0.1, end - time.monotonic())
            if left <= 0:
                break
            time.sleep(left)
    except KeyboardInterrupt:
        pass
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
