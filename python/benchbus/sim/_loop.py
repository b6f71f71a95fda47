"""The thread of the simulated line's forwarder and of the simulated gateway: a loop of
steps, each waiting on its file descriptors, until stopped. Pure Python, no pymodbus."""

from __future__ import annotations

import logging
import threading

__all__ = ["StepLoop"]

log = logging.getLogger("benchbus.sim")


class StepLoop:
    """A daemon thread that runs :meth:`_step` until :meth:`_end` (a subclass defines
    :meth:`_step`, which waits on its descriptors, and :meth:`_wake`, which ends that wait)."""

    def __init__(self, what: str, name: str) -> None:
        """``what`` names the loop in the log (``"simulator line thread"``); ``name`` is the
        thread's."""
        self._what = what
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        """Start the thread."""
        self._thread.start()

    def _end(self, timeout: float) -> bool:
        """Stop the thread and wait for it; False if it did not end within ``timeout``."""
        self._stopping = True
        self._wake()
        if self._thread.is_alive():
            self._thread.join(timeout)
        if self._thread.is_alive():  # pragma: no cover - the loop ends within a wait
            log.error("%s did not stop", self._what)
            return False
        return True

    def _run(self) -> None:
        try:
            while not self._stopping:
                self._step()
        except Exception:  # pragma: no cover - a bug here must not pass silently
            log.exception("%s failed", self._what)
        finally:
            self._ended()

    def _step(self) -> None:
        raise NotImplementedError

    def _wake(self) -> None:
        raise NotImplementedError

    def _ended(self) -> None:
        """Called in the thread as it ends: release whoever waits on it."""
