"""A communication watchdog's host side: a thread that keeps talking to a device.

A drive whose communication-loss timeout is set (F08.04 on a BLD) trips and stops its motor
when no request reaches it for that long. :class:`KeepAlive` sends one harmless read every
``interval`` seconds while the host lives, so the timer runs out only when the host dies
(or the line does): exactly the case where the motor must stop.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from benchbus._core import _Ticks
from benchbus._record import check_seconds
from benchbus._scope import Scoped

__all__ = ["KeepAlive", "check_interval"]

log = logging.getLogger("benchbus.device")

#: The shortest and longest keepalive periods, seconds.
MIN_INTERVAL, MAX_INTERVAL = 0.01, 60.0
#: Seconds :meth:`KeepAlive.stop` waits for the thread (a read in progress finishes first).
_JOIN_TIMEOUT = 10.0


def check_interval(interval: object) -> float:
    """``interval`` as a float, or TypeError / ValueError if it is not 0.01..60 seconds."""
    seconds = check_seconds("interval", interval)
    if not MIN_INTERVAL <= seconds <= MAX_INTERVAL:
        raise ValueError(f"interval must be {MIN_INTERVAL} to {MAX_INTERVAL} s, got {interval!r}")
    return seconds


class KeepAlive(Scoped):
    """A daemon thread calling ``read()`` every ``interval`` seconds on absolute deadlines.

    Made by :meth:`benchbus.Drive.keepalive`; not usually built directly. A read that fails
    is logged at WARNING on the ``benchbus.device`` logger and counted in :attr:`errors`,
    and the thread goes on (the next read may well succeed). :meth:`stop` ends it; so does
    leaving a ``with`` block, and closing the drive. The thread is a daemon: if the process
    dies, the reads stop, which is the point.
    """

    def __init__(self, read: Callable[[], object], interval: float, name: str) -> None:
        """Start calling ``read`` now, then every ``interval`` s; ``name`` names the thread."""
        self._read = read
        self._name = name
        #: Seconds between reads.
        self.interval: float = check_interval(interval)
        #: Reads that failed so far.
        self.errors: int = 0
        #: Reads that succeeded so far.
        self.reads: int = 0
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    @property
    def running(self) -> bool:
        """Whether the thread is alive and not asked to stop."""
        return self._thread.is_alive() and not self._stopping.is_set()

    def stop(self) -> None:
        """Stop the reads and wait for the thread (at most 10 s, for a read in progress).

        Safe to call more than once, and from any thread but the keepalive's own.
        """
        self._stopping.set()
        if threading.current_thread() is not self._thread:
            self._thread.join(_JOIN_TIMEOUT)
            if self._thread.is_alive():
                log.warning(
                    "%s: the keepalive thread did not end within %s s", self._name, _JOIN_TIMEOUT
                )

    def _wait(self, seconds: float) -> None:
        self._stopping.wait(seconds)

    def _run(self) -> None:
        for _n, _deadline, _missed in _Ticks(self.interval, sleep=self._wait):
            if self._stopping.is_set():
                return
            try:
                self._read()
                self.reads += 1
            except Exception as exc:
                self.errors += 1
                log.warning(
                    "%s: keepalive read failed (%d so far): %s", self._name, self.errors, exc
                )

    def _leave(self, exc: BaseException | None) -> None:
        """Leaving a ``with`` block: :meth:`stop`."""
        self.stop()

    def __repr__(self) -> str:
        """Name, interval, state and error count."""
        state = "running" if self.running else "stopped"
        return (
            f"<KeepAlive {self._name} every {self.interval} s, {state},"
            f" {self.reads} reads, {self.errors} errors>"
        )
