"""Steady sampling on absolute deadlines: the clock every periodic loop in benchbus uses."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator

__all__ = ["ticks"]


def ticks(
    interval: float,
    duration: float | None = None,
    *,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> Iterator[tuple[int, float, int]]:
    """Yield ``(n, deadline, missed)`` at ``start + n * interval`` for n = 0, 1, 2, ...

    Deadlines are absolute, so time spent in the loop body never accumulates as drift. A
    body that overruns its period skips the deadlines already past (``missed`` counts them)
    rather than firing late ones in a burst. With ``duration`` the ticks stop before
    ``start + duration``; without, they go on until the caller stops iterating.
    ``clock`` and ``sleep`` are injectable for tests.
    """
    if isinstance(interval, bool) or not (
        isinstance(interval, (int, float)) and math.isfinite(interval) and interval > 0
    ):
        raise ValueError(f"interval must be a positive number of seconds, got {interval!r}")
    if duration is not None and not (
        isinstance(duration, (int, float)) and math.isfinite(duration) and duration >= 0
    ):
        raise ValueError(f"duration must be >= 0 seconds, got {duration!r}")
    start = clock()
    n = 0
    while True:
        deadline = start + n * interval
        if duration is not None and _past(n, interval, duration):
            return
        now = clock()
        if now < deadline:
            sleep(deadline - now)
            missed = 0
        else:
            # Late: skip to the latest deadline not yet past.
            behind = int((now - deadline) // interval)
            missed = behind
            n += behind
            deadline = start + n * interval
            if duration is not None and _past(n, interval, duration):
                return
        yield n, deadline, missed
        n += 1


def _past(n: int, interval: float, duration: float) -> bool:
    """Whether tick ``n`` falls at or after ``duration``: in tick counts, not clock values,
    so the count does not depend on where the clock starts (0.9 s at 0.3 s is 3 ticks)."""
    return n * interval >= duration - 1e-9 * max(1.0, duration)
